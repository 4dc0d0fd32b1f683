"""``gsverse-convert`` against PlayCanvas ``splat-transform`` on the same file, and how it scales.

Input: a 3DGS PLY (SH degree 3, with normals: 62 float properties, 248 bytes per splat) of
surface splats on a bumpy bar, and the bar's mesh as a binary PLY (full run: 1M splats, 248 MB,
and a 100,000-face mesh; ``--quick``: 20k splats, ~6k faces).

Side by side, each command a fresh process (start-up and imports included), median of the
repetitions, peak resident memory of the process:

* PlayCanvas ``splat-transform`` (npm ``@playcanvas/splat-transform``, installed with
  ``npm ci`` in ``tests/splat_transform``, where the tests use it too), PLY → GLB;
* ``gsverse-convert --plain`` (format only: the same PLY → ``KHR_gaussian_splatting`` GLB);
* ``gsverse-convert --mesh`` (anchored to the mesh: binding, sorting, the anchor accessors);

with the ratios the goals are stated in: plain / splat-transform, anchored / plain, and each
peak RSS / the input file's size. Then where the memory of the plain conversion goes, stage by
stage (numpy's allocations traced by ``tracemalloc``, the process's resident and peak memory
after each stage), and a scaling table (``--sizes``, default 100k, 1M, 4M splats on the same
mesh): plain and anchored conversion and ``gsverse-validate`` of the anchored output, with the
time per splat.

Each command runs as a fresh process through :func:`benchmarks.processes.run_process`: its peak
RSS from a small launcher, and the memory it will use made resident first (untimed, the same
for every command, splat-transform included; :mod:`benchmarks.processes` says why).

``python -m benchmarks.convert [--quick] [--sizes 100k 1M 4M] [--repeat N]`` prints the tables.
"""
from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from .processes import run_process

HERE = Path(__file__).resolve().parent
#: The splat-transform command line tool, after ``npm ci`` in ``tests/splat_transform`` (the
#: one install of it, shared with the tests of the splat-format readers).
SPLAT_TRANSFORM = (HERE.parent / "tests" / "splat_transform" / "node_modules" / "@playcanvas"
                   / "splat-transform" / "bin" / "cli.mjs")
#: Scaling sizes by name.
SIZES = {"10k": 10_000, "20k": 20_000, "100k": 100_000, "250k": 250_000, "1M": 1_000_000,
         "2M": 2_000_000, "4M": 4_000_000}
DEFAULT_SIZES = ("100k", "1M", "4M")
#: Rounds of the side-by-side runs and of the scaling rows (medians). On a virtual machine
#: whose host takes memory back (see processes.py) one conversion of 1M splats still moves by
#: up to 0.4 s between rounds: a median of five needs three slow rounds to move, of three two.
ROUNDS = 5
QUICK_SIZES = ("10k", "20k")
#: Splats generated at a time (bounds the generator's float64 temporaries).
_CHUNK = 250_000

_STAGES = """
import json, os, sys, time, tracemalloc
def rss():
    out = {}
    for line in open("/proc/self/status"):
        if line.startswith(("VmRSS:", "VmHWM:")):
            out[line.split(":")[0]] = int(line.split()[1]) / 1024.0
    return out
t0 = time.perf_counter()
from gsverse_format.io.registry import FRAMES, rotate_asset, write_asset
from gsverse_format.io.ply import read_ply_asset
rows = []
def stage(name, fn):
    tracemalloc.start()
    t = time.perf_counter()
    value = fn()
    seconds = time.perf_counter() - t
    current, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    rows.append(dict(stage=name, seconds=seconds, traced_peak_mb=peak / 2**20,
                     traced_kept_mb=current / 2**20, **rss()))
    return value
rows.append(dict(stage="start-up and imports", seconds=time.perf_counter() - t0,
                 traced_peak_mb=0.0, traced_kept_mb=0.0, **rss()))
asset = stage("read the PLY (file frame)", lambda: read_ply_asset(sys.argv[1]))
asset = stage("frame change into glTF",   # as read_asset does: the SH rotated in their own array
              lambda: rotate_asset(asset, FRAMES["3dgs"].to_gltf, consume=True))
stage("write the GLB", lambda: write_asset(asset, sys.argv[2], frame_change=False))
print(json.dumps(rows))
"""


_ANCHORED_STAGES = _STAGES.split("rows = []")[0] + """
from gsverse_format.binding import bind_local
from gsverse_format.model import Anchoring, SplatAsset, SplatPrimitive
from gsverse_format.pipeline import load_source
import numpy as np
rows = []
def stage(name, fn):
    tracemalloc.start()
    t = time.perf_counter()
    value = fn()
    seconds = time.perf_counter() - t
    current, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    rows.append(dict(stage=name, seconds=seconds, traced_peak_mb=peak / 2**20,
                     traced_kept_mb=current / 2**20, **rss()))
    return value
rows.append(dict(stage="start-up and imports", seconds=time.perf_counter() - t0,
                 traced_peak_mb=0.0, traced_kept_mb=0.0, **rss()))
result = stage("read PLY and mesh, frame change", lambda: load_source("3dgs", sys.argv[1], sys.argv[3]))
bound = stage("bind to the nearest triangles", lambda: bind_local(result.splats, result.mesh))
order = np.argsort(bound.anchors.face_index, kind="stable")
def _sort():   # as gsverse-convert does: the splats reordered in place, the anchors copied
    result.splats.permute(order)
    return result.splats, bound.anchors.subset(order)
splats, anchors = stage("sort by face (in place)", _sort)
mesh = result.mesh
del result, bound
asset = SplatAsset([SplatPrimitive(splats, Anchoring(mesh, anchors), "splats")])
stage("write the GLB", lambda: write_asset(asset, sys.argv[2], frame_change=False))
print(json.dumps(rows))
"""


def _env() -> dict:
    from . import child_env

    return child_env()


def _python(module_main: str, *args: str) -> list[str]:
    return [sys.executable, "-c", f"from {module_main} import main; raise SystemExit(main())",
            *args]


def splat_transform_problem() -> str | None:
    """Why splat-transform cannot run here, or None."""
    if shutil.which("node") is None:
        return "node is not on PATH"
    if not SPLAT_TRANSFORM.is_file():
        return "not installed: run `npm ci` in tests/splat_transform"
    return None


def make_mesh(quick: bool):
    from .accuracy import bar_mesh

    return bar_mesh(48, 60) if quick else bar_mesh(200, 251)   # ~6k or ~100k faces


def write_inputs(folder: Path, mesh, n: int, seed: int = 3) -> tuple[Path, Path]:
    """``splats.ply`` (``n`` SH-degree-3 splats with normals), ``mesh.ply`` and the same mesh as
    ``mesh.obj`` in ``folder``; returns the paths of the first two."""
    from gsverse_format.io.ply import write_splat_ply
    from gsverse_format.model import SplatCloud

    from .accuracy import surface_object

    parts = []
    for i, start in enumerate(range(0, n, _CHUNK)):
        m = min(_CHUNK, n - start)
        c = surface_object(mesh, m, seed=seed + i)
        rng = np.random.default_rng(seed + 1000 + i)
        parts.append(SplatCloud(c.means, c.rotations, c.scales,
                                rng.uniform(0.1, 1.0, m).astype(np.float32),
                                rng.normal(0, 0.3, (m, 16, 3)).astype(np.float32)))
        del c
    cloud = SplatCloud.concatenate(parts) if len(parts) > 1 else parts[0]
    del parts
    splats, mesh_path = folder / "splats.ply", folder / "mesh.ply"
    write_splat_ply(cloud, splats, normals=True)
    del cloud
    import trimesh

    tm = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    tm.export(mesh_path)
    tm.export(folder / "mesh.obj")   # the same mesh as OBJ (``v`` and ``f`` records)
    return splats, mesh_path


def _warm_bytes(previous: list[dict], first: int) -> int:
    """Memory to make resident before a command's next run: its peak RSS so far, else
    ``first``."""
    peaks = [r["peak_rss_mb"] for r in previous if np.isfinite(r["peak_rss_mb"])]
    return int(max(peaks) * 2**20) if peaks else first


def _median_runs(commands: dict[str, tuple[list[str], Path]], repeat: int,
                 warm: int) -> dict[str, dict]:
    """Each command ``repeat`` times, the commands interleaved (round by round, so that a
    slower spell of the machine falls on all of them), with medians per command."""
    runs: dict[str, list[dict]] = {key: [] for key in commands}
    errors: dict[str, dict] = {}
    for _ in range(repeat):
        for key, (cmd, output) in commands.items():
            if key in errors:
                continue
            if output.exists():
                output.unlink()
            r = run_process(cmd, env=_env(), warm=_warm_bytes(runs[key], warm))
            if r["rc"] != 0:
                errors[key] = {"error": r["output"][-2000:], "command": " ".join(cmd)}
                continue
            runs[key].append(r)
    res: dict[str, dict] = {}
    for key, (_, output) in commands.items():
        if key in errors:
            res[key] = errors[key]
            continue
        walls = [r["wall_s"] for r in runs[key]]
        res[key] = {"wall_s": float(np.median(walls)), "best_s": float(min(walls)),
                    "peak_rss_mb": float(max(r["peak_rss_mb"] for r in runs[key])),
                    "output_mb": output.stat().st_size / 2**20}
    return res


def head_to_head(folder: Path, splats: Path, mesh_path: Path, repeat: int, log) -> dict:
    """The three conversions of the same PLY, side by side (interleaved rounds)."""
    res: dict = {}
    commands: dict[str, tuple[list[str], Path]] = {}
    problem = splat_transform_problem()
    if problem is None:
        out = folder / "splat-transform.glb"
        commands["splat_transform"] = (
            ["node", str(SPLAT_TRANSFORM), "-q", "-w", str(splats), str(out)], out)
        version = subprocess.run(["node", str(SPLAT_TRANSFORM), "--version"],
                                 capture_output=True, text=True)
        found = re.search(r"\d+\.\d+\.\d+", version.stdout + version.stderr)
        res["splat_transform_version"] = found.group(0) if found else ""
    else:
        res["splat_transform"] = {"skipped": problem}
    plain, anchored = folder / "plain.glb", folder / "anchored.glb"
    commands["plain"] = (_python("gsverse_format.cli.convert", str(splats), str(plain),
                                 "--plain", "-q", "-w"), plain)
    commands["anchored"] = (_python("gsverse_format.cli.convert", str(splats), str(anchored),
                                    "--mesh", str(mesh_path), "-q", "-w"), anchored)
    log(f"convert: {', '.join(commands)} side by side, {repeat} round(s)")
    res.update(_median_runs(commands, repeat, 3 * splats.stat().st_size))
    return res


def memory_stages(splats: Path, folder: Path, mesh_path: Path | None = None) -> list[dict]:
    """Where the memory of a plain conversion goes (of an anchored one, given the mesh),
    stage by stage (a fresh process)."""
    out = folder / "stages.glb"
    script = _STAGES if mesh_path is None else _ANCHORED_STAGES
    r = subprocess.run([sys.executable, "-c", script, str(splats), str(out),
                        *([str(mesh_path)] if mesh_path is not None else [])],
                       capture_output=True, text=True, env=_env())
    if r.returncode != 0:
        return [{"stage": "error", "error": r.stderr[-1000:]}]
    return json.loads(r.stdout.strip().splitlines()[-1])


def _read_through(path: Path) -> None:
    """Read ``path`` once, so that every timed run finds it in the page cache (the first run
    after writing a 1 GiB input otherwise waits for the disk, the others do not)."""
    with open(path, "rb") as handle:
        while handle.read(1 << 24):
            pass


def scaling(folder: Path, mesh, sizes: list[str], log, rounds: int = ROUNDS) -> list[dict]:
    """Plain and anchored conversion (mesh as PLY and as OBJ) and validation at each size:
    ``rounds`` interleaved rounds of the four commands, medians."""
    rows = []
    for name in sizes:
        n = SIZES[name]
        d = folder / f"scale-{name}"
        d.mkdir()
        log(f"convert: scaling, {name} splats")
        splats, mesh_path = write_inputs(d, mesh, n, seed=11)
        _read_through(splats)
        row: dict = {"size": name, "n_splats": n, "input_mb": splats.stat().st_size / 2**20,
                     "rounds": rounds}
        plain, anchored = d / "plain.glb", d / "anchored.glb"
        runs = {
            "plain": _python("gsverse_format.cli.convert", str(splats), str(plain), "--plain",
                             "-q", "-w"),
            "anchored": _python("gsverse_format.cli.convert", str(splats), str(anchored),
                                "--mesh", str(mesh_path), "-q", "-w"),
            "anchored_obj": _python("gsverse_format.cli.convert", str(splats),
                                    str(d / "anchored-obj.glb"), "--mesh", str(d / "mesh.obj"),
                                    "-q", "-w"),
            "validate": _python("gsverse_format.validators.cli", str(anchored)),
        }
        times: dict[str, list[float]] = {key: [] for key in runs}
        done: dict[str, list[dict]] = {key: [] for key in runs}
        for _ in range(rounds):
            for key, cmd in runs.items():
                if f"{key}_error" in row:
                    continue
                r = run_process(cmd, env=_env(),
                                warm=_warm_bytes(done[key], 3 * splats.stat().st_size))
                done[key].append(r)
                if r["rc"] != 0:
                    row[f"{key}_error"] = r["output"][-500:]
                    continue
                times[key].append(r["wall_s"])
                row[f"{key}_peak_rss_mb"] = max(row.get(f"{key}_peak_rss_mb", 0.0),
                                                r["peak_rss_mb"])
        for key, values in times.items():
            if values and f"{key}_error" not in row:
                row[f"{key}_s"] = float(np.median(values))
                row[f"{key}_us_per_splat"] = row[f"{key}_s"] / n * 1e6
        rows.append(row)
        shutil.rmtree(d)
    return rows


def first_run(folder: Path, mesh, n: int, log) -> dict:
    """An anchored conversion of ``n`` splats in a fresh numba cache (``NUMBA_CACHE_DIR``):
    with nothing compiled (whatever numba kernels the run needs compile during it; an
    anchored conversion needs none, binding's search being the C extension), right after
    ``python -m gsverse_format.precompile`` (the README's set-up), and warm (median of two
    later runs)."""
    d = folder / "first-run"
    d.mkdir()
    splats, mesh_path = write_inputs(d, mesh, n, seed=21)
    _read_through(splats)
    cache = d / "numba-cache"
    env = dict(_env(), NUMBA_CACHE_DIR=str(cache))
    cmd = _python("gsverse_format.cli.convert", str(splats), str(d / "out.glb"), "--mesh",
                  str(mesh_path), "-q", "-w")
    res: dict = {"n_splats": n, "n_faces": mesh.face_count}

    def timed(key: str, command: list[str]) -> bool:
        r = run_process(command, env=env, warm=3 * splats.stat().st_size)
        if r["rc"] != 0:
            res["error"] = f"{key}: " + r["output"].strip()[-500:]
            return False
        res[f"{key}_s"] = r["wall_s"]
        return True

    log(f"convert: first run after install, {n} splats")
    cache.mkdir()
    if not timed("uncompiled", cmd):
        return res
    shutil.rmtree(cache)
    cache.mkdir()
    if not timed("precompile", [sys.executable, "-m", "gsverse_format.precompile", "-q"]):
        return res
    if not timed("first", cmd):
        return res
    warm = []
    for _ in range(2):
        if not timed("warm", cmd):
            return res
        warm.append(res["warm_s"])
    res["warm_s"] = float(np.median(warm))
    res["first_over_warm"] = res["first_s"] / res["warm_s"]
    res["uncompiled_over_warm"] = res["uncompiled_s"] / res["warm_s"]
    shutil.rmtree(d)
    return res


def run(quick: bool = False, log=print, workdir: str | None = None,
        sizes: list[str] | None = None, repeat: int | None = None) -> dict:
    t_start = time.perf_counter()
    n = 20_000 if quick else 1_000_000
    repeat = repeat or (1 if quick else ROUNDS)
    mesh = make_mesh(quick)
    tmp = tempfile.TemporaryDirectory(dir=workdir)
    folder = Path(tmp.name)
    try:
        log(f"convert: writing {n} splats, {mesh.face_count} faces")
        splats, mesh_path = write_inputs(folder, mesh, n)
        res: dict = {"n_splats": n, "n_faces": mesh.face_count,
                     "input_mb": splats.stat().st_size / 2**20, "repeat": repeat}
        res.update(head_to_head(folder, splats, mesh_path, repeat, log))
        input_mb = res["input_mb"]
        st, plain, anchored = res["splat_transform"], res["plain"], res["anchored"]
        ratios: dict = {}
        if "wall_s" in plain and "wall_s" in st:
            ratios["plain_over_splat_transform"] = plain["wall_s"] / st["wall_s"]
        if "wall_s" in plain and "wall_s" in anchored:
            ratios["anchored_over_plain"] = anchored["wall_s"] / plain["wall_s"]
        for key, r in (("splat_transform", st), ("plain", plain), ("anchored", anchored)):
            if "peak_rss_mb" in r:
                ratios[f"{key}_rss_over_input"] = r["peak_rss_mb"] / input_mb
        res["ratios"] = ratios
        # the keys the report's memory summary reads
        if "peak_rss_mb" in anchored:
            res["cli_peak_rss_mb"] = anchored["peak_rss_mb"]
        if "peak_rss_mb" in plain:
            res["plain_peak_rss_mb"] = plain["peak_rss_mb"]
        log("convert: memory by stage")
        res["stages"] = memory_stages(splats, folder)
        res["anchored_stages"] = memory_stages(splats, folder, mesh_path)
        splats.unlink()
        res["scaling"] = scaling(folder, mesh, list(sizes or (QUICK_SIZES if quick else DEFAULT_SIZES)),
                                 log, rounds=1 if quick else ROUNDS)
        # not with --quick: compiling every kernel twice takes more than a minute
        res["first_run"] = {"skipped": "not run with --quick"} if quick else \
            first_run(folder, mesh, 100_000, log)
    finally:
        tmp.cleanup()
    res["seconds"] = time.perf_counter() - t_start
    log(f"convert: done in {res['seconds']:.1f} s")
    return res


# ---------------------------------------------------------------------------- report


def _f(x, digits: int = 3) -> str:
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "–"
    return f"{x:.{digits}g}"


def _table(header: list[str], rows: list[list]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def _goal(what: str, value: float, limit: float, low: float | None = None) -> str:
    """``what: value× (goal ≤ limit: met / missed by …)``; with ``low``, the goal is the band
    [low, limit]."""
    if low is None:
        ok, band = value <= limit, f"≤ {limit:g}"
        miss = 100.0 * (value / limit - 1.0)
    else:
        ok, band = low <= value <= limit, f"{low:g}–{limit:g}"
        miss = 100.0 * (value / limit - 1.0 if value > limit else 1.0 - value / low)
    verdict = "met" if ok else f"missed by {miss:.0f} %"
    return f"{what}: **{value:.2f}×** (goal {band}: {verdict})"


def scaling_markdown(scale: list[dict], n_faces: int) -> list[str]:
    """The scaling table and its goals: anchored ≤ 1.5× plain at every size, with the mesh as
    PLY and as OBJ; time per splat from 1M to 4M not growing by more than 20 %; peak RSS ≤ 3×
    the input."""
    if not scale:
        return []
    rounds = scale[0].get("rounds", 1)
    L = [f"Scaling (the same {n_faces:,}-face mesh, as PLY and as OBJ; each command a fresh "
         f"process, the four commands interleaved, median of {rounds} round(s); µs per splat = "
         "wall time / splats, start-up included; peak = the largest peak RSS of the rounds, "
         "over the input file's size; memory made resident before each run, untimed, see "
         "`benchmarks/processes.py`):", ""]
    rows = []
    for r in scale:
        row = [f"{r['n_splats']:,}", _f(r["input_mb"])]
        for key in ("plain", "anchored", "anchored_obj", "validate"):
            if f"{key}_s" not in r:
                row += ["failed", "–", "–"]
                continue
            middle = (_f(r[f"{key}_us_per_splat"]) if key in ("plain", "validate") or
                      "plain_s" not in r else f"{r[f'{key}_s'] / r['plain_s']:.2f}×")
            row += [_f(r[f"{key}_s"]), middle, _f(r[f"{key}_peak_rss_mb"] / r["input_mb"])]
        rows.append(row)
    L.append(_table(["splats", "input MiB", "plain s", "plain µs/splat", "plain peak ×",
                     "anchored (PLY mesh) s", "× plain", "peak ×", "anchored (OBJ mesh) s",
                     "× plain", "peak ×", "validate s", "validate µs/splat", "peak ×"], rows))
    L.append("")
    goals = []
    for r in scale:
        for key, what in (("anchored", "PLY"), ("anchored_obj", "OBJ")):
            if f"{key}_s" in r and "plain_s" in r:
                goals.append(_goal(f"{r['n_splats']:,} splats, anchored ({what} mesh) / `--plain`",
                                   r[f"{key}_s"] / r["plain_s"], 1.5))
    by_n = {r["n_splats"]: r for r in scale}
    if 1_000_000 in by_n and 4_000_000 in by_n:
        a, b = by_n[1_000_000], by_n[4_000_000]
        for key, what in (("plain", "`--plain`"), ("anchored", "anchored"),
                          ("validate", "`gsverse-validate`")):
            if f"{key}_us_per_splat" in a and f"{key}_us_per_splat" in b:
                # flat means no growth per splat: below 0.8 the process's fixed costs (start-up,
                # imports, numba's set-up) are spread over four times the splats
                ratio = b[f"{key}_us_per_splat"] / a[f"{key}_us_per_splat"]
                goals.append(_goal(f"{what} time per splat, 4M / 1M", ratio, 1.2)
                             + (" (lower at 4M: the fixed costs of a process spread over more "
                                "splats)" if ratio < 0.8 else ""))
    # (below 1M splats the interpreter and the libraries outweigh the input)
    worst = max(((r[k] / r["input_mb"], r["n_splats"]) for r in scale for k in r
                 if k.endswith("_peak_rss_mb") and r["n_splats"] >= 1_000_000), default=None)
    if worst is not None:
        goals.append(_goal(f"largest peak RSS / input (at {worst[1]:,} splats)", worst[0], 3.0))
    return L + [f"- {g}" for g in goals] + [""]


def first_run_markdown(first: dict) -> list[str]:
    """The first conversion after installing, against a warm one."""
    if not first:
        return []
    if "skipped" in first:
        return [f"First anchored conversion after installing: {first['skipped']}.", ""]
    L = [f"First anchored conversion after installing ({first['n_splats']:,} splats, "
         f"{first['n_faces']:,} faces; an empty `NUMBA_CACHE_DIR`; each a fresh process):", ""]
    if "error" in first:
        return L + ["The measurement failed:", "", "```", first["error"], "```", ""]
    L.append(_table(["run", "wall s", "/ warm"], [
        ["an empty numba cache, no precompile (an anchored conversion runs no numba kernel)",
         _f(first["uncompiled_s"]),
         f"{first['uncompiled_over_warm']:.2f}×"],
        ["`python -m gsverse_format.precompile` (the README's set-up)", _f(first["precompile_s"]),
         "–"],
        ["first conversion after it", _f(first["first_s"]), f"{first['first_over_warm']:.2f}×"],
        ["warm (median of two later runs)", _f(first["warm_s"]), "1×"]]))
    L.append("")
    L.append("- " + _goal("first conversion after installing / warm", first["first_over_warm"], 1.5))
    return L + [""]


def markdown(conv: dict) -> list[str]:
    """The report section (Markdown lines) for the result of :func:`run`."""
    L = ["## `gsverse-convert` end to end", ""]
    if not conv:
        return L + ["Not run.", ""]
    if "plain" not in conv:   # a failure before the runs
        return L + ["The benchmark failed:", "", "```", str(conv.get("error", "")), "```", ""]
    input_mb = conv["input_mb"]
    L.append(f"A 3DGS PLY of {conv['n_splats']:,} splats (SH degree 3 with normals, "
             f"{input_mb:.1f} MiB) and a {conv['n_faces']:,}-face mesh PLY; each command a fresh "
             f"process, the commands interleaved, median of {conv['repeat']} round(s); peak RSS of "
             "the process; memory made resident before each run, untimed (a virtual machine's "
             "free page reporting otherwise adds up to a second to a run, see "
             "`benchmarks/processes.py`).")
    L.append("")
    rows = []
    st = conv["splat_transform"]
    label = f"PlayCanvas `splat-transform` {conv.get('splat_transform_version', '')}, PLY → GLB"
    named = ((label.replace("  ", " "), st), ("`gsverse-convert --plain` (format only)", conv["plain"]),
             ("`gsverse-convert --mesh` (anchored)", conv["anchored"]))
    for name, r in named:
        if "skipped" in r:
            rows.append([name, f"skipped: {r['skipped']}", "–", "–", "–"])
        elif "error" in r:
            rows.append([name, "failed: " + r["error"].strip().splitlines()[-1][:120], "–", "–", "–"])
        else:
            rows.append([name, _f(r["wall_s"]), _f(r["peak_rss_mb"], 4),
                         _f(r["peak_rss_mb"] / input_mb), _f(r["output_mb"], 4)])
    L.append(_table(["run", "wall s", "peak RSS MiB", "peak RSS / input", "output MiB"], rows))
    L.append("")
    ratios = conv.get("ratios", {})

    def goal(what: str, value: float, limit: float) -> str:
        verdict = "met" if value <= limit else f"missed by {100.0 * (value / limit - 1.0):.0f} %"
        return f"{what}: **{value:.2f}×** (goal ≤ {limit:g}: {verdict})"

    goals = []
    if "plain_over_splat_transform" in ratios:
        goals.append(goal("`--plain` / splat-transform wall time",
                          ratios["plain_over_splat_transform"], 1.0))
    if "anchored_over_plain" in ratios:
        goals.append(goal("anchored / `--plain` wall time", ratios["anchored_over_plain"], 1.5))
    for key, what in (("plain", "`--plain`"), ("anchored", "anchored")):
        if f"{key}_rss_over_input" in ratios:
            goals.append(goal(f"{what} peak RSS / input size", ratios[f"{key}_rss_over_input"], 3.0))
    L += [f"- {g}" for g in goals]
    if conv["n_splats"] < 500_000:
        L.append(f"- At {conv['n_splats']:,} splats these ratios mostly compare start-up costs "
                 "(interpreters, imports): the goals are stated for 1M splats.")
    L.append("")
    for key, what in (("stages", "plain"), ("anchored_stages", "anchored")):
        stages = conv.get(key) or []
        if not stages:
            continue
        if "error" in stages[0]:
            L += [f"The {what} memory breakdown failed:", "", "```", stages[0]["error"], "```", ""]
            continue
        L.append(f"Where the memory of the {what} conversion goes (a fresh process; traced: numpy "
                 "and Python allocations during the stage; RSS and peak RSS of the process after "
                 "it; the PLY is memory-mapped, so its pages count in RSS but not in the traced "
                 "bytes" + ("; numba's compiled kernels count in RSS only" if key != "stages" else "")
                 + "):")
        L.append("")
        L.append(_table(["stage", "seconds", "traced peak MiB", "traced kept MiB", "RSS MiB",
                         "peak RSS MiB"],
                        [[s["stage"], _f(s["seconds"]), _f(s["traced_peak_mb"]),
                          _f(s["traced_kept_mb"]), _f(s.get("VmRSS"), 4), _f(s.get("VmHWM"), 4)]
                         for s in stages]))
        L.append("")
    L += scaling_markdown(conv.get("scaling") or [], conv["n_faces"])
    L += first_run_markdown(conv.get("first_run") or {})
    return L


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.convert", description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true", help="20k splats, ~6k faces; sizes 10k, 20k")
    p.add_argument("--sizes", nargs="+", choices=list(SIZES),
                   help=f"scaling sizes (default: {' '.join(DEFAULT_SIZES)})")
    p.add_argument("--repeat", type=int,
                   help=f"repetitions of the side-by-side runs (default {ROUNDS})")
    p.add_argument("--json", metavar="FILE", help="also write the results as JSON")
    args = p.parse_args(argv)
    res = run(args.quick, log=lambda msg: print(msg, file=sys.stderr, flush=True),
              sizes=args.sizes, repeat=args.repeat)
    print("\n".join(markdown(res)))
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=1, default=float), encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
