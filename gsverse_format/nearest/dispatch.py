"""Exact nearest-triangle queries (point → closest triangle of a mesh): the entry points,
:func:`nearest_triangles` and :func:`nearest_faces` (its faces and distances alone), both
re-exported by :mod:`gsverse_format.nearest`.

:func:`nearest_triangles` returns, for every query point, a triangle whose float64 distance to
the point is *exactly* the minimum over all selectable triangles — the value a brute-force scan
with :func:`closest_points_on_triangles` over every face would find — with the closest point on
it and that point's barycentric coordinates; among faces at exactly the minimal distance the
smallest face index wins.

Three implementations give identical results, bit for bit:

* :mod:`gsverse_format.nearest.reference`, the vectorised numpy reference, whose docstring
  states the kernel, the certified branch-and-bound search and the tie rule;
* :mod:`gsverse_format.nearest.native`, the search in C (``native/search/gsverse_nearest.h``,
  built with the package when a C compiler is present; a BVH traversed per point on all
  cores), which loads in a millisecond;
* :mod:`gsverse_format.nearest.compiled`, the same search compiled by numba, with its kernel in
  :mod:`gsverse_format.nearest.compiled_kernel`: the compiled search where the C one was not
  built.

This module only chooses between them (``method``). ``"auto"`` runs the C search when it was
built and neither :func:`gsverse_format.backend.set_backend` nor ``GSVERSE_BACKEND`` chose a
backend; otherwise :mod:`gsverse_format.backend` resolves it: ``GSVERSE_BACKEND=numpy`` or
``set_backend("numpy")`` forces the reference, ``numba`` the numba search, and under ``"auto"``
small jobs run the reference (see :data:`gsverse_format.backend.NEAREST_NUMPY_BELOW`).
"""
from __future__ import annotations

from typing import Callable

from numpy.typing import ArrayLike

import numpy as np

from ..atomic import interruptions_immediate
from ..backend import NEAREST_NUMPY_BELOW, BackendUnavailableError, get_backend, resolve_backend
from .native import (native_available, native_unavailable_reason, nearest_faces_native,
                     nearest_triangles_native)
from .reference import NearestResult, closest_points_on_triangles, nearest_triangles_numpy

__all__ = ["NearestResult", "nearest_triangles", "nearest_faces", "closest_points_on_triangles",
           "METHODS"]

#: The names ``method`` accepts.
METHODS: tuple[str, ...] = ("auto", "native", "numba", "numpy")


def nearest_triangles(points: ArrayLike, vertices: ArrayLike, faces: ArrayLike, *,
                      exclude: ArrayLike | None = None, chunk: int = 65536,
                      progress: Callable[[int, int], None] | None = None,
                      method: str = "auto") -> NearestResult:
    """Exact nearest triangle of ``(vertices, faces)`` for every point of ``points``.

    ``points`` (N, 3), ``vertices`` (V, 3) and ``faces`` (F, 3) integer indices; ``exclude``
    an optional (F,) boolean mask of faces never to return (for example degenerate ones).
    Queries run ``chunk`` points at a time; ``progress(done, total)`` is called after each.
    Raises ``ValueError`` on malformed input or when no face is selectable.
    See :mod:`gsverse_format.nearest.reference` for the exactness guarantee and the tie rule.

    ``method`` picks the implementation; all return identical results. ``"native"`` is the C
    search of :mod:`gsverse_format.nearest.native`, ``"numba"`` the numba search of
    :mod:`gsverse_format.nearest.compiled` (both multi-threaded), ``"numpy"`` the vectorised
    reference of :mod:`gsverse_format.nearest.reference`, and ``"auto"`` (default) the C search
    when it was built and no process-wide backend was chosen, else the process-wide choice of
    :mod:`gsverse_format.backend`: numba when it can be imported, unless ``GSVERSE_BACKEND`` or
    :func:`~gsverse_format.backend.set_backend` says otherwise, and numpy for jobs of fewer
    than :data:`~gsverse_format.backend.NEAREST_NUMPY_BELOW` points + faces (there the
    reference answers faster than numba can be imported, let alone compile its kernels).
    ``"native"`` where the C search was not built, or ``"numba"`` without numba, raises
    :class:`~gsverse_format.backend.BackendUnavailableError` (an ``ImportError``).
    """
    return _run(_choose(method, points, faces), points, vertices, faces, exclude, chunk,
                progress)


def nearest_faces(points: ArrayLike, vertices: ArrayLike, faces: ArrayLike, *,
                  exclude: ArrayLike | None = None, chunk: int = 65536,
                  progress: Callable[[int, int], None] | None = None,
                  method: str = "auto") -> tuple[np.ndarray, np.ndarray]:
    """``(face, distance)`` of :func:`nearest_triangles` (same arguments, same values) for
    callers that need no closest points: the C search then neither computes nor stores them
    and their barycentrics (48 bytes a point); the other implementations compute them and
    drop them."""
    chosen = _choose(method, points, faces)
    if chosen == "native":
        return nearest_faces_native(points, vertices, faces, exclude=exclude, chunk=chunk,
                                    progress=progress)
    res = _run(chosen, points, vertices, faces, exclude, chunk, progress)
    return res.face, res.distance


def _run(chosen: str, points: ArrayLike, vertices: ArrayLike, faces: ArrayLike,
         exclude: ArrayLike | None, chunk: int,
         progress: Callable[[int, int], None] | None) -> NearestResult:
    """The whole search by the implementation :func:`_choose` chose."""
    if chosen == "native":
        return nearest_triangles_native(points, vertices, faces, exclude=exclude, chunk=chunk,
                                        progress=progress)
    if chosen == "numba":
        with interruptions_immediate():   # compiled code: no Python handler may raise inside
            from .compiled import nearest_triangles_numba

            return nearest_triangles_numba(points, vertices, faces, exclude=exclude,
                                           chunk=chunk, progress=progress)
    return nearest_triangles_numpy(points, vertices, faces, exclude=exclude, chunk=chunk,
                                   progress=progress)


def _choose(method: str, points: ArrayLike, faces: ArrayLike) -> str:
    """The implementation ``method`` names for this job: ``"native"``, ``"numba"`` or
    ``"numpy"`` (see :func:`nearest_triangles`)."""
    chosen = method.strip().lower() if isinstance(method, str) else method
    if chosen not in METHODS:
        raise ValueError(f"method must be 'auto', 'native', 'numba' or 'numpy', got {method!r}")
    if chosen == "native" and not native_available():
        raise BackendUnavailableError(native_unavailable_reason())
    if chosen == "native" or (chosen == "auto" and get_backend() == "auto"
                              and native_available()):
        return "native"
    size = int(np.shape(points)[0]) + int(np.shape(faces)[0])
    return resolve_backend(chosen, argument="method", size=size,
                           numpy_below=NEAREST_NUMPY_BELOW)
