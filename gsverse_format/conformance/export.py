"""``gsverse-conformance export DIR``: write the conformance suite as language-neutral files.

Suite layout (all binary arrays are raw little-endian, row-major, no header; ``.f32`` is
IEEE float32, ``.f64`` IEEE float64)::

    DIR/suite.json                      index: version, case list, tags, counts
    DIR/LAYOUT.md                       the file and dump layout (this docstring, expanded)
    DIR/cases/<id>/case.json            manifest: what the case tests, files, tolerances
    DIR/cases/<id>/asset.glb            the asset to import (one anchored splat primitive)
    DIR/cases/<id>/poses/pose_NNN.f32   (V, 3) anchor-mesh vertex positions of pose NNN
    DIR/cases/<id>/poses/deformed_NNN.f32  rig cases: (V, 3) vertices p' of pose NNN as skinning
                                        or morphing outputs them (.rig_poses)
    DIR/cases/<id>/expected/...         float64 reference outputs (see LAYOUT.md)
    DIR/cases/<id>/skinned.glb          skinned cases: the animation the poses come from
    DIR/cases/<id>/reference/*.png      render cases: the reference pictures (.render_export)

Expected outputs come from the float64 reference (:mod:`gsverse_format.remapping.reference`),
evaluated on exactly the values stored in the files: the anchors as read back from ``asset.glb``
(dequantized) and the float32 poses.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from ..version import __version__
from ..errors import UsageError
from ..frames import EPS_DEGENERATE, local_frames
from ..io.gltf import asset_to_gltf, gltf_to_bytes
from ..model import (Anchoring, GamesAnchors, LocalAnchors, SplatAsset, SplatCloud,
                     SplatPrimitive)
from ..remapping.reference import face_matrices, prepare_rest, remap
from . import cases as case_defs
from . import cases_rig as rig_defs
from . import invalid_cases as invalid_defs
from . import cases_spz as spz_defs
from .spz_export import uncompressed_expectation
from .harness import cov6, read_asset
from .glb import pack_glb, patch_accessor, unpack_glb
from .render_export import export_render_cases
from .case_tools import Pose
from .rig_poses import DEFORMED_FILE, RigPose, rig_pose_list

__all__ = ["export_suite", "SUITE_VERSION", "F32_UNIT_ROUNDOFF", "cov6", "LAYOUT_TEXT"]

SUITE_VERSION = 3  # suite format 3: spec v1.1/1.2 rules and tolerances, and the render level
#: u = 2⁻²⁴, the float32 unit roundoff: tolerances are stated in multiples of it.
F32_UNIT_ROUNDOFF = 2.0 ** -24
#: ‖Σ − Σ_ref‖_F is measured against max(‖Σ_ref‖_F, COV_FLOOR · ‖Σ_rest‖_F).
COV_FLOOR = 1e-3
#: Base relative covariance tolerance (well-conditioned triangles and deformations).
COV_BASE = 4e-6
_KHR = "KHR_gaussian_splatting"
_ANCHOR = "GSVERSE_gaussian_splatting_mesh_anchor"
_CTYPE = {5120: "BYTE", 5121: "UNSIGNED_BYTE", 5122: "SHORT", 5123: "UNSIGNED_SHORT",
          5125: "UNSIGNED_INT", 5126: "FLOAT"}


def _ceil2(x: float) -> float:
    """``x`` rounded up to two significant digits (tolerances are stated this way)."""
    if x <= 0 or not math.isfinite(x):
        return x
    e = math.floor(math.log10(x)) - 1
    return float(f"{math.ceil(x / 10 ** e - 1e-9) * 10 ** e:.3g}")


def _write(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)


def _write_array(path: Path, array: np.ndarray, dtype: str) -> None:
    _write(path, np.ascontiguousarray(array, dtype=np.dtype(dtype).newbyteorder("<")).tobytes())


# --------------------------------------------------------------------------- tolerances

MEAN_REASON = (
    "float32 arithmetic on positions: a float32 implementation rounds the coordinates it "
    "forms, so its mean is off by about one unit of float32 roundoff u = 2^-24 of the "
    "largest coordinate and lever arm involved; 8 u (X + lever) allows 8 such roundings "
    "(X = largest vertex or mean norm, lever = largest |b1||e1| + |b2||e2| + |d| k). The "
    "normal offset d m (m = (e1 x e2) / sqrt(a_c a_r)) inherits the float32 error of the "
    "cross product of the current edges, about u |e1||e2| absolute: Y_normal = largest "
    "|d| min(8 u P / sqrt(a_c a_r), 6 sqrt(u P / a_r)) over splats and poses (P = |e1||e2|; "
    "the second form bounds it near zero area, where the square root is ill-conditioned); on "
    "faces degenerate at rest (m = n_c) |d| min(2, 8 u P / a_c) while a_c > eps_deg l^2 / 2.")
COV_REASON = (
    "relative Frobenius error per splat. 4e-6 (about 67 u) covers float32 evaluation on "
    "well-conditioned triangles and deformations (measured errors near 5e-7, quaternion and "
    "dequantization round trips included) with margin, and is 25x below the rest-pose "
    "consistency bound of the spec (1e-4); 32 u kappa_triangle adds the float32 error of the "
    "cross product of a thin triangle (kappa_triangle = l^2/a over regular faces and faces "
    "within a factor 2 below the degenerate threshold), 32 u kappa_deformation the "
    "error of an ill-conditioned deformation gradient G (ratio of its largest to smallest "
    "singular value). When a triangle collapses the covariance collapses with it; the error "
    "is then measured against 1e-3 of the splat's rest covariance instead of a vanishing "
    "number. On current faces below half the degenerate threshold (local profile) the float32 "
    "scaled normal m is uncertain by dm = min(8 u P / sqrt(a_c a_r), 6 sqrt(u P / a_r)) "
    "(P = |e1||e2|): Z_normal = largest sqrt(3) (2 ||A||_2 + dm) dm, a tolerance relative to "
    "the splat's rest covariance.")
RIG_MEAN_REASON = (
    "Rig cases: the expected outputs come from the float64 splat-local vertices (M^-1 p'); "
    "an implementation reads or computes p' in float32 first, so X also covers the largest "
    "|p'|.")
OPACITY_REASON = ("pass-through: the remap never changes opacity; 2^-23 only admits a "
                  "conversion through another floating-point type in the harness.")
SH_REASON = ("pass-through: the remap never changes SH coefficients (they are not rotated "
             "with the splat); 2^-23 max(1, |x|) only admits a conversion through another "
             "floating-point type in the harness.")


def _normal_error(rest, tri: np.ndarray, face: np.ndarray):
    """Per splat: the float32 error bound of the scaled normal m (faces regular at rest),
    min(8 u P / sqrt(a_c a_r), 6 sqrt(u P / a_r)), its counterpart on faces degenerate at rest
    (the tilt of n_c, min(2, 8 u P / a_c) while a_c > eps_deg l^2 / 2, else 0), and whether the
    current face is below half the degenerate threshold (outside kappa_triangle's reach)."""
    u = F32_UNIT_ROUNDOFF
    e1 = tri[face, 1] - tri[face, 0]
    e2 = tri[face, 2] - tri[face, 0]
    p = np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
    a_c = np.linalg.norm(np.cross(e1, e2), axis=1)
    longest2 = np.max(np.stack([np.einsum("ij,ij->i", e, e) for e in (e1, e2, e2 - e1)]), axis=0)
    reg = rest.regular[face]
    a_r = np.where(reg, rest.area2[face], 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        first = np.where(a_c > 0, 8 * u * p / np.sqrt(a_c * a_r), np.inf)
        regular_term = np.minimum(first, 6 * np.sqrt(u * p / a_r))
        tilt = np.where(a_c > 0, 8 * u * p / a_c, np.inf)
        degenerate_term = np.where(a_c > 0.5 * EPS_DEGENERATE * longest2, np.minimum(2.0, tilt), 0.0)
    low = a_c <= 0.5 * EPS_DEGENERATE * longest2
    return reg, np.where(reg, regular_term, degenerate_term), low


def _normal_terms(anchors: LocalAnchors, rest, tri: np.ndarray, face: np.ndarray,
                  a: np.ndarray) -> tuple[float, float]:
    """Y_normal (see MEAN_REASON) and Z_normal (see COV_REASON)."""
    reg, dm, low = _normal_error(rest, tri, face)
    y = np.abs(anchors.normal_offset.astype(np.float64)) * dm
    # ||dSigma||_F <= (2 ||A||_2 + dm) dm sum s^2 <= sqrt(3) (2 ||A||_2 + dm) dm ||Sigma_rest||_F
    norm_a = np.linalg.norm(a[face], ord=2, axis=(1, 2))
    z = np.where(reg & low, np.sqrt(3.0) * (2 * norm_a + dm) * dm, 0.0)
    return (float(np.max(y)) if len(y) else 0.0), (float(np.max(z)) if len(z) else 0.0)


def _condition_terms(anchoring: Anchoring, poses: list[np.ndarray],
                     expected_means: list[np.ndarray]) -> dict[str, float]:
    mesh, anchors = anchoring.mesh, anchoring.anchors
    face = anchors.face_index.astype(np.intp)
    used = np.unique(face)
    local = anchors if isinstance(anchors, LocalAnchors) else None
    rest = prepare_rest(mesh.triangles()) if local is not None else None
    b = anchors.barycentrics.astype(np.float64)
    d = (np.abs(local.normal_offset.astype(np.float64)) if local is not None
         else np.zeros(len(face)))
    x = max(float(np.max(np.linalg.norm(m, axis=1))) for m in expected_means)
    lever = y = y_normal = z_normal = 0.0
    k_tri = k_g = 1.0
    for verts in poses:
        tri = mesh.triangles(verts)
        x = max(x, float(np.max(np.linalg.norm(verts.astype(np.float64), axis=1))))
        fr = local_frames(tri)
        edges = np.stack([tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], tri[:, 2] - tri[:, 1]], 1)
        longest = np.linalg.norm(edges, axis=2).max(axis=1)
        # regular faces, and degenerate ones within a factor 2 of the threshold (a float32
        # implementation may classify those either way: the rigid frame is then uncertain)
        near = (fr.area2 > 0.5 * EPS_DEGENERATE * longest ** 2)[used]
        if np.any(near):
            k_tri = max(k_tri, float(np.max(longest[used][near] ** 2 / fr.area2[used][near])))
        e1 = np.linalg.norm(edges[face, 0], axis=1)
        e2 = np.linalg.norm(edges[face, 1], axis=1)
        if local is not None and rest is not None:
            safe = np.where(rest.regular[face], rest.area2[face], 1.0)
            k = np.where(rest.regular[face], np.sqrt(fr.area2[face] / safe), 1.0)
            _, _, a_law = face_matrices(rest, fr, tri, local.deformation)
            yn, zn = _normal_terms(local, rest, tri, face, a_law)
            y_normal, z_normal = max(y_normal, yn), max(z_normal, zn)
        else:
            k = np.zeros(len(face))
        lever = max(lever, float(np.max(np.abs(b[:, 0]) * e1 + np.abs(b[:, 1]) * e2 + d * k)))
        y = max(y, float(np.max(d * k)))
        if local is not None and rest is not None and local.deformation == "affine":
            sv = np.linalg.svd(a_law[used], compute_uv=False)
            top = sv[:, 0]
            low = np.where(sv[:, 2] > 1e-12 * top, sv[:, 2],
                           np.where(sv[:, 1] > 1e-12 * top, sv[:, 1], top))
            ok = top > 0
            if np.any(ok):
                k_g = max(k_g, float(np.max(top[ok] / low[ok])))
    return {"X": x, "lever": lever, "Y": y, "Y_normal": y_normal, "Z_normal": z_normal,
            "kappa_triangle": k_tri, "kappa_deformation": k_g}


def _tolerance_values(terms: dict[str, float]) -> tuple[float, float, float]:
    u = F32_UNIT_ROUNDOFF
    mean = 8 * u * (terms["X"] + terms["lever"]) + terms["Y_normal"]
    cov = COV_BASE + 32 * u * (terms["kappa_triangle"] + terms["kappa_deformation"])
    return _ceil2(mean), _ceil2(cov), _ceil2(terms["Z_normal"])


def _tolerances(terms: dict[str, float], per_pose: list[dict[str, float]]) -> dict:
    mean, cov, rest_rtol = _tolerance_values(terms)
    pose_values = [_tolerance_values(t) for t in per_pose]
    rounded = {k: float(f"{v:.6g}") for k, v in terms.items()}
    return {
        "mean": {"atol": mean, "unit": "scene units",
                 "per_pose": [m for m, _, _ in pose_values],
                 "metric": "|mean - mean_ref| (Euclidean) <= atol, per splat and pose (atol of "
                           "the pose from per_pose; the rest dump uses pose 0's)",
                 "formula": "8 u (X + lever) + Y_normal, u = 2^-24",
                 "terms": {k: rounded[k] for k in ("X", "lever", "Y", "Y_normal")},
                 "reason": MEAN_REASON},
        "covariance": {"rtol": cov, "floor": COV_FLOOR, "rest_rtol": rest_rtol,
                       "per_pose": [c for _, c, _ in pose_values],
                       "rest_rtol_per_pose": [r for _, _, r in pose_values],
                       "metric": "||S - S_ref||_F <= rtol * max(||S_ref||_F, floor * "
                                 "||S_rest_ref||_F) + rest_rtol * ||S_rest_ref||_F, per splat and "
                                 "pose (rtol and rest_rtol of the pose from per_pose and "
                                 "rest_rtol_per_pose; the rest dump uses pose 0's)",
                       "formula": "rtol = 4e-6 + 32 u (kappa_triangle + kappa_deformation), "
                                  "rest_rtol = Z_normal, u = 2^-24",
                       "terms": {k: rounded[k] for k in ("kappa_triangle", "kappa_deformation",
                                                         "Z_normal")},
                       "reason": COV_REASON},
        "opacity": {"atol": 2.0 ** -23, "metric": "|o - o_ref| <= atol", "reason": OPACITY_REASON},
        "sh": {"atol": 2.0 ** -23, "rtol": 2.0 ** -23,
               "metric": "|c - c_ref| <= atol + rtol |c_ref| per coefficient",
               "reason": SH_REASON},
    }


# --------------------------------------------------------------------------- remap cases

def _splat_accessors(doc: dict) -> tuple[dict, dict]:
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            khr = prim.get("extensions", {}).get(_KHR)
            if khr is not None and _ANCHOR in khr.get("extensions", {}):
                return prim["attributes"], khr["extensions"][_ANCHOR]
    raise RuntimeError("no anchored primitive in the exported asset")


def _initial_asset(case: case_defs.RemapCase) -> SplatAsset:
    anchoring = Anchoring(case.mesh, case.anchors)
    r = remap(anchoring)
    if isinstance(case.anchors, LocalAnchors):
        # local_scale itself (so that the writer shares the accessor), except on faces
        # degenerate at rest, where the remap at rest changes the scales
        regular = local_frames(case.mesh.triangles()).regular[case.anchors.face_index]
        scales = np.where(regular[:, None], case.anchors.local_scale, r.scales)
    else:
        scales = r.scales
    cloud = SplatCloud(r.means, r.rotations, scales, case.opacities, case.sh)
    return SplatAsset([SplatPrimitive(cloud, anchoring, name=case.id)], "gsverse-conformance")


def _consistent_asset(case: case_defs.RemapCase, path: Path) -> SplatPrimitive:
    """Write the asset; if quantization changed the anchors, rewrite the stored rest pose from
    the anchors as stored (so that the file is rest-consistent); return it as read back."""
    data = gltf_to_bytes(asset_to_gltf(_initial_asset(case), quantize=case.quantize,
                                       anchors=case.encoding, compress=case.compress))
    _write(path, data)
    # derived anchors come from the stored rest pose: consistent by construction
    derived = "barycentrics" not in _splat_accessors(unpack_glb(data)[0])[1]
    prim = read_asset(str(path)).primitives[0]
    r = remap(prim.anchoring)
    means = r.means.astype(np.float32)
    rots = r.rotations.astype(np.float32)
    games = isinstance(prim.anchoring.anchors, GamesAnchors)
    same = np.array_equal(means, prim.splats.means) and np.array_equal(rots, prim.splats.rotations)
    if games:
        same = same and np.array_equal(r.scales.astype(np.float32), prim.splats.scales)
    if not same and not derived:
        doc, blob = unpack_glb(data)
        attrs, ext = _splat_accessors(doc)
        blob = patch_accessor(doc, blob, attrs["POSITION"], means)
        blob = patch_accessor(doc, blob, attrs[f"{_KHR}:ROTATION"], rots)
        if games:
            blob = patch_accessor(doc, blob, attrs[f"{_KHR}:SCALE"], r.scales.astype(np.float32))
        _write(path, pack_glb(doc, blob))
        prim = read_asset(str(path)).primitives[0]
    if case.edit is not None:
        doc, blob = case.edit(*unpack_glb(path.read_bytes()))
        _write(path, pack_glb(doc, blob))
        prim = read_asset(str(path)).primitives[0]
    return prim


def _anchor_summary(path: Path) -> dict:
    doc, _ = unpack_glb(path.read_bytes())
    _, ext = _splat_accessors(doc)
    anchor_prim = doc["meshes"][ext["mesh"]]["primitives"][ext.get("primitive", 0)]
    out = {"profile": ext["profile"]}
    if "deformation" in ext:
        out["deformation"] = ext["deformation"]
    out["mesh"] = ext["mesh"]
    out["primitive"] = ext.get("primitive", 0)
    out["vertex_count"] = doc["accessors"][anchor_prim["attributes"]["POSITION"]]["count"]
    indexed = anchor_prim.get("indices") is not None
    out["indexed"] = indexed
    out["face_count"] = (doc["accessors"][anchor_prim["indices"]]["count"] if indexed
                         else out["vertex_count"]) // 3
    types = {}
    out["face_encoding"] = "faceCounts" if "faceCounts" in ext else "faceIndex"
    out["derived"] = ext["profile"] == "local" and "barycentrics" not in ext
    for key in ("faceIndex", "faceCounts", "barycentrics", "normalOffset", "localRotation",
                "localScale", "rho"):
        if key in ext:
            acc = doc["accessors"][ext[key]]
            types[key] = _CTYPE[acc["componentType"]] + (" normalized" if acc.get("normalized")
                                                           else "")
    out["component_types"] = types
    return out


def _export_remap(case: case_defs.RemapCase, case_dir: Path) -> dict:
    asset_path = case_dir / "asset.glb"
    prim = _consistent_asset(case, asset_path)
    anchoring = prim.anchoring
    if anchoring is None:
        raise RuntimeError(f"{case.id}: the exported asset has no anchoring")
    splats = prim.splats
    n = len(splats)
    files: dict[str, Any] = {"asset": "asset.glb", "poses": [], "expected": {}}
    rest_cov = splats.covariances()
    exp = case_dir / "expected"
    _write_array(exp / "rest.means.f64", splats.means.astype(np.float64), "f8")
    _write_array(exp / "rest.cov.f64", cov6(rest_cov), "f8")
    _write_array(exp / "rest.opacity.f32", splats.opacities, "f4")
    _write_array(exp / "rest.sh.f32", splats.sh, "f4")
    files["expected"]["rest"] = {"means": "expected/rest.means.f64", "cov": "expected/rest.cov.f64",
                                 "opacity": "expected/rest.opacity.f32",
                                 "sh": "expected/rest.sh.f32"}
    pose_arrays: list[np.ndarray] = []
    means_list: list[np.ndarray] = [splats.means.astype(np.float64)]
    poses_meta: list[dict[str, Any]] = []
    expected_poses: list[dict[str, str]] = []
    rig = rig_pose_list(case, asset_path) if case.rig is not None else None
    poses: list[Pose | RigPose] = list(rig.poses) if rig is not None else list(case.poses)
    for p, pose in enumerate(poses):
        stem = f"pose_{p:03d}"
        meta: dict[str, Any] = {"index": p, "label": pose.label}
        if isinstance(pose, RigPose):   # p' shipped, expected from the float64 local vertices
            _write_array(case_dir / DEFORMED_FILE.format(p), pose.deformed, "f4")
            meta["deformed"] = DEFORMED_FILE.format(p)
        else:
            _write_array(case_dir / "poses" / f"{stem}.f32", pose.vertices, "f4")
            meta["file"] = f"poses/{stem}.f32"
        meta["source"] = pose.source
        r = remap(anchoring, pose.vertices)
        if not (np.all(np.isfinite(r.means)) and np.all(np.isfinite(r.covariances))):
            raise RuntimeError(f"{case.id}: reference output is not finite at pose {p}")
        _write_array(exp / f"{stem}.means.f64", r.means, "f8")
        _write_array(exp / f"{stem}.cov.f64", cov6(r.covariances), "f8")
        pose_arrays.append(pose.vertices)
        means_list.append(r.means)
        poses_meta.append(meta)
        expected_poses.append({"means": f"expected/{stem}.means.f64",
                               "cov": f"expected/{stem}.cov.f64"})
    if rig is not None:   # no splat-local pose files: a harness must do M^-1 itself
        del files["poses"]
        files["deformed"] = [m["deformed"] for m in poses_meta]
    else:
        files["poses"] = [m["file"] for m in poses_meta]
    files["expected"]["poses"] = expected_poses
    if case.skinned_asset is not None:
        _write(case_dir / "skinned.glb", case.skinned_asset)
        files["skinned_asset"] = "skinned.glb"
    per_pose = [_condition_terms(anchoring, [verts], [means_list[0], means])
                for verts, means in zip(pose_arrays, means_list[1:])]
    # every term is a maximum over splats and poses: the case's terms are the poses' largest
    if rig is not None:   # an implementation rounds p' (the deformed file) before M^-1
        for t, pose in zip(per_pose, rig.poses):
            t["X"] = max(t["X"], float(np.max(np.linalg.norm(pose.deformed, axis=1))))
    terms = {key: max(t[key] for t in per_pose) for key in per_pose[0]}
    extra: dict[str, Any] = {}
    if case.validator_codes:
        extra = {"validator_codes": case.validator_codes, "note": case.note}
    if rig is not None:
        extra["rig"] = rig.layout
    if case.compress:   # the second expectation: the remap of the uncompressed rest pose
        extra["compression"] = uncompressed_expectation(
            _initial_asset(case), prim, asset_path, pose_arrays, case_dir, _write_array, cov6,
            read_asset)
    tolerances = _tolerances(terms, per_pose)
    if rig is not None:
        tolerances["mean"]["reason"] += " " + RIG_MEAN_REASON
    return {
        "id": case.id,
        "suite_version": SUITE_VERSION,
        "kind": "remap" if rig is None else "rig",
        "description": case.description,
        "tags": case.tags,
        "expect": "remap",
        **extra,
        "splat_count": n,
        "sh_degree": splats.sh_degree,
        "sh_coefficients": int(splats.sh.shape[1]),
        "anchor": _anchor_summary(asset_path),
        "pose_count": len(case.poses),
        "poses": poses_meta,
        "files": files,
        "tolerances": tolerances,
    }


# --------------------------------------------------------------------------- invalid cases

def _base_glb(kind: str, cache: dict, tmp: Path) -> bytes:
    if kind not in cache:
        base = invalid_defs.invalid_base_case(kind)
        path = tmp / f"base-{kind}.glb"
        _consistent_asset(base, path)
        cache[kind] = path.read_bytes()
    return cache[kind]


def _export_invalid(case: invalid_defs.InvalidCase, case_dir: Path, cache: dict, tmp: Path) -> dict:
    doc, blob = unpack_glb(_base_glb(case.base, cache, tmp))
    doc, blob = case.mutate(doc, blob)
    _write(case_dir / "asset.glb", pack_glb(doc, blob))
    return {
        "id": case.id,
        "suite_version": SUITE_VERSION,
        "kind": "invalid",
        "description": case.description,
        "tags": ["invalid"] + case.tags + [f"profile:{case.base.split('-')[0]}"]
        + (["encoding:compact"] if case.base.endswith("-compact") else []),
        "expect": "refuse",
        "rule": case.rule,
        "validator_code": case.validator_code,
        "files": {"asset": "asset.glb"},
    }


# --------------------------------------------------------------------------- suite

LAYOUT_TEXT = """# gsverse conformance suite: file and dump layout

The full guide (what to implement, harness sketches for Unity, Godot and Unreal, what each
tolerance means) is `spec/conformance.md` of gsverse-format. This file is the layout only.

All arrays are raw little-endian, row-major, without header. `.f32` = IEEE float32,
`.f64` = IEEE float64. N = splats, V = anchor vertices, K = SH coefficients per channel.
Coordinates are the asset's local (glTF) space: metres, +Y up, right-handed.

## Suite (read by your harness)

    suite.json                         version, list of cases (id, kind, tags, path)
    cases/<id>/case.json               manifest (kind "remap" or "invalid")
    cases/<id>/asset.glb               asset: one anchored KHR_gaussian_splatting primitive
    cases/<id>/poses/pose_NNN.f32      (V, 3) anchor vertex positions; pose_000 is the rest
    cases/<id>/skinned.glb             skinned cases only: the animation sampled into the poses
    cases/<id>/expected/...            float64 reference (read by the runner, not by you)

Rig cases (kind "rig", the anchor mesh animated by asset.glb itself, no pose_NNN.f32):

    cases/<id>/poses/deformed_NNN.f32  (V, 3) p': the anchor vertices as skinning/morphing output
                                       them (skinned: the scene's global space)
    case.json "rig"                    splat_node_matrix M (16, column-major), skinned, ...
    case.json "poses"[NNN].source      {"kind": "rest"} or {"kind": "animation", "animation": A,
                                       "time": T}

    Pose NNN in the splat primitive's local space is M^-1 p' for a skinned anchor mesh (do it in
    double precision), p' for a morph-only one; or sample the asset's animation A at time T
    (weights normalized per vertex), then M^-1. Remap that, dump pose_NNN as below.

Render cases (listed under `render_cases` in suite.json, the render level):

    cases/<id>/case.json               manifest (kind "render"): frames (deformation, camera), thresholds
    cases/<id>/asset.glb               asset: anchored (and plain) splat primitives
    cases/<id>/frames/frame_NNN.f32    (V, 3) anchor vertices of frame NNN (deformation kind "vertices")
    cases/<id>/reference/frame_NNN.png the reference picture of frame NNN

## Dumps (written by your harness, read by `gsverse-conformance check SUITE RESULTS`)

For every case, a folder `RESULTS/<id>/`. Splats in file order (element i of the
primitive's accessors). Each array may be written as `.f32` or `.f64`.

Remap cases:

    rest.means       (N, 3)  POSITION as imported, before any remap
    rest.cov         (N, 6)  covariance xx, xy, xz, yy, yz, zz of the imported splats
      or rest.rotation (N, 4) unit quaternion x, y, z, w  +  rest.scale (N, 3) linear
    rest.opacity     (N,)    imported opacity (linear)
    rest.sh          (N, K, 3) imported SH coefficients, coefficient-major
    pose_NNN.means   (N, 3)  means after remapping onto poses/pose_NNN.f32 (rig: pose NNN)
    pose_NNN.cov     (N, 6)  covariances after that remap
      or pose_NNN.rotation (N, 4) + pose_NNN.scale (N, 3)
    posed.opacity    (N,)    opacity the splats carry after the last pose
    posed.sh         (N, K, 3) SH the splats carry after the last pose

Invalid cases (and any case your importer rejects):

    refused          a text file: your importer's error message

Render cases: your engine's picture of every frame, same size as the reference, over black:

    frame_NNN.png    8-bit RGB (or RGBA), sRGB-encoded display colours

Any case: `error`, a text file, when the harness itself failed on the case (it fails).

Optional: `RESULTS/harness.json` (an object: name, version, precision, engine...) is echoed in
the report. `"unsupported": ["encoding:spz"]` in it declares that the plugin does not decode
SPZ-compressed rest poses: the cases tagged so are reported UNSUPPORTED, not checked (the only
optional feature).

encoding:spz cases also ship expected/uncompressed/pose_NNN.{means,cov,bound}.f64: the remap of
the uncompressed rest pose and the per-splat bound (mean, covariance) within which the check
compares your outputs with it (case.json "compression").
"""


def export_suite(directory: str | os.PathLike) -> dict:
    """Write the suite into ``directory`` (created; an existing suite there is replaced).

    Returns the ``suite.json`` content. Raises :class:`UsageError` if ``directory`` exists,
    is not empty and does not hold a suite.
    """
    target = Path(directory)
    if target.exists() and (not target.is_dir() or (any(target.iterdir())
                                                    and not (target / "suite.json").is_file())):
        raise UsageError("exists and is not an empty folder or a previous suite; choose a new "
                         "folder", target)
    parent = target.resolve().parent
    if not parent.is_dir():
        raise UsageError(f"folder {str(parent)!r} does not exist", target)
    tmp = Path(tempfile.mkdtemp(prefix=".tmp-suite-", dir=parent))
    try:
        entries = []
        for case in case_defs.remap_cases():
            manifest = _export_remap(case, tmp / "cases" / case.id)
            _write(tmp / "cases" / case.id / "case.json",
                   json.dumps(manifest, indent=1).encode("utf-8"))
            entries.append({"id": case.id, "kind": "remap", "tags": case.tags,
                            "path": f"cases/{case.id}"})
        for case in rig_defs.rig_cases():
            manifest = _export_remap(case, tmp / "cases" / case.id)
            _write(tmp / "cases" / case.id / "case.json",
                   json.dumps(manifest, indent=1).encode("utf-8"))
            entries.append({"id": case.id, "kind": "rig", "tags": case.tags,
                            "path": f"cases/{case.id}"})
        cache: dict = {}
        scratch = tmp / ".bases"
        scratch.mkdir()
        for invalid in (invalid_defs.invalid_cases() + rig_defs.rig_invalid_cases()
                        + spz_defs.spz_invalid_cases()):
            manifest = _export_invalid(invalid, tmp / "cases" / invalid.id, cache, scratch)
            _write(tmp / "cases" / invalid.id / "case.json",
                   json.dumps(manifest, indent=1).encode("utf-8"))
            entries.append({"id": invalid.id, "kind": "invalid", "tags": manifest["tags"],
                            "path": f"cases/{invalid.id}"})
        shutil.rmtree(scratch)
        render_entries = export_render_cases(tmp)
        suite = {
            "format": "gsverse-conformance-suite",
            "version": SUITE_VERSION,
            "generator": f"gsverse-format {__version__}",
            "extension": _ANCHOR,
            "layout": "LAYOUT.md",
            "guide": "spec/conformance.md of gsverse-format",
            "counts": {"remap": sum(e["kind"] == "remap" for e in entries),
                       "rig": sum(e["kind"] == "rig" for e in entries),
                       "invalid": sum(e["kind"] == "invalid" for e in entries),
                       "render": len(render_entries)},
            "cases": entries,
            "render_cases": render_entries,
        }
        _write(tmp / "suite.json", json.dumps(suite, indent=1).encode("utf-8"))
        _write(tmp / "LAYOUT.md", LAYOUT_TEXT.encode("utf-8"))
        if target.exists():
            old = Path(tempfile.mkdtemp(prefix=".old-suite-", dir=parent))
            os.replace(target, old / "suite")
            os.replace(tmp, target)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, target)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return suite
