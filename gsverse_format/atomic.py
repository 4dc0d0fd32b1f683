"""Atomic file output: write to a temporary file beside the target, then rename.

Temporary files (and folders) are named ``.<target name>.gsverse-tmp-<host>-<pid>-<random>``:
hidden, never ending in an output suffix (so that no glob, ``--skip-existing`` or folder scan
takes one for an output), and naming the machine and process that owns them. A process
removes its own temporaries when it fails or is interrupted (the command-line tools turn
SIGTERM and SIGHUP into the same unwinding as Ctrl-C); a process killed outright (SIGKILL,
power loss) leaves its temporary behind, and the next write into that folder on the same
machine removes it once its process is gone and it is older than :data:`STALE_AFTER_S`.

Operating-system failures of the write itself (a read-only folder, a full disk, a file-size
limit, an output path that is a folder) are :class:`~gsverse_format.errors.OutputError`
naming the output and the system's reason.
"""
from __future__ import annotations

import contextlib
import errno
import hashlib
import os
import re
import secrets
import shutil
import socket
import time
from typing import IO, Iterator

from .errors import OutputError, UsageError

__all__ = ["atomic_write", "temporary_folder", "check_target", "file_mode", "is_temporary",
           "sweep_stale", "discard_temporaries", "output_error", "TEMP_MARK", "STALE_AFTER_S"]

#: What every temporary's name holds between the target's name and its owner.
TEMP_MARK = ".gsverse-tmp-"
#: A dead process's temporary is removed only when it has not changed for this many seconds
#: (a guard against a process id seen from another PID namespace on the same host name).
STALE_AFTER_S = 600.0
#: The operating-system errors that mean "this output cannot be written here" (the user's
#: environment, not a bug): permissions, read-only or full file systems, quotas, size limits,
#: a path through a file or onto a folder, a name too long, an I/O error of the device.
WRITE_ERRNOS = frozenset(getattr(errno, name) for name in (
    "EACCES", "EPERM", "EROFS", "ENOSPC", "EDQUOT", "EFBIG", "EISDIR", "ENOTDIR", "ENOENT",
    "ENAMETOOLONG", "EIO", "ELOOP", "EMLINK", "ETXTBSY", "EXDEV") if hasattr(errno, name))

_NAME = re.compile(r"^\.(?P<target>.+)" + re.escape(TEMP_MARK)
                   + r"(?P<host>[0-9a-f]{8})-(?P<pid>\d+)-[0-9a-f]{8}$")
#: Temporaries this process has open right now (removed by :func:`discard_temporaries`).
_LIVE: set[str] = set()
#: Folders this process has swept already.
_SWEPT: set[str] = set()


def _host() -> str:
    return hashlib.sha1(socket.gethostname().encode("utf-8", "replace")).hexdigest()[:8]


def _temporary_name(path: str) -> str:
    """A fresh temporary name beside ``path`` (the target's name cut to fit NAME_MAX)."""
    folder, base = os.path.split(os.path.abspath(path))
    tail = f"{TEMP_MARK}{_host()}-{os.getpid()}-{secrets.token_hex(4)}"
    base = base.encode("utf-8", "surrogateescape")[:200].decode("utf-8", "ignore") or "out"
    return os.path.join(folder, f".{base}{tail}")


def is_temporary(name: str) -> bool:
    """Whether the file name ``name`` (no folder) is one of these temporaries."""
    return _NAME.match(name) is not None


def _alive(pid: int) -> bool:
    if os.name != "posix":  # no harmless "is it alive" signal there: keep everything
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, ValueError):
        return True  # someone else's process, or an id we cannot ask about: keep the file
    return True


def sweep_stale(folder: str | os.PathLike[str], *, min_age: float = STALE_AFTER_S) -> list[str]:
    """Remove the temporaries in ``folder`` left by dead processes of this machine (their
    process id no longer exists) that have not changed for ``min_age`` seconds; returns their
    paths. Anything else (other names, other machines' or live processes' temporaries) stays."""
    removed: list[str] = []
    host, now = _host(), time.time()
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        m = _NAME.match(entry.name)
        if m is None or m["host"] != host or _alive(int(m["pid"])):
            continue
        try:
            if now - entry.stat(follow_symlinks=False).st_mtime < min_age:
                continue
            if entry.is_dir(follow_symlinks=False):
                shutil.rmtree(entry.path)
            else:
                os.unlink(entry.path)
        except OSError:
            continue
        removed.append(entry.path)
    return removed


def _sweep_once(folder: str) -> None:
    key = os.path.realpath(folder)
    if key not in _SWEPT:
        _SWEPT.add(key)
        sweep_stale(folder)


def _remove(tmp: str) -> None:
    with contextlib.suppress(FileNotFoundError):
        if os.path.isdir(tmp) and not os.path.islink(tmp):
            shutil.rmtree(tmp, ignore_errors=True)
        else:
            os.unlink(tmp)
    _LIVE.discard(tmp)


def discard_temporaries() -> None:
    """Remove every temporary this process still has open (a process boundary calls this
    when a signal ends the process, in case the signal came between creating a temporary
    and the ``try`` that removes it)."""
    for tmp in list(_LIVE):
        with contextlib.suppress(OSError):
            _remove(tmp)


def output_error(err: OSError, path: str | os.PathLike[str]) -> OutputError | None:
    """``err`` as an :class:`OutputError` naming ``path`` when it is an operating-system
    refusal to write there (:data:`WRITE_ERRNOS`); None for anything else (a bug)."""
    if err.errno not in WRITE_ERRNOS:
        return None
    reason = err.strerror or str(err)
    if err.errno == errno.EFBIG:
        reason += " (the file-size limit, ulimit -f, or the file system's)"
    return OutputError(f"cannot write: {reason}", path)


def check_target(path: str, protect: tuple[str | os.PathLike | None, ...] = ()) -> str:
    """The folder to write ``path`` in, after refusing targets that must not be replaced: a
    folder or a path through a file (:class:`OutputError`), a protected input or a missing
    folder (:class:`UsageError`)."""
    target = os.path.realpath(path)
    if os.path.isdir(target):
        raise OutputError("is a folder; give a file name for the output", path)
    exists = os.path.exists(target)
    for other in protect:
        if other is None or not exists or not os.path.exists(other):
            continue
        if os.path.isdir(other):
            root = os.path.realpath(other).rstrip(os.sep) + os.sep
            if target.startswith(root):
                raise UsageError(f"output would overwrite a file inside the input folder "
                                 f"{os.fspath(other)} (every file there may be an input); "
                                 f"write it elsewhere", path)
        elif os.path.samefile(other, target):
            raise UsageError("output would overwrite an input file", path)
    folder = os.path.dirname(os.path.abspath(path)) or "."
    if not os.path.isdir(folder):
        if os.path.exists(folder) or any(os.path.isfile(p) for p in _parents(folder)):
            raise OutputError(f"cannot write: {folder!r} is not a folder", path)
        raise UsageError(f"output folder {folder!r} does not exist", path)
    return folder


def _parents(folder: str) -> Iterator[str]:
    while True:
        yield folder
        parent = os.path.dirname(folder)
        if parent == folder:
            return
        folder = parent


def _current_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "wb",
                 protect: tuple[str | os.PathLike, ...] = ()) -> Iterator[IO]:
    """Open a temporary file in the target's folder; on success rename it over ``path``.

    On any exception the temporary file is removed and ``path`` is left untouched, so a
    failed write never leaves a half-written output. ``protect`` lists inputs that must never
    be overwritten: files, and folders (no file inside one is replaced); a ``UsageError`` is
    raised before anything is written. An operating-system refusal to write (see
    :func:`output_error`) is an :class:`OutputError` naming ``path``.
    """
    path = os.fspath(path)
    folder = check_target(path, tuple(protect))
    _sweep_once(folder)
    tmp = _temporary_name(path)
    _LIVE.add(tmp)
    try:
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0),
                         0o666)
        except BaseException:
            _LIVE.discard(tmp)
            raise
        try:
            with os.fdopen(fd, mode) as handle:
                yield handle
                handle.flush()
                os.fsync(handle.fileno())
            _deliver_pending_signals()
            os.replace(tmp, path)
            _LIVE.discard(tmp)
        except BaseException:
            _remove(tmp)
            raise
    except OSError as err:
        wrapped = output_error(err, path)
        if wrapped is None:
            raise
        raise wrapped from None


def _deliver_pending_signals() -> None:
    """Run the Python handlers of signals that arrived during the last system calls (the
    write and ``fsync`` of a large file take most of a conversion's final second) *before*
    the rename: CPython runs handlers only at certain points of Python code, such as entering
    a Python function (this one), and none lies between ``fsync`` and ``os.replace``. A
    SIGINT/SIGTERM/SIGHUP received while the file was written then aborts the write, and the
    output is left as it was, instead of being renamed into place just before the
    interruption is reported."""


@contextlib.contextmanager
def temporary_folder(path: str | os.PathLike,
                     protect: tuple[str | os.PathLike, ...] = ()) -> Iterator[str]:
    """A temporary folder beside ``path``, named and cleaned up like :func:`atomic_write`'s
    files, for writers that need file names (move the finished file over ``path`` with
    ``os.replace`` inside the block); removed with everything in it on leaving."""
    path = os.fspath(path)
    folder = check_target(path, tuple(protect))
    _sweep_once(folder)
    tmp = _temporary_name(path)
    _LIVE.add(tmp)
    try:
        try:
            os.mkdir(tmp, 0o700)
        except BaseException:
            _LIVE.discard(tmp)
            raise
        try:
            yield tmp
        finally:
            _remove(tmp)
    except OSError as err:
        wrapped = output_error(err, path)
        if wrapped is None:
            raise
        raise wrapped from None


def file_mode() -> int:
    """The permission bits a plain ``open()`` would give a new file (for files made in a
    :func:`temporary_folder` and renamed over the target)."""
    return 0o666 & ~_current_umask()
