"""Validation time of large anchored assets: ``python -m benchmarks.validate [--quick]``.

Builds anchored GLBs (and, with usd-core installed, the same assets as binary ``.usdc``) of
1,000,000 splats (``--quick``: 20,000) on a closed mesh of about 82k
triangles, with a rest pose that is exactly the remap at rest (so every check runs to the end,
the rest-pose comparison included), writes them to a temporary folder, and times
:func:`gsverse_format.validators.validate.validate_file` on each: the full validation of the
file from disk (parsing, bounds, every value check, the anchor mesh's degenerate/sliver/
duplicate analysis and the rest-pose consistency check of every splat).

Prints one row per asset and format: profile, SH degree, splats, triangles, file size, the
median and best wall time of the timed runs and the median CPU time per run of this process
and its children (seconds; USD files are parsed in a child process; validation is
single-threaded, so on a busy machine the CPU time is the better estimate of the uncontended
wall time), and the number of findings (0 expected). The target is ≤ 1 s for 1M splats in a
GLB. Timings taken while other processes kept the CPU busy are flagged.
"""
from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time

import numpy as np

from benchmarks.timing import measure
from gsverse_format import quaternion as quat
from gsverse_format.frames import games_frames, local_frames
from gsverse_format.io.gltf import write_gltf
from gsverse_format.model import (Anchoring, GamesAnchors, LocalAnchors, SplatAsset, SplatCloud,
                                  SplatPrimitive, TriangleMesh)


def _mesh(subdivisions: int) -> TriangleMesh:
    import trimesh

    ico = trimesh.creation.icosphere(subdivisions=subdivisions)
    rng = np.random.default_rng(0)
    v = ico.vertices * (1.0 + 0.05 * rng.uniform(-1, 1, (len(ico.vertices), 1)))
    return TriangleMesh(v, ico.faces)


def anchored_asset(n: int, *, profile: str = "local", sh_degree: int = 0,
                   subdivisions: int = 6, seed: int = 0) -> SplatAsset:
    """``n`` splats anchored to a bumpy sphere, sorted by face; rest pose = remap at rest."""
    mesh = _mesh(subdivisions)
    rng = np.random.default_rng(seed)
    face = np.sort(rng.integers(0, mesh.face_count, n)).astype(np.uint32)
    bary = rng.dirichlet([2, 2, 2], n)[:, 1:].astype(np.float32)
    tri = mesh.triangles()
    k = (sh_degree + 1) ** 2
    sh = rng.normal(0, 0.2, (n, k, 3)).astype(np.float32)
    opacity = rng.uniform(0.1, 1.0, n).astype(np.float32)
    b = bary.astype(np.float64)
    if profile == "games":
        rho = rng.uniform(0.2, 1.5, n).astype(np.float32)
        rotation, base, _ = games_frames(tri)
        v = tri[face]
        means = v[:, 0] + b[:, :1] * (v[:, 1] - v[:, 0]) + b[:, 1:] * (v[:, 2] - v[:, 0])
        scales = np.maximum(rho.astype(np.float64)[:, None] * base[face], 0.0) + 1e-8
        rotations = quat.from_matrix(rotation)[face]
        anchors = GamesAnchors(face, bary, rho)
    else:
        frames = local_frames(tri)
        offset = rng.normal(0, 0.002, n).astype(np.float32)
        q_local = quat.canonical_sign(quat.normalize(rng.normal(size=(n, 4)))).astype(np.float32)
        s_local = rng.uniform(0.002, 0.01, (n, 3)).astype(np.float32)
        v = tri[face]
        means = (v[:, 0] + b[:, :1] * (v[:, 1] - v[:, 0]) + b[:, 1:] * (v[:, 2] - v[:, 0])
                 + offset.astype(np.float64)[:, None] * frames.rotation[face, :, 2])
        rotations = quat.multiply(quat.from_matrix(frames.rotation)[face], q_local)
        scales = s_local
        anchors = LocalAnchors(face, bary, offset, q_local, s_local, "affine")
    cloud = SplatCloud(means, rotations, scales, opacity, sh)
    return SplatAsset([SplatPrimitive(cloud, Anchoring(mesh, anchors), "bench")])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.validate",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="20,000 splats (a smoke run)")
    parser.add_argument("--splats", type=int, default=None, help="splats per asset")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs per batch")
    args = parser.parse_args(argv)
    from gsverse_format.validators.validate import validate_file

    n = args.splats or (20_000 if args.quick else 1_000_000)
    cases = [("local/affine", 0), ("games", 0), ("local/affine", 3)]
    if args.quick:
        cases = cases[:2]
    writers = [(".glb", write_gltf)]
    try:
        from gsverse_format.io.usd import write_usd

        import pxr  # noqa: F401  (usd-core is optional)
        writers.append((".usdc", write_usd))
    except ImportError:
        pass
    print(f"gsverse-validate: validation time of anchored assets ({os.cpu_count()} CPUs)")
    print(f"{'asset':<14} {'SH':>2} {'format':<6} {'splats':>9} {'triangles':>9} {'file MB':>8} "
          f"{'median s':>9} {'best s':>7} {'CPU s':>6} {'findings':>8}")
    with tempfile.TemporaryDirectory(prefix="gsverse-bench-") as tmp:
        for label, degree in cases:
            asset = anchored_asset(n, profile=label.split("/")[0], sh_degree=degree)
            tri = asset.primitives[0].anchoring.mesh.face_count
            for suffix, write in writers:
                path = os.path.join(tmp, f"{label.replace('/', '_')}_sh{degree}{suffix}")
                write(asset, path)
                _time_one(validate_file, path, label, degree, suffix, n, tri, args.repeat)
                os.unlink(path)
            del asset
    return 0


def _cpu_seconds() -> float:
    """CPU time of this process and its finished children (USD is parsed in a child)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def _time_one(validate_file, path: str, label: str, degree: int, suffix: str, n: int,
              tri: int, repeat: int) -> None:
    report = validate_file(path)
    cpu: list[float] = []

    def run() -> None:
        c0 = _cpu_seconds()
        validate_file(path)
        cpu.append(_cpu_seconds() - c0)

    timing = measure(run, repeat=repeat, batches=2, warmup=0, retry_contended=1)
    size = os.path.getsize(path) / 2 ** 20
    flag = " (CPU contended)" if timing.contended else ""
    print(f"{label:<14} {degree:>2} {suffix[1:]:<6} {n:>9,} {tri:>9,} {size:>8.1f} "
          f"{timing.median:>9.3f} {timing.best:>7.3f} {float(np.median(cpu)):>6.3f} "
          f"{len(report.findings):>8}{flag}")
    for f in report.findings[:5]:
        print(f"    {f.code}: {f.message}")


if __name__ == "__main__":
    sys.exit(main())
