"""The process boundary shared by the command-line tools: one place that turns what a command
raises into its one-line message and exit status.

Exit statuses: 0 success, 1 bad input or an output the system refuses to write
(``GsverseError``; an ``OSError`` naming a file: permissions, a full disk, a file-size limit;
out of memory), 2 bad usage (``UsageError``), 70 an internal error (a bug: one line with the
exception's type; ``GSVERSE_DEBUG=1`` re-raises it for the traceback), 128 + the signal's
number when interrupted: 130 Ctrl-C (SIGINT), 143 SIGTERM, 129 SIGHUP — the three unwind alike,
removing the temporary file of a write in progress, so no output is left half-written; 141
when standard output is a pipe closed by its reader (``| head``), as if killed by SIGPIPE,
without a message. A closed standard output (``>&-``) discards the summary; a command whose
product goes there (``-`` as OUT) refuses it as bad usage.

With ``--json`` (``json_errors``) an error is also printed on standard output, as
``{"error": {"kind", "message", "path", "cause"}, "input": ..., "exit": N}``, so that a caller
parsing standard output always gets one JSON document. Warnings of the conversion that the
user should act on (:class:`gsverse_format.fit.MeshFitWarning`) are one
``<prog>: warning: <message>`` line on standard error (none under ``-q``).
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import signal
import sys
import threading
import warnings
from typing import Any, Callable, Iterator

from ..atomic import (WRITE_ERRNOS, discard_temporaries, outputs_written,
                      stop_signals_end_native_calls)
from ..errors import GsverseError, UsageError
from ..progress import Progress, silenced_warnings
from ..textsafe import escape

__all__ = ["Interrupted", "run_command", "json_error", "parse_args", "warning_lines", "interrupting_signals", "quiet_broken_stdout",
           "closed_stdout_error", "EXIT_SIGPIPE", "STOP_SIGNALS"]

#: The signals that stop a command the way Ctrl-C does (SIGINT already raises
#: ``KeyboardInterrupt``): job schedulers, containers and CI send SIGTERM, a closed terminal
#: SIGHUP.
STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP")
                     if hasattr(signal, name))
#: The exit status of a command whose standard output was closed by the pipe's reader.
EXIT_SIGPIPE = 128 + getattr(signal, "SIGPIPE", 13)


class Interrupted(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised in the main thread like Ctrl-C's ``KeyboardInterrupt``, so that
    everything unwinds the same way (temporary files removed, worker processes stopped)."""

    def __init__(self, signum: int) -> None:
        self.signum = signum
        super().__init__(signal.Signals(signum).name)


def _raise_interrupted(signum: int, frame: object) -> None:
    raise Interrupted(signum)


@contextlib.contextmanager
def interrupting_signals() -> Iterator[None]:
    """While inside: SIGTERM and SIGHUP raise :class:`Interrupted` (only in the main thread,
    where Python runs signal handlers; a no-op elsewhere). Signals the caller set to be
    ignored (``nohup``) stay ignored. Inside long native calls the stop signals end the
    process at once (:func:`gsverse_format.atomic.interruptions_immediate`)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    saved = {}
    for signum in STOP_SIGNALS:
        previous = signal.getsignal(signum)
        if previous == signal.SIG_IGN:
            continue
        saved[signum] = previous
        signal.signal(signum, _raise_interrupted)
    try:
        with stop_signals_end_native_calls():
            yield
    finally:
        for signum, previous in saved.items():
            signal.signal(signum, previous)


def quiet_broken_stdout() -> None:
    """After standard output's reader went away: point file descriptor 1 at the null device,
    so that the interpreter's final flush does not print a second error."""
    with contextlib.suppress(OSError, ValueError, AttributeError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)


def _os_message(exc: OSError) -> str | None:
    """One line for an ``OSError`` that is the environment's doing (it names a file, or it is
    a refusal to write), or None for one that can only be a bug."""
    reason = exc.strerror or str(exc)
    if exc.filename is not None and exc.errno is not None:
        return f"{os.fsdecode(exc.filename)}: {reason}"
    if exc.errno in WRITE_ERRNOS:
        return f"cannot write: {reason}"
    return None


@contextlib.contextmanager
def warning_lines(prog: str, progress: Progress, quiet: bool = False) -> Iterator[None]:
    """While inside: every :class:`~gsverse_format.fit.MeshFitWarning` (each one, not only
    the first of its kind) is shown as one ``<prog>: warning: <message>`` line on standard
    error, after finishing the progress line; under ``quiet`` none is; other warnings are
    shown as Python shows them."""
    from ..fit import MeshFitWarning

    with warnings.catch_warnings():   # restores the filters and showwarning on the way out
        shown = warnings.showwarning
        warnings.simplefilter("ignore" if quiet else "always", MeshFitWarning)

        def show(message: Any, category: type[Warning], filename: str, lineno: int,
                 file: Any = None, line: str | None = None) -> None:
            if issubclass(category, MeshFitWarning):
                progress.close()
                if sys.stderr is not None:
                    print(f"{prog}: warning: {escape(str(message))}", file=sys.stderr)
                return
            shown(message, category, filename, lineno, file, line)

        warnings.showwarning = show
        yield


def run_command(prog: str, label: str, progress: Progress, work: Callable[[], int], *,
                quiet: bool = False, interrupted: str = "interrupted",
                json_errors: bool = False) -> int:
    """Run ``work`` (which prints its own results and returns the exit status) with every
    warning silenced under ``quiet`` and SIGTERM/SIGHUP handled like Ctrl-C; an exception
    becomes one line on stderr prefixed by ``prog`` (``label`` names the input when memory
    runs out) and its exit status; with ``json_errors`` also a JSON object on stdout
    (:func:`json_error`)."""
    error: BaseException | None = None
    try:
        with interrupting_signals(), silenced_warnings(quiet), \
                warning_lines(prog, progress, quiet):
            status = work()
            if sys.stdout is not None:
                sys.stdout.flush()  # a closed pipe is found here, not at the interpreter's exit
            return status
    except BrokenPipeError:
        progress.close()
        quiet_broken_stdout()
        return EXIT_SIGPIPE
    except UsageError as exc:
        message, status, kind, error = f"error: {exc}", 2, "usage", exc
    except GsverseError as exc:
        message, status, kind, error = f"error: {exc}", 1, "input", exc
    except MemoryError:
        message, status, kind = f"error: {label}: out of memory", 1, "memory"
    except KeyboardInterrupt as exc:
        discard_temporaries()
        signum = exc.signum if isinstance(exc, Interrupted) else signal.SIGINT
        written = outputs_written()
        if written:   # the interruption came after an output was complete: say so, not "none"
            message = f"interrupted; {escape(written[-1])} was written" + (
                f" (and {len(written) - 1} more)" if len(written) > 1 else "")
        else:
            message = interrupted
        status, kind = 128 + signum, "interrupted"
    except OSError as exc:
        text = _os_message(exc)
        if text is None:
            return _internal(prog, label, progress, exc, json_errors)
        message, status, kind = f"error: {text}", 1, "system"
    except Exception as exc:  # a bug, not bad input: still one line; GSVERSE_DEBUG=1 shows it all
        return _internal(prog, label, progress, exc, json_errors)
    progress.close()
    print(f"{prog}: {escape(message)}", file=sys.stderr)
    if json_errors:
        _print_json_error(kind, message.removeprefix("error: "), label, status, error)
    return status


def parse_args(parser: argparse.ArgumentParser, argv: list[str] | None,
               check: Callable[[argparse.Namespace], None] | None = None) -> argparse.Namespace:
    """``parser.parse_args(argv)``, then ``check(args)`` (which may call ``parser.error``);
    with ``--json`` among the arguments, a usage error of the parser (exit status 2, usage and
    message on standard error as usual) is also the ``--json`` error object on standard
    output."""
    args = sys.argv[1:] if argv is None else argv

    def parse() -> argparse.Namespace:
        namespace = parser.parse_args(args)
        if check is not None:
            check(namespace)
        return namespace

    if "--json" not in args:
        return parse()
    caught = io.StringIO()
    try:
        with contextlib.redirect_stderr(caught):
            return parse()
    except SystemExit as exc:
        text = caught.getvalue()
        if sys.stderr is not None:
            sys.stderr.write(text)
        if exc.code not in (0, None):
            last = text.strip().splitlines()[-1] if text.strip() else "bad usage"
            message = last.split(": error: ", 1)[-1]
            status = exc.code if isinstance(exc.code, int) else 2
            _print_json_error("usage", message, None, status, None)
        raise


def json_error(kind: str, message: str, label: str | None, status: int,
               exc: BaseException | None = None) -> dict[str, Any]:
    """The ``--json`` form of an error: ``{"error": {"kind", "message", "path", "cause"},
    "input", "exit"}``; ``kind`` is usage, input, memory, interrupted, system or internal;
    ``path`` and ``cause`` are the file and the cause of a :class:`GsverseError` (else
    ``None`` and the message)."""
    path = getattr(exc, "path", None) if isinstance(exc, GsverseError) else None
    cause = exc.cause if isinstance(exc, GsverseError) else message
    return {"error": {"kind": kind, "message": message, "path": path, "cause": cause},
            "input": label, "exit": status}


def _print_json_error(kind: str, message: str, label: str | None, status: int,
                      exc: BaseException | None) -> None:
    if sys.stdout is None:
        return
    with contextlib.suppress(OSError, ValueError):
        print(json.dumps(json_error(kind, message, label, status, exc), indent=2))
        sys.stdout.flush()


def _internal(prog: str, label: str, progress: Progress, exc: BaseException,
              json_errors: bool = False) -> int:
    if os.environ.get("GSVERSE_DEBUG"):
        progress.close()
        raise exc
    progress.close()
    message = (f"internal error: {type(exc).__name__}: {exc} "
               f"(set GSVERSE_DEBUG=1 for a traceback, and please report it)").replace("\n", " ")
    print(f"{prog}: {escape(message)}", file=sys.stderr)
    if json_errors:
        _print_json_error("internal", message, label, 70, exc)
    return 70


def closed_stdout_error() -> UsageError | None:
    """A :class:`UsageError` when standard output is closed (``>&-``: Python then has no
    ``sys.stdout``), else None."""
    return UsageError("standard output is closed", "-") if sys.stdout is None else None

