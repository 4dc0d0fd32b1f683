"""Batch conversion: many inputs into one output folder, in local processes or on Dask.

``gsverse-convert IN... --output-dir DIR`` (:mod:`gsverse_format.cli.convert`) calls
:func:`plan` and then :func:`run_batch`:

1. :func:`collect` turns the command line's inputs into :class:`AssetSpec` s: files and folders
   as given, glob patterns expanded (``*``, ``?``, ``[...]``, ``**``; sorted), and manifests
   (``.csv`` / ``.json``, :func:`read_manifest`) naming input, output, mesh and options per
   asset. The command line's options are every asset's defaults; a manifest overrides them.
2. :func:`plan` names the outputs: a manifest's ``output`` (relative to ``DIR``), else the
   input's path relative to the inputs' common folder, with the ``--to`` suffix (``a/x.ply``
   and ``b/x.ply`` become ``DIR/a/x.glb`` and ``DIR/b/x.glb``). Two assets with one output,
   an output that exists (without ``overwrite`` or ``skip_existing``), a manifest output outside
   ``DIR`` (absolute, ``..``, or through a symbolic link) and an output that is a file some
   asset of the batch reads are each a :class:`UsageError` naming the row, before anything runs.
3. :func:`run_batch` converts each asset with :func:`convert_one` (the single-file pipeline,
   :func:`gsverse_format.pipeline.convert`, atomic writes included) in ``jobs`` worker
   processes, or, with ``scheduler``, as one task per asset on a Dask distributed cluster
   (:mod:`gsverse_format.batch_workers`). A failing asset is reported in its
   :class:`AssetResult` and the rest still convert, also when a worker process dies.

Memory stays bounded by one asset per process: a local worker converts one asset at a time;
on Dask, an asset is one task, so start workers with ``--nthreads 1`` (a worker converts one
asset at a time), or give each worker a resource ``asset=1``
(``dask worker ADDRESS --resources asset=1``): the tasks then ask for one unit of it.
"""
from __future__ import annotations

import csv
import dataclasses
import glob
import json
import os
import signal
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable

from .atomic import make_folder
from .batch_workers import DASK_RESOURCE, AssetResult, BatchTask, convert_one, run_dask, run_local
from .edit import EDIT_FLAGS
from .errors import UsageError
from .pipeline import ConvertOptions
from .progress import Progress

__all__ = ["AssetSpec", "BatchTask", "AssetResult", "BatchReport", "DASK_RESOURCE",
           "MANIFEST_SUFFIXES", "collect", "read_manifest", "plan", "convert_one", "run_batch"]

#: Inputs with these suffixes are manifests, not splat files.
MANIFEST_SUFFIXES = (".csv", ".json")
#: The Dask worker resource a task asks one unit of, when every worker declares it.

_TRUE = {"1", "true", "yes", "y", "on"}
_FALSE = {"0", "false", "no", "n", "off"}


def _as_bool(value: Any) -> bool:
    if isinstance(value, bool):
        return value
    if isinstance(value, (int, float)) and value in (0, 1):
        return bool(value)
    text = str(value).strip().lower()
    if text in _TRUE:
        return True
    if text in _FALSE:
        return False
    raise ValueError(f"not a boolean: {value!r} (use true/false, yes/no or 1/0)")


def _as_int(value: Any) -> int:
    if isinstance(value, bool) or (isinstance(value, float) and not value.is_integer()):
        raise ValueError(f"not an integer: {value!r}")
    return int(str(value).strip()) if not isinstance(value, (int, float)) else int(value)


def _as_float(value: Any) -> float:
    if isinstance(value, bool):
        raise ValueError(f"not a number: {value!r}")
    return float(value)


def _as_str(value: Any) -> str:
    return str(value).strip()


#: Manifest column / key (dashes or underscores) -> (ConvertOptions field, parser, is a path).
MANIFEST_KEYS: dict[str, tuple[str, Callable[[Any], Any], bool]] = {
    "mesh": ("mesh", _as_str, True),
    "from": ("source", _as_str, False),
    "source": ("source", _as_str, False),
    "pt": ("pt_path", _as_str, True),
    "pt_path": ("pt_path", _as_str, True),
    "k": ("k", _as_int, False),
    "deformation": ("deformation", _as_str, False),
    "max_distance": ("max_distance", _as_float, False),
    "absolute_distance": ("absolute_distance", _as_bool, False),
    "drop_unanchored": ("drop_unanchored", _as_bool, False),
    "faces": ("faces", _as_int, False),
    "reconstruct_faces": ("reconstruct_faces", _as_int, False),
    "sh_degree": ("sh_degree", _as_int, False),
    "keep_order": ("keep_order", _as_bool, False),
    "plain": ("plain", _as_bool, False),
    "legacy_trellis_frame": ("legacy_trellis_frame", _as_bool, False),
    "frame_change": ("frame_change", _as_bool, False),
    "no_frame_change": ("frame_change", lambda v: not _as_bool(v), False),
    "bake_poses": ("bake_poses", _as_str, True),
    "watertight": ("watertight", _as_bool, False),
    "collider": ("collider", _as_str, False),
    "physics": ("physics", lambda v: [_as_str(v)], False),
    "mass": ("mass", lambda v: [_as_str(v)], False),
    "ground": ("ground", _as_bool, False),
    "drop_nonfinite": ("drop_nonfinite", _as_bool, False),
    "edit_frame": ("edit_frame", _as_str, False),
    # the edits' numbers: "x,y,z" or a JSON list, checked by SplatEdit.from_options
    **{name: (name, lambda v: v, False) for name in EDIT_FLAGS},
}


@dataclass(frozen=True)
class AssetSpec:
    """One asset to convert: ``output`` is None until :func:`plan` names it; ``origin`` says
    where it was named (``manifest.csv:3``, or the command line's argument); ``position`` is
    its place among the inputs, set by :func:`plan` (``-1``: not planned), which keeps the
    report in input order when some assets are skipped."""

    input: str
    options: ConvertOptions
    output: str | None = None
    origin: str = ""
    position: int = -1


@dataclass
class BatchReport:
    """The whole batch; ``as_dict()`` is the ``--json`` output."""

    output_dir: str
    assets: list[AssetResult] = field(default_factory=list)
    scheduler: str | None = None
    jobs: int | None = 1  # local processes; None on Dask
    seconds: float = 0.0
    interrupted: bool = False
    #: The exit status when interrupted: 128 + the signal's number (130 for Ctrl-C).
    interrupt_status: int = 130

    def count(self, status: str) -> int:
        return sum(a.status == status for a in self.assets)

    @property
    def exit_status(self) -> int:
        """0 when no asset failed, 1 otherwise (when interrupted: 130, or 143 for SIGTERM, 129
        for SIGHUP)."""
        if self.interrupted:
            return self.interrupt_status
        return 1 if self.count("failed") else 0

    def as_dict(self) -> dict[str, Any]:
        return {"output_dir": self.output_dir, "scheduler": self.scheduler, "jobs": self.jobs,
                "total": len(self.assets), "ok": self.count("ok"),
                "failed": self.count("failed"), "skipped": self.count("skipped"),
                "interrupted": self.count("interrupted"), "seconds": self.seconds,
                "assets": [a.as_dict() for a in self.assets]}

    def lines(self) -> list[str]:
        out = [f"{a.input} -> {a.output}: {a.status}"
               + (f" ({a.summary.get('splats', 0)} splats, {a.summary.get('anchored', 0)} "
                  f"anchored)" if a.summary else "") for a in self.assets
               if a.status in ("ok", "skipped")]
        out.append(f"converted {self.count('ok')} of {len(self.assets)} assets into "
                   f"{self.output_dir} ({self.count('failed')} failed, {self.count('skipped')} "
                   f"skipped, {self.count('interrupted')} interrupted) in {self.seconds:.1f} s")
        return out


# --- inputs -------------------------------------------------------------------------------

def _is_glob(text: str) -> bool:
    return any(c in text for c in "*?[")


def collect(inputs: Iterable[str], defaults: ConvertOptions) -> list[AssetSpec]:
    """The assets the command line names: files and folders, glob patterns (sorted matches;
    a pattern matching nothing is a :class:`UsageError`) and manifests (by suffix)."""
    specs: list[AssetSpec] = []
    for arg in inputs:
        if arg == "-":
            raise UsageError("standard input ('-') cannot be part of a batch")
        if not os.path.exists(arg) and _is_glob(arg):
            matches = sorted(glob.glob(arg, recursive=True))
            if not matches:
                raise UsageError("no file matches this pattern", arg)
            paths = matches
        else:
            paths = [arg]
        for path in paths:
            if os.path.splitext(path)[1].lower() in MANIFEST_SUFFIXES and os.path.isfile(path):
                specs.extend(read_manifest(path, defaults))
            else:
                specs.append(AssetSpec(path, defaults, origin=arg))
    if not specs:
        raise UsageError("no inputs to convert")
    return specs


def _manifest_rows(path: str) -> list[tuple[int, dict[str, Any]]]:
    """(line or item number, row) pairs of a CSV (header row) or JSON manifest."""
    if path.lower().endswith(".json"):
        try:
            with open(path, encoding="utf-8") as f:
                data = json.load(f)
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise UsageError(f"cannot read the manifest: {exc}", path) from None
        if isinstance(data, dict) and "assets" in data:
            data = data["assets"]
        if not isinstance(data, list):
            raise UsageError("a JSON manifest is a list of assets or {\"assets\": [...]}", path)
        rows = []
        for i, item in enumerate(data, 1):
            if isinstance(item, str):
                item = {"input": item}
            if not isinstance(item, dict):
                raise UsageError(f"asset {i}: an object or an input path, not {item!r}", path)
            rows.append((i, item))
        return rows
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            lines = [line for line in f]
    except (OSError, UnicodeDecodeError) as exc:
        raise UsageError(f"cannot read the manifest: {exc}", path) from None
    reader = csv.DictReader(lines)
    if not reader.fieldnames:
        raise UsageError("an empty CSV manifest (it needs a header row with an input column)",
                         path)
    rows = []
    for row in reader:
        if not any((v or "").strip() for v in row.values() if isinstance(v, str)):
            continue  # blank line
        if None in row:
            raise UsageError(f"line {reader.line_num}: more cells than header columns", path)
        rows.append((reader.line_num, {k: v for k, v in row.items() if (v or "").strip()}))
    return rows


def read_manifest(path: str, defaults: ConvertOptions) -> list[AssetSpec]:
    """The assets of a manifest: CSV with a header row, or JSON (a list of objects, or
    ``{"assets": [...]}``; a bare string is an input). Keys: ``input`` (required), ``output``
    (relative to the output folder), ``mesh`` and the options of :data:`MANIFEST_KEYS` (the
    long flags, dashes or underscores). Paths are relative to the manifest's folder; empty
    cells and missing keys take the command line's value."""
    folder = os.path.dirname(os.path.abspath(path))
    specs = []
    for number, row in _manifest_rows(path):
        where = f"{path}:{number}" if path.lower().endswith(".csv") else f"{path}: asset {number}"
        values: dict[str, Any] = {}
        given: dict[str, Any] = {}
        for key, value in row.items():
            norm = str(key).strip().lower().replace("-", "_").lstrip("_")
            if norm in ("input", "output"):
                given[norm] = _as_str(value)
                continue
            if norm not in MANIFEST_KEYS:
                raise UsageError(f"unknown column {key!r}; use input, output or "
                                 f"{', '.join(sorted(MANIFEST_KEYS))}", where)
            name, parse, is_path = MANIFEST_KEYS[norm]
            if value is None:
                continue
            try:
                parsed = parse(value)
            except (TypeError, ValueError) as exc:
                raise UsageError(f"{key}: {exc}", where) from None
            values[name] = os.path.join(folder, parsed) if is_path else parsed
        if not given.get("input"):
            raise UsageError("no input", where)
        specs.append(AssetSpec(os.path.join(folder, given["input"]),
                               dataclasses.replace(defaults, **values),
                               given.get("output") or None, where))
    return specs


def _common_folder(paths: list[str]) -> str:
    parents = [os.path.dirname(os.path.abspath(p.rstrip("/\\") or p)) for p in paths]
    try:
        return os.path.commonpath(parents)
    except ValueError:  # different drives
        return ""


def _inside_output_dir(output_dir: str, name: str, where: str) -> str:
    """``name`` (a manifest's ``output``) joined to ``output_dir``; :class:`UsageError` when
    it is absolute or leads out of the folder, by ``..`` or through a symbolic link (the
    folder's real path is compared with the output's, as the glTF reader does for URIs)."""
    if os.path.isabs(name) or os.path.splitdrive(name)[0]:
        raise UsageError(f"output {name!r} is an absolute path; a manifest's outputs are "
                         f"relative to --output-dir", where)
    out = os.path.normpath(os.path.join(output_dir, name))
    root = os.path.realpath(output_dir)
    real = os.path.realpath(out)
    if real == root or os.path.commonpath([root, real]) != root:
        raise UsageError(f"output {name!r} leads outside --output-dir {output_dir}", where)
    return out


def _input_files(spec: AssetSpec) -> list[str]:
    """Every file an asset reads: its input, meshes, poses and checkpoint."""
    o = spec.options
    paths = [spec.input, o.mesh, o.bake_poses, o.pt_path, *(o.meshes or [])]
    return [p for p in paths if p]


def _refuse_outputs_over_inputs(named: list[AssetSpec]) -> None:
    """:class:`UsageError` naming the row when an asset's output is a file some asset of the
    batch reads (the same path, a link to it, or the same file under another name): the
    batch would convert a file it had just overwritten."""
    reads: dict[str, AssetSpec] = {}
    stats: dict[tuple[int, int], AssetSpec] = {}
    for s in named:
        for path in _input_files(s):
            reads.setdefault(os.path.normcase(os.path.realpath(path)), s)
            try:
                st = os.stat(path)
            except OSError:
                continue
            stats.setdefault((st.st_dev, st.st_ino), s)
    for s in named:
        assert s.output is not None
        owner = reads.get(os.path.normcase(os.path.realpath(s.output)))
        if owner is None:
            try:
                st = os.stat(s.output)
                owner = stats.get((st.st_dev, st.st_ino))
            except OSError:
                owner = None
        if owner is not None:
            whose = "its own input" if owner is s else f"an input of {owner.origin or owner.input}"
            raise UsageError(f"output {s.output} is {whose}; write the outputs elsewhere",
                             s.origin or s.input)


def plan(specs: list[AssetSpec], output_dir: str, to: str = "glb", *, overwrite: bool = False,
         skip_existing: bool = False) -> tuple[list[AssetSpec], list[AssetResult]]:
    """Name every output under ``output_dir``; returns (assets to convert, assets skipped
    because their output exists, with ``skip_existing``). :class:`UsageError` for two assets
    with one output, or an output that exists (without ``overwrite``/``skip_existing``)."""
    suffix = "." + to.lower().lstrip(".")
    common = _common_folder([s.input for s in specs if s.output is None])
    named: list[AssetSpec] = []
    for s in specs:
        if s.output is not None:
            out = _inside_output_dir(output_dir, s.output, s.origin or s.input)
        else:
            src = os.path.abspath(s.input.rstrip("/\\") or s.input)
            rel = os.path.relpath(src, common) if common else os.path.basename(src)
            out = os.path.join(output_dir, os.path.splitext(rel)[0] + suffix)
        named.append(dataclasses.replace(s, output=os.path.normpath(out),
                                         position=len(named)))
    seen: dict[str, AssetSpec] = {}
    for s in named:
        assert s.output is not None
        key = os.path.normcase(os.path.abspath(s.output))
        if key in seen:
            raise UsageError(f"{seen[key].input} and {s.input} would both be written to "
                             f"{s.output}; name the outputs in a manifest", s.origin or s.input)
        seen[key] = s
    _refuse_outputs_over_inputs(named)
    todo, skipped = [], []
    existing = [s for s in named if s.output is not None and os.path.exists(s.output)]
    if existing and not (overwrite or skip_existing):
        more = f" (and {len(existing) - 1} more)" if len(existing) > 1 else ""
        raise UsageError(f"output exists{more}; use -w/--overwrite to replace, or "
                         f"--skip-existing to keep it", existing[0].output)
    for s in named:
        assert s.output is not None
        if skip_existing and not overwrite and os.path.exists(s.output):
            skipped.append(AssetResult(s.input, s.output, "skipped"))
        else:
            todo.append(s)
    return todo, skipped


# --- the batch ----------------------------------------------------------------------------

def run_batch(specs: list[AssetSpec], output_dir: str, *, jobs: int | None = None,
              scheduler: str | None = None, overwrite: bool = False, quiet: bool = False,
              skipped: Iterable[AssetResult] = (), progress: Progress | None = None
              ) -> BatchReport:
    """Convert planned ``specs`` (:func:`plan`): ``jobs`` local processes (default: the CPU
    count; 1 converts in this process), or one task per asset on the Dask scheduler at
    ``scheduler``. The report lists the assets in input order: converted and ``skipped`` ones
    (both from :func:`plan`) where their inputs were (by :attr:`AssetSpec.position`; specs not
    planned come first, in their order, then ``skipped``). A Ctrl-C stops the batch: running
    conversions are interrupted (their temporary files removed), pending ones never start, and
    the report says ``interrupted``."""
    start = time.perf_counter()
    progress = progress or Progress(enabled=False)
    jobs = max(1, jobs if jobs is not None else (os.cpu_count() or 1))
    jobs = min(jobs, max(1, len(specs)))
    tasks = []
    for i, s in enumerate(specs):
        assert s.output is not None, "plan() names the outputs"
        tasks.append(BatchTask(i, s.input, s.output, s.options, overwrite, quiet))
    results: dict[int, AssetResult] = {}
    by_output = {t.output: t.index for t in tasks}
    failed = 0

    def tick(result: AssetResult) -> None:
        nonlocal failed
        results[by_output[result.output]] = result
        failed += result.status == "failed"
        progress.update(len(results), len(tasks),
                        f"{len(results)}/{len(tasks)}" + (f", {failed} failed" if failed else ""))

    existed = {t.index: os.path.exists(t.output) for t in tasks}
    report = BatchReport(output_dir, scheduler=scheduler, jobs=None if scheduler else jobs)
    make_folder(output_dir)
    progress.stage(f"converting {len(tasks)} assets")
    progress.update(0, len(tasks))
    try:
        if scheduler:
            run_dask(tasks, scheduler, quiet, tick)
        else:
            run_local(tasks, jobs, tick)
    except KeyboardInterrupt as exc:  # Ctrl-C; SIGTERM and SIGHUP under the command line
        report.interrupted = True
        report.interrupt_status = 128 + getattr(exc, "signum", signal.SIGINT)
    finally:
        progress.close()
    for t in tasks:
        result = results.get(t.index)
        if result is None and not existed[t.index] and os.path.exists(t.output):
            result = AssetResult(t.input, t.output, "ok")  # written as the interrupt came
        report.assets.append(result or AssetResult(
            t.input, t.output, "interrupted", f"{t.input}: not converted (interrupted)"))
    report.assets = _in_input_order(report.assets, [s.position for s in specs], list(skipped))
    report.seconds = time.perf_counter() - start
    return report


def _in_input_order(done: list[AssetResult], positions: list[int],
                    skipped: list[AssetResult]) -> list[AssetResult]:
    """``done`` (one result per spec, at ``positions`` among the inputs) and ``skipped`` (the
    remaining positions, in order) merged in input order."""
    if not skipped or any(p < 0 for p in positions):
        return done + skipped
    total = len(done) + len(skipped)
    free = iter(sorted(set(range(total)) - set(positions)))
    slots: dict[int, AssetResult] = dict(zip(positions, done))
    for result in skipped:
        slots[next(free, total + len(slots))] = result
    return [slots[k] for k in sorted(slots)]
