"""``python -m benchmarks``: speed, accuracy and memory of gsverse-format, as one report.

Writes ``report.md``, PNG plots and ``results.json`` into ``--out`` (default
``benchmark-report/``). ``--quick`` runs a small version of everything (about a minute; CI runs
it to check that the benchmarks work, not their timings).

Sections: remap speed (numpy reference and fast path against the memory-bandwidth floor),
nearest-triangle binding against Open3D and trimesh (``benchmarks/binding.py``, run as a
separate process), ``gsverse-convert`` end to end against PlayCanvas splat-transform with its
scaling (``--sizes``),
validation time (``benchmarks/validate.py``, a separate process), the refusal of hostile
inputs against the readers' limits (``benchmarks/hostile.py``, a separate process), the file
size of anchored assets against plain KHR (``benchmarks/size.py``, a separate process), peak
memory, accuracy against analytic deformations across profiles, anchor resolutions and
quantizations with the cost of each point, the stretch comparison with a VR-GS-style cage,
the CPU renderer's speed with the remap's accuracy in image space (PSNR/SSIM,
``benchmarks/render.py``), and the remap and the deformed sort in each web engine plugin as
ratios to the engine's own splat pass, with the GPU rows (``benchmarks/engines.py``: headless
Chromium run by node as a separate process).
"""
from __future__ import annotations

import argparse
import datetime
import os
import platform
import resource
import sys
import time
from pathlib import Path

SECTIONS = ("remap", "binding", "convert", "validate", "hostile", "size", "accuracy", "render",
            "engines")
HERE = Path(__file__).resolve().parent


def _meta(argv: list[str], quick: bool) -> dict:
    cpu = platform.processor() or platform.machine()
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        mem = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    except (ValueError, OSError, AttributeError):
        mem = float("nan")
    from importlib.metadata import PackageNotFoundError, version

    versions = {}
    #: module -> the distributions that install it (Open3D also comes as ``open3d-cpu``)
    distributions = {"numpy": ("numpy",), "scipy": ("scipy",), "numba": ("numba",),
                     "trimesh": ("trimesh",), "matplotlib": ("matplotlib",),
                     "open3d": ("open3d", "open3d-cpu")}
    for mod, names in distributions.items():
        versions[mod] = "absent"
        for name in names:
            try:
                versions[mod] = version(name) + ("" if name == mod else f" ({name})")
                break
            except PackageNotFoundError:
                continue
    try:
        import numba

        versions["numba threads"] = str(numba.config.NUMBA_NUM_THREADS)
    except Exception:
        pass
    return {"command": " ".join(["python -m benchmarks", *argv]), "quick": quick, "cpu": cpu,
            "cores": os.cpu_count(), "memory_gib": mem, "python": platform.python_version(),
            "versions": versions, "date": datetime.datetime.now().astimezone().isoformat(timespec="minutes")}


def _external(module: str, args: list[str], log) -> dict:
    """Run ``python -m benchmarks.<module> args`` (another benchmark script) and keep its
    Markdown output, wall time and peak memory."""
    from .processes import run_process

    if not (HERE / f"{module}.py").is_file():
        return {"missing": f"benchmarks/{module}.py"}
    cmd = [sys.executable, "-m", f"benchmarks.{module}", *args]
    log(f"{module}: running `{' '.join(['python', '-m', f'benchmarks.{module}', *args])}`")
    from . import child_env

    res = run_process(cmd, cwd=str(HERE.parent), env=child_env(benchmarks=True))
    res["command"] = " ".join(["python", "-m", f"benchmarks.{module}", *args])
    log(f"{module}: done in {res['wall_s']:.1f} s (exit {res['rc']})")
    return res


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    p = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__.split("\n")[0])
    p.add_argument("--out", default="benchmark-report", help="output folder (default: benchmark-report)")
    p.add_argument("--quick", action="store_true", help="small sizes (about a minute)")
    p.add_argument("--only", nargs="+", choices=SECTIONS, help="run only these sections")
    p.add_argument("--skip", nargs="+", choices=SECTIONS, default=[], help="skip these sections")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    from .convert import SIZES as convert_sizes

    p.add_argument("--sizes", nargs="+", choices=list(convert_sizes),
                   help="splat counts of the convert/validate scaling table (default 100k 1M 4M)")
    args = p.parse_args(argv)
    log = (lambda *a, **k: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr, flush=True))
    sections = [s for s in (args.only or SECTIONS) if s not in args.skip]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    res: dict = {}
    quick = args.quick
    if "remap" in sections:
        from . import remap

        res["remap"] = remap.run(quick, log)
    if "binding" in sections:
        res["binding"] = _external("binding", ["--quick", "--points", "20000", "--faces", "20000"]
                                   if quick else [], log)
    if "convert" in sections:
        from . import convert

        res["convert"] = convert.run(quick, log, sizes=args.sizes)
    if "validate" in sections:
        res["validate"] = _external("validate", ["--quick"] if quick else [], log)
    if "hostile" in sections:
        res["hostile"] = _external("hostile", ["--quick"] if quick else [], log)
    if "size" in sections:
        res["size"] = _external("size", ["--quick"] if quick else [], log)
    if "accuracy" in sections:
        from . import accuracy

        res["accuracy"] = accuracy.run(quick, log)
    if "render" in sections:
        from . import render

        res["render"] = render.run(quick, log)
    if "engines" in sections:
        from . import engines

        res["engines"] = engines.run(quick, log)
    res["self_peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    res["meta"] = _meta(argv, quick)
    res["meta"]["seconds"] = time.perf_counter() - t0
    from .report import write_report

    path = write_report(res, out)
    log(f"report: {path} ({res['meta']['seconds']:.0f} s)")
    print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
