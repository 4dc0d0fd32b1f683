"""``python -m benchmarks.binding --quick`` runs and prints its table (timings are not checked)."""
from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_binding_benchmark_quick():
    pytest.importorskip("numba")
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    out = subprocess.run([sys.executable, "-m", "benchmarks.binding", "--quick"], cwd=ROOT,
                         env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    text = out.stdout
    assert "| method | Mpts/s (median) | Mpts/s (best) | threads | exact? |" in text
    rows = [line for line in text.splitlines() if line.startswith("| ours")]
    from gsverse_format.nearest import _native

    generic = int(_native.level() > 0)   # the generic query loop beside the one this CPU runs
    assert len(rows) == 4 + generic
    assert "numba" in rows[0] and "identical to numpy reference" in rows[0]
    assert "native" in rows[1] and "identical to numba's" in rows[1]
    if generic:
        assert "generic x86-64 query loop" in rows[2] and "identical to numba's" in rows[2]
    assert "`bind_local`" in rows[2 + generic] and "ours: `bind_local`" in text
    assert "ratio ours / Open3D" in text


def test_convert_benchmark_quick():
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    out = subprocess.run([sys.executable, "-m", "benchmarks.convert", "--quick", "--sizes", "10k",
                          "--repeat", "1"], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    text = out.stdout
    assert "| run | wall s | peak RSS MiB | peak RSS / input | output MiB |" in text
    rows = {line.split(" | ")[0]: line for line in text.splitlines() if line.startswith("| ")}
    for name in ("| `gsverse-convert --plain` (format only)", "| `gsverse-convert --mesh` (anchored)"):
        cells = rows[name].strip("| ").split(" | ")
        assert all(float(c) > 0 for c in cells[1:]), rows[name]   # wall, RSS, ratio, output
    assert "anchored / `--plain` wall time" in text
    assert "| read the PLY (file frame) |" in text and "| write the GLB |" in text
    scaling = [line for line in text.splitlines() if line.startswith("| 10,000 |")]
    assert len(scaling) == 1 and "failed" not in scaling[0]



def test_size_benchmark_puts_the_three_layouts_side_by_side():
    """A small run of ``python -m benchmarks.size``: the side-by-side table has one row per SH
    degree, and its sizes and ratios are those of the detailed rows (sizes are exact); the
    delivery table adds the SPZ-compressed layouts and splat-transform's .spz, with the
    decoded rest pose within the stated bounds."""
    import re

    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    out = subprocess.run([sys.executable, "-m", "benchmarks.size", "--splats", "3000",
                          "--faces", "300"], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    lines = out.stdout.splitlines()
    detail = {}
    for line in lines:     # | SH | layout | bits | bytes | ...
        cells = [c.strip() for c in line.split("|")[1:-1]]
        if len(cells) == 9 and cells[2] == "32":
            detail[int(cells[0]), cells[1]] = int(cells[3].replace(",", ""))
    side = [line for line in lines if re.match(r"\| [03] \| [0-9,]+ \|", line)]
    assert len(side) == 2
    for line in side:
        cells = line.strip("| ").split(" | ")
        degree, plain, explicit, compact = int(cells[0]), *(int(c.replace(",", ""))
                                                           for c in cells[1:4])
        assert (detail[degree, "plain KHR"], detail[degree, "anchored, explicit"],
                detail[degree, "anchored, compact (default)"]) == (plain, explicit, compact)
        assert plain < compact < explicit
        assert cells[4:] == [f"{explicit / plain:.3f}×", f"{compact / plain:.3f}×",
                             f"{explicit / compact:.3f}×"]
    # the delivery table: the same splats in every layout, SPZ against splat-transform's
    delivery = [line.strip("| ").split(" | ") for line in lines
                if re.match(r"\| 3,000 \| [03] \|", line)]
    assert [int(r[1]) for r in delivery] == [0, 3]
    for r in delivery:
        plain, explicit, compact, compact_spz, plain_spz = (int(c.replace(",", ""))
                                                            for c in r[2:7])
        assert (plain, explicit, compact) == (detail[int(r[1]), "plain KHR"],
                                              detail[int(r[1]), "anchored, explicit"],
                                              detail[int(r[1]), "anchored, compact (default)"])
        assert plain_spz < compact_spz < compact / 2
        spz = int(r[7].replace(",", ""))           # splat-transform is installed with the tests
        assert r[9] == f"{compact_spz / spz:.3f}×"
        assert float(r[13]) <= 1.0                  # decoded within the stated SPZ bounds
        assert all(float(v) <= 1.0 for v in r[14].split(", "))


def _engines(args: list[str], **env_changes) -> subprocess.CompletedProcess:
    env = dict(os.environ, **env_changes)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    return subprocess.run([sys.executable, "-m", "benchmarks.engines", *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=600)


def test_engines_benchmark_rows_are_well_formed():
    """``python -m benchmarks.engines`` at a tiny size: a row per engine with its static frame,
    remap and sort and their ratios, and the two GPU rows (timings are not checked)."""
    import json
    import math

    out = _engines(["--sizes", "2000", "--rounds", "1", "--json"])
    assert out.returncode == 0, out.stderr[-2000:]
    res = json.loads(out.stdout)
    if res.get("skipped"):
        pytest.skip(res["skipped"])
    assert not res.get("error"), res
    assert {r["engine"] for r in res["rows"]} == {"PlayCanvas", "three.js + Spark"}
    for r in res["rows"]:
        assert r["n"] == 2000 and r["rounds"] == 1
        for key in ("baseMs", "remapFrameMs", "remapMs", "sortMs", "remapRatio", "sortRatio"):
            assert isinstance(r[key], (int, float)) and math.isfinite(r[key]), (key, r)
        assert r["baseMs"] > 0 and r["remapFrameMs"] > 0 and r["sortMs"] >= 0
        assert math.isclose(r["remapRatio"], r["remapMs"] / r["baseMs"])
        assert math.isclose(r["sortRatio"], r["sortMs"] / r["baseMs"])
    assert len(res["backends"]) == 2 and all(b["renderer"] for b in res["backends"])
    web, native = res["gpu_rows"]
    assert web["target"].startswith("web shaders") and native["target"].startswith("native kernels")
    if "SwiftShader" in web["device"]:
        assert web["result"].startswith("empty: no GPU") and "rows" not in web
    # the report section renders the rows
    md = subprocess.run([sys.executable, "-c", "import json, sys; from benchmarks.engines import markdown; "
                         "print('\\n'.join(markdown(json.load(sys.stdin))))"], input=out.stdout, cwd=ROOT,
                        env=dict(os.environ, PYTHONPATH=str(ROOT)), capture_output=True, text=True,
                        timeout=120)
    assert md.returncode == 0, md.stderr[-2000:]
    table = [line for line in md.stdout.splitlines() if line.startswith(("| PlayCanvas |", "| three.js + Spark |"))]
    assert len(table) == 2 and all(line.count("|") == 8 for line in table)
    assert "| web shaders (WebGL2) |" in md.stdout and "| native kernels" in md.stdout


def test_engines_benchmark_says_why_it_did_not_run(tmp_path):
    """Without node (an empty PATH) the section says why, and so do the GPU rows."""
    out = _engines(["--sizes", "2000"], PATH=str(tmp_path))
    assert out.returncode == 0, out.stderr[-2000:]
    assert "Skipped: node is not installed." in out.stdout
    assert "| web shaders (WebGL2) | – | not run: node is not installed |" in out.stdout
    assert "| native kernels (GLSL/HLSL, Vulkan) | – | empty: vulkaninfo is not installed |" in out.stdout


def test_remap_face_split_recovers_the_costs_it_was_built_from():
    """``benchmarks.remap.face_split`` on scaling rows made from a known cost per face (20 ns)
    and per splat (10 ns), 2 threads: the fit gives them back, and the face budget of the
    1.3× goal is 0.3 / (φ_small − 1.3 φ_mid) splats."""
    code = (
        "import json\n"
        "from benchmarks.remap import face_split\n"
        "rows = [{'n': n, 'faces_used': f, 'threads': 2, 'ms': (f * 20.0 + n * 10.0) / 2 / 1e6}\n"
        "        for n, f in ((100_000, 63_000), (1_000_000, 100_000), (4_000_000, 100_000))]\n"
        "print(json.dumps(face_split(rows)))\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    split = json.loads(out.stdout)
    assert abs(split["face_ns"] - 20.0) < 1e-6 and abs(split["splat_ns"] - 10.0) < 1e-6
    assert abs(split["small_faces_per_splat"] - 0.63) < 1e-12
    assert abs(split["face_budget"] - 0.3 / (0.63 - 1.3 * 0.1)) < 1e-9
