"""The benchmark command runs and writes its report (timings are not checked)."""
from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_quick_benchmark_writes_the_report(tmp_path):
    out = tmp_path / "report"
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    proc = subprocess.run([sys.executable, "-m", "benchmarks", "--quick", "-q", "--out", str(out)],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-4000:]
    report = (out / "report.md").read_text(encoding="utf-8")
    for heading in ("## Remap speed", "## Binding", "## `gsverse-convert` end to end", "## Validation",
                    "## File size: anchored against plain KHR",
                    "## Peak memory", "## Accuracy against analytic deformations",
                    "## Stretch: our profiles against a VR-GS-style cage",
                    "## Rendering: speed and accuracy in image space"):
        assert heading in report
    results = json.loads((out / "results.json").read_text(encoding="utf-8"))
    assert results["remap"]["rows"] and results["accuracy"]["rows"]
    if importlib.util.find_spec("matplotlib") is None:
        assert "Plots were skipped" in report
    else:
        for png in ("remap_speed.png", "accuracy_magnitude.png", "accuracy_resolution.png",
                    "accuracy_quantization.png", "pareto.png", "stretch.png"):
            assert (out / png).stat().st_size > 1000, png
