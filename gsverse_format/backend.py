"""The one switch between the compiled (numba) and the reference (numpy) implementations.

Two computations have a compiled implementation beside their numpy reference:

* the exact nearest-triangle search, :func:`gsverse_format.nearest.nearest_triangles`
  (reference :mod:`gsverse_format.nearest.reference`, compiled
  :mod:`gsverse_format.nearest.compiled`; identical results, bit for bit). It has a third
  implementation, in C (:mod:`gsverse_format.nearest.native`), which ``"auto"`` runs before
  this module's choice whenever it was built and neither :func:`set_backend` nor
  ``GSVERSE_BACKEND`` chose: the small-job rule below applies where it was not built;
* the per-frame float32 remap, :class:`gsverse_format.remapping.fast.FastRemapper` and
  :func:`gsverse_format.remapping.fast.remap_auto` (reference
  :mod:`gsverse_format.remapping.reference`, compiled :mod:`gsverse_format.remapping.compiled`;
  equal within the float32 bounds of :mod:`gsverse_format.remapping.bounds`).

Each takes a backend name, ``"numba"``, ``"numpy"`` or ``"auto"`` (the default). An explicit
``"numba"`` or ``"numpy"`` is used as given. ``"auto"`` defers to the process-wide choice,
which is, in this order:

1. the last :func:`set_backend` call (``set_backend("auto")`` clears it);
2. the environment variable ``GSVERSE_BACKEND`` (``numba``, ``numpy`` or ``auto``, any case;
   unset or empty means ``auto``), read at each call; ``GSVERSE_BACKEND=numpy`` forces the
   reference everywhere, for example to rule the compiled code out when chasing a problem;
3. ``numba`` when it can be imported, else ``numpy``.

Asking for ``numba`` (by argument, :func:`set_backend` or the environment) where numba cannot
be imported raises :class:`BackendUnavailableError`; an unknown name raises ``ValueError``.

Small inputs (cold start)
    numba compiles a kernel on its first call and caches the machine code on disk
    (``cache=True``: in ``__pycache__`` beside the module, or under ``NUMBA_CACHE_DIR``). On a
    fresh install the README's first conversion (3,000 splats, 1,280 faces) spent 8.4 s compiling
    the 14 functions of the nearest-triangle search, against 0.84 s with the cache filled; even
    warm, importing numba and loading those cached kernels costs about 0.43 s in a new process,
    where the numpy reference answers that query in 0.05 s. So ``"auto"`` (only ``"auto"``, and
    only when neither :func:`set_backend` nor ``GSVERSE_BACKEND`` chose) runs the numpy
    reference for a job whose size is below that computation's threshold, without importing
    numba at all:

    * nearest triangles: points + faces below :data:`NEAREST_NUMPY_BELOW` (32,768). Measured
      (2-core EPYC, one process per row, first call with the kernels in the on-disk cache):
      numba 0.43 s at 3,000 points × 1,280 faces, 0.43–0.51 s at 20,000 × 5,120 and 0.47 s at
      40,000 × 20,480; the numpy reference 0.05 s, 0.27 s and 0.73 s. The two cross near
      points + faces ≈ 40,000, and below the threshold the reference stays under about 0.4 s;
    * one-shot remaps (:func:`gsverse_format.remapping.fast.remap_auto`): splats below
      :data:`REMAP_NUMPY_BELOW` (65,536). At 65,536 splats the float64 reference took 0.36 s
      of CPU (``local``/affine, with rotations and scales; 0.08 s rigid, 0.05 s games; 0.03 s
      at 3,000 splats), while compiling the remap kernels in a fresh cache took 9.5 s
      (``local``) and 6.1 s (games). A :class:`~gsverse_format.remapping.fast.FastRemapper` is
      built for per-frame use and keeps numba under ``"auto"``.

    Both implementations give the same results (bit for bit for the nearest search, within the
    float32 bounds of :mod:`gsverse_format.remapping.bounds` for the remap), so the threshold
    changes only the time. ``tests/test_backend.py`` checks, in a fresh process with an empty
    ``NUMBA_CACHE_DIR``, that converting and validating the README example never imports numba.

Threading layer
    :func:`configure_numba` (called by :func:`numba_available` and by every compiled module
    when imported) sets numba's threading-layer priority to OpenMP, then TBB, then the built-in
    workqueue (numba's default tries TBB first). pymeshlab bundles an older libtbb; once it is
    loaded, numba's TBB probe warned "The TBB threading layer requires TBB version 2021 update
    6 or later" and then fell back to OpenMP anyway, so trying OpenMP first removes the warning
    and changes no speed (the same layer runs). workqueue stays last: it is not thread-safe
    (two Python threads launching kernels at once abort the process, e.g. a Dask worker with
    several threads). ``NUMBA_THREADING_LAYER`` or ``NUMBA_THREADING_LAYER_PRIORITY`` set in
    the environment are left as the user set them; the remap section of ``python -m benchmarks``
    notes the layer in use.

Vector width
    :func:`configure_numba` also compiles the kernels without AVX-512 (the host's features
    with every ``avx512*``, ``avx10*`` and ``evex512`` feature off, so AVX2 and FMA at most)
    on CPUs that have it. On AVX-512 targets LLVM vectorises the remap's splat loops sixteen
    splats wide, loading each splat's twelve constants with gathers and storing its nine
    outputs with scatters (the arrays are interleaved, a row per splat); with AVX2 the same
    loops use shuffles. Measured on a 2-vCPU AMD EPYC (Zen 5, ``znver5``), one thread, 1M
    splats: 16.4 against 7.0 ms on 100k faces, 19.7 against 3.4 ms on 200 faces (long
    runs, where the vectorised loop does all the work). The features enter the key of
    numba's on-disk cache, so kernels compiled with other features are compiled again.
    ``NUMBA_CPU_FEATURES`` or ``NUMBA_CPU_NAME`` set in the environment (or
    ``numba.config.CPU_FEATURES`` / ``CPU_NAME`` set before) are left as they are.
"""
from __future__ import annotations

import os
from functools import lru_cache

from .atomic import interruptions_immediate

__all__ = ["BACKENDS", "ENVIRONMENT_VARIABLE", "NEAREST_NUMPY_BELOW", "REMAP_NUMPY_BELOW",
           "BackendUnavailableError", "get_backend", "set_backend", "resolve_backend",
           "numba_available", "numba_unavailable_reason", "configure_numba",
           "without_512_bit_vectors"]

#: The names a backend argument, :func:`set_backend` and ``GSVERSE_BACKEND`` accept.
BACKENDS: tuple[str, ...] = ("auto", "numba", "numpy")
#: The environment variable that sets the process-wide choice (see the module docstring).
ENVIRONMENT_VARIABLE = "GSVERSE_BACKEND"

#: ``"auto"`` runs the numpy nearest-triangle search below this many points + faces
#: (see "Small inputs" in the module docstring for the measurement).
NEAREST_NUMPY_BELOW = 32_768
#: ``"auto"`` runs a one-shot remap on the numpy reference below this many splats.
REMAP_NUMPY_BELOW = 65_536
#: numba's threading layers in the order this package prefers them (see the module docstring).
THREADING_LAYER_PRIORITY = ["omp", "tbb", "workqueue"]
#: Target features :func:`configure_numba` turns off (prefixes; see "Vector width").
_WIDE_VECTOR_FEATURES = ("avx512", "avx10", "evex512")

_chosen: str | None = None


class BackendUnavailableError(ImportError):
    """The compiled backend was asked for, but numba cannot be imported."""


def _check(name: str, where: str) -> str:
    value = name.strip().lower() if isinstance(name, str) else name
    if value not in BACKENDS:
        raise ValueError(f"{where} must be 'auto', 'numba' or 'numpy', got {name!r}")
    return value


def set_backend(name: str) -> None:
    """Set the process-wide backend that ``"auto"`` resolves to (``"auto"`` clears it)."""
    global _chosen
    value = _check(name, "backend")
    _chosen = None if value == "auto" else value


def get_backend() -> str:
    """The process-wide choice: ``"numba"``, ``"numpy"`` or ``"auto"`` (numba when importable).

    :func:`set_backend` wins over ``GSVERSE_BACKEND``; neither set means ``"auto"``.
    """
    if _chosen is not None:
        return _chosen
    return _check(os.environ.get(ENVIRONMENT_VARIABLE, "") or "auto", ENVIRONMENT_VARIABLE)


@lru_cache(maxsize=None)
def numba_unavailable_reason() -> str | None:
    """Why numba cannot be imported (``"ImportError: ..."``), or None when it can."""
    try:
        configure_numba()
    except Exception as exc:  # ImportError, or a broken llvmlite / numpy combination
        return f"{type(exc).__name__}: {exc}"
    return None


def configure_numba() -> None:
    """Import numba and prefer its OpenMP, then TBB, then workqueue threading layer (see
    "Threading layer" in the module docstring), unless ``NUMBA_THREADING_LAYER`` or
    ``NUMBA_THREADING_LAYER_PRIORITY`` is set. The compiled modules call it when imported;
    it takes effect before numba first starts its threads. Imported where a stop signal
    ends the process at once (:func:`gsverse_format.atomic.interruptions_immediate`): an
    interruption raised inside numba's import leaves it half set up, and its ``ImportError``
    would then read as "numba unavailable" and the run go on without it."""
    with interruptions_immediate():
        import numba

    if not (os.environ.get("NUMBA_THREADING_LAYER")
            or os.environ.get("NUMBA_THREADING_LAYER_PRIORITY")):
        setattr(numba.config, "THREADING_LAYER_PRIORITY", list(THREADING_LAYER_PRIORITY))
    config = numba.config
    if (getattr(config, "CPU_FEATURES", None) is None and getattr(config, "CPU_NAME", None) is None
            and not os.environ.get("NUMBA_CPU_FEATURES") and not os.environ.get("NUMBA_CPU_NAME")):
        from numba.core.codegen import get_host_cpu_features

        host = get_host_cpu_features()
        narrowed = without_512_bit_vectors(host)
        if host and narrowed != host:
            setattr(config, "CPU_FEATURES", narrowed)


def without_512_bit_vectors(features: str) -> str:
    """LLVM's comma-separated target ``features`` (``+avx2,+avx512f,...``) with every
    AVX-512 and AVX10 feature, and ``evex512``, turned off (see "Vector width" in the module
    docstring); the others as given."""
    out = []
    for item in features.split(","):
        name = item[1:] if item[:1] in "+-" else item
        if item[:1] == "+" and name.startswith(_WIDE_VECTOR_FEATURES):
            item = "-" + name
        out.append(item)
    return ",".join(out)


def numba_available() -> bool:
    """True when the compiled backend can be used (numba imports)."""
    return numba_unavailable_reason() is None


def resolve_backend(requested: str = "auto", *, argument: str = "backend",
                    size: int | None = None, numpy_below: int = 0) -> str:
    """The backend to run, ``"numba"`` or ``"numpy"``, for a ``requested`` name.

    ``"auto"`` resolves through :func:`get_backend` (see the module docstring); when that is
    ``"auto"`` too and the job's ``size`` is below ``numpy_below``, the answer is ``"numpy"``
    and numba is not imported (see "Small inputs" in the module docstring). Raises
    ``ValueError`` on an unknown name (naming ``argument``) and
    :class:`BackendUnavailableError` when ``"numba"`` is asked for and numba cannot be imported.
    """
    value = _check(requested, argument)
    if value == "auto":
        value = get_backend()
        if value == "auto":
            if size is not None and size < numpy_below:
                return "numpy"
            return "numba" if numba_available() else "numpy"
    if value == "numba" and not numba_available():
        raise BackendUnavailableError(
            f"the numba backend needs numba (pip install 'numba>=0.60'): "
            f"{numba_unavailable_reason()}")
    return value
