"""Former path of :mod:`gsverse_format.remapping.reference` (re-exports only).

Kept because the spec named ``gsverse_format.remap_reference`` as the reference implementation,
so code written against it keeps working; new code imports from :mod:`gsverse_format.remapping`.
"""
from __future__ import annotations

from .remapping.reference import (RemapResult, RestData, covariance_entries, covariances_from,
                                  face_matrices, iter_moments, prepare_rest, remap, remap_moments)

__all__ = ["RemapResult", "remap", "RestData", "prepare_rest", "remap_moments", "iter_moments",
           "covariance_entries", "face_matrices", "covariances_from"]
