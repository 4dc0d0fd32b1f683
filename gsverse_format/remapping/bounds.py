"""Error bounds of the float32 fast remap against the float64 reference.

:class:`gsverse_format.remapping.fast.FastRemapper` (compiled kernels in
:mod:`gsverse_format.remapping.compiled`) stores its results in float32;
:func:`float32_error_bounds` gives, per splat, how far they may lie from the float64 reference
:mod:`gsverse_format.remapping.reference`.

Precision (float32 result against the float64 reference, u = 2⁻²⁴ the float32 unit roundoff;
checked by ``tests/test_remap_fast.py`` and ``tests/test_stability.py``):

* means: ``|Δμ| <= 16 u (|v0| + |b1| |e1| + |b2| |e2| + |d| k) + |d| ν`` where, on faces
  regular at rest, ``ν = min(8 u P / √(a_c a_r), 6 √(u P / a_r))`` (P = |e1| |e2| of the current
  triangle) bounds the float32 error of the normal term d·m, and ν = 0 on faces degenerate at
  rest (k = 1 there);
* ``local`` covariances: ``‖ΔΣ‖_F <= 64 u ‖A‖_F² ‖L‖_F²`` (``‖L‖_F² = Σ s_l²``, the trace of
  the rest covariance). Relative to ‖Σ‖_F this is at most ``576 u κ(A)²`` (κ the condition
  number of A; ‖A‖_F² ≤ 3‖A‖₂², ‖L‖_F² ≤ 3‖L‖₂², ‖Σ‖_F ≥ σ_min(A)² ‖L‖₂²); the tests also
  check ``‖ΔΣ‖_F / ‖Σ‖_F <= 1e-5`` for stretches and compressions up to 10×.
* ``games`` covariances: ``‖ΔΣ‖_F <= 64 u Σ_j scale_j²``.
"""
from __future__ import annotations

import numpy as np

from ..frames import GAMES_EPS, games_frames, local_frames
from ..model import Anchoring, GamesAnchors
from .reference import face_matrices, prepare_rest

__all__ = ["float32_error_bounds", "F32_UNIT_ROUNDOFF", "MEAN_BOUND_FACTOR", "COV_BOUND_FACTOR"]

#: u = 2⁻²⁴, float32 unit roundoff (half the machine epsilon 2⁻²³).
F32_UNIT_ROUNDOFF = 2.0 ** -24
#: Multiples of u in the stated float32-vs-float64 bounds (see :func:`float32_error_bounds`).
MEAN_BOUND_FACTOR = 16.0
COV_BOUND_FACTOR = 64.0


def float32_error_bounds(anchoring: Anchoring, vertices: np.ndarray | None = None
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Per-splat bounds on |μ_fast − μ_ref| and ‖Σ_fast − Σ_ref‖_F (float32 fast path against
    the float64 reference), as (N,) float64 arrays ``(mean_bound, cov_bound)``.

    * mean: ``16 u (|v0| + |b1| |e1| + |b2| |e2| + |d| k)``, plus, on faces regular at rest,
      the float32 error of the normal term d·m: ``|d| min(8 u P / √(a_c a_r), 6 √(u P / a_r))``
      with P = |e1| |e2| of the current triangle (k = 1 and no such term on faces degenerate
      at rest, where m = n_c);
    * ``local`` covariance: ``64 u ‖A‖_F² Σ s_l²`` with A = [E_c C_r⁻¹ | m] (affine), k R_c
      (rigid) or R_c (faces degenerate at rest);
    * ``games`` covariance: ``64 u Σ_j scale_j²``.

    u = 2⁻²⁴. Both implementations evaluate the branch tests of the current frames in float64;
    a triangle within rounding of a branch point may take different branches. Only frames with
    a jump there are affected: the current frame R_c at ``a = ε_deg ℓ²`` (the rigid law, and
    faces degenerate at rest) and the games frame at ``|u| = ε_deg ℓ`` or ``|r| = ε_deg ℓ``;
    these bounds do not cover such triangles. The affine law and every mean on faces regular
    at rest have no branch on the current triangle.
    """
    mesh = anchoring.mesh
    v = mesh.vertices if vertices is None else np.asarray(vertices)
    tri = mesh.triangles(v)
    anchors = anchoring.anchors
    face = anchors.face_index.astype(np.intp)
    b = np.abs(anchors.barycentrics.astype(np.float64))
    len1 = np.linalg.norm(tri[:, 1] - tri[:, 0], axis=1)
    len2 = np.linalg.norm(tri[:, 2] - tri[:, 0], axis=1)
    v0 = np.linalg.norm(tri[face, 0], axis=1)
    base_mean = v0 + b[:, 0] * len1[face] + b[:, 1] * len2[face]
    u = F32_UNIT_ROUNDOFF
    if isinstance(anchors, GamesAnchors):
        _, base, _ = games_frames(tri)
        scales = np.maximum(anchors.rho.astype(np.float64)[:, None] * base[face], 0.0) + GAMES_EPS
        return MEAN_BOUND_FACTOR * u * base_mean, COV_BOUND_FACTOR * u * np.sum(scales * scales, axis=1)
    rest = prepare_rest(mesh.triangles())
    cur = local_frames(tri)
    k, _, a = face_matrices(rest, cur, tri, anchors.deformation)
    a2 = np.sum(a * a, axis=(1, 2))
    # float32 error of d·m on faces regular at rest, per unit |d|
    p = len1 * len2
    a_r = np.where(rest.regular, rest.area2, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        normal = np.fmin(8.0 * u * p / np.sqrt(cur.area2 * a_r), 6.0 * np.sqrt(u * p / a_r))
    normal = np.where(rest.regular, normal, 0.0)
    d = np.abs(anchors.normal_offset.astype(np.float64))
    mean_bound = MEAN_BOUND_FACTOR * u * (base_mean + d * k[face]) + d * normal[face]
    s2 = np.sum(anchors.local_scale.astype(np.float64) ** 2, axis=1)
    return mean_bound, COV_BOUND_FACTOR * u * a2[face] * s2
