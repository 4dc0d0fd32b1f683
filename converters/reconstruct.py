"""An anchor mesh reconstructed from the splats themselves (a 3DGS PLY given without a mesh).

This is a step of the conversion pipeline, not a source: when a source returns no mesh, the
pipeline (:mod:`gsverse_format.pipeline`) rotates its splats into the glTF frame and calls
:func:`reconstruct_mesh`, which runs :func:`build_anchor_mesh` on them:

1. **Points.** Splat centres with opacity below ``min_opacity`` (default 0.05) are ignored;
   if that would leave fewer than a tenth of the splats, the more opaque half is used instead.
2. **Normals.** Each splat's normal is its shortest axis (the column of its rotation matrix
   belonging to its smallest scale): optimised 3DGS splats flatten onto surfaces. The axis has
   no sign, so the normals are oriented by Hoppe's propagation: a k-nearest-neighbour graph
   (k = 12) weighted by ``1 − |nᵢ·nⱼ|`` (plus a tiny distance term), its minimum spanning
   tree, and flips along the tree wherever neighbouring normals disagree, so orientation
   travels through smoothly curving regions first. Each connected part of the graph is seeded
   at its point farthest from the centroid of all points, whose normal is made to point away
   from that centroid — the one place where "outward from the centroid" is reliable. (Orienting
   every normal outward from the centroid alone fails on non-convex shapes: the inner wall of
   a torus would be reversed.) pymeshlab's own point-cloud normals were not used because they
   replace the splat axes by PCA normals of neighbourhoods, which blur thin features.
3. **Weights.** Each point enters screened Poisson with confidence
   ``opacity × flatness``, ``flatness = clip(1 − s_min / s_mid, 0.1, 1)``: faint splats and
   nearly isotropic ones (whose shortest axis is no reliable normal) count less.
4. **Screened Poisson** (pymeshlab ``generate_surface_reconstruction_screened_poisson``),
   octree ``depth`` chosen from the requested face count (``ceil(log4(2·faces/3))`` clamped to
   5..10: depth 7 for 20 000 faces) unless given. Poisson closes every surface; it adapts to the
   point density, so a deeper octree than the points support adds no detail.
5. **Trim.** Poisson's per-vertex density estimate (vertex quality, ≈ log₄ of the weighted
   sample density) is low where the surface was extrapolated rather than supported by splats.
   Faces whose mean vertex density lies below ``min(P_trim(q), median(q) − trim_gap)`` are
   removed — the lowest ``trim_percentile`` percent (default 20) but only where the density is
   at least 4^trim_gap (default 4×) below the typical one, so closed, evenly covered objects
   lose nothing. Components holding less than ``min_component`` (1 %) of the faces are then
   removed (floaters).
6. **Decimate** to ``faces`` (:func:`gsverse_format.meshops.decimate`, quadric edge collapse)
   and **repair** (:func:`gsverse_format.meshops.repair`).

Quality to expect
    The mesh is a smooth, watertight-where-supported envelope of the splat centres, good enough
    as a deformation cage for compact objects captured from all sides (the mean surface error
    is a fraction of the Poisson cell, see the report's distances). It does not reproduce
    detail finer than a few octree cells, and Poisson smooths sharp edges.

When to bring your own mesh (``--mesh``)
    * thin structures (leaves, cloth, wires, ears): splats on both sides of a sheet thinner
      than a cell fuse, normals of the two sides cancel, and the sheet vanishes or gets holes;
    * open scenes and backgrounds (rooms, landscapes, skies): splats far from any surface, huge
      background splats and one-sided capture give Poisson nothing coherent to close, and the
      trimming leaves ragged fragments;
    * hair, fur, smoke and other volumetric looks: there is no surface for the splats to lie
      on, so the shortest axes are random;
    * anything meant to be rigged: a reconstructed mesh has no artist topology or skin weights.
"""
from __future__ import annotations

import math
import os
import time
from dataclasses import replace
from typing import Any, Callable

import numpy as np

from gsverse_format.atomic import interruptions_immediate
from gsverse_format.converters.base import SourceResult
from gsverse_format.errors import FormatError, UsageError
from gsverse_format.meshops import bbox_diagonal, decimate, face_components, mesh_stats, repair
from gsverse_format.model import SplatCloud, TriangleMesh
from gsverse_format.native_output import native_output
from gsverse_format.nearest import nearest_faces
from gsverse_format.quaternion import normalize, to_matrix

__all__ = ["DEFAULT_FACES", "reconstruct_mesh", "build_anchor_mesh", "splat_normals",
           "orient_normals", "poisson_depth", "distance_check"]

#: Face count of the reconstructed mesh when neither ``--reconstruct-faces`` nor ``--faces``
#: is given.
DEFAULT_FACES = 20000
_MIN_POINTS = 16
_CHECK_SAMPLE = 200_000


def poisson_depth(faces: int) -> int:
    """Octree depth for about ``faces`` output faces: ``ceil(log4(2·faces/3))`` in 5..10.

    A compact object reconstructed at depth d has roughly 3·4^d to 8·4^d faces, so this leaves
    the decimation at least 2x more faces than requested to choose from.
    """
    return int(min(10, max(5, math.ceil(math.log(max(2.0 * faces / 3.0, 1.0), 4)))))


def splat_normals(splats: SplatCloud) -> tuple[np.ndarray, np.ndarray]:
    """Unoriented normals (N, 3) — each splat's shortest axis — and flatness (N,) in [0, 1].

    ``flatness = 1 − s_min / s_mid`` (0 for a splat with two equal smallest scales, whose
    shortest axis is arbitrary; near 1 for a flat disc).
    """
    r = to_matrix(normalize(splats.rotations))                       # columns = splat axes
    s = splats.scales.astype(np.float64)
    order = np.argsort(s, axis=1)
    smallest = order[:, 0]
    normals = np.take_along_axis(r, smallest[:, None, None].repeat(3, axis=1), axis=2)[:, :, 0]
    s_sorted = np.take_along_axis(s, order, axis=1)
    flat = 1.0 - np.divide(s_sorted[:, 0], s_sorted[:, 1], out=np.ones(len(s)),
                           where=s_sorted[:, 1] > 0)
    return normals, np.clip(flat, 0.0, 1.0)


def orient_normals(points: np.ndarray, normals: np.ndarray, k: int = 12) -> tuple[np.ndarray, int]:
    """Consistently oriented copies of unit ``normals`` at ``points`` (see the module docstring).

    Returns ``(oriented normals (N, 3), number of normals flipped)``. Deterministic.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order, connected_components, minimum_spanning_tree
    from scipy.spatial import cKDTree

    p = np.asarray(points, dtype=np.float64)
    nrm = np.asarray(normals, dtype=np.float64)
    n = len(p)
    if n == 0:
        return nrm.copy(), 0
    k = int(min(k, n - 1))
    centre = p.mean(axis=0)
    if k >= 1:
        dist, idx = cKDTree(p).query(p, k + 1)
        rows = np.repeat(np.arange(n), k)
        cols = idx[:, 1:].ravel()
        d = dist[:, 1:].ravel()
        ok = np.isfinite(d) & (cols < n) & (cols != rows)
        rows, cols, d = rows[ok], cols[ok], d[ok]
        scale = float(np.mean(d)) if d.size and np.mean(d) > 0 else 1.0
        w = 1.0 - np.abs(np.einsum("ij,ij->i", nrm[rows], nrm[cols])) + 1e-4 * d / scale + 1e-9
        graph = coo_matrix((w, (rows, cols)), shape=(n, n)).tocsr()
        tree = minimum_spanning_tree(graph)
        _, label = connected_components(tree, directed=False)
        tree = tree.tocoo()
        tr, tc = tree.row, tree.col
    else:
        label = np.zeros(n, np.int64)
        tr = tc = np.zeros(0, np.int64)
    # Seed of each part: its point farthest from the global centroid.
    far = np.einsum("ij,ij->i", p - centre, p - centre)
    order = np.lexsort((-far, label))
    first = np.r_[True, label[order][1:] != label[order][:-1]]
    seeds = order[first]
    # One BFS over the forest plus a virtual root (index n) joined to every seed.
    rows = np.concatenate([tr, np.full(len(seeds), n)])
    cols = np.concatenate([tc, seeds])
    forest = coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n + 1, n + 1)).tocsr()
    _, pred = breadth_first_order(forest, n, directed=False, return_predecessors=True)
    pred = pred.astype(np.int64)
    pred[n] = n
    if np.any(pred[:n] < 0):  # pragma: no cover - every point is reachable by construction
        raise RuntimeError("normal orientation: unreachable points")
    rel = np.ones(n + 1)
    inner = pred[:n] != n
    i = np.flatnonzero(inner)
    rel[i] = np.where(np.einsum("ij,ij->i", nrm[i], nrm[pred[i]]) < 0, -1.0, 1.0)
    s = np.flatnonzero(~inner)
    rel[s] = np.where(np.einsum("ij,ij->i", nrm[s], p[s] - centre) < 0, -1.0, 1.0)
    # Sign of every node = product of the relative signs on its path to the root
    # (pointer jumping: log2(depth) vectorised passes).
    sign, up = rel.copy(), pred.copy()
    while np.any(up != n):
        sign = sign * sign[up]
        up = up[up]
    sign = sign[:n]
    return nrm * sign[:, None], int(np.count_nonzero(sign < 0))


def _select_points(splats: SplatCloud, min_opacity: float) -> tuple[np.ndarray, str | None]:
    alpha = splats.opacities
    keep = alpha >= min_opacity
    note = None
    if np.count_nonzero(keep) < max(_MIN_POINTS, len(splats) // 10):
        keep = alpha >= np.median(alpha)
        note = (f"fewer than a tenth of the splats have opacity >= {min_opacity:g}: "
                f"the more opaque half (opacity >= {float(np.median(alpha)):.3g}) was used")
    return np.flatnonzero(keep), note


#: what PoissonRecon prints on the terminal past Python (out-of-bound points, zero-length or
#: undefined normals): held and made summary notes (gsverse_format.native_output)
_POISSON_WARNING = ("[WARNING] Found ",)


def _default_threads() -> int:
    """Half the usable cores: Poisson's OpenMP threads spin while waiting, so with every core
    requested it slows down several-fold as soon as other processes compete for the cores."""
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # pragma: no cover - not on Linux
        cores = os.cpu_count() or 1
    return max(1, cores // 2)


def _poisson(points: np.ndarray, normals: np.ndarray, weights: np.ndarray, depth: int,
             threads: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    import pymeshlab  # a dependency: missing, it is an installation problem, not bad input

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=points, v_normals_matrix=normals,
                               v_scalar_array=weights))
    with interruptions_immediate():
        ms.generate_surface_reconstruction_screened_poisson(
            depth=int(depth), confidence=True, preclean=False, threads=int(threads))
    m = ms.current_mesh()
    m.compact()
    v = np.array(m.vertex_matrix(), dtype=np.float64, copy=True)
    f = np.array(m.face_matrix(), dtype=np.int64, copy=True).reshape(-1, 3)
    q = np.array(m.vertex_scalar_array(), dtype=np.float64, copy=True)
    del ms
    return v, f, q


def _distinct_positions(splats: SplatCloud, use: np.ndarray) -> tuple[np.ndarray, str | None]:
    """``use`` less the splats at the position of an earlier one (exactly equal means).

    Copies add nothing to a surface, and many copies of one point make the k-d tree of
    :func:`orient_normals` quadratic (a million splats at one point ran for hours in scipy's
    native code, beyond the reach of SIGTERM); too few distinct points is refused."""
    if use.size == 0:
        return use, None
    _, first = np.unique(splats.means[use], axis=0, return_index=True)
    if len(first) < _MIN_POINTS:
        raise FormatError(f"only {len(first)} distinct splat positions: too few to reconstruct "
                          "a mesh; pass the object's mesh with --mesh")
    if len(first) == use.size:
        return use, None
    return (use[np.sort(first)],
            f"{use.size - len(first)} splats at the position of another left out of the "
            "reconstruction")


def build_anchor_mesh(splats: SplatCloud, faces: int | None = DEFAULT_FACES,
                      depth: int | None = None, *, min_opacity: float = 0.05,
                      trim_percentile: float = 20.0, trim_gap: float = 1.0,
                      min_component: float = 0.01, threads: int | None = None,
                      stage: Callable[[str], None] | None = None,
                      ) -> tuple[TriangleMesh, dict[str, Any]]:
    """Reconstruct an anchor mesh from ``splats`` (see the module docstring for each step).

    Returns ``(mesh, report)``; the mesh is in the splats' frame and units. ``report`` holds
    what was done and measured: ``points`` used of ``splats``, ``normals_flipped``, ``depth``,
    ``poisson_faces``, ``trim_threshold`` and ``trimmed_faces``, ``removed_components``,
    ``faces`` and ``vertices`` of the result, its ``boundary_edges`` and ``components``,
    ``seconds`` per stage and ``notes`` (list of str). ``threads`` for Poisson defaults to half
    the usable cores. ``stage`` (e.g. :meth:`gsverse_format.progress.Progress.stage`) is called
    with the name of each step as it starts.
    """
    stage = stage or (lambda label: None)
    faces = DEFAULT_FACES if faces is None else int(faces)
    if faces < 4:
        raise UsageError(f"the reconstructed mesh needs at least 4 faces, not {faces}")
    if depth is not None and not 3 <= int(depth) <= 12:
        raise UsageError(f"Poisson depth must be 3..12, not {depth}")
    if len(splats) < _MIN_POINTS:
        raise FormatError(f"only {len(splats)} splats: too few to reconstruct a mesh; "
                          "pass the object's mesh with --mesh")
    report: dict[str, Any] = {"splats": len(splats), "notes": [], "seconds": {}}
    stage(f"reconstructing the anchor mesh: normals of {len(splats)} splats")
    t0 = time.perf_counter()
    use, note = _select_points(splats, min_opacity)
    if note:
        report["notes"].append(note)
    use, note = _distinct_positions(splats, use)
    if note:
        report["notes"].append(note)
    report["points"] = int(use.size)
    pts = splats.means[use].astype(np.float64)
    raw, flat = splat_normals(splats.subset(use))
    normals, flipped = orient_normals(pts, raw)
    weights = np.clip(splats.opacities[use].astype(np.float64), 1e-3, 1.0) * np.clip(flat, 0.1, 1.0)
    report["normals_flipped"] = flipped
    report["seconds"]["normals"] = time.perf_counter() - t0

    t1 = time.perf_counter()
    depth = poisson_depth(faces) if depth is None else int(depth)
    report["depth"] = depth
    stage(f"reconstructing the anchor mesh: screened Poisson, depth {depth}")
    import pymeshlab

    try:
        with native_output(_POISSON_WARNING) as printed:
            v, f, q = _poisson(pts, normals, weights, depth,
                               _default_threads() if threads is None else max(1, int(threads)))
    except pymeshlab.PyMeshLabException as exc:   # the filter refused these points
        raise FormatError(f"screened Poisson reconstruction failed ({type(exc).__name__}: "
                          f"{exc})".splitlines()[0] + "; pass a mesh with --mesh") from None
    report["seconds"]["poisson"] = time.perf_counter() - t1
    report["notes"].extend(f"screened Poisson: {line.removeprefix('[WARNING]').strip()}"
                           for line in printed.held)
    report["poisson_faces"] = int(len(f))
    if len(f) == 0:
        raise FormatError("screened Poisson produced no surface from the splat centres; "
                          "pass a mesh with --mesh")

    stage(f"reconstructing the anchor mesh: trimming {len(f)} faces")
    t2 = time.perf_counter()
    fq = q[f].mean(axis=1)
    threshold = float(min(np.percentile(q, trim_percentile), np.median(q) - trim_gap))
    keep = fq >= threshold
    report["trim_threshold"] = threshold
    report["trimmed_faces"] = int(np.count_nonzero(~keep))
    f = f[keep]
    n_comp, label = face_components(f, len(v))
    sizes = np.bincount(label, minlength=n_comp)
    small = sizes < min_component * len(f)
    report["removed_components"] = int(np.count_nonzero(small))
    f = f[~small[label]]
    if len(f) == 0:
        raise FormatError("nothing of the reconstructed surface survived trimming; "
                          "pass a mesh with --mesh")
    mesh = TriangleMesh(v, f)
    report["seconds"]["trim"] = time.perf_counter() - t2

    stage(f"reconstructing the anchor mesh: decimating {mesh.face_count} -> {faces} faces")
    t3 = time.perf_counter()
    mesh = repair(decimate(mesh, faces))
    report["seconds"]["decimate_repair"] = time.perf_counter() - t3
    stats = mesh_stats(mesh)
    report.update(faces=stats.faces, vertices=stats.vertices, boundary_edges=stats.boundary_edges,
                  components=stats.components)
    report["seconds"]["total"] = time.perf_counter() - t0
    return mesh, report


def distance_check(splats: SplatCloud, mesh: TriangleMesh, *,
                   sample: int = _CHECK_SAMPLE) -> dict[str, float | int]:
    """Distances from splat centres to ``mesh`` relative to its bounding-box diagonal.

    Returns ``{"distance_p50_rel", "distance_p95_rel", "distance_max_rel", "checked"}``; at most
    ``sample`` splats (an evenly spaced subset) are measured.
    """
    n = len(splats)
    idx = np.arange(n) if n <= sample else np.linspace(0, n - 1, sample).astype(np.int64)
    diag = bbox_diagonal(mesh) or 1.0
    d = nearest_faces(splats.means[idx], mesh.vertices, mesh.faces.astype(np.int64))[1]
    p50, p95 = np.percentile(d, [50, 95]) if d.size else (0.0, 0.0)
    return {"distance_p50_rel": float(p50 / diag), "distance_p95_rel": float(p95 / diag),
            "distance_max_rel": float(d.max() / diag) if d.size else 0.0, "checked": int(idx.size)}


def reconstruct_mesh(result: SourceResult, faces: int | None, input_path: str, *,
                     stage: Callable[[str], None] | None = None) -> SourceResult:
    """``result`` (splats without a mesh) with an anchor mesh of about ``faces`` faces
    (default :data:`DEFAULT_FACES`) reconstructed from its splats, in the splats' frame; the
    notes and ``check`` say what was done and how close the splats lie to the mesh.
    ``stage`` is called with the name of each step as it starts."""
    try:
        mesh, report = build_anchor_mesh(result.splats, faces, stage=stage)
    except FormatError as exc:
        raise exc.with_path(input_path) from None
    notes = [f"anchor mesh reconstructed from {report['points']} of {report['splats']} splat "
             f"centres (screened Poisson depth {report['depth']}, {report['poisson_faces']} "
             f"faces, {report['trimmed_faces']} trimmed) and decimated to {report['faces']} "
             f"faces; for thin, open or hairy subjects pass a mesh with --mesh"]
    notes.extend(report["notes"])
    check = {f"reconstruct_{k}": v for k, v in report.items() if k not in ("notes", "seconds")}
    check["reconstruct_seconds"] = round(report["seconds"]["total"], 3)
    if stage is not None:
        stage("reconstructing the anchor mesh: measuring splat distances")
    check.update(distance_check(result.splats, mesh))
    return replace(result, mesh=mesh, notes=result.notes + notes, check={**result.check, **check})
