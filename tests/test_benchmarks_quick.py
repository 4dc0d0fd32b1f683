"""``python -m benchmarks.binding --quick`` runs and prints its table (timings are not checked)."""
from __future__ import annotations

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
    assert len(rows) == 3
    assert "identical to numpy reference" in rows[0]
    assert "`bind_local`" in rows[1] and "ours: `bind_local`" in text
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
