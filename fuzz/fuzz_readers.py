"""Fuzz every reader of the toolkit, and the validator, with mutated valid files.

Seeds are small valid files built from the data model: 3DGS splat PLY (binary little and big
endian, ASCII), a PLY triangle mesh, GLB / glTF assets (``local`` and ``games`` anchors,
quantized anchors, plain splats) and USD assets (``.usda`` text and ``.usdc`` crate). Each
input is one seed with one to three mutations:

* generic: bit flips, interesting bytes, interesting 32- and 64-bit integers, truncation,
  insertion, deletion, duplication of a range, splicing with another seed;
* glTF (structure-aware, the GLB container rebuilt so that the edit reaches the JSON checks):
  values of another JSON type, accessor counts, references (accessor, buffer view, buffer,
  mesh, node, child, scene indices) out of range or pointing elsewhere, byte offsets, lengths
  and strides, enumerations (componentType, type, mode), extension objects (members removed,
  retyped, unknown, moved to another primitive or out of ``KHR_gaussian_splatting``), keys
  deleted or written twice, array elements deleted or duplicated; and GLB header edits;
* PLY: header edits (element counts such as 0, −1 or 10¹², property types, format line,
  missing ``end_header``);
* USD text: numbers, type names and tokens replaced, lines deleted or duplicated, array
  elements dropped, composition arcs and value clips (to the file itself, to missing files,
  outside the folder) inserted.

Every input is written to a file and passed to each target that accepts its kind:
``read_splat_ply``, ``read_ply_elements``, ``read_ply_mesh`` and ``read_mesh`` for PLY;
``read_gltf``, ``read_mesh`` and ``validate`` for GLB/glTF; ``read_usd`` and
``validate_usd`` for USD, run in a long-lived child process (:mod:`fuzz.usd_worker`: the
USD library may crash the process reading a corrupt file, which is a refusal, as in
:mod:`gsverse_format.io.usd.isolation`). Each run of a target has one outcome:

* ``ok``: a normal return (for the validator: a report without errors);
* ``refused``: a clean refusal, the toolkit's own
  :class:`~gsverse_format.errors.GsverseError` (or, for the validator, a report with error
  findings; for USD, the USD library crashing the child);
* ``internal``: an internal error, any other exception (``MemoryError`` included: sizes must be
  checked before allocating) or a validator ``INTERNAL_ERROR`` finding; a failure;
* ``hang``: the target took longer than ``--timeout`` seconds; a failure.

A numpy ``RuntimeWarning`` (overflow, invalid value) raised while a target runs is counted per
target and listed: the command-line tools would print it. Inputs that reach a new outcome
join the corpus (a crude feedback loop).

The web splat formats (``.spz``, ``.sog``, ``.ksplat``, compressed PLY) and the web plugin's JS
reader have structure-aware targets of their own (:mod:`fuzz.webformats`, :mod:`fuzz.js_worker`:
the JS reader in one long-lived Node process, an exception other than its ``AnchorError`` an
internal error).

``python -m fuzz --runs 100000`` (or ``python -m fuzz.fuzz_readers``) is the long run (``--kinds`` restricts it to some
kinds of file); the test suite runs a few thousand inputs. ``--engine atheris`` uses
coverage-guided libFuzzer mutation instead, when the ``atheris`` package is installed. Exit
status 1 when any input failed; failing inputs are kept in ``--crash-dir``.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import pathlib
import random
import re
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import traceback
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable

from fuzz.mutations import mutate
from fuzz.seeds import seeds
from fuzz.webformats import JS_KIND, WEB_KINDS, mutate_any, web_seeds, web_targets

__all__ = ["seeds", "mutate", "Fuzzer", "UsdWorker", "USD_WORKER_CODE", "OUTCOMES", "main"]

#: The outcomes of running one target on one input; the last two are failures.
OUTCOMES = ("ok", "refused", "internal", "hang")
#: Kinds of input, by file name suffix.
KINDS = (".glb", ".gltf", ".ply", ".usda", ".usdc") + tuple(WEB_KINDS)
#: Short names of kinds on the command line.
KIND_NAMES = {"cply": ".compressed.ply", "js": JS_KIND}
#: The program of the USD worker child (``python -c USD_WORKER_CODE``).
USD_WORKER_CODE = "from fuzz.usd_worker import main; main()"
#: Marks the targets run by the USD worker in :func:`make_targets`.
IN_USD_WORKER = None
#: Inputs are cut to this many bytes.
MAX_INPUT = 4 * 2 ** 20
#: Seconds a new USD worker may take to start (imports), on top of the per-target timeout.
STARTUP = 60.0
_ROOT = str(pathlib.Path(__file__).resolve().parents[1])


# ---------------------------------------------------------------------------- targets

class _Hang(Exception):
    pass


def make_targets(usd: str = "worker") -> dict[str, list[tuple[str, Any]]]:
    """Target name and function per kind of input. The USD targets run in the
    :class:`UsdWorker` (``usd="worker"``) or, with ``usd="api"``, through the public API, one
    child process per input (:func:`~gsverse_format.io.usd.read_usd` with ``isolate=True``,
    the validator's own isolation)."""
    from gsverse_format.io.gltf import read_gltf
    from gsverse_format.io.mesh import read_mesh
    from gsverse_format.io.ply import read_ply_elements, read_ply_mesh, read_splat_ply
    from gsverse_format.validators.container import Options
    from gsverse_format.validators.validate import validate_file

    def validate(path: str):
        return validate_file(path, Options(max_bytes=64 * 2 ** 20))

    def read_usd(path: str):
        from gsverse_format.io.usd import read_usd as read

        return read(path, isolate=True)   # the USD library itself may crash: a child process

    gltf = [("read_gltf", read_gltf), ("read_mesh", read_mesh), ("validate", validate)]
    usd_targets = ([("read_usd", IN_USD_WORKER), ("validate_usd", IN_USD_WORKER)]
                   if usd == "worker" else [("read_usd", read_usd), ("validate_usd", validate)])
    return {".glb": gltf, ".gltf": gltf, ".usda": usd_targets, ".usdc": usd_targets,
            ".ply": [("read_splat_ply", read_splat_ply), ("read_ply_elements", read_ply_elements),
                     ("read_ply_mesh", read_ply_mesh), ("read_mesh", read_mesh)],
            **web_targets()}


def classify_report(report: Any) -> tuple[str, str]:
    """(outcome, detail) of a validation report: an ``INTERNAL_ERROR`` finding is an internal
    error, errors a refusal."""
    from gsverse_format.codes import Code

    internal = [f for f in report.findings if f.code == Code.INTERNAL_ERROR]
    if internal:
        return "internal", f"validator INTERNAL_ERROR: {internal[0].message}"
    return ("refused" if report.exit_status else "ok"), ""


class UsdWorker:
    """The parent side of :mod:`fuzz.usd_worker`: one child kept alive across inputs, started
    again when the USD library ends it; ``timeout`` seconds per target."""

    def __init__(self, timeout: float) -> None:
        self.timeout = timeout
        self.proc: subprocess.Popen | None = None
        self.buffer = b""
        self.starts = 0
        self.library_crashes = 0
        self.fresh = False

    def _start(self) -> None:
        from gsverse_format.io.usd.isolation import CHILD_MEMORY_BASE, child_limits

        env = dict(os.environ)
        env["PYTHONPATH"] = _ROOT + (os.pathsep + env["PYTHONPATH"]
                                     if env.get("PYTHONPATH") else "")
        self.proc = subprocess.Popen(
            [sys.executable, "-c", USD_WORKER_CODE, str(self.timeout)], cwd=_ROOT, env=env,
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
            preexec_fn=child_limits(CHILD_MEMORY_BASE + 32 * MAX_INPUT)
            if os.name == "posix" else None)
        self.buffer = b""
        self.starts += 1
        self.fresh = True

    def close(self) -> None:
        if self.proc is not None:
            with contextlib.suppress(OSError):
                self.proc.stdin.close()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
            self.proc = None

    def _line(self, seconds: float) -> bytes | None:
        """The next line from the child; b"" when it ended, None after ``seconds``."""
        assert self.proc is not None and self.proc.stdout is not None
        fd = self.proc.stdout.fileno()
        end = time.monotonic() + seconds
        while b"\n" not in self.buffer:
            left = end - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                return None
            chunk = os.read(fd, 1 << 16)
            if not chunk:
                return b""
            self.buffer += chunk
        line, self.buffer = self.buffer.split(b"\n", 1)
        return line

    def _ended(self) -> tuple[str, str]:
        """Outcome for the target the child was running when it ended."""
        assert self.proc is not None
        code = self.proc.wait()
        self.proc = None
        if code < 0:  # a signal: the USD library crashed on this input (isolation's rule)
            self.library_crashes += 1
            try:
                name = signal.Signals(-code).name
            except ValueError:
                name = f"signal {-code}"
            return "refused", f"corrupt USD file: the USD library crashed reading it ({name})"
        return "internal", f"the USD worker exited with status {code}"

    def run(self, path: str, names: list[str]) -> list[tuple[str, str, str, tuple]]:
        """(target, outcome, detail, codes) for each of ``names`` on ``path`` (after a hang,
        for the targets run so far)."""
        out: list[tuple[str, str, str, tuple]] = []
        todo = list(names)
        while todo:
            if self.proc is None:
                self._start()
            assert self.proc is not None and self.proc.stdin is not None
            try:
                self.proc.stdin.write(json.dumps({"path": path, "targets": todo}).encode()
                                      + b"\n")
                self.proc.stdin.flush()
            except BrokenPipeError:
                self.proc.wait()
                self.proc = None
                continue
            for name in list(todo):
                # the first request of a new child also pays for its imports
                line = self._line(self.timeout + (STARTUP if self.fresh else 0))
                self.fresh = False
                todo.remove(name)
                if line is None:
                    self.proc.kill()
                    self.proc.wait()
                    self.proc = None
                    out.append((name, "hang", f"more than {self.timeout:g} s", ()))
                    return out  # the other targets would hang on the same layer: not run
                if not line:
                    outcome, detail = self._ended()
                    out.append((name, outcome, detail, ()))
                    break
                reply = json.loads(line)
                out.append((name, reply["outcome"], reply["detail"], tuple(reply["codes"])))
        return out


@dataclass
class Failure:
    target: str
    suffix: str
    kind: str
    detail: str
    saved: str | None = None


@dataclass
class Fuzzer:
    """Runs inputs through the targets; keeps statistics and failures (internal errors and
    hangs)."""

    workdir: str
    timeout: float = 10.0
    crash_dir: str | None = None
    targets: dict = field(default_factory=make_targets)
    runs: int = 0
    outcomes: dict[str, dict[str, int]] = field(default_factory=dict)
    failures: list[Failure] = field(default_factory=list)
    slowest: float = 0.0
    signatures: set = field(default_factory=set)
    corpus_size: int = 0
    usd_worker: UsdWorker | None = None
    js_worker: UsdWorker | None = None
    interrupted: bool = False
    warned: dict[str, list] = field(default_factory=dict)

    def run_one(self, suffix: str, data: bytes) -> bool:
        """Run every target of ``suffix`` on ``data``; True when it reached a new outcome."""
        self.runs += 1
        path = os.path.join(self.workdir, "input" + suffix)
        with open(path, "wb") as handle:
            handle.write(data)
        results = []
        if suffix == JS_KIND:  # the JS reader, in its Node process (fuzz.js_worker)
            if self.js_worker is None:
                from fuzz.js_worker import JsWorker

                self.js_worker = JsWorker(self.timeout)
            start = time.perf_counter()
            results += [(n, o, d, (n, o) + c if c else (n, o, _shape(d)),
                         time.perf_counter() - start)
                        for n, o, d, c in self.js_worker.run(path, ["js_reader"])]
        worker = [name for name, fn in self.targets[suffix]
                  if fn is IN_USD_WORKER and suffix != JS_KIND]
        if worker:
            if self.usd_worker is None:
                self.usd_worker = UsdWorker(self.timeout)
            # A new folder per USD input: the USD library caches layers by path.
            folder = os.path.join(self.workdir, f"usd{self.runs}")
            os.makedirs(folder)
            os.replace(path, os.path.join(folder, "input" + suffix))
            path = os.path.join(folder, "input" + suffix)
            start = time.perf_counter()
            results += [(n, o, d, (n, o) + c if c else (n, o, _shape(d)), 0.0)
                        for n, o, d, c in self.usd_worker.run(path, worker)]
            if results:
                elapsed = (time.perf_counter() - start) / len(results)
                results = [r[:4] + (elapsed,) for r in results]
        for name, fn in self.targets[suffix]:
            if fn is not IN_USD_WORKER:
                results.append(self._call(name, fn, path))
        new = False
        for name, outcome, detail, sig, elapsed in results:
            if outcome in ("internal", "hang"):
                self._fail(name, suffix, outcome, detail, data)
            if sig not in self.signatures:
                self.signatures.add(sig)
                new = True
            self.slowest = max(self.slowest, elapsed)
            if elapsed > self.timeout and outcome != "hang":
                self._fail(name, suffix, "hang", f"took {elapsed:.1f} s", data)
            stats = self.outcomes.setdefault(name, {})
            stats[outcome] = stats.get(outcome, 0) + 1
        if worker:
            with contextlib.suppress(OSError):
                os.remove(path)
                os.rmdir(os.path.dirname(path))
        return new

    def _call(self, name: str, fn: Callable[[str], object], path: str):
        from gsverse_format.errors import GsverseError

        start = time.perf_counter()
        outcome, detail, sig = "ok", "", (name, "ok")
        caught: list = []
        try:
            with _deadline(self.timeout), warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                result = fn(path)
            if hasattr(result, "findings"):  # a validation report: its outcome and codes
                outcome, detail = classify_report(result)
                sig = (name, outcome) + tuple(sorted(c.value for c in result.codes()))
        except GsverseError as err:
            outcome, detail = "refused", err.cause
            sig = (name, outcome, _shape(err.cause))
        except _Hang:
            outcome, detail = "hang", f"more than {self.timeout:g} s"
            sig = (name, outcome)
        except BaseException as err:  # noqa: BLE001 - any other exception is the finding
            if isinstance(err, KeyboardInterrupt):
                raise
            tb = traceback.extract_tb(err.__traceback__)
            where = f"{os.path.basename(tb[-1].filename)}:{tb[-1].lineno}" if tb else "?"
            outcome, detail = "internal", f"{type(err).__name__}: {err} at {where}"[:400]
            sig = (name, outcome, type(err).__name__, where)
        numeric = [w for w in caught if issubclass(w.category, RuntimeWarning)]
        if numeric:  # numpy's overflow/invalid warnings would reach the user's terminal
            w = numeric[0]
            self.warned.setdefault(name, [0, f"{w.message} at "
                                   f"{os.path.basename(w.filename)}:{w.lineno}"])[0] += 1
        return name, outcome, detail, sig, time.perf_counter() - start

    def close(self) -> None:
        for worker in (self.usd_worker, self.js_worker):
            if worker is not None:
                worker.close()

    def _fail(self, target: str, suffix: str, kind: str, detail: str, data: bytes) -> None:
        saved = None
        if self.crash_dir:
            os.makedirs(self.crash_dir, exist_ok=True)
            name = f"{kind}-{target}-{len(self.failures):04d}{suffix}"
            saved = os.path.join(self.crash_dir, name)
            with open(saved, "wb") as handle:
                handle.write(data)
        self.failures.append(Failure(target, suffix, kind, detail, saved))


def _shape(cause: str) -> str:
    """A refusal's message without its numbers and quoted names (one corpus signature for
    the same reason with other values)."""
    cause = re.sub(r"'[^']*'|\"[^\"]*\"|\([^)]*\)", "_", cause)
    return re.sub(r"\d+", "#", cause)[:60]


@contextlib.contextmanager
def _deadline(seconds: float):
    """Raise :class:`_Hang` in the main thread after ``seconds`` (POSIX timers)."""
    if not hasattr(signal, "setitimer") or seconds <= 0:
        yield
        return

    def alarm(signum, frame):
        raise _Hang()

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _limit_memory(limit: int | None) -> None:
    if not limit:
        return
    try:
        import resource

        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        if hard == resource.RLIM_INFINITY or limit < hard:
            resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    except (ImportError, ValueError, OSError):
        pass


#: Share of the inputs of each kind when all kinds run.
WEIGHTS = {".glb": 0.3, ".gltf": 0.15, ".ply": 0.3, ".usda": 0.15, ".usdc": 0.1,
           ".spz": 0.15, ".sog": 0.15, ".ksplat": 0.1, ".compressed.ply": 0.1, JS_KIND: 0.2}


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def run_builtin(runs: int, seed: int, timeout: float, crash_dir: str | None,
                progress: bool = False, kinds: tuple[str, ...] = KINDS,
                usd: str = "worker") -> Fuzzer:
    """The seeded mutation fuzzer: ``runs`` inputs of ``kinds`` (the seeds themselves first)."""
    rng = random.Random(seed)
    base = seeds()
    web = web_seeds() if set(kinds) & set(WEB_KINDS) - {JS_KIND} else []
    js = [(JS_KIND, d) for s, d in base if s in (".glb", ".gltf")]
    initial = [(s, d) for s, d in base + web + js if s in kinds]
    corpus: dict[str, list[bytes]] = {}
    for suffix, data in initial:
        corpus.setdefault(suffix, []).append(data)
    present = [k for k in kinds if k in corpus]
    weights = [WEIGHTS[k] for k in present]
    with tempfile.TemporaryDirectory(prefix="gsverse-fuzz-") as work:
        fuzzer = Fuzzer(work, timeout, crash_dir, make_targets(usd))
        try:
            for suffix, data in initial[:runs]:
                fuzzer.run_one(suffix, data)
            start = time.perf_counter()
            while fuzzer.runs < runs and not fuzzer.interrupted:
                suffix = rng.choices(present, weights)[0]
                pool = corpus[suffix]
                # Favour the seeds: most inputs start from a valid file.
                data = rng.choice(pool[:len(pool) if rng.random() < 0.5 else 8])
                flat = [(s, d) for s in present for d in corpus[s][:8]]
                for _ in range(rng.choice((1, 1, 1, 2, 3))):
                    data = mutate_any(rng, suffix, data, flat)
                if len(data) > MAX_INPUT:
                    data = data[:MAX_INPUT]
                try:
                    if fuzzer.run_one(suffix, data) and len(pool) < 1000:
                        pool.append(data)
                except KeyboardInterrupt:  # Ctrl-C, SIGTERM: stop, and report what ran
                    fuzzer.interrupted = True
                if progress and fuzzer.runs % 5000 == 0:
                    rate = fuzzer.runs / max(time.perf_counter() - start, 1e-9)
                    sys.stderr.write(f"  {fuzzer.runs} inputs, {len(fuzzer.failures)} failures, "
                                     f"corpus {sum(map(len, corpus.values()))}, {rate:.0f}/s\n")
        finally:
            fuzzer.close()
        fuzzer.corpus_size = sum(map(len, corpus.values()))
    return fuzzer


def run_atheris(runs: int, timeout: float, crash_dir: str | None) -> int:  # pragma: no cover
    """Coverage-guided run under libFuzzer (needs ``pip install atheris``; glTF and PLY)."""
    import atheris

    with atheris.instrument_imports(include=["gsverse_format"]):
        import gsverse_format.io.gltf  # noqa: F401
        import gsverse_format.io.ply  # noqa: F401
        import gsverse_format.io.mesh  # noqa: F401
        import gsverse_format.validators.validate  # noqa: F401

    work = tempfile.mkdtemp(prefix="gsverse-fuzz-")
    corpus_dir = os.path.join(work, "corpus")
    os.makedirs(corpus_dir)
    for i, (suffix, data) in enumerate(seeds()):
        if suffix in (".glb", ".gltf", ".ply"):
            with open(os.path.join(corpus_dir, f"seed{i}{suffix}"), "wb") as handle:
                handle.write(data)
    fuzzer = Fuzzer(work, timeout, crash_dir)

    def one(data: bytes) -> None:
        suffix = (".glb" if data[:4] == b"glTF" else ".ply" if data[:3] == b"ply"
                  else ".gltf")
        before = len(fuzzer.failures)
        fuzzer.run_one(suffix, data)
        if len(fuzzer.failures) > before:
            failure = fuzzer.failures[-1]
            raise RuntimeError(f"{failure.kind} in {failure.target}: {failure.detail}")

    args = [sys.argv[0], f"-runs={runs}", f"-timeout={int(max(timeout, 1))}",
            "-max_len=65536", corpus_dir]
    if crash_dir:
        os.makedirs(crash_dir, exist_ok=True)
        args.insert(1, f"-artifact_prefix={crash_dir.rstrip('/')}/")
    atheris.Setup(args, one)
    atheris.Fuzz()
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m fuzz",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=100000, help="inputs to run (default 100000)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (builtin engine)")
    parser.add_argument("--kinds", default=",".join(k.lstrip(".") for k in KINDS
                                                    if k != JS_KIND or shutil.which("node")),
                        help="kinds of input, comma-separated (default: all (js where Node runs): "
                             "glb,gltf,ply,usda,usdc,spz,sog,ksplat,cply,js; cply: compressed "
                             "PLY, js: GLB and glTF read by the web plugin in Node)")
    parser.add_argument("--usd", choices=("worker", "api"), default="worker",
                        help="run the USD targets in one long-lived child (default) or through "
                             "the public API, one child process per input (slow)")
    parser.add_argument("--timeout", type=float, default=10.0,
                        help="seconds one target may take on one input (default 10)")
    parser.add_argument("--crash-dir", default=None,
                        help="keep failing inputs here (default: a new temporary folder)")
    parser.add_argument("--engine", choices=("builtin", "atheris"), default="builtin")
    parser.add_argument("--memory-limit", type=int, default=8 * 2 ** 30, metavar="BYTES",
                        help="address-space limit of the run, so that an unchecked huge "
                             "allocation fails instead of exhausting the machine (default 8 GiB;"
                             " 0: none)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")
    args = parser.parse_args(argv)
    kinds = tuple(KIND_NAMES.get(k.strip(), "." + k.strip().lstrip("."))
                  for k in args.kinds.split(",") if k.strip())
    unknown = [k for k in kinds if k not in KINDS]
    if unknown or not kinds:
        parser.error(f"unknown kind(s) {', '.join(unknown) or '(none)'}; use "
                     "glb,gltf,ply,usda,usdc,spz,sog,ksplat,cply,js")
    _limit_memory(args.memory_limit)
    signal.signal(signal.SIGTERM, _interrupt)
    crash_dir = args.crash_dir or tempfile.mkdtemp(prefix="gsverse-fuzz-crashes-")
    if args.engine == "atheris":
        return run_atheris(args.runs, args.timeout, crash_dir)
    start = time.perf_counter()
    fuzzer = run_builtin(args.runs, args.seed, args.timeout, crash_dir, not args.quiet, kinds,
                         args.usd)
    elapsed = time.perf_counter() - start
    internal = sum(1 for f in fuzzer.failures if f.kind == "internal")
    hangs = sum(1 for f in fuzzer.failures if f.kind == "hang")
    print(f"inputs: {fuzzer.runs}  internal errors: {internal}  hangs: {hangs}  "
          f"corpus: {fuzzer.corpus_size}  distinct outcomes: {len(fuzzer.signatures)}  "
          f"slowest: {fuzzer.slowest:.3f} s  time: {elapsed:.1f} s  seed: {args.seed}"
          + ("  (interrupted)" if fuzzer.interrupted else ""))
    for name, stats in sorted(fuzzer.outcomes.items()):
        print(f"  {name:<18} runs {sum(stats.values()):>7}  "
              + "  ".join(f"{k} {stats.get(k, 0)}" for k in OUTCOMES))
    for name, (count, first) in sorted(fuzzer.warned.items()):
        print(f"  {name}: {count} input(s) raised a RuntimeWarning (printed to users), e.g. "
              f"{first}")
    if fuzzer.usd_worker is not None:
        print(f"  USD worker: {fuzzer.usd_worker.starts} start(s), "
              f"{fuzzer.usd_worker.library_crashes} USD library crash(es) counted as refusals")
    for f in fuzzer.failures[:20]:
        print(f"FAIL {f.kind} {f.target} {f.suffix}: {f.detail} -> {f.saved}")
    if not fuzzer.failures:
        with contextlib.suppress(OSError):
            os.rmdir(crash_dir)
    return 1 if fuzzer.failures else 0


if __name__ == "__main__":
    sys.exit(main())
