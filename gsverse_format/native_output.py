"""What native libraries print on the process's file descriptors 1 and 2 (C stdio,
``std::cout``), held back while they run (:func:`native_output`): screened Poisson (pymeshlab)
prints ``[WARNING] Found out-of-bound points: N`` straight to the terminal, past Python's
``sys.stderr``, which a command's one-line-per-finding stderr does not allow. The lines that
start with a prefix the caller names are held for it (it turns them into summary notes); every
other line is written back to stderr when the block ends, so nothing else is lost (a Python
thread's output during the block included)."""
from __future__ import annotations

import ctypes
import os
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["NativeOutput", "native_output"]


class NativeOutput:
    """``held``: the lines printed during a :func:`native_output` block that start with one of
    its prefixes (filled when the block ends)."""

    def __init__(self) -> None:
        self.held: list[str] = []


def _flush_c_stdio() -> None:
    """Flush C stdio buffers (a native ``printf`` to a file is block-buffered)."""
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):  # pragma: no cover - no C library to flush
        pass


@contextmanager
def native_output(hold: tuple[str, ...]) -> Iterator[NativeOutput]:
    """Redirect file descriptors 1 and 2 to a temporary file for the block; when it ends (also
    on an exception) restore them, keep the lines that start with a prefix in ``hold`` in the
    yielded :class:`NativeOutput` and write the others to stderr."""
    out = NativeOutput()
    for stream in (sys.stdout, sys.stderr):
        if stream is not None:
            stream.flush()
    _flush_c_stdio()
    saved: list[int] = []
    try:
        saved.append(os.dup(1))
        saved.append(os.dup(2))
    except OSError:   # a descriptor is closed: nothing can reach a terminal through it
        for fd in saved:
            os.close(fd)
        yield out
        return
    try:
        with tempfile.TemporaryFile() as held:
            os.dup2(held.fileno(), 1)
            os.dup2(held.fileno(), 2)
            try:
                yield out
            finally:
                for stream in (sys.stdout, sys.stderr):
                    if stream is not None:
                        stream.flush()
                _flush_c_stdio()
                os.dup2(saved[0], 1)
                os.dup2(saved[1], 2)
                held.seek(0)
                lines = held.read().decode("utf-8", "replace").splitlines()
                out.held = [line for line in lines if line.startswith(hold)]
                rest = [line for line in lines if not line.startswith(hold)]
                if rest and sys.stderr is not None:
                    sys.stderr.write("".join(line + "\n" for line in rest))
                    sys.stderr.flush()
    finally:
        for fd in saved:
            os.close(fd)
