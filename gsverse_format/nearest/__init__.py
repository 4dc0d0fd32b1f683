"""Exact nearest-triangle search (point → closest triangle of a mesh), used by the binding.

* :mod:`.dispatch`: :func:`nearest_triangles` and :func:`nearest_faces`, the entry points, choosing an implementation
  (:mod:`gsverse_format.backend`);
* :mod:`.reference`: the vectorised numpy reference, whose docstring states the point–triangle
  kernel, the certified branch-and-bound search and the tie rule;
* :mod:`.native`: the same search in C (``native/search/gsverse_nearest.h``, the extension
  ``_native`` built at install), bit-identical to the reference; what binding runs;
* :mod:`.compiled` (numba): a BVH traversed per point on all cores, bit-identical to the
  reference; its scalar kernel in :mod:`.compiled_kernel`; what binding runs where the C
  search was not built.

Importing this package does not import numba; :mod:`.dispatch` imports the compiled modules only
when the numba backend is chosen.
"""
from __future__ import annotations

# No __all__: the API reference (pdoc, scripts/api_docs.py) gives each module of a package a
# page of its own only when the package has none.
from .dispatch import nearest_faces, nearest_triangles
from .reference import NearestResult, closest_points_on_triangles
