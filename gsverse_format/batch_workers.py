"""Where a batch's assets are converted: one asset (:func:`convert_one`), local worker
processes (:func:`run_local`) or a Dask cluster (:func:`run_dask`), for
:mod:`gsverse_format.batch`.

Each local worker is a process of its own, fed one asset at a time through a pipe: when one
dies (killed; the kernel's out-of-memory killer sends SIGKILL) only the asset it was converting
fails, and a new worker takes the remaining ones (a ``ProcessPoolExecutor`` would fail every
pending asset with ``BrokenProcessPool``).
"""
from __future__ import annotations

import dataclasses
import os
import signal
import sys
import uuid
import warnings
from dataclasses import dataclass
from typing import Any, Callable

from .atomic import WRITE_ERRNOS, set_stop_signals_end_native_calls, sweep_dead
from .errors import GsverseError, UsageError
from .pipeline import ConvertOptions, convert
from .progress import Progress, silenced_warnings

DASK_RESOURCE = "asset"
#: Seconds to reach a Dask scheduler (TCP connection), and beyond that for its handshake.
DASK_CONNECT_S = 30
DASK_HANDSHAKE_S = 15

@dataclass(frozen=True)
class BatchTask:
    """What a worker gets: one asset, its output path and options (picklable)."""

    index: int
    input: str
    output: str
    options: ConvertOptions
    overwrite: bool = False
    quiet: bool = False


@dataclass
class AssetResult:
    """One asset's outcome: ``status`` is ``ok``, ``failed``, ``skipped`` (its output existed)
    or ``interrupted`` (never converted: the batch was stopped); ``error`` is one line (naming
    the file) unless ok; ``summary`` is the single-file ``--json`` summary when ok (None for
    an output completed just as the batch was interrupted)."""

    input: str
    output: str
    status: str
    error: str | None = None
    summary: dict[str, Any] | None = None

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


# --- one asset ----------------------------------------------------------------------------

def _error_line(exc: BaseException, input_path: str) -> str:
    if isinstance(exc, GsverseError):
        text = str(exc)
    elif isinstance(exc, OSError) and (exc.filename is not None or exc.errno in WRITE_ERRNOS):
        named = f"{os.fsdecode(exc.filename)}: " if exc.filename is not None else ""
        text = f"{named}{exc.strerror or exc}"  # the environment's doing, not a bug
    elif isinstance(exc, MemoryError):
        text = "out of memory"
    else:
        text = (f"internal error: {type(exc).__name__}: {exc} (please report it)"
                .replace("\n", " "))
    return text if input_path in text else f"{input_path}: {text}"


def convert_one(task: BatchTask) -> AssetResult:
    """Convert one asset (in whichever process runs it); never raises for a bad asset."""
    with silenced_warnings(task.quiet):  # also in child processes (the USD reader)
        try:
            if not task.overwrite and os.path.exists(task.output):
                raise UsageError("output exists; use -w/--overwrite to replace it", task.output)
            folder = os.path.dirname(os.path.abspath(task.output))
            os.makedirs(folder, exist_ok=True)
            summary = convert(task.input, task.output, task.options, Progress(enabled=False))
            return AssetResult(task.input, task.output, "ok", summary=summary.as_dict())
        except Exception as exc:  # a failing asset is reported; the batch goes on
            return AssetResult(task.input, task.output, "failed", _error_line(exc, task.input))
        finally:
            if _STOPPING:  # pragma: no cover - a local worker told to stop
                os._exit(143)


# --- local processes ----------------------------------------------------------------------

_STOPPING = False


def _raise_exit(signum: int, frame: Any) -> None:  # pragma: no cover - runs in a worker
    """SIGTERM in a local worker: unwind the conversion (its temporary file is removed), then
    :func:`convert_one` ends the process (the pool would otherwise start the next asset)."""
    global _STOPPING
    _STOPPING = True
    raise SystemExit(128 + signum)


def _init_worker(numba_threads: int, quiet: bool) -> None:  # pragma: no cover - in a worker
    """A local worker: Ctrl-C and SIGHUP (sent to the whole terminal's process group) are the
    parent's to handle, which stops the workers with SIGTERM; SIGTERM unwinds (an atomic write
    in progress removes its temporary file), or inside a long native call ends the worker at
    once (``atomic.interruptions_immediate``); numba threads shared out among the workers."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if hasattr(signal, "SIGHUP"):
        signal.signal(signal.SIGHUP, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _raise_exit)
    set_stop_signals_end_native_calls(True)   # inside long native calls: see atomic
    if "numba" not in sys.modules:
        os.environ.setdefault("NUMBA_NUM_THREADS", str(numba_threads))
    if quiet:
        warnings.simplefilter("ignore")
        os.environ["PYTHONWARNINGS"] = "ignore"


def _worker_main(conn: Any, numba_threads: int, quiet: bool) -> None:  # pragma: no cover
    """A local worker process: convert the tasks the parent sends, one at a time, until it
    sends None (or goes away)."""
    _init_worker(numba_threads, quiet)
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            return
        if task is None:
            return
        conn.send(convert_one(task))


def _death(exitcode: int | None) -> str:
    """Why a worker ended, in words: killed by a signal (SIGKILL is what the kernel's
    out-of-memory killer sends) or exited."""
    if exitcode is not None and exitcode < 0:
        try:
            name = signal.Signals(-exitcode).name
        except ValueError:
            name = f"signal {-exitcode}"
        hint = " (the kernel's out-of-memory killer sends it)" if name == "SIGKILL" else ""
        return f"the worker process was killed by {name}{hint}"
    return f"the worker process exited with status {exitcode}"


class _Worker:
    """One local worker process and the task it is converting (None when idle)."""

    def __init__(self, ctx: Any, threads: int, quiet: bool) -> None:
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=_worker_main, args=(child, threads, quiet),
                                   daemon=True)
        self.process.start()
        child.close()
        self.task: BatchTask | None = None

    def give(self, task: BatchTask) -> None:
        self.task = task
        try:
            self.conn.send(task)
        except (OSError, ValueError):
            pass  # it died: its sentinel says so, and the task is reported failed

    def stop(self, terminate: bool) -> None:
        if terminate and self.process.is_alive():
            try:
                self.process.terminate()  # SIGTERM: unwinds, temporary file removed
            except (OSError, ValueError):
                pass
        elif self.process.is_alive():
            try:
                self.conn.send(None)
            except (OSError, ValueError):
                pass
        self.process.join(timeout=30)
        if self.process.is_alive():  # pragma: no cover - a conversion that ignores SIGTERM
            self.process.kill()
            self.process.join()
        self.conn.close()


def run_local(tasks: list[BatchTask], jobs: int, tick: Callable[[AssetResult], None]) -> None:
    """Convert ``tasks`` in ``jobs`` worker processes, one asset per worker at a time. A
    worker that dies (killed, out of memory) fails only the asset it was converting; a new
    worker takes the remaining ones."""
    if jobs <= 1 or len(tasks) == 1:
        for task in tasks:
            tick(convert_one(task))
        return
    import multiprocessing
    from multiprocessing.connection import wait

    ctx = multiprocessing.get_context("spawn")
    threads = max(1, (os.cpu_count() or 1) // jobs)
    quiet = any(t.quiet for t in tasks)
    pending = list(reversed(tasks))
    workers: list[_Worker] = []
    try:
        workers = [_Worker(ctx, threads, quiet) for _ in range(min(jobs, len(tasks)))]
        for w in workers:
            if pending:
                w.give(pending.pop())
        while any(w.task is not None for w in workers):
            busy = [w for w in workers if w.task is not None]
            ready = wait([w.conn for w in busy] + [w.process.sentinel for w in busy])
            for w in busy:
                if w.conn not in ready and w.process.sentinel not in ready:
                    continue
                current = w.task
                assert current is not None
                result: AssetResult | None = None
                if w.conn.poll():
                    try:
                        result = w.conn.recv()
                    except (EOFError, OSError):
                        result = None
                if result is not None:
                    w.task = None
                    tick(result)
                    if pending:
                        w.give(pending.pop())
                    continue
                w.process.join(timeout=5)
                if w.process.is_alive():  # the pipe is still open: not finished yet
                    continue
                tick(AssetResult(current.input, current.output, "failed",
                                 f"{current.input}: {_death(w.process.exitcode)} while "
                                 f"converting it"))
                w.task = None
                w.stop(terminate=False)
                sweep_dead(os.path.dirname(os.path.abspath(current.output)), w.process.pid)
                workers.remove(w)
                if pending:
                    fresh = _Worker(ctx, threads, quiet)
                    workers.append(fresh)
                    fresh.give(pending.pop())
    except BaseException:
        for w in workers:
            w.stop(terminate=True)
        raise
    for w in workers:
        w.stop(terminate=False)


# --- Dask ---------------------------------------------------------------------------------

def _dask_client(address: str) -> Any:
    try:
        from distributed import Client
    except ImportError:
        raise UsageError("--scheduler needs Dask distributed (pip install dask distributed)") \
            from None
    import threading

    box: dict[str, Any] = {}

    def connect() -> None:
        try:
            box["client"] = Client(address, timeout=f"{DASK_CONNECT_S}s")
        except Exception as exc:  # noqa: BLE001 - a network peer's bytes are input
            # distributed trusts what the server sends: a server that is not Dask makes its
            # handshake fail with AssertionError, MemoryError (an HTTP reply read as a frame
            # length of 3·10¹⁸ bytes) and others; the type is kept in the message.
            box["error"] = exc
        except BaseException as exc:  # pragma: no cover - re-raised below, in this thread
            box["unexpected"] = exc

    # Client's timeout covers the TCP connection only: a server that accepts and never
    # answers (not a Dask scheduler) would hold the handshake forever. The thread is a
    # daemon, so a connection that never ends does not keep the process alive.
    thread = threading.Thread(target=connect, name="dask-connect", daemon=True)
    thread.start()
    thread.join(DASK_CONNECT_S + DASK_HANDSHAKE_S)
    if thread.is_alive():
        raise UsageError(f"no Dask scheduler answered within {DASK_CONNECT_S + DASK_HANDSHAKE_S}"
                         f" s (is it a Dask scheduler's address?)", address)
    if "unexpected" in box:
        raise box["unexpected"]
    if "error" in box:
        exc = box["error"]
        raise UsageError(f"cannot connect to the Dask scheduler: {type(exc).__name__}: {exc}"
                         .replace("\n", " "), address) from None
    return box["client"]


def _dask_resources(client: Any, quiet: bool) -> dict[str, float] | None:
    """``{asset: 1}`` when every worker declares that resource; else None, with a warning
    when a worker would run several assets at once (memory is then not bounded by one)."""
    try:
        info = client.scheduler_info(n_workers=-1)
    except TypeError:  # an older distributed
        info = client.scheduler_info()
    workers = list(info.get("workers", {}).values())
    if workers and all(DASK_RESOURCE in (w.get("resources") or {}) for w in workers):
        return {DASK_RESOURCE: 1}
    busy = [w for w in workers if (w.get("nthreads") or 1) > 1]
    if busy and not quiet:
        warnings.warn(f"{len(busy)} Dask worker(s) have more than one thread and may convert "
                      f"several assets at once; start workers with --nthreads 1 or "
                      f"--resources {DASK_RESOURCE}=1 to convert one asset at a time",
                      RuntimeWarning, stacklevel=2)
    return None


def run_dask(tasks: list[BatchTask], address: str, quiet: bool,
              tick: Callable[[AssetResult], None]) -> None:
    from distributed import as_completed as dask_completed

    client = _dask_client(address)
    try:
        resources = _dask_resources(client, quiet)
        token = uuid.uuid4().hex[:12]
        futures = {}
        for t in tasks:
            fut = client.submit(convert_one, t, key=f"gsverse-convert-{token}-{t.index}",
                                pure=False, retries=0, resources=resources)
            futures[fut.key] = (fut, t)
        try:
            for fut in dask_completed([f for f, _ in futures.values()]):
                task = futures[fut.key][1]
                try:
                    tick(fut.result())
                except Exception as exc:  # KilledWorker (out of memory), lost connection
                    tick(AssetResult(task.input, task.output, "failed",
                                     f"{task.input}: Dask task failed: {type(exc).__name__}: "
                                     f"{exc}".replace("\n", " ")))
        except BaseException:
            client.cancel([f for f, _ in futures.values()])
            raise
    finally:
        client.close()
