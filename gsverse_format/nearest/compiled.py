"""Compiled exact nearest-triangle search (numba), bit-identical to the numpy reference.

:func:`nearest_triangles_numba` answers the same question as the numpy reference
:func:`gsverse_format.nearest.reference.nearest_triangles_numpy` and returns the same
:class:`~gsverse_format.nearest.reference.NearestResult`, face for face and bit for bit; only
the search structure differs. Callers use :func:`gsverse_format.nearest.nearest_triangles`,
which picks one of the two (:mod:`gsverse_format.backend`).

Point–triangle distance
    The scalar kernel of :mod:`gsverse_format.nearest.compiled_kernel`, a transcription of the
    reference kernel in the same order of floating-point operations: each distance equals the
    reference's in float64.

Search and certificate
    One binary BVH over the selectable faces: median splits of the centroids along their widest
    axis, with leaf boundaries at multiples of 4 faces (so leaf ``j`` holds face positions
    ``4j .. 4j + 3`` and the tree is balanced); every inner node stores the axis-aligned boxes of
    both children, rounded outwards to float32. A box holds the corners of its triangles, hence
    the triangles, so the squared distance to the box is a lower bound of the distance to any of
    them; each leaf also has a slab (a unit normal and the range of ``n·x`` over its corners),
    and each face the box of its own corners, giving two more lower bounds. Queries are sorted
    along a coarse Morton curve (for cache locality) and handed to the threads in blocks of
    consecutive points; each point descends depth first, nearer child first. A subtree, leaf or
    face is skipped only when its bound exceeds ``d* + m`` (``d*`` the best distance so far)
    with the reference's margin ``m = 1e-11 (|q|∞ + S + d*)`` (``S`` the largest vertex
    coordinate magnitude). The kernel's closest point lies on its triangle up to the rounding of
    ``a + v ab + w ac``, so a computed distance is never below the true one by more than a few
    units of ``1e-16 (|q|∞ + S)``, and the bounds are never above it by more: every face whose
    computed distance equals the minimum is evaluated, and the result is the brute-force one.

Ties
    Among faces at exactly the minimal float64 distance, the smallest input face index wins, as
    in the reference. The result does not depend on ``chunk``, on the query order or on the
    number of threads.

Units are those of the input coordinates; all distance arithmetic is float64. Compiled code is
cached on disk (``cache=True``, next to this module or under ``NUMBA_CACHE_DIR``; see
:mod:`gsverse_format.nearest.compiled_kernel` and :mod:`gsverse_format.compiled_chunks` on
editing the functions this module inlines); the first call
in a fresh environment compiles it, which takes 10–20 s (:func:`warm_up` does it up front).
Throughput against other tools: ``python -m benchmarks.binding``.
"""
from __future__ import annotations

from typing import Callable

import numba
import numpy as np
from numba import njit, prange
from numpy.typing import ArrayLike

from ..backend import configure_numba
from ..compiled_chunks import chunk_count, fetch_add, next_chunk
from .compiled_kernel import RECORD_WIDTH, closest_point, f32_down, f32_up, face_record, max3, min3
from .reference import MARGIN, NearestResult, prepare_query

configure_numba()

__all__ = ["Tree", "nearest_triangles_numba", "build_tree", "query_tree", "warm_up"]

_LEAF = 4                 # faces per BVH leaf (leaf j holds positions 4j .. 4j + 3)
_BLOCK = 64               # consecutive (Morton-sorted) queries handed to a thread at once
_STACK = 128              # traversal stack depth (the tree depth is at most ~log2(F / 4) + 1)
_SPLIT_TASKS = 32         # the top of the tree is split until this many subtrees remain
_ORDER_BITS = 6           # Morton grid of the query sort: 2^6 cells per axis
_SQRT_GAP = 1.0 + 4e-15   # d2 > best2 * gap implies sqrt(d2) > sqrt(best2) after rounding


# --------------------------------------------------------------------------- hierarchy

@njit(cache=True, inline="always")
def _split_sizes(n):
    """Faces and leaves of the left part of a node of ``n`` faces (``n > _LEAF``)."""
    m = (n + _LEAF - 1) // _LEAF
    lm = (m + 1) // 2
    return lm * _LEAF, lm


@njit(cache=True)
def _select(cent, perm, lo, hi, kth, axis):
    """Partial sort of positions ``lo..hi`` (inclusive) by ``cent[:, axis]``: position ``kth``
    gets its order statistic, smaller keys before it and larger after (rows move with ``perm``)."""
    while hi > lo:
        mid = (lo + hi) >> 1
        a, b, c = cent[lo, axis], cent[mid, axis], cent[hi, axis]
        if a > b:
            a, b = b, a
        if b > c:
            b = c
            if a > b:
                b = a
        pivot = b
        i, j = lo, hi
        while i <= j:
            while cent[i, axis] < pivot:
                i += 1
            while cent[j, axis] > pivot:
                j -= 1
            if i <= j:
                for d in range(3):
                    cent[i, d], cent[j, d] = cent[j, d], cent[i, d]
                perm[i], perm[j] = perm[j], perm[i]
                i += 1
                j -= 1
        if kth <= j:
            hi = j
        elif kth >= i:
            lo = i
        else:
            return


@njit(cache=True)
def _split(cent, perm, child, node, s, n):
    """Reorder the faces of inner node ``node`` (positions ``s .. s+n-1``) into its children
    (median of the centroids along their widest axis) and link them.

    A child reference ``>= 0`` is an inner node, ``< 0`` is leaf ``-ref - 1``. Inner nodes are
    numbered in preorder, so the numbering follows from the face counts alone. Returns the
    two children as (ref, start, count) triples.
    """
    lo0, lo1, lo2 = np.inf, np.inf, np.inf
    hi0, hi1, hi2 = -np.inf, -np.inf, -np.inf
    for i in range(s, s + n):
        x, y, z = cent[i, 0], cent[i, 1], cent[i, 2]
        lo0, hi0 = min(lo0, x), max(hi0, x)
        lo1, hi1 = min(lo1, y), max(hi1, y)
        lo2, hi2 = min(lo2, z), max(hi2, z)
    e0, e1, e2 = hi0 - lo0, hi1 - lo1, hi2 - lo2
    axis = 0
    if e1 > e0 and e1 >= e2:
        axis = 1
    elif e2 > e0 and e2 > e1:
        axis = 2
    left, lm = _split_sizes(n)
    _select(cent, perm, s, s + n - 1, s + left, axis)
    right = n - left
    lref = node + 1 if left > _LEAF else -(s // _LEAF) - 1
    rref = node + lm if right > _LEAF else -((s + left) // _LEAF) - 1
    child[node, 0] = lref
    child[node, 1] = rref
    return lref, s, left, rref, s + left, right


@njit(cache=True)
def _leaf(V, F, face_of, j, rec, box, slab):
    """Records of the faces of leaf ``j``, and the leaf's box (lo, hi) and slab (unit normal
    ``n``, min and max of ``n·x`` over its corners)."""
    nf = face_of.shape[0]
    end = min(j * _LEAF + _LEAF, nf)
    for d in range(6):
        box[j, d] = np.inf if d < 3 else -np.inf
    sx, sy, sz = 0.0, 0.0, 0.0
    for k in range(j * _LEAF, end):
        f = face_of[k]
        nx, ny, nz = face_record(V, F, f, rec[k])
        sx += nx
        sy += ny
        sz += nz
        for d in range(3):
            x0, x1, x2 = V[F[f, 0], d], V[F[f, 1], d], V[F[f, 2], d]
            box[j, d] = min(box[j, d], min3(x0, x1, x2))
            box[j, 3 + d] = max(box[j, 3 + d], max3(x0, x1, x2))
    norm = np.sqrt(sx * sx + sy * sy + sz * sz)
    if not (norm > 0 and np.isfinite(norm)):
        for d in range(5):
            slab[j, d] = 0.0                       # no usable normal: the slab bound is 0
        return
    nx, ny, nz = sx / norm, sy / norm, sz / norm
    hmin, hmax = np.inf, -np.inf
    for k in range(j * _LEAF, end):
        f = face_of[k]
        for c in range(3):
            i = F[f, c]
            h = nx * V[i, 0] + ny * V[i, 1] + nz * V[i, 2]
            hmin, hmax = min(hmin, h), max(hmax, h)
    slab[j, 0], slab[j, 1], slab[j, 2] = nx, ny, nz
    slab[j, 3], slab[j, 4] = hmin, hmax


@njit(cache=True)
def _node_box(k, child, leafbox, own, cbox):
    """Children's boxes of inner node ``k`` (float32, rounded outwards) and its own box."""
    for side in range(2):
        ref = child[k, side]
        b = own[ref] if ref >= 0 else leafbox[-ref - 1]
        for d in range(3):
            cbox[k, 6 * side + d] = f32_down(b[d])
            cbox[k, 6 * side + 3 + d] = f32_up(b[3 + d])
        if side == 0:
            for d in range(6):
                own[k, d] = b[d]
        else:
            for d in range(3):
                own[k, d] = min(own[k, d], b[d])
                own[k, 3 + d] = max(own[k, 3 + d], b[3 + d])


@njit(cache=True)
def _build_top(V, F, idx, cent, perm, child, max_tasks):
    """Centroids, then the top of the tree split breadth first until ``max_tasks`` subtrees
    remain. Returns the top nodes (in order) and the tasks left: subtrees and single leaves,
    as (root node, start, count) with node -1 for a leaf."""
    nf = idx.shape[0]
    for k in range(nf):
        f = idx[k]
        for d in range(3):
            cent[k, d] = (V[F[f, 0], d] + V[F[f, 1], d] + V[F[f, 2], d]) / 3.0
    size = child.shape[0] + 1                        # inner nodes, and leaves
    q_node = np.empty(size, np.int64)                # breadth-first queue of inner nodes
    q_s = np.empty(size, np.int64)
    q_n = np.empty(size, np.int64)
    l_s = np.empty(size + 1, np.int64)               # leaves created by the top splits
    l_n = np.empty(size + 1, np.int64)
    top = np.empty(size, np.int64)
    n_top, n_leaf, head, tail = 0, 0, 0, 0
    if nf > _LEAF:
        q_node[0], q_s[0], q_n[0] = 0, 0, nf
        tail = 1
    else:
        l_s[0], l_n[0] = 0, nf
        n_leaf = 1
    while head < tail and tail - head < max_tasks:
        node = q_node[head]
        lref, ls, ln, rref, rs, rn = _split(cent, perm, child, node, q_s[head], q_n[head])
        head += 1
        top[n_top] = node
        n_top += 1
        for ref, s0, n0 in ((lref, ls, ln), (rref, rs, rn)):
            if ref >= 0:
                q_node[tail], q_s[tail], q_n[tail] = ref, s0, n0
                tail += 1
            else:
                l_s[n_leaf], l_n[n_leaf] = s0, n0
                n_leaf += 1
    m = tail - head
    t_node = np.full(m + n_leaf, -1, np.int64)
    t_s = np.empty(m + n_leaf, np.int64)
    t_n = np.empty(m + n_leaf, np.int64)
    t_node[:m], t_s[:m], t_n[:m] = q_node[head:tail], q_s[head:tail], q_n[head:tail]
    t_s[m:], t_n[m:] = l_s[:n_leaf], l_n[:n_leaf]
    return top[:n_top].copy(), t_node, t_s, t_n


@njit(cache=True)
def _build_task(V, F, cent, perm, child, rec, leafbox, slab, cbox, own, node, s, n):
    """One task: split the subtree of inner node ``node`` recursively (none for a leaf task,
    ``node < 0``), then compute its leaves and its node boxes bottom-up."""
    if node >= 0:
        st_node = np.empty(_STACK, np.int64)
        st_s = np.empty(_STACK, np.int64)
        st_n = np.empty(_STACK, np.int64)
        st_node[0], st_s[0], st_n[0] = node, s, n
        sp = 1
        while sp > 0:
            sp -= 1
            lref, ls, ln, rref, rs, rn = _split(cent, perm, child, st_node[sp], st_s[sp], st_n[sp])
            if rref >= 0:
                st_node[sp], st_s[sp], st_n[sp] = rref, rs, rn
                sp += 1
            if lref >= 0:
                st_node[sp], st_s[sp], st_n[sp] = lref, ls, ln
                sp += 1
    for j in range(s // _LEAF, (s + n + _LEAF - 1) // _LEAF):
        _leaf(V, F, perm, j, rec, leafbox, slab)
    if node >= 0:
        for k in range(node + (n + _LEAF - 1) // _LEAF - 2, node - 1, -1):
            _node_box(k, child, leafbox, own, cbox)


@njit(cache=True, parallel=True)
def _build_tasks(V, F, cent, perm, child, rec, leafbox, slab, cbox, own,
                 t_node, t_s, t_n, n_threads):
    """:func:`_build_task` for every task, handed out one at a time to the threads."""
    counter = np.zeros(1, np.int64)
    for _ in prange(n_threads):
        while True:
            i = fetch_add(counter, 1)
            if i >= t_node.shape[0]:
                break
            _build_task(V, F, cent, perm, child, rec, leafbox, slab, cbox, own,
                        t_node[i], t_s[i], t_n[i])


@njit(cache=True)
def _finish_top(child, leafbox, cbox, own, top):
    """Node boxes of the top of the tree; returns the largest magnitude of a vertex coordinate
    of the selectable faces."""
    for i in range(top.shape[0] - 1, -1, -1):
        _node_box(top[i], child, leafbox, own, cbox)
    scale = 0.0
    for j in range(leafbox.shape[0]):
        for d in range(6):
            scale = max(scale, abs(leafbox[j, d]))
    return scale


class Tree:
    """BVH over the selectable faces of a mesh (see the module docstring).

    ``rec`` (Fs, 16) float64 kernel constants in tree order, ``face`` (Fs,) int64 input face
    index of each position,
    ``child`` (K, 2) int64 child references of the inner nodes, ``cbox`` (K, 12) float32
    children's boxes, ``slab`` (L, 5) float64 leaf slabs, ``root`` the root reference and
    ``scale`` the largest magnitude of the selectable faces' vertex coordinates.
    """

    def __init__(self, rec: np.ndarray, face: np.ndarray, child: np.ndarray, cbox: np.ndarray,
                 slab: np.ndarray, root: int, scale: float) -> None:
        self.rec, self.face = rec, face
        self.child, self.cbox, self.slab = child, cbox, slab
        self.root, self.scale = int(root), float(scale)


def build_tree(vertices: ArrayLike, faces: ArrayLike, idx: ArrayLike) -> Tree:
    """BVH over faces ``faces[idx]`` of ``vertices`` (float64 (V, 3), int64 (F, 3))."""
    V = np.ascontiguousarray(vertices, dtype=np.float64)
    F = np.ascontiguousarray(faces, dtype=np.int64)
    idx = np.ascontiguousarray(idx, dtype=np.int64)
    nf = idx.shape[0]
    n_leaves = (nf + _LEAF - 1) // _LEAF
    n_inner = max(n_leaves - 1, 0)
    cent = np.empty((nf, 3))
    perm = idx.copy()
    child = np.empty((n_inner, 2), np.int64)
    top, t_node, t_s, t_n = _build_top(V, F, idx, cent, perm, child, _SPLIT_TASKS)
    rec = np.empty((nf, RECORD_WIDTH))
    leafbox = np.empty((n_leaves, 6))
    slab = np.empty((n_leaves, 5))
    cbox = np.empty((n_inner, 12), np.float32)
    own = np.empty((n_inner, 6))
    _build_tasks(V, F, cent, perm, child, rec, leafbox, slab, cbox, own, t_node, t_s, t_n,
                 numba.get_num_threads())
    scale = _finish_top(child, leafbox, cbox, own, top)
    return Tree(rec, perm, child, cbox, slab, 0 if nf > _LEAF else -1, scale)


# --------------------------------------------------------------------------- search

@njit(cache=True, inline="always")
def _box_dist2(b, o, px, py, pz):
    """Squared distance from ``p`` to the float32 box ``b[o:o+6]`` (lo, hi)."""
    dx = max(max(np.float64(b[o]) - px, 0.0), px - np.float64(b[o + 3]))
    dy = max(max(np.float64(b[o + 1]) - py, 0.0), py - np.float64(b[o + 4]))
    dz = max(max(np.float64(b[o + 2]) - pz, 0.0), pz - np.float64(b[o + 5]))
    return dx * dx + dy * dy + dz * dz


@njit(cache=True, inline="always")
def _face_box_dist2(r, px, py, pz):
    """Squared distance from ``p`` to the box of the corners ``a, a + ab, a + ac`` of record
    ``r`` (the triangle the kernel evaluates, up to the rounding of the sums)."""
    x0, y0, z0 = r[0], r[1], r[2]
    x1, y1, z1 = x0 + r[3], y0 + r[4], z0 + r[5]
    x2, y2, z2 = x0 + r[6], y0 + r[7], z0 + r[8]
    dx = max(max(min3(x0, x1, x2) - px, 0.0), px - max3(x0, x1, x2))
    dy = max(max(min3(y0, y1, y2) - py, 0.0), py - max3(y0, y1, y2))
    dz = max(max(min3(z0, z1, z2) - pz, 0.0), pz - max3(z0, z1, z2))
    return dx * dx + dy * dy + dz * dz


@njit(cache=True, inline="always")
def _centre_dist2(b, o, px, py, pz):
    """Four times the squared distance from ``p`` to the centre of the box ``b[o:o+6]``."""
    dx = 2.0 * px - np.float64(b[o]) - np.float64(b[o + 3])
    dy = 2.0 * py - np.float64(b[o + 1]) - np.float64(b[o + 4])
    dz = 2.0 * pz - np.float64(b[o + 2]) - np.float64(b[o + 5])
    return dx * dx + dy * dy + dz * dz


@njit(cache=True)
def _search(rec, face, child, cbox, slab, root, scale, px, py, pz, st_node, st_lb):
    """Nearest face to ``p`` (smallest input index on ties): ``(position, v, w, d²)``."""
    nf = rec.shape[0]
    qabs = max(max(abs(px), abs(py)), abs(pz)) + scale
    best = np.inf
    best2 = np.inf
    bface = np.iinfo(np.int64).max
    bpos, bv, bw = -1, 0.0, 0.0
    thr2 = np.inf
    node = root
    sp = 0
    while True:
        if node >= 0:
            lb0 = _box_dist2(cbox[node], 0, px, py, pz)
            lb1 = _box_dist2(cbox[node], 6, px, py, pz)
            ok0 = lb0 <= thr2
            ok1 = lb1 <= thr2
            if ok0 and ok1:
                # nearer box first; on a tie (typically inside both) the nearer box centre
                if lb0 < lb1 or (lb0 == lb1 and _centre_dist2(cbox[node], 0, px, py, pz)
                                 <= _centre_dist2(cbox[node], 6, px, py, pz)):
                    st_node[sp], st_lb[sp] = child[node, 1], lb1
                    node = child[node, 0]
                else:
                    st_node[sp], st_lb[sp] = child[node, 0], lb0
                    node = child[node, 1]
                sp += 1
                continue
            if ok0:
                node = child[node, 0]
                continue
            if ok1:
                node = child[node, 1]
                continue
        else:
            j = -node - 1
            sl = slab[j]
            h = sl[0] * px + sl[1] * py + sl[2] * pz
            dz = max(max(sl[3] - h, 0.0), h - sl[4])
            if dz * dz <= thr2:
                for k in range(j * _LEAF, min(j * _LEAF + _LEAF, nf)):
                    if _face_box_dist2(rec[k], px, py, pz) > thr2:
                        continue                   # the face's own box is too far
                    v, w, d2 = closest_point(rec[k], px, py, pz)
                    if d2 > best2 * _SQRT_GAP:
                        continue               # sqrt(d2) > best: cannot win, not even a tie
                    d = np.sqrt(d2)
                    if d < best or (d == best and face[k] < bface):
                        if d < best:
                            thr2 = _threshold2(d, qabs)
                        best, best2, bface, bpos, bv, bw = d, d2, face[k], k, v, w
        # pop the next subtree that may still hold a face within the threshold
        node = -(1 << 62)
        while sp > 0:
            sp -= 1
            if st_lb[sp] <= thr2:
                node = st_node[sp]
                break
        if node == -(1 << 62):
            return bpos, bv, bw, best2


@njit(cache=True, inline="always")
def _threshold2(best, qabs):
    """Square of ``d* + m``: boxes farther than this cannot hold a face at distance ``d*``."""
    t = best + MARGIN * (qabs + best)
    return t * t


@njit(cache=True, parallel=True)
def _query(P, order, lo, hi, rec, face, child, cbox, slab, root, scale, n_threads,
           out_face, out_dist, out_closest, out_bary):
    """Search the (spatially sorted) queries ``P[lo:hi]``, blocks of them at a time per
    thread; the result of ``P[i]`` goes to row ``order[i]`` of the outputs."""
    n = hi - lo
    n_blocks = chunk_count(n, _BLOCK)
    counter = np.zeros(1, np.int64)
    for _ in prange(n_threads):
        st_node = np.empty(_STACK, np.int64)
        st_lb = np.empty(_STACK)
        while True:
            b, start, stop = next_chunk(counter, _BLOCK, n)
            if b >= n_blocks:
                break
            for i in range(lo + start, lo + stop):
                px, py, pz = P[i, 0], P[i, 1], P[i, 2]
                k, v, w, d2 = _search(rec, face, child, cbox, slab, root, scale,
                                      px, py, pz, st_node, st_lb)
                r = rec[k]
                q = order[i]
                out_face[q] = face[k]
                out_dist[q] = np.sqrt(d2)
                out_closest[q, 0] = r[0] + v * r[3] + w * r[6]
                out_closest[q, 1] = r[1] + v * r[4] + w * r[7]
                out_closest[q, 2] = r[2] + v * r[5] + w * r[8]
                out_bary[q, 0] = max(1.0 - v - w, 0.0)
                out_bary[q, 1] = v
                out_bary[q, 2] = w


@njit(cache=True)
def _sort_queries(P):
    """Points in the order of a coarse Morton curve over their bounding box (for cache
    locality): ``(order, P[order])``. One counting-sort pass over 2^(3 _ORDER_BITS) cells."""
    n = P.shape[0]
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for i in range(n):
        for d in range(3):
            lo[d] = min(lo[d], P[i, d])
            hi[d] = max(hi[d], P[i, d])
    cells = 1 << _ORDER_BITS
    inv = np.zeros(3)
    for d in range(3):
        if hi[d] > lo[d]:
            inv[d] = (cells - 1e-3) / (hi[d] - lo[d])
    keys = np.empty(n, np.int64)
    count = np.zeros((1 << (3 * _ORDER_BITS)) + 1, np.int64)
    for i in range(n):
        code = 0
        for d in range(3):
            c = np.int64(min(max((P[i, d] - lo[d]) * inv[d], 0.0), cells - 1.0))
            for bit in range(_ORDER_BITS):
                code |= ((c >> bit) & 1) << (3 * bit + d)
        keys[i] = code
        count[code + 1] += 1
    for b in range(count.shape[0] - 1):
        count[b + 1] += count[b]
    order = np.empty(n, np.int64)
    for i in range(n):
        k = keys[i]
        order[count[k]] = i
        count[k] += 1
    Ps = np.empty((n, 3))
    for i in range(n):
        for d in range(3):
            Ps[i, d] = P[order[i], d]
    return order, Ps


def query_tree(tree: Tree | None, points: ArrayLike, *, chunk: int = 65536,
               progress: Callable[[int, int], None] | None = None) -> NearestResult:
    """Nearest faces of ``points`` (finite float64 (N, 3)) in ``tree``; see the module docstring.

    Points are searched in a spatial order, ``chunk`` at a time (``progress(done, total)`` is
    called after each); the result does not depend on ``chunk``. ``tree`` may be None only
    when there are no points.
    """
    P = np.ascontiguousarray(points, dtype=np.float64)
    n = P.shape[0]
    res = NearestResult.allocate(n)
    if n == 0:
        if progress is not None:
            progress(0, 0)
        return res
    if tree is None:
        raise ValueError("query_tree needs a tree for a non-empty query")
    order, Ps = _sort_queries(P)
    threads = numba.get_num_threads()
    for lo in range(0, n, chunk):
        hi = min(lo + chunk, n)
        _query(Ps, order, lo, hi, tree.rec, tree.face, tree.child, tree.cbox,
               tree.slab, tree.root, tree.scale, threads,
               res.face, res.distance, res.closest, res.barycentric)
        if progress is not None:
            progress(hi, n)
    return res


def nearest_triangles_numba(points: ArrayLike, vertices: ArrayLike, faces: ArrayLike, *,
                            exclude: ArrayLike | None = None, chunk: int = 65536,
                            progress: Callable[[int, int], None] | None = None
                            ) -> NearestResult:
    """Compiled :func:`~gsverse_format.nearest.reference.nearest_triangles_numpy`: same
    arguments, same result, bit for bit."""
    P, V, F, idx = prepare_query(points, vertices, faces, exclude, chunk)
    if P.shape[0] == 0:
        return query_tree(None, P, chunk=chunk, progress=progress)
    return query_tree(build_tree(V, F, idx), P, chunk=chunk, progress=progress)


def warm_up() -> None:
    """Compile (or load from the on-disk cache) every kernel with a tiny problem."""
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0, 0, 1], [1, 0, 1]])
    f = np.array([[0, 1, 2], [1, 3, 2], [0, 1, 4], [1, 5, 4], [2, 3, 4], [0, 2, 4]])
    p = np.array([[0.2, 0.3, 0.5], [2.0, 2.0, 2.0], [-1.0, 0.5, 0.2]])
    nearest_triangles_numba(p, v, f)
