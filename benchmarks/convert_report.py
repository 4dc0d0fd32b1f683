"""The report of :mod:`benchmarks.convert`: its tables and goals as Markdown lines."""
from __future__ import annotations

import numpy as np


def _f(x, digits: int = 3) -> str:
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "–"
    return f"{x:.{digits}g}"


def _table(header: list[str], rows: list[list]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def _goal(what: str, value: float, limit: float, low: float | None = None) -> str:
    """``what: value× (goal ≤ limit: met / missed by …)``; with ``low``, the goal is the band
    [low, limit]."""
    if low is None:
        ok, band = value <= limit, f"≤ {limit:g}"
        miss = 100.0 * (value / limit - 1.0)
    else:
        ok, band = low <= value <= limit, f"{low:g}–{limit:g}"
        miss = 100.0 * (value / limit - 1.0 if value > limit else 1.0 - value / low)
    verdict = "met" if ok else f"missed by {miss:.0f} %"
    return f"{what}: **{value:.2f}×** (goal {band}: {verdict})"


def scaling_markdown(scale: list[dict], n_faces: int) -> list[str]:
    """The scaling table and its goals: anchored ≤ 1.5× plain at every size, with the mesh as
    PLY and as OBJ; time per splat from 1M to 4M not growing by more than 20 %; peak RSS ≤ 3×
    the input."""
    if not scale:
        return []
    rounds = scale[0].get("rounds", 1)
    L = [f"Scaling (the same {n_faces:,}-face mesh, as PLY and as OBJ; each command a fresh "
         f"process, the four commands interleaved, their order rotated each round, median of "
         f"{rounds} round(s); × plain = the median over the rounds of the anchored time over "
         "the plain time of the same round; µs per splat = "
         "wall time / splats, start-up included; peak = the largest peak RSS of the rounds, "
         "over the input file's size; memory made resident before each run, untimed, see "
         "`benchmarks/processes.py`):", ""]
    rows = []
    for r in scale:
        row = [f"{r['n_splats']:,}", _f(r["input_mb"])]
        for key in ("plain", "anchored", "anchored_obj", "validate"):
            if f"{key}_s" not in r:
                row += ["failed", "–", "–"]
                continue
            middle = (_f(r[f"{key}_us_per_splat"]) if key in ("plain", "validate") or
                      f"{key}_over_plain" not in r else f"{r[f'{key}_over_plain']:.2f}×")
            row += [_f(r[f"{key}_s"]), middle, _f(r[f"{key}_peak_rss_mb"] / r["input_mb"])]
        rows.append(row)
    L.append(_table(["splats", "input MiB", "plain s", "plain µs/splat", "plain peak ×",
                     "anchored (PLY mesh) s", "× plain", "peak ×", "anchored (OBJ mesh) s",
                     "× plain", "peak ×", "validate s", "validate µs/splat", "peak ×"], rows))
    L.append("")
    goals = []
    for r in scale:
        for key, what in (("anchored", "PLY"), ("anchored_obj", "OBJ")):
            if f"{key}_over_plain" in r:
                goals.append(_goal(f"{r['n_splats']:,} splats, anchored ({what} mesh) / `--plain`",
                                   r[f"{key}_over_plain"], 1.5)
                             + f" (ratio of the medians: {r[f'{key}_s'] / r['plain_s']:.2f}×)")
    by_n = {r["n_splats"]: r for r in scale}
    if 1_000_000 in by_n and 4_000_000 in by_n:
        a, b = by_n[1_000_000], by_n[4_000_000]
        for key, what in (("plain", "`--plain`"), ("anchored", "anchored"),
                          ("validate", "`gsverse-validate`")):
            if f"{key}_us_per_splat" in a and f"{key}_us_per_splat" in b:
                # flat means no growth per splat: below 0.8 the process's fixed costs (start-up,
                # imports, numba's set-up) are spread over four times the splats
                ratio = b[f"{key}_us_per_splat"] / a[f"{key}_us_per_splat"]
                goals.append(_goal(f"{what} time per splat, 4M / 1M", ratio, 1.2)
                             + (" (lower at 4M: the fixed costs of a process spread over more "
                                "splats)" if ratio < 0.8 else ""))
    # (below 1M splats the interpreter and the libraries outweigh the input)
    worst = max(((r[k] / r["input_mb"], r["n_splats"]) for r in scale for k in r
                 if k.endswith("_peak_rss_mb") and r["n_splats"] >= 1_000_000), default=None)
    if worst is not None:
        goals.append(_goal(f"largest peak RSS / input (at {worst[1]:,} splats)", worst[0], 3.0))
    return L + [f"- {g}" for g in goals] + [""]


def first_run_markdown(first: dict) -> list[str]:
    """The first conversion after installing, against a warm one."""
    if not first:
        return []
    if "skipped" in first:
        return [f"First anchored conversion after installing: {first['skipped']}.", ""]
    L = [f"First anchored conversion after installing ({first['n_splats']:,} splats, "
         f"{first['n_faces']:,} faces; an empty `NUMBA_CACHE_DIR`; each a fresh process):", ""]
    if "error" in first:
        return L + ["The measurement failed:", "", "```", first["error"], "```", ""]
    L.append(_table(["run", "wall s", "/ warm"], [
        ["an empty numba cache, no precompile (an anchored conversion runs no numba kernel)",
         _f(first["uncompiled_s"]),
         f"{first['uncompiled_over_warm']:.2f}×"],
        ["`python -m gsverse_format.precompile` (the README's set-up)", _f(first["precompile_s"]),
         "–"],
        ["first conversion after it", _f(first["first_s"]), f"{first['first_over_warm']:.2f}×"],
        ["warm (median of two later runs)", _f(first["warm_s"]), "1×"]]))
    L.append("")
    L.append("- " + _goal("first conversion after installing / warm", first["first_over_warm"], 1.5))
    return L + [""]


def markdown(conv: dict) -> list[str]:
    """The report section (Markdown lines) for the result of :func:`run`."""
    L = ["## `gsverse-convert` end to end", ""]
    if not conv:
        return L + ["Not run.", ""]
    if "plain" not in conv:   # a failure before the runs
        return L + ["The benchmark failed:", "", "```", str(conv.get("error", "")), "```", ""]
    input_mb = conv["input_mb"]
    L.append(f"A 3DGS PLY of {conv['n_splats']:,} splats (SH degree 3 with normals, "
             f"{input_mb:.1f} MiB) and a {conv['n_faces']:,}-face mesh PLY; each command a fresh "
             f"process, the commands interleaved, their order rotated each round, median of "
             f"{conv['repeat']} round(s); the ratios of times are medians over the rounds of the "
             "two commands' times in the same round; peak RSS of "
             "the process; memory made resident before each run, untimed (a virtual machine's "
             "free page reporting otherwise adds up to a second to a run, see "
             "`benchmarks/processes.py`).")
    L.append("")
    rows = []
    st = conv["splat_transform"]
    label = f"PlayCanvas `splat-transform` {conv.get('splat_transform_version', '')}, PLY → GLB"
    named = ((label.replace("  ", " "), st), ("`gsverse-convert --plain` (format only)", conv["plain"]),
             ("`gsverse-convert --mesh` (anchored)", conv["anchored"]))
    for name, r in named:
        if "skipped" in r:
            rows.append([name, f"skipped: {r['skipped']}", "–", "–", "–"])
        elif "error" in r:
            rows.append([name, "failed: " + r["error"].strip().splitlines()[-1][:120], "–", "–", "–"])
        else:
            rows.append([name, _f(r["wall_s"]), _f(r["peak_rss_mb"], 4),
                         _f(r["peak_rss_mb"] / input_mb), _f(r["output_mb"], 4)])
    L.append(_table(["run", "wall s", "peak RSS MiB", "peak RSS / input", "output MiB"], rows))
    L.append("")
    ratios = conv.get("ratios", {})

    def goal(what: str, value: float, limit: float) -> str:
        verdict = "met" if value <= limit else f"missed by {100.0 * (value / limit - 1.0):.0f} %"
        return f"{what}: **{value:.2f}×** (goal ≤ {limit:g}: {verdict})"

    goals = []
    if "plain_over_splat_transform" in ratios:
        goals.append(goal("`--plain` / splat-transform wall time",
                          ratios["plain_over_splat_transform"], 1.0))
    if "anchored_over_plain" in ratios:
        goals.append(goal("anchored / `--plain` wall time", ratios["anchored_over_plain"], 1.5))
    for key, what in (("plain", "`--plain`"), ("anchored", "anchored")):
        if f"{key}_rss_over_input" in ratios:
            goals.append(goal(f"{what} peak RSS / input size", ratios[f"{key}_rss_over_input"], 3.0))
    L += [f"- {g}" for g in goals]
    if conv["n_splats"] < 500_000:
        L.append(f"- At {conv['n_splats']:,} splats these ratios mostly compare start-up costs "
                 "(interpreters, imports): the goals are stated for 1M splats.")
    L.append("")
    for key, what in (("stages", "plain"), ("anchored_stages", "anchored")):
        stages = conv.get(key) or []
        if not stages:
            continue
        if "error" in stages[0]:
            L += [f"The {what} memory breakdown failed:", "", "```", stages[0]["error"], "```", ""]
            continue
        L.append(f"Where the memory of the {what} conversion goes (a fresh process; traced: numpy "
                 "and Python allocations during the stage; RSS and peak RSS of the process after "
                 "it; the PLY is memory-mapped, so its pages count in RSS but not in the traced "
                 "bytes" + ("; numba's compiled kernels count in RSS only" if key != "stages" else "")
                 + "):")
        L.append("")
        L.append(_table(["stage", "seconds", "traced peak MiB", "traced kept MiB", "RSS MiB",
                         "peak RSS MiB"],
                        [[s["stage"], _f(s["seconds"]), _f(s["traced_peak_mb"]),
                          _f(s["traced_kept_mb"]), _f(s.get("VmRSS"), 4), _f(s.get("VmHWM"), 4)]
                         for s in stages]))
        L.append("")
    L += scaling_markdown(conv.get("scaling") or [], conv["n_faces"])
    L += first_run_markdown(conv.get("first_run") or {})
    return L
