// gsverse_remap_core.glsl -- per-splat remap of GSVERSE_gaussian_splatting_mesh_anchor splats
// (extension version 1.2), GLSL 450. The same rules, in the same order of operations, as the
// float32 build of native/gsverse_remap.h (gsv_local_faces + gsv_local_splats,
// gsv_games_faces + gsv_games_splats); spec/README.md is normative.
//
// No bindings here: native/kernels/glsl/gsverse_remap.comp declares the buffers (Vulkan,
// Godot's RenderingDevice) and calls these functions once per splat. The rest quantities of the
// local profile (C_r^-1, 1/sqrt(a_r), the classification at rest) are computed on the CPU in
// double precision (gsv_prepare_rest) and only stored as float: a float32 computation of them
// is amplified by a later opening of a rest sliver (spec Outputs, precision and epsilons).
// Everything is relative to the triangle's first corner, which is added back last, so large
// coordinates keep their accuracy.

const float GSV_EPS_DEGENERATE = 1e-6;   // regular iff a > eps * l^2 (spec Triangle frames)
const float GSV_GAMES_EPS = 1e-8;        // GaMeS absolute epsilon, scene units

struct GsvLocalFace {
    vec3 o, e1, e2;   // first corner, edges relative to it
    vec3 m;           // scaled normal (e1 x e2) / (sqrt(a_c) sqrt(a_r)); n_c if degenerate at rest
    mat3 a_aff;       // affine law: [E_c C_r^-1 | m]; R_c if degenerate at rest
    mat3 r;           // R_c, columns t, b, n
    float k;          // sqrt(a_c / a_r); 1 if degenerate at rest
};

// perp(t) = normalize(t x u), u the axis with the smallest |t_k| (lowest k on ties)
vec3 gsv_perp(vec3 t) {
    vec3 ax = abs(t);
    int k = 0;
    if (ax.y < ax.x) k = 1;
    if (ax.z < (k == 0 ? ax.x : ax.y)) k = 2;
    vec3 u = vec3(0.0);
    u[k] = 1.0;
    vec3 o = cross(t, u);
    return o * (1.0 / sqrt(dot(o, o)));
}

// The local frame (spec Triangle frames): R_c with columns t, b, n; area2 = |e1 x e2|.
mat3 gsv_frame(vec3 e1, vec3 e2, out float area2, out vec3 cr) {
    vec3 e3 = e2 - e1;
    cr = cross(e1, e2);
    float a = sqrt(dot(cr, cr));
    float s1 = dot(e1, e1), s2 = dot(e2, e2), s3 = dot(e3, e3);
    float longest2 = max(max(s1, s2), s3);
    area2 = a;
    vec3 t = vec3(1.0, 0.0, 0.0), b = vec3(0.0, 1.0, 0.0), n = vec3(0.0, 0.0, 1.0);
    if (a > GSV_EPS_DEGENERATE * longest2) {
        t = e1 * (1.0 / sqrt(s1));
        n = cr * (1.0 / a);
        b = cross(n, t);
    } else if (longest2 > 0.0) {
        // a segment: t along the longest of (e1, e2, e3) by squared length, first on ties
        vec3 d = e1;
        float best = s1;
        if (s2 > best) { d = e2; best = s2; }
        if (s3 > best) { d = e3; best = s3; }
        t = d * (1.0 / sqrt(best));
        n = gsv_perp(t);
        b = cross(n, t);
    }
    return mat3(t, b, n);
}

// The current state of one face, local profile. rest_inv = C_r^-1 row-major (inv.z = 0).
GsvLocalFace gsv_local_face(vec3 v0, vec3 v1, vec3 v2, vec4 rest_inv, float rest_inv_sqrt_area2,
                            bool rest_regular) {
    GsvLocalFace f;
    f.o = v0;
    f.e1 = v1 - v0;
    f.e2 = v2 - v0;
    float ac;
    vec3 cr;
    f.r = gsv_frame(f.e1, f.e2, ac, cr);
    if (rest_regular) {
        float root_c = sqrt(ac);
        f.k = root_c * rest_inv_sqrt_area2;
        f.m = root_c > 0.0 ? cr / root_c * rest_inv_sqrt_area2 : vec3(0.0);
        f.a_aff = mat3(f.e1 * rest_inv.x + f.e2 * rest_inv.z,
                       f.e1 * rest_inv.y + f.e2 * rest_inv.w, f.m);
    } else {
        // degenerate at rest: G := I, k := 1, m := n_c, A := R_c (both laws)
        f.k = 1.0;
        f.m = f.r[2];
        f.a_aff = f.r;
    }
    return f;
}

// Rotation matrix of a quaternion (x, y, z, w), normalized first.
mat3 gsv_quat_to_matrix(vec4 q) {
    float len = sqrt(dot(q, q));
    float x = 0.0, y = 0.0, z = 0.0, w = 1.0;
    if (len > 0.0) { x = q.x / len; y = q.y / len; z = q.z / len; w = q.w / len; }
    // columns
    return mat3(1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y),
                2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x),
                2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y));
}

// cov6 (xx, xy, xz, yy, yz, zz) of M M^T
void gsv_outer(mat3 m, out float cov6[6]) {
    vec3 r0 = vec3(m[0].x, m[1].x, m[2].x);
    vec3 r1 = vec3(m[0].y, m[1].y, m[2].y);
    vec3 r2 = vec3(m[0].z, m[1].z, m[2].z);
    cov6[0] = dot(r0, r0); cov6[1] = dot(r0, r1); cov6[2] = dot(r0, r2);
    cov6[3] = dot(r1, r1); cov6[4] = dot(r1, r2); cov6[5] = dot(r2, r2);
}

// One splat of the local profile: mean v0 + b1 e1 + b2 e2 + d m (the small part first, the
// corner last); Sigma = A R_l S_l^2 R_l^T A^T with A = a_aff (affine) or k R_c (rigid).
void gsv_local_splat(GsvLocalFace f, vec2 bary, float d, vec4 rotation, vec3 scale, bool rigid,
                     out vec3 mean, out float cov6[6]) {
    mean = f.o + (bary.x * f.e1 + bary.y * f.e2 + d * f.m);
    mat3 rl = gsv_quat_to_matrix(rotation);
    mat3 l = mat3(rl[0] * scale.x, rl[1] * scale.y, rl[2] * scale.z);
    mat3 a = rigid ? f.k * f.r : f.a_aff;
    gsv_outer(a * l, cov6);
}

// The games frame R = [n | b1 | b2] and base scales (spec Remap: the games profile), relative
// to v0: g = (e1 + e2) / 3, u = e1 - g, w = e2 - g.
mat3 gsv_games_frame(vec3 e1, vec3 e2, out vec3 base) {
    vec3 g = (e1 + e2) / 3.0;
    vec3 u = e1 - g, w = e2 - g, e3 = e2 - e1;
    vec3 cr = cross(e1, e2);
    float a = sqrt(dot(cr, cr));
    float s1 = dot(e1, e1), s2 = dot(e2, e2), s3 = dot(e3, e3);
    float longest2 = max(max(s1, s2), s3);
    float tol = GSV_EPS_DEGENERATE * sqrt(longest2);  // relative tests on degenerate triangles
    float lu = sqrt(dot(u, u));
    vec3 n = vec3(0.0, 0.0, 1.0), b1 = vec3(1.0, 0.0, 0.0), b2 = vec3(0.0, 1.0, 0.0);
    if (a > GSV_EPS_DEGENERATE * longest2) {
        b1 = u * (1.0 / lu);
        n = cr * (1.0 / a);
        b2 = cross(n, b1);
    } else if (lu > tol) {
        // degenerate: b2 from w by Gram-Schmidt against b1
        b1 = u * (1.0 / lu);
        vec3 rr = w - dot(w, b1) * b1;
        float lr = sqrt(dot(rr, rr));
        b2 = lr > tol ? rr * (1.0 / lr) : gsv_perp(b1);
        n = cross(b1, b2);
    } else if (longest2 > 0.0) {
        // degenerate, v1 at the centroid: the splat lies along w
        b2 = w * (1.0 / sqrt(dot(w, w)));
        b1 = gsv_perp(b2);
        n = cross(b1, b2);
    }
    base = vec3(GSV_GAMES_EPS, (lu + GSV_GAMES_EPS) / 2.0, dot(w, b2) / 2.0);
    return mat3(n, b1, b2);
}

// ---- rotation + scale outputs (for renderers that want them; the covariance is normative)

const int GSV_JACOBI_SWEEPS = 6;   // cyclic sweeps, converged for 3x3 (plugins/web/src/decompose.js)

// quaternion (x, y, z, w), w >= 0, of a rotation matrix: Shepperd, pivot on the largest of
// 4x^2, 4y^2, 4z^2, 4w^2. m[c][r] is row r, column c.
vec4 gsv_mat_to_quat(mat3 m) {
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
    return (q.w < 0.0 ? -q : q) / sqrt(dot(q, q));
}

// one Jacobi rotation zeroing a[p][q] (a symmetric); v accumulates the eigenvectors (columns).
// t = sign(theta) / (|theta| + sqrt(theta^2 + 1)): |t| <= 1, nothing cancels.
void gsv_jacobi_rotate(inout mat3 a, inout mat3 v, int p, int q) {
    float apq = a[q][p];
    if (apq == 0.0) return;
    float theta = (a[q][q] - a[p][p]) / (2.0 * apq);
    float t = (theta >= 0.0 ? 1.0 : -1.0) / (abs(theta) + sqrt(theta * theta + 1.0));
    float c = 1.0 / sqrt(t * t + 1.0);
    float s = t * c;
    // A <- J^T A J: the column update A J, then the same update of the transpose
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

// Sigma = R diag(scale)^2 R^T by cyclic Jacobi on Sigma / max|Sigma_ij| (no float32 overflow or
// underflow inside the rotations); R right-handed; scales sqrt(max(lambda, 0)). The algorithm
// of the web plugin's shader and src/decompose.js.
void gsv_cov_to_rot_scale(mat3 sigma, out vec4 quat, out vec3 scale) {
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
        gsv_jacobi_rotate(a, v, 0, 1);
        gsv_jacobi_rotate(a, v, 0, 2);
        gsv_jacobi_rotate(a, v, 1, 2);
    }
    if (determinant(v) < 0.0) v[2] = -v[2];
    quat = gsv_mat_to_quat(v);
    scale = sqrt(max(vec3(a[0][0], a[1][1], a[2][2]) * norm, vec3(0.0)));
}

// Rotation + scale of one local splat: rigid R_c R_l and k s_l directly; affine from Sigma.
void gsv_local_rotation_scale(GsvLocalFace f, vec4 rotation, vec3 scale, bool rigid,
                              out vec4 quat, out vec3 scale_out) {
    mat3 rl = gsv_quat_to_matrix(rotation);
    if (rigid) {
        quat = gsv_mat_to_quat(f.r * rl);
        scale_out = f.k * scale;
    } else {
        mat3 m = f.a_aff * mat3(rl[0] * scale.x, rl[1] * scale.y, rl[2] * scale.z);
        gsv_cov_to_rot_scale(m * transpose(m), quat, scale_out);
    }
}

// One splat of the games profile: mean v0 + a1 e1 + a2 e2; scale_j = max(rho s_j, 0) + eps.
// Also the covariance's own factors, for rotation + scale outputs: the frame and sc.
void gsv_games_splat(vec3 v0, vec3 v1, vec3 v2, vec2 bary, float rho, out vec3 mean,
                     out float cov6[6], out mat3 frame, out vec3 scale) {
    vec3 e1 = v1 - v0, e2 = v2 - v0, base;
    mat3 r = gsv_games_frame(e1, e2, base);
    mean = v0 + (bary.x * e1 + bary.y * e2);
    vec3 sc = max(rho * base, vec3(0.0)) + GSV_GAMES_EPS;
    gsv_outer(mat3(r[0] * sc.x, r[1] * sc.y, r[2] * sc.z), cov6);
    frame = r;
    scale = sc;
}
