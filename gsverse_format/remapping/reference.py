"""Reference remap: current anchor-mesh vertices -> splat means, rotations, scales, covariances.

This is the normative algorithm of ``spec/README.md`` §Remap, written to be read next to it.
It computes in float64 throughout; inputs may be float32.

For splat i on face f with current corners (v0, v1, v2), e1 = v1 − v0, e2 = v2 − v0:

``local`` profile (rest data: barycentrics (b1, b2), normal offset d, local rotation R_l, local
scale S_l; rest frame R_r, edge matrix C_r, doubled area a_r; current frame R_c, C_c, a_c)::

    k      = sqrt(a_c / a_r)                        # normal-axis / isotropic size factor
    m      = (e1 × e2) / sqrt(a_c a_r)  (0 when a_c = 0)   # = k n_c, continuous as a_c -> 0
    mean   = v0 + b1 e1 + b2 e2 + d m
    affine: A = [E_c C_r⁻¹ | m]  (E_c = [e1 e2], 3×2)      # = R_c blockdiag(C_c C_r⁻¹, k)
    rigid:  A = k R_c
    Σ = A R_l S_l² R_lᵀ Aᵀ

    faces degenerate at rest: k := 1, m := n_c, A := R_c (G := I), both laws

``games`` profile (barycentrics (α1, α2), ρ; frame [n, b1, b2] and base scales s of the current
triangle, see :func:`gsverse_format.frames.games_frames`)::

    mean   = α0 v0 + α1 v1 + α2 v2,  α0 = 1 − α1 − α2
    scales = max(ρ s, 0) + ε;  rotation = [n, b1, b2];  Σ = R diag(scales)² Rᵀ

Rotation/scale pairs are not unique; the covariance is the normative output. For the affine law
the reported pair comes from the SVD of M, with axes ordered and signed to match R_l, so that at
rest the stored rotation and scale come back unchanged.

This module is the reference. The per-frame float32 path is
:mod:`gsverse_format.remapping.fast` (compiled kernels in :mod:`gsverse_format.remapping.compiled`,
error bounds against this module in :mod:`gsverse_format.remapping.bounds`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator

import numpy as np

from .. import quaternion as quat
from ..frames import GAMES_EPS, LocalFrames, games_frames, local_frames
from ..model import Anchoring, GamesAnchors, LocalAnchors, TriangleMesh

__all__ = ["RemapResult", "remap", "RestData", "prepare_rest",
           "remap_moments", "iter_moments", "covariance_entries", "face_matrices",
           "covariances_from"]

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

    ``inverse_shape`` is C_r⁻¹ and ``area2`` the rest doubled area, computed in float64 (spec
    v1.1 §Precision: rest quantities in double precision). For faces that are degenerate at
    rest (``regular`` False) the spec's rule applies: G := I and k := 1 (see
    :func:`face_matrices`); their ``inverse_shape`` is the identity and is not used.
    """

    rotation: np.ndarray
    inverse_shape: np.ndarray
    area2: np.ndarray
    regular: np.ndarray


def prepare_rest(rest_triangles: np.ndarray) -> RestData:
    """Precompute rest frames, C_r⁻¹ and areas for the ``local`` profile."""
    return _rest_from_frames(local_frames(rest_triangles))


def _rest_from_frames(frames: LocalFrames) -> RestData:
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
    """k = sqrt(a_c / a_r) per splat (a_c the true doubled area); k = 1 on faces degenerate
    at rest (spec rule)."""
    a_r = rest.area2[face]
    reg = rest.regular[face]
    safe = np.where(reg, a_r, 1.0)
    return np.where(reg, np.sqrt(current_area2[face] / safe), 1.0)


def face_matrices(rest: RestData, cur: LocalFrames, tri: np.ndarray, deformation: str
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per face: size factor k (F,), scaled normal m = k n_c (F, 3) and the matrix A (F, 3, 3)
    with Σ = A R_l S_l² R_lᵀ Aᵀ (spec §Remap: the local profile).

    Faces regular at rest: k = sqrt(a_c/a_r), m = (e1 × e2)/(sqrt(a_c) sqrt(a_r)) (0 when
    a_c = 0), A = [E_c C_r⁻¹ | m] (affine) or k R_c (rigid). Faces degenerate at rest: k = 1,
    m = n_c, A = R_c.
    """
    f = len(tri)
    reg = rest.regular
    e = np.stack([tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]], axis=-1)   # (F, 3, 2)
    root_r = np.sqrt(np.where(reg, rest.area2, 1.0))
    root_c = np.sqrt(cur.area2)
    k = np.where(reg, root_c / root_r, 1.0)
    cross = cur.cross if cur.cross is not None else np.cross(e[:, :, 0], e[:, :, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        m = np.where((root_c > 0.0)[:, None], cross / (root_c * root_r)[:, None], 0.0)
    m = np.where(reg[:, None], m, cur.rotation[:, :, 2])
    if deformation == "rigid":
        a = cur.rotation * k[:, None, None]
    else:
        a = np.empty((f, 3, 3))
        a[:, :, :2] = e @ rest.inverse_shape
        a[:, :, 2] = m
        a[~reg] = cur.rotation[~reg]
    return k, m, a


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
    k, m, a = face_matrices(rest, cur, tri, anchors.deformation)
    b = anchors.barycentrics.astype(np.float64)
    d = anchors.normal_offset.astype(np.float64)

    v0 = tri[face, 0]
    e1 = tri[face, 1] - v0
    e2 = tri[face, 2] - v0
    r_c = cur.rotation[face]
    means = v0 + b[:, 0:1] * e1 + b[:, 1:2] * e2 + d[:, None] * m[face]

    r_l = quat.to_matrix(anchors.local_rotation)
    s_l = anchors.local_scale.astype(np.float64)
    if anchors.deformation == "rigid":
        rot = r_c @ r_l
        scales = s_l * k[face][:, None]
    else:
        mm = a[face] @ (r_l * s_l[:, None, :])
        u, sigma, _ = np.linalg.svd(mm)
        rot, scales = _align_axes(u, sigma, r_c @ r_l)
    rs = rot * scales[:, None, :]
    cov = rs @ np.swapaxes(rs, 1, 2)
    return RemapResult(means, quat.from_matrix(rot), scales, cov)


def _remap_games(anchors: GamesAnchors, tri: np.ndarray) -> RemapResult:
    face = anchors.face_index.astype(np.intp)
    rotation, base, _ = games_frames(tri)
    a = anchors.barycentrics.astype(np.float64)
    v0 = tri[face, 0]
    # μ = α0 v0 + α1 v1 + α2 v2, evaluated relative to the first corner
    means = v0 + a[:, 0:1] * (tri[face, 1] - v0) + a[:, 1:2] * (tri[face, 2] - v0)
    rho = anchors.rho.astype(np.float64)[:, None]
    scales = np.maximum(rho * base[face], 0.0) + GAMES_EPS
    rot = rotation[face]
    rs = rot * scales[:, None, :]
    cov = rs @ np.swapaxes(rs, 1, 2)
    return RemapResult(means, quat.from_matrix(rot), scales, cov)


def _current_triangles(mesh: TriangleMesh, vertices: np.ndarray | None) -> np.ndarray:
    """(F, 3, 3) corners of ``mesh`` posed at ``vertices`` (default: its rest vertices)."""
    current = mesh.vertices if vertices is None else np.asarray(vertices)
    if current.shape != mesh.vertices.shape:
        raise ValueError(f"expected vertices of shape {mesh.vertices.shape}, got {current.shape}")
    return mesh.triangles(current)


def remap(anchoring: Anchoring, vertices: np.ndarray | None = None, *,
          rest: RestData | None = None) -> RemapResult:
    """Remap the splats of ``anchoring`` onto the mesh with current ``vertices`` (V, 3).

    ``vertices`` defaults to the rest vertices (then the result reproduces the rest pose).
    ``rest`` may pass precomputed :func:`prepare_rest` data to skip recomputing it per frame.
    """
    mesh = anchoring.mesh
    tri = _current_triangles(mesh, vertices)
    anchors = anchoring.anchors
    if isinstance(anchors, GamesAnchors):
        return _remap_games(anchors, tri)
    if rest is None:
        rest = prepare_rest(mesh.triangles())
    return _remap_local(anchors, rest, tri)


# ----------------------------------------------------------------------------------------
# Means and covariances only
# ----------------------------------------------------------------------------------------

#: Splats per block in :func:`remap_moments` (keeps the temporaries in cache).
_BLOCK = 32768


def _quaternion_columns(q: np.ndarray):
    """The nine entries r_ij of the rotation matrices of quaternions ``q`` (n, 4) xyzw, as
    float64 arrays, normalizing as :func:`gsverse_format.quaternion.to_matrix` does (the
    zero quaternion gives the identity)."""
    x, y, z, w = (q[:, j].astype(np.float64) for j in range(4))
    n2 = x * x + y * y + z * z + w * w
    zero = n2 == 0.0
    if np.any(zero):
        w = np.where(zero, 1.0, w)
        n2 = np.where(zero, 1.0, n2)
    s = 2.0 / n2
    xs, ys, zs = x * s, y * s, z * s
    wx, wy, wz = w * xs, w * ys, w * zs
    xx, xy, xz = x * xs, x * ys, x * zs
    yy, yz, zz = y * ys, y * zs, z * zs
    return ((1.0 - (yy + zz), xy - wz, xz + wy),
            (xy + wz, 1.0 - (xx + zz), yz - wx),
            (xz - wy, yz + wx, 1.0 - (xx + yy)))


def _gram(b) -> tuple:
    """The six distinct entries (00, 01, 02, 11, 12, 22) of B Bᵀ for B given as rows of
    column arrays."""
    (b00, b01, b02), (b10, b11, b12), (b20, b21, b22) = b
    return (b00 * b00 + b01 * b01 + b02 * b02,
            b00 * b10 + b01 * b11 + b02 * b12,
            b00 * b20 + b01 * b21 + b02 * b22,
            b10 * b10 + b11 * b11 + b12 * b12,
            b10 * b20 + b11 * b21 + b12 * b22,
            b20 * b20 + b21 * b21 + b22 * b22)


def _store(cov: np.ndarray, entries: tuple) -> None:
    c00, c01, c02, c11, c12, c22 = entries
    cov[:, 0, 0] = c00
    cov[:, 0, 1] = cov[:, 1, 0] = c01
    cov[:, 0, 2] = cov[:, 2, 0] = c02
    cov[:, 1, 1] = c11
    cov[:, 1, 2] = cov[:, 2, 1] = c12
    cov[:, 2, 2] = c22


def _face_table_local(anchors: LocalAnchors, rest: RestData, tri: np.ndarray,
                      cur=None) -> np.ndarray:
    """Per face, as rows: v0 (3), e1 (3), e2 (3), m = k·n_c (3) and the 3x3 matrix A (9,
    row-major) with Σ = A R_l S_l² R_lᵀ Aᵀ (see :func:`face_matrices`). ``cur`` may pass the
    current frames when they are already known."""
    if cur is None:
        cur = local_frames(tri)
    _, m, a = face_matrices(rest, cur, tri, anchors.deformation)
    v0 = tri[:, 0]
    table = np.concatenate([v0, tri[:, 1] - v0, tri[:, 2] - v0, m, a.reshape(-1, 9)], axis=1)
    return np.ascontiguousarray(table.T)


def _face_table_games(tri: np.ndarray) -> np.ndarray:
    """Per face, as rows: v0 (3), e1 (3), e2 (3), the frame [n | b1 | b2] (9, row-major) and
    the base scales (3)."""
    rotation, base, _ = games_frames(tri)
    v0 = tri[:, 0]
    table = np.concatenate([v0, tri[:, 1] - v0, tri[:, 2] - v0, rotation.reshape(-1, 9), base],
                           axis=1)
    return np.ascontiguousarray(table.T)


def iter_moments(anchoring: Anchoring, vertices: np.ndarray | None = None, *,
                 rest: RestData | None = None, block: int = _BLOCK
                 ) -> Iterator[tuple[slice, tuple, tuple]]:
    """Blocks of :func:`remap_moments` as per-component arrays.

    Yields ``(slice, (μx, μy, μz), (Σ00, Σ01, Σ02, Σ11, Σ12, Σ22))`` for consecutive blocks of
    at most ``block`` splats, all float64 arrays of the block's length, so that a caller that
    only compares or reduces them never materializes (N, 3, 3) arrays.
    """
    mesh = anchoring.mesh
    tri = _current_triangles(mesh, vertices)
    anchors = anchoring.anchors
    if isinstance(anchors, GamesAnchors):
        table = _face_table_games(tri)
    elif rest is None and vertices is None:  # at rest: the current frames are the rest frames
        frames = local_frames(tri)
        table = _face_table_local(anchors, _rest_from_frames(frames), tri, frames)
    else:
        if rest is None:
            rest = prepare_rest(mesh.triangles())
        table = _face_table_local(anchors, rest, tri)
    n = len(anchors)
    face = anchors.face_index.astype(np.intp)
    for start in range(0, n, block):
        sl = slice(start, min(start + block, n))
        t = np.take(table, face[sl], axis=1)
        bary = anchors.barycentrics[sl].astype(np.float64)
        b1, b2 = bary[:, 0], bary[:, 1]
        if isinstance(anchors, GamesAnchors):
            mean = tuple(t[j] + b1 * t[3 + j] + b2 * t[6 + j] for j in range(3))
            rho = anchors.rho[sl].astype(np.float64)
            sc = [np.maximum(rho * t[18 + j], 0.0) + GAMES_EPS for j in range(3)]
            b = tuple(tuple(t[9 + 3 * i + j] * sc[j] for j in range(3)) for i in range(3))
        else:
            d = anchors.normal_offset[sl].astype(np.float64)
            mean = tuple(t[j] + b1 * t[3 + j] + b2 * t[6 + j] + d * t[9 + j] for j in range(3))
            r = _quaternion_columns(anchors.local_rotation[sl])
            s = anchors.local_scale[sl].astype(np.float64)
            a = [[t[12 + 3 * i + j] for j in range(3)] for i in range(3)]
            b = tuple(tuple((a[i][0] * r[0][j] + a[i][1] * r[1][j] + a[i][2] * r[2][j]) * s[:, j]
                            for j in range(3)) for i in range(3))
        yield sl, mean, _gram(b)


def remap_moments(anchoring: Anchoring, vertices: np.ndarray | None = None, *,
                  rest: RestData | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Means (N, 3) and covariances (N, 3, 3), float64: the remap's normative outputs.

    The same law as :func:`remap` (``means`` and ``covariances`` agree to float64 rounding)
    without the rotation/scale decomposition: for the ``affine`` law Σ = (A R_l S_l)(A R_l
    S_l)ᵀ with the per-face A = R_c G computed once per face, so no SVD is needed. Evaluated
    per block of splats on per-component arrays (:func:`iter_moments`), this is about an
    order of magnitude faster than :func:`remap`.
    """
    n = len(anchoring.anchors)
    means = np.empty((n, 3))
    cov = np.empty((n, 3, 3))
    for sl, mean, entries in iter_moments(anchoring, vertices, rest=rest):
        for j in range(3):
            means[sl, j] = mean[j]
        _store(cov[sl], entries)
    return means, cov


def covariance_entries(rotations: np.ndarray, scales: np.ndarray
                       ) -> tuple[np.ndarray, ...]:
    """(Σ00, Σ01, Σ02, Σ11, Σ12, Σ22), float64, of Σ = R diag(s)² Rᵀ for quaternions
    (n, 4) x, y, z, w (normalized first; zero gives the identity) and linear scales (n, 3)."""
    r = _quaternion_columns(rotations)
    s = scales.astype(np.float64)
    return _gram(tuple(tuple(r[i][j] * s[:, j] for j in range(3)) for i in range(3)))


def covariances_from(rotations: np.ndarray, scales: np.ndarray) -> np.ndarray:
    """(N, 3, 3) float64 covariances R diag(s)² Rᵀ (see :func:`covariance_entries`)."""
    n = len(rotations)
    cov = np.empty((n, 3, 3))
    for start in range(0, n, _BLOCK):
        sl = slice(start, min(start + _BLOCK, n))
        _store(cov[sl], covariance_entries(rotations[sl], scales[sl]))
    return cov
