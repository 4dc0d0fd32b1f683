"""Atomic file output: write to a temporary file beside the target, then rename.

Temporary files (and folders) are named ``.<target name>.gsverse-tmp-<host>-<pid>-<random>``:
hidden, never ending in an output suffix (so that no glob, ``--skip-existing`` or folder scan
takes one for an output), and naming the machine and process that owns them. A process
removes its own temporaries when it fails or is interrupted (the command-line tools turn
SIGTERM and SIGHUP into the same unwinding as Ctrl-C), wherever the interruption lands: as
a temporary comes into being, while it is written, during the rename (which is then undone:
an interrupted write leaves the output as it was) and while it is removed
(:func:`interruptions_deferred`). A process killed outright (SIGKILL, power loss) leaves its
temporary behind, and the next write into that folder on the same machine removes it once
its process is gone and it is older than :data:`STALE_AFTER_S`.

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
import signal
import socket
import threading
import time
from typing import IO, Any, Callable, Iterator, TypeVar

from .errors import OutputError, UsageError

__all__ = ["atomic_write", "temporary_folder", "check_target", "file_mode", "is_temporary",
           "sweep_stale", "discard_temporaries", "interruptions_deferred",
           "interruptions_immediate", "stop_signals_end_native_calls",
           "set_stop_signals_end_native_calls", "outputs_written",
           "output_error", "make_folder",
           "TEMP_MARK", "STALE_AFTER_S"]

T = TypeVar("T")

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
#: Outputs this process has put in place (see :func:`outputs_written`).
_WRITTEN: list[str] = []
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


def _remove_temporaries(folder: str | os.PathLike[str],
                        pick: Callable[[os.DirEntry[str], int], bool]) -> list[str]:
    """Remove the temporaries in ``folder`` of this machine for which ``pick(entry, pid)``
    holds (``pid``: the process that made it); returns their paths."""
    removed: list[str] = []
    host = _host()
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        m = _NAME.match(entry.name)
        if m is None or m["host"] != host:
            continue
        try:
            if not pick(entry, int(m["pid"])):
                continue
            if entry.is_dir(follow_symlinks=False):
                shutil.rmtree(entry.path)
            else:
                os.unlink(entry.path)
        except OSError:
            continue
        removed.append(entry.path)
    return removed


def sweep_stale(folder: str | os.PathLike[str], *, min_age: float = STALE_AFTER_S) -> list[str]:
    """Remove the temporaries in ``folder`` left by dead processes of this machine (their
    process id no longer exists) that have not changed for ``min_age`` seconds; returns their
    paths. Anything else (other names, other machines' or live processes' temporaries) stays."""
    now = time.time()
    return _remove_temporaries(folder, lambda entry, pid: not _alive(pid) and now - entry.stat(
        follow_symlinks=False).st_mtime >= min_age)


def sweep_dead(folder: str | os.PathLike[str], pid: int) -> list[str]:
    """Remove the temporaries in ``folder`` of process ``pid`` of this machine, known dead
    (a batch's worker killed while writing): whatever their age; returns their paths."""
    if _alive(pid):
        return []
    return _remove_temporaries(folder, lambda entry, owner: owner == pid)


def _sweep_once(folder: str) -> None:
    key = os.path.realpath(folder)
    if key not in _SWEPT:
        _SWEPT.add(key)
        sweep_stale(folder)


def _remove(tmp: str) -> None:
    """Remove the temporary ``tmp`` (gone already: nothing to do); an interruption received
    meanwhile is raised once it is gone."""
    with interruptions_deferred():
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


def _not_a_folder(path: str) -> str | None:
    """Why ``path`` cannot be a folder: a file, a broken symbolic link or a symbolic link
    loop (None when it is a folder or does not exist)."""
    if os.path.isdir(path):
        return None
    if os.path.islink(path):
        try:
            os.stat(path)
        except OSError as err:
            if err.errno == errno.ELOOP:
                return "is a symbolic link loop"
            return f"is a broken symbolic link (to {os.readlink(path)!r})"
    if os.path.lexists(path):
        return "is a file, not a folder"
    return None


def make_folder(path: str | os.PathLike[str]) -> None:
    """Make the output folder ``path`` and its parents; :class:`OutputError` naming the part
    of ``path`` that cannot be a folder, with the true cause (a file, a broken symbolic link,
    a symbolic link loop), or the operating system's refusal."""
    spath = os.fspath(path)
    clean = os.path.normpath(spath)
    for part in reversed(list(_parents(clean))):
        cause = _not_a_folder(part)
        if cause is not None:
            raise OutputError(f"cannot make the output folder: {cause}", part)
    try:
        os.makedirs(clean, exist_ok=True)
    except OSError as err:
        raise OutputError(f"cannot make the output folder: {err.strerror or err}",
                          spath) from None


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

    ``mode`` is ``"wb"`` or ``"w"`` (text). On any exception the temporary file is removed and
    ``path`` is left untouched, so a failed write never leaves a half-written output; an
    interruption (Ctrl-C, or SIGTERM/SIGHUP under the command-line tools) received at any
    point before the output is in place is such an exception (see :func:`_commit`).
    ``protect`` lists inputs that must never be overwritten: files, and folders (no file
    inside one is replaced); a ``UsageError`` is raised before anything is written. An
    operating-system refusal to write (see :func:`output_error`) is an :class:`OutputError`
    naming ``path``.
    """
    if "w" not in mode:
        raise ValueError(f"atomic_write writes new files: mode 'w' or 'wb', not {mode!r}")
    path = os.fspath(path)
    folder = check_target(path, tuple(protect))
    _sweep_once(folder)
    tmp = _temporary_name(path)
    # open() makes the file and its file object in one call: no interruption can come between
    # the two and leave the descriptor without an owner ("x": never an existing file).
    with _output_errors(path), _owned(tmp, lambda: open(tmp, mode.replace("w", "x"))) as handle:
        with handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        _commit(tmp, path)


@contextlib.contextmanager
def temporary_folder(path: str | os.PathLike,
                     protect: tuple[str | os.PathLike, ...] = (), *,
                     result: str | None = None) -> Iterator[str]:
    """A temporary folder beside ``path``, named and cleaned up like :func:`atomic_write`'s
    files, for writers that need file names; removed with everything in it on leaving.

    With ``result`` (a file name in the folder), the file the block leaves there becomes
    ``path`` when the block completes, exactly as :func:`atomic_write` commits its file
    (interruptions and refusals included). Without it the block moves its file into place
    itself."""
    path = os.fspath(path)
    folder = check_target(path, tuple(protect))
    _sweep_once(folder)
    tmp = _temporary_name(path)
    with _output_errors(path), _owned(tmp, lambda: os.mkdir(tmp, 0o700)):
        yield tmp
        if result is not None:
            _commit(os.path.join(tmp, result), path)


@contextlib.contextmanager
def _output_errors(path: str) -> Iterator[None]:
    """Operating-system refusals to write (:func:`output_error`) raised inside, as
    :class:`OutputError` naming ``path``; any other ``OSError`` is a bug and passes as is."""
    try:
        yield
    except OSError as err:
        wrapped = output_error(err, path)
        if wrapped is None:
            raise
        raise wrapped from None


@contextlib.contextmanager
def _owned(tmp: str, create: Callable[[], T]) -> Iterator[T]:
    """``create()`` the temporary ``tmp`` (a file or a folder; yields what ``create`` returns)
    and remove it on leaving, however the block ends; a rename inside the block (the commit)
    leaves nothing to remove.

    It is registered for :func:`discard_temporaries` before it exists. A ``create`` that
    fails with an ``OSError`` made nothing (an existing name is refused), so nothing is
    removed; any other exception out of it is an interruption raised just as the temporary
    came into being, which therefore is removed."""
    _LIVE.add(tmp)
    try:
        made = create()
    except OSError:
        _LIVE.discard(tmp)
        raise
    except BaseException:
        _remove(tmp)
        raise
    try:
        yield made
    finally:
        _remove(tmp)


def _commit(tmp: str, path: str) -> None:
    """Rename the finished temporary file ``tmp`` over ``path``: the one point at which an
    output appears or changes (:func:`atomic_write`, :func:`temporary_folder`).

    An interruption received before the rename aborts it: the Python handlers of signals
    that arrived during the last system calls run first (CPython runs them only at certain
    points of Python code, such as entering a Python function, and none lies between
    ``fsync`` and the rename). One received *during* the rename is raised just after it,
    when ``path`` already holds the new file; the rename is then undone (the previous file,
    kept as a hard link for that moment, is put back, or the new one removed), so that an
    exception out of here always means that ``path`` is as it was. (Only where the file
    system refuses hard links can a replaced file not be put back.) A completed rename is
    recorded in :func:`outputs_written`."""
    backup = _temporary_name(path)
    _LIVE.add(backup)
    try:
        previous = _keep(path, backup)
        try:
            _deliver_pending_signals()
            os.replace(tmp, path)
        except BaseException:
            if not os.path.lexists(tmp):  # renamed: the exception came just after the rename
                _undo(path, backup, previous)
            raise
        _WRITTEN.append(path)
    finally:
        _remove(backup)


def outputs_written() -> list[str]:
    """The outputs this process has put in place so far, in order (for a message after an
    interruption: one that arrives after an output's rename finds it written)."""
    return list(_WRITTEN)


#: What :func:`_keep` found at the target: nothing, a file linked to the backup name, or a
#: file that could not be linked.
_NOTHING, _KEPT, _NOT_KEPT = "nothing", "kept", "not kept"


def _keep(path: str, backup: str) -> str:
    """Link the file at ``path`` (if any) to the name ``backup``, so that a rename over it
    can be undone."""
    try:
        os.link(path, backup, follow_symlinks=False)
    except FileNotFoundError:
        return _NOTHING if not os.path.lexists(path) else _NOT_KEPT
    except (OSError, NotImplementedError):  # no hard links on this file system
        return _NOT_KEPT
    return _KEPT


def _undo(path: str, backup: str, previous: str) -> None:
    """Put ``path`` back as it was before the rename of :func:`_commit`."""
    with interruptions_deferred(), contextlib.suppress(OSError):
        if previous == _KEPT:
            os.replace(backup, path)
        elif previous == _NOTHING:
            os.unlink(path)


def _deliver_pending_signals() -> None:
    """Run the Python handlers of signals received so far (calling a Python function is one
    of the points where CPython runs them)."""


#: The signals that interrupt a run (the command-line tools give SIGTERM and SIGHUP the
#: handling of Ctrl-C's SIGINT).
_STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP")
                      if hasattr(signal, name))


@contextlib.contextmanager
def interruptions_deferred() -> Iterator[None]:
    """While inside, SIGINT, SIGTERM and SIGHUP are only noted; on leaving, the handlers of
    those received run (the interruption they raise comes out of the ``with``), so that work
    inside (cleaning up, starting a child process and keeping its id) is never left half
    done. Applies to signals with Python handlers, in the main thread, the only place
    Python runs them (elsewhere, and for signals ignored or left to the system, nothing
    changes)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []

    def note(signum: int, frame: object) -> None:
        received.append(signum)

    saved: list[tuple[int, Any]] = []
    try:
        for signum in _STOP_SIGNALS:
            handler = signal.getsignal(signum)
            if callable(handler):
                saved.append((signum, handler))
                signal.signal(signum, note)
        yield
    finally:
        _restore_handlers(saved)
        for signum in dict.fromkeys(received):  # an interruption wins over any other error
            signal.raise_signal(signum)


#: Whether :func:`interruptions_immediate` may end the process (set by the command-line
#: tools' boundary and in batch workers, :func:`stop_signals_end_native_calls`): in a
#: library caller's process, an interactive session above all, a stop signal must never end
#: the interpreter.
_END_PROCESS: list[bool] = [False]


def set_stop_signals_end_native_calls(enabled: bool) -> bool:
    """Whether :func:`interruptions_immediate` ends the process on a stop signal from now on
    (a batch worker sets it for its life); returns the previous setting."""
    previous = _END_PROCESS[0]
    _END_PROCESS[0] = bool(enabled)
    return previous


@contextlib.contextmanager
def stop_signals_end_native_calls() -> Iterator[None]:
    """While inside, :func:`interruptions_immediate` ends the process on a stop signal (a
    command-line tool's run: a process of this package's own)."""
    previous = set_stop_signals_end_native_calls(True)
    try:
        yield
    finally:
        set_stop_signals_end_native_calls(previous)


@contextlib.contextmanager
def interruptions_immediate() -> Iterator[None]:
    """While inside, SIGINT, SIGTERM and SIGHUP end the process at once, by the system's
    default action, instead of running their Python handlers. For three kinds of call:
    native calls that hold the interpreter for long (manifold3d, pymeshlab's filters,
    screened Poisson), during which no Python handler can run, so that a stop signal or a
    time limit (``timeout``) still ends the command within a second; compiled numba code
    and numba's import, which call back into Python, where an exception raised by a handler
    crashes the process or becomes a ``SystemError`` or ``ImportError``; and library code that
    catches ``BaseException`` (trimesh's readers), which would swallow the interruption. The process then exits as killed by the signal (a shell
    reports 128 + its number, as the command-line tools' own handling does). Nothing is
    half-written: outputs appear only by renaming a finished temporary, and a temporary left
    by a process so ended is removed by the next write into its folder
    (:func:`sweep_stale`). Signals received before the block have their handlers run first;
    those received on leaving are handled by the handlers put back. Main thread only, and
    only signals with Python handlers; the others (ignored, default) are left as they are.
    Without POSIX signal masks (Windows) nothing changes.

    Only in the package's own processes (:func:`stop_signals_end_native_calls`); in a library
    caller's process the block defers the signals instead (:func:`interruptions_deferred`:
    the ``KeyboardInterrupt`` of Ctrl-C comes out of the ``with`` once the call returns)."""
    if not _END_PROCESS[0]:
        with interruptions_deferred():
            yield
        return
    if (threading.current_thread() is not threading.main_thread()
            or not hasattr(signal, "pthread_sigmask")):
        yield
        return
    saved: list[tuple[int, Any]] = []
    blocked = set(_STOP_SIGNALS)
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, blocked)
    try:
        _deliver_pending_signals()   # a handler raising here leaves with the mask restored
        for signum in _STOP_SIGNALS:
            handler = signal.getsignal(signum)
            if callable(handler):
                saved.append((signum, handler))
                signal.signal(signum, signal.SIG_DFL)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
    try:
        yield
    finally:
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, blocked)
        try:
            _restore_handlers(saved)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)


def _restore_handlers(saved: list[tuple[int, Any]]) -> None:
    """Put back every handler of ``saved``, even when the first ones put back raise at once
    (a signal that came as its handler returned)."""
    if not saved:
        return
    try:
        signal.signal(*saved[0])
    finally:
        _restore_handlers(saved[1:])


def file_mode() -> int:
    """The permission bits a plain ``open()`` would give a new file (for files made in a
    :func:`temporary_folder` and renamed over the target)."""
    return 0o666 & ~_current_umask()
