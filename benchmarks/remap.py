"""Remap speed: numpy reference and the compiled fast path against the memory-bandwidth floor.

Workload (as in the issue): 1M splats anchored to a 100k-face mesh (a bent and waved grid of
250 × 200 quads, 50k vertices), uniformly random faces, barycentrics, normal offsets, rotations
and scales; splats sorted by face as files store them (spec §Ordering), plus a shuffled copy to
show what the order is worth. ``--quick``: 100k splats on a 10k-face grid.

Floor. The bytes a remap must stream per splat (read the per-splat anchors, write the mean and
the six covariance entries; per-face data stay in cache and are not counted) divided by the copy
bandwidth measured in the same run with the same thread count (a numba parallel copy of a
256 MiB float32 array; bytes read + bytes written): the median of every copy timed in the run
at that thread count, one before and one after each fast-path timing besides the first, so
that the share of the floor does not move with one copy's luck. The fast path's ``local`` splat stream is
4 (face) + 48 (b1, b2, d, L = R_l S_l) read + 12 + 24 written = 88 bytes; ``games`` is 16 + 36.
The numpy reference reads the stored anchors (face 4, barycentrics 8, offset 4, rotation 16,
scale 12 = 44 bytes; ``games`` 16) and writes float64 means and 3×3 covariances; its floor uses
those bytes (float64 output, 96 bytes).

Every timing is a median over repetitions in batches during which other processes used less
than a quarter of a core (over all batches, marked †, when there were none).

Further rows (``local/affine``, the fast path):

* **busy core**: 1 and all threads while this benchmark's own child process spins on one core
  (``python -c "while True: pass"``): the remap must degrade gracefully, never slower on 2
  threads than on 1 (one parallel region per frame, chunks handed out dynamically);
* **scaling**: 100k, 1M and 4M splats on the same 100k-face mesh (``--quick``: 10k, 100k, 400k
  on 10k faces), with the time per 1M splats and the share of the floor: 100k splats should not
  cost much more per splat than 1M (faces without splats are not computed).
"""
from __future__ import annotations

import subprocess
import sys
import time
import tracemalloc

import numpy as np

from gsverse_format.model import Anchoring, GamesAnchors, LocalAnchors, TriangleMesh
from gsverse_format.remapping.reference import remap as reference_remap
from gsverse_format.remapping.fast import FastRemapper, numba_available

from .timing import measure

TARGET_MS = 8.0


def grid_mesh(nx: int, ny: int) -> TriangleMesh:
    """A bent and waved grid of nx × ny quads (2 nx ny faces)."""
    u, v = np.meshgrid(np.linspace(0, 2, nx + 1), np.linspace(0, 1.6, ny + 1), indexing="ij")
    z = 0.1 * np.sin(3 * u) * np.cos(2 * v) + 0.3 * u * u
    verts = np.stack([u, v, z], -1).reshape(-1, 3)
    idx = np.arange((nx + 1) * (ny + 1)).reshape(nx + 1, ny + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return TriangleMesh(verts, faces)


def random_anchors(mesh: TriangleMesh, n: int, profile: str, seed: int = 0):
    """Random anchors, sorted by face."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(seed)
    face = np.sort(rng.integers(0, mesh.face_count, n))
    bary = rng.dirichlet([1, 1, 1], n)[:, 1:]
    if profile == "games":
        return GamesAnchors(face, bary, rng.uniform(0.2, 2.0, n))
    law = profile.split("/")[1]
    return LocalAnchors(face, bary, rng.normal(0, 0.003, n),
                        Rotation.random(n, random_state=seed + 1).as_quat(),
                        np.exp(rng.normal(-5, 0.5, (n, 3))), law)


def deformed(mesh: TriangleMesh) -> np.ndarray:
    v = mesh.vertices.astype(np.float64)
    return (v * [1.5, 1.0, 1.0] + 0.05 * np.sin(4 * v[:, [1, 2, 0]])).astype(np.float32)


_COPY = []


def _copy_kernel():
    if not _COPY:
        from numba import njit, prange

        @njit(parallel=True, cache=True)
        def _copy(a, b):  # pragma: no cover - compiled
            for i in prange(a.shape[0]):
                b[i] = a[i]

        _COPY.append(_copy)
    return _COPY[0]


def copy_bandwidth(threads: int, mib: int = 256, min_quiet: int = 0,
                   max_wait_s: float = 0.0, *, batches: int = 3,
                   retry_contended: int = 3) -> tuple[float, dict]:
    """GB/s of a numba parallel copy on ``threads`` threads ((read + write) / s)."""
    import numba

    _copy = _copy_kernel()
    x = np.ones(mib * 2**20 // 4, np.float32)
    y = np.empty_like(x)
    before = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        t = measure(lambda: _copy(x, y), repeat=5, batches=batches,
                    retry_contended=retry_contended, min_quiet=min_quiet, max_wait_s=max_wait_s)
    finally:
        numba.set_num_threads(before)
    return 2 * x.nbytes / t.median / 1e9, t.as_dict()


_ARITH = []
#: Faces in the workspace of :func:`face_arithmetic_ns` (8 rows of float64: 64 KiB, in L2).
_ARITH_FACES = 1024


def _arith_kernel():
    if not _ARITH:
        from numba import njit

        b = _ARITH_FACES

        @njit(error_model="numpy")
        def _arith(w, reps):  # pragma: no cover - compiled
            for _ in range(reps):
                for j in range(b):
                    cx, cy, cz, root_r = w[j], w[b + j], w[2 * b + j], w[3 * b + j]
                    root_c = np.sqrt(np.sqrt(cx * cx + cy * cy + cz * cz))
                    s = root_c * root_r
                    w[4 * b + j] = cx / s
                    w[5 * b + j] = cy / s
                    w[6 * b + j] = cz / s
                    w[7 * b + j] = root_c / root_r

        _ARITH.append(_arith)
    return _ARITH[0]


def face_arithmetic_ns(reps: int = 2000) -> float:
    """Nanoseconds a face of the float64 arithmetic alone of the affine face step (two square
    roots, four divisions, as :func:`gsverse_format.remapping.compiled_runs._affine_block`
    computes them), in a loop LLVM vectorises, on one core, with no gather and no table row:
    a lower bound of any face step that keeps the faces in float64. Median of 5 timings."""
    kernel = _arith_kernel()
    w = np.random.default_rng(0).uniform(0.5, 1.5, 8 * _ARITH_FACES)
    kernel(w, 1)
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        kernel(w, reps)
        times.append(time.perf_counter() - t0)
    return float(np.median(times)) / (reps * _ARITH_FACES) * 1e9


def copy_sample(threads: int, mib: int = 256) -> float:
    """One short copy measurement (GB/s, median of 5 copies, one batch) on ``threads``
    threads: the samples taken between the remap timings that the floor is the median of."""
    return copy_bandwidth(threads, mib, batches=1, retry_contended=0)[0]


def numpy_copy_bandwidth(mib: int = 256) -> float:
    x = np.ones(mib * 2**20 // 4, np.float32)
    y = np.empty_like(x)
    t = measure(lambda: np.copyto(y, x), repeat=5, batches=3)
    return 2 * x.nbytes / t.median / 1e9


def _peak_bytes(fn) -> int:
    tracemalloc.start()
    tracemalloc.reset_peak()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def _row(name, impl, threads, n, timing, bytes_per_splat, bw, *, order="by face", check=None):
    ms = timing.median * 1e3
    floor_ms = bytes_per_splat * n / (bw * 1e9) * 1e3 if bw else float("nan")
    return {"case": name, "impl": impl, "threads": threads, "order": order, "n": n, "ms": ms,
            "ms_per_1M": ms * 1e6 / n, "best_ms": timing.best * 1e3, "msplats_s": n / timing.median / 1e6,
            "bytes_per_splat": bytes_per_splat, "floor_ms": floor_ms,
            "floor_fraction": floor_ms / ms if ms else float("nan"),
            "contended": timing.contended, "other_cores": timing.other_cores,
            "own_cores": timing.own_cores, "check": check}


def _accuracy(anchoring, vertices, out, ref=None):
    ref = ref if ref is not None else reference_remap(anchoring, vertices)
    cov = out.covariances()
    rel = np.linalg.norm(cov - ref.covariances, axis=(1, 2)) / np.linalg.norm(ref.covariances, axis=(1, 2))
    return {"max_mean_err": float(np.max(np.abs(out.means - ref.means))),
            "max_cov_rel_err": float(np.max(rel))}


def _impl_name(fast: FastRemapper) -> str:
    return ("fast path (numba, float32, one pass over runs)" if fast.one_pass
            else "fast path (numba, float32, face pass + splat pass)")


def _busy_loop() -> subprocess.Popen:
    """A child process that keeps one core busy until killed."""
    proc = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    time.sleep(0.5)
    return proc


def _busy_rows(result: dict, mesh, verts, anchoring, threads_all: int, bw: dict,
               quick: bool) -> None:
    """1 and all threads while one core is kept busy by a child process."""
    import numba

    variants = [FastRemapper(anchoring, backend="numba"),
                FastRemapper(anchoring, backend="numba", one_pass=False)]
    for fast in variants:
        fast.remap(verts)
    n = variants[0].n_splats
    busy = _busy_loop()
    try:
        for th in sorted({1, threads_all}):
            numba.set_num_threads(th)
            for fast in variants:
                t = measure(lambda: fast.remap(verts), repeat=10 if quick else 40, batches=2)
                row = _row(anchoring.anchors.profile + "/" + anchoring.anchors.deformation,
                           _impl_name(fast), th, n, t, fast.bytes_per_splat, bw[th],
                           order="by face, one core busy")
                row["busy_core"] = True
                row["one_pass"] = fast.one_pass
                result["rows"].append(row)
    finally:
        numba.set_num_threads(threads_all)
        busy.kill()
        busy.wait()
    for one_pass in (True, False):
        rows = {r["threads"]: r for r in result["rows"]
                if r.get("busy_core") and r.get("one_pass") == one_pass}
        if 1 in rows and threads_all in rows and threads_all > 1:
            ratio = rows[threads_all]["ms"] / rows[1]["ms"]
            if one_pass:
                result["busy_core_ratio"] = ratio
            result["notes"].append(
                f"one core busy, {'one pass' if one_pass else 'two passes'}: {threads_all} "
                f"threads take {ratio:.2f}× the time of 1 thread ({rows[threads_all]['ms']:.2f} "
                f"vs {rows[1]['ms']:.2f} ms); goal ≤ 1")


def _scaling_rows(result: dict, mesh, verts, threads_all: int, bw: dict, quick: bool) -> None:
    """The fast path at 0.1×, 1× and 4× the workload's splat count on the same mesh, and the
    split of its time into a cost per face computed and a cost per splat (:func:`face_split`)."""
    import numba

    base = result["n_splats"]
    numba.set_num_threads(threads_all)
    for n in (base // 10, base, 4 * base):
        anchors = random_anchors(mesh, n, "local/affine", seed=3)
        anchoring = Anchoring(mesh, anchors)
        fast = FastRemapper(anchoring, backend="numba")
        fast.remap(verts)
        reps = max(5, min(100, int(40 * base / n))) if not quick else 10
        t = measure(lambda: fast.remap(verts), repeat=reps, batches=3,
                    retry_contended=0 if quick else 2)
        row = _row(f"local/affine, {n:,} splats", _impl_name(fast), threads_all, n, t,
                   fast.bytes_per_splat, bw[threads_all], order="by face (scaling)")
        row["scaling"] = True
        row["faces_used"] = int(np.unique(anchors.face_index).shape[0])
        result["rows"].append(row)
        fast = anchoring = anchors = None
    rows = {r["n"]: r for r in result["rows"] if r.get("scaling")}
    small, mid = rows.get(base // 10), rows.get(base)
    if small and mid:
        result["scaling_ratio"] = small["ms_per_1M"] / mid["ms_per_1M"]
        result["notes"].append(f"{base // 10:,} splats cost {result['scaling_ratio']:.2f}× per "
                               f"splat what {base:,} do (goal ≤ 1.3×)")
        split = face_split(list(rows.values()))
        if split:
            split["arithmetic_ns"] = face_arithmetic_ns(reps=200 if quick else 2000)
            result["face_split"] = split
            result["notes"].append(
                f"least squares over the scaling rows: {split['face_ns']:.1f} ns per face computed "
                f"and {split['splat_ns']:.1f} ns per splat ({threads_all} threads, wall time × "
                f"threads); with {split['small_faces_per_splat']:.2f} faces a splat at "
                f"{base // 10:,} splats and {split['mid_faces_per_splat']:.2f} at {base:,}, a ratio "
                f"of 1.3 needs a face to cost at most {split['face_budget']:.2f} splats "
                f"(it costs {split['face_ns'] / split['splat_ns']:.2f}); the float64 arithmetic "
                f"of a face alone, vectorised on one core: {split['arithmetic_ns']:.2f} ns")


def face_split(rows: list[dict]) -> dict | None:
    """Split the scaling rows' times into a cost per face computed and a cost per splat.

    The one-pass remap computes every face that carries a splat once a frame, then every splat,
    so a frame takes about ``faces_used · f + n · s``; a least-squares fit over the rows (times
    the thread count, so the costs are in core time) gives f and s. The per-splat ratio of
    ``n₁`` splats over ``n₂`` on the same mesh is then ``(φ₁ f + s) / (φ₂ f + s)`` with
    ``φ = faces_used / n``, and a ratio of 1.3 needs ``f ≤ 0.3 s / (φ₁ − 1.3 φ₂)`` (the
    *face budget*, in splats)."""
    rows = sorted((r for r in rows if r.get("faces_used")), key=lambda r: r["n"])
    if len(rows) < 2:
        return None
    a = np.array([[r["faces_used"], r["n"]] for r in rows], np.float64)
    t = np.array([r["ms"] * 1e6 * r["threads"] for r in rows], np.float64)      # core ns
    (f, s), *_ = np.linalg.lstsq(a, t, rcond=None)
    if not (f > 0 and s > 0):
        return None
    phi_small = rows[0]["faces_used"] / rows[0]["n"]
    phi_mid = rows[1]["faces_used"] / rows[1]["n"]
    denom = phi_small - 1.3 * phi_mid
    return {"face_ns": float(f), "splat_ns": float(s), "small_faces_per_splat": phi_small,
            "mid_faces_per_splat": phi_mid,
            "face_budget": float(0.3 / denom) if denom > 0 else float("inf")}


def run(quick: bool = False, log=print) -> dict:
    """Time every implementation; returns rows and the bandwidth figures."""
    t_start = time.perf_counter()
    result = {"rows": [], "notes": [], "target_ms": TARGET_MS}
    nx, ny = (50, 100) if quick else (250, 200)
    n = 100_000 if quick else 1_000_000
    mesh = grid_mesh(nx, ny)
    verts = deformed(mesh)
    result.update(n_splats=n, n_faces=mesh.face_count, n_vertices=len(mesh.vertices))
    log(f"remap: {n} splats, {mesh.face_count} faces")

    have_numba = numba_available()
    threads_all = 1
    if have_numba:
        import numba

        threads_all = numba.config.NUMBA_NUM_THREADS
        bw = {}
        samples: dict[int, list[float]] = {}   # copy bandwidths, interleaved with the remaps
        for th in sorted({1, threads_all}):
            gbs, info = copy_bandwidth(th, 64 if quick else 256, 0 if quick else 3,
                                       0 if quick else 120)
            bw[th] = gbs
            samples[th] = [gbs]
            result.setdefault("bandwidth", []).append({"threads": th, "gb_s": gbs, **info})
        result["numpy_copy_gb_s"] = numpy_copy_bandwidth(64 if quick else 256)
    else:
        result["notes"].append("numba is not importable: only the numpy reference was timed")
        bw = {1: numpy_copy_bandwidth(64 if quick else 256)}
        result["bandwidth"] = [{"threads": 1, "gb_s": bw[1], "kind": "numpy copyto"}]

    ref_reps = 1 if quick else 2
    for case in ("local/affine", "local/rigid", "games"):
        anchors = random_anchors(mesh, n, case)
        anchoring = Anchoring(mesh, anchors)
        ref_bytes = (16 if case == "games" else 44) + 96
        # numpy reference
        holder = {}
        t = measure(lambda: holder.__setitem__("r", reference_remap(anchoring, verts)),
                    repeat=ref_reps, batches=1 if quick else 2, warmup=0)
        ref = holder["r"]
        result["rows"].append(_row(case, "numpy reference `remap` (float64, with rotations/scales)",
                                   1, n, t, ref_bytes, bw.get(1)))
        if case == "local/affine":
            result["peak_numpy_remap_mb"] = _peak_bytes(lambda: reference_remap(anchoring, verts)) / 2**20
        try:
            from gsverse_format.remapping.reference import remap_moments
        except ImportError:
            remap_moments = None
        if remap_moments is not None:
            t = measure(lambda: remap_moments(anchoring, verts), repeat=ref_reps,
                        batches=1 if quick else 2, warmup=1)
            result["rows"].append(_row(case, "numpy `remap_moments` (float64, means + covariances)",
                                       1, n, t, ref_bytes, bw.get(1)))
        if not have_numba:
            continue
        t0 = time.perf_counter()
        fast = FastRemapper(anchoring, backend="numba")
        build_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        out = fast.remap(verts)
        first_s = time.perf_counter() - t0
        check = _accuracy(anchoring, verts, out, ref)
        result["notes"].append(f"{case}: FastRemapper construction {build_s:.2f} s; first remap "
                               f"(kernel compilation or cache load) {first_s:.2f} s")
        for th in sorted({1, threads_all}):
            numba.set_num_threads(th)
            try:
                reps = 10 if quick else 40
                # The headline rows wait (up to a few minutes) for quiet moments on a busy machine.
                samples[th].append(copy_sample(th, 64 if quick else 256))
                t = measure(lambda: fast.remap(verts), repeat=reps, batches=3,
                            retry_contended=1 if quick else 6, min_quiet=0 if quick else 3,
                            max_wait_s=0 if quick else (240 if case == "local/affine" else 120))
                samples[th].append(copy_sample(th, 64 if quick else 256))
                result["rows"].append(_row(case, "fast path (numba, float32)", th, n, t,
                                           fast.bytes_per_splat, bw[th], check=check))
                result["rows"][-1]["impl"] = _impl_name(fast)
                if not fast.one_pass:
                    tf = measure(lambda: fast.face_pass(verts), repeat=reps, batches=2,
                                 retry_contended=0 if quick else 2)
                    result["rows"][-1]["face_pass_ms"] = tf.median * 1e3
                if case == "local/rigid":
                    fast_r = FastRemapper(anchoring, backend="numba", rotations=True)
                    fast_r.remap(verts)
                    t = measure(lambda: fast_r.remap(verts), repeat=reps, batches=2,
                                retry_contended=0 if quick else 2, min_quiet=0 if quick else 2,
                                max_wait_s=0 if quick else 60)
                    result["rows"].append(_row(case, "fast path + rotations/scales", th, n, t,
                                               fast_r.bytes_per_splat, bw[th]))
                if case == "games":
                    fast_g = FastRemapper(anchoring, backend="numba", rotations=True)
                    fast_g.remap(verts)
                    t = measure(lambda: fast_g.remap(verts), repeat=reps, batches=2,
                                retry_contended=0 if quick else 2, min_quiet=0 if quick else 2,
                                max_wait_s=0 if quick else 60)
                    result["rows"].append(_row(case, "fast path + rotations/scales", th, n, t,
                                               fast_g.bytes_per_splat, bw[th]))
            finally:
                numba.set_num_threads(threads_all)
        if case == "local/affine":
            plan = fast._plan
            index_bytes = (plan.run_of.nbytes + plan.face.nbytes + plan.chunk.nbytes
                           if plan is not None else fast._face.nbytes)
            result["fast_buffers_mb"] = (fast._consts.nbytes + index_bytes + fast._table.nbytes
                                         + out.means.nbytes + out.cov6.nbytes) / 2**20
            result["peak_fast_remap_mb"] = _peak_bytes(lambda: fast.remap(verts)) / 2**20
            # The two passes on the same face-sorted splats (what the one pass is worth).
            two = FastRemapper(anchoring, backend="numba", one_pass=False)
            two.remap(verts)
            for th in sorted({1, threads_all}):
                numba.set_num_threads(th)
                try:
                    t = measure(lambda: two.remap(verts), repeat=10 if quick else 40, batches=2,
                                retry_contended=0 if quick else 2)
                finally:
                    numba.set_num_threads(threads_all)
                result["rows"].append(_row(case, _impl_name(two), th, n, t, two.bytes_per_splat,
                                           bw[th]))
            two = None
            # Random splat order: what face-sorted storage is worth.
            perm = np.random.default_rng(5).permutation(n)
            shuffled = FastRemapper(Anchoring(mesh, anchors.subset(perm)), backend="numba")
            shuffled.remap(verts)
            t = measure(lambda: shuffled.remap(verts), repeat=5 if quick else 10, batches=2,
                        retry_contended=0 if quick else 2)
            result["rows"].append(_row(case, _impl_name(shuffled), threads_all, n, t,
                                       shuffled.bytes_per_splat, bw[threads_all], order="random"))
            shuffled = None
            fast = out = None
            _busy_rows(result, mesh, verts, anchoring, threads_all, bw, quick)
            anchors = anchoring = None
            _scaling_rows(result, mesh, verts, threads_all, bw, quick)
        fast = out = None  # release the buffers before the next case
    if have_numba:
        # The floor: the median of every copy measured in this run at the row's thread count
        # (taken before and after each fast-path timing), not one copy: a single measurement
        # moved the share of the floor by ±15 points between runs.
        median_bw = {th: float(np.median(v)) for th, v in samples.items()}
        result["copy_samples"] = {str(th): v for th, v in samples.items()}
        for entry in result.get("bandwidth", []):
            entry["gb_s_single"] = entry["gb_s"]
            entry["gb_s"] = median_bw.get(entry["threads"], entry["gb_s"])
            entry["samples"] = len(samples.get(entry["threads"], []))
        for row in result["rows"]:
            gbs = median_bw.get(row["threads"])
            if gbs:
                row["floor_ms"] = row["bytes_per_splat"] * row["n"] / (gbs * 1e9) * 1e3
                row["floor_fraction"] = row["floor_ms"] / row["ms"] if row["ms"] else float("nan")
    result["seconds"] = time.perf_counter() - t_start
    target = [r for r in result["rows"] if r["case"] == "local/affine" and r["impl"].startswith("fast path (")
              and r["threads"] == threads_all and r["order"] == "by face"]
    if have_numba:
        result["threading_layer"] = numba.threading_layer()
        result["notes"].append(f"numba threading layer: {result['threading_layer']}")
    if target:
        r = target[0]
        # Per 1M splats (the quick run has fewer splats and a smaller mesh).
        result["target_met"] = bool(r["ms_per_1M"] <= TARGET_MS) if not quick else None
        result["headline"] = r
    log(f"remap: done in {result['seconds']:.1f} s")
    return result
