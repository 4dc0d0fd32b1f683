"""The exact nearest-triangle search in C, bit-identical to the numpy reference.

:func:`nearest_triangles_native` answers the question of
:func:`gsverse_format.nearest.reference.nearest_triangles_numpy` with the same
:class:`~gsverse_format.nearest.reference.NearestResult`, face for face and bit for bit. The
search is ``native/search/gsverse_nearest.h`` (portable C99: the same BVH, bounds, certificate
and tie rule as the numba search of :mod:`gsverse_format.nearest.compiled`, whose docstring
states them), compiled at install time into the extension ``gsverse_format.nearest._native``
(``setup.py``) without fused multiply-adds, and run on POSIX threads without the interpreter
lock. The margin and the degenerate-face ratio come from
:mod:`gsverse_format.nearest.reference` at each call, so the rules stay written once.

Why it exists beside the numba search: it loads in about a millisecond, where a new process
spends 0.6–1 s importing numba and loading its cached kernels before the first query (more
than a whole plain 100k-splat conversion). Binding therefore uses it whenever it was built
(:func:`gsverse_format.nearest.nearest_triangles`, ``method="auto"``). Installed without a C
compiler the extension is absent, :func:`native_unavailable_reason` says so, and the search
runs on numba.

Threads: :func:`gsverse_format.threads.native_threads` (the usable CPUs, or
``GSVERSE_THREADS``).
"""
from __future__ import annotations

from functools import lru_cache
from types import ModuleType
from typing import Callable

import numpy as np
from numpy.typing import ArrayLike

from ..threads import native_threads
from .reference import DEGENERATE_RATIO, MARGIN, NearestResult, prepare_query

__all__ = ["native_unavailable_reason", "native_available", "nearest_triangles_native",
           "nearest_faces_native"]


@lru_cache(maxsize=None)
def _module() -> ModuleType | None:
    try:
        from . import _native
    except ImportError:
        return None
    return _native


def native_unavailable_reason() -> str | None:
    """Why the C search cannot be used, or None when it can."""
    if _module() is None:
        return ("the compiled search gsverse_format.nearest._native was not built (the package "
                "was installed without a C compiler); reinstall with gcc or clang present")
    return None


def native_available() -> bool:
    """True when the C search was built with the package."""
    return _module() is not None


def nearest_triangles_native(points: ArrayLike, vertices: ArrayLike, faces: ArrayLike, *,
                             exclude: ArrayLike | None = None, chunk: int = 65536,
                             progress: Callable[[int, int], None] | None = None,
                             _level: int | None = None) -> NearestResult:
    """The C search: same arguments and result as
    :func:`~gsverse_format.nearest.reference.nearest_triangles_numpy`, bit for bit.

    The query loop is compiled for several instruction sets (generic x86-64 or any CPU, AVX2,
    AVX-512F; the same operations in the same order, so the same bits) and runs the widest
    this CPU has (``_native.level()``); ``_level`` picks a narrower one (the tests compare
    them).

    Raises :class:`ImportError` when the extension was not built (see
    :func:`native_unavailable_reason`)."""
    P, V, F, idx = prepare_query(points, vertices, faces, exclude, chunk, float32_points=True)
    res = NearestResult.allocate(P.shape[0])
    _search(P, V, F, idx, chunk, progress, _level, res.face, res.distance, res.closest,
            res.barycentric)
    return res


def nearest_faces_native(points: ArrayLike, vertices: ArrayLike, faces: ArrayLike, *,
                         exclude: ArrayLike | None = None, chunk: int = 65536,
                         progress: Callable[[int, int], None] | None = None,
                         _level: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``face`` and ``distance`` of :func:`nearest_triangles_native`, the same values,
    without its closest points and barycentrics: neither computed nor stored (48 bytes a
    point)."""
    P, V, F, idx = prepare_query(points, vertices, faces, exclude, chunk, float32_points=True)
    face, distance = np.empty(P.shape[0], np.int64), np.empty(P.shape[0])
    _search(P, V, F, idx, chunk, progress, _level, face, distance, None, None)
    return face, distance


def _search(P: np.ndarray, V: np.ndarray, F: np.ndarray, idx: np.ndarray, chunk: int,
            progress: Callable[[int, int], None] | None, level: int | None,
            face: np.ndarray, distance: np.ndarray, closest: np.ndarray | None,
            barycentric: np.ndarray | None) -> None:
    """The search of checked arguments (:func:`prepare_query`; ``P`` float64, or float32
    converted exactly as the C code reads it) into the given rows; the closest points and
    barycentrics only when arrays for them are given."""
    mod = _module()
    if mod is None:
        raise ImportError(native_unavailable_reason())
    n = P.shape[0]
    if n == 0:
        if progress is not None:
            progress(0, 0)
        return
    threads = native_threads()
    level = mod.level() if level is None else level
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    tree = mod.build(V, F, np.ascontiguousarray(idx, dtype=np.int64), DEGENERATE_RATIO, threads)
    order = np.empty(n, np.int64)
    Ps = np.empty((n, 3))
    mod.sort_queries(P, order, Ps)               # float32 points converted as they are read
    for lo in range(0, n, chunk):
        hi = min(lo + chunk, n)
        mod.query(tree, Ps, order, lo, hi, MARGIN, threads, face, distance, closest,
                  barycentric, level)
        if progress is not None:
            progress(hi, n)
