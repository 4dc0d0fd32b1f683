"""Packaging: subpackage mapping, package data, console script."""
from __future__ import annotations

import importlib.util
import shutil
import subprocess
import sys
from importlib import resources


def test_converters_and_validators_are_subpackages_only():
    assert importlib.util.find_spec("gsverse_format.converters") is not None
    assert importlib.util.find_spec("gsverse_format.validators") is not None
    # Never installed as top-level names ("validators" is a popular PyPI package).
    for name in ("converters", "validators"):
        spec = importlib.util.find_spec(name)
        assert spec is None or "gsverse" not in (spec.origin or ""), spec


def test_package_data_is_installed():
    schema = resources.files("gsverse_format") / "schema"
    assert (schema / "primitive.KHR_gaussian_splatting.GSVERSE_gaussian_splatting_mesh_anchor.schema.json").is_file()
    usd = resources.files("gsverse_format") / "usd_schema"
    assert (usd / "plugInfo.json").is_file() and (usd / "generatedSchema.usda").is_file()


def test_console_script_runs():
    exe = shutil.which("gsverse-convert")
    cmd = [exe] if exe else [sys.executable, "-m", "gsverse_format.cli.convert"]
    proc = subprocess.run(cmd + ["--version"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and "gsverse-convert" in proc.stdout
