/*
 * gsverse_remap.h -- per-frame remap of GSVERSE_gaussian_splatting_mesh_anchor splats
 * (extension version 1.2).
 *
 * Portable C99, header-only, no dependencies: it includes only the standard headers
 * <math.h>, <stddef.h> and <stdint.h> (the last two are compiler-provided type headers),
 * allocates nothing and keeps no global state. It compiles as C99 and as C++.
 * Normative text: spec/README.md of gsverse-format, version 1.1 (the section names below refer
 * to it: Triangle frames, Remap: the local profile, Remap: the games profile, Outputs,
 * precision and epsilons).
 *
 * USAGE
 *   In exactly one C or C++ file:
 *       #define GSV_REMAP_IMPLEMENTATION
 *       #include "gsverse_remap.h"
 *   Everywhere else include it without the define (declarations only). Define
 *   GSV_REMAP_STATIC as well to make every function static (one private copy per file).
 *
 *   Precision: the per-frame arithmetic (current faces, splats) uses gsv_real, double by
 *   default (the spec's reference precision). Compile with -DGSV_REAL=float for a float32
 *   build: the code subtracts the triangle's first corner before anything else (edges,
 *   centroid offsets) and adds it back last, so large coordinates keep their accuracy; it
 *   passes the conformance suite. The rest quantities of the local profile (classification,
 *   C_r^-1, a_r, 1/sqrt(a_r)) are ALWAYS computed in double precision by gsv_prepare_rest, in
 *   every build, from the float inputs, and only then rounded to gsv_real for storage, as
 *   spec v1.1 (Outputs, precision and epsilons) requires: float32 rest quantities of a rest
 *   sliver are amplified by a later opening of the triangle.
 *   Inputs and outputs are float, the types of the file and of GPU buffers.
 *
 *   Arrays are tightly packed: vertices float[3V], indices uint32_t[3F] (NULL when the anchor
 *   primitive is not indexed: triangle f is then vertices 3f, 3f+1, 3f+2), per splat
 *   face uint32_t[N], bary float[2N], offset float[N], rotation float[4N] (x, y, z, w),
 *   scale float[3N], rho float[N]; outputs means float[3N], covariances float[6N] in the
 *   order xx, xy, xz, yy, yz, zz, rotations float[4N] (x, y, z, w), scales float[3N].
 *
 *   local profile (once per asset, then every frame):
 *       gsv_rest_face *rest = ...F entries...;   gsv_local_face *cur = ...F entries...;
 *       gsv_prepare_rest(rest_vertices, indices, F, rest);            double precision
 *       each frame:
 *           gsv_local_faces(vertices, indices, F, rest, cur);              per face
 *           gsv_local_splats(cur, N, face, bary, offset, rotation, scale,  per splat
 *                            GSV_AFFINE or GSV_RIGID, means, cov6, NULL, NULL);
 *     Faces regular at rest: k = sqrt(a_c / a_r), scaled normal m = (e1 x e2) / (sqrt(a_c)
 *     sqrt(a_r)) (0 when a_c = 0), mean v0 + b1 e1 + b2 e2 + d m, affine A = [E_c C_r^-1 | m],
 *     rigid A = k R_c. Faces degenerate at rest: k = 1, m = n_c, A = R_c for both laws.
 *     Sigma = A R_l S_l^2 R_l^T A^T.
 *   games profile (every frame):
 *           gsv_games_faces(vertices, indices, F, gcur);
 *           gsv_games_splats(gcur, N, face, bary, rho, means, cov6, rot, scl);
 *     Everything relative to v0: g = (e1 + e2)/3, u = e1 - g, w = e2 - g; the frame rules of
 *     the spec (relative tests against eps_deg * l on degenerate triangles); mean
 *     v0 + a1 e1 + a2 e2.
 *
 *   Rotation/scale outputs (optional, pass NULL to skip): rigid and games produce them
 *   directly; for the affine law they come from an eigen-decomposition of the covariance
 *   (gsv_cov_to_rot_scale). The covariance is the normative output; rotation/scale pairs
 *   are not unique.
 *
 *   Reading anchors: gsv_read_floats()/gsv_read_uints() read glTF accessor bytes of any
 *   component type (little-endian, with byteStride) and dequantize normalized integers;
 *   gsv_normalize_quaternions() renormalizes quaternions: call it on localRotation of EVERY
 *   component type (FLOAT included) and on the rest-pose ROTATION. Before remapping, refuse the
 *   asset when gsv_anchor_accessor_allowed() rejects an accessor layout,
 *   gsv_check_face_indices() finds a face index out of range, gsv_all_finite() finds NaN or
 *   infinity (anchor mesh, anchors, rest POSITION/ROTATION/SCALE),
 *   gsv_check_quaternions_nonzero() finds a zero localRotation (after dequantization, before
 *   normalization) or gsv_check_scales_nonnegative() a negative localScale component.
 *
 *   Compact anchors (version 1.2): gsv_faces_from_counts() turns a faceCounts accessor (one
 *   count per triangle, the splats grouped by face in face order) into per-splat face indices
 *   and refuses a wrong count or sum; a local primitive without barycentrics stores no other
 *   anchor data: gsv_derive_local() derives barycentrics, normal offsets and local rotations
 *   from the rest pose (POSITION, the dequantized ROTATION) and the rest anchor mesh in
 *   double precision, and refuses splats on faces degenerate at rest; the local scales are
 *   the rest SCALE. Derived anchors are used as stored ones: before deriving, refuse a zero
 *   rest ROTATION (gsv_check_quaternions_nonzero, before normalizing it) and a negative rest
 *   SCALE component (gsv_check_scales_nonnegative). Then remap as with stored anchors.
 *
 *   Animated anchor meshes (spec §Animated anchor meshes): an engine skins and morphs the
 *   anchor mesh itself; skinned vertices come out in the scene's global space (glTF ignores
 *   the transform of the node drawing a skinned mesh). gsv_splat_local() brings them into the
 *   splat primitive's local space in double precision, M^-1 p', with M the global matrix of
 *   the splat node (16 doubles, column-major as glTF's node.matrix; affine, last row
 *   0 0 0 1); it returns 0 when M is singular or not finite. The vertices of a morph-only
 *   (unskinned) anchor mesh are already splat-local: remap them as they are.
 */
#ifndef GSVERSE_REMAP_H
#define GSVERSE_REMAP_H

#include <stddef.h>
#include <stdint.h>

#ifndef GSV_REAL
#define GSV_REAL double
#endif
typedef GSV_REAL gsv_real;

#ifdef GSV_REMAP_STATIC
#if defined(__GNUC__) || defined(__clang__)
#define GSV_API static __attribute__((unused))
#else
#define GSV_API static
#endif
#else
#define GSV_API extern
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* glTF component types */
enum {
    GSV_BYTE = 5120, GSV_UNSIGNED_BYTE = 5121, GSV_SHORT = 5122,
    GSV_UNSIGNED_SHORT = 5123, GSV_UNSIGNED_INT = 5125, GSV_FLOAT = 5126
};
/* deformation laws of the local profile */
enum { GSV_AFFINE = 0, GSV_RIGID = 1 };
/* anchor properties (for gsv_anchor_accessor_allowed) */
enum {
    GSV_PROP_FACE_INDEX = 0, GSV_PROP_BARYCENTRICS = 1, GSV_PROP_NORMAL_OFFSET = 2,
    GSV_PROP_LOCAL_ROTATION = 3, GSV_PROP_LOCAL_SCALE = 4, GSV_PROP_RHO = 5,
    GSV_PROP_FACE_COUNTS = 6
};

#define GSV_EPS_DEGENERATE 1e-6 /* regular iff a > eps * l^2 (spec Triangle frames) */
#define GSV_GAMES_EPS 1e-8      /* GaMeS absolute epsilon, scene units */

/* Local frame of one triangle (spec Triangle frames). r is row-major 3x3 whose columns are
   t, b, n; c is the 2x2 edge matrix C row-major (c[0] c[1] / c[2] c[3]); area2 = a = |e1 x e2|,
   the true value for degenerate triangles too; regular = 1 for regular triangles. */
typedef struct gsv_frame {
    gsv_real r[9];
    gsv_real c[4];
    gsv_real area2;
    int regular;
} gsv_frame;

/* Rest data of one face, local profile (computed in double precision by gsv_prepare_rest,
   then stored as gsv_real): C_r^-1 (row-major 2x2, inv[2] = 0), the rest doubled area a_r and
   1/sqrt(a_r). Faces degenerate at rest (regular = 0) use G := I and k := 1 (spec Faces
   degenerate at rest); their inv is the identity and inv_sqrt_area2 is 1, both unused. */
typedef struct gsv_rest_face {
    gsv_real inv[4];
    gsv_real area2;
    gsv_real inv_sqrt_area2;
    int regular;
} gsv_rest_face;

/* Current state of one face, local profile: first corner o, edges e1 e2 (relative to o),
   the scaled normal m = (e1 x e2) / (sqrt(a_c) sqrt(a_r)) (0 when a_c = 0; n_c on faces
   degenerate at rest), a_aff = the affine law's A = [E_c C_r^-1 | m] (row-major 3x3; R_c on
   faces degenerate at rest), r = R_c (the current frame), k = size factor sqrt(a_c / a_r)
   (1 on faces degenerate at rest). */
typedef struct gsv_local_face {
    gsv_real o[3], e1[3], e2[3];
    gsv_real m[3];
    gsv_real a_aff[9];
    gsv_real r[9];
    gsv_real k;
} gsv_local_face;

/* Current state of one face, games profile: first corner, edges, frame R = [n | b1 | b2]
   (row-major 3x3) and base scales s. */
typedef struct gsv_games_face {
    gsv_real o[3], e1[3], e2[3];
    gsv_real r[9];
    gsv_real base[3];
} gsv_games_face;

GSV_API void gsv_local_frame(const float v0[3], const float v1[3], const float v2[3],
                             gsv_frame *out);
GSV_API void gsv_games_frame(const float v0[3], const float v1[3], const float v2[3],
                             gsv_real r[9], gsv_real base[3]);
GSV_API void gsv_prepare_rest(const float *vertices, const uint32_t *indices, size_t face_count,
                              gsv_rest_face *rest);
GSV_API void gsv_local_faces(const float *vertices, const uint32_t *indices, size_t face_count,
                             const gsv_rest_face *rest, gsv_local_face *cur);
GSV_API void gsv_local_splats(const gsv_local_face *cur, size_t n, const uint32_t *face,
                              const float *bary, const float *offset, const float *rotation,
                              const float *scale, int law, float *means, float *cov6,
                              float *rotations, float *scales);
GSV_API void gsv_games_faces(const float *vertices, const uint32_t *indices, size_t face_count,
                             gsv_games_face *cur);
GSV_API void gsv_games_splats(const gsv_games_face *cur, size_t n, const uint32_t *face,
                              const float *bary, const float *rho, float *means, float *cov6,
                              float *rotations, float *scales);

/* helpers */
GSV_API void gsv_quat_to_matrix(const gsv_real q[4], gsv_real m[9]);
GSV_API void gsv_matrix_to_quat(const gsv_real m[9], gsv_real q[4]);
GSV_API void gsv_rot_scale_to_cov(const float q[4], const float s[3], float cov6[6]);
GSV_API void gsv_cov_to_rot_scale(const float cov6[6], float q[4], float s[3]);
GSV_API double gsv_dequantize(int32_t code, int component_type, int normalized);
GSV_API int gsv_read_floats(const void *data, size_t stride, size_t count, int ncomp,
                            int component_type, int normalized, float *out);
GSV_API int gsv_read_uints(const void *data, size_t stride, size_t count,
                           int component_type, uint32_t *out);
GSV_API void gsv_normalize_quaternions(float *q, size_t count);
GSV_API int gsv_anchor_accessor_allowed(int property, int ncomp, int component_type,
                                        int normalized);
GSV_API int gsv_check_face_indices(const uint32_t *face, size_t n, size_t face_count);
GSV_API int gsv_all_finite(const float *values, size_t count);
GSV_API int gsv_check_quaternions_nonzero(const float *q, size_t count);
GSV_API int gsv_check_scales_nonnegative(const float *values, size_t count);
GSV_API int gsv_faces_from_counts(const uint32_t *counts, size_t count_len, size_t face_count,
                                  size_t n, uint32_t *face);
GSV_API int gsv_derive_local(const float *rest_vertices, const uint32_t *indices, size_t n,
                             const uint32_t *face, const float *means, const float *rotations,
                             float *bary, float *offset, float *rotation);
GSV_API int gsv_splat_local(const float *deformed, size_t vertex_count, const double m[16],
                            float *out);

#ifdef __cplusplus
}
#endif

#endif /* GSVERSE_REMAP_H */

/* ======================================================================================= */
#ifdef GSV_REMAP_IMPLEMENTATION
#ifndef GSV_REMAP_IMPLEMENTED
#define GSV_REMAP_IMPLEMENTED

#include <math.h>

#ifdef __cplusplus
extern "C" {
#endif

#define GSV_SQRT(x) ((gsv_real)sqrt((double)(x)))

static gsv_real gsv__dot(const gsv_real a[3], const gsv_real b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void gsv__cross(const gsv_real a[3], const gsv_real b[3], gsv_real out[3]) {
    gsv_real x = a[1] * b[2] - a[2] * b[1];
    gsv_real y = a[2] * b[0] - a[0] * b[2];
    gsv_real z = a[0] * b[1] - a[1] * b[0];
    out[0] = x; out[1] = y; out[2] = z;
}

static gsv_real gsv__norm(const gsv_real a[3]) { return GSV_SQRT(gsv__dot(a, a)); }

static void gsv__scale(const gsv_real a[3], gsv_real s, gsv_real out[3]) {
    out[0] = a[0] * s; out[1] = a[1] * s; out[2] = a[2] * s;
}

/* perp(t) = normalize(t x u), u the axis with the smallest |t_k| (lowest k on ties). */
static void gsv__perp(const gsv_real t[3], gsv_real out[3]) {
    gsv_real u[3] = {0, 0, 0};
    int k = 0;
    gsv_real ax = fabs((double)t[0]), ay = fabs((double)t[1]), az = fabs((double)t[2]);
    if (ay < ax) k = 1;
    if (az < (k == 0 ? ax : ay)) k = 2;
    u[k] = 1;
    gsv__cross(t, u, out);
    gsv__scale(out, (gsv_real)1 / gsv__norm(out), out);
}

static void gsv__columns(const gsv_real c0[3], const gsv_real c1[3], const gsv_real c2[3],
                         gsv_real m[9]) {
    int i;
    for (i = 0; i < 3; ++i) { m[3 * i] = c0[i]; m[3 * i + 1] = c1[i]; m[3 * i + 2] = c2[i]; }
}

static void gsv__edges(const float *v0, const float *v1, const float *v2, gsv_real o[3],
                       gsv_real e1[3], gsv_real e2[3]) {
    int i;
    for (i = 0; i < 3; ++i) {
        o[i] = (gsv_real)v0[i];
        e1[i] = (gsv_real)v1[i] - (gsv_real)v0[i];
        e2[i] = (gsv_real)v2[i] - (gsv_real)v0[i];
    }
}

/* The local frame from edges (spec Triangle frames); also returns cross = e1 x e2. */
static void gsv__frame(const gsv_real e1[3], const gsv_real e2[3], gsv_frame *f,
                       gsv_real cross[3]) {
    gsv_real e3[3], t[3], b[3], n[3];
    gsv_real s1, s2, s3, longest2, a;
    int i;
    for (i = 0; i < 3; ++i) e3[i] = e2[i] - e1[i];
    gsv__cross(e1, e2, cross);
    a = gsv__norm(cross);
    /* squared lengths: the longest edge and its ties are decided on |e|^2 */
    s1 = gsv__dot(e1, e1); s2 = gsv__dot(e2, e2); s3 = gsv__dot(e3, e3);
    longest2 = s1 > s2 ? s1 : s2;
    if (s3 > longest2) longest2 = s3;
    f->c[0] = f->c[1] = f->c[2] = f->c[3] = 0;
    f->area2 = a;                               /* the true a, degenerate triangles too */
    if (a > (gsv_real)GSV_EPS_DEGENERATE * longest2) {
        gsv_real l1 = GSV_SQRT(s1);
        gsv__scale(e1, (gsv_real)1 / l1, t);
        gsv__scale(cross, (gsv_real)1 / a, n);
        gsv__cross(n, t, b);
        f->c[0] = l1;
        f->c[1] = gsv__dot(e2, t);
        f->c[3] = a / l1;
        f->regular = 1;
    } else if (longest2 > 0) {
        /* a segment: t along the longest of (e1, e2, e3) by squared length, the first of
           them on exact ties */
        const gsv_real *d = e1;
        gsv_real best = s1;
        if (s2 > best) { d = e2; best = s2; }
        if (s3 > best) { d = e3; best = s3; }
        gsv__scale(d, (gsv_real)1 / GSV_SQRT(best), t);
        gsv__perp(t, n);
        gsv__cross(n, t, b);
        f->c[0] = gsv__dot(e1, t);
        f->c[1] = gsv__dot(e2, t);
        f->regular = 0;
    } else {
        t[0] = 1; t[1] = 0; t[2] = 0;
        b[0] = 0; b[1] = 1; b[2] = 0;
        n[0] = 0; n[1] = 0; n[2] = 1;
        f->regular = 0;
    }
    gsv__columns(t, b, n, f->r);
}

GSV_API void gsv_local_frame(const float v0[3], const float v1[3], const float v2[3],
                             gsv_frame *out) {
    gsv_real o[3], e1[3], e2[3], cross[3];
    gsv__edges(v0, v1, v2, o, e1, e2);
    gsv__frame(e1, e2, out, cross);
}

/* The games frame and base scales (spec Remap: the games profile). */
static void gsv__games(const gsv_real e1[3], const gsv_real e2[3], gsv_real r[9],
                       gsv_real base[3]) {
    /* everything relative to v0: g = c - v0 = (e1 + e2) / 3, u = v1 - c = e1 - g,
       w = v2 - c = e2 - g */
    gsv_real g[3], u[3], w[3], e3[3], cr[3], b1[3], b2[3], n[3];
    gsv_real lu, a, s1, s2, s3, longest2, ell, tol;
    int i;
    for (i = 0; i < 3; ++i) {
        g[i] = (e1[i] + e2[i]) / 3;
        u[i] = e1[i] - g[i];
        w[i] = e2[i] - g[i];
        e3[i] = e2[i] - e1[i];
    }
    gsv__cross(e1, e2, cr);
    a = gsv__norm(cr);
    s1 = gsv__dot(e1, e1); s2 = gsv__dot(e2, e2); s3 = gsv__dot(e3, e3);
    longest2 = s1 > s2 ? s1 : s2;
    if (s3 > longest2) longest2 = s3;
    ell = GSV_SQRT(longest2);
    tol = (gsv_real)GSV_EPS_DEGENERATE * ell;  /* the relative tests of degenerate triangles */
    lu = gsv__norm(u);
    if (a > (gsv_real)GSV_EPS_DEGENERATE * longest2) {
        /* regular: |u| > eps_deg l / 2 > 0 */
        gsv__scale(u, (gsv_real)1 / lu, b1);
        gsv__scale(cr, (gsv_real)1 / a, n);
        gsv__cross(n, b1, b2);
    } else if (lu > tol) {
        /* degenerate: b2 from w by Gram-Schmidt against b1 */
        gsv_real rr[3], wb, lr;
        gsv__scale(u, (gsv_real)1 / lu, b1);
        wb = gsv__dot(w, b1);
        for (i = 0; i < 3; ++i) rr[i] = w[i] - wb * b1[i];
        lr = gsv__norm(rr);
        if (lr > tol) gsv__scale(rr, (gsv_real)1 / lr, b2);
        else gsv__perp(b1, b2);
        gsv__cross(b1, b2, n);
    } else if (longest2 > 0) {
        /* degenerate, v1 at the centroid (e.g. the midpoint of v0 v2): the splat lies along w */
        gsv__scale(w, (gsv_real)1 / gsv__norm(w), b2);
        gsv__perp(b2, b1);
        gsv__cross(b1, b2, n);
    } else {
        n[0] = 0; n[1] = 0; n[2] = 1;
        b1[0] = 1; b1[1] = 0; b1[2] = 0;
        b2[0] = 0; b2[1] = 1; b2[2] = 0;
    }
    base[0] = (gsv_real)GSV_GAMES_EPS;
    base[1] = (lu + (gsv_real)GSV_GAMES_EPS) / 2;
    base[2] = gsv__dot(w, b2) / 2;
    gsv__columns(n, b1, b2, r);
}

GSV_API void gsv_games_frame(const float v0[3], const float v1[3], const float v2[3],
                             gsv_real r[9], gsv_real base[3]) {
    gsv_real o[3], e1[3], e2[3];
    gsv__edges(v0, v1, v2, o, e1, e2);
    gsv__games(e1, e2, r, base);
}

static void gsv__corners(const float *vertices, const uint32_t *indices, size_t f,
                         const float **v0, const float **v1, const float **v2) {
    size_t i0 = 3 * f, i1 = 3 * f + 1, i2 = 3 * f + 2;
    if (indices) { i0 = indices[i0]; i1 = indices[i1]; i2 = indices[i2]; }
    *v0 = vertices + 3 * i0; *v1 = vertices + 3 * i1; *v2 = vertices + 3 * i2;
}

/* The rest frame of one triangle in double precision, whatever gsv_real is (spec Outputs,
   precision and epsilons: rest quantities in binary64 from the stored float32 values). The
   classification, R_r and C_r follow Triangle frames exactly: t = e1 / |e1|, n = (e1 x e2) / a,
   b = n x t, C_r = [[p, q], [0, h]] with p = |e1|, q = e2 . t, h = a / |e1|. Sets *area2 = a
   for every triangle; for a triangle regular at rest returns 1 and sets r (row-major, columns
   t, b, n) and c = (p, q, h), otherwise returns 0 and leaves r and c unset. The one rest frame
   of the local profile: gsv_prepare_rest and gsv_derive_local both use it. */
static int gsv__rest_frame_double(const float *v0, const float *v1, const float *v2,
                                  double r[9], double c[3], double *area2) {
    double e1[3], e2[3], e3[3], cr[3], t[3], b[3], n[3];
    double s1, s2, s3, longest2, a, p;
    int i;
    for (i = 0; i < 3; ++i) {
        e1[i] = (double)v1[i] - (double)v0[i];
        e2[i] = (double)v2[i] - (double)v0[i];
        e3[i] = (double)v2[i] - (double)v1[i];
    }
    cr[0] = e1[1] * e2[2] - e1[2] * e2[1];
    cr[1] = e1[2] * e2[0] - e1[0] * e2[2];
    cr[2] = e1[0] * e2[1] - e1[1] * e2[0];
    a = sqrt(cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]);
    s1 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2];
    s2 = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2];
    s3 = e3[0] * e3[0] + e3[1] * e3[1] + e3[2] * e3[2];
    longest2 = s1 > s2 ? s1 : s2;
    if (s3 > longest2) longest2 = s3;
    *area2 = a;
    if (!(a > GSV_EPS_DEGENERATE * longest2)) return 0;
    p = sqrt(s1);
    for (i = 0; i < 3; ++i) { t[i] = e1[i] / p; n[i] = cr[i] / a; }
    b[0] = n[1] * t[2] - n[2] * t[1];
    b[1] = n[2] * t[0] - n[0] * t[2];
    b[2] = n[0] * t[1] - n[1] * t[0];
    for (i = 0; i < 3; ++i) { r[3 * i] = t[i]; r[3 * i + 1] = b[i]; r[3 * i + 2] = n[i]; }
    c[0] = p;
    c[1] = e2[0] * t[0] + e2[1] * t[1] + e2[2] * t[2];
    c[2] = a / p;
    return 1;
}

/* The rest quantities of one triangle that the remap uses, in double precision: C_r^-1 (the
   identity on a triangle degenerate at rest), a_r and 1 / sqrt(a_r). Returns 1 for a triangle
   regular at rest. */
static int gsv__rest_double(const float *v0, const float *v1, const float *v2, double inv[4],
                            double *area2, double *inv_sqrt_area2) {
    double r[9], c[3];
    if (!gsv__rest_frame_double(v0, v1, v2, r, c, area2)) {
        inv[0] = 1; inv[1] = 0; inv[2] = 0; inv[3] = 1;
        *inv_sqrt_area2 = 1;
        return 0;
    }
    /* C_r^-1 = [[1/p, -q/(p h)], [0, 1/h]] */
    inv[0] = 1 / c[0]; inv[1] = -c[1] / (c[0] * c[2]);
    inv[2] = 0; inv[3] = 1 / c[2];
    *inv_sqrt_area2 = 1 / sqrt(*area2);
    return 1;
}

GSV_API void gsv_prepare_rest(const float *vertices, const uint32_t *indices, size_t face_count,
                              gsv_rest_face *rest) {
    size_t f;
    for (f = 0; f < face_count; ++f) {
        const float *v0, *v1, *v2;
        double inv[4], area2, inv_sqrt;
        gsv_rest_face *out = rest + f;
        int i;
        gsv__corners(vertices, indices, f, &v0, &v1, &v2);
        out->regular = gsv__rest_double(v0, v1, v2, inv, &area2, &inv_sqrt);
        /* computed in double, stored as gsv_real */
        for (i = 0; i < 4; ++i) out->inv[i] = (gsv_real)inv[i];
        out->area2 = (gsv_real)area2;
        out->inv_sqrt_area2 = (gsv_real)inv_sqrt;
    }
}

GSV_API void gsv_local_faces(const float *vertices, const uint32_t *indices, size_t face_count,
                             const gsv_rest_face *rest, gsv_local_face *cur) {
    size_t f;
    for (f = 0; f < face_count; ++f) {
        const float *v0, *v1, *v2;
        const gsv_rest_face *rf = rest + f;
        gsv_frame fr;
        gsv_local_face *out = cur + f;
        gsv_real cross[3];
        int i, j;
        gsv__corners(vertices, indices, f, &v0, &v1, &v2);
        gsv__edges(v0, v1, v2, out->o, out->e1, out->e2);
        gsv__frame(out->e1, out->e2, &fr, cross);   /* R_c, a_c = |e1 x e2| */
        for (i = 0; i < 9; ++i) out->r[i] = fr.r[i];
        if (rf->regular) {
            /* k = sqrt(a_c / a_r); m = (e1 x e2) / (sqrt(a_c) sqrt(a_r)), 0 when a_c = 0 */
            gsv_real root_c = GSV_SQRT(fr.area2);
            out->k = root_c * rf->inv_sqrt_area2;
            for (i = 0; i < 3; ++i)                 /* |e1 x e2| / sqrt(a_c) = sqrt(a_c) */
                out->m[i] = root_c > 0 ? cross[i] / root_c * rf->inv_sqrt_area2 : (gsv_real)0;
            /* affine A = [E_c C_r^-1 | m] (C_r^-1 upper triangular) */
            for (i = 0; i < 3; ++i) {
                for (j = 0; j < 2; ++j)
                    out->a_aff[3 * i + j] = out->e1[i] * rf->inv[j] + out->e2[i] * rf->inv[2 + j];
                out->a_aff[3 * i + 2] = out->m[i];
            }
        } else {
            /* degenerate at rest: G := I, k := 1, m := n_c, A := R_c (both laws) */
            out->k = 1;
            for (i = 0; i < 3; ++i) out->m[i] = fr.r[3 * i + 2];
            for (i = 0; i < 9; ++i) out->a_aff[i] = fr.r[i];
        }
    }
}

GSV_API void gsv_quat_to_matrix(const gsv_real q[4], gsv_real m[9]) {
    gsv_real len = GSV_SQRT(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    gsv_real x = 0, y = 0, z = 0, w = 1;
    if (len > 0) { x = q[0] / len; y = q[1] / len; z = q[2] / len; w = q[3] / len; }
    m[0] = 1 - 2 * (y * y + z * z); m[1] = 2 * (x * y - w * z);     m[2] = 2 * (x * z + w * y);
    m[3] = 2 * (x * y + w * z);     m[4] = 1 - 2 * (x * x + z * z); m[5] = 2 * (y * z - w * x);
    m[6] = 2 * (x * z - w * y);     m[7] = 2 * (y * z + w * x);     m[8] = 1 - 2 * (x * x + y * y);
}

GSV_API void gsv_matrix_to_quat(const gsv_real m[9], gsv_real q[4]) {
    /* Shepperd: pivot on the largest of 4w^2, 4x^2, 4y^2, 4z^2; result with w >= 0 */
    gsv_real tr = m[0] + m[4] + m[8];
    gsv_real cand[4];
    gsv_real s, len;
    int i, k = 0;
    cand[0] = 1 + 2 * m[0] - tr; cand[1] = 1 + 2 * m[4] - tr;
    cand[2] = 1 + 2 * m[8] - tr; cand[3] = 1 + tr;
    for (i = 1; i < 4; ++i) if (cand[i] > cand[k]) k = i;
    s = 2 * GSV_SQRT(cand[k] > 0 ? cand[k] : 0);
    if (s <= 0) { q[0] = q[1] = q[2] = 0; q[3] = 1; return; }
    if (k == 3) {
        q[0] = (m[7] - m[5]) / s; q[1] = (m[2] - m[6]) / s; q[2] = (m[3] - m[1]) / s; q[3] = s / 4;
    } else if (k == 0) {
        q[0] = s / 4; q[1] = (m[1] + m[3]) / s; q[2] = (m[2] + m[6]) / s; q[3] = (m[7] - m[5]) / s;
    } else if (k == 1) {
        q[0] = (m[1] + m[3]) / s; q[1] = s / 4; q[2] = (m[5] + m[7]) / s; q[3] = (m[2] - m[6]) / s;
    } else {
        q[0] = (m[2] + m[6]) / s; q[1] = (m[5] + m[7]) / s; q[2] = s / 4; q[3] = (m[3] - m[1]) / s;
    }
    len = GSV_SQRT(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (q[3] < 0) len = -len;
    for (i = 0; i < 4; ++i) q[i] /= len;
}

/* cov6 = M M^T for a row-major 3x3 M */
static void gsv__outer(const gsv_real m[9], float cov6[6]) {
    static const int rs[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
    int j;
    for (j = 0; j < 6; ++j) {
        const gsv_real *a = m + 3 * rs[j][0], *b = m + 3 * rs[j][1];
        cov6[j] = (float)(a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
    }
}

GSV_API void gsv_rot_scale_to_cov(const float q[4], const float s[3], float cov6[6]) {
    gsv_real qq[4], r[9], m[9];
    int i, j;
    for (i = 0; i < 4; ++i) qq[i] = q[i];
    gsv_quat_to_matrix(qq, r);
    for (i = 0; i < 3; ++i) for (j = 0; j < 3; ++j) m[3 * i + j] = r[3 * i + j] * (gsv_real)s[j];
    gsv__outer(m, cov6);
}

/* Symmetric 3x3 eigen-decomposition (cyclic Jacobi, double): a is destroyed, v gets the
   eigenvectors as columns (row-major), d the eigenvalues. */
static void gsv__jacobi(double a[9], double v[9], double d[3]) {
    int sweep, p, q, i;
    for (i = 0; i < 9; ++i) v[i] = (i % 4 == 0) ? 1.0 : 0.0;
    for (sweep = 0; sweep < 64; ++sweep) {
        double off = fabs(a[1]) + fabs(a[2]) + fabs(a[5]);
        double diag = fabs(a[0]) + fabs(a[4]) + fabs(a[8]);
        if (off <= 1e-300 || off <= 1e-17 * diag) break;
        for (p = 0; p < 2; ++p) {
            for (q = p + 1; q < 3; ++q) {
                double apq = a[3 * p + q], app, aqq, theta, t, c, s;
                int k;
                if (apq == 0.0) continue;
                app = a[3 * p + p]; aqq = a[3 * q + q];
                theta = (aqq - app) / (2.0 * apq);
                t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                c = 1.0 / sqrt(t * t + 1.0);
                s = t * c;
                for (k = 0; k < 3; ++k) {          /* A <- J^T A J */
                    double akp = a[3 * k + p], akq = a[3 * k + q];
                    a[3 * k + p] = c * akp - s * akq;
                    a[3 * k + q] = s * akp + c * akq;
                }
                for (k = 0; k < 3; ++k) {
                    double apk = a[3 * p + k], aqk = a[3 * q + k];
                    a[3 * p + k] = c * apk - s * aqk;
                    a[3 * q + k] = s * apk + c * aqk;
                }
                for (k = 0; k < 3; ++k) {          /* V <- V J */
                    double vkp = v[3 * k + p], vkq = v[3 * k + q];
                    v[3 * k + p] = c * vkp - s * vkq;
                    v[3 * k + q] = s * vkp + c * vkq;
                }
            }
        }
    }
    d[0] = a[0]; d[1] = a[4]; d[2] = a[8];
}

GSV_API void gsv_cov_to_rot_scale(const float cov6[6], float q[4], float s[3]) {
    double a[9], v[9], d[3], det;
    gsv_real m[9], qq[4];
    int i;
    a[0] = cov6[0]; a[1] = cov6[1]; a[2] = cov6[2];
    a[3] = cov6[1]; a[4] = cov6[3]; a[5] = cov6[4];
    a[6] = cov6[2]; a[7] = cov6[4]; a[8] = cov6[5];
    gsv__jacobi(a, v, d);
    det = v[0] * (v[4] * v[8] - v[5] * v[7]) - v[1] * (v[3] * v[8] - v[5] * v[6])
        + v[2] * (v[3] * v[7] - v[4] * v[6]);
    if (det < 0) { v[2] = -v[2]; v[5] = -v[5]; v[8] = -v[8]; }   /* proper rotation */
    for (i = 0; i < 9; ++i) m[i] = (gsv_real)v[i];
    gsv_matrix_to_quat(m, qq);
    for (i = 0; i < 4; ++i) q[i] = (float)qq[i];
    for (i = 0; i < 3; ++i) s[i] = (float)sqrt(d[i] > 0 ? d[i] : 0.0);
}

GSV_API void gsv_local_splats(const gsv_local_face *cur, size_t n, const uint32_t *face,
                              const float *bary, const float *offset, const float *rotation,
                              const float *scale, int law, float *means, float *cov6,
                              float *rotations, float *scales) {
    size_t i;
    for (i = 0; i < n; ++i) {
        const gsv_local_face *f = cur + face[i];
        gsv_real b1 = bary[2 * i], b2 = bary[2 * i + 1], d = offset[i];
        gsv_real q[4], rl[9], l[9], m[9];
        const gsv_real *a;
        gsv_real ak[9];
        int r, c, j;
        /* mean = v0 + b1 e1 + b2 e2 + d m: the small part first, the corner last */
        for (j = 0; j < 3; ++j) {
            gsv_real rel = b1 * f->e1[j] + b2 * f->e2[j] + d * f->m[j];
            means[3 * i + j] = (float)(f->o[j] + rel);
        }
        for (j = 0; j < 4; ++j) q[j] = rotation[4 * i + j];
        gsv_quat_to_matrix(q, rl);
        for (r = 0; r < 3; ++r)                    /* L = R_l S_l */
            for (c = 0; c < 3; ++c) l[3 * r + c] = rl[3 * r + c] * (gsv_real)scale[3 * i + c];
        if (law == GSV_RIGID) {                    /* A = k R_c */
            for (j = 0; j < 9; ++j) ak[j] = f->k * f->r[j];
            a = ak;
        } else {
            a = f->a_aff;                          /* A = [E_c C_r^-1 | m] */
        }
        for (r = 0; r < 3; ++r)                    /* M = A L */
            for (c = 0; c < 3; ++c)
                m[3 * r + c] = a[3 * r] * l[c] + a[3 * r + 1] * l[3 + c] + a[3 * r + 2] * l[6 + c];
        gsv__outer(m, cov6 + 6 * i);
        if (rotations && scales) {
            if (law == GSV_RIGID) {                /* rotation R_c R_l, scales k s_l */
                gsv_real rot[9], qo[4];
                for (r = 0; r < 3; ++r)
                    for (c = 0; c < 3; ++c)
                        rot[3 * r + c] = f->r[3 * r] * rl[c] + f->r[3 * r + 1] * rl[3 + c]
                                       + f->r[3 * r + 2] * rl[6 + c];
                gsv_matrix_to_quat(rot, qo);
                for (j = 0; j < 4; ++j) rotations[4 * i + j] = (float)qo[j];
                for (j = 0; j < 3; ++j) scales[3 * i + j] = (float)(f->k * (gsv_real)scale[3 * i + j]);
            } else {
                gsv_cov_to_rot_scale(cov6 + 6 * i, rotations + 4 * i, scales + 3 * i);
            }
        }
    }
}

GSV_API void gsv_games_faces(const float *vertices, const uint32_t *indices, size_t face_count,
                             gsv_games_face *cur) {
    size_t f;
    for (f = 0; f < face_count; ++f) {
        const float *v0, *v1, *v2;
        gsv__corners(vertices, indices, f, &v0, &v1, &v2);
        gsv__edges(v0, v1, v2, cur[f].o, cur[f].e1, cur[f].e2);
        gsv__games(cur[f].e1, cur[f].e2, cur[f].r, cur[f].base);
    }
}

GSV_API void gsv_games_splats(const gsv_games_face *cur, size_t n, const uint32_t *face,
                              const float *bary, const float *rho, float *means, float *cov6,
                              float *rotations, float *scales) {
    size_t i;
    for (i = 0; i < n; ++i) {
        const gsv_games_face *f = cur + face[i];
        gsv_real a1 = bary[2 * i], a2 = bary[2 * i + 1], sc[3], m[9];
        int r, c, j;
        /* mean = a0 v0 + a1 v1 + a2 v2 = v0 + a1 e1 + a2 e2 */
        for (j = 0; j < 3; ++j) means[3 * i + j] = (float)(f->o[j] + (a1 * f->e1[j] + a2 * f->e2[j]));
        for (j = 0; j < 3; ++j) {                  /* scale_j = max(rho s_j, 0) + eps */
            gsv_real v = (gsv_real)rho[i] * f->base[j];
            sc[j] = (v > 0 ? v : 0) + (gsv_real)GSV_GAMES_EPS;
        }
        for (r = 0; r < 3; ++r) for (c = 0; c < 3; ++c) m[3 * r + c] = f->r[3 * r + c] * sc[c];
        gsv__outer(m, cov6 + 6 * i);
        if (rotations && scales) {
            gsv_real q[4];
            gsv_matrix_to_quat(f->r, q);
            for (j = 0; j < 4; ++j) rotations[4 * i + j] = (float)q[j];
            for (j = 0; j < 3; ++j) scales[3 * i + j] = (float)sc[j];
        }
    }
}

/* ---------------------------------------------------------------- reading and checking */

static uint32_t gsv__le(const unsigned char *p, int bytes) {
    uint32_t v = 0;
    int i;
    for (i = bytes - 1; i >= 0; --i) v = (v << 8) | p[i];
    return v;
}

GSV_API double gsv_dequantize(int32_t code, int component_type, int normalized) {
    double v = (double)code;
    if (!normalized) return v;
    switch (component_type) {
        case GSV_UNSIGNED_BYTE: return v / 255.0;
        case GSV_UNSIGNED_SHORT: return v / 65535.0;
        case GSV_BYTE: v /= 127.0; return v < -1.0 ? -1.0 : v;
        case GSV_SHORT: v /= 32767.0; return v < -1.0 ? -1.0 : v;
        default: return v;
    }
}

GSV_API int gsv_read_floats(const void *data, size_t stride, size_t count, int ncomp,
                            int component_type, int normalized, float *out) {
    const unsigned char *base = (const unsigned char *)data;
    size_t size, i;
    int j;
    switch (component_type) {
        case GSV_BYTE: case GSV_UNSIGNED_BYTE: size = 1; break;
        case GSV_SHORT: case GSV_UNSIGNED_SHORT: size = 2; break;
        case GSV_UNSIGNED_INT: case GSV_FLOAT: size = 4; break;
        default: return -1;
    }
    if (normalized && (component_type == GSV_FLOAT || component_type == GSV_UNSIGNED_INT))
        return -1;
    if (stride == 0) stride = size * (size_t)ncomp;
    for (i = 0; i < count; ++i) {
        for (j = 0; j < ncomp; ++j) {
            const unsigned char *p = base + i * stride + (size_t)j * size;
            uint32_t raw = gsv__le(p, (int)size);
            int32_t code;
            if (component_type == GSV_FLOAT) {
                union { uint32_t u; float f; } pun;
                pun.u = raw;
                out[i * (size_t)ncomp + (size_t)j] = pun.f;
                continue;
            }
            if (component_type == GSV_UNSIGNED_INT) {
                out[i * (size_t)ncomp + (size_t)j] = (float)raw;
                continue;
            }
            if (component_type == GSV_BYTE) code = (int32_t)(raw ^ 0x80u) - 0x80;
            else if (component_type == GSV_SHORT) code = (int32_t)(raw ^ 0x8000u) - 0x8000;
            else code = (int32_t)raw;
            out[i * (size_t)ncomp + (size_t)j] =
                (float)gsv_dequantize(code, component_type, normalized);
        }
    }
    return 0;
}

GSV_API int gsv_read_uints(const void *data, size_t stride, size_t count,
                           int component_type, uint32_t *out) {
    const unsigned char *base = (const unsigned char *)data;
    size_t size, i;
    switch (component_type) {
        case GSV_UNSIGNED_BYTE: size = 1; break;
        case GSV_UNSIGNED_SHORT: size = 2; break;
        case GSV_UNSIGNED_INT: size = 4; break;
        default: return -1;
    }
    if (stride == 0) stride = size;
    for (i = 0; i < count; ++i) out[i] = gsv__le(base + i * stride, (int)size);
    return 0;
}

GSV_API void gsv_normalize_quaternions(float *q, size_t count) {
    size_t i;
    for (i = 0; i < count; ++i) {
        float *p = q + 4 * i;
        double len = sqrt((double)p[0] * p[0] + (double)p[1] * p[1] + (double)p[2] * p[2]
                          + (double)p[3] * p[3]);
        if (len > 0) {
            p[0] = (float)(p[0] / len); p[1] = (float)(p[1] / len);
            p[2] = (float)(p[2] / len); p[3] = (float)(p[3] / len);
        } else {
            p[0] = p[1] = p[2] = 0; p[3] = 1;
        }
    }
}

GSV_API int gsv_anchor_accessor_allowed(int property, int ncomp, int component_type,
                                        int normalized) {
    int ct = component_type, nz = normalized ? 1 : 0;
    switch (property) {
        case GSV_PROP_FACE_INDEX:
        case GSV_PROP_FACE_COUNTS:
            return ncomp == 1 && !nz && (ct == GSV_UNSIGNED_BYTE || ct == GSV_UNSIGNED_SHORT
                                         || ct == GSV_UNSIGNED_INT);
        case GSV_PROP_BARYCENTRICS:
            return ncomp == 2 && ((ct == GSV_FLOAT && !nz)
                                  || (nz && (ct == GSV_UNSIGNED_BYTE || ct == GSV_UNSIGNED_SHORT)));
        case GSV_PROP_NORMAL_OFFSET:
        case GSV_PROP_RHO:
            return ncomp == 1 && ct == GSV_FLOAT && !nz;
        case GSV_PROP_LOCAL_ROTATION:
            return ncomp == 4 && ((ct == GSV_FLOAT && !nz)
                                  || (nz && (ct == GSV_BYTE || ct == GSV_SHORT)));
        case GSV_PROP_LOCAL_SCALE:
            return ncomp == 3 && ((ct == GSV_FLOAT && !nz) || ct == GSV_UNSIGNED_BYTE
                                  || ct == GSV_UNSIGNED_SHORT);
        default:
            return 0;
    }
}

GSV_API int gsv_check_face_indices(const uint32_t *face, size_t n, size_t face_count) {
    size_t i;
    for (i = 0; i < n; ++i) if ((size_t)face[i] >= face_count) return 0;
    return 1;
}

GSV_API int gsv_all_finite(const float *values, size_t count) {
    size_t i;
    for (i = 0; i < count; ++i) {
        float v = values[i];
        if (v != v || v - v != 0.0f) return 0;   /* NaN, or infinity (inf - inf is NaN) */
    }
    return 1;
}

/* 1 when no quaternion (count of them, 4 floats each) has zero length: a zero localRotation
   makes the asset invalid (spec v1.1). Check after dequantization, before normalization. */
GSV_API int gsv_check_quaternions_nonzero(const float *q, size_t count) {
    size_t i;
    for (i = 0; i < count; ++i) {
        const float *p = q + 4 * i;
        double n2 = (double)p[0] * p[0] + (double)p[1] * p[1] + (double)p[2] * p[2]
                  + (double)p[3] * p[3];
        if (n2 == 0.0) return 0;
    }
    return 1;
}

/* 1 when none of the count values is negative: a negative localScale component (after
   dequantization) makes the asset invalid (spec v1.1). -0 counts as zero. */
GSV_API int gsv_check_scales_nonnegative(const float *values, size_t count) {
    size_t i;
    for (i = 0; i < count; ++i) if (values[i] < 0.0f) return 0;
    return 1;
}

/* Per-splat face indices from faceCounts (version 1.2): splat i belongs to face f with
   S_f <= i < S_{f+1}, S_f the sum of the counts before f. Returns 0 (refuse the asset) when
   count_len differs from face_count or the counts, summed in 64-bit integers, differ from n;
   face (n entries) is written only up to n. */
GSV_API int gsv_faces_from_counts(const uint32_t *counts, size_t count_len, size_t face_count,
                                  size_t n, uint32_t *face) {
    uint64_t total = 0;
    size_t f, i = 0;
    uint32_t c;
    if (count_len != face_count) return 0;
    for (f = 0; f < face_count; ++f) total += counts[f];
    if (total != (uint64_t)n) return 0;
    for (f = 0; f < face_count; ++f)
        for (c = 0; c < counts[f]; ++c) face[i++] = (uint32_t)f;
    return 1;
}

/* Shepperd's quaternion (x, y, z, w; w >= 0) of a row-major rotation matrix, in double. */
static void gsv__matrix_to_quat_d(const double m[9], double q[4]) {
    double tr = m[0] + m[4] + m[8], cand[4], s, len;
    int i, k = 0;
    cand[0] = 1 + 2 * m[0] - tr; cand[1] = 1 + 2 * m[4] - tr;
    cand[2] = 1 + 2 * m[8] - tr; cand[3] = 1 + tr;
    for (i = 1; i < 4; ++i) if (cand[i] > cand[k]) k = i;
    s = 2 * sqrt(cand[k] > 0 ? cand[k] : 0);
    if (k == 3) {
        q[0] = (m[7] - m[5]) / s; q[1] = (m[2] - m[6]) / s; q[2] = (m[3] - m[1]) / s; q[3] = s / 4;
    } else if (k == 0) {
        q[0] = s / 4; q[1] = (m[1] + m[3]) / s; q[2] = (m[2] + m[6]) / s; q[3] = (m[7] - m[5]) / s;
    } else if (k == 1) {
        q[0] = (m[1] + m[3]) / s; q[1] = s / 4; q[2] = (m[5] + m[7]) / s; q[3] = (m[2] - m[6]) / s;
    } else {
        q[0] = (m[2] + m[6]) / s; q[1] = (m[5] + m[7]) / s; q[2] = s / 4; q[3] = (m[3] - m[1]) / s;
    }
    len = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (q[3] < 0) len = -len;
    for (i = 0; i < 4; ++i) q[i] /= len;
}

/* Derived local anchors (version 1.2, spec Derived local anchors), in double precision in
   every build: for splat i on face f with rest frame R_r = [t | b | n], edge matrix C_r and
   first corner v0, (x, y, z) = R_r^T (mu - v0), b2 = y / C_r[1,1],
   b1 = (x - C_r[0,1] b2) / C_r[0,0], d = z, q_l = conj(q_r) (x) q (q normalized; Hamilton,
   x y z w). Writes bary[2n], offset[n], rotation[4n]; returns 0 (refuse the asset) when a
   splat's face is degenerate at rest (a <= eps_deg l^2: C_r is singular). */
GSV_API int gsv_derive_local(const float *rest_vertices, const uint32_t *indices, size_t n,
                             const uint32_t *face, const float *means, const float *rotations,
                             float *bary, float *offset, float *rotation) {
    double r[9], c[3], qr[4], area2;
    const float *v0 = NULL, *v1, *v2;
    size_t s;
    for (s = 0; s < n; ++s) {
        const float *q = rotations + 4 * s;
        double rel[3], qq[4], x, y, z, b2, len;
        int i;
        /* the face's rest frame (gsv_prepare_rest's), once per run of splats on one face */
        if (s == 0 || face[s] != face[s - 1]) {
            gsv__corners(rest_vertices, indices, face[s], &v0, &v1, &v2);
            if (!gsv__rest_frame_double(v0, v1, v2, r, c, &area2)) return 0;
            gsv__matrix_to_quat_d(r, qr);
        }
        for (i = 0; i < 3; ++i) rel[i] = (double)means[3 * s + i] - (double)v0[i];
        /* (x, y, z) = R_r^T (mu - v0): the dot products with the columns t, b, n */
        x = rel[0] * r[0] + rel[1] * r[3] + rel[2] * r[6];
        y = rel[0] * r[1] + rel[1] * r[4] + rel[2] * r[7];
        z = rel[0] * r[2] + rel[1] * r[5] + rel[2] * r[8];
        b2 = y / c[2];
        bary[2 * s] = (float)((x - c[1] * b2) / c[0]);
        bary[2 * s + 1] = (float)b2;
        offset[s] = (float)z;
        len = sqrt((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2]
                   + (double)q[3] * q[3]);
        for (i = 0; i < 4; ++i) qq[i] = len > 0 ? (double)q[i] / len : (i == 3 ? 1.0 : 0.0);
        /* conj(q_r) (x) q */
        {
            double ax = -qr[0], ay = -qr[1], az = -qr[2], aw = qr[3];
            double ox = aw * qq[0] + ax * qq[3] + ay * qq[2] - az * qq[1];
            double oy = aw * qq[1] - ax * qq[2] + ay * qq[3] + az * qq[0];
            double oz = aw * qq[2] + ax * qq[1] - ay * qq[0] + az * qq[3];
            double ow = aw * qq[3] - ax * qq[0] - ay * qq[1] - az * qq[2];
            if (ow < 0) { ox = -ox; oy = -oy; oz = -oz; ow = -ow; }
            rotation[4 * s] = (float)ox; rotation[4 * s + 1] = (float)oy;
            rotation[4 * s + 2] = (float)oz; rotation[4 * s + 3] = (float)ow;
        }
    }
    return 1;
}

GSV_API int gsv_splat_local(const float *deformed, size_t vertex_count, const double m[16],
                            float *out) {
    /* column-major: element (row r, column c) is m[4c + r]; A = upper 3x3, t = m[12..14] */
    double a[9], inv[9], det;
    size_t i;
    int r, c;
    for (c = 0; c < 3; ++c)
        for (r = 0; r < 3; ++r) a[3 * r + c] = m[4 * c + r];
    for (i = 0; i < 16; ++i)
        if (!(m[i] - m[i] == 0.0)) return 0;   /* NaN or infinity */
    inv[0] = a[4] * a[8] - a[5] * a[7];
    inv[1] = a[2] * a[7] - a[1] * a[8];
    inv[2] = a[1] * a[5] - a[2] * a[4];
    inv[3] = a[5] * a[6] - a[3] * a[8];
    inv[4] = a[0] * a[8] - a[2] * a[6];
    inv[5] = a[2] * a[3] - a[0] * a[5];
    inv[6] = a[3] * a[7] - a[4] * a[6];
    inv[7] = a[1] * a[6] - a[0] * a[7];
    inv[8] = a[0] * a[4] - a[1] * a[3];
    det = a[0] * inv[0] + a[1] * inv[3] + a[2] * inv[6];
    if (det == 0.0 || !(det - det == 0.0)) return 0;
    for (i = 0; i < 9; ++i) inv[i] /= det;
    for (i = 0; i < vertex_count; ++i) {
        double x = (double)deformed[3 * i] - m[12];
        double y = (double)deformed[3 * i + 1] - m[13];
        double z = (double)deformed[3 * i + 2] - m[14];
        for (r = 0; r < 3; ++r)
            out[3 * i + r] = (float)(inv[3 * r] * x + inv[3 * r + 1] * y + inv[3 * r + 2] * z);
    }
    return 1;
}

#ifdef __cplusplus
}
#endif

#endif /* GSV_REMAP_IMPLEMENTED */
#endif /* GSV_REMAP_IMPLEMENTATION */
