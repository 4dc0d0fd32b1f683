"""The rest-pose consistency bounds of the spec (spec/README.md §Rest-pose consistency).

A stored rest pose must equal the remap at the rest anchor mesh within

* means: |Δμ| ≤ 10⁻⁵ · D + 8 · ε₃₂ · L, with D the diagonal of the anchor mesh's bounding box,
  L the largest absolute vertex coordinate and ε₃₂ = 2⁻²³ the float32 machine epsilon (the
  second term is float32 rounding of positions far from the origin: 8 units in the last
  place, which matters only for meshes smaller than about 1/100 of their distance to the
  origin);
* covariances: ‖ΔΣ‖_F ≤ 10⁻⁴ · ‖Σ‖_F, plus an absolute floor of (10⁻⁷ · D)² for covariances
  below float32 resolution.

Writers (the converters) and the validator use these functions, so they cannot disagree.
"""
from __future__ import annotations

import numpy as np

from .model import TriangleMesh

__all__ = ["REST_MEAN_RELATIVE", "REST_ROUNDING_ULPS", "REST_COVARIANCE_RELATIVE",
           "REST_COVARIANCE_FLOOR", "mesh_extent", "rest_mean_tolerance"]

#: |Δμ| relative to the anchor mesh's bounding-box diagonal D.
REST_MEAN_RELATIVE = 1e-5
#: float32 units in the last place of the largest vertex coordinate added to the mean bound.
REST_ROUNDING_ULPS = 8
#: ‖ΔΣ‖_F relative to ‖Σ‖_F.
REST_COVARIANCE_RELATIVE = 1e-4
#: Absolute covariance floor, as a fraction of D (squared): (1e-7 · D)².
REST_COVARIANCE_FLOOR = 1e-7

_EPS32 = float(np.finfo(np.float32).eps)


def mesh_extent(mesh: TriangleMesh) -> tuple[float, float]:
    """(D, L): the bounding-box diagonal and the largest absolute coordinate of the vertices
    (metres; 0 for an empty mesh)."""
    if len(mesh.vertices) == 0:
        return 0.0, 0.0
    v = mesh.vertices.astype(np.float64)
    return float(np.linalg.norm(v.max(axis=0) - v.min(axis=0))), float(np.abs(v).max())


def rest_mean_tolerance(diagonal: float, largest: float) -> float:
    """The bound on |Δμ| for a mesh of bounding-box diagonal ``diagonal`` whose largest
    absolute coordinate is ``largest`` (see the module docstring)."""
    return REST_MEAN_RELATIVE * diagonal + REST_ROUNDING_ULPS * _EPS32 * largest
