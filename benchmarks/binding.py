"""Nearest-triangle binding throughput: this package against Open3D and trimesh, in one run.

Usage (from the repository root)::

    python -m benchmarks.binding             # ~1M faces, 1M points
    python -m benchmarks.binding --quick     # ~50k faces, 50k points (a smoke run, < 30 s)
    python -m benchmarks.binding --points 200000 --faces 300000 --mesh sphere

Workload: a bumpy, vertex-jittered torus (``--mesh torus``, the default; non-convex) or a bumpy
icosphere (``--mesh sphere``, subdivision level nearest to ``--faces``), and query points that
are area-weighted surface samples plus Gaussian noise with σ = 0.5 × the mean edge length.

Methods, timed side by side on the same points:

* ``gsverse_format.nearest.nearest_triangles(method="native")``: the C search, which binding
  uses (the whole call; it must give numba's results bit for bit).
* ``gsverse_format.nearest.nearest_triangles(method="numba")``: the whole call (input checks,
  BVH build and queries); its BVH build alone; and its queries alone on a prebuilt tree. The
  first call of the process (numba import and compilation, or loading the on-disk cache) is
  reported separately, and in the full run also a compilation from scratch in a subprocess.
* Open3D ``RaycastingScene.compute_closest_points`` (float32), queries only; its BVH is built
  before (the build is reported separately). Open3D is not a dependency of this package; it is
  only measured when it can be imported.
* ``trimesh.proximity.closest_point`` on a subset of the points (per-point cost extrapolated);
  its R-tree is built before timing.

After one untimed call of each, the methods are timed in rounds: every round calls each of them
once, back to back, so that all see the same load on a shared machine. The table gives the
median over rounds during which other processes used less than a quarter of a core (over all
rounds when there were none, marked †), the best round, and the range of cores other processes
used meanwhile. The ratio to Open3D is the median over rounds of the per-round ratio.

Accuracy: distances are compared with ours (float64, certified exact). Ours is also checked to
be bit-identical to the numpy reference implementation on a subset (``--verify`` points).
Faces may legitimately differ where several faces are at the same distance (shared edges and
vertices); ours returns the smallest index.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from . import child_env
from .timing import Timing, cpu_busy_seconds, measure

SIGMA_EDGES = 0.5         # query noise, in mean edge lengths
F32_EPS = 2.0 ** -24      # float32 unit roundoff


# --------------------------------------------------------------------------- workload

def bumpy_torus(faces: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Closed torus (major radius 1, minor 0.35) of about ``faces`` triangles, with smooth
    bumps and vertex jitter (irregular, slightly anisotropic triangles)."""
    rng = np.random.default_rng(seed)
    ratio = 1.0 / 0.35
    nv = max(3, int(round(np.sqrt(faces / (2 * ratio)))))
    nu = max(3, int(round(faces / (2 * nv))))
    u = 2 * np.pi * np.arange(nu) / nu
    w = 2 * np.pi * np.arange(nv) / nv
    U, W = np.meshgrid(u, w, indexing="ij")
    r = 0.35 * (1 + 0.08 * np.sin(7 * U) * np.sin(5 * W) + 0.02 * np.sin(23 * U + 11 * W))
    x = (1 + r * np.cos(W)) * np.cos(U)
    y = (1 + r * np.cos(W)) * np.sin(U)
    z = r * np.sin(W)
    v = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    v += 0.15 * (2 * np.pi * 0.35 / nv) * rng.normal(size=v.shape)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = i * nv + j
    b = ((i + 1) % nu) * nv + j
    c = ((i + 1) % nu) * nv + (j + 1) % nv
    d = i * nv + (j + 1) % nv
    f = np.concatenate([np.column_stack([a.ravel(), b.ravel(), c.ravel()]),
                        np.column_stack([a.ravel(), c.ravel(), d.ravel()])])
    return v, f.astype(np.int64)


def bumpy_sphere(faces: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Icosphere of the subdivision level whose face count (20·4^L) is nearest to ``faces``,
    with 1% radial vertex noise."""
    import trimesh

    level = int(np.clip(np.round(np.log(max(faces, 20) / 20) / np.log(4)), 0, 9))
    ico = trimesh.creation.icosphere(subdivisions=level)
    rng = np.random.default_rng(seed)
    v = ico.vertices * (1.0 + 0.01 * rng.uniform(-1, 1, size=(len(ico.vertices), 1)))
    return np.asarray(v, np.float64), np.asarray(ico.faces, np.int64)


def query_points(v: np.ndarray, f: np.ndarray, n: int, seed: int = 1):
    """Area-weighted surface samples plus N(0, (0.5 mean edge)²) noise; returns (points, edge)."""
    rng = np.random.default_rng(seed)
    tri = v[f]
    edge = float(np.mean(np.linalg.norm(tri[:, 1] - tri[:, 0], axis=1)))
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    fi = rng.choice(len(f), n, p=area / area.sum())
    bary = rng.dirichlet([1.0, 1.0, 1.0], n)
    p = np.einsum("ni,nij->nj", bary, tri[fi]) + SIGMA_EDGES * edge * rng.normal(size=(n, 3))
    return p, edge


# --------------------------------------------------------------------------- helpers

def _fmt_rate(t: Timing, n: int) -> tuple[str, str]:
    mark = " †" if t.contended else ""
    return f"{n / t.median / 1e6:.3f}{mark}", f"{n / t.best / 1e6:.3f}"


def _load(t: Timing) -> str:
    lo, hi = t.other_cores
    return f"{lo:.2f}-{hi:.2f}"


def _interleaved(fns: dict, rounds: int) -> dict[str, Timing]:
    """Time every callable once per round, in turn, so that all see the same machine load;
    each call is its own batch (with the cores other processes used meanwhile)."""
    out = {name: Timing() for name in fns}
    for _ in range(rounds):
        for name, fn in fns.items():
            busy0, own0, t0 = cpu_busy_seconds(), _own_cpu(), time.perf_counter()
            fn()
            wall = time.perf_counter() - t0
            busy1, own1 = cpu_busy_seconds(), _own_cpu()
            other = None
            if busy0 is not None and busy1 is not None and wall > 0:
                other = max(0.0, ((busy1 - busy0) - (own1 - own0)) / wall)
            out[name].samples.append(wall)
            out[name].batches.append({"samples": [wall], "other": other,
                                      "own": (own1 - own0) / wall if wall > 0 else float("nan")})
    return out


def _own_cpu() -> float:
    tm = os.times()
    return tm.user + tm.system


def _compile_from_scratch() -> float | None:
    """Seconds to import and compile the kernels in a fresh process with an empty cache."""
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(child_env(), NUMBA_CACHE_DIR=tmp)
        code = ("import time; t = time.perf_counter(); "
                "from gsverse_format.nearest import compiled; compiled.warm_up(); "
                "print(time.perf_counter() - t)")
        try:
            out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                                 text=True, timeout=600, check=True)
            return float(out.stdout.strip().splitlines()[-1])
        except (subprocess.SubprocessError, ValueError, IndexError):
            return None


_SMALL_JOB = r"""
import sys, time
import numpy as np
t0 = time.perf_counter()
from gsverse_format.nearest import nearest_triangles
level, n, method = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
import trimesh
m = trimesh.creation.icosphere(subdivisions=level)
v, f = np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)
rng = np.random.default_rng(0)
p = v[rng.integers(0, len(v), n)] + rng.normal(0, 0.05, (n, 3))
t = time.perf_counter()
nearest_triangles(p, v, f, method=method)
print(len(f), time.perf_counter() - t)
"""


def _small_jobs() -> list[str]:
    """First call in a fresh process (kernels in the on-disk cache, numba import included) of
    the compiled search against the numpy reference, at the sizes around
    ``gsverse_format.backend.NEAREST_NUMPY_BELOW`` (where ``"auto"`` switches)."""
    from gsverse_format.backend import NEAREST_NUMPY_BELOW

    lines = []
    for level, n in ((3, 3000), (4, 20000), (5, 40000)):
        cells = []
        for method in ("numba", "numpy"):
            try:
                out = subprocess.run([sys.executable, "-c", _SMALL_JOB, str(level), str(n), method],
                                     capture_output=True, text=True, timeout=600, check=True,
                                     env=child_env())
                faces, sec = out.stdout.split()[-2:]
                cells.append(f"{method} {float(sec):.2f} s")
            except (subprocess.SubprocessError, ValueError):
                cells.append(f"{method} failed")
                faces = "?"
        lines.append(f"{n:,} points × {faces} faces: " + ", ".join(cells))
    return [f"small jobs, first call in a fresh process (`auto` runs numpy below "
            f"{NEAREST_NUMPY_BELOW:,} points + faces): " + "; ".join(lines)]


# --------------------------------------------------------------------------- main

def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.binding", description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="~50k faces and 50k points (smoke run)")
    ap.add_argument("--points", type=int, default=None, help="query points (default 1,000,000)")
    ap.add_argument("--faces", type=int, default=None, help="mesh faces (default ~1,000,000)")
    ap.add_argument("--mesh", choices=("torus", "sphere"), default="torus")
    ap.add_argument("--repeat", type=int, default=None, help="timed repetitions per method")
    ap.add_argument("--trimesh-points", type=int, default=None, help="trimesh subset size")
    ap.add_argument("--verify", type=int, default=None,
                    help="points checked against the numpy reference implementation")
    ap.add_argument("--no-compile-time", action="store_true",
                    help="skip measuring a compilation from an empty cache (a fresh process)")
    ap.add_argument("--threads", type=int, default=None,
                    help="pin the process to this many CPUs (all methods) and use as many "
                         "numba threads; default: all CPUs")
    args = ap.parse_args(argv)
    if args.threads:
        # before numba or Open3D start their thread pools, which inherit the affinity
        cpus = sorted(os.sched_getaffinity(0))[:args.threads]
        os.sched_setaffinity(0, cpus)
        os.environ["NUMBA_NUM_THREADS"] = str(len(cpus))
        os.environ["OMP_NUM_THREADS"] = str(len(cpus))
    quick = args.quick
    n = args.points or (50_000 if quick else 1_000_000)
    nfaces = args.faces or (50_000 if quick else 1_000_000)
    repeat = args.repeat or (2 if quick else 5)
    n_tm = min(n, args.trimesh_points or (2_000 if quick else 20_000))
    n_ver = min(n, args.verify if args.verify is not None else (2_000 if quick else 2_000))

    v, f = bumpy_torus(nfaces) if args.mesh == "torus" else bumpy_sphere(nfaces)
    p, edge = query_points(v, f, n)
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    print(f"# Nearest-triangle binding: {args.mesh}, {len(f):,} faces, {n:,} points "
          f"(noise σ = {SIGMA_EDGES} × mean edge = {SIGMA_EDGES * edge:.3g}), "
          f"{cpus} of {os.cpu_count()} CPUs")
    print()

    rows = []          # method, Mpts/s median, best, threads, exact, max diff, agreement, load
    notes = []

    # ---- setup of every method (untimed warm-up calls), then interleaved timing rounds
    t0 = time.perf_counter()
    import numba

    from gsverse_format.nearest import compiled as nearest_compiled
    from gsverse_format.nearest import nearest_triangles
    from gsverse_format.nearest.native import _module as native_module
    from gsverse_format.nearest.native import nearest_triangles_native
    from gsverse_format.threads import native_threads
    nearest_compiled.warm_up()
    first_call = time.perf_counter() - t0
    threads = numba.get_num_threads()
    idx = np.arange(len(f))
    state: dict = {}
    from gsverse_format.binding import bind_local
    from gsverse_format.model import SplatCloud, TriangleMesh

    rng_b = np.random.default_rng(4)
    quats = rng_b.normal(size=(n, 4))
    cloud = SplatCloud(p.astype(np.float32), (quats / np.linalg.norm(quats, axis=1)[:, None]
                                              ).astype(np.float32),
                       np.full((n, 3), 0.01, np.float32), np.full(n, 0.5, np.float32),
                       np.zeros((n, 1, 3), np.float32))
    mesh_b = TriangleMesh(v.astype(np.float32), f)
    timed = {
        "bind": lambda: bind_local(cloud, mesh_b),
        "full": lambda: state.__setitem__("ref", nearest_triangles(p, v, f, method="numba")),
        "native": lambda: state.__setitem__("native",
                                            nearest_triangles(p, v, f, method="native")),
        "build": lambda: state.__setitem__("tree", nearest_compiled.build_tree(v, f, idx)),
        "query": lambda: nearest_compiled.query_tree(state["tree"], p),
    }
    native_level = native_module().level()
    if native_level > 0:
        timed["generic"] = lambda: state.__setitem__("generic", nearest_triangles_native(
            p, v, f, _level=0))
    o3d = None
    try:
        import open3d as o3d
    except Exception as exc:                       # not installed, or a missing system library
        notes.append(f"Open3D: not measured (`import open3d` failed: {exc}). To compare, "
                     "install it: `pip install open3d` (on Debian/Ubuntu also "
                     "`apt-get install libusb-1.0-0`).")
    else:
        tb = time.perf_counter()
        scene = o3d.t.geometry.RaycastingScene()
        scene.add_triangles(o3d.core.Tensor(v.astype(np.float32)),
                            o3d.core.Tensor(f.astype(np.uint32)))
        scene.compute_closest_points(o3d.core.Tensor(p[:1].astype(np.float32)))   # builds BVH
        notes.append(f"Open3D: scene + BVH build {time.perf_counter() - tb:.3f} s (not in its rate)")
        pts = o3d.core.Tensor(p.astype(np.float32))
        timed["open3d"] = lambda: state.__setitem__("o3d", scene.compute_closest_points(pts))
    for fn in timed.values():                      # warm-up (JIT cache, first-touch memory)
        fn()
    t = _interleaved(timed, repeat)
    ref = state["ref"]

    # ---- ours
    exact = "certified float64"
    if n_ver:
        sub = np.random.default_rng(2).choice(n, n_ver, replace=False)
        numpy_ref = nearest_triangles(p[sub], v, f, method="numpy")
        same = all(np.array_equal(getattr(numpy_ref, k), getattr(ref, k)[sub])
                   for k in ("face", "distance", "closest", "barycentric"))
        exact += f"; {'identical' if same else 'DIFFERS'} to numpy reference on {n_ver:,} pts"
    med, best = _fmt_rate(t["full"], n)
    rows.append(["ours, numba `nearest_triangles(method=\"numba\")` (checks + BVH build + "
                 "queries)", med, best, threads, exact, "0 (reference)", "100%", _load(t["full"])])
    same_c = all(np.array_equal(getattr(state["native"], k), getattr(ref, k))
                 for k in ("face", "distance", "closest", "barycentric"))
    med, best = _fmt_rate(t["native"], n)
    rows.append(["ours, C `nearest_triangles(method=\"native\")` (checks + BVH build + queries; "
                 "what `bind_local` runs)", med, best, native_threads(),
                 "identical to numba's" if same_c else "DIFFERS from numba's", "0", "100%",
                 _load(t["native"])])
    if native_level > 0:
        same_g = all(np.array_equal(getattr(state["generic"], k), getattr(ref, k))
                     for k in ("face", "distance", "closest", "barycentric"))
        med, best = _fmt_rate(t["generic"], n)
        rows.append([f"ours, the same C search with its generic x86-64 query loop (this CPU "
                     f"runs the {('AVX2', 'AVX-512F')[native_level - 1]} one above)", med, best,
                     native_threads(), "identical to numba's" if same_g else
                     "DIFFERS from numba's", "0", "100%", _load(t["generic"])])
    med, best = _fmt_rate(t["bind"], n)
    rows.append(["ours, `bind_local` (the binding of `gsverse-convert --mesh`: search + anchors)",
                 med, best, threads, "same faces", "–", "–", _load(t["bind"])])
    notes.append(f"ours: `bind_local` {t['bind'].median:.3f} s, of which the search "
                 f"{t['native'].median:.3f} s (the C search) and the anchors (frames, barycentrics, offsets, "
                 f"local rotations) the rest")
    med, best = _fmt_rate(t["query"], n)
    rows.append(["ours, queries only (BVH prebuilt)", med, best, threads, "same", "0", "100%",
                 _load(t["query"])])
    notes.append(f"ours: BVH build {t['build'].median:.3f} s (best {t['build'].best:.3f}); first "
                 f"call in this process (numba import + compile or cache load) {first_call:.2f} s")
    if not quick and not args.no_compile_time:
        scratch = _compile_from_scratch()
        notes.append("ours: compilation from an empty cache (fresh process, import included): "
                     + (f"{scratch:.1f} s" if scratch is not None else "failed to measure"))
        notes.extend(_small_jobs())
    scale = np.abs(v).max() + np.abs(p).max(axis=1)

    # ---- Open3D
    if o3d is not None:
        out = state["o3d"]
        cp = out["points"].numpy().astype(np.float64)
        fid = out["primitive_ids"].numpy().astype(np.int64)
        d = np.linalg.norm(p - cp, axis=1)
        diff = np.abs(d - ref.distance)
        ok = bool(np.all(diff <= 8 * F32_EPS * scale))
        med, best = _fmt_rate(t["open3d"], n)
        rows.append([f"Open3D {o3d.__version__} `compute_closest_points` (float32, queries only)",
                     med, best, cpus,
                     "to float32 rounding" if ok else "no", f"{diff.max():.1e}",
                     f"{np.mean(fid == ref.face):.2%}", _load(t["open3d"])])

    # ---- trimesh
    try:
        import rtree  # noqa: F401  (trimesh's proximity queries need it)
        import trimesh
        import trimesh.proximity
    except Exception as exc:
        notes.append(f"trimesh: not measured ({exc}; `pip install trimesh rtree` to include it)")
    else:
        sub = np.random.default_rng(3).choice(n, n_tm, replace=False)
        mesh = trimesh.Trimesh(v, f, process=False)
        tb = time.perf_counter()
        mesh.triangles_tree                      # noqa: B018  (builds the R-tree)
        tm_build = time.perf_counter() - tb
        out = {}
        t_tm = measure(lambda: out.__setitem__("r", trimesh.proximity.closest_point(mesh, p[sub])),
                       repeat=1, batches=1, warmup=0)
        _, d, tid = out["r"]
        diff = d - ref.distance[sub]
        farther = diff > 1e-12 * scale[sub]
        med, best = _fmt_rate(t_tm, n_tm)
        rows.append([f"trimesh {trimesh.__version__} `proximity.closest_point` "
                     f"({n_tm:,}-pt subset, extrapolated)", med, best, 1,
                     f"no: {farther.mean():.2%} farther" if farther.any() else "yes on this subset",
                     f"{np.abs(diff).max():.1e}", f"{np.mean(tid == ref.face[sub]):.2%}",
                     _load(t_tm)])
        notes.append(f"trimesh: R-tree build {tm_build:.2f} s (not in its rate)")

    # ---- report
    print("| method | Mpts/s (median) | Mpts/s (best) | threads | exact? | max abs(d - d_ref) "
          "| face agreement | other cores busy |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print("| " + " | ".join(str(x) for x in r) + " |")
    print()
    if o3d is not None:
        full, query, other = t["full"].samples, t["query"].samples, t["open3d"].samples
        r_full = np.median(np.array(other) / np.array(full))
        r_query = np.median(np.array(other) / np.array(query))
        print(f"ratio ours / Open3D (throughput; median over {len(full)} rounds in which every "
              f"method ran once, back to back): **{r_full:.2f}x** with our whole call (input "
              f"checks and BVH build included) against Open3D's queries alone; {r_query:.2f}x "
              f"queries against queries")
    else:
        print("ratio ours / Open3D: not measured (Open3D not importable)")
    print()
    for note in notes:
        print(f"- {note}")
    if any("†" in str(r[1]) for r in rows):
        print("- † other processes kept at least a quarter of a core busy during every "
              "repetition of this row: the machine was not quiet, rates are pessimistic")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
