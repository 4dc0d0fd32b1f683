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

with the ratios the goals are stated in: plain / splat-transform, anchored / plain (each the
median over the rounds of the two commands' times in the same round), and each peak RSS / the
input file's size. Then where the memory of the plain conversion goes, stage by
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

from .convert_report import markdown
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


def _median_runs(commands: dict[str, tuple[list[str], Path | None]], repeat: int,
                 warm: int) -> dict[str, dict]:
    """Each command ``repeat`` times, the commands interleaved round by round (so that a slower
    spell of the machine falls on all of them), the order rotated by one each round (so that
    no command always runs right after the same one), with medians per command and each
    round's wall times (``walls``, None where the command was not run; for
    :func:`paired_ratio`). ``commands``: key -> (command, output file or None); a command that
    fails is not run again and reports its error."""
    keys = list(commands)
    runs: dict[str, list[dict]] = {key: [] for key in commands}
    walls: dict[str, list[float | None]] = {key: [] for key in commands}
    errors: dict[str, dict] = {}
    for round_ in range(repeat):
        turn = round_ % len(keys) if keys else 0
        for key in keys[turn:] + keys[:turn]:
            cmd, output = commands[key]
            if key in errors:
                walls[key].append(None)
                continue
            if output is not None and output.exists():
                output.unlink()
            r = run_process(cmd, env=_env(), warm=_warm_bytes(runs[key], warm))
            if r["rc"] != 0:
                errors[key] = {"error": r["output"][-2000:], "command": " ".join(cmd)}
                walls[key].append(None)
                continue
            runs[key].append(r)
            walls[key].append(r["wall_s"])
    res: dict[str, dict] = {}
    for key, (_, output) in commands.items():
        if key in errors:
            res[key] = errors[key]
            continue
        times = [r["wall_s"] for r in runs[key]]
        res[key] = {"wall_s": float(np.median(times)), "best_s": float(min(times)),
                    "peak_rss_mb": float(max(r["peak_rss_mb"] for r in runs[key])),
                    "walls": walls[key]}
        if output is not None:
            res[key]["output_mb"] = output.stat().st_size / 2**20
    return res


def paired_ratio(a: dict, b: dict) -> float:
    """The median over the rounds of ``a``'s wall time over ``b``'s in the same round (two
    results of :func:`_median_runs`): a slower spell of the machine that falls on one round
    moves both of its times, and so the ratio less than either median. NaN without a round
    in which both ran."""
    pairs = [x / y for x, y in zip(a.get("walls", []), b.get("walls", []))
             if x is not None and y is not None]
    return float(np.median(pairs)) if pairs else float("nan")


def head_to_head(folder: Path, splats: Path, mesh_path: Path, repeat: int, log) -> dict:
    """The three conversions of the same PLY, side by side (interleaved rounds)."""
    res: dict = {}
    commands: dict[str, tuple[list[str], Path | None]] = {}
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
    ``rounds`` interleaved rounds of the four commands (:func:`_median_runs`), medians, and
    each anchored conversion's :func:`paired_ratio` to the plain one."""
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
        anchored_obj = d / "anchored-obj.glb"
        runs: dict[str, tuple[list[str], Path | None]] = {
            "plain": (_python("gsverse_format.cli.convert", str(splats), str(plain), "--plain",
                              "-q", "-w"), plain),
            "anchored": (_python("gsverse_format.cli.convert", str(splats), str(anchored),
                                 "--mesh", str(mesh_path), "-q", "-w"), anchored),
            "anchored_obj": (_python("gsverse_format.cli.convert", str(splats),
                                     str(anchored_obj), "--mesh", str(d / "mesh.obj"), "-q",
                                     "-w"), anchored_obj),
            # validates the anchored output of the same round, or of the round before
            "validate": (_python("gsverse_format.validators.cli", str(anchored)), None),
        }
        res = _median_runs(runs, rounds, 3 * splats.stat().st_size)
        for key, r in res.items():
            if "error" in r:
                row[f"{key}_error"] = r["error"][-500:]
                continue
            row[f"{key}_s"] = r["wall_s"]
            row[f"{key}_us_per_splat"] = r["wall_s"] / n * 1e6
            row[f"{key}_peak_rss_mb"] = r["peak_rss_mb"]
            if key.startswith("anchored") and "wall_s" in res["plain"]:
                row[f"{key}_over_plain"] = paired_ratio(r, res["plain"])
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
            ratios["plain_over_splat_transform"] = paired_ratio(plain, st)
        if "wall_s" in plain and "wall_s" in anchored:
            ratios["anchored_over_plain"] = paired_ratio(anchored, plain)
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
