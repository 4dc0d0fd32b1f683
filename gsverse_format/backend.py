"""The one switch between the compiled (numba) and the reference (numpy) implementations.

Two computations have a compiled implementation beside their numpy reference:

* the exact nearest-triangle search, :func:`gsverse_format.nearest.nearest_triangles`
  (reference :mod:`gsverse_format.nearest_reference`, compiled
  :mod:`gsverse_format.nearest_compiled`; identical results, bit for bit);
* the per-frame float32 remap, :class:`gsverse_format.remap_fast.FastRemapper` and
  :func:`gsverse_format.remap_fast.remap_auto` (reference :mod:`gsverse_format.remap_reference`,
  compiled :mod:`gsverse_format.remap_compiled`; equal within the float32 bounds of
  :mod:`gsverse_format.remap_bounds`).

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
"""
from __future__ import annotations

import os
from functools import lru_cache

__all__ = ["BACKENDS", "ENVIRONMENT_VARIABLE", "BackendUnavailableError", "get_backend",
           "set_backend", "resolve_backend", "numba_available", "numba_unavailable_reason"]

#: The names a backend argument, :func:`set_backend` and ``GSVERSE_BACKEND`` accept.
BACKENDS: tuple[str, ...] = ("auto", "numba", "numpy")
#: The environment variable that sets the process-wide choice (see the module docstring).
ENVIRONMENT_VARIABLE = "GSVERSE_BACKEND"

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
        import numba  # noqa: F401
    except Exception as exc:  # ImportError, or a broken llvmlite / numpy combination
        return f"{type(exc).__name__}: {exc}"
    return None


def numba_available() -> bool:
    """True when the compiled backend can be used (numba imports)."""
    return numba_unavailable_reason() is None


def resolve_backend(requested: str = "auto", *, argument: str = "backend") -> str:
    """The backend to run, ``"numba"`` or ``"numpy"``, for a ``requested`` name.

    ``"auto"`` resolves through :func:`get_backend` (see the module docstring). Raises
    ``ValueError`` on an unknown name (naming ``argument``) and
    :class:`BackendUnavailableError` when ``"numba"`` is asked for and numba cannot be imported.
    """
    value = _check(requested, argument)
    if value == "auto":
        value = get_backend()
        if value == "auto":
            return "numba" if numba_available() else "numpy"
    if value == "numba" and not numba_available():
        raise BackendUnavailableError(
            f"the numba backend needs numba (pip install 'numba>=0.60'): "
            f"{numba_unavailable_reason()}")
    return value
