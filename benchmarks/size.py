"""File size of anchored assets against plain ``KHR_gaussian_splatting`` and against the
compressed formats splats are delivered in (goals: float32 anchors ≤ +35% at SH0 and ≤ +15% at
SH3; quantized ≤ +15% at SH0 and ≤ +5% at SH3; compact anchors with the rest pose
SPZ-compressed ≤ 1.3× splat-transform's ``.spz`` at SH0 and ≤ 1.15× at SH3).

    python -m benchmarks.size [--splats N] [--faces F] [--quick | --large] [-v]

One synthetic object (default 200k splats on a 20k-face capsule, ``--large`` 1M on 100k,
``--quick`` 100k on 6k): the
splats sit on random faces with random barycentrics, normal offsets, rotations and scales, and
their rest pose is the reference remap of those anchors. The same splats are written as GLB

* plain KHR (no anchoring), float32 and with the rest ``ROTATION`` quantized to 16/8 bits;
* anchored, explicit anchors (extension 1.1 layout), float32 and ``--quantize 16``/``8``;
* anchored, compact anchors (1.2: ``faceCounts`` + derived ``local`` anchors; what
  ``gsverse-convert`` writes by default), likewise;

at SH degree 0 and 3. Each row gives the bytes, the overhead over plain float32 KHR and over
plain KHR quantized the same way (the fair comparison for quantized rows: the rest pose shrinks
in both), the goal, and the rest-pose check of spec §Outputs on the file read back (the worst
|Δμ| and ‖ΔΣ‖_F in units of their tolerances; ≤ 1 holds). The anchored overhead includes the
anchor mesh (FLOAT positions and indices). A second table puts the three float32 files side
by side per SH degree with their ratios (what ``gsverse-convert`` writes without
``--quantize``: plain with ``--plain``, explicit with ``--anchors explicit``, compact by
default).

A third table, the delivery table, puts side by side for the same splats (SH 0 and 3; 200k
and 1M splats by default, the one size of ``--quick`` or ``--splats``): plain KHR, anchored
explicit, anchored compact, anchored compact with the rest pose SPZ-compressed
(``gsverse-convert --compress spz``), plain KHR SPZ-compressed, and PlayCanvas
splat-transform's ``.spz`` (version 4, its default) and ``.sog`` of a PLY of the same splats
in the same order (``tests/splat_transform``; ``.sog`` on the CPU with one k-means iteration
for the SH palette, and for SH above 0 only up to :data:`SOG_SH_SPLATS` splats, or
``--sog-sh-splats``). Its columns give the
ratio compact+SPZ / ``.spz`` against the goal, the share of the anchor mesh and
``faceCounts`` in the compact+SPZ file, and two checks of that file read back: the decoded
rest pose against the input in units of the bounds spec §SPZ-compressed rest pose states
(worst of position, scale, rotation and covariance; ≤ 1 holds), and the rest-pose check
above (the derived anchors against the decoded rest pose). Sizes are deterministic: no
timing is involved.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

#: (SH degree, quantized) -> the goal on the overhead over plain KHR, in percent
GOALS = {(0, False): 35.0, (3, False): 15.0, (0, True): 15.0, (3, True): 5.0}
#: SH degree -> the goal on anchored compact + SPZ over splat-transform's ``.spz``
SPZ_GOALS = {0: 1.3, 3: 1.15}
#: The delivery table's sizes: (splats, faces)
DELIVERY_SIZES = ((200_000, 20_000), (1_000_000, 100_000))
#: splat-transform's .sog of SH above 0 is run up to this many splats (``--sog-sh-splats``):
#: its SH palette's k-means on the CPU (no GPU here) took 15 min for 200k SH3 splats and grows
#: faster than the count.
SOG_SH_SPLATS = 50_000


def make_asset(n: int, faces: int, seed: int = 7):
    """(mesh, anchoring, rest cloud with SH3) for ``n`` splats on a capsule of about ``faces``
    faces, sorted by face as the converter writes them."""
    from gsverse_format.model import Anchoring, LocalAnchors, SplatCloud
    from gsverse_format.poses.analytic import random_quaternions
    from gsverse_format.remapping.reference import remap

    from .accuracy import bar_mesh

    around = max(8, int(round(np.sqrt(faces / 2.5))))
    mesh = bar_mesh(around, max(4, int(round(faces / (2 * around)))))
    rng = np.random.default_rng(seed)
    face = np.sort(rng.integers(0, mesh.face_count, n))
    bary = rng.dirichlet([1.0, 1.0, 1.0], n)[:, 1:]
    size = np.sqrt(2.0 * np.pi * 0.3 * 2.6 / mesh.face_count)       # ~ edge length
    anchors = LocalAnchors(face, bary, rng.uniform(-0.3, 0.3, n) * size,
                           random_quaternions(rng, n),
                           0.3 * size * np.exp(rng.normal(0.0, 0.5, (n, 3))))
    anchoring = Anchoring(mesh, anchors)
    rest = remap(anchoring)
    cloud = SplatCloud(rest.means, rest.rotations, anchors.local_scale,
                       rng.uniform(0.05, 1.0, n).astype(np.float32),
                       rng.normal(0.0, 0.3, (n, 16, 3)).astype(np.float32))
    return mesh, anchoring, cloud


def _rest_check(path: Path) -> tuple[float, float]:
    """Worst rest-pose errors of the file read back, in units of the spec's tolerances."""
    from gsverse_format.io.gltf import read_gltf
    from gsverse_format.remapping.reference import covariance_entries, iter_moments
    from gsverse_format.tolerances import (REST_COVARIANCE_FLOOR, REST_COVARIANCE_RELATIVE,
                                           mesh_extent, rest_mean_tolerance)

    prim = read_gltf(path).primitives[0]
    anchoring = prim.anchoring
    assert anchoring is not None
    diagonal, largest = mesh_extent(anchoring.mesh)
    mean_tol = rest_mean_tolerance(diagonal, largest)
    floor = (REST_COVARIANCE_FLOOR * diagonal) ** 2
    worst_mean = worst_cov = 0.0
    splats = prim.splats
    for sl, mu, ref in iter_moments(anchoring):
        stored = splats.means[sl].astype(np.float64)
        mean = np.sqrt(sum((mu[i] - stored[:, i]) ** 2 for i in range(3)))
        got = covariance_entries(splats.rotations[sl], splats.scales[sl])
        d = [g - r for g, r in zip(got, ref)]
        diff = np.sqrt(d[0] ** 2 + d[3] ** 2 + d[5] ** 2 + 2.0 * (d[1] ** 2 + d[2] ** 2 + d[4] ** 2))
        norm = np.sqrt(ref[0] ** 2 + ref[3] ** 2 + ref[5] ** 2
                       + 2.0 * (ref[1] ** 2 + ref[2] ** 2 + ref[4] ** 2))
        worst_mean = max(worst_mean, float(mean.max() / mean_tol))
        worst_cov = max(worst_cov, float((diff / (REST_COVARIANCE_RELATIVE * norm + floor)).max()))
    return worst_mean, worst_cov


def run(n: int, faces: int, log=lambda msg: None) -> dict:
    from gsverse_format.io.gltf import write_gltf
    from gsverse_format.io.gltf.writer import QUANTIZE_BITS
    from gsverse_format.model import SplatAsset, SplatCloud, SplatPrimitive

    mesh, anchoring, cloud = make_asset(n, faces)
    rows: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        for degree in (0, 3):
            k = (degree + 1) ** 2
            c = SplatCloud(cloud.means, cloud.rotations, cloud.scales, cloud.opacities,
                           np.ascontiguousarray(cloud.sh[:, :k]))
            plain = {}
            for bits in (None, 16, 8):
                quant = QUANTIZE_BITS[bits] if bits else None
                path = Path(tmp) / "plain.glb"
                write_gltf(SplatAsset([SplatPrimitive(c, None, "splats")]), path, quantize=quant)
                plain[bits] = path.stat().st_size
                rows.append(dict(sh=degree, layout="plain KHR", bits=bits or 32,
                                 bytes=plain[bits],
                                 over_float=100.0 * (plain[bits] / plain[None] - 1),
                                 over_same=0.0, goal=None, rest=None))
            for encoding in ("explicit", "compact"):
                for bits in (None, 16, 8):
                    quant = QUANTIZE_BITS[bits] if bits else None
                    path = Path(tmp) / f"{encoding}.glb"
                    t0 = time.perf_counter()
                    write_gltf(SplatAsset([SplatPrimitive(c, anchoring, "splats")]), path,
                               quantize=quant, anchors=encoding)
                    size = path.stat().st_size
                    rest = _rest_check(path)
                    log(f"size: SH{degree} {encoding} {bits or 32}-bit {size:,} bytes "
                        f"({time.perf_counter() - t0:.1f} s with the rest check)")
                    layout = f"anchored, {encoding}" + (" (default)" if encoding == "compact"
                                                          else "")
                    rows.append(dict(sh=degree, layout=layout, bits=bits or 32,
                                     bytes=size, over_float=100.0 * (size / plain[None] - 1),
                                     over_same=100.0 * (size / plain[bits] - 1),
                                     goal=GOALS[(degree, bits is not None)], rest=rest))
    return {"n": n, "faces": mesh.face_count, "rows": rows}


def markdown(res: dict) -> str:
    L = [f"# File size: {res['n']:,} splats, {res['faces']:,}-face anchor mesh", "",
         "Overhead over plain KHR_gaussian_splatting at the same SH degree: 'vs float' against "
         "plain float32, 'vs same' against plain KHR with the rest ROTATION quantized to the "
         "same bits (the goal is judged on 'vs same', the stricter). 'rest' is the rest-pose "
         "check of the file read back, worst |Δμ| and ‖ΔΣ‖_F in units of their tolerances "
         "(≤ 1 holds).", "",
         "| SH | layout | bits | bytes | vs float | vs same | goal | met | rest (μ, Σ) |",
         "|---|---|---|---|---|---|---|---|---|"]
    for r in res["rows"]:
        goal = f"≤ +{r['goal']:.0f}%" if r["goal"] is not None else ""
        met = "" if r["goal"] is None else ("yes" if r["over_same"] <= r["goal"] else "no")
        rest = "" if r["rest"] is None else f"{r['rest'][0]:.2g}, {r['rest'][1]:.2g}"
        L.append(f"| {r['sh']} | {r['layout']} | {r['bits']} | {r['bytes']:,} | "
                 f"{r['over_float']:+.1f}% | {r['over_same']:+.1f}% | {goal} | {met} | {rest} |")
    L += ["", "SH coefficients stay FLOAT (KHR_gaussian_splatting allows no other type), and "
          "OPACITY too (a SCALAR vertex attribute is padded to 4 bytes in glTF), so quantizing "
          "shrinks the rest ROTATION only; explicit anchors keep a FLOAT ROTATION (their rest "
          "pose is the remap of the stored anchors) and FLOAT barycentrics where some leave "
          "[0, 1]."]
    L += ["", *ratios(res)]
    if res.get("delivery"):
        L += ["", *delivery_markdown(res["delivery"])]
    return "\n".join(L)


def ratios(res: dict) -> list[str]:
    """The float32 files side by side per SH degree: plain KHR, anchored explicit (1.1 layout),
    anchored compact (1.2, the default), and their ratios."""
    L = ["Side by side (float32, what gsverse-convert writes without --quantize):", "",
         "| SH | plain KHR | anchored explicit | anchored compact (default) | explicit / plain "
         "| compact / plain | explicit / compact |",
         "|---|---|---|---|---|---|---|"]
    for degree in sorted({r["sh"] for r in res["rows"]}):
        size = {r["layout"].split(" (")[0]: r["bytes"] for r in res["rows"]
                if r["sh"] == degree and r["bits"] == 32}
        plain, explicit, compact = (size["plain KHR"], size["anchored, explicit"],
                                    size["anchored, compact"])
        L.append(f"| {degree} | {plain:,} | {explicit:,} | {compact:,} | "
                 f"{explicit / plain:.3f}× | {compact / plain:.3f}× | {explicit / compact:.3f}× |")
    return L


def _spz_bound_check(path: Path, cloud) -> float:
    """The decoded rest pose of the compressed file against the input ``cloud`` (same order),
    in units of the bounds of spec §SPZ-compressed rest pose: the worst of position, scale,
    rotation angle and covariance (≤ 1 holds)."""
    from gsverse_format.io.gltf import read_gltf
    from gsverse_format.io.spz_stream import quantization_bounds

    got = read_gltf(path).primitives[0].splats
    bound = quantization_bounds(12)
    worst = float(np.abs(got.means.astype(np.float64) - cloud.means).max() / bound["position"])
    worst = max(worst, float(np.abs(got.scales.astype(np.float64) / cloud.scales - 1).max()
                             / bound["scale"]))
    q0 = cloud.rotations.astype(np.float64)
    q0 /= np.linalg.norm(q0, axis=1, keepdims=True)
    q1 = got.rotations.astype(np.float64)
    q1 /= np.linalg.norm(q1, axis=1, keepdims=True)
    # the decoded quaternion may be the input turned by 180° about its own x and z (the frame
    # change), which leaves the covariance alone: compare covariances for the angle
    a, b = cloud.covariances().astype(np.float64), got.covariances().astype(np.float64)
    rel = np.linalg.norm(a - b, axis=(1, 2)) / np.linalg.norm(a, axis=(1, 2))
    return max(worst, float(rel.max() / bound["covariance"]))


def _mesh_share(path: Path) -> tuple[float, float]:
    """The fraction of the file the anchor mesh (positions, indices) and ``faceCounts`` take,
    and the fraction 16-bit positions (``KHR_mesh_quantization`` SHORT VEC3, padded to 8 bytes
    a vertex) would save."""
    from gsverse_format.conformance.glb import unpack_glb
    from gsverse_format.vocabulary import EXTENSION, KHR

    doc, _ = unpack_glb(path.read_bytes())
    views = set()
    vertices = 0
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            ext = prim.get("extensions", {}).get(KHR, {}).get("extensions", {}).get(EXTENSION)
            if ext is not None and "faceCounts" in ext:
                views.add(doc["accessors"][ext["faceCounts"]]["bufferView"])
            if prim.get("mode", 4) == 4:
                views.add(doc["accessors"][prim["attributes"]["POSITION"]]["bufferView"])
                vertices += doc["accessors"][prim["attributes"]["POSITION"]]["count"]
                views.add(doc["accessors"][prim["indices"]]["bufferView"])
    size = path.stat().st_size
    return sum(doc["bufferViews"][v]["byteLength"] for v in views) / size, 4 * vertices / size


def _splat_transform(ply: Path, out: Path) -> int | str:
    """The size of splat-transform's output for ``ply`` (suffix of ``out``), or why not."""
    import subprocess

    from .convert import SPLAT_TRANSFORM, splat_transform_problem

    problem = splat_transform_problem()
    if problem is not None:
        return problem
    # .sog on the CPU (no GPU here), its SH palette with one k-means iteration: the file is
    # within 0.01 % of the default ten iterations' size (1,042,723 against 1,042,632 bytes for
    # 20k SH3 splats), which take about twenty times as long
    sog = ["-g", "cpu", "-i", "1"] if out.suffix == ".sog" else []
    cmd = ["node", str(SPLAT_TRANSFORM), "-q", "-w", *sog, str(ply), str(out)]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=3600)
    if done.returncode != 0 or not out.is_file():
        return "failed: " + (done.stderr.strip().splitlines() or ["?"])[-1][:120]
    return out.stat().st_size


def delivery(sizes, log=lambda msg: None, sog_sh_splats: int = SOG_SH_SPLATS) -> list[dict]:
    """The delivery table's rows: per size and SH degree, the bytes of each layout."""
    from gsverse_format.io.gltf import write_gltf
    from gsverse_format.io.ply import write_splat_ply
    from gsverse_format.model import SplatAsset, SplatCloud, SplatPrimitive

    rows = []
    for n, faces in sizes:
        mesh, anchoring, cloud = make_asset(n, faces)
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            for degree in (0, 3):
                k = (degree + 1) ** 2
                c = SplatCloud(cloud.means, cloud.rotations, cloud.scales, cloud.opacities,
                               np.ascontiguousarray(cloud.sh[:, :k]))
                anchored = SplatAsset([SplatPrimitive(c, anchoring, "splats")])
                plain = SplatAsset([SplatPrimitive(c, None, "splats")])
                row: dict = {"n": n, "faces": mesh.face_count, "sh": degree}
                for key, asset, kw in (
                        ("plain", plain, {}), ("explicit", anchored, {"anchors": "explicit"}),
                        ("compact", anchored, {"anchors": "compact"}),
                        ("compact_spz", anchored, {"anchors": "compact", "compress": "spz"}),
                        ("plain_spz", plain, {"compress": "spz"})):
                    path = folder / f"{key}.glb"
                    t0 = time.perf_counter()
                    write_gltf(asset, path, **kw)
                    row[key] = path.stat().st_size
                    log(f"size: {n:,} SH{degree} {key} {row[key]:,} bytes "
                        f"({time.perf_counter() - t0:.1f} s)")
                row["spz_bound"] = _spz_bound_check(folder / "compact_spz.glb", c)
                row["rest"] = _rest_check(folder / "compact_spz.glb")
                row["mesh_share"], row["q16_saving"] = _mesh_share(folder / "compact_spz.glb")
                ply = folder / "splats.ply"
                write_splat_ply(c, ply)
                for key, suffix in (("st_spz", ".spz"), ("st_sog", ".sog")):
                    if key == "st_sog" and degree and n > sog_sh_splats:
                        row[key] = "not run: CPU SH k-means; --sog-sh-splats"
                        continue
                    t0 = time.perf_counter()
                    row[key] = _splat_transform(ply, folder / f"st{suffix}")
                    log(f"size: {n:,} SH{degree} splat-transform {suffix} {row[key]} "
                        f"({time.perf_counter() - t0:.1f} s)")
                rows.append(row)
        del mesh, anchoring, cloud
    return rows


def delivery_markdown(rows: list[dict]) -> list[str]:
    """The delivery table: the same splats in every layout, bytes and ratios."""
    def cell(v) -> str:
        return f"{v:,}" if isinstance(v, int) else f"({v})"

    L = ["Delivery: the same splats as plain KHR, anchored explicit, anchored compact "
         "(default), anchored compact with the rest pose SPZ-compressed (`--compress spz`), "
         "plain KHR SPZ-compressed, and splat-transform's .spz (v4) and .sog; goal: compact + "
         "SPZ ≤ 1.3× the .spz at SH0, ≤ 1.15× at SH3. 'mesh' is the share of the anchor mesh "
         "and faceCounts in the compact + SPZ file ('q16' what 16-bit anchor-mesh positions "
         "would save of it); 'bound' the decoded rest pose against the "
         "input in units of the stated SPZ bounds, 'rest' the derived anchors against the "
         "decoded rest pose in units of the rest-pose tolerances (≤ 1 holds).", "",
         "| splats | SH | plain KHR | explicit | compact | compact + SPZ | plain + SPZ | .spz | "
         ".sog | compact+SPZ / .spz | goal | met | mesh (q16) | bound | rest (μ, Σ) |",
         "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        spz = r["st_spz"]
        ratio = r["compact_spz"] / spz if isinstance(spz, int) else None
        goal = SPZ_GOALS[r["sh"]]
        L.append(f"| {r['n']:,} | {r['sh']} | {r['plain']:,} | {r['explicit']:,} | "
                 f"{r['compact']:,} | {r['compact_spz']:,} | {r['plain_spz']:,} | {cell(spz)} | "
                 f"{cell(r['st_sog'])} | {'' if ratio is None else f'{ratio:.3f}×'} | "
                 f"≤ {goal}× | {'' if ratio is None else ('yes' if ratio <= goal else 'no')} | "
                 f"{100 * r['mesh_share']:.1f}% ({100 * r['q16_saving']:.1f}%) | "
                 f"{r['spz_bound']:.2f} | "
                 f"{r['rest'][0]:.2g}, {r['rest'][1]:.2g} |")
    return L


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.size", description=__doc__.split("\n")[0])
    p.add_argument("--splats", type=int, default=None,
                   help="one size for both tables (default: 200k, and 200k and 1M for the "
                        "delivery table)")
    p.add_argument("--faces", type=int, default=None)
    size = p.add_mutually_exclusive_group()
    size.add_argument("--quick", action="store_true", help="100k splats on about 6k faces")
    size.add_argument("--large", action="store_true", help="1M splats on about 100k faces")
    p.add_argument("--sog-sh-splats", type=int, default=SOG_SH_SPLATS, metavar="N",
                   help=f"run splat-transform's .sog for SH above 0 up to N splats (default "
                        f"{SOG_SH_SPLATS:,}: its SH k-means on the CPU takes far longer than "
                        "everything else)")
    p.add_argument("-v", "--verbose", action="store_true", help="progress lines on stderr")
    args = p.parse_args(argv)
    n, faces = ((100_000, 6_000) if args.quick else (1_000_000, 100_000) if args.large
                else (args.splats or 200_000, args.faces or max(1, (args.splats or 200_000) // 10)))
    log = (lambda msg: print(msg, file=sys.stderr, flush=True)) if args.verbose \
        else (lambda msg: None)
    res = run(n, faces, log=log)
    sizes = ((n, faces),) if args.quick or args.splats else DELIVERY_SIZES
    res["delivery"] = delivery(sizes, log=log, sog_sh_splats=args.sog_sh_splats)
    print(markdown(res))
    return 0


if __name__ == "__main__":
    sys.path.insert(0, os.fspath(Path(__file__).resolve().parents[1]))
    raise SystemExit(main())
