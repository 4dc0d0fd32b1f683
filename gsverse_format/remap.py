"""Reference remap: current anchor-mesh vertices -> splat means, rotations, scales, covariances.

This is the normative algorithm of ``spec/README.md`` §Remap, written to be read next to it.
It computes in float64 throughout; inputs may be float32.

For splat i on face f with current corners (v0, v1, v2), e1 = v1 − v0, e2 = v2 − v0:

``local`` profile (rest data: barycentrics (b1, b2), normal offset d, local rotation R_l, local
scale S_l; rest frame R_r, edge matrix C_r, doubled area a_r; current frame R_c, C_c, a_c)::

    k      = sqrt(a_c / a_r)                        # normal-axis / isotropic size factor
    mean   = v0 + b1 e1 + b2 e2 + d k n_c
    affine: G = blockdiag(C_c C_r⁻¹, k);  M = G R_l S_l;  Σ = R_c M Mᵀ R_cᵀ
    rigid:  Σ = k² (R_c R_l) S_l² (R_c R_l)ᵀ

``games`` profile (barycentrics (α1, α2), ρ; frame [n, b1, b2] and base scales s of the current
triangle, see :func:`gsverse_format.frames.games_frames`)::

    mean   = α0 v0 + α1 v1 + α2 v2,  α0 = 1 − α1 − α2
    scales = max(ρ s, 0) + ε;  rotation = [n, b1, b2];  Σ = R diag(scales)² Rᵀ

Rotation/scale pairs are not unique; the covariance is the normative output. For the affine law
the reported pair comes from the SVD of M, with axes ordered and signed to match R_l, so that at
rest the stored rotation and scale come back unchanged.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import quaternion as quat
from .frames import GAMES_EPS, games_frames, local_frames
from .model import Anchoring, GamesAnchors, LocalAnchors, SplatCloud

__all__ = ["RemapResult", "remap", "remap_primitive_splats", "RestData", "prepare_rest"]

_PERMUTATIONS = np.array([[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]])


@dataclass
class RemapResult:
    """Remapped splats, all float64: means (N,3), rotations (N,4) xyzw unit, scales (N,3) linear,
    covariances (N,3,3) symmetric positive semi-definite."""

    means: np.ndarray
    rotations: np.ndarray
    scales: np.ndarray
    covariances: np.ndarray


@dataclass
class RestData:
    """Per-face data of the rest mesh a plugin precomputes once (``local`` profile).

    ``inverse_shape`` is C_r⁻¹ and ``area2`` the rest doubled area. For faces that are
    degenerate at rest (``regular`` False) the spec's rule applies: C_r⁻¹ := identity and
    k := 1 (see :func:`_size_factor`).
    """

    rotation: np.ndarray
    inverse_shape: np.ndarray
    area2: np.ndarray
    regular: np.ndarray


def prepare_rest(rest_triangles: np.ndarray) -> RestData:
    """Precompute rest frames, C_r⁻¹ and areas for the ``local`` profile."""
    frames = local_frames(rest_triangles)
    c = frames.shape
    inv = np.zeros_like(c)
    reg = frames.regular
    # C_r is upper triangular: [[p, q], [0, h]] -> [[1/p, -q/(p h)], [0, 1/h]].
    p, q, h = c[reg, 0, 0], c[reg, 0, 1], c[reg, 1, 1]
    inv[reg, 0, 0] = 1.0 / p
    inv[reg, 0, 1] = -q / (p * h)
    inv[reg, 1, 1] = 1.0 / h
    inv[~reg] = np.eye(2)
    return RestData(frames.rotation, inv, frames.area2, reg)


def _size_factor(current_area2: np.ndarray, rest: RestData, face: np.ndarray) -> np.ndarray:
    """k = sqrt(a_c / a_r) per splat; k = 1 on faces degenerate at rest (spec rule)."""
    a_r = rest.area2[face]
    reg = rest.regular[face]
    safe = np.where(reg, a_r, 1.0)
    return np.where(reg, np.sqrt(current_area2[face] / safe), 1.0)


def _align_axes(u: np.ndarray, sigma: np.ndarray, reference: np.ndarray):
    """Reorder/sign the columns of rotations ``u`` (and ``sigma``) to best match ``reference``.

    Chooses, per splat, the column permutation maximizing Σ|⟨u_π(j), ref_j⟩|, flips each column
    to a non-negative dot with its reference column, then restores det = +1 by flipping the
    least aligned column if needed. Covariance is unchanged by construction.
    """
    dots = np.abs(np.einsum("nij,nik->njk", u, reference))  # dots[n, j, k] = |<u_j, ref_k>|
    scores = np.stack([dots[:, p, np.arange(3)].sum(-1) for p in _PERMUTATIONS], axis=-1)
    best = _PERMUTATIONS[np.argmax(scores, axis=-1)]  # (N, 3): column of u for reference axis j
    u = np.take_along_axis(u, best[:, None, :], axis=2)
    sigma = np.take_along_axis(sigma, best, axis=1)
    signed = np.einsum("nij,nij->nj", u, reference)
    u = u * np.where(signed < 0.0, -1.0, 1.0)[:, None, :]
    flip = np.linalg.det(u) < 0.0
    if np.any(flip):
        weakest = np.argmin(np.abs(np.einsum("nij,nij->nj", u[flip], reference[flip])), axis=-1)
        u[flip, :, weakest] *= -1.0
    return u, sigma


def _remap_local(anchors: LocalAnchors, rest: RestData, tri: np.ndarray) -> RemapResult:
    face = anchors.face_index.astype(np.intp)
    cur = local_frames(tri)
    b = anchors.barycentrics.astype(np.float64)
    d = anchors.normal_offset.astype(np.float64)
    k = _size_factor(cur.area2, rest, face)

    v0 = tri[face, 0]
    e1 = tri[face, 1] - v0
    e2 = tri[face, 2] - v0
    r_c = cur.rotation[face]
    means = v0 + b[:, 0:1] * e1 + b[:, 1:2] * e2 + (d * k)[:, None] * r_c[:, :, 2]

    r_l = quat.to_matrix(anchors.local_rotation)
    s_l = anchors.local_scale.astype(np.float64)
    if anchors.deformation == "rigid":
        rot = r_c @ r_l
        scales = s_l * k[:, None]
    else:
        g = np.zeros((len(face), 3, 3))
        g[:, :2, :2] = cur.shape[face] @ rest.inverse_shape[face]
        g[:, 2, 2] = k
        m = g @ (r_l * s_l[:, None, :])
        u, sigma, _ = np.linalg.svd(m)
        u, sigma = _align_axes(u, sigma, r_l)
        rot = r_c @ u
        scales = sigma
    rs = rot * scales[:, None, :]
    cov = rs @ np.swapaxes(rs, 1, 2)
    return RemapResult(means, quat.from_matrix(rot), scales, cov)


def _remap_games(anchors: GamesAnchors, tri: np.ndarray) -> RemapResult:
    face = anchors.face_index.astype(np.intp)
    rotation, base, _ = games_frames(tri)
    a = anchors.barycentrics.astype(np.float64)
    alpha = np.concatenate([1.0 - a.sum(axis=1, keepdims=True), a], axis=1)
    means = np.einsum("nm,nmx->nx", alpha, tri[face])
    rho = anchors.rho.astype(np.float64)[:, None]
    scales = np.maximum(rho * base[face], 0.0) + GAMES_EPS
    rot = rotation[face]
    rs = rot * scales[:, None, :]
    cov = rs @ np.swapaxes(rs, 1, 2)
    return RemapResult(means, quat.from_matrix(rot), scales, cov)


def remap(anchoring: Anchoring, vertices: np.ndarray | None = None, *,
          rest: RestData | None = None) -> RemapResult:
    """Remap the splats of ``anchoring`` onto the mesh with current ``vertices`` (V, 3).

    ``vertices`` defaults to the rest vertices (then the result reproduces the rest pose).
    ``rest`` may pass precomputed :func:`prepare_rest` data to skip recomputing it per frame.
    """
    mesh = anchoring.mesh
    current = mesh.vertices if vertices is None else np.asarray(vertices)
    if current.shape != mesh.vertices.shape:
        raise ValueError(f"expected vertices of shape {mesh.vertices.shape}, got {current.shape}")
    tri = mesh.triangles(current)
    anchors = anchoring.anchors
    if isinstance(anchors, GamesAnchors):
        return _remap_games(anchors, tri)
    if rest is None:
        rest = prepare_rest(mesh.triangles())
    return _remap_local(anchors, rest, tri)


def remap_primitive_splats(splats: SplatCloud, anchoring: Anchoring,
                           vertices: np.ndarray | None = None) -> SplatCloud:
    """A new SplatCloud posed on ``vertices``; opacity and SH pass through unchanged."""
    r = remap(anchoring, vertices)
    return SplatCloud(r.means, r.rotations, r.scales, splats.opacities, splats.sh,
                      splats.color_space, dict(splats.extra))
