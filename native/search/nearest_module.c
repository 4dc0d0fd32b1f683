/*
 * gsverse_format.nearest._native: the C search of gsverse_nearest.h as a CPython extension.
 *
 * Four functions, called by gsverse_format/nearest/native.py (which checks and converts the
 * arguments first; the checks here only keep a wrong call from reading or writing out of
 * bounds):
 *
 *   build(V, F, idx, degenerate_ratio, threads) -> tree (a capsule)
 *   sort_queries(P, order, Ps)          coarse Morton order of P into order, P[order] into Ps
 *                                       (P float64 or float32; Ps float64)
 *   query(tree, Ps, order, lo, hi, margin, threads, face, distance, closest, barycentric,
 *         level)                        the queries, by the loop compiled for `level`
 *                                       (closest and barycentric both None: not computed)
 *   level() -> the widest instruction level this CPU runs: 0 generic, 1 AVX2, 2 AVX-512F
 *             (x86-64 with GCC or clang; elsewhere always 0)
 *
 * Arrays are C-contiguous float64 ('d') or int64 buffers (sort_queries also reads float32
 * points). The work runs without the interpreter lock, on `threads` POSIX threads (the
 * calling thread among them) that take build
 * tasks and blocks of 64 consecutive queries from a shared counter, so a thread kept off its
 * core delays only the block it holds.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <pthread.h>
#include <stdint.h>
#include <string.h>

#define GSV_NEAREST_IMPLEMENTATION
#define GSV_NEAREST_STATIC
#include "gsverse_nearest.h"

#define TASKS 32          /* the top of the tree is split until this many subtrees remain */
#define BLOCK 64          /* consecutive (sorted) queries a thread takes at once */
#define ORDER_BITS 6      /* Morton grid of the query order: 2^6 cells per axis */
#define MAX_THREADS 256

static const char *CAPSULE = "gsverse_format.nearest._native.tree";

/* ------------------------------------------------------------------ buffers */

static int is_int64(const Py_buffer *b)
{
    const char *f = b->format ? b->format : "B";
    if (*f == '=' || *f == '<' || *f == '@') f++;
    return b->itemsize == 8 && (strcmp(f, "l") == 0 || strcmp(f, "q") == 0);
}

static int is_float64(const Py_buffer *b)
{
    const char *f = b->format ? b->format : "B";
    if (*f == '=' || *f == '<' || *f == '@') f++;
    return b->itemsize == 8 && strcmp(f, "d") == 0;
}

/* A C-contiguous buffer of `n` 8-byte items (n < 0: any multiple of `multiple`). */
static int get(PyObject *o, Py_buffer *b, int writable, int is_float, Py_ssize_t n,
               Py_ssize_t multiple, const char *name)
{
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(o, b, flags) < 0) return -1;
    if (!(is_float ? is_float64(b) : is_int64(b))) {
        PyErr_Format(PyExc_TypeError, "%s must be a %s buffer", name,
                     is_float ? "float64" : "int64");
        PyBuffer_Release(b);
        return -1;
    }
    if ((n >= 0 && b->len != n * 8) || (n < 0 && (b->len / 8) % multiple != 0)) {
        PyErr_Format(PyExc_ValueError, "%s has the wrong size", name);
        PyBuffer_Release(b);
        return -1;
    }
    return 0;
}

static void release(Py_buffer *bufs, int n)
{
    int i;
    for (i = 0; i < n; i++) PyBuffer_Release(&bufs[i]);
}

/* ------------------------------------------------------------------ threads */

typedef struct {
    void (*work)(void *ctx, int64_t item);
    void *ctx;
    int64_t items;
    int64_t counter;
} pool;

static void *pool_worker(void *arg)
{
    pool *p = (pool *)arg;
    for (;;) {
        int64_t i = __atomic_fetch_add(&p->counter, 1, __ATOMIC_RELAXED);
        if (i >= p->items) break;
        p->work(p->ctx, i);
    }
    return NULL;
}

/* work(ctx, i) for every i < items on up to `threads` threads; the calling thread takes part,
 * so the work is done even when no thread can be started. */
static void run_pool(void (*work)(void *, int64_t), void *ctx, int64_t items, int threads)
{
    pthread_t tid[MAX_THREADS];
    int started = 0, i;
    pool p;
    p.work = work; p.ctx = ctx; p.items = items; p.counter = 0;
    if (threads > MAX_THREADS) threads = MAX_THREADS;
    if ((int64_t)threads > items) threads = (int)items;
    for (i = 1; i < threads; i++) {
        if (pthread_create(&tid[started], NULL, pool_worker, &p) != 0) break;
        started++;
    }
    pool_worker(&p);
    for (i = 0; i < started; i++) pthread_join(tid[i], NULL);
}

/* ------------------------------------------------------------------ build */

typedef struct {
    gsv_nearest_tree *t;
    const double *V;
    const int64_t *F;
} build_ctx;

static void build_one(void *ctx, int64_t i)
{
    build_ctx *c = (build_ctx *)ctx;
    gsv_nearest_build_task(c->t, c->V, c->F, i);
}

static void tree_free(PyObject *capsule)
{
    gsv_nearest_tree *t = (gsv_nearest_tree *)PyCapsule_GetPointer(capsule, CAPSULE);
    if (t) {
        gsv_nearest_free(t);
        PyMem_RawFree(t);
    }
}

static PyObject *build(PyObject *self, PyObject *args)
{
    PyObject *oV, *oF, *oi, *capsule;
    Py_buffer b[3];
    double ratio;
    int threads, failed = 0;
    Py_ssize_t nv, nfaces, nf, k;
    gsv_nearest_tree *t;
    build_ctx c;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOdi", &oV, &oF, &oi, &ratio, &threads)) return NULL;
    if (get(oV, &b[0], 0, 1, -1, 3, "vertices") < 0) return NULL;
    if (get(oF, &b[1], 0, 0, -1, 3, "faces") < 0) { release(b, 1); return NULL; }
    if (get(oi, &b[2], 0, 0, -1, 1, "idx") < 0) { release(b, 2); return NULL; }
    nv = b[0].len / 24; nfaces = b[1].len / 24; nf = b[2].len / 8;
    for (k = 0; k < 3 * nfaces && !failed; k++) {
        int64_t v = ((const int64_t *)b[1].buf)[k];
        failed = v < 0 || v >= nv;
    }
    for (k = 0; k < nf && !failed; k++) {
        int64_t f = ((const int64_t *)b[2].buf)[k];
        failed = f < 0 || f >= nfaces;
    }
    if (failed || nf == 0) {
        release(b, 3);
        PyErr_SetString(PyExc_ValueError, nf == 0 ? "no selectable faces" : "index out of range");
        return NULL;
    }
    t = (gsv_nearest_tree *)PyMem_RawMalloc(sizeof *t);
    if (!t || gsv_nearest_alloc(t, nf) < 0) {
        PyMem_RawFree(t);
        release(b, 3);
        return PyErr_NoMemory();
    }
    c.t = t; c.V = (const double *)b[0].buf; c.F = (const int64_t *)b[1].buf;
    Py_BEGIN_ALLOW_THREADS
    {
        int64_t n = gsv_nearest_build_top(t, c.V, c.F, (const int64_t *)b[2].buf, ratio, TASKS);
        run_pool(build_one, &c, n, threads);
        gsv_nearest_build_finish(t);
    }
    Py_END_ALLOW_THREADS
    release(b, 3);
    capsule = PyCapsule_New(t, CAPSULE, tree_free);
    if (!capsule) {
        gsv_nearest_free(t);
        PyMem_RawFree(t);
    }
    return capsule;
}

/* ------------------------------------------------------------------ query order */

/* The Morton code of a grid cell: bit `bit` of (gx, gy, gz) at bit 3 bit + (0, 1, 2). */
static uint32_t spread_bits(int64_t g)
{
    uint32_t out = 0;
    int bit;
    for (bit = 0; bit < ORDER_BITS; bit++) out |= (uint32_t)((g >> bit) & 1) << (3 * bit);
    return out;
}

/* The counting sort of sort_queries over points of type T (float or double): the cells' codes
 * into keys, the order, and the sorted points as double. */
#define SORT_POINTS(NAME, T)                                                                 \
static void NAME(const T *P, int64_t n, int64_t *order, double *Ps, uint32_t *keys,        \
                 int64_t *count)                                                             \
{                                                                                            \
    const int64_t cells = (int64_t)1 << ORDER_BITS, n_codes = (int64_t)1 << (3 * ORDER_BITS); \
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}; \
    double inv[3] = {0.0, 0.0, 0.0};                                                         \
    uint32_t spread[1 << ORDER_BITS];                                                        \
    int64_t i, c;                                                                            \
    int d;                                                                                   \
    for (c = 0; c < cells; c++) spread[c] = spread_bits(c);                                  \
    for (i = 0; i < n; i++)                                                                  \
        for (d = 0; d < 3; d++) {                                                            \
            lo[d] = gsv__min(lo[d], (double)P[3 * i + d]);                                   \
            hi[d] = gsv__max(hi[d], (double)P[3 * i + d]);                                   \
        }                                                                                    \
    for (d = 0; d < 3; d++)                                                                  \
        if (hi[d] > lo[d]) inv[d] = ((double)cells - 1e-3) / (hi[d] - lo[d]);                \
    for (i = 0; i < n; i++) {                                                                \
        uint32_t code = 0;                                                                   \
        for (d = 0; d < 3; d++) {                                                            \
            int64_t g = (int64_t)gsv__min(gsv__max(((double)P[3 * i + d] - lo[d]) * inv[d],  \
                                                   0.0), (double)cells - 1.0);               \
            code |= spread[g] << d;                                                          \
        }                                                                                    \
        keys[i] = code;                                                                      \
        count[code + 1]++;                                                                   \
    }                                                                                        \
    for (c = 0; c < n_codes; c++) count[c + 1] += count[c];                                  \
    for (i = 0; i < n; i++) order[count[keys[i]]++] = i;                                     \
    for (i = 0; i < n; i++)                                                                  \
        for (d = 0; d < 3; d++) Ps[3 * i + d] = (double)P[3 * order[i] + d];                 \
}

SORT_POINTS(sort_points_f32, float)
SORT_POINTS(sort_points_f64, double)

static int is_float32(const Py_buffer *b)
{
    const char *f = b->format ? b->format : "B";
    if (*f == '=' || *f == '<' || *f == '@') f++;
    return b->itemsize == 4 && strcmp(f, "f") == 0;
}

static PyObject *sort_queries(PyObject *self, PyObject *args)
{
    PyObject *oP, *oo, *os;
    Py_buffer b[3];
    Py_ssize_t n;
    int64_t *count;
    uint32_t *keys;
    int f32;
    const int64_t n_codes = (int64_t)1 << (3 * ORDER_BITS);
    (void)self;
    if (!PyArg_ParseTuple(args, "OOO", &oP, &oo, &os)) return NULL;
    /* the points: float64, or float32 (converted exactly as they are read) */
    if (PyObject_GetBuffer(oP, &b[0], PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) return NULL;
    f32 = is_float32(&b[0]);
    if (!f32 && !is_float64(&b[0])) {
        PyErr_SetString(PyExc_TypeError, "points must be a float64 or float32 buffer");
        release(b, 1);
        return NULL;
    }
    if ((b[0].len / b[0].itemsize) % 3 != 0) {
        PyErr_SetString(PyExc_ValueError, "points has the wrong size");
        release(b, 1);
        return NULL;
    }
    n = b[0].len / b[0].itemsize / 3;
    if (get(oo, &b[1], 1, 0, n, 1, "order") < 0) { release(b, 1); return NULL; }
    if (get(os, &b[2], 1, 1, 3 * n, 1, "sorted points") < 0) { release(b, 2); return NULL; }
    keys = (uint32_t *)PyMem_RawMalloc((size_t)(n > 0 ? n : 1) * sizeof(uint32_t));
    count = (int64_t *)PyMem_RawCalloc((size_t)n_codes + 1, sizeof(int64_t));
    if (!keys || !count) {
        PyMem_RawFree(keys); PyMem_RawFree(count);
        release(b, 3);
        return PyErr_NoMemory();
    }
    Py_BEGIN_ALLOW_THREADS
    if (f32)
        sort_points_f32((const float *)b[0].buf, n, (int64_t *)b[1].buf, (double *)b[2].buf,
                        keys, count);
    else
        sort_points_f64((const double *)b[0].buf, n, (int64_t *)b[1].buf, (double *)b[2].buf,
                        keys, count);
    Py_END_ALLOW_THREADS
    PyMem_RawFree(keys);
    PyMem_RawFree(count);
    release(b, 3);
    Py_RETURN_NONE;
}

/* ------------------------------------------------------------------ queries */

typedef struct {
    const gsv_nearest_tree *t;
    double margin;
    const double *P;
    const int64_t *order;
    int64_t lo, hi;
    int64_t *face;
    double *distance, *closest, *bary;   /* closest and bary: NULL when not asked for */
} query_ctx;

static void query_run(const query_ctx *c, int64_t blk)
{
    const gsv_nearest_tree *t = c->t;
    int64_t st_node[GSV_NEAREST_STACK], i, start = c->lo + blk * BLOCK;
    double st_lb[GSV_NEAREST_STACK];
    int64_t stop = start + BLOCK < c->hi ? start + BLOCK : c->hi;
    for (i = start; i < stop; i++) {
        const double *p = c->P + 3 * i;
        double v, w, d2;
        int64_t k = gsv_nearest_search(t, c->margin, p[0], p[1], p[2], st_node, st_lb,
                                       &v, &w, &d2);
        const double *r = t->rec + GSV_NEAREST_RECORD * k;
        int64_t q = c->order[i];
        c->face[q] = t->face[k];
        c->distance[q] = sqrt(d2);
        if (c->closest) {
            c->closest[3 * q] = r[0] + v * r[3] + w * r[6];
            c->closest[3 * q + 1] = r[1] + v * r[4] + w * r[7];
            c->closest[3 * q + 2] = r[2] + v * r[5] + w * r[8];
            c->bary[3 * q] = gsv__max(1.0 - v - w, 0.0);
            c->bary[3 * q + 1] = v;
            c->bary[3 * q + 2] = w;
        }
    }
}

static void query_block(void *ctx, int64_t blk) { query_run((const query_ctx *)ctx, blk); }

/* The same loop compiled for wider instruction sets (levels 1 and 2), everything it calls
 * inlined into it (flatten): the operations and their order are the C source's, only the
 * instructions differ, so the results are the same bits (-ffp-contract=off still forbids fused
 * multiply-adds). Measured on 1M points and 100k faces, one thread: 0.66 s generic, 0.58 s
 * AVX2, 0.48 s AVX-512F. */
#if defined(__x86_64__) && defined(__GNUC__) && defined(__has_attribute)
#if __has_attribute(target) && __has_attribute(flatten)
#define LEVELS 3
__attribute__((target("avx2"), flatten))
static void query_block_avx2(void *ctx, int64_t blk) { query_run((const query_ctx *)ctx, blk); }
__attribute__((target("avx512f"), flatten))
static void query_block_avx512f(void *ctx, int64_t blk) { query_run((const query_ctx *)ctx, blk); }
#endif
#endif
#ifndef LEVELS
#define LEVELS 1
#endif

/* The widest level this CPU runs: 0 generic, 1 AVX2, 2 AVX-512F. */
static int supported_level(void)
{
#if LEVELS > 1
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx512f")) return 2;
    if (__builtin_cpu_supports("avx2")) return 1;
#endif
    return 0;
}

static PyObject *level(PyObject *self, PyObject *args)
{
    (void)self; (void)args;
    return PyLong_FromLong(supported_level());
}

static PyObject *query(PyObject *self, PyObject *args)
{
    PyObject *cap, *oP, *oo, *of, *od, *oc, *ob;
    Py_buffer b[6];
    Py_ssize_t lo, hi, n, i;
    double margin;
    int threads, lvl, nb, bad = 0;
    query_ctx c;
    void (*work)(void *, int64_t) = query_block;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOnndiOOOOi", &cap, &oP, &oo, &lo, &hi, &margin, &threads,
                          &of, &od, &oc, &ob, &lvl)) return NULL;
    if (lvl < 0 || lvl > supported_level()) {
        PyErr_SetString(PyExc_ValueError, "instruction level not supported here");
        return NULL;
    }
#if LEVELS > 1
    if (lvl == 1) work = query_block_avx2;
    if (lvl == 2) work = query_block_avx512f;
#endif
    c.t = (const gsv_nearest_tree *)PyCapsule_GetPointer(cap, CAPSULE);
    if (!c.t) return NULL;
    if (get(oP, &b[0], 0, 1, -1, 3, "points") < 0) return NULL;
    n = b[0].len / 24;
    if (get(oo, &b[1], 0, 0, n, 1, "order") < 0) { release(b, 1); return NULL; }
    if (get(of, &b[2], 1, 0, n, 1, "face") < 0) { release(b, 2); return NULL; }
    if (get(od, &b[3], 1, 1, n, 1, "distance") < 0) { release(b, 3); return NULL; }
    nb = 4;
    if (oc != Py_None || ob != Py_None) {         /* the closest points: both or neither */
        if (get(oc, &b[4], 1, 1, 3 * n, 1, "closest") < 0) { release(b, 4); return NULL; }
        if (get(ob, &b[5], 1, 1, 3 * n, 1, "barycentric") < 0) { release(b, 5); return NULL; }
        nb = 6;
    }
    c.order = (const int64_t *)b[1].buf;
    if (lo < 0 || hi > n || lo > hi) {
        release(b, nb);
        PyErr_SetString(PyExc_ValueError, "bad query range");
        return NULL;
    }
    for (i = lo; i < hi && !bad; i++) bad = c.order[i] < 0 || c.order[i] >= n;
    if (bad) {
        release(b, nb);
        PyErr_SetString(PyExc_ValueError, "order out of range");
        return NULL;
    }
    c.margin = margin; c.P = (const double *)b[0].buf; c.lo = lo; c.hi = hi;
    c.face = (int64_t *)b[2].buf; c.distance = (double *)b[3].buf;
    c.closest = nb == 6 ? (double *)b[4].buf : NULL;
    c.bary = nb == 6 ? (double *)b[5].buf : NULL;
    Py_BEGIN_ALLOW_THREADS
    run_pool(work, &c, (hi - lo + BLOCK - 1) / BLOCK, threads);
    Py_END_ALLOW_THREADS
    release(b, nb);
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"build", build, METH_VARARGS,
     "build(V, F, idx, degenerate_ratio, threads): the BVH over faces F[idx] (a capsule)."},
    {"sort_queries", sort_queries, METH_VARARGS,
     "sort_queries(P, order, Ps): coarse Morton order of the points (float64 or float32), and "
     "the sorted points (float64)."},
    {"query", query, METH_VARARGS,
     "query(tree, Ps, order, lo, hi, margin, threads, face, distance, closest, barycentric, "
     "level): nearest faces of Ps[lo:hi], written to rows order[lo:hi] of the outputs "
     "(closest and barycentric may both be None), by the loop compiled for instruction level "
     "`level` (at most level())."},
    {"level", level, METH_NOARGS,
     "level(): the widest instruction level of the query loop this CPU runs (0 generic, 1 "
     "AVX2, 2 AVX-512F)."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_native",
    "The exact nearest-triangle search in C (native/search/gsverse_nearest.h).", -1, methods,
    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__native(void) { return PyModule_Create(&module); }
