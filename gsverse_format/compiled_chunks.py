"""Dynamic scheduling of the compiled (numba) kernels: chunks handed out from a shared counter.

The parallel kernels of :mod:`gsverse_format.remapping` and the queries of
:mod:`gsverse_format.nearest` start one worker per thread (``prange(workers)``) and let each
worker take the next chunk of the work from a shared counter until none is left, instead of
giving each thread a fixed share: when another process keeps a thread off its core, the other
threads take the remaining chunks and the region waits only for the chunk that thread holds.
The loop each of them runs::

    n_chunks = chunk_count(n, size)
    counter = np.zeros(1, np.int64)
    for _ in prange(workers):
        while True:
            c, start, stop = next_chunk(counter, size, n)
            if c >= n_chunks:
                break
            for i in range(start, stop):
                ...

:func:`fetch_add` is the atomic increment (one ``atomicrmw add``); :func:`next_chunk` takes a
chunk and gives its bounds. Both are inlined into the kernels that call them. The test against
``n_chunks`` stays in the kernel, after the bounds: a :func:`next_chunk` that returned a marker
for "none left" instead made the one-pass ``games`` kernel about 20% slower.

Importing this module imports numba. Compiled code is cached on disk (``cache=True``), and numba
checks only a function's own source file for changes: after editing :func:`next_chunk`, delete
the cached entries of the modules that inline it (``__pycache__/*.nbi`` and ``*.nbc`` in
``remapping/`` and ``nearest/``, or under ``NUMBA_CACHE_DIR``).
"""
from __future__ import annotations

from typing import Any, Callable

from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

from .backend import configure_numba

configure_numba()

__all__ = ["fetch_add", "next_chunk", "chunk_count"]


@intrinsic
def fetch_add(typingctx: Any, arr: Any, val: Any) -> tuple[Any, Callable[..., Any]]:
    """Atomically add ``val`` to ``arr[0]`` (int64) and return the previous value."""
    sig = types.int64(arr, types.int64)

    def codegen(context, builder, signature, args):
        a, v = args
        aryty = signature.args[0]
        ary = context.make_array(aryty)(context, builder, a)
        ptr = cgutils.get_item_pointer(context, builder, aryty, ary,
                                       [context.get_constant(types.intp, 0)])
        return builder.atomic_rmw("add", ptr, v, "monotonic")

    return sig, codegen


@njit(cache=True, inline="always")
def chunk_count(n, size):
    """The number of chunks of ``size`` items that cover ``n`` items."""
    return (n + size - 1) // size


@njit(cache=True, inline="always")
def next_chunk(counter, size, n):
    """The next chunk for the calling thread: ``(c, start, stop)``, chunk ``c`` (taken from
    ``counter``, a (1,) int64 array shared by the workers) covering items ``start .. stop - 1``
    of ``n``, ``size`` at a time. The caller stops once ``c`` reaches its number of chunks
    (:func:`chunk_count`); ``start`` and ``stop`` of such a chunk mean nothing."""
    c = fetch_add(counter, 1)
    start = c * size
    return c, start, min(start + size, n)
