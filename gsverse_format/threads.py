"""How many threads the package's native work runs on: the C nearest-triangle search, the
anchor derivation after it, and the C row gathers (:mod:`gsverse_format.rows`).

:func:`native_threads`: ``GSVERSE_THREADS`` when set to a positive integer, else the CPUs this
process may run on (``os.sched_getaffinity``). The numba kernels follow numba's own setting
(``NUMBA_NUM_THREADS``).
"""
from __future__ import annotations

import os

__all__ = ["THREADS_VARIABLE", "native_threads"]

#: Environment variable overriding the number of native threads (a positive integer).
THREADS_VARIABLE = "GSVERSE_THREADS"


def native_threads() -> int:
    """Threads of the native work: ``GSVERSE_THREADS`` when set, else the usable CPUs
    (``ValueError`` when the variable is set to anything but a positive integer)."""
    value = os.environ.get(THREADS_VARIABLE, "").strip()
    if value:
        try:
            n = int(value)
        except ValueError:
            n = 0
        if n < 1:
            raise ValueError(f"{THREADS_VARIABLE} must be a positive integer, got {value!r}")
        return n
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except AttributeError:                       # not on Linux
        return max(os.cpu_count() or 1, 1)
