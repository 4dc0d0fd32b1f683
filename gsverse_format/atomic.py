"""Atomic file output: write to a temporary file beside the target, then rename."""
from __future__ import annotations

import contextlib
import os
import tempfile
from typing import IO, Iterator

from .errors import UsageError


def _current_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "wb",
                 protect: tuple[str | os.PathLike, ...] = ()) -> Iterator[IO]:
    """Open a temporary file in the target's folder; on success rename it over ``path``.

    On any exception the temporary file is removed and ``path`` is left untouched, so a
    failed write never leaves a half-written output. ``protect`` lists input files that
    must never be overwritten (a ``UsageError`` is raised before anything is written).
    """
    path = os.fspath(path)
    target = os.path.realpath(path)
    for other in protect:
        if other is not None and os.path.exists(other) and os.path.exists(target) \
                and os.path.samefile(other, target):
            raise UsageError("output would overwrite an input file", path)
    folder = os.path.dirname(os.path.abspath(path)) or "."
    if not os.path.isdir(folder):
        raise UsageError(f"output folder {folder!r} does not exist", path)
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=os.path.basename(path)[-16:], dir=folder)
    try:
        os.chmod(tmp, 0o666 & ~_current_umask())  # mkstemp creates 0600; behave like open()
        with os.fdopen(fd, mode) as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
