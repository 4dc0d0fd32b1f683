"""``gsverse-convert`` end to end against reading and writing the same files alone.

Input: a 3DGS PLY (SH degree 3) of surface splats on a bumpy bar and the bar's mesh as a binary
PLY (``--quick``: 20k splats, ~6k faces; full: 500k splats, ~41k faces). Timed:

* ``gsverse-convert splats.ply out.glb --mesh mesh.ply`` as a fresh process (interpreter start,
  imports, reading, binding, writing), with its peak resident memory;
* the same conversion in-process (:func:`gsverse_format.pipeline.convert`, imports done);
* reading the input PLY, reading the mesh and writing the converted asset's GLB, each alone
  (in-process), and all three together in a fresh process with its peak resident memory.

The difference between the conversion and the plain reading + writing is what anchoring costs
(nearest-triangle binding, sorting by face, the rest-pose check).
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from .timing import measure

_IO_SNIPPET = """
import sys, time
from gsverse_format.io.ply import read_splat_ply
from gsverse_format.io.mesh import read_mesh
from gsverse_format.io.gltf import read_gltf, write_gltf
t0 = time.perf_counter()
asset = read_gltf(sys.argv[3])
t1 = time.perf_counter()
read_splat_ply(sys.argv[1]); read_mesh(sys.argv[2]); write_gltf(asset, sys.argv[4])
print(t1 - t0, time.perf_counter() - t1)
"""


def _vm_hwm_kib(pid: int) -> int | None:
    try:
        with open(f"/proc/{pid}/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1])
    except (OSError, ValueError):
        pass
    return None


def run_process(args: list[str], cwd: str | None = None, env: dict | None = None) -> dict:
    """Run a command; wall seconds, exit status, peak RSS (MiB) and its output.

    The peak is the child's own high-water mark (``VmHWM`` in ``/proc/<pid>/status``, polled
    every 20 ms until it exits). ``ru_maxrss`` from ``wait4`` is not used: on Linux a child
    started by fork/exec inherits the parent's peak in it.
    """
    t0 = time.perf_counter()
    peak = None
    with tempfile.TemporaryFile() as out:
        p = subprocess.Popen(args, stdout=out, stderr=subprocess.STDOUT, cwd=cwd, env=env)
        while True:
            pid, status, usage = os.wait4(p.pid, os.WNOHANG)
            if pid:
                break
            hwm = _vm_hwm_kib(p.pid)
            if hwm is not None:
                peak = hwm if peak is None else max(peak, hwm)
            time.sleep(0.02)
        p.returncode = os.waitstatus_to_exitcode(status)
        wall = time.perf_counter() - t0
        out.seek(0)
        text = out.read().decode("utf-8", "replace")
    return {"wall_s": wall, "rc": p.returncode,
            "peak_rss_mb": (peak / 1024.0) if peak is not None else float("nan"), "output": text}


def run(quick: bool = False, log=print, workdir: str | None = None) -> dict:
    from gsverse_format.pipeline import ConvertOptions, convert
    from gsverse_format.io.gltf import read_gltf, write_gltf
    from gsverse_format.io.mesh import read_mesh
    from gsverse_format.io.ply import read_splat_ply, write_splat_ply
    from gsverse_format.model import SplatCloud

    from .accuracy import bar_mesh, surface_object

    t_start = time.perf_counter()
    n = 20_000 if quick else 500_000
    mesh = bar_mesh(48, 60) if quick else bar_mesh(128, 160)
    cloud = surface_object(mesh, n, seed=3)
    rng = np.random.default_rng(4)
    cloud = SplatCloud(cloud.means, cloud.rotations, cloud.scales, rng.uniform(0.1, 1.0, n),
                       rng.normal(0, 0.3, (n, 16, 3)))
    tmp = tempfile.TemporaryDirectory(dir=workdir)
    d = Path(tmp.name)
    splats, mesh_path, out, out2 = d / "splats.ply", d / "mesh.ply", d / "out.glb", d / "io.glb"
    write_splat_ply(cloud, splats)
    import trimesh

    trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).export(mesh_path)
    log(f"convert: {n} splats, {mesh.face_count} faces")
    res = {"n_splats": n, "n_faces": mesh.face_count,
           "input_mb": splats.stat().st_size / 2**20}
    cmd = [sys.executable, "-c", "from gsverse_format.cli.convert import main; raise SystemExit(main())",
           str(splats), str(out), "--mesh", str(mesh_path), "-q", "-w"]
    runs = [run_process(cmd) for _ in range(1 if quick else 3)]
    if any(r["rc"] != 0 for r in runs):
        res["error"] = runs[-1]["output"][-2000:]
        tmp.cleanup()
        return res
    res["cli_wall_s"] = float(np.median([r["wall_s"] for r in runs]))
    res["cli_peak_rss_mb"] = max(r["peak_rss_mb"] for r in runs)
    res["output_mb"] = out.stat().st_size / 2**20
    baseline = [sys.executable, "-c", _IO_SNIPPET, str(splats), str(mesh_path), str(out), str(out2)]
    io_runs = [run_process(baseline) for _ in range(1 if quick else 3)]
    res["io_process_peak_rss_mb"] = max(r["peak_rss_mb"] for r in io_runs)
    # The baseline process also reads the converted GLB (to have the asset to write); that
    # reading is measured inside it and taken out of its wall time.
    extra = [float(r["output"].strip().splitlines()[-1].split()[0]) for r in io_runs]
    inner = [float(r["output"].strip().splitlines()[-1].split()[1]) for r in io_runs]
    res["io_process_wall_s"] = float(np.median([r["wall_s"] - e for r, e in zip(io_runs, extra)]))
    res["io_process_inner_s"] = float(np.median(inner))
    empty = run_process([sys.executable, "-c", "import gsverse_format.cli.convert"])
    res["import_s"] = empty["wall_s"]

    reps = 1 if quick else 3
    t = measure(lambda: convert(str(splats), str(out), ConvertOptions(mesh=str(mesh_path))),
                repeat=1, batches=reps, warmup=1)
    res["convert_s"] = t.median
    res["convert_contended"] = t.contended
    asset = read_gltf(out)
    t_ply = measure(lambda: read_splat_ply(splats), repeat=1, batches=reps, warmup=1)
    t_mesh = measure(lambda: read_mesh(mesh_path), repeat=1, batches=reps, warmup=1)
    t_glb = measure(lambda: write_gltf(asset, out2), repeat=1, batches=reps, warmup=1)
    res["read_ply_s"], res["read_mesh_s"], res["write_glb_s"] = t_ply.median, t_mesh.median, t_glb.median
    res["io_s"] = t_ply.median + t_mesh.median + t_glb.median
    res["overhead_ratio"] = res["convert_s"] / res["io_s"]
    res["seconds"] = time.perf_counter() - t_start
    tmp.cleanup()
    log(f"convert: done in {res['seconds']:.1f} s")
    return res
