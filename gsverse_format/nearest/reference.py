"""Exact nearest-triangle queries (point → closest triangle of a mesh): the numpy reference.

:func:`nearest_triangles_numpy` returns, for every query point, a triangle whose float64
distance to the point is *exactly* the minimum over all selectable triangles — the same value a
brute-force scan with :func:`closest_points_on_triangles` over every face would find — together
with the closest point on it and that point's barycentric coordinates. It is not a
k-nearest-centroid heuristic: the search is a branch-and-bound over a bounding-volume hierarchy
whose pruning is certified.

Point–triangle distance
    Ericson's Voronoi-region test ("Real-Time Collision Detection", §5.1.5), vectorised in
    float64. Two robustness changes: inside the face region the barycentrics come from a
    per-triangle dual basis (``ap · e_v``, ``ap · e_w``), which stays accurate on slivers where
    Ericson's ``va, vb, vc`` products cancel; and a triangle whose height over its longest edge is
    at most ``1e-8`` times that edge (zero-area: a segment or a point), or a face-region result
    that falls outside the simplex through rounding, is resolved as the closest of the three edge
    segments. The closest point is always ``a + v (b - a) + w (c - a)`` with ``(u, v, w)`` in the
    simplex, so it lies on the triangle; no NaN arises for degenerate triangles.

Search and certificate
    Faces are grouped into size classes (powers of 4 of the radius ``r_f`` of the ball about the
    centroid that holds the triangle), so that a few huge triangles do not inflate the bounds of
    their neighbours, and each class gets a binary BVH (median splits of centroids along their
    widest axis, leaves of at most 8 faces). Every node stores a ball (centre ``C``, radius
    ``R``) and a cylinder about its best-fit plane (unit normal ``n``, half-thickness ``t``,
    radius ``ρ``) that contain all of its triangles — exact for leaves, merged conservatively in
    closed form for inner nodes — so that
    ``lb = max(|q - C| - R, sqrt(max(|h| - t, 0)² + max(λ - ρ, 0)²))``, with ``h = n·(q - C)``
    and ``λ`` the distance of ``q`` from the axis, is a lower bound of the distance from ``q`` to
    any of the node's triangles (the cylinder keeps queries far above flat regions cheap).
    All points of a chunk are searched together, depth first per point: each point first
    descends into its most promising child down to a leaf, whose exact distances give the upper
    bound ``d*``, which only decreases as further leaves are scanned (once a point has scanned
    a few leaves, its remaining candidates are expanded breadth first, in larger batches, which
    matters when little can be pruned, e.g. at the centre of a sphere). A node is discarded only
    when ``lb > d* + m`` with ``m = 1e-11 (|q|∞ + S + d*)`` (``S`` bounds the mesh coordinates),
    a margin far above the float64 rounding of the bounds and of the distances, so every face
    whose computed distance equals the final minimum is scanned: the result is the brute-force
    minimum.

Ties
    Among faces whose float64 distance equals the minimum exactly, the smallest face index wins
    (duplicated triangles therefore resolve to their first copy). The result does not depend on
    ``chunk``.

Implementations
    This module is the vectorised numpy reference. :mod:`gsverse_format.nearest.compiled` (numba)
    returns the identical result; :func:`gsverse_format.nearest.nearest_triangles`, which callers
    use, picks one of the two (:mod:`gsverse_format.backend`).

Units are those of the input coordinates; all arithmetic is float64.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["NearestResult", "nearest_triangles_numpy", "closest_points_on_triangles",
           "prepare_query", "DEGENERATE_RATIO", "MARGIN"]

#: A triangle is treated as a segment/point when its height over its longest edge is at most
#: this fraction of that edge.
DEGENERATE_RATIO = 1e-8
#: Relative pruning margin: a node is discarded only when its lower bound exceeds
#: ``d* + MARGIN (|q|∞ + S + d*)`` (see the module docstring).
MARGIN = 1e-11
_LEAF = 8                 # faces per BVH leaf (at most)
_BLOCK = 1 << 17          # (query, face) pairs evaluated per kernel call
_FRONTIER = 1 << 20       # (query, node) pairs processed at once before splitting the work
_MATURE = 8               # leaves a query scans depth first before going breadth first


@dataclass
class NearestResult:
    """Per query point: nearest face, closest point on it, distance, barycentrics.

    ``face`` (N,) int64 index into the input ``faces``; ``closest`` (N, 3) float64 point on that
    triangle; ``distance`` (N,) float64 Euclidean distance from the query to ``closest``;
    ``barycentric`` (N, 3) float64 ``(u, v, w)`` with ``closest = u·a + v·b + w·c`` (up to
    rounding), all ``>= 0`` and summing to 1.
    """

    face: np.ndarray
    closest: np.ndarray
    distance: np.ndarray
    barycentric: np.ndarray

    def __len__(self) -> int:
        return int(self.face.shape[0])

    @classmethod
    def allocate(cls, n: int) -> "NearestResult":
        """Uninitialised arrays for ``n`` results, for a search that fills every row."""
        return cls(np.empty(n, np.int64), np.empty((n, 3)), np.empty(n), np.empty((n, 3)))


# --------------------------------------------------------------------------- point–triangle

# Columns of the per-face table (structure of the kernel's inputs).
_AX, _AY, _AZ, _BX, _BY, _BZ, _CX, _CY, _CZ = range(9)         # a, ab = b - a, ac = c - a
_ABAB, _ACAC, _ABAC = 9, 10, 11                                # |ab|², |ac|², ab·ac
_EVX, _EVY, _EVZ, _EWX, _EWY, _EWZ = range(12, 18)             # dual basis of (ab, ac)
_DEG = 18                                                      # 1.0 when degenerate
_NCOL = 19


def _face_table(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(19, F) float64 per-face constants of the distance kernel (elementwise, deterministic)."""
    f = np.empty((_NCOL, a.shape[0]))
    ax, ay, az = a[:, 0], a[:, 1], a[:, 2]
    abx, aby, abz = b[:, 0] - ax, b[:, 1] - ay, b[:, 2] - az
    acx, acy, acz = c[:, 0] - ax, c[:, 1] - ay, c[:, 2] - az
    f[_AX], f[_AY], f[_AZ] = ax, ay, az
    f[_BX], f[_BY], f[_BZ] = abx, aby, abz
    f[_CX], f[_CY], f[_CZ] = acx, acy, acz
    abab = abx * abx + aby * aby + abz * abz
    acac = acx * acx + acy * acy + acz * acz
    f[_ABAB], f[_ACAC] = abab, acac
    f[_ABAC] = abx * acx + aby * acy + abz * acz
    nx, ny, nz = aby * acz - abz * acy, abz * acx - abx * acz, abx * acy - aby * acx
    nn = nx * nx + ny * ny + nz * nz
    bcx, bcy, bcz = acx - abx, acy - aby, acz - abz
    lmax2 = np.maximum(np.maximum(abab, acac), bcx * bcx + bcy * bcy + bcz * bcz)
    # height over the longest edge = |n| / lmax; degenerate when <= ratio * lmax
    regular = np.isfinite(nn) & (nn > (DEGENERATE_RATIO * lmax2) ** 2)
    inv = np.divide(1.0, nn, out=np.zeros_like(nn), where=regular)
    # e_v = (ac × n) / |n|², e_w = (n × ab) / |n|²: v = ap·e_v, w = ap·e_w for ap in the plane
    f[_EVX] = (acy * nz - acz * ny) * inv
    f[_EVY] = (acz * nx - acx * nz) * inv
    f[_EVZ] = (acx * ny - acy * nx) * inv
    f[_EWX] = (ny * abz - nz * aby) * inv
    f[_EWY] = (nz * abx - nx * abz) * inv
    f[_EWZ] = (nx * aby - ny * abx) * inv
    f[_DEG] = np.where(regular, 0.0, 1.0)
    return f


def _segments(g: np.ndarray, apx, apy, apz):
    """Closest point among the three edges: (v, w) with closest = a + v·ab + w·ac."""
    abx, aby, abz = g[_BX], g[_BY], g[_BZ]
    acx, acy, acz = g[_CX], g[_CY], g[_CZ]
    abab, acac = g[_ABAB], g[_ACAC]
    z = np.zeros_like(abab)
    # AB: t ∈ [0, 1] along ab
    t1 = np.clip(np.divide(abx * apx + aby * apy + abz * apz, abab, out=z.copy(), where=abab > 0), 0, 1)
    ex, ey, ez = apx - t1 * abx, apy - t1 * aby, apz - t1 * abz
    best = ex * ex + ey * ey + ez * ez
    v, w = t1, z.copy()
    # AC
    t2 = np.clip(np.divide(acx * apx + acy * apy + acz * apz, acac, out=z.copy(), where=acac > 0), 0, 1)
    ex, ey, ez = apx - t2 * acx, apy - t2 * acy, apz - t2 * acz
    d2 = ex * ex + ey * ey + ez * ez
    take = d2 < best
    best = np.where(take, d2, best)
    v, w = np.where(take, 0.0, v), np.where(take, t2, w)
    # BC: b + t (c - b)
    bcx, bcy, bcz = acx - abx, acy - aby, acz - abz
    bpx, bpy, bpz = apx - abx, apy - aby, apz - abz
    bcbc = bcx * bcx + bcy * bcy + bcz * bcz
    t3 = np.clip(np.divide(bcx * bpx + bcy * bpy + bcz * bpz, bcbc, out=z.copy(), where=bcbc > 0), 0, 1)
    ex, ey, ez = bpx - t3 * bcx, bpy - t3 * bcy, bpz - t3 * bcz
    d2 = ex * ex + ey * ey + ez * ez
    take = d2 < best
    v, w = np.where(take, 1.0 - t3, v), np.where(take, t3, w)
    return v, w


def _kernel(g: np.ndarray, px: np.ndarray, py: np.ndarray, pz: np.ndarray, full: bool = False):
    """Distance from points to triangles, pairwise: ``g`` (19, M) face columns, ``p*`` (M,).

    Returns the distance (M,), or with ``full`` also the closest point (M, 3) and the
    barycentrics (M, 3). Every operation is elementwise, so a pair's result does not depend on
    which other pairs share the call.
    """
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        abx, aby, abz = g[_BX], g[_BY], g[_BZ]
        acx, acy, acz = g[_CX], g[_CY], g[_CZ]
        apx, apy, apz = px - g[_AX], py - g[_AY], pz - g[_AZ]
        abab, acac, abac = g[_ABAB], g[_ACAC], g[_ABAC]
        d1 = abx * apx + aby * apy + abz * apz        # ab·ap
        d2 = acx * apx + acy * apy + acz * apz        # ac·ap
        d3 = d1 - abab                                # ab·bp
        d4 = d2 - abac                                # ac·bp
        d5 = d1 - abac                                # ab·cp
        d6 = d2 - acac                                # ac·cp
        va = d3 * d6 - d5 * d4
        vb = d5 * d2 - d1 * d6
        vc = d1 * d4 - d3 * d2
        # face region (the default): barycentrics of the projection from the dual basis
        v = apx * g[_EVX] + apy * g[_EVY] + apz * g[_EVZ]
        w = apx * g[_EWX] + apy * g[_EWY] + apz * g[_EWZ]
        face = np.ones(v.shape, bool)
        # Ericson's regions, applied in reverse precedence so the first matching test wins
        e43, e56 = d4 - d3, d5 - d6
        r = (va <= 0) & (e43 >= 0) & (e56 >= 0)                       # edge BC
        den = e43 + e56
        t = np.clip(np.divide(e43, den, out=np.zeros_like(den), where=den > 0), 0, 1)
        v, w, face = np.where(r, 1.0 - t, v), np.where(r, t, w), face & ~r
        r = (vb <= 0) & (d2 >= 0) & (d6 <= 0)                          # edge AC
        den = d2 - d6
        t = np.clip(np.divide(d2, den, out=np.zeros_like(den), where=den > 0), 0, 1)
        v, w, face = np.where(r, 0.0, v), np.where(r, t, w), face & ~r
        r = (d6 >= 0) & (d5 <= d6)                                     # vertex C
        v, w, face = np.where(r, 0.0, v), np.where(r, 1.0, w), face & ~r
        r = (vc <= 0) & (d1 >= 0) & (d3 <= 0)                          # edge AB
        den = d1 - d3
        t = np.clip(np.divide(d1, den, out=np.zeros_like(den), where=den > 0), 0, 1)
        v, w, face = np.where(r, t, v), np.where(r, 0.0, w), face & ~r
        r = (d3 >= 0) & (d4 <= d3)                                     # vertex B
        v, w, face = np.where(r, 1.0, v), np.where(r, 0.0, w), face & ~r
        r = (d1 <= 0) & (d2 <= 0)                                      # vertex A
        v, w, face = np.where(r, 0.0, v), np.where(r, 0.0, w), face & ~r
        # degenerate triangles, or a face-region result outside the simplex: closest edge
        bad = (g[_DEG] != 0) | (face & ~((v >= 0) & (w >= 0) & (v + w <= 1)))
        if bad.any():
            i = np.flatnonzero(bad)
            v[i], w[i] = _segments(g[:, i], apx[i], apy[i], apz[i])
        cx = g[_AX] + v * abx + w * acx
        cy = g[_AY] + v * aby + w * acy
        cz = g[_AZ] + v * abz + w * acz
        ex, ey, ez = px - cx, py - cy, pz - cz
        dist = np.sqrt(ex * ex + ey * ey + ez * ez)
    if not full:
        return dist
    u = np.maximum(1.0 - v - w, 0.0)
    return dist, np.stack([cx, cy, cz], axis=-1), np.stack([u, v, w], axis=-1)


def closest_points_on_triangles(points: ArrayLike, a: ArrayLike, b: ArrayLike, c: ArrayLike
                                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closest point on triangle ``(a[i], b[i], c[i])`` to ``points[i]``, pairwise, float64.

    Arguments broadcast to (M, 3). Returns ``(closest (M, 3), barycentric (M, 3), distance (M,))``
    with ``closest = a + v (b - a) + w (c - a)`` and barycentric ``(u, v, w)`` in the simplex.
    This is the exact kernel :func:`nearest_triangles_numpy` uses, so a brute-force scan with it
    reproduces that function's distances bit for bit.
    """
    p, a, b, c = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (points, a, b, c)))
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points and triangle corners must broadcast to shape (M, 3), got {p.shape}")
    g = _face_table(a, b, c)
    Q = np.ascontiguousarray(p.T)
    dist, closest, bary = _kernel(g, Q[0], Q[1], Q[2], full=True)
    return closest, bary, dist


# --------------------------------------------------------------------------- hierarchy

@dataclass
class _Tree:
    """A forest of BVHs over the selectable faces, in a face order where nodes are ranges."""

    order: np.ndarray      # (Fs,) position -> original face index
    table: np.ndarray      # (19, Fs) kernel columns in that order
    start: np.ndarray      # (K,) first position of each node
    count: np.ndarray      # (K,) faces in each node
    child: np.ndarray      # (K,) index of the left child (right = left + 1), -1 for leaves
    bound: np.ndarray      # (9, K) rows C (3), n (3), R, t, ρ
    roots: np.ndarray      # (T,) root node of each class tree
    scale: float           # bound on the magnitude of the mesh coordinates


def _ranges(start: np.ndarray, count: np.ndarray) -> np.ndarray:
    """Concatenation of ``arange(start[i], start[i] + count[i])``."""
    total = int(count.sum())
    if total == 0:
        return np.zeros(0, np.int64)
    offs = np.cumsum(count) - count
    return np.repeat(start - offs, count) + np.arange(total)


def _leaf_bounds(corners: np.ndarray, start: np.ndarray, count: np.ndarray):
    """Exact ball and plane-cylinder of the corner points of each leaf (ranges of faces).

    Returns ``(bound (L, 9), lo (L, 3), hi (L, 3), moments (L, 10))`` with the moments
    ``[n, Σx, Σxxᵀ (6)]`` of the corners (``x`` relative to the origin of ``corners``).
    """
    pos = _ranges(start, count)
    pts = corners[pos].reshape(-1, 3)                     # 3 corners per face
    seg = np.repeat(np.arange(len(start)), 3 * count)
    head = 3 * (np.cumsum(count) - count)
    x, y, z = pts[:, 0], pts[:, 1], pts[:, 2]
    mom = np.column_stack([np.ones_like(x), x, y, z, x * x, y * y, z * z, x * y, x * z, y * z])
    mom = np.add.reduceat(mom, head, axis=0)
    lo = np.minimum.reduceat(pts, head, axis=0)
    hi = np.maximum.reduceat(pts, head, axis=0)
    centre = 0.5 * (lo + hi)
    normal = _normals(mom)
    d = pts - centre[seg]
    ns = normal[seg]
    h = d[:, 0] * ns[:, 0] + d[:, 1] * ns[:, 1] + d[:, 2] * ns[:, 2]
    lat = d - h[:, None] * ns
    radius = np.sqrt(np.maximum.reduceat(d[:, 0] ** 2 + d[:, 1] ** 2 + d[:, 2] ** 2, head))
    thick = np.maximum.reduceat(np.abs(h), head)
    rho = np.sqrt(np.maximum.reduceat(lat[:, 0] ** 2 + lat[:, 1] ** 2 + lat[:, 2] ** 2, head))
    return np.column_stack([centre, normal, radius, thick, rho]), lo, hi, mom


def _normals(mom: np.ndarray) -> np.ndarray:
    """Unit direction of least spread (best-fit plane normal) from corner moments."""
    n = mom[:, 0]
    m = mom[:, 1:4] / n[:, None]
    xx, yy, zz, xy, xz, yz = (mom[:, 4:10] / n[:, None]).T
    cov = np.empty((len(n), 3, 3))
    cov[:, 0, 0] = xx - m[:, 0] * m[:, 0]
    cov[:, 1, 1] = yy - m[:, 1] * m[:, 1]
    cov[:, 2, 2] = zz - m[:, 2] * m[:, 2]
    cov[:, 0, 1] = cov[:, 1, 0] = xy - m[:, 0] * m[:, 1]
    cov[:, 0, 2] = cov[:, 2, 0] = xz - m[:, 0] * m[:, 2]
    cov[:, 1, 2] = cov[:, 2, 1] = yz - m[:, 1] * m[:, 2]
    _, vec = np.linalg.eigh(cov)
    normal = vec[:, :, 0]
    return normal / np.linalg.norm(normal, axis=1, keepdims=True)


def _merge_bounds(child: np.ndarray, lo: np.ndarray, hi: np.ndarray, mom: np.ndarray) -> np.ndarray:
    """Conservative ball and cylinder of a parent from its two children's (``child`` (P, 2, 9)).

    The parent's frame comes from the summed moments; each child's points lie in its ball and
    cylinder, whose extents along and across the parent's axis have closed forms.
    """
    centre = 0.5 * (lo + hi)
    normal = _normals(mom)
    dc = child[:, :, 0:3] - centre[:, None, :]
    nc = child[:, :, 3:6]
    rc, tc, pc = child[:, :, 6], child[:, :, 7], child[:, :, 8]
    h = np.einsum("pkj,pj->pk", dc, normal)
    lat = np.linalg.norm(dc - h[:, :, None] * normal[:, None, :], axis=2)
    cos = np.minimum(np.abs(np.einsum("pkj,pj->pk", nc, normal)), 1.0)
    sin = np.sqrt(1.0 - cos * cos)
    half = 0.5 * (hi - lo)
    thick = np.max(np.abs(h) + np.minimum(tc * cos + pc * sin, rc), axis=1)
    thick = np.minimum(thick, np.sum(np.abs(normal) * half, axis=1))
    radius = np.minimum(np.max(np.linalg.norm(dc, axis=2) + rc, axis=1), np.linalg.norm(half, axis=1))
    rho = np.minimum(np.max(lat + np.minimum(tc * sin + pc, rc), axis=1), radius)
    return np.column_stack([centre, normal, radius, thick, rho])


def _build(a: np.ndarray, b: np.ndarray, c: np.ndarray, faces_idx: np.ndarray) -> _Tree:
    """BVH forest over triangles ``(a, b, c)`` (each (Fs, 3)); ``faces_idx`` their input indices."""
    corners_all = np.stack([a, b, c], axis=1)                     # (Fs, 3, 3)
    if not np.all(np.isfinite(corners_all)):
        raise ValueError("mesh vertices used by selectable faces must be finite")
    cent = corners_all.mean(axis=1)
    r = np.sqrt(np.max(np.sum((corners_all - cent[:, None, :]) ** 2, axis=2), axis=1))
    pos_r = r[r > 0]
    ref = float(np.median(pos_r)) if pos_r.size else 1.0
    with np.errstate(divide="ignore"):
        cls = np.where(r > 4 * ref, np.ceil(np.log(np.maximum(r, 1e-300) / (4 * ref)) / np.log(4.0)), 0)
    cls = cls.astype(np.int64)
    # class-major face order; each class is split recursively into ranges
    order = np.lexsort((np.arange(len(r)), cls))
    classes, first, sizes = np.unique(cls[order], return_index=True, return_counts=True)
    roots = np.arange(len(classes), dtype=np.int64)
    n_nodes = len(classes)
    cur_start, cur_count = first.astype(np.int64), sizes.astype(np.int64)
    node_start, node_count, children = [cur_start], [cur_count], []
    while True:                                    # one level of median splits per pass
        split = cur_count > _LEAF
        ch = np.full(len(cur_start), -1, np.int64)
        if not split.any():
            children.append(ch)
            break
        s, n = cur_start[split], cur_count[split]
        pos = _ranges(s, n)
        seg = np.repeat(np.arange(len(s)), n)
        head = np.cumsum(n) - n
        pc = cent[order[pos]]
        low = np.minimum.reduceat(pc, head, axis=0)
        ext = np.maximum.reduceat(pc, head, axis=0) - low
        axis = np.argmax(ext, axis=1)              # split along the widest centroid extent
        rows = np.arange(len(s))
        lo_, ext_ = low[rows, axis][seg], ext[rows, axis][seg]
        key = np.divide(pc[np.arange(len(pos)), axis[seg]] - lo_, ext_, out=np.zeros(len(pos)),
                        where=ext_ > 0)
        # sort within each range (ranges stay in place: key in [seg, seg + 0.5])
        order[pos] = order[pos][np.argsort(seg + 0.5 * np.clip(key, 0, 1), kind="stable")]
        left_n = (n + 1) // 2
        ch[split] = n_nodes + 2 * np.arange(len(s))
        children.append(ch)
        n_nodes += 2 * len(s)
        cur_start = np.stack([s, s + left_n], axis=1).ravel()
        cur_count = np.stack([left_n, n - left_n], axis=1).ravel()
        node_start.append(cur_start)
        node_count.append(cur_count)
    start = np.concatenate(node_start)
    count = np.concatenate(node_count)
    child = np.concatenate(children)
    # bounds: exact for leaves, merged upwards for inner nodes (children follow their parents)
    origin = 0.5 * (corners_all.min(axis=(0, 1)) + corners_all.max(axis=(0, 1)))
    corners = corners_all[order] - origin
    k = len(start)
    bound, lo, hi, mom = np.empty((k, 9)), np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 10))
    leaf = np.flatnonzero(child < 0)
    bound[leaf], lo[leaf], hi[leaf], mom[leaf] = _leaf_bounds(corners, start[leaf], count[leaf])
    bounds_at = np.cumsum([0] + [len(x) for x in node_start])      # node ids level by level
    for lo_id, hi_id in reversed(list(zip(bounds_at[:-1], bounds_at[1:]))):
        ids = np.arange(lo_id, hi_id)
        p = ids[child[ids] >= 0]
        if not p.size:
            continue
        left, right = child[p], child[p] + 1
        lo[p] = np.minimum(lo[left], lo[right])
        hi[p] = np.maximum(hi[left], hi[right])
        mom[p] = mom[left] + mom[right]
        bound[p] = _merge_bounds(bound[np.stack([left, right], axis=1)], lo[p], hi[p], mom[p])
    bound[:, 0:3] += origin
    table = _face_table(a[order], b[order], c[order])
    scale = float(np.max(np.abs(corners_all)))
    return _Tree(faces_idx[order], table, start, count, child, np.ascontiguousarray(bound.T), roots, scale)


# --------------------------------------------------------------------------- search

class _Best:
    """Running per-query best (distance, original face) with the smallest-index tie rule."""

    def __init__(self, n: int):
        self.dist = np.full(n, np.inf)
        self.face = np.full(n, np.iinfo(np.int64).max, np.int64)

    def merge(self, q: np.ndarray, d: np.ndarray, f: np.ndarray) -> None:
        """Fold candidates (q sorted ascending) into the running best."""
        if q.size == 0:
            return
        head = np.flatnonzero(np.r_[True, q[1:] != q[:-1]])
        qq = q[head]
        dmin = np.minimum.reduceat(d, head)
        cnt = np.diff(np.r_[head, q.size])
        fmin = np.minimum.reduceat(np.where(d == np.repeat(dmin, cnt), f, np.iinfo(np.int64).max), head)
        bd, bf = self.dist[qq], self.face[qq]
        better = (dmin < bd) | ((dmin == bd) & (fmin < bf))
        self.dist[qq[better]] = dmin[better]
        self.face[qq[better]] = fmin[better]


def _scan(tree: _Tree, best: _Best, q: np.ndarray, pos: np.ndarray, Q: np.ndarray) -> None:
    """Exact distances of (query, face position) pairs, q sorted, folded into ``best``."""
    for lo in range(0, q.size, _BLOCK):
        qb, fb = q[lo:lo + _BLOCK], pos[lo:lo + _BLOCK]
        d = _kernel(np.take(tree.table, fb, axis=1), Q[0][qb], Q[1][qb], Q[2][qb])
        best.merge(qb, d, tree.order[fb])


def _lower_bounds(tree: _Tree, Q: np.ndarray, q: np.ndarray, node: np.ndarray, centre: bool = False):
    """Lower bound of the distance from query ``q`` (columns of ``Q``) to the faces of ``node``.

    With ``centre`` also returns the distance to the node's centre.
    """
    bd = np.take(tree.bound, node, axis=1)
    dx, dy, dz = Q[0][q] - bd[0], Q[1][q] - bd[1], Q[2][q] - bd[2]
    nx, ny, nz = bd[3], bd[4], bd[5]
    h = dx * nx + dy * ny + dz * nz
    lx, ly, lz = dx - h * nx, dy - h * ny, dz - h * nz
    ax = np.maximum(np.abs(h) - bd[7], 0.0)
    lat = np.maximum(np.sqrt(lx * lx + ly * ly + lz * lz) - bd[8], 0.0)
    dc = np.sqrt(dx * dx + dy * dy + dz * dz)
    lb = np.maximum(np.sqrt(ax * ax + lat * lat), dc - bd[6])
    return (lb, dc) if centre else lb


def _search_chunk(tree: _Tree, Q: np.ndarray) -> _Best:
    """Branch and bound for the points ``Q`` (3, n) all at once, depth first per point at first.

    Work items are (query, node, lower bound) triples sorted by query. Expanding an item scans
    its leaves and splits the children of its inner nodes into the most promising child of each
    query (processed next, so every query quickly reaches a leaf and a tight upper bound) and
    the rest (pushed below it and pruned again, against the improved bounds, when popped).
    Once every query of an item has scanned a few leaves its children stay together
    (breadth first), which keeps the batches large when little can be pruned.
    """
    n = Q.shape[1]
    best = _Best(n)
    qabs = np.max(np.abs(Q), axis=0) + tree.scale
    q0 = np.repeat(np.arange(n), len(tree.roots))
    n0 = np.tile(tree.roots, n)
    stack = [(q0, n0, _lower_bounds(tree, Q, q0, n0))]
    leaves = np.zeros(n, np.int64)           # leaves scanned per query
    while stack:
        q, node, lb = stack.pop()
        dstar = best.dist[q]
        keep = lb <= dstar + MARGIN * (qabs[q] + dstar)
        q, node, lb = q[keep], node[keep], lb[keep]
        if q.size > _FRONTIER:
            half = q.size // 2
            stack.append((q[half:], node[half:], lb[half:]))
            stack.append((q[:half], node[:half], lb[:half]))
            continue
        ch = tree.child[node]
        leaf = ch < 0
        if leaf.any():
            ql, nl = q[leaf], node[leaf]
            cnt = tree.count[nl]
            _scan(tree, best, np.repeat(ql, cnt), _ranges(tree.start[nl], cnt), Q)
            np.add.at(leaves, ql, 1)
        inner = ~leaf
        if not inner.any():
            continue
        q2 = np.repeat(q[inner], 2)
        c2 = (ch[inner][:, None] + np.arange(2)).ravel()
        lb2, dc2 = _lower_bounds(tree, Q, q2, c2, centre=True)
        dstar = best.dist[q2]
        keep = lb2 <= dstar + MARGIN * (qabs[q2] + dstar)
        q2, c2, lb2, dc2 = q2[keep], c2[keep], lb2[keep], dc2[keep]
        if not q2.size:
            continue
        head = np.flatnonzero(np.r_[True, q2[1:] != q2[:-1]])
        if leaves[q2[head]].min() >= _MATURE:
            # every query here already has a good upper bound: breadth first, in large batches
            # (depth first costs one small batch per node when little can be pruned)
            stack.append((q2, c2, lb2))
            continue
        # the most promising child of each query: least lower bound, then nearest centre
        cnt = np.diff(np.r_[head, q2.size])
        low = lb2 == np.repeat(np.minimum.reduceat(lb2, head), cnt)
        key = np.where(low, dc2, np.inf)
        low &= key == np.repeat(np.minimum.reduceat(key, head), cnt)
        at = np.where(low, np.arange(q2.size), q2.size)
        first = np.zeros(q2.size, bool)
        first[np.minimum.reduceat(at, head)] = True
        rest = ~first
        if rest.any():
            stack.append((q2[rest], c2[rest], lb2[rest]))
        stack.append((q2[first], c2[first], lb2[first]))
    return best


def prepare_query(points: ArrayLike, vertices: ArrayLike, faces: ArrayLike,
                  exclude: ArrayLike | None = None, chunk: int = 65536, *,
                  float32_points: bool = False
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Validated inputs of a query, shared by the implementations.

    Returns ``(P (N, 3) float64, V (V, 3) float64, F (F, 3) int64, idx)`` with ``idx`` the
    indices of the selectable faces. Raises ``ValueError`` (see
    :func:`nearest_triangles_numpy`). ``float32_points`` leaves float32 points as they are
    (C-contiguous) for a caller that converts them to float64 as it reads them: the same
    values, without a float64 copy of them all."""
    P = np.asarray(points)
    if not (float32_points and P.dtype == np.float32):
        P = np.asarray(P, dtype=np.float64)
    P = np.ascontiguousarray(P)
    V = np.asarray(vertices, dtype=np.float64)
    Fc = np.asarray(faces)
    if P.ndim != 2 or P.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {P.shape}")
    if V.ndim != 2 or V.shape[1] != 3:
        raise ValueError(f"vertices must have shape (V, 3), got {V.shape}")
    if Fc.ndim != 2 or Fc.shape[1] != 3 or (Fc.size and not np.issubdtype(Fc.dtype, np.integer)):
        raise ValueError(f"faces must be an integer array of shape (F, 3), got {Fc.shape} {Fc.dtype}")
    Fc = Fc.astype(np.int64, copy=False)
    if Fc.size and (Fc.min() < 0 or Fc.max() >= V.shape[0]):
        raise ValueError("faces reference vertices out of range")
    if chunk < 1:
        raise ValueError("chunk must be positive")
    selectable = np.ones(Fc.shape[0], bool)
    if exclude is not None:
        ex = np.asarray(exclude)
        if ex.shape != (Fc.shape[0],) or ex.dtype != bool:
            raise ValueError(f"exclude must be a boolean mask of shape ({Fc.shape[0]},)")
        selectable &= ~ex
    idx = np.flatnonzero(selectable)
    if idx.size == 0:
        raise ValueError("no selectable faces: the mesh is empty or every face is excluded")
    if not np.all(np.isfinite(P)):
        raise ValueError("points must be finite")
    if P.shape[0] and not np.all(np.isfinite(V)) and not np.all(np.isfinite(V[Fc[idx]])):
        raise ValueError("mesh vertices used by selectable faces must be finite")
    return P, V, Fc, idx


def nearest_triangles_numpy(points: ArrayLike, vertices: ArrayLike, faces: ArrayLike, *,
                            exclude: ArrayLike | None = None, chunk: int = 65536,
                            progress: Callable[[int, int], None] | None = None
                            ) -> NearestResult:
    """Exact nearest triangle of ``(vertices, faces)`` for every point of ``points`` (numpy).

    ``points`` (N, 3), ``vertices`` (V, 3) and ``faces`` (F, 3) integer indices; ``exclude``
    an optional (F,) boolean mask of faces never to return (for example degenerate ones).
    Queries run ``chunk`` points at a time; ``progress(done, total)`` is called after each.
    Raises ``ValueError`` on malformed input or when no face is selectable.
    See the module docstring for the exactness guarantee and the tie rule.
    """
    P, V, Fc, idx = prepare_query(points, vertices, faces, exclude, chunk)
    n = P.shape[0]
    result = NearestResult(np.zeros(n, np.int64), np.zeros((n, 3)), np.zeros(n), np.zeros((n, 3)))
    if n == 0:
        if progress is not None:
            progress(0, 0)
        return result
    sel = Fc[idx]
    tree = _build(V[sel[:, 0]], V[sel[:, 1]], V[sel[:, 2]], idx)
    position = np.empty(Fc.shape[0], np.int64)
    position[tree.order] = np.arange(tree.order.size)
    for lo in range(0, n, chunk):
        Q = np.ascontiguousarray(P[lo:lo + chunk].T)
        face = _search_chunk(tree, Q).face
        # the same kernel on the same face columns: reproduces the distance found in the search
        d, cp, bary = _kernel(np.take(tree.table, position[face], axis=1), Q[0], Q[1], Q[2], full=True)
        result.face[lo:lo + chunk] = face
        result.distance[lo:lo + chunk] = d
        result.closest[lo:lo + chunk] = cp
        result.barycentric[lo:lo + chunk] = bary
        if progress is not None:
            progress(min(lo + chunk, n), n)
    return result
