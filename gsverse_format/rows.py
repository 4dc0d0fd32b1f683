"""Rows of arrays taken in a new order: the splats' arrays grouped by face.

:func:`take_rows` is ``array[index]`` along the first axis, :func:`permute_rows_in_place`
is ``array[:] = array[order]`` without a second copy of the array alive, and
:func:`contiguous_rows` is ``np.ascontiguousarray(view[start:stop])`` for a view of some
columns of an array (one SH coefficient of every splat, as a glTF writer stores them). All
three give numpy's result bit for bit: the gathers are byte copies. For integer indices and arrays of at least
:data:`NATIVE_MIN_BYTES` they run in C (``native/rows/rows_module.c``, built by ``setup.py``
as the optional extension ``gsverse_format._rows``) on :func:`~gsverse_format.threads.
native_threads` threads, prefetching the rows ahead; numpy's ``take`` copies one row at a
time with nothing in flight, and a gather in a random order waits on memory. Measured on 1M
rows in face order (100k faces, random input order), two threads: the (N, 16, 3) float32 SH
reordered in place 0.04 s against 0.1 s, (N, 3) float32 taken 0.002–0.003 s against
0.011 s. Without the extension (installed without a C compiler) or below the size, numpy does
the same work.
"""
from __future__ import annotations

import math
from functools import lru_cache
from types import ModuleType

import numpy as np

from .threads import native_threads

__all__ = ["NATIVE_MIN_BYTES", "PERMUTE_BLOCKS", "native_rows_available", "take_rows",
           "permute_rows_in_place", "contiguous_rows"]

#: Smallest gather (bytes of the result) handed to the C gather; smaller ones cost less in
#: numpy than starting the threads.
NATIVE_MIN_BYTES = 1 << 20

#: :func:`permute_rows_in_place` reorders an array in this many blocks of columns, so that its
#: temporary is half the array instead of a full copy. Measured (SH degree 3, numpy's gather,
#: fresh processes): 1M splats (192 MB) 0.096 s with 2 blocks against 0.13 s with 3 and
#: 0.06-0.18 s with 1; 4M (768 MB) 0.37-0.39 s against 0.54-1.05 s with 3 and 1.0-1.7 s for
#: ``np.take`` into a new array (a block is one random gather over all rows). The half-size
#: temporary stays under the conversion's peak, which is reading the PLY.
PERMUTE_BLOCKS = 2


@lru_cache(maxsize=None)
def _module() -> ModuleType | None:
    try:
        from . import _rows
    except ImportError:
        return None
    return _rows


def native_rows_available() -> bool:
    """True when the C gather was built with the package."""
    return _module() is not None


def _gather(src: np.ndarray, row_bytes: int, offset: int, width: int, order: np.ndarray,
            dst: np.ndarray) -> bool:
    """Bytes ``offset .. offset + width`` of rows ``order`` of ``src`` (rows of ``row_bytes``)
    into the rows of ``dst`` with the C gather; False, with nothing written, when it cannot
    (no extension, or an index numpy must judge: negative or out of range)."""
    mod = _module()
    if mod is None or order.dtype.kind not in "iu" or order.ndim != 1:
        return False
    if order.dtype != np.int64:
        if order.size and int(order.max()) > np.iinfo(np.int64).max:
            return False
        order = order.astype(np.int64)
    try:
        mod.gather(src, row_bytes, offset, width, np.ascontiguousarray(order), dst,
                   native_threads())
    except ValueError:
        return False
    return True


def _plain(array: np.ndarray) -> bool:
    """Whether ``array``'s rows are plain bytes the C gather may copy."""
    return (array.ndim >= 1 and array.flags.c_contiguous and not array.dtype.hasobject
            and array.dtype.itemsize > 0)


def take_rows(array: np.ndarray, index) -> np.ndarray:
    """``array[index]`` along the first axis: for a 1-D integer index array ``np.take``'s
    result (the C gather for large results; negative and out-of-range indices are numpy's to
    judge), fancy indexing for anything else (boolean masks, slices)."""
    if not (isinstance(index, np.ndarray) and index.dtype.kind in "iu" and index.ndim == 1):
        return array[index]
    array = np.asarray(array)
    if _plain(array) and len(array):
        row_bytes = array.nbytes // len(array)
        if row_bytes * len(index) >= NATIVE_MIN_BYTES:
            out = np.empty((len(index),) + array.shape[1:], array.dtype)
            if _gather(array, row_bytes, 0, row_bytes, index, out):
                return out
    return np.take(array, index, axis=0)


def permute_rows_in_place(array: np.ndarray, order: np.ndarray) -> None:
    """``array[:] = array[order]`` for a C-contiguous, writeable ``array`` and a permutation
    ``order`` of its rows (not checked here), :data:`PERMUTE_BLOCKS` blocks of columns at a
    time when its row divides into that many, else whole rows: each block gathered into a
    temporary, then copied back."""
    flat = array.reshape(array.shape[0], -1)
    blocks = math.gcd(flat.shape[1], PERMUTE_BLOCKS)
    width = flat.itemsize * flat.shape[1] // blocks
    items = flat.view(np.dtype((np.void, width)))
    # one temporary for every block: a fresh one would be faulted in again each time
    block = (np.empty((len(order), width), np.uint8)
             if _plain(array) and len(array) * width >= NATIVE_MIN_BYTES else None)
    for b in range(blocks):
        if block is not None and _gather(array, width * blocks, b * width, width, order, block):
            items[:, b] = block.view(items.dtype)[:, 0]
        else:
            items[:, b] = items[order, b]


def _column_layout(view: np.ndarray) -> tuple[np.ndarray, int, int, int] | None:
    """``(base, row_bytes, offset, width)`` when ``view`` is a block of columns of the
    C-contiguous array ``base`` (the same rows; each of its rows ``width`` contiguous bytes at
    ``offset`` in a row of ``base`` of ``row_bytes``), else None."""
    base = view.base
    if (not isinstance(base, np.ndarray) or view.ndim < 1 or not _plain(base)
            or view.dtype.hasobject or len(base) != len(view) or len(view) == 0):
        return None
    row_bytes = base.nbytes // len(base)
    width = view.dtype.itemsize
    for size, stride in zip(view.shape[:0:-1], view.strides[:0:-1]):
        if size > 1 and stride != width:
            return None
        width *= size
    offset = view.__array_interface__["data"][0] - base.__array_interface__["data"][0]
    if view.strides[0] != row_bytes or width == 0 or not 0 <= offset <= row_bytes - width:
        return None
    return base, row_bytes, offset, width


def contiguous_rows(view: np.ndarray, start: int, stop: int) -> np.ndarray:
    """``np.ascontiguousarray(view[start:stop])``, bit for bit (0 <= start <= stop <= len).
    A block of :data:`NATIVE_MIN_BYTES` or more of a view of some columns of a C-contiguous
    array (``sh[:, k, :]``: rows strided, the bytes of a row contiguous) is copied by the C
    extension's ``columns`` on the native threads: numpy's strided copy of rows of a few
    bytes is bound by its loop (see ``native/rows/rows_module.c``)."""
    part = view[start:stop]
    mod = _module()
    if mod is None or part.flags.c_contiguous or part.nbytes < NATIVE_MIN_BYTES:
        return np.ascontiguousarray(part)
    layout = _column_layout(view)
    if layout is None:
        return np.ascontiguousarray(part)
    base, row_bytes, offset, width = layout
    out = np.empty(part.shape, view.dtype)
    mod.columns(base, row_bytes, offset, width, start, out, native_threads())
    return out

