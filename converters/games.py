"""GaMeS / GS-Verse source: splats parameterized on the triangles of a mesh.

What GaMeS writes (``waczjoan/gaussian-mesh-splatting``) and GS-Verse consumes
------------------------------------------------------------------------------
* ``point_cloud/iteration_<N>/point_cloud.ply`` — a standard 3DGS PLY whose means, rotations and
  scales GaMeS derived from the mesh; opacity and SH are learned. Splat ``i`` belongs to face
  ``i // k`` (face-major, k = ``--num_splats``).
* ``model_params.pt`` beside it — ``_alpha`` (F×k×3, raw), ``_scale`` (N×1, raw ρ), ``vertices``,
  ``faces`` (the multi-mesh variant stores one entry per mesh in lists).
* GS-Verse's ``scripts/import_params.py`` turns that into ``model_params.json`` =
  ``{"_alpha": F×k×3 nested lists, "_scale": N×1}``, shipped with ``point_cloud.ply`` and the
  training ``mesh.obj``.

GaMeS normalizes α = (relu(α̂) + 1e-8) / Σ (relu(α̂) + 1e-8) and puts the mean at α·(v0, v1, v2);
its frame and scales follow the ``games`` profile of the spec, with ρ multiplying all three base
scales — so the stored anchors are exactly (face, α1, α2, raw ρ).

Frames
------
GaMeS's NeRF-synthetic reader maps ``mesh.obj`` vertices (x, y, z) → (x, −z, y) before training
(Blender's Z-up world); its COLMAP multi-mesh reader uses the OBJ as is. The loader finds out
which by comparing α·triangles with the PLY means under both maps, and returns everything in
that training frame, naming it: ``"z-up"`` for the NeRF-synthetic case (the pipeline rotates it
into glTF by (x, y, z) → (x, z, −y), so the mesh comes back as the OBJ holds it), ``"3dgs"`` for
COLMAP (180° about +Z, as for any 3DGS PLY). The splats' SH are rotated with them.

The rest pose returned is the ``games`` remap at the rest mesh (opacity and SH from the PLY), so
that it agrees with the anchors by construction; ``check`` reports how far it is from the PLY's
own means and covariances (GaMeS adds ε = 1e-8 to its normalization denominators and computes in
float32, the spec normalizes exactly).
"""
from __future__ import annotations

import glob
import json
import os
import re

import numpy as np

from gsverse_format.converters.base import SourceOptions, SourceResult, require_splats
from gsverse_format.converters.checkpoint import as_array, load_torch_checkpoint
from gsverse_format.converters.registry import register_source
from gsverse_format.errors import FormatError
from gsverse_format.frames import GAMES_EPS, degenerate_mask
from gsverse_format.io.mesh import read_mesh
from gsverse_format.io.ply import read_splat_ply
from gsverse_format.io.registry import FRAMES, Z_UP_TO_GLTF
from gsverse_format.model import Anchoring, GamesAnchors, SplatCloud, TriangleMesh
from gsverse_format.remapping.reference import RemapResult, remap
from gsverse_format.tolerances import mesh_extent, rest_mean_tolerance
from gsverse_format.transform import rotate_mesh, rotate_splats

__all__ = ["load", "detect", "normalize_alpha", "BLENDER_MESH_TO_TRAINING", "Z_UP_TO_GLTF"]

#: GaMeS's NeRF-synthetic reader: mesh.obj (x, y, z) -> training frame (x, −z, y).
BLENDER_MESH_TO_TRAINING = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])

#: GaMeS frame -> (mesh.obj -> training frame, description, the training frame's name in
#: :data:`gsverse_format.io.registry.FRAMES`).
_FRAMES = {
    "colmap": (np.eye(3), "COLMAP (mesh used as is)", "3dgs"),
    "blender": (BLENDER_MESH_TO_TRAINING,
                "NeRF-synthetic/Blender (GaMeS maps mesh.obj (x, y, z) to (x, -z, y), Z up)",
                "z-up"),
}
_MESH_FIX = ("pass the mesh GaMeS was trained with (--mesh <dataset>/mesh.obj for NeRF-synthetic "
             "scenes, <dataset>/sparse/0/<name>.obj for COLMAP ones)")


def normalize_alpha(raw: np.ndarray) -> np.ndarray:
    """GaMeS's weights from raw α̂ (..., 3): (relu(α̂) + 1e-8) / Σ (relu(α̂) + 1e-8), float64."""
    a = np.maximum(np.asarray(raw, dtype=np.float64), 0.0) + GAMES_EPS
    return a / a.sum(axis=-1, keepdims=True)


# --------------------------------------------------------------------------------------------
# Finding the files


def _iteration(path: str) -> int:
    match = re.search(r"iteration_(\d+)", path)
    return int(match.group(1)) if match else -1


def _locate(input_path: str) -> tuple[str, list[str], list[str]]:
    """(point_cloud.ply, folders to search for model_params and mesh.obj, notes)."""
    notes: list[str] = []
    if os.path.isdir(input_path):
        ply = os.path.join(input_path, "point_cloud.ply")
        if not os.path.isfile(ply):
            found = glob.glob(os.path.join(glob.escape(input_path), "point_cloud", "iteration_*",
                                           "point_cloud.ply"))
            found = [p for p in found if _iteration(os.path.basename(os.path.dirname(p))) >= 0]
            if not found:
                raise FormatError("no point_cloud.ply here nor in point_cloud/iteration_*/; pass "
                                  "GaMeS's output folder, a GS-Verse export folder, or the "
                                  "point_cloud.ply itself", input_path)
            ply = max(found, key=lambda p: _iteration(os.path.basename(os.path.dirname(p))))
            if len(found) > 1:
                notes.append(f"used the highest of {len(found)} iterations: "
                             f"{os.path.basename(os.path.dirname(ply))}")
        _inside_run(ply, input_path)
        folders = [os.path.dirname(ply), input_path]
    elif os.path.isfile(input_path):
        ply = input_path
        folders = [os.path.dirname(os.path.abspath(ply))]
    else:
        raise FormatError("file not found", input_path)
    unique: list[str] = []
    for folder in folders:
        if os.path.abspath(folder) not in [os.path.abspath(u) for u in unique]:
            unique.append(folder)
    return ply, unique, notes


def _inside_run(found: str, root: str) -> None:
    """Refuse a file found in the run folder ``root`` that is a symbolic link (or lies under
    one) to a file outside it: like the glTF reader's buffer URIs, a run folder only brings
    in files inside it. Files named on the command line (``--mesh``, ``--pt``) are the user's
    choice and not checked."""
    folder = os.path.realpath(root)
    real = os.path.realpath(found)
    if not real.startswith(folder.rstrip(os.sep) + os.sep):
        raise FormatError(f"is a symbolic link to {real}, outside the run folder {root}: only "
                          "files inside it are read (copy the file in, or name it with --mesh "
                          "or --pt)", found)


def _first(folders: list[str], name: str) -> str | None:
    """The first ``name`` in ``folders`` (the last of which is the run folder, or the
    folder of the input PLY); it must lie inside that folder."""
    for folder in folders:
        candidate = os.path.join(folder, name)
        if os.path.isfile(candidate):
            _inside_run(candidate, folders[-1])
            return candidate
    return None


# --------------------------------------------------------------------------------------------
# model_params


class _Params:
    """Raw GaMeS parameters: per-mesh α̂ blocks, ρ, and (from a .pt) the trained mesh."""

    def __init__(self, alpha: list[np.ndarray], scale: np.ndarray, path: str,
                 mesh: TriangleMesh | None = None, frame: str | None = None):
        self.alpha, self.scale, self.path, self.mesh, self.frame = alpha, scale, path, mesh, frame


def _unwrap(value, depth: int):
    """GS-Verse's import script unwraps one-element lists (multi-mesh runs); do the same."""
    while isinstance(value, (list, tuple)) and len(value) == 1 and _depth(value) > depth:
        value = value[0]
    return value


def _depth(value) -> int:
    d = 0
    while isinstance(value, (list, tuple)) and value:
        value, d = value[0], d + 1
    return d


def _read_json(path: str) -> _Params:
    try:
        with open(path, "rb") as f:
            data = json.load(f)
    except (OSError, ValueError, RecursionError) as exc:
        raise FormatError(f"cannot read JSON: {exc}".splitlines()[0], path) from None
    if not isinstance(data, dict) or "_alpha" not in data or "_scale" not in data:
        raise FormatError("not a GaMeS model_params.json (needs the keys _alpha and _scale, as "
                          "GS-Verse's scripts/import_params.py writes them)", path)
    alpha = as_array(_unwrap(data["_alpha"], 3), "_alpha", path).astype(np.float64)
    scale = as_array(_unwrap(data["_scale"], 2), "_scale", path).astype(np.float64)
    return _Params([alpha], scale.reshape(-1), path)


def _read_pt(path: str) -> _Params:
    data = load_torch_checkpoint(path)
    if not isinstance(data, dict) or "_alpha" not in data or "_scale" not in data:
        raise FormatError("not a GaMeS model_params.pt (needs the keys _alpha and _scale)", path)
    multi = isinstance(data["_alpha"], (list, tuple))

    def listed(key):
        value = data.get(key)
        if value is None:
            return None
        return list(value) if isinstance(value, (list, tuple)) else [value]

    alpha = [as_array(a, "_alpha", path).astype(np.float64) for a in listed("_alpha")]
    scales = [as_array(s, "_scale", path).astype(np.float64).reshape(-1) for s in listed("_scale")]
    if len(scales) != len(alpha):
        raise FormatError(f"{len(alpha)} _alpha blocks but {len(scales)} _scale blocks", path)
    scale = np.concatenate(scales) if scales else np.zeros(0)
    vertices, faces = listed("vertices"), listed("faces")
    mesh = None
    if vertices is not None and faces is not None:
        if len(vertices) != len(alpha) or len(faces) != len(alpha):
            raise FormatError(f"{len(alpha)} _alpha blocks but {len(vertices)} vertex and "
                              f"{len(faces)} face arrays", path)
        all_v, all_f, offset = [], [], 0
        for v, f in zip(vertices, faces):
            v = as_array(v, "vertices", path).astype(np.float64).reshape(-1, 3)
            f = as_array(f, "faces", path).astype(np.int64).reshape(-1, 3)
            if f.size and (f.min() < 0 or f.max() >= len(v)):
                raise FormatError(f"faces reference vertex {int(f.max())} of {len(v)}", path)
            if not np.all(np.isfinite(v)):
                raise FormatError("vertices hold NaN or Inf", path)
            all_v.append(v)
            all_f.append(f + offset)
            offset += len(v)
        mesh = TriangleMesh(np.concatenate(all_v).astype(np.float32), np.concatenate(all_f))
    # gs_mesh (one mesh, NeRF-synthetic reader) stores tensors; gs_multi_mesh (COLMAP) lists.
    return _Params(alpha, scale, path, mesh, "colmap" if multi else "blender")


def _read_params(path: str) -> _Params:
    return _read_pt(path) if path.lower().endswith((".pt", ".pth")) else _read_json(path)


def _layout(params: _Params, n_ply: int, f_mesh: int, options: SourceOptions, ply: str,
            mesh_name: str) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """(face index (N,), normalized α (N, 3), splats per face of each block)."""
    path = params.path
    blocks = params.alpha
    if len(blocks) == 1 and blocks[0].ndim == 2:           # flattened (N, 3)
        a = blocks[0]
        if a.shape[1] != 3:
            raise FormatError(f"_alpha has shape {a.shape}, expected (faces, k, 3)", path)
        k = options.k or (a.shape[0] // f_mesh if f_mesh and a.shape[0] % f_mesh == 0 else None)
        if not k or a.shape[0] % k:
            raise FormatError(f"_alpha is flat ({a.shape[0]} rows) and {f_mesh} mesh faces do not "
                              "divide it; set --k (GaMeS's --num_splats)", path)
        blocks = [a.reshape(-1, k, 3)]
    faces_total = 0
    face_blocks, alphas, ks = [], [], []
    for a in blocks:
        if a.ndim != 3 or a.shape[2] != 3:
            raise FormatError(f"_alpha has shape {a.shape}, expected (faces, k, 3)", path)
        f, k = a.shape[0], a.shape[1]
        if options.k is not None and k != options.k:
            raise FormatError(f"_alpha holds {k} splats per face, not --k {options.k}; drop --k "
                              "or pass the parameters of the matching run", path)
        face_blocks.append(np.repeat(np.arange(faces_total, faces_total + f, dtype=np.int64), k))
        alphas.append(a.reshape(-1, 3))
        ks.append(k)
        faces_total += f
    face_index = np.concatenate(face_blocks) if face_blocks else np.zeros(0, np.int64)
    raw = np.concatenate(alphas) if alphas else np.zeros((0, 3))
    if not np.all(np.isfinite(raw)) or not np.all(np.isfinite(params.scale)):
        raise FormatError("_alpha or _scale holds NaN or Inf", path)
    if faces_total != f_mesh:
        raise FormatError(f"model parameters describe {faces_total} faces but the mesh has "
                          f"{f_mesh}: not the mesh of this run; " + _MESH_FIX, mesh_name)
    if len(face_index) != n_ply:
        raise FormatError(f"the PLY has {n_ply} splats but the model parameters describe "
                          f"{len(face_index)} ({faces_total} faces × "
                          f"{'/'.join(map(str, sorted(set(ks))))}"
                          "); they come from different runs or iterations: use the "
                          "model_params saved beside this point_cloud.ply", ply)
    if params.scale.size != n_ply:
        raise FormatError(f"_scale has {params.scale.size} values for {n_ply} splats", path)
    return face_index, normalize_alpha(raw), ks


# --------------------------------------------------------------------------------------------
# Loader


def _mean_error(alpha: np.ndarray, face_index: np.ndarray, mesh: TriangleMesh,
                rotation: np.ndarray, means: np.ndarray) -> float:
    tri = mesh.triangles() @ np.asarray(rotation, np.float64).T
    mu = np.einsum("nm,nmx->nx", alpha, tri[face_index])
    return float(np.max(np.linalg.norm(mu - means, axis=1))) if len(face_index) else 0.0


def _diagonal(mesh: TriangleMesh) -> float:
    v = mesh.vertices.astype(np.float64)
    return float(np.linalg.norm(v.max(axis=0) - v.min(axis=0))) if len(v) else 0.0


def _detect_frame(alpha: np.ndarray, face_index: np.ndarray, mesh: TriangleMesh,
                  cloud: SplatCloud, params: _Params, mesh_name: str,
                  ply: str) -> tuple[str, dict[str, float]]:
    """(frame name, {frame: max mean error}) — the frame whose α·triangles give the PLY means."""
    means = cloud.means.astype(np.float64)
    tol = rest_mean_tolerance(*mesh_extent(mesh))
    if params.mesh is not None:  # trained vertices from the .pt: already in the training frame
        assert params.frame is not None
        err = _mean_error(alpha, face_index, mesh, np.eye(3), means)
        if err > tol:
            raise FormatError(f"α·triangles of the checkpoint's vertices miss the PLY means by up "
                              f"to {err:.3g} ({err / max(_diagonal(mesh), 1e-300):.2g} of the mesh "
                              "diagonal): the PLY and model_params.pt come from different "
                              "iterations; use the pair saved together", ply)
        return params.frame, {params.frame: err}
    errors = {name: _mean_error(alpha, face_index, mesh, rot, means)
              for name, (rot, _, _) in _FRAMES.items()}
    best = min(errors, key=errors.__getitem__)
    if errors[best] > tol:
        d = max(_diagonal(mesh), 1e-300)
        listed = ", ".join(f"{errors[k]:.3g} ({errors[k] / d:.2g} of the diagonal) {k}"
                           for k in _FRAMES)
        raise FormatError(f"α·triangles of this mesh miss the PLY means in both frames GaMeS uses "
                          f"(max error {listed}; expected ≤ {tol:.2g}): it is not the "
                          "training mesh, its faces were reordered, or its vertices were trained "
                          "(--vertices_lr > 0: pass model_params.pt, which holds them); "
                          + _MESH_FIX, mesh_name)
    return best, errors


def _compare(rest: RemapResult, cloud: SplatCloud, diagonal: float,
             to_gltf: np.ndarray) -> dict[str, float]:
    """How far the rebuilt rest pose lies from the PLY's splats, measured in the glTF frame
    (where the written file holds them): ``to_gltf`` takes the training frame there."""
    r = np.asarray(to_gltf, np.float64)
    means, covariances = rest.means @ r.T, r @ rest.covariances @ r.T
    cloud = rotate_splats(cloud, r)
    if len(cloud) == 0:
        return {"max_mean_error": 0.0, "max_mean_error_rel": 0.0, "max_mean_error_rel_splat": 0.0,
                "max_cov_rel_error": 0.0}
    err = np.linalg.norm(means - cloud.means.astype(np.float64), axis=1)
    size = np.max(cloud.scales.astype(np.float64), axis=1)
    ref = cloud.covariances()
    num = np.linalg.norm(covariances - ref, axis=(1, 2))
    den = np.linalg.norm(ref, axis=(1, 2))
    cov = num / np.where(den > 0.0, den, 1.0)
    return {"max_mean_error": float(err.max()),
            "max_mean_error_rel": float(err.max() / diagonal) if diagonal > 0 else 0.0,
            "max_mean_error_rel_splat": float(np.max(err / np.where(size > 0, size, 1.0))),
            "max_cov_rel_error": float(cov.max()),
            "p99_cov_rel_error": float(np.percentile(cov, 99))}


def load(input_path: str, mesh_path: str | None, options: SourceOptions) -> SourceResult:
    """Load GaMeS / GS-Verse output: a folder or ``point_cloud.ply`` with ``model_params``
    (``.json``, or ``.pt`` with PyTorch) and the training mesh; see the module docstring."""
    input_path = os.fspath(input_path)
    ply, folders, notes = _locate(input_path)

    params_path: str | None
    if options.pt_path is not None:
        params_path = os.fspath(options.pt_path)
        if not os.path.isfile(params_path):
            raise FormatError("file not found", params_path)
    else:
        params_path = _first(folders, "model_params.json") or _first(folders, "model_params.pt")
        if params_path is None:
            raise FormatError(f"no model_params.json or model_params.pt beside "
                              f"{os.path.basename(ply)}: GaMeS saves model_params.pt next to "
                              "point_cloud.ply (GS-Verse's scripts/import_params.py makes "
                              "model_params.json from it); put it there or pass it with --pt", ply)
    cloud = read_splat_ply(ply)
    require_splats(cloud, ply)
    params = _read_params(params_path)
    notes.append(f"GaMeS parameters from {os.path.basename(params_path)}")

    mesh_name: str | None
    if params.mesh is not None:
        mesh, mesh_name = params.mesh, params_path
        notes.append("anchor mesh = the trained vertices and faces of the checkpoint"
                     + ("; --mesh was not needed" if mesh_path is not None else ""))
    else:
        mesh_name = os.fspath(mesh_path) if mesh_path is not None else _first(folders, "mesh.obj")
        if mesh_name is None:
            raise FormatError("no mesh.obj beside the splats: GaMeS splats need the mesh they were "
                              "trained on; " + _MESH_FIX, ply)
        mesh = read_mesh(mesh_name)

    face_index, alpha, ks = _layout(params, len(cloud), mesh.face_count, options, ply, mesh_name)
    frame, frame_errors = _detect_frame(alpha, face_index, mesh, cloud, params, mesh_name, ply)
    k_text = "/".join(map(str, sorted(set(ks)))) or "0"
    notes.append(f"GaMeS binding: {k_text} splat(s) per face on {mesh.face_count} faces; "
                 f"frame {_FRAMES[frame][1]}")

    if params.mesh is None:   # mesh.obj -> the training frame of the PLY
        mesh = rotate_mesh(mesh, _FRAMES[frame][0])

    anchors = GamesAnchors(face_index.astype(np.uint32), alpha[:, 1:], params.scale)
    rest = remap(Anchoring(mesh, anchors))
    splats = SplatCloud(rest.means, rest.rotations, rest.scales, cloud.opacities, cloud.sh,
                        cloud.color_space, dict(cloud.extra))

    diagonal = _diagonal(mesh)
    degenerate = int(np.count_nonzero(degenerate_mask(mesh.triangles())))
    check = {"frame": frame, "k": ks[0] if len(set(ks)) == 1 else ks, "faces": mesh.face_count,
             "mesh_diagonal": diagonal, "frame_mean_errors": frame_errors,
             "degenerate_faces": degenerate}
    check.update(_compare(rest, cloud, diagonal, FRAMES[_FRAMES[frame][2]].to_gltf))
    notes.append(f"rest pose rebuilt from the mesh: PLY means reproduced within "
                 f"{check['max_mean_error']:.2g} ({check['max_mean_error_rel']:.2g} of the mesh "
                 f"diagonal), covariances within {check['max_cov_rel_error']:.2g} (relative)")
    if degenerate:
        notes.append(f"{degenerate} face(s) of the mesh are degenerate; their splats follow the "
                     "spec's fallback frame")
    return SourceResult(splats, mesh, anchors, notes, check, frame=_FRAMES[frame][2],
                        inputs=(ply, params_path, mesh_name))


def detect(input_path: str, mesh_path: str | None) -> str | None:
    """A folder, or a PLY with GaMeS's model_params beside it."""
    if os.path.isdir(input_path):
        return "input is a folder (GaMeS / GS-Verse output)"
    folder = os.path.dirname(os.path.abspath(input_path))
    beside = ("model_params.json", "model_params.pt")
    if os.path.splitext(input_path)[1].lower() == ".ply" and any(
            os.path.isfile(os.path.join(folder, name)) for name in beside):
        return "model_params.json/.pt beside the PLY (GaMeS / GS-Verse)"
    return None


register_source("games", load, detect=detect, priority=10)
