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
    assert len(rows) == 2
    assert "identical to numpy reference" in rows[0]
    assert "ratio ours / Open3D" in text
