"""Types of the compiled extension built from native/rows/rows_module.c (see
:mod:`gsverse_format.rows`, which is its only caller)."""
import numpy as np

def gather(src: np.ndarray, row_bytes: int, offset: int, width: int, order: np.ndarray,
           dst: np.ndarray, threads: int) -> None: ...

def columns(src: np.ndarray, row_bytes: int, offset: int, width: int, first: int,
            dst: np.ndarray, threads: int) -> None: ...
