"""Former path of :mod:`gsverse_format.remapping.fast` (re-exports only).

Kept because the README and the spec named ``gsverse_format.remap_fast.FastRemapper``, so code
written against them keeps working; new code imports from :mod:`gsverse_format.remapping`.
"""
from __future__ import annotations

from .remapping.fast import (COV6_ORDER, FastRemapper, RemapOutput, cov6_to_matrix,
                             matrix_to_cov6, numba_available, remap_auto)

__all__ = ["COV6_ORDER", "RemapOutput", "FastRemapper", "remap_auto", "numba_available",
           "cov6_to_matrix", "matrix_to_cov6"]
