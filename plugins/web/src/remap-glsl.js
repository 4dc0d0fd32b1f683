/**
 * GLSL (WebGL2, GLSL ES 3.00) remap of GSVERSE_gaussian_splatting_mesh_anchor splats: the
 * engine-free chunk every WebGL2 engine plugin of this package runs (src/playcanvas/, src/three/).
 *
 * `remapChunkGLSL()` returns ONE string of functions, `gsvRemapSplat(out mean, out quat,
 * out scale)`, which remaps the current splat (the engine's `splat.index`) onto the current
 * anchor vertices, in the splat primitive's local space. It is used, literally unchanged, by
 *   - the engine's unified work-buffer copy pass (`gsplatModifyVS` via the gsplat component's
 *     work-buffer modifier: `modifySplatCenter` / `modifySplatRotationScale`, see
 *     `modifyChunkGLSL()`), which is what renders, and
 *   - the conformance/benchmark pass (`processChunkGLSL()`, run by the engine's
 *     `GSplatProcessor` over the same splat streams), which writes float32 results that are
 *     read back from the GPU.
 *
 * Inputs:
 *   per splat, extra resource streams in the engine's row order (generated `loadXxx()`):
 *     gsvAnchor     RGBA32UI  faceIndex, bits of b1 (alpha1), b2 (alpha2), d (local) or rho (games)
 *     gsvLocalRot   RGBA32F   localRotation x, y, z, w (unit; identity for games)
 *     gsvLocalScale RGBA32F   localScale x, y, z (linear; unused for games)
 *   per instance (uniforms):
 *     gsvVertices   RGBA32F   current anchor vertex positions (xyz), uploaded every frame
 *     gsvFaces      RGBA32UI  corner indices i0, i1, i2 of each face (file order) and 1 when the
 *                             face is regular at rest (0: degenerate at rest)
 *     gsvRest       RGBA32F   per face: C_r^-1 = [[p, q], [0, r]] as (p, q, r) and 1/sqrt(a_r),
 *                             computed in binary64 on the CPU, then rounded to float32
 *     gsvLaw        float     0 local/affine, 1 local/rigid, 2 games
 *   All 2D data textures are addressed row-major: element i at (i % width, i / width).
 *
 * Precision: float32 throughout, edges relative to the first corner (e1 = v1 - v0,
 * e2 = v2 - v0) before anything else, the games centroid as v0 + (e1 + e2) / 3, the mean's
 * corner added last, relative degenerate tests (a > 1e-6 l^2, |u| > 1e-6 l): the per-frame
 * arithmetic of spec/README.md §Outputs, precision and epsilons.
 *
 * Rotation + scale: the rigid law and games produce them directly (R_c R_l, k s_l;
 * [n b1 b2], max(rho s, 0) + eps). For the affine law the engine wants a rotation and
 * scales, so the shader forms Sigma = M M^T with M = A R_l S_l, divides it by its largest
 * entry (no float32 overflow or underflow inside the rotations) and diagonalizes it by cyclic
 * Jacobi: pairs (0,1), (0,2), (1,2) per sweep, GSV_JACOBI_SWEEPS sweeps (converged for 3x3),
 * each rotation from the stable t = sign(theta) / (|theta| + sqrt(theta^2 + 1)) with
 * theta = (a_qq - a_pp) / (2 a_pq): |t| <= 1, so every rotation angle is at most 45 degrees
 * and nothing cancels; a theta whose square overflows gives t = 0; a pair already zero is
 * skipped; the annihilated pair is set to exactly zero. Jacobi is backward stable: the
 * reconstructed R diag(s)^2 R^T differs from the float32 Sigma by a few units of roundoff of
 * ||Sigma|| whatever the eigenvalue spread (the error is relative to the largest eigenvalue,
 * so tiny eigenvalues of very flat splats are known only absolutely, which is what the
 * covariance needs), repeated eigenvalues included (any orthonormal basis of an eigenspace is
 * valid). The eigenvector matrix is made right-handed (the third column negated when
 * det < 0) and turned into a quaternion by the largest-diagonal (Shepperd) branch, w >= 0;
 * scales are sqrt(max(lambda, 0)). The same
 * algorithm is mirrored in JS by src/decompose.js. Everything ports to HLSL line by line
 * (mat3 columns -> float3x3 rows, texelFetch -> Load).
 */

import { JACOBI_SWEEPS } from './decompose.js';

/** Cyclic Jacobi sweeps (the same count as src/decompose.js). */
export const GSV_JACOBI_SWEEPS = JACOBI_SWEEPS;

/** Largest width of the chunk's data textures (every WebGL2 device supports 4096; the chunk reads
 * element i at (i % width, i / width) of whatever width a texture has). */
export const DATA_TEXTURE_MAX_WIDTH = 4096;

/**
 * Names of the per-splat inputs. The chunk reads them through functions the engine defines
 * before it: `uvec4 loadGsvAnchor()`, `vec4 loadGsvLocalRot()`, `vec4 loadGsvLocalScale()`
 * (PlayCanvas: its generated stream loaders; three.js/Spark: texel fetches at the splat's index).
 */
export const STREAM_ANCHOR = 'gsvAnchor';
export const STREAM_LOCAL_ROT = 'gsvLocalRot';
export const STREAM_LOCAL_SCALE = 'gsvLocalScale';

/** The deliberately broken remaps the chunk can build (every engine's broken-variant tests). */
export const REMAP_FAULTS = {
    /** the local frame's normal taken as e2 x e1 (a wrong frame axis: normal offset and the
     * affine law's third column on the wrong side, rigid frame mirrored) */
    'frame-axis': 'the local profile normal flipped (e2 x e1)',
    /** the GaMeS frame's b1 taken towards v2 instead of v1 */
    'games-axis': 'the games frame b1 built from w (towards v2) instead of u',
};

/**
 * The remap functions (one string, shared by the render and the conformance pass of every
 * engine). `fault`: a key of REMAP_FAULTS builds that broken remap; any other value (an
 * engine's render fault, checked by the engine) builds the right one.
 * @param {{fault?: string|null}} [options]
 * @returns {string}
 */
export function remapChunkGLSL(options = {}) {
    const fault = options.fault ?? null;
    const localCross = fault === 'frame-axis' ? 'cross(e2, e1)' : 'cross(e1, e2)';
    const gamesU = fault === 'games-axis' ? 'e2 - g' : 'e1 - g';
    const gamesW = fault === 'games-axis' ? 'e1 - g' : 'e2 - g';
    return /* glsl */ `
// ---- GS-Verse mesh-anchor remap (spec v1.1), GLSL ES 3.00 ----
uniform highp sampler2D gsvVertices;
uniform highp usampler2D gsvFaces;
uniform highp sampler2D gsvRest;
uniform float gsvLaw;

#define GSV_EPS_DEG 1e-6
#define GSV_GAMES_EPS 1e-8
#define GSV_JACOBI_SWEEPS ${GSV_JACOBI_SWEEPS}

ivec2 gsvAt(int i, int width) { return ivec2(i % width, i / width); }
vec3 gsvVertex(uint i) {
    return texelFetch(gsvVertices, gsvAt(int(i), textureSize(gsvVertices, 0).x), 0).xyz;
}

// perp(t) = normalize(t x u), u the axis of the smallest |t_k| (lowest k on ties)
vec3 gsvPerp(vec3 t) {
    vec3 a = abs(t);
    int k = 0;
    if (a.y < a.x) k = 1;
    if (a.z < (k == 0 ? a.x : a.y)) k = 2;
    vec3 u = vec3(k == 0 ? 1.0 : 0.0, k == 1 ? 1.0 : 0.0, k == 2 ? 1.0 : 0.0);
    vec3 c = cross(t, u);
    return c / sqrt(dot(c, c));
}

// rotation matrix (columns) of a quaternion x, y, z, w (normalized here)
mat3 gsvQuatToMat(vec4 q) {
    float len = sqrt(dot(q, q));
    q = len > 0.0 ? q / len : vec4(0.0, 0.0, 0.0, 1.0);
    float x = q.x, y = q.y, z = q.z, w = q.w;
    return mat3(
        1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y),
        2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x),
        2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y));
}

// quaternion (x, y, z, w), w >= 0, of a rotation matrix: Shepperd, pivot on the largest of
// 4x^2, 4y^2, 4z^2, 4w^2. m[c][r] is row r, column c.
vec4 gsvMatToQuat(mat3 m) {
    float m00 = m[0][0], m11 = m[1][1], m22 = m[2][2];
    float m01 = m[1][0], m02 = m[2][0], m10 = m[0][1], m12 = m[2][1], m20 = m[0][2], m21 = m[1][2];
    float tr = m00 + m11 + m22;
    vec4 cand = vec4(1.0 + 2.0 * m00 - tr, 1.0 + 2.0 * m11 - tr, 1.0 + 2.0 * m22 - tr, 1.0 + tr);
    int k = 0;
    float best = cand.x;
    if (cand.y > best) { k = 1; best = cand.y; }
    if (cand.z > best) { k = 2; best = cand.z; }
    if (cand.w > best) { k = 3; best = cand.w; }
    float s = 2.0 * sqrt(max(best, 0.0));
    if (!(s > 0.0)) return vec4(0.0, 0.0, 0.0, 1.0);
    vec4 q;
    if (k == 3) q = vec4((m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, s / 4.0);
    else if (k == 0) q = vec4(s / 4.0, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s);
    else if (k == 1) q = vec4((m01 + m10) / s, s / 4.0, (m12 + m21) / s, (m02 - m20) / s);
    else q = vec4((m02 + m20) / s, (m12 + m21) / s, s / 4.0, (m10 - m01) / s);
    float len = sqrt(dot(q, q));
    return (q.w < 0.0 ? -q : q) / len;
}

// one Jacobi rotation zeroing a[p][q] (a symmetric); v accumulates the eigenvectors (columns)
void gsvJacobiRotate(inout mat3 a, inout mat3 v, int p, int q) {
    float apq = a[q][p];
    if (apq == 0.0) return;
    float theta = (a[q][q] - a[p][p]) / (2.0 * apq);
    float t = (theta >= 0.0 ? 1.0 : -1.0) / (abs(theta) + sqrt(theta * theta + 1.0));
    float c = 1.0 / sqrt(t * t + 1.0);
    float s = t * c;
    // A <- J^T A J with J the rotation in the (p, q) plane: the column update A J, then, as
    // J^T A J = (A J)^T J for symmetric A, the same column update of the transpose
    vec3 cp = a[p], cq = a[q];
    a[p] = c * cp - s * cq;
    a[q] = s * cp + c * cq;
    a = transpose(a);
    cp = a[p]; cq = a[q];
    a[p] = c * cp - s * cq;
    a[q] = s * cp + c * cq;
    a[q][p] = 0.0;   // annihilated exactly
    a[p][q] = 0.0;
    cp = v[p]; cq = v[q];   // V <- V J
    v[p] = c * cp - s * cq;
    v[q] = s * cp + c * cq;
}

// Sigma = R diag(scale)^2 R^T: cyclic Jacobi on Sigma / max|Sigma_ij| (see the module comment)
void gsvCovToRotScale(mat3 sigma, out vec4 quat, out vec3 scale) {
    vec3 m0 = abs(sigma[0]), m1 = abs(sigma[1]), m2 = abs(sigma[2]);
    float norm = max(max(max(m0.x, m0.y), max(m0.z, m1.y)), max(m1.z, m2.z));
    if (!(norm > 0.0)) {
        quat = vec4(0.0, 0.0, 0.0, 1.0);
        scale = vec3(0.0);
        return;
    }
    mat3 a = sigma * (1.0 / norm);
    mat3 v = mat3(1.0);
    for (int sweep = 0; sweep < GSV_JACOBI_SWEEPS; ++sweep) {
        gsvJacobiRotate(a, v, 0, 1);
        gsvJacobiRotate(a, v, 0, 2);
        gsvJacobiRotate(a, v, 1, 2);
    }
    if (determinant(v) < 0.0) v[2] = -v[2];
    quat = gsvMatToQuat(v);
    scale = sqrt(max(vec3(a[0][0], a[1][1], a[2][2]) * norm, vec3(0.0)));
}

// local profile: mean, and rotation + scale (affine: via Sigma; rigid: directly)
void gsvRemapLocal(uvec4 anchor, vec4 localRot, vec3 localScale, bool rigid,
                   out vec3 mean, out vec4 quat, out vec3 scale) {
    uint face = anchor.x;
    float b1 = uintBitsToFloat(anchor.y), b2 = uintBitsToFloat(anchor.z), d = uintBitsToFloat(anchor.w);
    ivec2 fat = gsvAt(int(face), textureSize(gsvFaces, 0).x);
    uvec4 corners = texelFetch(gsvFaces, fat, 0);
    vec4 rest = texelFetch(gsvRest, gsvAt(int(face), textureSize(gsvRest, 0).x), 0);
    vec3 v0 = gsvVertex(corners.x);
    vec3 e1 = gsvVertex(corners.y) - v0;
    vec3 e2 = gsvVertex(corners.z) - v0;
    // current frame (spec Triangle frames)
    vec3 e3 = e2 - e1;
    vec3 cr = ${localCross};
    float ac = sqrt(dot(cr, cr));
    float s1 = dot(e1, e1), s2 = dot(e2, e2), s3 = dot(e3, e3);
    float longest2 = max(max(s1, s2), s3);
    vec3 t, b, n;
    if (ac > GSV_EPS_DEG * longest2) {
        t = e1 / sqrt(s1);
        n = cr / ac;
    } else if (longest2 > 0.0) {
        vec3 dir = e1;
        float best = s1;
        if (s2 > best) { dir = e2; best = s2; }
        if (s3 > best) { dir = e3; best = s3; }
        t = dir / sqrt(best);
        n = gsvPerp(t);
    } else {
        t = vec3(1.0, 0.0, 0.0);
        n = vec3(0.0, 0.0, 1.0);
    }
    b = cross(n, t);
    mat3 rc = mat3(t, b, n);
    float k;
    vec3 m;
    mat3 a;
    if (corners.w != 0u) {
        // regular at rest: k = sqrt(a_c / a_r), m = (e1 x e2) / (sqrt(a_c) sqrt(a_r))
        float rootc = sqrt(ac);
        k = rootc * rest.w;
        m = rootc > 0.0 ? cr / rootc * rest.w : vec3(0.0);
        a = mat3(e1 * rest.x, e1 * rest.y + e2 * rest.z, m);   // [E_c C_r^-1 | m]
    } else {
        // degenerate at rest: k := 1, m := n_c, A := R_c (both laws)
        k = 1.0;
        m = n;
        a = rc;
    }
    mean = v0 + (b1 * e1 + b2 * e2 + d * m);
    mat3 rl = gsvQuatToMat(localRot);
    if (rigid) {
        quat = gsvMatToQuat(rc * rl);
        scale = k * localScale;
    } else {
        mat3 mm = a * mat3(rl[0] * localScale.x, rl[1] * localScale.y, rl[2] * localScale.z);
        gsvCovToRotScale(mm * transpose(mm), quat, scale);
    }
}

// games profile (GaMeS): mean, frame [n b1 b2], scales max(rho s, 0) + eps
void gsvRemapGames(uvec4 anchor, out vec3 mean, out vec4 quat, out vec3 scale) {
    uint face = anchor.x;
    float a1 = uintBitsToFloat(anchor.y), a2 = uintBitsToFloat(anchor.z), rho = uintBitsToFloat(anchor.w);
    uvec4 corners = texelFetch(gsvFaces, gsvAt(int(face), textureSize(gsvFaces, 0).x), 0);
    vec3 v0 = gsvVertex(corners.x);
    vec3 e1 = gsvVertex(corners.y) - v0;
    vec3 e2 = gsvVertex(corners.z) - v0;
    vec3 g = (e1 + e2) / 3.0;         // centroid relative to v0
    vec3 u = ${gamesU};
    vec3 w = ${gamesW};
    vec3 e3 = e2 - e1;
    vec3 cr = cross(e1, e2);
    float ac = sqrt(dot(cr, cr));
    float longest2 = max(max(dot(e1, e1), dot(e2, e2)), dot(e3, e3));
    float tol = GSV_EPS_DEG * sqrt(longest2);
    float lu = sqrt(dot(u, u));
    vec3 n, fb1, fb2;
    if (ac > GSV_EPS_DEG * longest2) {
        fb1 = u / lu;
        n = cr / ac;
        fb2 = cross(n, fb1);
    } else if (lu > tol) {
        fb1 = u / lu;
        vec3 r = w - dot(w, fb1) * fb1;
        float lr = sqrt(dot(r, r));
        fb2 = lr > tol ? r / lr : gsvPerp(fb1);
        n = cross(fb1, fb2);
    } else if (longest2 > 0.0) {
        fb2 = w / sqrt(dot(w, w));
        fb1 = gsvPerp(fb2);
        n = cross(fb1, fb2);
    } else {
        n = vec3(0.0, 0.0, 1.0);
        fb1 = vec3(1.0, 0.0, 0.0);
        fb2 = vec3(0.0, 1.0, 0.0);
    }
    vec3 base = vec3(GSV_GAMES_EPS, (lu + GSV_GAMES_EPS) / 2.0, dot(w, fb2) / 2.0);
    mean = v0 + (a1 * e1 + a2 * e2);
    scale = max(rho * base, vec3(0.0)) + GSV_GAMES_EPS;
    quat = gsvMatToQuat(mat3(n, fb1, fb2));
}

// the current splat (engine row splat.index), splat-local space
void gsvRemapSplat(out vec3 mean, out vec4 quat, out vec3 scale) {
    uvec4 anchor = load${cap(STREAM_ANCHOR)}();
    if (gsvLaw > 1.5) {
        gsvRemapGames(anchor, mean, quat, scale);
    } else {
        gsvRemapLocal(anchor, load${cap(STREAM_LOCAL_ROT)}(), load${cap(STREAM_LOCAL_SCALE)}().xyz,
                      gsvLaw > 0.5, mean, quat, scale);
    }
}
// ---- end of GS-Verse remap ----
`;
}

/** @param {string} s */
export function cap(s) {
    return s.charAt(0).toUpperCase() + s.slice(1);
}
