"""Render speed of the CPU reference renderer and the remap's accuracy in image space.

``python -m benchmarks.render [--quick]`` prints Markdown; ``python -m benchmarks`` includes it
(section ``render``).

Speed. Random Gaussians on the surface of a bumpy bar (the accuracy benchmark's object, 100k and
1M splats, SH degree 3, opacities U(0.3, 1)) framed automatically, rendered by
:func:`gsverse_format.render.render_gaussians` (compiled path, all cores numba may use) at
512×512 and 1024×1024; the time is the median of repeated renders after a warm-up (compiled
code cached), split into projection + sorting/binning and tile compositing.

Accuracy in image space. The object, deformations, profiles/laws, anchor resolutions and
quantizations of :mod:`benchmarks.accuracy` (same ground truth: μ' = φ(μ), Σ' = J Σ Jᵀ), with
colour: each splat's colour is a smooth pattern of its *rest* position (stripes along and
around the bar, SH degree 0), opacity 0.8, so a splat that lands in the wrong place or with the
wrong shape changes pixels. For each case the ground-truth deformed Gaussians and the remapped
ones are rendered with the same camera (framing the truth, 384×384, two views: front and
side), and the table reports PSNR (dB, over RGB on black) and SSIM (Wang et al. 2004: 11×11
Gaussian window σ = 1.5, on luminance) — the metrics reconstruction papers report. The
``games`` profile renders its own GaMeS splats (its truth is φ of their rest pose), as in the
W₂ tables. At rest every profile reproduces the truth to float32 precision (PSNR > 60 dB).
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from gsverse_format.model import Anchoring, LocalAnchors
from gsverse_format.remapping.fast import FastRemapper
from gsverse_format.remapping.reference import remap as reference_remap
from gsverse_format.binding import bind_local
from gsverse_format.render.camera import frame_bounds
from gsverse_format.render.raster import render_gaussians

from . import accuracy as acc

SPEED_SIZES = (100_000, 1_000_000)
SPEED_IMAGES = ((512, 512), (1024, 1024))


def _pattern(x: np.ndarray) -> np.ndarray:
    """Colour (N, 3) in [0.1, 0.9] from rest positions: stripes along Y and around the bar."""
    ang = np.arctan2(x[:, 2], x[:, 0])
    r = 0.5 + 0.4 * np.sin(14.0 * x[:, 1])
    g = 0.5 + 0.4 * np.sin(6.0 * ang)
    b = 0.5 + 0.4 * np.sin(9.0 * x[:, 1] + 3.0 * ang)
    return np.stack([r, g, b], axis=1)


def _sh_of(color: np.ndarray) -> np.ndarray:
    return ((color - 0.5) / 0.28209479177387814)[:, None, :].astype(np.float32)


def ssim(a: np.ndarray, b: np.ndarray) -> float:
    """Mean SSIM of the luminance of two (H, W, 3) images in [0, 1]."""
    from scipy.ndimage import gaussian_filter

    w = np.array([0.299, 0.587, 0.114])
    x, y = a @ w, b @ w
    f = lambda z: gaussian_filter(z, 1.5, truncate=3.5)  # noqa: E731  (11x11 window)
    mx, my = f(x), f(y)
    sxx, syy, sxy = f(x * x) - mx * mx, f(y * y) - my * my, f(x * y) - mx * my
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    s = ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx * mx + my * my + c1) * (sxx + syy + c2))
    return float(s.mean())


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((a - b) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(1.0 / mse)


def _image(mu, cov, op, sh, cam) -> np.ndarray:
    img = render_gaussians(mu, cov, op, sh, cam)
    return np.clip(img.rgb.astype(np.float64), 0.0, 1.0)      # on black


def speed(quick: bool, log) -> list[dict]:
    from .timing import measure
    import numba

    fine = acc.bar_mesh(64, 80)
    rows = []
    for n in SPEED_SIZES[:1] if quick else SPEED_SIZES:
        cloud = acc.surface_object(fine, n, seed=4)
        rng = np.random.default_rng(5)
        mu = cloud.means.astype(np.float64)
        cov = cloud.covariances()
        op = rng.uniform(0.3, 1.0, n)
        sh = rng.normal(0, 0.2, (n, 16, 3)).astype(np.float32)
        sh[:, 0] = _sh_of(_pattern(mu))[:, 0]
        for w, h in SPEED_IMAGES[:1] if quick else SPEED_IMAGES:
            cam = frame_bounds(mu.min(0), mu.max(0), width=w, height=h)
            t = measure(lambda: render_gaussians(mu, cov, op, sh, cam), repeat=1 if quick else 3,
                        batches=1 if quick else 2)
            rows.append({"splats": n, "width": w, "height": h, "seconds": t.median,
                         "best_s": t.best, "contended": t.contended,
                         "threads": numba.get_num_threads()})
            log(f"render: {n} splats {w}x{h}: {t.median:.2f} s")
    return rows


def accuracy(quick: bool, log) -> dict:
    n_splats = 2000 if quick else 20000
    fine = acc.bar_mesh(32, 40) if quick else acc.bar_mesh(128, 160)
    notes: list[str] = []
    levels = acc._levels(fine, 1 if quick else 5, notes)
    lo, hi = fine.vertices.min(0).astype(float), fine.vertices.max(0).astype(float)
    bar = acc.Bar(float(lo[1]), float(hi[1]))
    h = acc.mean_edge(fine)
    cloud = acc.surface_object(fine, n_splats, seed=1)
    mu0, cov0 = cloud.means.astype(np.float64), cloud.covariances()
    size = 160 if quick else 384
    magnitudes = (5,) if quick else acc.MAGNITUDES
    cases = [(d, m) for d in acc.DEFORMATIONS for m in magnitudes]
    views = ((30.0, 15.0),) if quick else ((30.0, 15.0), (120.0, 15.0))
    rows = []
    for li, mesh in enumerate(levels):
        bound = bind_local(cloud, mesh).anchors
        games = acc.games_object(mesh, n_splats, size=0.55 * h, seed=2 + li)
        g0 = reference_remap(Anchoring(mesh, games))
        for profile, law in acc.PROFILES:
            pname = acc.profile_name(profile, law)
            base = games if profile == "games" else LocalAnchors(
                bound.face_index, bound.barycentrics, bound.normal_offset, bound.local_rotation,
                bound.local_scale, law)
            mu_rest, cov_rest = (g0.means, g0.covariances) if profile == "games" else (mu0, cov0)
            sh = _sh_of(_pattern(mu_rest))
            op = np.full(len(mu_rest), 0.8)
            for qmode in acc.QUANTIZATIONS:
                if li > 0 and qmode != "float32":
                    continue        # quantization is varied on the finest level only
                anchors, _ = acc.quantize(base, qmode)
                fast = FastRemapper(Anchoring(mesh, anchors))
                for dname, m in cases:
                    mu_t, jac = acc.deform(dname, m, bar, mu_rest)
                    cov_t = jac @ cov_rest @ np.swapaxes(jac, 1, 2)
                    cur, _ = acc.deform(dname, m, bar, mesh.vertices)
                    out = fast.remap(cur)
                    ps, ss = [], []
                    for az, el in views:
                        cam = frame_bounds(mu_t.min(0), mu_t.max(0), width=size, height=size,
                                           azimuth=az, elevation=el)
                        truth = _image(mu_t, cov_t, op, sh, cam)
                        cand = _image(out.means.astype(np.float64), out.covariances(), op, sh, cam)
                        ps.append(psnr(cand, truth))
                        ss.append(ssim(cand, truth))
                    rows.append({"profile": pname, "level": li, "faces": mesh.face_count,
                                 "quant": qmode, "deformation": dname, "magnitude": m,
                                 "psnr": float(np.mean(ps)), "ssim": float(np.mean(ss))})
        log(f"render accuracy: level {li} ({mesh.face_count} faces) done")
    return {"n_splats": n_splats, "size": size, "levels": [m.face_count for m in levels],
            "rows": rows, "notes": notes}


def run(quick: bool = False, log=print) -> dict:
    t0 = time.perf_counter()
    res = {"speed": speed(quick, log), "accuracy": accuracy(quick, log)}
    res["seconds"] = time.perf_counter() - t0
    return res


def markdown(res: dict) -> list[str]:
    """The section's Markdown (used by benchmarks/report.py and the script's output)."""
    L = ["## Rendering: speed and accuracy in image space", ""]
    L += ["| splats | image | render time, median (best), s | numba threads |", "|---:|---|---:|---:|"]
    for r in res["speed"]:
        mark = " †" if r["contended"] else ""
        L.append(f"| {r['splats']:,} | {r['width']}×{r['height']} | {r['seconds']:.2f}{mark} "
                 f"({r['best_s']:.2f}) | {r['threads']} |")
    a = res["accuracy"]
    L += ["", f"Image-space error of the remap against the ground-truth deformed Gaussians "
          f"({a['n_splats']:,} splats, {a['size']}×{a['size']}, mean over views; PSNR dB / SSIM):", ""]
    rows = a["rows"]
    cases = sorted({(r["deformation"], r["magnitude"]) for r in rows},
                   key=lambda c: (acc.DEFORMATIONS.index(c[0]), c[1]))
    head = "| profile | faces | anchors | " + " | ".join(f"{d} {m}" for d, m in cases) + " |"
    L += [head, "|---|---:|---|" + "---:|" * len(cases)]
    keys = []
    for r in rows:
        k = (r["profile"], r["faces"], r["quant"])
        if k not in keys:
            keys.append(k)
    for k in keys:
        cells = []
        for d, m in cases:
            hit = [r for r in rows if (r["profile"], r["faces"], r["quant"], r["deformation"],
                                        r["magnitude"]) == (*k, d, m)]
            cells.append(f"{hit[0]['psnr']:.1f} / {hit[0]['ssim']:.3f}" if hit else "")
        L.append(f"| {k[0]} | {k[1]:,} | {k[2]} | " + " | ".join(cells) + " |")
    return L


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.render", description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true", help="small sizes")
    args = p.parse_args(argv)
    import sys

    res = run(args.quick, lambda msg: print(msg, file=sys.stderr, flush=True))
    print("\n".join(markdown(res)))
    print(f"\n({res['seconds']:.0f} s; {os.cpu_count()} CPUs)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
