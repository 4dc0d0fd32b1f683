"""The remap and the deformed sort in each engine plugin, as ratios to the engine's own splat pass.

    python -m benchmarks.engines [--quick] [--sizes 100k 1M] [--rounds N]

Runs ``plugins/web/bench/engines.mjs --json`` (node, headless Debian Chromium through the
conformance run's launch helper) as a separate process: for PlayCanvas and for three.js + Spark,
at each size, rounds of three interleaved frames on the synthetic tube of
``plugins/web/bench/page/synthetic.js`` (affine law, canvas 256 x 256):

* static frame: one rendered frame of the splats as they are: the engine's own per-frame splat
  work (its update and the draw of every splat; the camera stands still, so nothing is sorted),
  fenced by a 1-pixel readback of the canvas;
* remap: PlayCanvas, a remapped frame (a new pose: the vertex upload and the engine's
  work-buffer copy of every splat through the remap chunk, then the same draw) minus the static
  frame of its round (the copy runs inside the frame); Spark, its regeneration of every splat
  with the remap as the mesh's object modifier, timed on its own (Spark runs it apart from the
  draw) and fenced by the same readback;
* sort: the order by the deformed positions (PlayCanvas: the deformed means into its sort
  centres on the CPU plus its worker's sort; Spark: its readback of the depths, its worker's
  sort and the upload of the order).

Medians over rounds; the ratios remap / static and sort / static are the result, the
milliseconds context: without a GPU, Chromium draws through SwiftShader on the CPU cores.

GPU rows: the web shaders on a real GPU (the same benchmark with Chromium asked for the GPU,
``--gpu``; filled when its WebGL renderer is not a software one) and the native kernels
(``benchmarks/kernels.py``) on a Vulkan device that is not a CPU; otherwise each row says why
it is empty. This is a benchmark, not a test: when node, Chromium or the plugin's npm packages
are missing, the section says so instead of failing.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

_ROOT = Path(__file__).resolve().parents[1]
WEB = _ROOT / "plugins" / "web"
SCRIPT = WEB / "bench" / "engines.mjs"
#: npm packages of plugins/web the benchmark loads (node side and page side)
PACKAGES = ("playwright-core", "playcanvas", "three", "@sparkjsdev/spark")
#: WebGL / Vulkan device names of software rasterizers (the renderer strings Chromium reports)
SOFTWARE = re.compile(r"swiftshader|llvmpipe|lavapipe|softpipe|software|basic render", re.I)
#: wall-clock limit of one node run, seconds (1M splats on SwiftShader take minutes)
TIMEOUT_S = 3600


def missing() -> str | None:
    """Why the browser benchmark cannot run here, or None."""
    if shutil.which("node") is None:
        return "node is not installed"
    chromium = os.environ.get("CHROMIUM", "/usr/bin/chromium")
    if not os.access(chromium, os.X_OK):
        return f"Chromium is not installed ({chromium}; Debian: chromium, or set $CHROMIUM)"
    if not SCRIPT.is_file():
        return f"{SCRIPT.relative_to(_ROOT)} is not present in this checkout"
    absent = [p for p in PACKAGES if not (WEB / "node_modules" / p / "package.json").is_file()]
    if absent:
        return f"npm packages missing in plugins/web ({', '.join(absent)}; run `npm ci` there)"
    return None


def software(renderer: str) -> bool:
    """True when a WebGL or Vulkan device name is a software rasterizer's."""
    return bool(SOFTWARE.search(renderer or ""))


def ratio(x: float) -> str:
    """A ratio for the tables: two decimals, three below 0.1 (a sort at 1 % of a frame)."""
    return f"{x:.2f}" if abs(x) >= 0.1 else f"{x:.3f}"


def _node(args: list[str], log) -> dict:
    cmd = ["node", str(SCRIPT.relative_to(WEB)), "--json", *args]
    log(f"engines: running `{' '.join(cmd)}` in plugins/web")
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, cwd=WEB, capture_output=True, text=True, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return {"error": f"no result within {TIMEOUT_S} s", "command": " ".join(cmd)}
    wall = time.perf_counter() - t0
    log(f"engines: done in {wall:.1f} s (exit {p.returncode})")
    if p.returncode != 0:
        last = (p.stderr.strip().splitlines() or ["(no message)"])[-1]
        return {"error": f"exit status {p.returncode}: {last}", "command": " ".join(cmd)}
    out = json.loads(p.stdout)
    out.update(command=" ".join(cmd), wall_s=wall)
    return out


def vulkan_devices() -> list[tuple[str, str]] | None:
    """(device name, device type) of every Vulkan device ``vulkaninfo --summary`` lists, or
    None without vulkaninfo."""
    if shutil.which("vulkaninfo") is None:
        return None
    try:
        p = subprocess.run(["vulkaninfo", "--summary"], capture_output=True, text=True, timeout=60)
    except subprocess.TimeoutExpired:
        return None
    types = re.findall(r"deviceType\s*=\s*(\S+)", p.stdout)
    names = [n.strip() for n in re.findall(r"deviceName\s*=\s*(.+)", p.stdout)]
    return list(zip(names, types))


def _web_gpu_row(gpu: dict) -> dict:
    if gpu.get("error"):
        return {"target": "web shaders (WebGL2)", "device": "–",
                "result": f"not run: Chromium asked for the GPU failed ({gpu['error']})"}
    renderer = gpu["backends"][0]["renderer"] if gpu.get("backends") else ""
    if not gpu.get("rows"):
        return {"target": "web shaders (WebGL2)", "device": renderer,
                "result": "empty: no GPU on this machine (Chromium asked for the GPU renders "
                          "through a software rasterizer)"}
    return {"target": "web shaders (WebGL2)", "device": renderer, "rows": gpu["rows"],
            "result": "; ".join(f"{r['engine']} {r['n']:,}: remap / static {ratio(r['remapRatio'])}, "
                                f"sort / static {ratio(r['sortRatio'])}, static {r['baseMs']:.2f} ms"
                                for r in gpu["rows"])}


def _native_gpu_row() -> dict:
    devices = vulkan_devices()
    target = "native kernels (GLSL/HLSL, Vulkan)"
    if devices is None:
        return {"target": target, "device": "–", "result": "empty: vulkaninfo is not installed"}
    gpus = [(n, t) for n, t in devices if not t.endswith("_CPU") and not software(n)]
    if not gpus:
        names = ", ".join(n for n, _ in devices) or "none"
        return {"target": target, "device": names,
                "result": "empty: no GPU on this machine (the Vulkan devices are CPU ones: "
                          "the kernels run on lavapipe, see the kernels table of BENCHMARKS.md)"}
    return {"target": target, "device": ", ".join(n for n, _ in gpus),
            "result": "not timed: a GPU is present, but the kernels' Vulkan host "
                      "(tests/native_kernels.py) opens lavapipe only"}


def run(quick: bool, log=print, sizes: list[int] | None = None, rounds: int | None = None) -> dict:
    """The engine rows and the GPU rows (see the module docstring)."""
    sizes = sizes or ([10_000, 30_000] if quick else [100_000, 1_000_000])
    rounds = rounds or (3 if quick else 5)
    why = missing()
    res: dict = {"sizes": sizes, "rounds": rounds}
    if why:
        log(f"engines: skipped: {why}")
        res["skipped"] = why
        res["gpu_rows"] = [{"target": "web shaders (WebGL2)", "device": "–", "result": f"not run: {why}"},
                           _native_gpu_row()]
        return res
    args = ["--sizes", ",".join(map(str, sizes)), "--rounds", str(rounds)]
    res.update(_node(args, log))
    res["gpu_rows"] = [_web_gpu_row(_node([*args, "--gpu"], log)), _native_gpu_row()]
    return res


def markdown(res: dict) -> list[str]:
    L = ["## Engines: the remap and the deformed sort against the engine's own splat pass", ""]
    if res.get("skipped"):
        L += [f"Skipped: {res['skipped']}.", ""]
    elif res.get("error"):
        L += [f"`{res['command']}` failed: {res['error']}", ""]
    else:
        L.append(f"`{res['command']}` in plugins/web (a separate process: {res['wall_s']:.0f} s). "
                 f"Median of {res['rounds']} rounds of interleaved frames per row. Static frame: one "
                 "rendered frame of the same splats with no remap (the engine's own per-frame splat "
                 "work, fenced by a 1-pixel readback); remap: PlayCanvas, a remapped frame (new pose "
                 "uploaded, every splat copied through the remap) minus the static frame of its "
                 "round; Spark, its regeneration of every splat through the remap, fenced; sort: the "
                 "order by the deformed positions (PlayCanvas: sort centres on the CPU + its "
                 "worker's sort; Spark: depth readback + its worker's sort). The ratios are the "
                 "result; the milliseconds are those of the device named below.")
        L.append("")
        for b in res.get("backends", []):
            L.append(f"- {b['engine']}: {b['device']}, {b['renderer']}, canvas {b['canvas']}, "
                     f"{b['cores']} CPU cores")
        L.append("")
        L.append("| engine | splats | static frame ms | remap ms | remap / static | sort ms | sort / static |")
        L.append("|---|---|---|---|---|---|---|")
        for r in res.get("rows", []):
            L.append(f"| {r['engine']} | {r['n']:,} | {r['baseMs']:.1f} | {r['remapMs']:.1f} | "
                     f"{ratio(r['remapRatio'])} | {r['sortMs']:.1f} | {ratio(r['sortRatio'])} |")
        L.append("")
    L += ["GPU rows:", "", "| target | device | result |", "|---|---|---|"]
    for g in res.get("gpu_rows", []):
        L.append(f"| {g['target']} | {g['device']} | {g['result']} |")
    L.append("")
    return L


def _size(text: str) -> int:
    t = text.lower().replace("_", "")
    scale = {"k": 1_000, "m": 1_000_000}.get(t[-1:], 1)
    return int(float(t[:-1] if scale > 1 else t) * scale)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.engines", description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="10k and 30k splats, 3 rounds")
    p.add_argument("--sizes", nargs="+", help="splat counts (default 100k 1M)")
    p.add_argument("--rounds", type=int, help="rounds per row (default 5, quick 3)")
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    args = p.parse_args(argv)
    sizes = [_size(s) for s in args.sizes] if args.sizes else None
    res = run(args.quick, log=lambda line: print(line, file=sys.stderr), sizes=sizes, rounds=args.rounds)
    print(json.dumps(res, indent=1) if args.json else "\n".join(markdown(res)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
