// gsverse_remap_core.hlsli -- per-splat remap of GSVERSE_gaussian_splatting_mesh_anchor splats
// (extension version 1.2), HLSL (the dialect of Unity compute shaders, Unreal .usf files, DXC,
// FXC and glslang's HLSL front-end). The same rules, in the same order of operations, as the
// float32 build of native/gsverse_remap.h and native/kernels/glsl/gsverse_remap_core.glsl;
// spec/README.md is normative. No bindings and no engine macros here:
// gsverse_remap_kernel.hlsli reads the buffers an engine include declares (engines/).
//
// Matrices are float3x3 in the mathematical sense (m[r][c] row r, column c; mul(a, b) is the
// product a b). The rest quantities of the local profile (C_r^-1, 1/sqrt(a_r), the
// classification at rest) are computed on the CPU in double precision and only stored as
// float (spec Outputs, precision and epsilons). Everything is relative to the triangle's
// first corner, which is added back last.

#ifndef GSVERSE_REMAP_CORE_HLSLI
#define GSVERSE_REMAP_CORE_HLSLI

static const float GSV_EPS_DEGENERATE = 1e-6;   // regular iff a > eps * l^2 (Triangle frames)
static const float GSV_GAMES_EPS = 1e-8;        // GaMeS absolute epsilon, scene units

struct GsvLocalFace {
    float3 o, e1, e2;   // first corner, edges relative to it
    float3 m;           // scaled normal (e1 x e2) / (sqrt(a_c) sqrt(a_r)); n_c if degenerate at rest
    float3x3 a_aff;     // affine law: [E_c C_r^-1 | m]; R_c if degenerate at rest
    float3x3 r;         // R_c, columns t, b, n
    float k;            // sqrt(a_c / a_r); 1 if degenerate at rest
};

// the matrix whose columns are c0, c1, c2
float3x3 gsv_columns(float3 c0, float3 c1, float3 c2) {
    return transpose(float3x3(c0, c1, c2));
}

// perp(t) = normalize(t x u), u the axis with the smallest |t_k| (lowest k on ties)
float3 gsv_perp(float3 t) {
    float3 ax = abs(t);
    int k = 0;
    if (ax.y < ax.x) k = 1;
    if (ax.z < (k == 0 ? ax.x : ax.y)) k = 2;
    float3 u = float3(k == 0 ? 1.0 : 0.0, k == 1 ? 1.0 : 0.0, k == 2 ? 1.0 : 0.0);
    float3 o = cross(t, u);
    return o * (1.0 / sqrt(dot(o, o)));
}

// The local frame (spec Triangle frames): R_c with columns t, b, n; area2 = |e1 x e2|.
float3x3 gsv_frame(float3 e1, float3 e2, out float area2, out float3 cr) {
    float3 e3 = e2 - e1;
    cr = cross(e1, e2);
    float a = sqrt(dot(cr, cr));
    float s1 = dot(e1, e1), s2 = dot(e2, e2), s3 = dot(e3, e3);
    float longest2 = max(max(s1, s2), s3);
    area2 = a;
    float3 t = float3(1.0, 0.0, 0.0), b = float3(0.0, 1.0, 0.0), n = float3(0.0, 0.0, 1.0);
    if (a > GSV_EPS_DEGENERATE * longest2) {
        t = e1 * (1.0 / sqrt(s1));
        n = cr * (1.0 / a);
        b = cross(n, t);
    } else if (longest2 > 0.0) {
        // a segment: t along the longest of (e1, e2, e3) by squared length, first on ties
        float3 d = e1;
        float best = s1;
        if (s2 > best) { d = e2; best = s2; }
        if (s3 > best) { d = e3; best = s3; }
        t = d * (1.0 / sqrt(best));
        n = gsv_perp(t);
        b = cross(n, t);
    }
    return gsv_columns(t, b, n);
}

// The current state of one face, local profile. rest_inv = C_r^-1 row-major (inv.z = 0).
GsvLocalFace gsv_local_face(float3 v0, float3 v1, float3 v2, float4 rest_inv,
                            float rest_inv_sqrt_area2, bool rest_regular) {
    GsvLocalFace f;
    f.o = v0;
    f.e1 = v1 - v0;
    f.e2 = v2 - v0;
    float ac;
    float3 cr;
    f.r = gsv_frame(f.e1, f.e2, ac, cr);
    if (rest_regular) {
        float root_c = sqrt(ac);
        f.k = root_c * rest_inv_sqrt_area2;
        f.m = root_c > 0.0 ? cr / root_c * rest_inv_sqrt_area2 : float3(0.0, 0.0, 0.0);
        f.a_aff = gsv_columns(f.e1 * rest_inv.x + f.e2 * rest_inv.z,
                              f.e1 * rest_inv.y + f.e2 * rest_inv.w, f.m);
    } else {
        // degenerate at rest: G := I, k := 1, m := n_c, A := R_c (both laws)
        f.k = 1.0;
        f.m = float3(f.r[0][2], f.r[1][2], f.r[2][2]);
        f.a_aff = f.r;
    }
    return f;
}

// Rotation matrix of a quaternion (x, y, z, w), normalized first.
float3x3 gsv_quat_to_matrix(float4 q) {
    float len = sqrt(dot(q, q));
    float x = 0.0, y = 0.0, z = 0.0, w = 1.0;
    if (len > 0.0) { x = q.x / len; y = q.y / len; z = q.z / len; w = q.w / len; }
    return float3x3(1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y),
                    2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x),
                    2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y));
}

// cov6 (xx, xy, xz, yy, yz, zz) of M M^T
void gsv_outer(float3x3 m, out float cov6[6]) {
    cov6[0] = dot(m[0], m[0]); cov6[1] = dot(m[0], m[1]); cov6[2] = dot(m[0], m[2]);
    cov6[3] = dot(m[1], m[1]); cov6[4] = dot(m[1], m[2]); cov6[5] = dot(m[2], m[2]);
}

// One splat of the local profile: mean v0 + b1 e1 + b2 e2 + d m (the small part first, the
// corner last); Sigma = A R_l S_l^2 R_l^T A^T with A = a_aff (affine) or k R_c (rigid).
void gsv_local_splat(GsvLocalFace f, float2 bary, float d, float4 rotation, float3 scale,
                     bool rigid, out float3 mean, out float cov6[6]) {
    mean = f.o + (bary.x * f.e1 + bary.y * f.e2 + d * f.m);
    float3x3 rl = gsv_quat_to_matrix(rotation);
    float3x3 l = float3x3(rl[0] * scale, rl[1] * scale, rl[2] * scale);   // R_l S_l
    float3x3 a = rigid ? f.k * f.r : f.a_aff;
    gsv_outer(mul(a, l), cov6);
}

// The games frame R = [n | b1 | b2] and base scales (spec Remap: the games profile), relative
// to v0: g = (e1 + e2) / 3 and u, w the corners v1, v2 relative to the centroid.
float3x3 gsv_games_frame(float3 e1, float3 e2, out float3 base) {
    float3 g = (e1 + e2) / 3.0;
    float3 u = e1 - g, w = e2 - g, e3 = e2 - e1;
    float3 cr = cross(e1, e2);
    float a = sqrt(dot(cr, cr));
    float s1 = dot(e1, e1), s2 = dot(e2, e2), s3 = dot(e3, e3);
    float longest2 = max(max(s1, s2), s3);
    float tol = GSV_EPS_DEGENERATE * sqrt(longest2);  // relative tests on degenerate triangles
    float lu = sqrt(dot(u, u));
    float3 n = float3(0.0, 0.0, 1.0), b1 = float3(1.0, 0.0, 0.0), b2 = float3(0.0, 1.0, 0.0);
    if (a > GSV_EPS_DEGENERATE * longest2) {
        b1 = u * (1.0 / lu);
        n = cr * (1.0 / a);
        b2 = cross(n, b1);
    } else if (lu > tol) {
        // degenerate: b2 from w by Gram-Schmidt against b1
        b1 = u * (1.0 / lu);
        float3 rr = w - dot(w, b1) * b1;
        float lr = sqrt(dot(rr, rr));
        b2 = lr > tol ? rr * (1.0 / lr) : gsv_perp(b1);
        n = cross(b1, b2);
    } else if (longest2 > 0.0) {
        // degenerate, v1 at the centroid: the splat lies along w
        b2 = w * (1.0 / sqrt(dot(w, w)));
        b1 = gsv_perp(b2);
        n = cross(b1, b2);
    }
    base = float3(GSV_GAMES_EPS, (lu + GSV_GAMES_EPS) / 2.0, dot(w, b2) / 2.0);
    return gsv_columns(n, b1, b2);
}

// ---- rotation + scale outputs (for renderers that want them; the covariance is normative)

static const int GSV_JACOBI_SWEEPS = 6;   // cyclic sweeps, converged for 3x3 (plugins/web/src/decompose.js)

// quaternion (x, y, z, w), w >= 0, of a rotation matrix: Shepperd, pivot on the largest of
// 4x^2, 4y^2, 4z^2, 4w^2.
float4 gsv_mat_to_quat(float3x3 m) {
    float m00 = m[0][0], m11 = m[1][1], m22 = m[2][2];
    float m01 = m[0][1], m02 = m[0][2], m10 = m[1][0], m12 = m[1][2], m20 = m[2][0], m21 = m[2][1];
    float tr = m00 + m11 + m22;
    float4 cand = float4(1.0 + 2.0 * m00 - tr, 1.0 + 2.0 * m11 - tr, 1.0 + 2.0 * m22 - tr, 1.0 + tr);
    int k = 0;
    float best = cand.x;
    if (cand.y > best) { k = 1; best = cand.y; }
    if (cand.z > best) { k = 2; best = cand.z; }
    if (cand.w > best) { k = 3; best = cand.w; }
    float s = 2.0 * sqrt(max(best, 0.0));
    if (!(s > 0.0)) return float4(0.0, 0.0, 0.0, 1.0);
    float4 q;
    if (k == 3) q = float4((m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, s / 4.0);
    else if (k == 0) q = float4(s / 4.0, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s);
    else if (k == 1) q = float4((m01 + m10) / s, s / 4.0, (m12 + m21) / s, (m02 - m20) / s);
    else q = float4((m02 + m20) / s, (m12 + m21) / s, s / 4.0, (m10 - m01) / s);
    return (q.w < 0.0 ? -q : q) / sqrt(dot(q, q));
}

// one Jacobi rotation zeroing a[p][q] (a symmetric); w accumulates the eigenvectors as ROWS
// (w = V^T). t = sign(theta) / (|theta| + sqrt(theta^2 + 1)): |t| <= 1, nothing cancels. The
// GLSL kernel's column updates, as row updates: J^T A, transposed, J^T (A J).
void gsv_jacobi_rotate(inout float3x3 a, inout float3x3 w, int p, int q) {
    float apq = a[p][q];
    if (apq == 0.0) return;
    float theta = (a[q][q] - a[p][p]) / (2.0 * apq);
    float t = (theta >= 0.0 ? 1.0 : -1.0) / (abs(theta) + sqrt(theta * theta + 1.0));
    float c = 1.0 / sqrt(t * t + 1.0);
    float s = t * c;
    float3 rp = a[p], rq = a[q];
    a[p] = c * rp - s * rq;
    a[q] = s * rp + c * rq;
    a = transpose(a);
    rp = a[p]; rq = a[q];
    a[p] = c * rp - s * rq;
    a[q] = s * rp + c * rq;
    a[p][q] = 0.0;   // annihilated exactly
    a[q][p] = 0.0;
    rp = w[p]; rq = w[q];   // V <- V J, i.e. V^T <- J^T V^T
    w[p] = c * rp - s * rq;
    w[q] = s * rp + c * rq;
}

// Sigma = R diag(scale)^2 R^T by cyclic Jacobi on Sigma / max|Sigma_ij|; R right-handed;
// scales sqrt(max(lambda, 0)). The algorithm of the web plugin's shader and src/decompose.js.
void gsv_cov_to_rot_scale(float3x3 sigma, out float4 quat, out float3 scale) {
    float3 m0 = abs(sigma[0]), m1 = abs(sigma[1]), m2 = abs(sigma[2]);
    float norm = max(max(max(m0.x, m0.y), max(m0.z, m1.y)), max(m1.z, m2.z));
    if (!(norm > 0.0)) {
        quat = float4(0.0, 0.0, 0.0, 1.0);
        scale = float3(0.0, 0.0, 0.0);
        return;
    }
    float3x3 a = sigma * (1.0 / norm);
    float3x3 w = float3x3(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
    for (int sweep = 0; sweep < GSV_JACOBI_SWEEPS; ++sweep) {
        gsv_jacobi_rotate(a, w, 0, 1);
        gsv_jacobi_rotate(a, w, 0, 2);
        gsv_jacobi_rotate(a, w, 1, 2);
    }
    if (determinant(w) < 0.0) w[2] = -w[2];
    quat = gsv_mat_to_quat(transpose(w));
    scale = sqrt(max(float3(a[0][0], a[1][1], a[2][2]) * norm, float3(0.0, 0.0, 0.0)));
}

// Rotation + scale of one local splat: rigid R_c R_l and k s_l directly; affine from Sigma.
void gsv_local_rotation_scale(GsvLocalFace f, float4 rotation, float3 scale, bool rigid,
                              out float4 quat, out float3 scale_out) {
    float3x3 rl = gsv_quat_to_matrix(rotation);
    if (rigid) {
        quat = gsv_mat_to_quat(mul(f.r, rl));
        scale_out = f.k * scale;
    } else {
        float3x3 m = mul(f.a_aff, float3x3(rl[0] * scale, rl[1] * scale, rl[2] * scale));
        gsv_cov_to_rot_scale(mul(m, transpose(m)), quat, scale_out);
    }
}

// One splat of the games profile: mean v0 + a1 e1 + a2 e2; scale_j = max(rho s_j, 0) + eps.
// Also the covariance's own factors, for rotation + scale outputs: the frame and sc.
void gsv_games_splat(float3 v0, float3 v1, float3 v2, float2 bary, float rho, out float3 mean,
                     out float cov6[6], out float3x3 frame, out float3 scale) {
    float3 e1 = v1 - v0, e2 = v2 - v0, base;
    float3x3 r = gsv_games_frame(e1, e2, base);
    mean = v0 + (bary.x * e1 + bary.y * e2);
    float3 sc = max(rho * base, float3(0.0, 0.0, 0.0)) + GSV_GAMES_EPS;
    gsv_outer(float3x3(r[0] * sc, r[1] * sc, r[2] * sc), cov6);
    frame = r;
    scale = sc;
}

#endif
