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
                    "## Rendering: speed and accuracy in image space",
                    "## Engines: the remap and the deformed sort against the engine's own splat pass"):
        assert heading in report
    results = json.loads((out / "results.json").read_text(encoding="utf-8"))
    assert results["remap"]["rows"] and results["accuracy"]["rows"]
    if importlib.util.find_spec("matplotlib") is None:
        assert "Plots were skipped" in report
    else:
        for png in ("remap_speed.png", "accuracy_magnitude.png", "accuracy_resolution.png",
                    "accuracy_quantization.png", "pareto.png", "stretch.png"):
            assert (out / png).stat().st_size > 1000, png


def test_benchmarks_use_a_regular_install(tmp_path):
    """Run from the checkout against a regular (non-editable) install, the benchmarks import
    the installed package, which has ``gsverse_format.converters``, not the checkout's source
    folder, which lacks it; and a child process the convert benchmark starts does too."""
    # the layout a regular install gives (pyproject.toml's package-dir: converters/ and
    # validators/ mapped into the package), copied rather than built, so that the test needs
    # neither a build backend nor an index
    import shutil

    site = tmp_path / "site"
    skip = shutil.ignore_patterns("__pycache__", "*.pyc")
    shutil.copytree(ROOT / "gsverse_format", site / "gsverse_format", ignore=skip)
    for folder in ("converters", "validators"):
        shutil.copytree(ROOT / folder, site / "gsverse_format" / folder, ignore=skip)
    env = dict(os.environ, PYTHONPATH=str(site))
    code = ("import benchmarks, gsverse_format, gsverse_format.converters; "
            "from benchmarks.convert import _env, _python; from benchmarks.processes import run_process; "
            "print(gsverse_format.__file__); "
            "r = run_process(_python('gsverse_format.cli.info', '--version'), env=_env()); "
            "print(r['rc'], r['output'].strip().splitlines()[-1])")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    where, child = proc.stdout.strip().splitlines()[-2:]
    assert Path(where).resolve().is_relative_to(site.resolve())
    assert child.startswith("0 ")
