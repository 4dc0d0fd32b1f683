"""Physics-ready anchor meshes: the closed 2-manifold check, watertight repair and colliders.

A soft body or a mesh collider needs a *closed 2-manifold*: every edge shared by exactly two
faces, wound consistently, no pinched vertices, so that the surface bounds a volume. Anchor
meshes need not be one (the spec allows open meshes: a cloth, a terrain patch), so this module
reports and repairs, it does not require.

:func:`manifold_report`
    whether a mesh is a closed 2-manifold, decided in numpy on the mesh with vertices at
    bit-identical positions merged (the UV-seam copies of textured exports, which manifold3d's
    ``Mesh.merge`` also merges): every edge has exactly two faces, and the faces are wound
    consistently, i.e. no directed edge (half-edge) occurs twice (edges from a corner to
    itself, of degenerate faces, ignored). Given two faces an edge, that is the condition under
    which manifold3d's ``Manifold`` constructor reports no error (an *oriented* 2-manifold;
    like it, the check accepts pinched vertices and degenerate faces);
    ``tests/test_manifold.py`` compares the two on varied meshes. Asking manifold3d took
    0.05 s of wall and 0.09 s of CPU (two threads) for 100k faces, competing with the
    conversion the report overlaps; the half-edge check takes about 0.01 s. The edge counts say
    why a mesh is not one.
:func:`make_watertight`
    a closed 2-manifold near the mesh (``--watertight``): (1) already one: the mesh unchanged;
    (2) duplicate vertices merged (weld, then manifold3d with ``merge``); (3) otherwise
    pymeshlab repairs what manifold3d cannot: degenerate, duplicate and non-manifold-edge faces
    removed (:func:`gsverse_format.meshops.repair`), holes closed, non-manifold edges and
    vertices repaired, holes closed again, then (2) again. No vertex moves: the repaired
    surface is the original one less the removed faces plus hole-filling triangles; callers
    re-bind the splats to it, so each splat is anchored to its nearest triangle of the surface
    that is written. When no step yields a manifold a :class:`FormatError` says how many
    boundary and non-manifold edges remain.
:func:`collider`
    a collision mesh for a rigid body: ``"hull"``, the convex hull of the mesh's vertices
    (manifold3d ``Manifold.hull_points``). manifold3d 3.x has no approximate convex
    decomposition (its ``decompose`` splits disconnected parts only), so no decomposition is
    offered.
"""
from __future__ import annotations

import _thread
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from .atomic import interruptions_immediate
from .errors import FormatError, UsageError
from .meshops import edge_valence, face_components, repair, weld
from .model import TriangleMesh

__all__ = [
    "COLLIDER_KINDS",
    "ManifoldReport",
    "collider",
    "make_watertight",
    "manifold_report",
]

#: The collider kinds :func:`collider` builds.
COLLIDER_KINDS = ("hull",)
#: A convex hull whose volume is at most this times the cube of its points' bounding-box
#: diagonal is flat (coplanar points, up to float32 rounding): no collider. A box of extents
#: 1 × 1 × t has volume about t/2.8 of that cube, so 1e-6 refuses only point sets flat to
#: within about three millionths of their size.
HULL_MIN_VOLUME = 1e-6


@dataclass(frozen=True)
class ManifoldReport:
    """Whether an anchor mesh is a closed 2-manifold, and the welded mesh's edge counts."""

    closed_manifold: bool
    boundary_edges: int
    nonmanifold_edges: int
    components: int
    #: How it was decided: ``"half-edges"`` (the module docstring; earlier versions wrote
    #: ``"manifold3d"``, or ``"edges"`` without manifold3d).
    checked_by: str

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    def why_not(self) -> str:
        """Completes "the anchor mesh is not a closed 2-manifold: ..."."""
        parts = []
        if self.boundary_edges:
            parts.append(f"{self.boundary_edges} boundary edges (holes or an open border)")
        if self.nonmanifold_edges:
            parts.append(f"{self.nonmanifold_edges} edges shared by more than two faces")
        return ", ".join(parts) or "inconsistent winding (a directed edge in two faces)"


def _manifold3d() -> Any:
    try:
        import manifold3d
    except ImportError:
        return None
    return manifold3d


def _to_manifold(m3d: Any, mesh: TriangleMesh) -> Any:
    """manifold3d's ``Manifold`` of ``mesh`` with duplicate vertices merged."""
    m = m3d.Mesh(vert_properties=np.array(mesh.vertices, np.float32, order="C"),
                 tri_verts=np.array(mesh.faces, np.uint32, order="C"))
    with interruptions_immediate():
        m.merge()
        return m3d.Manifold(m)


def _from_manifold(manifold: Any) -> TriangleMesh:
    out = manifold.to_mesh()
    return TriangleMesh(np.array(np.asarray(out.vert_properties)[:, :3], np.float32),
                        np.array(out.tri_verts, np.int64).reshape(-1, 3))


def _edge_counts(mesh: TriangleMesh) -> tuple[TriangleMesh, int, int, int]:
    """``(welded mesh, boundary edges, non-manifold edges, components)``: ``mesh`` with the
    vertices at equal positions merged (:func:`gsverse_format.meshops.weld`) and the counts
    :func:`gsverse_format.meshops.mesh_stats` gives for it, without its other statistics."""
    welded = weld(mesh)
    _, counts = edge_valence(welded.faces)
    components, _ = face_components(welded.faces, len(welded.vertices))
    return (welded, int(np.count_nonzero(counts == 1)), int(np.count_nonzero(counts > 2)),
            components)


def _edges_closed(mesh: TriangleMesh) -> bool:
    """Whether every edge of ``mesh``, vertices at equal positions merged, has exactly two
    faces: a necessary condition for a closed 2-manifold, decided in numpy.

    manifold3d is asked only when this holds. On meshes far from a manifold (100k copies of
    one triangle, the fan of a polygon of 10⁴ corners) its constructor runs for minutes in
    native code that holds the interpreter, so that not even SIGTERM's handler can run; the
    edge counts already say such meshes are not closed."""
    return mesh.face_count > 0 and _edge_counts(mesh)[1:3] == (0, 0)


def _manifold_if_closed(m3d: Any, mesh: TriangleMesh,
                        edges_closed: bool | None = None) -> Any | None:
    """manifold3d's ``Manifold`` of ``mesh`` when it is a closed 2-manifold, else None
    (``edges_closed``: :func:`_edges_closed` when the caller knows it)."""
    if not (_edges_closed(mesh) if edges_closed is None else edges_closed):
        return None
    manifold = _to_manifold(m3d, mesh)
    if manifold.status() == m3d.Error.NoError and not manifold.is_empty():
        return manifold
    return None


def _is_manifold(m3d: Any, mesh: TriangleMesh) -> bool:
    return _manifold_if_closed(m3d, mesh) is not None


def _consistently_wound(faces: np.ndarray) -> bool:
    """Whether no directed edge ``(a, b)``, ``a != b``, of ``faces`` (F, 3), indices >= 0,
    occurs twice (see the module docstring)."""
    f = np.asarray(faces, np.int64)
    start, end = f.ravel(), f[:, [1, 2, 0]].ravel()
    keep = start != end
    keys = start[keep] * (int(f.max()) + 1) + end[keep]
    keys.sort()
    return not bool(np.any(keys[1:] == keys[:-1]))


def manifold_report(mesh: TriangleMesh) -> ManifoldReport:
    """Whether ``mesh`` is a closed 2-manifold (see the module docstring)."""
    if not mesh.face_count:
        return ManifoldReport(False, 0, 0, 0, "half-edges")
    welded, boundary, nonmanifold, components = _edge_counts(mesh)
    closed = boundary == 0 and nonmanifold == 0 and _consistently_wound(welded.faces)
    return ManifoldReport(closed, boundary, nonmanifold, components, "half-edges")


class BackgroundReport:
    """:func:`manifold_report` of a mesh, computed on a thread started at once.

    numpy's sorts and array work release the interpreter, so on two or more cores the report
    overlaps what the caller does next (the convert pipeline writes its output meanwhile).
    :meth:`result` waits for the report and returns it, or raises what computing it raised.

    A thread of the low-level :mod:`_thread` module, not a :class:`threading.Thread`: a process
    that ends early (an error, a stop signal) does not wait for it, and it leaves no weak
    reference whose clean-up a stop signal's ``KeyboardInterrupt`` could interrupt (a
    ``threading`` thread's does, and Python then prints that traceback as "Exception ignored").
    Signals are the main thread's: there :meth:`result` waits on a lock, which their handlers
    interrupt, and in the report's thread
    :func:`~gsverse_format.atomic.interruptions_immediate` changes nothing."""

    def __init__(self, mesh: TriangleMesh) -> None:
        self._report: ManifoldReport | None = None
        self._error: BaseException | None = None
        self._done = _thread.allocate_lock()
        self._done.acquire()
        _thread.start_new_thread(self._run, (mesh,))

    def _run(self, mesh: TriangleMesh) -> None:
        try:
            self._report = manifold_report(mesh)
        except BaseException as exc:    # the thread's boundary: handed to the one that waits
            self._error = exc
        finally:
            self._done.release()

    def result(self) -> ManifoldReport:
        with self._done:
            pass
        if self._error is not None:
            raise self._error
        assert self._report is not None
        return self._report


def _require_manifold3d(what: str) -> Any:
    m3d = _manifold3d()
    if m3d is None:
        raise UsageError(f"{what} needs manifold3d, which cannot be imported; install it with: "
                         f"pip install manifold3d")
    return m3d


def _pymeshlab_close(mesh: TriangleMesh) -> TriangleMesh:
    """Non-manifold edges and vertices repaired, holes closed, winding made coherent."""
    from .meshops import _current, _meshset, _pymeshlab_errors

    failures = _pymeshlab_errors()
    try:
        ms = _meshset(repair(mesh))
        hole = max(30, mesh.face_count)
        with interruptions_immediate():
            ms.meshing_close_holes(maxholesize=hole)
            ms.meshing_repair_non_manifold_edges(method="Remove Faces")
            ms.meshing_repair_non_manifold_vertices()
            ms.meshing_close_holes(maxholesize=hole)
        vertices, faces = _current(ms)
        del ms
    except failures as exc:
        raise FormatError(f"--watertight: pymeshlab failed to close the anchor mesh "
                          f"({type(exc).__name__}: {exc})".splitlines()[0]) from None
    return TriangleMesh(vertices, faces)


def make_watertight(mesh: TriangleMesh) -> tuple[TriangleMesh, str]:
    """A closed 2-manifold version of ``mesh`` and what was done (one phrase).

    Raises :class:`FormatError` when neither merging duplicate vertices nor pymeshlab's hole
    closing yields one (see the module docstring)."""
    m3d = _require_manifold3d("--watertight")
    if _is_manifold(m3d, mesh):
        return mesh, "already a closed 2-manifold"
    welded = weld(mesh)
    manifold = _manifold_if_closed(m3d, welded)
    if manifold is not None:
        return _from_manifold(manifold), "merged duplicate vertices"
    before = manifold_report(mesh)
    closed = _pymeshlab_close(welded)
    manifold = _manifold_if_closed(m3d, closed)
    if manifold is not None:
        repaired = _from_manifold(manifold)
        added = repaired.face_count - mesh.face_count
        return repaired, (f"repaired {before.why_not()}: {mesh.face_count} -> "
                          f"{repaired.face_count} faces ({added:+d})")
    after = manifold_report(closed)
    raise FormatError(f"--watertight could not make the anchor mesh a closed 2-manifold: "
                      f"{after.why_not()} remain after closing holes; repair it in a mesh "
                      f"editor, or convert without --watertight (open anchor meshes are valid)")


def collider(mesh: TriangleMesh, kind: str = "hull") -> TriangleMesh:
    """A collision mesh of ``mesh``: ``"hull"``, its convex hull (a closed 2-manifold)."""
    if kind not in COLLIDER_KINDS:
        raise UsageError(f"--collider must be one of {', '.join(COLLIDER_KINDS)}, not {kind!r}")
    m3d = _require_manifold3d(f"--collider {kind}")
    points = np.array(mesh.vertices, np.float32, order="C")
    with interruptions_immediate():
        hull = m3d.Manifold.hull_points(points)
    # manifold3d returns a flat "hull" of thousands of triangles for coplanar points: a hull
    # whose volume is at most HULL_MIN_VOLUME times the cube of the points' bounding-box
    # diagonal spans no volume.
    diagonal = float(np.linalg.norm(np.ptp(points.astype(np.float64), axis=0))) \
        if len(points) else 0.0
    if hull.is_empty() or hull.volume() <= HULL_MIN_VOLUME * diagonal ** 3:
        raise FormatError("--collider hull: the anchor mesh's vertices span no volume (they "
                          "are coplanar or collinear)")
    return _from_manifold(hull)
