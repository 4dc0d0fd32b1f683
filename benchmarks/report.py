"""Markdown report and PNG plots from the benchmark results (see ``python -m benchmarks``)."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

DAGGER = "†"


def _f(x, digits=3) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    if isinstance(x, (int, np.integer)):
        return f"{x:,}"
    ax = abs(x)
    if ax == 0:
        return "0"
    if ax >= 1000 or ax < 1e-3:
        return f"{x:.{max(digits - 1, 1)}e}"
    return f"{x:.{digits}g}"


def _table(header: list[str], rows: list[list]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for r in rows:
        out.append("| " + " | ".join(str(c) for c in r) + " |")
    return "\n".join(out)


def _load(other) -> str:
    if not other or other[0] is None or not all(math.isfinite(v) for v in other):
        return "–"
    return f"{other[0]:.2f}–{other[1]:.2f}"


# --------------------------------------------------------------------------- plots

def _plt():
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        return plt
    except Exception:
        return None


def plot_remap(remap: dict, out: Path) -> str | None:
    plt = _plt()
    if plt is None or not remap.get("rows"):
        return None
    rows = [r for r in remap["rows"]]
    labels = [f"{r['case']}\n{r['impl'].split('(')[0].strip()}, {r['threads']}T"
              + (", random order" if r["order"] == "random" else "") for r in rows]
    vals = [r["ms_per_1M"] for r in rows]
    floors = [r["floor_ms"] * 1e6 / r.get("n", remap["n_splats"]) for r in rows]
    fig, ax = plt.subplots(figsize=(10, 0.42 * len(rows) + 1.5))
    y = np.arange(len(rows))
    ax.barh(y, vals, color=["#4c72b0" if "fast" in r["impl"] else "#999999" for r in rows])
    ax.scatter(floors, y, marker="|", s=200, color="k", label="bandwidth floor")
    ax.axvline(remap.get("target_ms", 8.0), color="#c44e52", ls="--", label="target 8 ms / 1M")
    ax.set_yticks(y, labels, fontsize=7)
    ax.set_xscale("log")
    ax.set_xlabel("ms per 1M splats (log)")
    ax.invert_yaxis()
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title(f"Remap, {remap['n_splats']:,} splats, {remap['n_faces']:,} faces")
    fig.tight_layout()
    path = out / "remap_speed.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path.name


def _acc_rows(acc, **sel):
    return [r for r in acc["rows"] if all(r[k] == v for k, v in sel.items())]


PROFILE_STYLE = {"games": ("#55a868", "o"), "local/affine": ("#4c72b0", "s"),
                 "local/rigid": ("#c44e52", "^")}
QUANT_MARK = {"float32": "o", "float16": "x", "norm16": "D"}


def plot_accuracy(acc: dict, out: Path) -> list[str]:
    plt = _plt()
    if plt is None:
        return []
    names = []
    defs = ("stretch", "twist", "bend")
    # magnitude
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6), sharey=True)
    for ax, d in zip(axes, defs):
        for prof, (col, mk) in PROFILE_STYLE.items():
            rows = sorted(_acc_rows(acc, profile=prof, level=0, quant="float32", deformation=d),
                          key=lambda r: r["magnitude"])
            if rows:
                ax.plot([r["magnitude"] for r in rows], [r["w2_p99"] for r in rows], marker=mk,
                        color=col, label=f"{prof} p99")
                ax.plot([r["magnitude"] for r in rows], [r["w2_p50"] for r in rows], marker=mk,
                        color=col, ls=":", alpha=0.7, label=f"{prof} median")
        ax.set_title(d)
        ax.set_xlabel("magnitude")
        ax.set_yscale("log")
    axes[0].set_ylabel("W₂ / splat size")
    axes[-1].legend(fontsize=7)
    fig.suptitle(f"Error against analytic truth, finest anchor mesh ({acc['levels'][0]:,} faces)")
    fig.tight_layout()
    fig.savefig(out / "accuracy_magnitude.png", dpi=110)
    plt.close(fig)
    names.append("accuracy_magnitude.png")
    # resolution
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6), sharey=True)
    for ax, d in zip(axes, defs):
        for prof, (col, mk) in PROFILE_STYLE.items():
            rows = sorted(_acc_rows(acc, profile=prof, quant="float32", deformation=d,
                                    magnitude=5), key=lambda r: r["faces"])
            if rows:
                ax.plot([r["faces"] for r in rows], [r["w2_p99"] for r in rows], marker=mk,
                        color=col, label=prof)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(f"{d}, magnitude 5")
        ax.set_xlabel("anchor-mesh faces")
    axes[0].set_ylabel("W₂ / splat size, p99")
    axes[-1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "accuracy_resolution.png", dpi=110)
    plt.close(fig)
    names.append("accuracy_resolution.png")
    # quantization
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    profs = list(PROFILE_STYLE)
    quants = ("float32", "float16", "norm16")
    for ax, (d, m, title) in zip(axes, (("rest", 1, "at rest (quantization alone)"),
                                        ("twist", 5, "twist, magnitude 5"))):
        w = 0.25
        for qi, q in enumerate(quants):
            vals = []
            for p in profs:
                rows = _acc_rows(acc, profile=p, level=0, quant=q, deformation=d, magnitude=m)
                vals.append(rows[0]["w2_p99"] if rows else np.nan)
            ax.bar(np.arange(len(profs)) + (qi - 1) * w, vals, w, label=q)
        ax.set_xticks(np.arange(len(profs)), profs)
        ax.set_yscale("log")
        ax.set_title(title)
        ax.set_ylabel("W₂ / splat size, p99")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "accuracy_quantization.png", dpi=110)
    plt.close(fig)
    names.append("accuracy_quantization.png")
    return names


def pareto_points(acc: dict, magnitude: int) -> list[dict]:
    """One point per (profile, level, quant): worst of the three deformations' p99 W₂/size."""
    pts = []
    for c in acc["costs"]:
        rows = [r for r in acc["rows"] if r["profile"] == c["profile"] and r["level"] == c["level"]
                and r["quant"] == c["quant"] and r["magnitude"] == magnitude]
        if not rows:
            continue
        worst = max(rows, key=lambda r: r["w2_p99"])
        pts.append({**c, "error": worst["w2_p99"], "worst": worst["deformation"]})
    return pts


def _front(xs, ys):
    order = np.lexsort((ys, xs))
    best = np.inf
    keep = []
    for i in order:
        if ys[i] < best:
            keep.append(i)
            best = ys[i]
    return keep


def plot_pareto(acc: dict, out: Path, magnitude: int) -> str | None:
    plt = _plt()
    pts = pareto_points(acc, magnitude)
    if plt is None or not pts:
        return None
    fig, axes = plt.subplots(1, 3, figsize=(13, 4), sharey=True)
    for ax, (key, label, logx) in zip(axes, (("faces", "anchor-mesh faces (physics cost)", True),
                                              ("anchor_bytes", "anchor bytes per splat", False),
                                              ("remap_ms", "remap ms per frame (this object, 1 thread)", True))):
        xs = np.array([p.get(key, np.nan) for p in pts], float)
        ys = np.array([p["error"] for p in pts], float)
        for p, x, y in zip(pts, xs, ys):
            col, _ = PROFILE_STYLE[p["profile"]]
            ax.scatter(x, y, color=col, marker=QUANT_MARK[p["quant"]], s=30)
        ok = np.isfinite(xs) & np.isfinite(ys)
        idx = np.flatnonzero(ok)
        if idx.size:
            front = idx[_front(xs[idx], ys[idx])]
            ax.step(xs[front], ys[front], where="post", color="k", lw=1, alpha=0.6)
        if logx:
            ax.set_xscale("log")
            from matplotlib.ticker import NullFormatter

            ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_yscale("log")
        ax.set_xlabel(label)
    axes[0].set_ylabel(f"worst p99 W₂ / splat size (magnitude {magnitude})")
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color=c, marker=m, ls="", label=p) for p, (c, m) in PROFILE_STYLE.items()]
    handles += [Line2D([], [], color="gray", marker=m, ls="", label=q) for q, m in QUANT_MARK.items()]
    handles.append(Line2D([], [], color="k", label="Pareto front"))
    axes[-1].legend(handles=handles, fontsize=7)
    fig.suptitle("Error against cost: each point is a profile × anchor resolution × quantization")
    fig.tight_layout()
    fig.savefig(out / "pareto.png", dpi=110)
    plt.close(fig)
    return "pareto.png"


def plot_stretch(stretch: dict, out: Path) -> str | None:
    plt = _plt()
    if plt is None or not stretch.get("rows"):
        return None
    methods = list(dict.fromkeys(r["method"] for r in stretch["rows"]))
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    for m in methods:
        rows = sorted([r for r in stretch["rows"] if r["method"] == m], key=lambda r: r["stretch"])
        s = [r["stretch"] for r in rows]
        style = "--" if m.startswith("cage") else ":" if m.startswith("truth") else "-"
        axes[0].plot(s, [100 * r["off_surface"] for r in rows], style, marker="o", label=m)
        axes[1].plot(s, [r["extent_p99"] for r in rows], style, marker="o", label=m)
        axes[2].plot(s, [r["extent_max"] for r in rows], style, marker="o", label=m)
    axes[0].set_ylabel(f"% splats > {100 * stretch['tau_diag']:.1f}% diag from surface")
    axes[1].set_ylabel("splat extent / triangle edge, p99")
    axes[2].set_ylabel("splat extent / triangle edge, max")
    for ax in axes:
        ax.set_xlabel("peak stretch factor")
        ax.set_xticks([2, 5, 10])
    axes[2].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "stretch.png", dpi=110)
    plt.close(fig)
    return "stretch.png"


# --------------------------------------------------------------------------- markdown

def _remap_md(remap: dict) -> list[str]:
    L = ["## Remap speed", ""]
    if "error" in remap:
        return L + [f"Not measured: {remap['error']}", ""]
    L.append(f"{remap['n_splats']:,} splats sorted by face, anchored to {remap['n_faces']:,} faces "
             f"({remap['n_vertices']:,} vertices); see `benchmarks/remap.py` for the workload and the floor.")
    L.append("")
    bw = remap.get("bandwidth", [])
    if bw:
        L.append("Copy bandwidth measured in this run (numba parallel copy, bytes read + written; the "
                 "median of the copies timed before and after each fast-path timing, the floor of every row): "
                 + "; ".join(f"{b['threads']} thread{'s' if b['threads'] > 1 else ''}: **{b['gb_s']:.1f} GB/s**"
                             + (f" (median of {b['samples']})" if b.get("samples") else "")
                             + (f" {DAGGER}" if b.get("contended") else "") for b in bw)
                 + (f"; numpy `copyto` 1 thread: {remap['numpy_copy_gb_s']:.1f} GB/s" if "numpy_copy_gb_s" in remap else "")
                 + ".")
        L.append("")
    h = remap.get("headline")
    if h:
        verdict = ("**met**" if h["ms_per_1M"] <= remap["target_ms"] else "**not met**")
        L.append(f"**Headline**: `local`/`affine` fast path, {h['threads']} threads: **{h['ms_per_1M']:.2f} ms per 1M "
                 f"splats** ({h['msplats_s']:.0f} M splats/s; best repetition {h['best_ms'] * 1e6 / remap['n_splats']:.2f} ms) "
                 f"against the target of ≤ {remap['target_ms']:g} ms: {verdict}"
                 + (" (quick run: smaller workload, target not judged)" if remap.get("target_met") is None else "")
                 + f". Floor: {h['bytes_per_splat']} B/splat at the measured {h['threads']}-thread copy bandwidth = "
                 f"{h['floor_ms'] * 1e6 / remap['n_splats']:.2f} ms per 1M, so the remap runs at "
                 f"**{100 * h['floor_fraction']:.0f}% of the bandwidth floor**."
                 + (f" {DAGGER} measured while other processes kept the CPU busy." if h["contended"] else ""))
        L.append("")
        goals = [f"- share of the copy floor, `local`/`affine`, {h['threads']} threads: "
                 f"**{100 * h['floor_fraction']:.0f} %** (goal ≥ 60 %: "
                 + ("met" if h["floor_fraction"] >= 0.6 else
                    f"missed by {100 * (1 - h['floor_fraction'] / 0.6):.0f} %") + ")"]
        if "scaling_ratio" in remap:
            ratio = remap["scaling_ratio"]
            goals.append(f"- per-splat cost of a tenth of the splats on the same mesh over the full "
                         f"count: **{ratio:.2f}×** (goal ≤ 1.3: "
                         + ("met" if ratio <= 1.3 else f"missed by {100 * (ratio / 1.3 - 1):.0f} %")
                         + ")")
            split = remap.get("face_split")
            if split:
                goals.append(
                    f"- where the ratio comes from (least squares over the scaling rows, core "
                    f"time): **{split['face_ns']:.1f} ns per face** computed, "
                    f"**{split['splat_ns']:.1f} ns per splat**; a tenth of the splats touches "
                    f"{split['small_faces_per_splat']:.2f} faces a splat against "
                    f"{split['mid_faces_per_splat']:.2f}, so 1.3× needs a face to cost at most "
                    f"{split['face_budget']:.2f} splats; it costs "
                    f"{split['face_ns'] / split['splat_ns']:.2f}"
                    + (f". The float64 arithmetic of a face alone (two square roots, four "
                       f"divisions), vectorised on one core: **{split['arithmetic_ns']:.2f} ns**"
                       if "arithmetic_ns" in split else ""))
        L += goals + [""]
    rows = []
    for r in remap["rows"]:
        rows.append([r["case"], r["impl"], r["threads"], r["order"],
                     _f(r["ms"]) + (f" {DAGGER}" if r["contended"] else ""), _f(r["ms_per_1M"]),
                     _f(r["msplats_s"]), r["bytes_per_splat"], _f(r["floor_ms"]),
                     f"{100 * r['floor_fraction']:.1f}%", _f(r.get("face_pass_ms")), _load(r["other_cores"])])
    L.append(_table(["profile", "implementation", "threads", "splat order", "ms / frame", "ms / 1M splats",
                     "M splats/s", "bytes/splat", "floor ms", "% of floor", "face pass ms",
                     "other cores busy"], rows))
    L.append("")
    checks = [r for r in remap["rows"] if r.get("check")]
    if checks:
        L.append("Fast path against the float64 reference on this workload: "
                 + "; ".join(f"{r['case']}: max |Δμ| {r['check']['max_mean_err']:.1e}, max relative ‖ΔΣ‖_F "
                             f"{r['check']['max_cov_rel_err']:.1e}" for r in checks if r["threads"] == 1) + ".")
        L.append("")
    for n in remap.get("notes", []):
        L.append(f"- {n}")
    L.append("")
    return L


def _convert_md(conv: dict) -> list[str]:
    from .convert import markdown

    return markdown(conv)


def _external_md(title: str, ext: dict | None, command: str) -> list[str]:
    L = [f"## {title}", ""]
    if not ext:
        return L + ["Not run.", ""]
    if ext.get("missing"):
        return L + [f"Skipped: `{ext['missing']}` is not present in this checkout.", ""]
    L.append(f"`{command}` (a separate process: {ext['wall_s']:.1f} s, peak RSS {ext['peak_rss_mb']:.0f} MiB"
             + (f", exit status {ext['rc']}" if ext["rc"] else "") + "):")
    L.append("")
    text = ext["output"].strip()
    lines = [ln for ln in text.splitlines() if "TBB" not in ln and "warnings.warn" not in ln]
    # Its own headings become sub-headings of this section.
    lines = ["##" + ln if ln.startswith("#") else ln for ln in lines]
    L.append("\n".join(lines))
    L.append("")
    return L


def _memory_md(res: dict) -> list[str]:
    L = ["## Peak memory", ""]
    rows = []
    rm = res.get("remap", {})
    if "peak_numpy_remap_mb" in rm:
        rows.append([f"numpy reference `remap`, local/affine, {rm['n_splats']:,} splats (tracemalloc peak per call)",
                     _f(rm["peak_numpy_remap_mb"])])
    if "fast_buffers_mb" in rm:
        rows.append(["fast path: per-asset buffers (per-splat constants, face table, outputs)",
                     _f(rm["fast_buffers_mb"])])
        rows.append(["fast path: extra allocation per `remap` call (tracemalloc peak)",
                     _f(rm["peak_fast_remap_mb"])])
    conv = res.get("convert") or {}
    if "cli_peak_rss_mb" in conv:
        rows.append([f"`gsverse-convert`, {conv['n_splats']:,} splats (process peak RSS)", _f(conv["cli_peak_rss_mb"])])
    if "plain_peak_rss_mb" in conv:
        rows.append(["`gsverse-convert --plain` of the same PLY (process peak RSS)",
                     _f(conv["plain_peak_rss_mb"])])
    for key, label in (("binding", "binding benchmark process"), ("validate", "validation benchmark process")):
        ext = res.get(key) or {}
        if "peak_rss_mb" in ext:
            rows.append([f"{label} (peak RSS)", _f(ext["peak_rss_mb"])])
    if "self_peak_rss_mb" in res:
        rows.append(["this benchmark process (peak RSS)", _f(res["self_peak_rss_mb"])])
    L.append(_table(["what", "MiB"], rows))
    L.append("")
    return L


def _acc_md(acc: dict, plots: dict) -> list[str]:
    L = ["## Accuracy against analytic deformations", ""]
    L.append(f"Object: {acc['n_splats']:,} surface splats on a bumpy bar meshed with {acc['fine_faces']:,} faces; "
             f"anchor meshes of {', '.join(f'{x:,}' for x in acc['levels'])} faces (decimation). "
             "Errors are per splat: position error / splat size (σ = √(tr Σ/3) of the true splat), relative "
             "Frobenius covariance error, and the 2-Wasserstein distance between candidate and true Gaussian "
             "/ splat size; median and 99th percentile. See `benchmarks/accuracy.py` for φ, the object and the metrics.")
    L.append("")
    for n in acc.get("notes", []):
        L.append(f"- {n}")
    L.append("### By profile, deformation and magnitude (finest anchor mesh, float32 anchors)")
    L.append("")
    rows = []
    for r in acc["rows"]:
        if r["level"] == 0 and r["quant"] == "float32":
            rows.append([r["profile"], r["deformation"], r["magnitude"] if r["deformation"] != "rest" else "–",
                         f"{_f(r['pos_p50'])} / {_f(r['pos_p99'])}", f"{_f(r['cov_p50'])} / {_f(r['cov_p99'])}",
                         f"{_f(r['w2_p50'])} / {_f(r['w2_p99'])}"])
    L.append(_table(["profile", "φ", "magnitude", "position / size (median / p99)",
                     "‖ΔΣ‖_F/‖Σ‖_F (median / p99)", "W₂ / size (median / p99)"], rows))
    L.append("")
    if plots.get("accuracy_magnitude.png"):
        L += ["![error by magnitude](accuracy_magnitude.png)", ""]
    L.append("### By anchor-mesh resolution (float32 anchors, magnitude 5) with the cost of each point")
    L.append("")
    rows = []
    cost = {(c["profile"], c["level"], c["quant"]): c for c in acc["costs"]}
    for prof in ("games", "local/affine", "local/rigid"):
        for li, faces in enumerate(acc["levels"]):
            cells = []
            for d in ("stretch", "twist", "bend"):
                rr = [r for r in acc["rows"] if r["profile"] == prof and r["level"] == li and r["quant"] == "float32"
                      and r["deformation"] == d and r["magnitude"] == 5]
                cells.append(f"{_f(rr[0]['pos_p99'])} / {_f(rr[0]['w2_p99'])}" if rr else "–")
            c = cost.get((prof, li, "float32"), {})
            rows.append([prof, f"{faces:,}", *cells, _f(c.get("remap_ms")) + (f" {DAGGER}" if c.get("remap_contended") else ""),
                         _f(c.get("anchor_bytes"))])
    L.append(_table(["profile", "faces", "stretch: pos p99 / W₂ p99", "twist: pos p99 / W₂ p99",
                     "bend: pos p99 / W₂ p99", "remap ms / frame (1 thread)", "anchor bytes / splat"], rows))
    L.append("")
    if plots.get("accuracy_resolution.png"):
        L += ["![error by resolution](accuracy_resolution.png)", ""]
    L.append("### By anchor quantization (finest anchor mesh)")
    L.append("")
    L.append("float16 is not a glTF component type (an upper bound for half-precision buffers); "
             "norm16 is what the glTF writer stores with `quantize={'barycentrics': 'unsigned_short', "
             "'localRotation': 'short'}` (barycentrics stay FLOAT when some lie outside [0, 1]). "
             "Normal offsets and scales stay float32 except in float16.")
    L.append("")
    rows = []
    for prof in ("games", "local/affine", "local/rigid"):
        for q in ("float32", "float16", "norm16"):
            rest = [r for r in acc["rows"] if r["profile"] == prof and r["level"] == 0 and r["quant"] == q
                    and r["deformation"] == "rest"]
            tw = [r for r in acc["rows"] if r["profile"] == prof and r["level"] == 0 and r["quant"] == q
                  and r["deformation"] == "twist" and r["magnitude"] == 10]
            c = cost.get((prof, 0, q), {})
            if not rest:
                continue
            rows.append([prof, q, f"{_f(rest[0]['pos_p99'])} / {_f(rest[0]['cov_p99'])} / {_f(rest[0]['w2_p99'])}",
                         f"{_f(tw[0]['w2_p99'])}" if tw else "–", _f(c.get("anchor_bytes")), c.get("note", "")])
    L.append(_table(["profile", "anchors", "at rest: pos / cov / W₂ (p99)", "twist 10: W₂ p99",
                     "anchor bytes / splat", "note"], rows))
    L.append("")
    if plots.get("accuracy_quantization.png"):
        L += ["![error by quantization](accuracy_quantization.png)", ""]
    L.append("### SH degree (size only; the remap passes SH through)")
    L.append("")
    L.append("Measured GLB bytes per splat for the same object (finest anchor mesh, included in the file):")
    L.append("")
    rows = []
    for s in acc["sh_sizes"]:
        rows.append([s["sh_degree"], _f(s["plain"]), _f(s["local/float32"]), _f(s["local/norm16"]),
                     _f(s["games/float32"]), _f(s["games/norm16"])])
    L.append(_table(["SH degree", "plain KHR (no anchors)", "local, float32", "local, norm16",
                     "games, float32", "games, norm16"], rows))
    L.append("")
    mag = plots.get("pareto_magnitude", 5)
    L.append(f"### Error against cost (Pareto), magnitude {mag}")
    L.append("")
    pts = pareto_points(acc, mag)
    rows = []
    for p in sorted(pts, key=lambda p: p["error"]):
        rows.append([p["profile"], f"{p['faces']:,}", p["quant"], _f(p["error"]), p["worst"],
                     _f(p.get("remap_ms")), _f(p["anchor_bytes"])])
    L.append(_table(["profile", "faces", "anchors", "worst p99 W₂/size", "worst φ",
                     "remap ms (1 thread)", "anchor bytes/splat"], rows))
    L.append("")
    if plots.get("pareto.png"):
        L += ["![Pareto](pareto.png)", ""]
    return L


def _stretch_md(st: dict, plots: dict) -> list[str]:
    L = ["## Stretch: our profiles against a VR-GS-style cage", ""]
    L.append(f"Local stretch of the bar's middle to 2×, 5× and 10×. Off surface: mean farther than "
             f"τ = {100 * st['tau_diag']:.1f}% of the rest bounding-box diagonal (or than one mean edge of the fine "
             f"mesh, {st['mean_edge']:.3g}) from φ(fine mesh). Extent: {st['note']}. The truth row is φ applied exactly.")
    L.append("")
    rows = []
    for r in st["rows"]:
        rows.append([r["method"], f"{r['stretch']}×", f"{100 * r['off_surface']:.2f}%",
                     f"{100 * r['off_surface_edge']:.2f}%", _f(r["dist_p99_diag"]), _f(r["extent_p99"]),
                     _f(r["extent_max"])])
    L.append(_table(["method", "stretch", "off surface (> τ)", "off surface (> 1 edge)", "p99 distance / diag",
                     "extent / edge, p99", "extent / edge, max"], rows))
    L.append("")
    if plots.get("stretch.png"):
        L += ["![stretch](stretch.png)", ""]
    return L


def write_report(res: dict, out: Path) -> Path:
    """Write ``report.md``, the PNG plots and ``results.json`` into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    plots: dict = {"pareto_magnitude": 5}
    have_plt = _plt() is not None
    if have_plt:
        if res.get("remap", {}).get("rows"):
            plots["remap_speed.png"] = plot_remap(res["remap"], out)
        acc = res.get("accuracy")
        if acc:
            for name in plot_accuracy(acc, out):
                plots[name] = name
            plots["pareto.png"] = plot_pareto(acc, out, plots["pareto_magnitude"])
            plots["stretch.png"] = plot_stretch(acc["stretch"], out)
    L = ["# gsverse-format benchmarks", ""]
    meta = res["meta"]
    L.append(f"Command: `{meta['command']}` ({'quick' if meta['quick'] else 'full'} run, {meta['seconds']:.0f} s).")
    L.append("")
    L.append(f"Machine: {meta['cpu']}, {meta['cores']} cores, {meta['memory_gib']:.0f} GiB RAM; "
             f"Python {meta['python']}, " + ", ".join(f"{k} {v}" for k, v in meta["versions"].items()) + ".")
    L.append(f"Date: {meta['date']}.")
    L.append("")
    L.append(f"Timings: median over repetitions in batches during which other processes used less than a quarter "
             f"of a core; {DAGGER} marks values for which no such batch existed (the machine was busy: those are "
             "pessimistic). 'other cores busy' is the range over batches of the CPU other processes used.")
    if not have_plt:
        L.append("")
        L.append("Plots were skipped: matplotlib is not installed (`pip install matplotlib`).")
    L.append("")
    if "remap" in res:
        L += _remap_md(res["remap"])
        if plots.get("remap_speed.png"):
            L += ["![remap speed](remap_speed.png)", ""]
    L += _external_md("Binding: nearest triangle, against Open3D and trimesh", res.get("binding"),
                      res.get("binding", {}).get("command", "python -m benchmarks.binding"))
    if "convert" in res:
        L += _convert_md(res["convert"])
    L += _external_md("Validation", res.get("validate"),
                      res.get("validate", {}).get("command", "python -m benchmarks.validate"))
    if "hostile" in res:
        L += _external_md("Hostile inputs", res.get("hostile"),
                          res.get("hostile", {}).get("command", "python -m benchmarks.hostile"))
    if "size" in res:
        L += _external_md("File size: anchored against plain KHR", res.get("size"),
                          res.get("size", {}).get("command", "python -m benchmarks.size"))
    L += _memory_md(res)
    if res.get("accuracy"):
        L += _acc_md(res["accuracy"], plots)
        L += _stretch_md(res["accuracy"]["stretch"], plots)
    if res.get("render"):
        from .render import markdown as render_md

        L += render_md(res["render"]) + [""]
    if res.get("engines"):
        from .engines import markdown as engines_md

        L += engines_md(res["engines"])
    path = out / "report.md"
    path.write_text("\n".join(L) + "\n", encoding="utf-8")
    (out / "results.json").write_text(json.dumps(res, indent=1, default=_json_default), encoding="utf-8")
    return path


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (set, tuple)):
        return list(o)
    return str(o)
