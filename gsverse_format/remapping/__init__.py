"""The remap: anchored splats onto the current anchor mesh (``spec/README.md`` §Remap).

* :mod:`.reference`: the normative float64 reference (:func:`remap`, :func:`remap_moments`),
  written to be read next to the spec;
* :mod:`.fast`: the per-frame float32 path, :class:`FastRemapper` and the one-shot
  :func:`remap_auto`, choosing between the compiled kernels and the reference
  (:mod:`gsverse_format.backend`);
* :mod:`.compiled` (numba): the per-face and per-splat steps and the two-pass kernels for splats
  in any order; :mod:`.compiled_runs` (numba): one parallel region per frame over runs of splats
  sharing a face (faces without splats are never computed);
* :mod:`.bounds`: the float32 error bounds of the fast path against the reference.

Importing this package does not import numba; :mod:`.fast` imports the compiled modules only
when the numba backend is chosen. The public entry point is :func:`gsverse_format.remap`.
"""
from __future__ import annotations

# No __all__: the API reference (pdoc, scripts/api_docs.py) gives each module of a package a
# page of its own only when the package has none.
from .bounds import float32_error_bounds
from .fast import FastRemapper, RemapOutput, remap_auto
from .reference import RemapResult, remap, remap_moments
