"""Types of the compiled extension built from native/search/nearest_module.c (see
:mod:`gsverse_format.nearest.native`, which is its only caller)."""
from typing import Any

import numpy as np

def build(V: np.ndarray, F: np.ndarray, idx: np.ndarray, degenerate_ratio: float,
          threads: int) -> Any: ...
def sort_queries(P: np.ndarray, order: np.ndarray, Ps: np.ndarray) -> None: ...
def query(tree: Any, Ps: np.ndarray, order: np.ndarray, lo: int, hi: int, margin: float,
          threads: int, face: np.ndarray, distance: np.ndarray, closest: np.ndarray,
          barycentric: np.ndarray) -> None: ...
