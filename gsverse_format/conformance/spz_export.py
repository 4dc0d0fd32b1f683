"""The second expectation of an ``encoding:spz`` case: the remap of the *uncompressed* rest
pose and the bound within which an implementation's remap of the compressed asset must stay
of it (spec §SPZ-compressed rest pose, "The error compression adds").

For a splat on face f the remap is affine in the rest pose: μ′ = M_f μ + t_f and
Σ′ = N_f Σ N_fᵀ, with M_f = A_f R_rᵀ the face's affine rest-to-current map (A_f of
:func:`..remapping.reference.face_matrices` for the ``affine`` law; means follow it under
both laws) and N_f the same for the splat's own law (k R_c R_rᵀ for ``rigid``); R_r is
orthonormal, so ‖M_f‖₂ = ‖A_f‖₂. The remaps of
the decoded and of the uncompressed rest pose therefore differ by at most ‖M_f‖₂ B_μ in the
mean and ‖N_f‖₂² B_Σ ‖Σ‖_F in the covariance, with B_μ = √3 · 2^−(fb+1) and
B_Σ = (1 + e^(1/32) − 1)² − 1 + 2 θ the stated bounds of the stream layer
(:func:`..io.spz_stream.quantization_bounds`, fb the stream's fractional bits) and Σ the
uncompressed rest covariance. ``check`` adds the usual tolerance of the case to these bounds
(the implementation's own float32 rounding).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..frames import local_frames
from ..io import spz_stream
from ..io.gltf import asset_to_gltf, gltf_to_bytes
from ..model import SplatAsset, SplatPrimitive
from ..remapping.reference import face_matrices, prepare_rest, remap
from .glb import anchored_primitive, unpack_glb

__all__ = ["uncompressed_expectation"]

_SPZ = "KHR_gaussian_splatting_compression_spz_2"
#: Slack of the export's own check that the reference remaps obey the bound: binary64
#: rounding of the two remaps (relative 1e-12 of the bound, plus 1e-15 absolute).
_SELF_CHECK_SLACK = 1e-12


def _fractional_bits(path: Path) -> int:
    doc, blob = unpack_glb(path.read_bytes())
    ext = anchored_primitive(doc)["extensions"]["KHR_gaussian_splatting"]["extensions"][_SPZ]
    view = doc["bufferViews"][ext["bufferView"]]
    start = view.get("byteOffset", 0)
    n = doc["accessors"][anchored_primitive(doc)["attributes"]["POSITION"]]["count"]
    data = spz_stream.inflate_bounded(blob[start:start + view["byteLength"]],
                                      spz_stream.stream_bytes(3, n, 3), str(path))
    return spz_stream.parse_header(data, str(path)).fractional_bits


def uncompressed_expectation(initial: SplatAsset, decoded: SplatPrimitive, asset_path: Path,
                             poses: list[np.ndarray], case_dir: Path,
                             write: Callable[[Path, np.ndarray, str], None],
                             cov6: Callable[[np.ndarray], np.ndarray],
                             read_asset: Callable[[str], Any]) -> dict:
    """Write ``expected/uncompressed/`` (the remap of ``initial``, the uncompressed asset, at
    every pose, and per pose and splat the bounds (N, 2): mean, covariance) and return the
    manifest's ``compression`` entry. ``decoded`` is the compressed asset as read back."""
    scratch = case_dir / ".uncompressed.glb"
    scratch.write_bytes(gltf_to_bytes(asset_to_gltf(initial, anchors="compact")))
    try:
        plain = read_asset(str(scratch)).primitives[0]
    finally:
        scratch.unlink()
    anchoring = plain.anchoring
    if anchoring is None or decoded.anchoring is None:
        raise RuntimeError(f"{asset_path}: no anchoring read back")
    anchors = anchoring.anchors
    if not np.array_equal(anchors.face_index, decoded.anchoring.anchors.face_index):
        raise RuntimeError(f"{asset_path}: the compressed and uncompressed splats differ in "
                           f"order or faces")
    bits = _fractional_bits(asset_path)
    bounds = spz_stream.quantization_bounds(bits)
    rest_norm = np.linalg.norm(plain.splats.covariances().astype(np.float64), axis=(1, 2))
    rest = prepare_rest(anchoring.mesh.triangles())
    folder = case_dir / "expected" / "uncompressed"
    files = []
    for p, vertices in enumerate(poses):
        tri = anchoring.mesh.triangles(np.asarray(vertices, np.float64))
        frames = local_frames(tri)
        # means follow the triangle affinely under both laws; covariances by the law's A
        stretch = [np.linalg.norm(face_matrices(rest, frames, tri, law)[2], 2,
                                  axis=(1, 2))[anchors.face_index]
                   for law in ("affine", anchors.deformation)]
        bound = np.stack([stretch[0] * bounds["mean"],
                          stretch[1] ** 2 * bounds["covariance"] * rest_norm], axis=1)
        mine, theirs = remap(anchoring, vertices), remap(decoded.anchoring, vertices)
        dm = np.linalg.norm(mine.means - theirs.means, axis=1)
        dc = np.linalg.norm(mine.covariances - theirs.covariances, axis=(1, 2))
        if np.any(dm > bound[:, 0] * (1 + _SELF_CHECK_SLACK) + 1e-15) or \
                np.any(dc > bound[:, 1] * (1 + _SELF_CHECK_SLACK) + 1e-15):
            raise RuntimeError(f"{asset_path}: pose {p}: the decoded rest pose is further from "
                               f"the uncompressed one than the stated bounds "
                               f"({(dm / bound[:, 0]).max():.3g}, {(dc / bound[:, 1]).max():.3g})")
        stem = f"pose_{p:03d}"
        write(folder / f"{stem}.means.f64", mine.means, "f8")
        write(folder / f"{stem}.cov.f64", cov6(mine.covariances), "f8")
        write(folder / f"{stem}.bound.f64", bound, "f8")
        files.append({"means": f"expected/uncompressed/{stem}.means.f64",
                      "cov": f"expected/uncompressed/{stem}.cov.f64",
                      "bound": f"expected/uncompressed/{stem}.bound.f64"})
    return {"extension": _SPZ, "fractional_bits": bits, "mean_bound": bounds["mean"],
            "covariance_relative_bound": bounds["covariance"],
            "uncompressed": files,
            "reason": "the remap of the uncompressed rest pose: |mu' - mu'_u| <= ||M_f||_2 "
                      "B_mu and ||Sigma' - Sigma'_u||_F <= ||M_f||_2^2 B_Sigma ||Sigma_u||_F "
                      "(bound, per pose and splat, columns mean and covariance), plus the "
                      "case's usual tolerance"}
