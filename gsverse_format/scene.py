"""Scenes of several objects and physics-ready anchor meshes, for :mod:`gsverse_format.pipeline`.

Scenes (``gsverse-convert scene.ply out.glb --mesh fox.obj --mesh chair.glb``)
    Each mesh is one object, read like a single ``--mesh`` (same frame as the splats, rotated
    into the glTF frame with them). Every splat is bound to its nearest non-degenerate
    triangle over all meshes (:func:`bind_scene`: :func:`gsverse_format.binding.bind_local`
    per mesh, then the smallest distance; on a tie the mesh given first wins). ``--max-distance``
    is relative to the bounding-box diagonal of *the object the splat is nearest to* (or in
    scene units with ``--absolute-distance``), so each object keeps the limit it would have
    alone; a splat beyond its object's limit is not anchored. Each object with splats becomes
    one anchored primitive and node named after its mesh file's stem (``fox``), its anchor mesh
    ``fox anchor mesh``; the splats anchored to no object stay one plain static primitive
    (``<input stem> static``), or are dropped with ``--drop-unanchored``. Without
    ``--max-distance`` every splat is anchored to its nearest object.

Does the mesh belong to the splats? (:func:`judge_fit`)
    Every anchor mesh, one or each object of a scene (judged on the splats nearest to it), is
    checked with :func:`gsverse_format.fit.assess_fit` once the splats' distances are known:
    the numbers go to the summary's ``fit``; a misfit is a note and a
    :class:`~gsverse_format.fit.MeshFitWarning` (``gsverse-convert`` prints it as a
    ``warning:`` line), or with ``--strict`` a :class:`BindingError` before anything is
    written.

Skin weights (:func:`normalize_skin_weights`)
    The skin weights of a rigged ``--mesh`` are written normalized, as readers use them (spec
    §Animated anchor meshes, *Skin weights*), with a note on how many vertices changed; with
    ``--strict`` weights that do not sum to 1 are an error. Negative weights and vertices
    whose weights are all zero are refused.

Physics-ready anchor meshes (:mod:`gsverse_format.manifold`)
    ``--watertight`` replaces each anchor mesh by a closed 2-manifold before binding, so the
    splats are bound (again, for a source's exact anchors) to the repaired surface;
    ``--collider hull`` adds each anchor mesh's convex hull as its collider; every summary
    reports whether each written anchor mesh is a closed 2-manifold. ``--physics`` makes
    objects bodies (each with its anchor mesh's hull as collider) and ``--ground`` puts a
    static ground box under the scene (:mod:`gsverse_format.physics`, spec §Physics).
"""
from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

import numpy as np

from .binding import BindResult, bind_local
from .convert_options import ConvertOptions, ConvertSummary, object_name
from .errors import BindingError, FormatError, GsverseError, UsageError
from .io.mesh import read_mesh
from .io.registry import FRAMES
from .model import (
    Anchoring,
    Collider,
    Ground,
    Physics,
    SplatAsset,
    SplatCloud,
    SplatPrimitive,
    TriangleMesh,
    face_order,
)
from .progress import Progress
from .transform import rotate_mesh

__all__ = [
    "anchor_scene",
    "bind_scene",
    "distance_stats",
    "face_distances",
    "finish_physics",
    "judge_fit",
    "object_name",
    "prepare_mesh",
    "read_scene_meshes",
]


def distance_stats(distance: np.ndarray, diagonal: float) -> dict[str, float]:
    """Percentiles of splat-to-mesh distances (the summary's ``distance``)."""
    if distance.size == 0:
        return {}
    p50, p95, p99 = np.percentile(distance, [50, 95, 99])
    return {"p50": float(p50), "p95": float(p95), "p99": float(p99),
            "max": float(distance.max()), "mesh_diagonal": float(diagonal)}


def face_distances(splats: SplatCloud, mesh: TriangleMesh, face_index: np.ndarray) -> np.ndarray:
    """Each splat's distance to its own triangle ``face_index`` of ``mesh`` (float64)."""
    from .nearest import closest_points_on_triangles

    tri = mesh.triangles()[face_index.astype(np.intp)]
    _, _, dist = closest_points_on_triangles(splats.means.astype(np.float64), tri[:, 0],
                                             tri[:, 1], tri[:, 2])
    return dist


def _diagonal(mesh: TriangleMesh) -> float:
    lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    return float(np.linalg.norm(hi.astype(np.float64) - lo))


def read_scene_meshes(paths: list[str], frame: str, frame_change: bool,
                      edit: Callable[[TriangleMesh], TriangleMesh] | None = None
                      ) -> list[TriangleMesh]:
    """The meshes of ``paths`` in the glTF frame, from the source's ``frame`` (as the source's
    own mesh is rotated), or as they are without ``frame_change``; ``edit`` is applied to
    each in the source's frame, before the rotation (``--mesh-translate`` and the like)."""
    meshes = [read_mesh(p) for p in paths]
    if edit is not None:
        meshes = [edit(m) for m in meshes]
    if frame_change and FRAMES[frame].name != "gltf":
        meshes = [rotate_mesh(m, FRAMES[frame].to_gltf) for m in meshes]
    return meshes


def normalize_skin_weights(mesh: TriangleMesh, path: str, options: ConvertOptions,
                           summary: ConvertSummary) -> None:
    """The skin weights of ``mesh``'s rig (from ``path``, a ``--mesh``) normalized in place,
    as readers use them (:func:`gsverse_format.rig.normalized_weights`), with a summary note
    on the vertices that changed. Refused (:class:`FormatError` naming ``path``): negative
    weights, vertices whose weights are all zero (no joint moves them: which one to bind them
    to is the author's choice), and with ``options.strict`` any vertex whose weights do not sum
    to 1."""
    from dataclasses import replace

    from .rig import WEIGHT_SUM_TOLERANCE, normalized_weights

    rig = mesh.rig
    if rig is None or rig.weights_0 is None:
        return
    w = np.asarray(rig.weights_0, dtype=np.float64)
    if not np.all(np.isfinite(w)):
        raise FormatError("non-finite skin weights (WEIGHTS_0)", path)
    negative = np.flatnonzero((w < 0).any(axis=1))
    if negative.size:
        raise FormatError(f"negative skin weights (WEIGHTS_0) on {negative.size} vertices "
                          f"(vertex {negative[0]} first); glTF 2.0 forbids them", path)
    fixed = normalized_weights(w)
    if fixed.all_zero.size:
        raise FormatError(f"{fixed.all_zero.size} vertices have skin weights (WEIGHTS_0) that "
                          f"are all zero (vertex {fixed.all_zero[0]} first): no joint moves "
                          f"them; weight them to a joint in the mesh's file", path)
    mesh.rig = replace(rig, weights_0=fixed.weights.astype(np.float32))
    if not fixed.changed:
        return
    text = (f"the skin weights (WEIGHTS_0) of {fixed.changed} of {len(w)} vertices do not sum "
            f"to 1 (off by up to {fixed.max_sum_error:.3g}; glTF 2.0: within "
            f"{WEIGHT_SUM_TOLERANCE:g})")
    if options.strict:
        raise FormatError(f"{text} (--strict)", path)
    summary.notes.append(f"{os.path.basename(path)}: {text}: normalized them, as readers do "
                         f"(each vertex's weights divided by their sum; weights changed by up "
                         f"to {fixed.max_change:.3g})")


def bind_scene(splats: SplatCloud, meshes: list[TriangleMesh], *, deformation: str = "affine",
               progress: Callable[[int, int], None] | None = None,
               paths: list[str] | None = None) -> tuple[np.ndarray, list[BindResult]]:
    """Each splat's nearest mesh (index into ``meshes``; ties to the first) and every mesh's
    binding of all splats (:func:`bind_local`); a binding error names ``paths[j]``."""
    bound = []
    for j, mesh in enumerate(meshes):
        try:
            bound.append(bind_local(splats, mesh, deformation=deformation, progress=progress))
        except GsverseError as exc:
            raise (exc.with_path(paths[j]) if paths else exc) from None
    owner = np.argmin(np.stack([b.distance for b in bound]), axis=0) if len(splats) \
        else np.zeros(0, np.intp)
    return owner, bound


def judge_fit(means: np.ndarray, mesh: TriangleMesh, distance: np.ndarray, name: str,
              path: str, options: ConvertOptions, summary: ConvertSummary) -> None:
    """Whether ``mesh`` belongs to the splats at ``means`` (each at ``distance`` from it):
    :func:`gsverse_format.fit.assess_fit`, recorded in ``summary.fit``. A misfit is a
    :class:`~gsverse_format.fit.MeshFitWarning` naming ``path`` and a summary note; with
    ``options.strict`` a :class:`BindingError` instead (nothing is written)."""
    import warnings

    from .fit import MeshFitWarning, assess_fit

    if len(means) == 0:
        return
    report = assess_fit(means, mesh.vertices, distance)
    summary.fit.append({"mesh": name, "path": path, **report.as_dict()})
    if report.ok:
        return
    text = f"the anchor mesh does not fit the splats: {report.message()}"
    if options.strict:
        raise BindingError(f"{text} (--strict)", path)
    summary.notes.append(f"{name}: {text}")
    warnings.warn(f"{path}: {text}", MeshFitWarning, stacklevel=2)


def prepare_mesh(mesh: TriangleMesh, options: ConvertOptions, summary: ConvertSummary,
                 path: str, progress: Progress | None = None) -> TriangleMesh:
    """``--watertight``: ``mesh`` made a closed 2-manifold (a note says what was done)."""
    if not options.watertight:
        return mesh
    from .manifold import make_watertight

    if progress is not None:
        progress.stage(f"repairing {object_name(path)}'s anchor mesh (--watertight)")
    try:
        repaired, what = make_watertight(mesh)
    except GsverseError as exc:
        raise exc.with_path(path) from None
    summary.notes.append(f"--watertight ({object_name(path)}): {what}")
    return repaired


def finish_physics(asset: SplatAsset, options: ConvertOptions,
                   summary: ConvertSummary) -> Callable[[], None]:
    """The manifold report of each written anchor mesh into ``summary.anchor_meshes``,
    ``--collider`` meshes into ``asset.colliders``, ``--physics`` (each such object's
    :class:`~gsverse_format.model.Physics`, with a hull collider whether or not ``--collider``
    asks for one) and ``--ground`` (:func:`gsverse_format.physics.ground_box` under every
    splat).

    The manifold reports are computed on threads of their own
    (:class:`~gsverse_format.manifold.BackgroundReport`) while the caller goes on (writes the
    output); each entry of ``summary.anchor_meshes`` has the report's keys, set to None until
    the returned function is called, which waits for the reports and fills them in."""
    from dataclasses import fields

    from .convert_options import physics_request
    from .manifold import BackgroundReport, ManifoldReport, collider

    kinds, masses = physics_request(summary.input, options)
    scene = bool(options.meshes)
    seen: dict[int, Collider | None] = {}
    pending: list[tuple[dict[str, Any], BackgroundReport]] = []
    for prim in asset.anchored:
        assert prim.anchoring is not None
        mesh = prim.anchoring.mesh
        name = prim.name if scene else next(iter(kinds), None)
        kind = kinds.get(name) if name is not None else None
        if id(mesh) not in seen:
            entry: dict[str, Any] = {"name": prim.name, "faces": mesh.face_count,
                                     **dict.fromkeys(f.name for f in fields(ManifoldReport)),
                                     "collider": None}
            pending.append((entry, BackgroundReport(mesh)))
            made = None
            hull_kind = options.collider or ("hull" if kind is not None else None)
            if hull_kind is not None:
                made = Collider(collider(mesh, hull_kind), mesh, hull_kind)
                asset.colliders.append(made)
                entry["collider"] = {"kind": hull_kind, "faces": made.mesh.face_count}
            seen[id(mesh)] = made
            summary.anchor_meshes.append(entry)
        made = seen[id(mesh)]
        if kind is None or name is None:
            continue
        if made is None:  # a mesh shared with an object without physics
            made = Collider(collider(mesh, "hull"), mesh, "hull")
            asset.colliders.append(made)
            seen[id(mesh)] = made
        prim.physics = Physics(kind, masses.get(name))
        summary.physics.append({"name": prim.name, "kind": kind, "mass": masses.get(name),
                                "collider": {"kind": made.kind,
                                             "faces": made.mesh.face_count}})
    missing = sorted(set(kinds) - {p.name for p in asset.anchored} if scene else ())
    if missing:
        summary.notes.append(f"--physics: {', '.join(missing)} has no anchored splats, so no "
                             f"body is written for it")
    if options.ground:
        from .physics import ground_box

        size, centre = ground_box(np.concatenate([p.splats.means for p in asset.primitives]))
        asset.ground = Ground(size, centre)
        summary.ground = {"size": list(size), "translation": list(centre),
                          "top": centre[1] + size[1] / 2}

    def complete() -> None:
        for entry, report in pending:
            entry.update(report.result().as_dict())

    return complete


def anchor_scene(result: Any, meshes: list[TriangleMesh], paths: list[str],
                 options: ConvertOptions, progress: Progress,
                 summary: ConvertSummary) -> SplatAsset:
    """Step 6 for several objects (see the module docstring): ``meshes`` in the splats'
    frame, one per path of ``paths``."""
    splats = result.splats
    if result.anchors is not None:
        raise UsageError(f"several --mesh need free splats; the {summary.source} source comes "
                         f"with its own binding", summary.input)
    if options.sh_degree is not None and splats.sh_degree > options.sh_degree:
        splats = splats.with_sh_degree(options.sh_degree)
    ready = []
    for mesh, path in zip(meshes, paths):
        if options.faces is not None and mesh.face_count > options.faces:
            from .meshops import decimate, decimation_shortfall

            progress.stage(f"decimating {object_name(path)}: {mesh.face_count} -> "
                           f"{options.faces} faces")
            try:
                mesh = decimate(mesh, options.faces)
            except GsverseError as exc:
                raise exc.with_path(path) from None
            shortfall = decimation_shortfall(mesh, options.faces)
            if shortfall is not None:
                summary.notes.append(f"{object_name(path)}: {shortfall}")
        ready.append(prepare_mesh(mesh, options, summary, path, progress))
    progress.stage(f"binding to the nearest triangles of {len(ready)} objects")
    owner, bound = bind_scene(splats, ready, deformation=options.deformation,
                              progress=progress.update, paths=paths)
    summary.mesh_faces = sum(m.face_count for m in ready)
    summary.degenerate_faces = sum(b.degenerate_faces for b in bound)
    summary.profile = "local"
    summary.deformation = options.deformation

    anchored = np.zeros(len(splats), bool)
    primitives = []
    for j, (mesh, path, b) in enumerate(zip(ready, paths, bound)):
        mine = owner == j
        # each object is judged on the splats nearest to it (those it could be given)
        judge_fit(splats.means[mine], mesh, b.distance[mine], object_name(path), path,
                  options, summary)
        diagonal = _diagonal(mesh)
        limit = None
        if options.max_distance is not None:
            limit = options.max_distance if options.absolute_distance \
                else options.max_distance * diagonal
            mine &= b.distance <= limit
        idx = np.flatnonzero(mine)
        if not options.keep_order:
            idx = idx[face_order(b.anchors.face_index[idx])]
        anchored[idx] = True
        name = object_name(path)
        summary.objects.append({
            "name": name, "mesh": path, "splats": int(idx.size), "faces": mesh.face_count,
            "degenerate_faces": b.degenerate_faces, "max_distance": limit,
            "distance": distance_stats(b.distance[idx], diagonal)})
        if idx.size:
            primitives.append(SplatPrimitive(splats.subset(idx),
                                             Anchoring(mesh, b.anchors.subset(idx)), name,
                                             result.khr))
        else:
            summary.notes.append(f"no splat is anchored to {name} ({path}): its mesh is not "
                                 f"written")
    return with_static_rest(primitives, splats, result.khr, np.flatnonzero(~anchored), options,
                            summary, "every mesh", "are the meshes")


def input_stem(summary: ConvertSummary) -> str:
    """The name of the converted asset's primitives: the input's file stem."""
    return os.path.splitext(os.path.basename(summary.input.rstrip(os.sep)))[0] or "splats"


def with_static_rest(primitives: list[SplatPrimitive], splats: SplatCloud, khr: Any,
                     far_idx: np.ndarray, options: ConvertOptions, summary: ConvertSummary,
                     from_what: str, frame_question: str) -> SplatAsset:
    """The asset of the anchored ``primitives`` and the splats of ``splats`` that stay
    unanchored (``far_idx``; ``splats`` as the anchored ones were taken from, after
    ``--sh-degree``): one plain static primitive with the KHR properties ``khr``, or dropped
    with ``--drop-unanchored``; an asset left with nothing is refused
    (``from_what``/``frame_question`` word the message)."""
    if far_idx.size:
        if options.drop_unanchored:
            summary.dropped = int(far_idx.size)
        else:
            primitives.append(SplatPrimitive(splats.subset(far_idx), None,
                                             f"{input_stem(summary)} static", khr))
    if not primitives:
        raise BindingError(f"all {len(splats)} splats are farther than --max-distance from "
                           f"{from_what}, so --drop-unanchored leaves nothing to write "
                           f"({frame_question} in the splats' frame?)", summary.input)
    return SplatAsset(primitives)
