"""SuGaR source: a refined SuGaR Gaussian PLY and the refined mesh it was trained on.

What SuGaR writes (``Anttwo/SuGaR``, refinement stage)
------------------------------------------------------
* ``refined_ply/<scene>/sugarfine_…_gaussperface<k>.ply`` — a standard 3DGS PLY (SH degree 3)
  whose splat ``i`` sits on triangle ``i // k`` of the refined mesh, in slot ``i % k``. The
  slot's position is fixed by a barycentric table (:data:`SLOT_BARYCENTRICS`, k = 1, 3, 4 or 6),
  so every mean lies exactly on its triangle; the splat is flat (``scale_0`` = log of a tiny
  "thickness" along the face normal).
* ``refined_mesh/<scene>/sugarfine_….obj`` — the refined vertices with the faces in training
  order (vertices may be split at UV seams by OBJ readers; only the face order matters here).
  It is written with 6 decimal places, so it matches the PLY to about 1e-6 scene units.
* ``refined/<scene>/…/<iterations>.pt`` — the checkpoint: ``state_dict['_points']`` (refined
  vertices, float32) and ``state_dict['_surface_mesh_faces']``; exact, when PyTorch is at hand.

The coarse mesh (``coarse_mesh/<scene>/sugarmesh_….ply``) has the same faces but the vertices
from *before* refinement, and ``--postprocess_mesh`` removes faces from the OBJ after the PLY
was written: both are detected and refused with the fix.

The binding is known exactly, so no nearest-triangle search is needed: the loader returns
``local`` anchors whose barycentrics are SuGaR's slot values, whose normal offset is the
(tiny) measured offset of the mean from the triangle's plane, and whose rotation is the splat's
rotation relative to the triangle's rest frame (spec §Writing anchors) — so the remap at rest
gives back the PLY splats. Splats on faces that are degenerate at rest (which the spec forbids
as anchors) are bound to their nearest regular face instead.

All SuGaR outputs are in the 3DGS/COLMAP frame: the loader returns splats, mesh and anchors in
it (``frame`` ``"3dgs"``), and the pipeline rotates them into glTF's frame like any 3DGS PLY
(180° about +Z; the anchors, relative to their triangles, do not change).
"""
from __future__ import annotations

import os
import re
from typing import Any

import numpy as np

from gsverse_format import quaternion as quat
from gsverse_format.binding import bind_local
from gsverse_format.converters.base import SourceOptions, SourceResult, require_splats
from gsverse_format.converters.checkpoint import as_array, load_torch_checkpoint
from gsverse_format.converters.registry import register_source
from gsverse_format.errors import FormatError, GsverseError
from gsverse_format.frames import local_frames
from gsverse_format.io.mesh import read_mesh
from gsverse_format.io.ply import describe_ply, read_splat_means, read_splat_ply
from gsverse_format.model import Anchoring, DeformationLaw, LocalAnchors, SplatCloud, TriangleMesh
from gsverse_format.remapping.reference import remap
from gsverse_format.tolerances import mesh_extent, rest_mean_tolerance

__all__ = ["SLOT_BARYCENTRICS", "load", "detect", "matches_layout", "slot_barycentrics",
           "face_anchors", "load_torch_checkpoint", "rest_errors", "mean_tolerance"]

#: SuGaR's slot table: row j = barycentric weights (w0, w1, w2) of corners (v0, v1, v2) for
#: slot j of a triangle carrying k splats. SuGaR holds them as float32.
SLOT_BARYCENTRICS = {
    1: ((1 / 3, 1 / 3, 1 / 3),),
    3: ((1 / 2, 1 / 4, 1 / 4), (1 / 4, 1 / 2, 1 / 4), (1 / 4, 1 / 4, 1 / 2)),
    4: ((1 / 3, 1 / 3, 1 / 3), (2 / 3, 1 / 6, 1 / 6), (1 / 6, 2 / 3, 1 / 6), (1 / 6, 1 / 6, 2 / 3)),
    6: ((2 / 3, 1 / 6, 1 / 6), (1 / 6, 2 / 3, 1 / 6), (1 / 6, 1 / 6, 2 / 3),
        (1 / 6, 5 / 12, 5 / 12), (5 / 12, 1 / 6, 5 / 12), (5 / 12, 5 / 12, 1 / 6)),
}
SLOTS = tuple(sorted(SLOT_BARYCENTRICS))

#: Absolute rounding of the refined OBJ (SuGaR writes it with 6 decimal places).
OBJ_ROUNDING = 5e-7

_REFINED_FIX = ("pass the refined mesh (--mesh refined_mesh/<scene>/sugarfine_*.obj) or the "
                "refined checkpoint (--pt refined/<scene>/.../<iterations>.pt)")


def slot_barycentrics(k: int) -> np.ndarray:
    """(k, 3) float32 slot weights (w0, w1, w2) of SuGaR for ``k`` splats per face."""
    if k not in SLOT_BARYCENTRICS:
        raise ValueError(f"SuGaR places 1, 3, 4 or 6 splats per face, not {k}")
    return np.asarray(SLOT_BARYCENTRICS[k], dtype=np.float32)


def face_anchors(splats: SplatCloud, mesh: TriangleMesh, face_index: np.ndarray,
                 barycentrics: np.ndarray,
                 deformation: DeformationLaw = "affine") -> LocalAnchors:
    """``local`` anchors of splats whose face and barycentric position are known.

    ``face_index`` (N,) gives each splat's triangle, ``barycentrics`` (N, 2) its weights (b1, b2) on
    corners 1 and 2. The normal offset is the signed distance of the mean from the plane
    through the barycentric point along the rest normal; rotation and scale are stored as
    :func:`gsverse_format.binding.bind_local` stores them (rotation relative to the triangle's
    rest frame, scale as is), so that the remap at rest reproduces the splats up to the
    in-plane distance between each mean and its barycentric point.
    """
    face = np.asarray(face_index, dtype=np.intp)
    b = np.asarray(barycentrics, dtype=np.float32).astype(np.float64)
    tri = mesh.triangles()
    frames = local_frames(tri)
    v0 = tri[face, 0]
    foot = v0 + b[:, 0:1] * (tri[face, 1] - v0) + b[:, 1:2] * (tri[face, 2] - v0)
    rot = frames.rotation[face]
    offset = np.einsum("ni,ni->n", splats.means.astype(np.float64) - foot, rot[:, :, 2])
    q_frame = quat.from_matrix(rot)
    q_local = quat.canonical_sign(quat.multiply(quat.conjugate(q_frame),
                                                quat.normalize(splats.rotations)))
    return LocalAnchors(face.astype(np.uint32), b, offset, q_local, splats.scales, deformation)


def rest_errors(splats: SplatCloud, mesh: TriangleMesh, anchors: LocalAnchors) -> dict[str, float]:
    """Pose ``anchors`` at the rest mesh and compare with ``splats``.

    At rest the ``local`` remap reduces to mean = v0 + b1 e1 + b2 e2 + d n_r and rotation
    R_r R_l with scale s_l (G = I, k = 1, both laws), evaluated here in float64 from the stored
    float32 anchors without the per-splat SVD; splats on faces degenerate at rest, where the
    spec's fallback applies, go through :func:`gsverse_format.remapping.reference.remap`. Returns
    ``max_mean_error`` (scene units), ``max_mean_error_rel`` (÷ the mesh's bounding-box diagonal)
    and ``max_cov_rel_error`` (max over splats of ‖ΔΣ‖_F / ‖Σ‖_F).
    """
    if len(splats) == 0:
        return {"max_mean_error": 0.0, "max_mean_error_rel": 0.0, "max_cov_rel_error": 0.0}
    tri = mesh.triangles()
    frames = local_frames(tri)
    face = anchors.face_index.astype(np.intp)
    b = anchors.barycentrics.astype(np.float64)
    v0 = tri[face, 0]
    rot = frames.rotation[face]
    means = (v0 + b[:, 0:1] * (tri[face, 1] - v0) + b[:, 1:2] * (tri[face, 2] - v0)
             + anchors.normal_offset.astype(np.float64)[:, None] * rot[:, :, 2])
    scale = anchors.local_scale.astype(np.float64)
    rs = (rot @ quat.to_matrix(anchors.local_rotation)) * scale[:, None, :]
    cov = rs @ np.swapaxes(rs, 1, 2)
    fallback = ~frames.regular[face]
    if np.any(fallback):
        posed = remap(Anchoring(mesh, anchors.subset(fallback)))
        means[fallback], cov[fallback] = posed.means, posed.covariances
    err = np.linalg.norm(means - splats.means.astype(np.float64), axis=1)
    ref = splats.covariances()
    num = np.linalg.norm(cov - ref, axis=(1, 2))
    den = np.linalg.norm(ref, axis=(1, 2))
    rel = num / np.where(den > 0.0, den, 1.0)
    diagonal = _diagonal(mesh)
    return {"max_mean_error": float(err.max()),
            "max_mean_error_rel": float(err.max() / diagonal) if diagonal > 0 else 0.0,
            "max_cov_rel_error": float(rel.max())}


def mean_tolerance(mesh: TriangleMesh) -> float:
    """Largest acceptable distance between a source's mean and its anchored position: the
    spec's rest-pose bound (:func:`gsverse_format.tolerances.rest_mean_tolerance`)."""
    return rest_mean_tolerance(*mesh_extent(mesh))


def _diagonal(mesh: TriangleMesh) -> float:
    return mesh_extent(mesh)[0]


def _mesh_from_checkpoint(pt_path: str) -> TriangleMesh:
    data = load_torch_checkpoint(pt_path)
    state = data.get("state_dict", data) if isinstance(data, dict) else None
    if not isinstance(state, dict) or "_points" not in state or "_surface_mesh_faces" not in state:
        raise FormatError("not a refined SuGaR checkpoint (no state_dict entries _points and "
                          "_surface_mesh_faces); pass the refined .pt from refined/<scene>/", pt_path)
    vertices = as_array(state["_points"], "_points", pt_path).astype(np.float64)
    faces = as_array(state["_surface_mesh_faces"], "_surface_mesh_faces", pt_path)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or faces.ndim != 2 or faces.shape[1] != 3:
        raise FormatError(f"_points {vertices.shape} / _surface_mesh_faces {faces.shape} are not "
                          "(V, 3) / (F, 3)", pt_path)
    if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise FormatError(f"_surface_mesh_faces reference vertex {int(faces.max())} of "
                          f"{len(vertices)}", pt_path)
    if not np.all(np.isfinite(vertices)):
        raise FormatError("_points holds NaN or Inf", pt_path)
    return TriangleMesh(vertices.astype(np.float32), faces.astype(np.int64))


# --------------------------------------------------------------------------------------------
# Loader


def _k_hint(input_path: str, options: SourceOptions) -> tuple[int | None, str]:
    if options.k is not None:
        return int(options.k), "--k"
    match = re.search(r"gaussperface(\d+)", os.path.basename(input_path))
    if match:
        return int(match.group(1)), "the file name"
    return None, ""


def _unless(k: int, source: str) -> str:
    return f" (unless --k {k} is wrong)" if source == "--k" else ""


def _splats_per_face(n: int, f: int, input_path: str, mesh_name: str,
                     options: SourceOptions) -> int:
    """k with n = k·f, or a FormatError explaining which mesh or option is wrong."""
    hint, source = _k_hint(input_path, options)
    if hint is not None:
        if hint not in SLOT_BARYCENTRICS:
            raise FormatError(f"k = {hint} (from {source}) splats per face, but SuGaR places 1, 3, "
                              "4 or 6 per face; set --k to the gaussperface value of the run",
                              input_path)
        if n % hint:
            raise FormatError(f"the PLY has {n} splats, not a multiple of k = {hint} (from "
                              f"{source}): not a refined SuGaR PLY, or a different k; set --k to "
                              "the gaussperface value of the run", input_path)
        expected = n // hint
        if f < expected:
            raise FormatError(f"the mesh has {f} faces but the PLY has {n} splats = {hint}×"
                              f"{expected} faces{_unless(hint, source)}; the mesh was probably "
                              "post-processed (--postprocess_mesh drops faces after the PLY is "
                              "written); export it without post-processing, or " + _REFINED_FIX,
                              mesh_name)
        if f > expected:
            raise FormatError(f"the mesh has {f} faces but the PLY has {n} splats = {hint}×"
                              f"{expected} faces: this mesh belongs to another run (or k = {hint} "
                              f"from {source} is wrong); " + _REFINED_FIX, mesh_name)
        return hint
    if f == 0 or n % f:
        bigger = [f"{k}×{n // k}" for k in SLOTS if n % k == 0 and n // k > f]
        guess = f" ({n} = {' or '.join(bigger)} faces)" if bigger else ""
        raise FormatError(f"the mesh has {f} faces but the PLY has {n} splats, not k×{f} for k in "
                          f"1, 3, 4, 6{guess}; the mesh was probably post-processed "
                          "(--postprocess_mesh drops faces); export it without post-processing, "
                          "or " + _REFINED_FIX + "; if k differs, set --k", mesh_name)
    k = n // f
    if k not in SLOT_BARYCENTRICS:
        raise FormatError(f"the PLY has {n} splats on {f} faces = {k} per face, but SuGaR places "
                          "1, 3, 4 or 6 per face: the mesh or the PLY comes from another run; "
                          + _REFINED_FIX + " of the same run, or set --k", mesh_name)
    return k


def _verify_means(means: np.ndarray, mesh: TriangleMesh, face_index: np.ndarray,
                  weights: np.ndarray, k: int, mesh_name: str,
                  explain: bool = True) -> tuple[float, float]:
    """Max distance of the PLY ``means`` from their slot positions (absolute, ÷ diagonal).
    Raises :class:`FormatError` beyond the tolerance: with the median distance and the likely
    cause, or, when not ``explain`` (source detection, which only needs the verdict), without
    them (the first ``np.median`` of a process costs 6–13 ms)."""
    tri = mesh.triangles()
    slot = np.einsum("nm,nmx->nx", weights.astype(np.float64), tri[face_index])
    err = np.linalg.norm(means.astype(np.float64) - slot, axis=1)
    extent = mesh_extent(mesh)
    diagonal = extent[0]
    worst = float(err.max()) if err.size else 0.0
    rel = worst / diagonal if diagonal > 0 else (0.0 if worst == 0 else np.inf)
    tolerance = rest_mean_tolerance(*extent)      # mean_tolerance(mesh), the extent computed once
    if worst <= tolerance:
        return worst, rel
    if not explain:
        raise FormatError(f"the PLY means lie up to {worst:.3g} from their slot positions",
                          mesh_name)
    median = float(np.median(err))
    said = (f"with k = {k}, the PLY means lie up to {worst:.3g} (median {median:.3g}; "
            f"{rel:.2g} of the mesh diagonal) from their slot positions on the mesh, expected "
            f"≤ {tolerance:.2g}")
    if worst <= tolerance + 4 * OBJ_ROUNDING and mesh_name.lower().endswith(".obj"):
        raise FormatError(f"{said}: that is the rounding of an OBJ written with 6 decimal places, "
                          "too coarse for a scene this small; pass the refined checkpoint "
                          "(--pt refined/<scene>/.../<iterations>.pt)", mesh_name)
    raise FormatError(f"{said}: this looks like the coarse mesh (sugarmesh_*.ply) or a re-exported "
                      "mesh (moved vertices or reordered faces); " + _REFINED_FIX, mesh_name)


def matches_layout(ply_path: str, mesh_path: str, info: dict[str, Any]) -> bool:
    """Whether a PLY (header summary ``info`` from ``describe_ply``) and a mesh look like a
    refined SuGaR PLY and its mesh, for source auto-detection.

    True for SuGaR's file names (``…gaussperface<k>.ply`` or ``sugarfine_*`` meshes), so that
    mismatched SuGaR files get SuGaR's diagnostics. Otherwise, for SH degree 3 PLYs only, the
    mesh is read and the splat count must be k × its face count (k in 1, 3, 4, 6) with the
    means at SuGaR's slot positions.
    """
    if re.search(r"gaussperface\d+", os.path.basename(ply_path)) or \
            os.path.basename(mesh_path).lower().startswith("sugarfine"):
        return True
    if info.get("sh_degree") != 3:
        return False
    try:
        mesh = read_mesh(mesh_path)
        n, f = int(info.get("count", -1)), mesh.face_count
        if f == 0 or n <= 0 or n % f or n // f not in SLOT_BARYCENTRICS:
            return False
        k = n // f
        means = read_splat_means(ply_path)      # the positions alone: nothing else is needed
        # the splats of the first 256 faces first: they turn down most other sources at once
        # (a 100k-splat 3DGS PLY with as many faces: 50 ms of slot positions saved)
        head = min(f, 256)
        for faces in (head, f) if head < f else (f,):
            _verify_means(means[:faces * k], mesh, np.repeat(np.arange(faces), k),
                          np.tile(slot_barycentrics(k), (faces, 1)), k, os.fspath(mesh_path),
                          explain=False)
    except GsverseError:
        return False
    return True


def load(input_path: str, mesh_path: str | None, options: SourceOptions) -> SourceResult:
    """Load a refined SuGaR PLY with its refined mesh (``mesh_path``) or checkpoint
    (``options.pt_path``); see the module docstring."""
    input_path = os.fspath(input_path)
    if mesh_path is None and options.pt_path is None:
        raise FormatError("SuGaR splats need the refined mesh they were trained on: "
                          + _REFINED_FIX, input_path)
    splats = read_splat_ply(input_path)
    require_splats(splats, input_path)
    notes: list[str] = []
    if options.pt_path is not None:
        mesh_name = os.fspath(options.pt_path)
        mesh = _mesh_from_checkpoint(mesh_name)
        notes.append("anchor mesh from the refined checkpoint (_points, _surface_mesh_faces)"
                     + ("; the --mesh file was not needed" if mesh_path is not None else ""))
    else:
        assert mesh_path is not None
        mesh_name = os.fspath(mesh_path)
        mesh = read_mesh(mesh_name)

    n, f = len(splats), mesh.face_count
    k = _splats_per_face(n, f, input_path, mesh_name, options)
    table = slot_barycentrics(k)
    face = np.repeat(np.arange(f, dtype=np.intp), k)
    weights = np.tile(table, (f, 1))
    worst, rel = _verify_means(splats.means, mesh, face, weights, k, mesh_name)
    notes.append(f"SuGaR binding: {k} splat(s) per face on {f} faces, slot positions match the "
                 f"PLY means within {worst:.2g} ({rel:.2g} of the mesh diagonal)")

    anchors = face_anchors(splats, mesh, face, weights[:, 1:])
    regular = local_frames(mesh.triangles()).regular
    on_degenerate = ~regular[face]
    moved = int(np.count_nonzero(on_degenerate))
    if moved:
        try:
            bound = bind_local(splats.subset(on_degenerate), mesh).anchors
        except GsverseError as exc:
            raise exc.with_path(mesh_name)
        for name in ("face_index", "barycentrics", "normal_offset", "local_rotation", "local_scale"):
            getattr(anchors, name)[on_degenerate] = getattr(bound, name)
        notes.append(f"{moved} splat(s) on {int(np.count_nonzero(~regular))} face(s) degenerate at "
                     "rest were bound to their nearest regular face instead")

    check = {"k": k, "faces": f, "mesh_diagonal": _diagonal(mesh),
             "ply_to_slot_max_error": worst, "ply_to_slot_max_error_rel": rel,
             "splats_rebound_from_degenerate_faces": moved}
    check.update(rest_errors(splats, mesh, anchors))
    return SourceResult(splats, mesh, anchors, notes, check, frame="3dgs")


def detect(input_path: str, mesh_path: str | None) -> str | None:
    """A PLY and a mesh in SuGaR's layout (:func:`matches_layout`)."""
    if mesh_path is None or os.path.splitext(input_path)[1].lower() != ".ply":
        return None
    if matches_layout(input_path, mesh_path, describe_ply(input_path)):
        return "splat count is k x face count with SuGaR's slot positions"
    return None


register_source("sugar", load, detect=detect, priority=30)
