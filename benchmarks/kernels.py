"""Per-frame cost of the compute kernels of native/kernels/ (GLSL 450 and HLSL) on lavapipe.

    python -m benchmarks.kernels [--sizes 100k 1M] [--quick]

Workload: the remap benchmark's (``benchmarks/remap.py``): a bent and waved grid of 100,000
faces, 100,000 and 1,000,000 splats with random anchors sorted by face, every profile and law;
``--quick``: 10,000 and 100,000 splats on 10,000 faces. Each kernel is compiled by glslang and
run by the Vulkan host of the conformance harness (``tests/native_kernels.py``) on Mesa's
lavapipe, the device named in the table. One frame = upload the deformed anchor vertices,
dispatch every splat, wait for the fence (the outputs stay on the device; reading them back is
not part of a frame). lavapipe runs the shader on the CPU cores (LLVM-compiled, SIMD lanes as
invocations), so the numbers say what software Vulkan costs on this machine, not what a GPU
costs. Timings are medians over repetitions (``benchmarks/timing.py``; a full run waits up to
20 s per row for a batch that other processes leave quiet). The first frame's
outputs are compared with the float64 reference (max |Δμ|) so that the table is of a remap that
is right. Prints a Markdown table; needs glslang, lavapipe and libvulkan
(``scripts/native-conformance --install``).
"""
from __future__ import annotations

import argparse
import ctypes
import importlib.util
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

from gsverse_format.model import Anchoring
from gsverse_format.remapping.reference import remap_moments

from .remap import deformed, grid_mesh, random_anchors
from .timing import measure

_ROOT = Path(__file__).resolve().parents[1]
PROFILES = ("local/affine", "local/rigid", "games")


def _harness():
    """tests/native_kernels.py, the conformance harness of the kernels (its compiler, host
    and buffer layout)."""
    spec = importlib.util.spec_from_file_location("native_kernels",
                                                  _ROOT / "tests" / "native_kernels.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _buffers(nk, lib, mesh, anchors, profile: str) -> dict[int, np.ndarray]:
    """Bindings 0 and 2..8 of the kernels for one workload (rest quantities in double; the
    covariance outputs only)."""
    n = len(anchors.face_index)
    idx = np.ascontiguousarray(mesh.faces.reshape(-1), np.uint32)
    games = profile == "games"
    out = {0: np.array([n, 0, 1 if games else 0, 1 if profile == "local/rigid" else 0, 0],
                       np.uint32),
           2: idx, 4: np.ascontiguousarray(anchors.face_index, np.uint32),
           5: np.ascontiguousarray(anchors.barycentrics, np.float32)}
    if games:
        out.update({3: np.zeros(8, np.float32), 6: np.ascontiguousarray(anchors.rho, np.float32),
                    7: np.zeros(4, np.float32), 8: np.zeros(3, np.float32)})
        return out
    rest_v = np.ascontiguousarray(mesh.vertices, np.float32)
    rest = np.zeros(mesh.face_count * lib.gsv_sizeof_rest_face(), np.uint8)
    lib.gsv_prepare_rest(rest_v.ctypes.data_as(ctypes.c_void_p),
                         idx.ctypes.data_as(ctypes.c_void_p), mesh.face_count,
                         rest.ctypes.data_as(ctypes.c_void_p))
    q = np.asarray(anchors.local_rotation, np.float64)
    q = (q / np.linalg.norm(q, axis=1, keepdims=True)).astype(np.float32)
    out.update({3: nk.rest_buffer(lib, rest, mesh.face_count),
                6: np.ascontiguousarray(anchors.normal_offset, np.float32), 7: q,
                8: np.ascontiguousarray(anchors.local_scale, np.float32)})
    return out


def run(sizes: list[int], quick: bool = False, log=print) -> list[dict]:
    nk = _harness()
    missing = nk.missing_tools()
    if missing:
        raise SystemExit("benchmarks.kernels: missing " + ", ".join(missing))
    mesh = grid_mesh(50, 100) if quick else grid_mesh(250, 200)
    verts = np.ascontiguousarray(deformed(mesh), np.float32)
    rows = []
    with tempfile.TemporaryDirectory(prefix="gsv-kernel-bench-") as tmp:
        folder = Path(tmp)
        lib = nk.build(folder, real="double")
        host = nk.build_host(folder)
        for language in nk.KERNEL_LANGUAGES:
            kernel = nk.Kernel(host, nk.compile_kernel(language, folder))
            try:
                for profile in PROFILES:
                    for n in sizes:
                        anchors = random_anchors(mesh, n, profile)
                        for binding, array in _buffers(nk, lib, mesh, anchors, profile).items():
                            kernel.upload(binding, array)
                        kernel.upload(9, np.zeros((n, 3), np.float32))
                        kernel.upload(10, np.zeros((n, 6), np.float32))

                        def frame():
                            kernel.upload(1, verts)
                            kernel.dispatch(n)

                        frame()
                        ref_means, _ = remap_moments(Anchoring(mesh, anchors), verts.astype(np.float64))
                        err = float(np.max(np.abs(kernel.download(9, (n, 3)) - ref_means)))
                        t = measure(frame, repeat=3, batches=2, warmup=1, min_quiet=0 if quick else 1,
                                    max_wait_s=0.0 if quick else 20.0)
                        row = {"kernel": language.upper(), "device": f"lavapipe: {kernel.device}",
                               "profile": profile, "splats": n, "faces": mesh.face_count,
                               "ms": 1e3 * t.median, "best_ms": 1e3 * t.best,
                               "contended": t.contended, "max_mean_error": err}
                        rows.append(row)
                        log(f"kernels: {language} {profile} {n}: {row['ms']:.1f} ms/frame")
            finally:
                kernel.close()
    return rows


def table(rows: list[dict]) -> str:
    lines = ["| kernel | device | profile | splats | faces | ms / frame (median) | best ms | "
             "M splats/s | max abs Δμ vs float64 |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        mark = " †" if r["contended"] else ""
        lines.append(f"| {r['kernel']} | {r['device']} | {r['profile']} | {r['splats']:,} | "
                     f"{r['faces']:,} | {r['ms']:.1f}{mark} | {r['best_ms']:.1f} | "
                     f"{r['splats'] / r['ms'] / 1e3:.1f} | {r['max_mean_error']:.1e} |")
    return "\n".join(lines)


def _size(text: str) -> int:
    t = text.lower().replace("_", "")
    scale = {"k": 1_000, "m": 1_000_000}.get(t[-1:], 1)
    return int(float(t[:-1] if scale > 1 else t) * scale)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", nargs="+", default=None, help="splat counts (default 100k 1M)")
    p.add_argument("--quick", action="store_true", help="10k and 100k splats on 10k faces")
    args = p.parse_args(argv)
    sizes = [_size(s) for s in args.sizes] if args.sizes else (
        [10_000, 100_000] if args.quick else [100_000, 1_000_000])
    rows = run(sizes, args.quick, log=lambda line: print(line, file=sys.stderr))
    print(f"cores: {os.cpu_count()}; † = other processes kept the CPU busy during every batch")
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.path.insert(0, os.fspath(Path(__file__).resolve().parents[1]))
    raise SystemExit(main())
