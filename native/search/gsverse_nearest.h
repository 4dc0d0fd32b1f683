/*
 * gsverse_nearest.h -- exact nearest-triangle search (point -> closest triangle of a mesh), the
 * search that binds splats to faces.
 *
 * Portable C99, header-only: it includes <math.h>, <stdint.h>, <stdlib.h> and <string.h>,
 * keeps no global state and starts no threads (the caller hands the independent pieces of work,
 * build tasks and blocks of queries, to its own threads). It compiles as C99 and as C++.
 *
 * USAGE
 *   In exactly one C or C++ file:
 *       #define GSV_NEAREST_IMPLEMENTATION
 *       #include "gsverse_nearest.h"
 *   Define GSV_NEAREST_STATIC as well to make every function static.
 *
 *   gsv_nearest_tree t;
 *   gsv_nearest_alloc(&t, nf);                       nf selectable faces; -1 when out of memory
 *   n = gsv_nearest_build_top(&t, V, F, idx, 32);    the top of the tree, n independent tasks
 *   for i in 0..n-1 (any thread, any order):  gsv_nearest_build_task(&t, V, F, i);
 *   gsv_nearest_build_finish(&t);
 *   for each query point p (any thread; each thread its own stack of GSV_NEAREST_STACK):
 *       k = gsv_nearest_search(&t, margin, px, py, pz, st_node, st_lb, &v, &w, &d2);
 *       face t.face[k], closest point a + v ab + w ac of record k, distance sqrt(d2)
 *   gsv_nearest_free(&t);
 *
 *   V: double[3 * vertices]; F: int64_t[3 * faces] (indices checked by the caller); idx:
 *   int64_t[nf], the selectable faces. The tree keeps no pointer to V, F or idx.
 *
 * RESULT
 *   For every point: a face whose double-precision distance to the point is exactly the
 *   minimum over the selectable faces (the value of a brute-force scan with the kernel below),
 *   the smallest input face index among faces at exactly that distance. This is the result of
 *   gsverse_format.nearest.reference, bit for bit, when margin and degenerate_ratio are its
 *   MARGIN and DEGENERATE_RATIO: the kernel (gsv_nearest_record, gsv_nearest_closest) is a
 *   transcription of the reference kernel in the same order of floating-point operations. Build
 *   without value-changing optimisations (no -ffast-math; -ffp-contract=off, so that no multiply
 *   and add are fused).
 *
 * SEARCH
 *   One binary BVH over the selectable faces: median splits of the centroids along their
 *   widest axis, leaf boundaries at multiples of 4 faces (leaf j holds positions 4j .. 4j + 3);
 *   each inner node stores its two children's boxes rounded outwards to float. Three lower
 *   bounds prune: a child's box, a leaf's slab (a unit normal and the range of n.x over its
 *   corners) and a face's own box. A subtree, leaf or face is skipped only when its bound
 *   exceeds (d* + m)^2, with d* the best distance so far and m = margin (|q|inf + S + d*)
 *   (S the largest magnitude of a vertex coordinate of the selectable faces): computed
 *   distances and bounds differ from the true values by less than m, so every face whose
 *   computed distance equals the minimum is evaluated.
 */
#ifndef GSVERSE_NEAREST_H
#define GSVERSE_NEAREST_H

#include <stdint.h>

#ifdef GSV_NEAREST_STATIC
#define GSV_NEAREST_DEF static
#else
#define GSV_NEAREST_DEF extern
#endif

#ifdef __cplusplus
extern "C" {
#endif

#define GSV_NEAREST_LEAF 4      /* faces per leaf */
#define GSV_NEAREST_STACK 128   /* traversal stack entries (the depth is at most ~log2(nf / 4) + 1) */
#define GSV_NEAREST_RECORD 16   /* doubles per face record: a, ab, ac, e_v, e_w, degenerate */

typedef struct {
    int64_t nf;            /* selectable faces (positions) */
    int64_t n_inner;       /* inner nodes: max(leaves - 1, 0) */
    int64_t n_leaves;
    int64_t root;          /* 0, or -1 (leaf 0) when nf <= GSV_NEAREST_LEAF */
    double scale;          /* largest |coordinate| of a selectable face's corner */
    double *rec;           /* nf * 16: kernel constants in tree order */
    int64_t *face;         /* nf: input face index of each position */
    int64_t *child;        /* n_inner * 2: >= 0 inner node, < 0 leaf -ref - 1 */
    float *cbox;           /* n_inner * 12: children's boxes (lo xyz, hi xyz) x 2 */
    double *slab;          /* n_leaves * 5: unit normal, min and max of n.x */
    /* build state */
    double degenerate_ratio;
    double *cent;          /* nf * 3 */
    double *leafbox;       /* n_leaves * 6 */
    double *own;           /* n_inner * 6 */
    int64_t *top;          /* inner nodes split by gsv_nearest_build_top, in order */
    int64_t n_top;
    int64_t *task;         /* (node or -1, start, count) per task */
    int64_t n_task;
} gsv_nearest_tree;

GSV_NEAREST_DEF int gsv_nearest_alloc(gsv_nearest_tree *t, int64_t nf);
GSV_NEAREST_DEF void gsv_nearest_free(gsv_nearest_tree *t);
GSV_NEAREST_DEF int64_t gsv_nearest_build_top(gsv_nearest_tree *t, const double *V,
                                              const int64_t *F, const int64_t *idx,
                                              double degenerate_ratio, int64_t max_tasks);
GSV_NEAREST_DEF void gsv_nearest_build_task(gsv_nearest_tree *t, const double *V,
                                            const int64_t *F, int64_t i);
GSV_NEAREST_DEF void gsv_nearest_build_finish(gsv_nearest_tree *t);
GSV_NEAREST_DEF void gsv_nearest_record(const double *V, const int64_t *F, int64_t f,
                                        double degenerate_ratio, double *r, double *normal);
GSV_NEAREST_DEF double gsv_nearest_closest(const double *r, double px, double py, double pz,
                                           double *v, double *w);
GSV_NEAREST_DEF int64_t gsv_nearest_search(const gsv_nearest_tree *t, double margin,
                                           double px, double py, double pz,
                                           int64_t *st_node, double *st_lb,
                                           double *v, double *w, double *d2);

#ifdef __cplusplus
}
#endif
#endif /* GSVERSE_NEAREST_H */

#ifdef GSV_NEAREST_IMPLEMENTATION
#ifndef GSV_NEAREST_IMPLEMENTED
#define GSV_NEAREST_IMPLEMENTED

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Python's min and max of two numbers: the first unless the second compares below (above) it.
 * The reference and the compiled search use these; NaN and signed zeros follow them. */
static double gsv__min(double a, double b) { return b < a ? b : a; }
static double gsv__max(double a, double b) { return b > a ? b : a; }
static double gsv__min3(double a, double b, double c) { return gsv__min(gsv__min(a, b), c); }
static double gsv__max3(double a, double b, double c) { return gsv__max(gsv__max(a, b), c); }
static double gsv__clip01(double x) { return gsv__min(gsv__max(x, 0.0), 1.0); }
/* numpy's maximum of two numbers: NaN when either is NaN. */
static double gsv__nanmax(double a, double b)
{
    if (a != a || b != b) return NAN;
    return a >= b ? a : b;
}
/* A float not above (below) x: the nearest one, stepped outwards when it rounded the other way. */
static float gsv__f32_down(double x)
{
    float f = (float)x;
    if ((double)f > x) f = nextafterf(f, -INFINITY);
    return f;
}
static float gsv__f32_up(double x)
{
    float f = (float)x;
    if ((double)f < x) f = nextafterf(f, INFINITY);
    return f;
}

GSV_NEAREST_DEF int gsv_nearest_alloc(gsv_nearest_tree *t, int64_t nf)
{
    int64_t nl = (nf + GSV_NEAREST_LEAF - 1) / GSV_NEAREST_LEAF;
    int64_t ni = nl > 1 ? nl - 1 : 0;
    size_t n = (size_t)(nf > 0 ? nf : 1), l = (size_t)(nl > 0 ? nl : 1);
    size_t k = (size_t)(ni > 0 ? ni : 1);
    memset(t, 0, sizeof *t);
    t->nf = nf;
    t->n_leaves = nl;
    t->n_inner = ni;
    t->rec = (double *)malloc(n * GSV_NEAREST_RECORD * sizeof(double));
    t->face = (int64_t *)malloc(n * sizeof(int64_t));
    t->child = (int64_t *)malloc(k * 2 * sizeof(int64_t));
    t->cbox = (float *)malloc(k * 12 * sizeof(float));
    t->slab = (double *)malloc(l * 5 * sizeof(double));
    t->cent = (double *)malloc(n * 3 * sizeof(double));
    t->leafbox = (double *)malloc(l * 6 * sizeof(double));
    t->own = (double *)malloc(k * 6 * sizeof(double));
    t->top = (int64_t *)malloc(k * sizeof(int64_t));
    t->task = (int64_t *)malloc((k + l + 1) * 6 * sizeof(int64_t));
    if (!t->rec || !t->face || !t->child || !t->cbox || !t->slab || !t->cent || !t->leafbox
        || !t->own || !t->top || !t->task) {
        gsv_nearest_free(t);
        return -1;
    }
    return 0;
}

GSV_NEAREST_DEF void gsv_nearest_free(gsv_nearest_tree *t)
{
    free(t->rec); free(t->face); free(t->child); free(t->cbox); free(t->slab);
    free(t->cent); free(t->leafbox); free(t->own); free(t->top); free(t->task);
    memset(t, 0, sizeof *t);
}

/* ------------------------------------------------------------------ kernel */

GSV_NEAREST_DEF void gsv_nearest_record(const double *V, const int64_t *F, int64_t f,
                                        double degenerate_ratio, double *r, double *normal)
{
    const double *A = V + 3 * F[3 * f], *B = V + 3 * F[3 * f + 1], *C = V + 3 * F[3 * f + 2];
    double ax = A[0], ay = A[1], az = A[2];
    double abx = B[0] - ax, aby = B[1] - ay, abz = B[2] - az;
    double acx = C[0] - ax, acy = C[1] - ay, acz = C[2] - az;
    double abab = abx * abx + aby * aby + abz * abz;
    double acac = acx * acx + acy * acy + acz * acz;
    double nx = aby * acz - abz * acy;
    double ny = abz * acx - abx * acz;
    double nz = abx * acy - aby * acx;
    double nn = nx * nx + ny * ny + nz * nz;
    double bcx = acx - abx, bcy = acy - aby, bcz = acz - abz;
    double lmax2 = gsv__nanmax(gsv__nanmax(abab, acac), bcx * bcx + bcy * bcy + bcz * bcz);
    double th = degenerate_ratio * lmax2;
    int regular = isfinite(nn) && nn > th * th;
    double inv = regular ? 1.0 / nn : 0.0;
    r[0] = ax; r[1] = ay; r[2] = az;
    r[3] = abx; r[4] = aby; r[5] = abz;
    r[6] = acx; r[7] = acy; r[8] = acz;
    r[9] = (acy * nz - acz * ny) * inv;
    r[10] = (acz * nx - acx * nz) * inv;
    r[11] = (acx * ny - acy * nx) * inv;
    r[12] = (ny * abz - nz * aby) * inv;
    r[13] = (nz * abx - nx * abz) * inv;
    r[14] = (nx * aby - ny * abx) * inv;
    r[15] = regular ? 0.0 : 1.0;
    normal[0] = nx; normal[1] = ny; normal[2] = nz;
}

/* Closest point among the three edges, as (v, w). */
static void gsv__segments(double apx, double apy, double apz, double abx, double aby,
                          double abz, double acx, double acy, double acz, double abab,
                          double acac, double *v, double *w)
{
    double t1 = abab > 0 ? (abx * apx + aby * apy + abz * apz) / abab : 0.0;
    double ex, ey, ez, best, d2, t2, t3, bcx, bcy, bcz, bpx, bpy, bpz, bcbc;
    t1 = gsv__clip01(t1);
    ex = apx - t1 * abx; ey = apy - t1 * aby; ez = apz - t1 * abz;
    best = ex * ex + ey * ey + ez * ez;
    *v = t1; *w = 0.0;
    t2 = acac > 0 ? (acx * apx + acy * apy + acz * apz) / acac : 0.0;
    t2 = gsv__clip01(t2);
    ex = apx - t2 * acx; ey = apy - t2 * acy; ez = apz - t2 * acz;
    d2 = ex * ex + ey * ey + ez * ez;
    if (d2 < best) {
        best = d2;
        *v = 0.0; *w = t2;
    }
    bcx = acx - abx; bcy = acy - aby; bcz = acz - abz;
    bpx = apx - abx; bpy = apy - aby; bpz = apz - abz;
    bcbc = bcx * bcx + bcy * bcy + bcz * bcz;
    t3 = bcbc > 0 ? (bcx * bpx + bcy * bpy + bcz * bpz) / bcbc : 0.0;
    t3 = gsv__clip01(t3);
    ex = bpx - t3 * bcx; ey = bpy - t3 * bcy; ez = bpz - t3 * bcz;
    d2 = ex * ex + ey * ey + ez * ez;
    if (d2 < best) {
        *v = 1.0 - t3; *w = t3;
    }
}

GSV_NEAREST_DEF double gsv_nearest_closest(const double *r, double px, double py, double pz,
                                           double *pv, double *pw)
{
    double ax = r[0], ay = r[1], az = r[2];
    double abx = r[3], aby = r[4], abz = r[5];
    double acx = r[6], acy = r[7], acz = r[8];
    double apx = px - ax, apy = py - ay, apz = pz - az;
    double abab = abx * abx + aby * aby + abz * abz;
    double acac = acx * acx + acy * acy + acz * acz;
    double v, w, cx, cy, cz, ex, ey, ez;
    if (r[15] != 0.0) {
        gsv__segments(apx, apy, apz, abx, aby, abz, acx, acy, acz, abab, acac, &v, &w);
    } else {
        double abac = abx * acx + aby * acy + abz * acz;
        double d1 = abx * apx + aby * apy + abz * apz;
        double d2 = acx * apx + acy * apy + acz * apz;
        double d3 = d1 - abab;
        double d4 = d2 - abac;
        double d5 = d1 - abac;
        double d6 = d2 - acac;
        if (d1 <= 0 && d2 <= 0) {                                        /* vertex A */
            v = 0.0; w = 0.0;
        } else if (d3 >= 0 && d4 <= d3) {                                /* vertex B */
            v = 1.0; w = 0.0;
        } else if ((d1 * d4 - d3 * d2) <= 0 && d1 >= 0 && d3 <= 0) {     /* edge AB */
            double den = d1 - d3;
            v = gsv__clip01(den > 0 ? d1 / den : 0.0); w = 0.0;
        } else if (d6 >= 0 && d5 <= d6) {                                /* vertex C */
            v = 0.0; w = 1.0;
        } else if ((d5 * d2 - d1 * d6) <= 0 && d2 >= 0 && d6 <= 0) {     /* edge AC */
            double den = d2 - d6;
            v = 0.0; w = gsv__clip01(den > 0 ? d2 / den : 0.0);
        } else {
            double e43 = d4 - d3, e56 = d5 - d6;
            if ((d3 * d6 - d5 * d4) <= 0 && e43 >= 0 && e56 >= 0) {     /* edge BC */
                double den = e43 + e56;
                double t = gsv__clip01(den > 0 ? e43 / den : 0.0);
                v = 1.0 - t; w = t;
            } else {                                                     /* face */
                v = apx * r[9] + apy * r[10] + apz * r[11];
                w = apx * r[12] + apy * r[13] + apz * r[14];
                if (!(v >= 0 && w >= 0 && v + w <= 1))
                    gsv__segments(apx, apy, apz, abx, aby, abz, acx, acy, acz, abab, acac,
                                  &v, &w);
            }
        }
    }
    cx = ax + v * abx + w * acx;
    cy = ay + v * aby + w * acy;
    cz = az + v * abz + w * acz;
    ex = px - cx; ey = py - cy; ez = pz - cz;
    *pv = v; *pw = w;
    return ex * ex + ey * ey + ez * ez;
}

/* ------------------------------------------------------------------ hierarchy */

/* Partial sort of positions lo..hi (inclusive) by cent[., axis]: position kth gets its order
 * statistic, smaller keys before it and larger after (face indices move along). */
static void gsv__select(double *cent, int64_t *perm, int64_t lo, int64_t hi, int64_t kth,
                        int axis)
{
    while (hi > lo) {
        int64_t mid = (lo + hi) >> 1, i = lo, j = hi;
        double a = cent[3 * lo + axis], b = cent[3 * mid + axis], c = cent[3 * hi + axis], pivot;
        if (a > b) { double s = a; a = b; b = s; }
        if (b > c) {
            b = c;
            if (a > b) b = a;
        }
        pivot = b;
        while (i <= j) {
            while (cent[3 * i + axis] < pivot) i++;
            while (cent[3 * j + axis] > pivot) j--;
            if (i <= j) {
                int d;
                int64_t s;
                for (d = 0; d < 3; d++) {
                    double x = cent[3 * i + d];
                    cent[3 * i + d] = cent[3 * j + d];
                    cent[3 * j + d] = x;
                }
                s = perm[i]; perm[i] = perm[j]; perm[j] = s;
                i++;
                j--;
            }
        }
        if (kth <= j) hi = j;
        else if (kth >= i) lo = i;
        else return;
    }
}

/* Split inner node `node` (positions s .. s+n-1) into its children: out = (lref, ls, ln, rref,
 * rs, rn). Inner nodes are numbered in preorder; a child ref < 0 is leaf -ref - 1. */
static void gsv__split(gsv_nearest_tree *t, int64_t node, int64_t s, int64_t n, int64_t *out)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    double e0, e1, e2;
    int64_t i, m, lm, left, right, lref, rref;
    int axis = 0, d;
    for (i = s; i < s + n; i++)
        for (d = 0; d < 3; d++) {
            double x = t->cent[3 * i + d];
            lo[d] = gsv__min(lo[d], x);
            hi[d] = gsv__max(hi[d], x);
        }
    e0 = hi[0] - lo[0]; e1 = hi[1] - lo[1]; e2 = hi[2] - lo[2];
    if (e1 > e0 && e1 >= e2) axis = 1;
    else if (e2 > e0 && e2 > e1) axis = 2;
    m = (n + GSV_NEAREST_LEAF - 1) / GSV_NEAREST_LEAF;
    lm = (m + 1) / 2;
    left = lm * GSV_NEAREST_LEAF;
    gsv__select(t->cent, t->face, s, s + n - 1, s + left, axis);
    right = n - left;
    lref = left > GSV_NEAREST_LEAF ? node + 1 : -(s / GSV_NEAREST_LEAF) - 1;
    rref = right > GSV_NEAREST_LEAF ? node + lm : -((s + left) / GSV_NEAREST_LEAF) - 1;
    t->child[2 * node] = lref;
    t->child[2 * node + 1] = rref;
    out[0] = lref; out[1] = s; out[2] = left;
    out[3] = rref; out[4] = s + left; out[5] = right;
}

/* Records of leaf j's faces, the leaf's box and its slab. */
static void gsv__leaf(gsv_nearest_tree *t, const double *V, const int64_t *F, int64_t j)
{
    int64_t end = j * GSV_NEAREST_LEAF + GSV_NEAREST_LEAF, k;
    double *box = t->leafbox + 6 * j, *slab = t->slab + 5 * j;
    double sx = 0.0, sy = 0.0, sz = 0.0, norm, nx, ny, nz, hmin, hmax;
    int d, c;
    if (end > t->nf) end = t->nf;
    for (d = 0; d < 6; d++) box[d] = d < 3 ? INFINITY : -INFINITY;
    for (k = j * GSV_NEAREST_LEAF; k < end; k++) {
        int64_t f = t->face[k];
        double nrm[3];
        gsv_nearest_record(V, F, f, t->degenerate_ratio, t->rec + GSV_NEAREST_RECORD * k, nrm);
        sx += nrm[0]; sy += nrm[1]; sz += nrm[2];
        for (d = 0; d < 3; d++) {
            double x0 = V[3 * F[3 * f] + d], x1 = V[3 * F[3 * f + 1] + d];
            double x2 = V[3 * F[3 * f + 2] + d];
            box[d] = gsv__min(box[d], gsv__min3(x0, x1, x2));
            box[3 + d] = gsv__max(box[3 + d], gsv__max3(x0, x1, x2));
        }
    }
    norm = sqrt(sx * sx + sy * sy + sz * sz);
    if (!(norm > 0 && isfinite(norm))) {
        for (d = 0; d < 5; d++) slab[d] = 0.0;             /* no usable normal: bound 0 */
        return;
    }
    nx = sx / norm; ny = sy / norm; nz = sz / norm;
    hmin = INFINITY; hmax = -INFINITY;
    for (k = j * GSV_NEAREST_LEAF; k < end; k++) {
        int64_t f = t->face[k];
        for (c = 0; c < 3; c++) {
            const double *p = V + 3 * F[3 * f + c];
            double h = nx * p[0] + ny * p[1] + nz * p[2];
            hmin = gsv__min(hmin, h);
            hmax = gsv__max(hmax, h);
        }
    }
    slab[0] = nx; slab[1] = ny; slab[2] = nz; slab[3] = hmin; slab[4] = hmax;
}

/* Children's boxes of inner node k (float, rounded outwards) and its own box. */
static void gsv__node_box(gsv_nearest_tree *t, int64_t k)
{
    int side, d;
    double *own = t->own + 6 * k;
    float *cb = t->cbox + 12 * k;
    for (side = 0; side < 2; side++) {
        int64_t ref = t->child[2 * k + side];
        const double *b = ref >= 0 ? t->own + 6 * ref : t->leafbox + 6 * (-ref - 1);
        for (d = 0; d < 3; d++) {
            cb[6 * side + d] = gsv__f32_down(b[d]);
            cb[6 * side + 3 + d] = gsv__f32_up(b[3 + d]);
        }
        if (side == 0) {
            for (d = 0; d < 6; d++) own[d] = b[d];
        } else {
            for (d = 0; d < 3; d++) {
                own[d] = gsv__min(own[d], b[d]);
                own[3 + d] = gsv__max(own[3 + d], b[3 + d]);
            }
        }
    }
}

GSV_NEAREST_DEF int64_t gsv_nearest_build_top(gsv_nearest_tree *t, const double *V,
                                              const int64_t *F, const int64_t *idx,
                                              double degenerate_ratio, int64_t max_tasks)
{
    /* Breadth-first queue of inner nodes in the first half of t->task (triples), leaves made
     * by the top splits in its second half; each half holds n_inner + n_leaves + 1 triples. */
    int64_t nf = t->nf, k, head = 0, tail = 0, n_leaf = 0, cap = t->n_inner + t->n_leaves + 1;
    int64_t *q = t->task, *lv = t->task + 3 * cap, out[6];
    int d;
    t->degenerate_ratio = degenerate_ratio;
    for (k = 0; k < nf; k++) {
        const int64_t f = idx[k];
        t->face[k] = f;
        for (d = 0; d < 3; d++)
            t->cent[3 * k + d] = (V[3 * F[3 * f] + d] + V[3 * F[3 * f + 1] + d]
                                  + V[3 * F[3 * f + 2] + d]) / 3.0;
    }
    t->n_top = 0;
    t->root = nf > GSV_NEAREST_LEAF ? 0 : -1;
    if (nf > GSV_NEAREST_LEAF) {
        q[0] = 0; q[1] = 0; q[2] = nf;
        tail = 1;
    } else {
        lv[0] = -1; lv[1] = 0; lv[2] = nf;
        n_leaf = 1;
    }
    while (head < tail && tail - head < max_tasks) {
        int side;
        gsv__split(t, q[3 * head], q[3 * head + 1], q[3 * head + 2], out);
        t->top[t->n_top++] = q[3 * head];
        head++;
        for (side = 0; side < 2; side++) {
            int64_t ref = out[3 * side], s0 = out[3 * side + 1], n0 = out[3 * side + 2];
            if (ref >= 0) {
                q[3 * tail] = ref; q[3 * tail + 1] = s0; q[3 * tail + 2] = n0;
                tail++;
            } else {
                int64_t *e = lv + 3 * n_leaf;
                e[0] = -1; e[1] = s0; e[2] = n0;
                n_leaf++;
            }
        }
    }
    /* tasks: the queue's remaining subtrees, then the leaves, packed at the start */
    memmove(q, q + 3 * head, (size_t)(tail - head) * 3 * sizeof(int64_t));
    memcpy(q + 3 * (tail - head), lv, (size_t)n_leaf * 3 * sizeof(int64_t));
    t->n_task = tail - head + n_leaf;
    return t->n_task;
}

GSV_NEAREST_DEF void gsv_nearest_build_task(gsv_nearest_tree *t, const double *V,
                                            const int64_t *F, int64_t i)
{
    int64_t node = t->task[3 * i], s = t->task[3 * i + 1], n = t->task[3 * i + 2], j, k;
    if (node >= 0) {
        int64_t st[3 * GSV_NEAREST_STACK], out[6];
        int sp = 1;
        st[0] = node; st[1] = s; st[2] = n;
        while (sp > 0) {
            sp--;
            gsv__split(t, st[3 * sp], st[3 * sp + 1], st[3 * sp + 2], out);
            if (out[3] >= 0) {
                st[3 * sp] = out[3]; st[3 * sp + 1] = out[4]; st[3 * sp + 2] = out[5];
                sp++;
            }
            if (out[0] >= 0) {
                st[3 * sp] = out[0]; st[3 * sp + 1] = out[1]; st[3 * sp + 2] = out[2];
                sp++;
            }
        }
    }
    for (j = s / GSV_NEAREST_LEAF; j < (s + n + GSV_NEAREST_LEAF - 1) / GSV_NEAREST_LEAF; j++)
        gsv__leaf(t, V, F, j);
    if (node >= 0)
        for (k = node + (n + GSV_NEAREST_LEAF - 1) / GSV_NEAREST_LEAF - 2; k >= node; k--)
            gsv__node_box(t, k);
}

GSV_NEAREST_DEF void gsv_nearest_build_finish(gsv_nearest_tree *t)
{
    int64_t i, j;
    double scale = 0.0;
    for (i = t->n_top - 1; i >= 0; i--) gsv__node_box(t, t->top[i]);
    for (j = 0; j < 6 * t->n_leaves; j++) scale = gsv__max(scale, fabs(t->leafbox[j]));
    t->scale = scale;
}

/* ------------------------------------------------------------------ search */

static double gsv__box_dist2(const float *b, double px, double py, double pz)
{
    double dx = gsv__max(gsv__max((double)b[0] - px, 0.0), px - (double)b[3]);
    double dy = gsv__max(gsv__max((double)b[1] - py, 0.0), py - (double)b[4]);
    double dz = gsv__max(gsv__max((double)b[2] - pz, 0.0), pz - (double)b[5]);
    return dx * dx + dy * dy + dz * dz;
}

/* Distance to the box of the corners a, a + ab, a + ac of a record. */
static double gsv__face_box_dist2(const double *r, double px, double py, double pz)
{
    double x0 = r[0], y0 = r[1], z0 = r[2];
    double x1 = x0 + r[3], y1 = y0 + r[4], z1 = z0 + r[5];
    double x2 = x0 + r[6], y2 = y0 + r[7], z2 = z0 + r[8];
    double dx = gsv__max(gsv__max(gsv__min3(x0, x1, x2) - px, 0.0), px - gsv__max3(x0, x1, x2));
    double dy = gsv__max(gsv__max(gsv__min3(y0, y1, y2) - py, 0.0), py - gsv__max3(y0, y1, y2));
    double dz = gsv__max(gsv__max(gsv__min3(z0, z1, z2) - pz, 0.0), pz - gsv__max3(z0, z1, z2));
    return dx * dx + dy * dy + dz * dz;
}

/* Four times the squared distance to the centre of a box. */
static double gsv__centre_dist2(const float *b, double px, double py, double pz)
{
    double dx = 2.0 * px - (double)b[0] - (double)b[3];
    double dy = 2.0 * py - (double)b[1] - (double)b[4];
    double dz = 2.0 * pz - (double)b[2] - (double)b[5];
    return dx * dx + dy * dy + dz * dz;
}

/* d2 > best2 * GAP implies sqrt(d2) > sqrt(best2) after rounding. */
#define GSV__SQRT_GAP (1.0 + 4e-15)

GSV_NEAREST_DEF int64_t gsv_nearest_search(const gsv_nearest_tree *t, double margin,
                                           double px, double py, double pz,
                                           int64_t *st_node, double *st_lb,
                                           double *pv, double *pw, double *pd2)
{
    const int64_t nf = t->nf, none = -((int64_t)1 << 62);
    double qabs = gsv__max(gsv__max(fabs(px), fabs(py)), fabs(pz)) + t->scale;
    double best = INFINITY, best2 = INFINITY, bv = 0.0, bw = 0.0, thr2 = INFINITY;
    int64_t bface = INT64_MAX, bpos = -1, node = t->root;
    int sp = 0;
    for (;;) {
        if (node >= 0) {
            const float *cb = t->cbox + 12 * node;
            const int64_t *ch = t->child + 2 * node;
            double lb0 = gsv__box_dist2(cb, px, py, pz), lb1 = gsv__box_dist2(cb + 6, px, py, pz);
            int ok0 = lb0 <= thr2, ok1 = lb1 <= thr2;
            if (ok0 && ok1) {
                /* nearer box first; on a tie (typically inside both) the nearer box centre */
                if (lb0 < lb1 || (lb0 == lb1 && gsv__centre_dist2(cb, px, py, pz)
                                                <= gsv__centre_dist2(cb + 6, px, py, pz))) {
                    st_node[sp] = ch[1]; st_lb[sp] = lb1; node = ch[0];
                } else {
                    st_node[sp] = ch[0]; st_lb[sp] = lb0; node = ch[1];
                }
                sp++;
                continue;
            }
            if (ok0) { node = ch[0]; continue; }
            if (ok1) { node = ch[1]; continue; }
        } else {
            int64_t j = -node - 1, k, end = j * GSV_NEAREST_LEAF + GSV_NEAREST_LEAF;
            const double *sl = t->slab + 5 * j;
            double h = sl[0] * px + sl[1] * py + sl[2] * pz;
            double dz = gsv__max(gsv__max(sl[3] - h, 0.0), h - sl[4]);
            if (end > nf) end = nf;
            if (dz * dz <= thr2) {
                for (k = j * GSV_NEAREST_LEAF; k < end; k++) {
                    const double *r = t->rec + GSV_NEAREST_RECORD * k;
                    double v, w, d2, d;
                    if (gsv__face_box_dist2(r, px, py, pz) > thr2) continue;
                    d2 = gsv_nearest_closest(r, px, py, pz, &v, &w);
                    if (d2 > best2 * GSV__SQRT_GAP) continue;   /* cannot win, not even tie */
                    d = sqrt(d2);
                    if (d < best || (d == best && t->face[k] < bface)) {
                        if (d < best) {            /* the square of d* + m */
                            double m = d + margin * (qabs + d);
                            thr2 = m * m;
                        }
                        best = d; best2 = d2; bface = t->face[k]; bpos = k; bv = v; bw = w;
                    }
                }
            }
        }
        /* pop the next subtree that may still hold a face within the threshold */
        node = none;
        while (sp > 0) {
            sp--;
            if (st_lb[sp] <= thr2) {
                node = st_node[sp];
                break;
            }
        }
        if (node == none) {
            *pv = bv; *pw = bw; *pd2 = best2;
            return bpos;
        }
    }
}

#endif /* GSV_NEAREST_IMPLEMENTED */
#endif /* GSV_NEAREST_IMPLEMENTATION */
