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


def test_every_subpackage_is_listed_for_installation():
    """pyproject lists its packages explicitly: a new subpackage must be added there, or a
    regular (non-editable) install would silently miss it."""
    import tomllib
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    config = tomllib.loads((root / "pyproject.toml").read_text(encoding="utf-8"))["tool"]
    listed = set(config["setuptools"]["packages"])
    mapped = {name: root / folder for name, folder in config["setuptools"]["package-dir"].items()}
    found = set()
    for name, folder in mapped.items():
        for init in folder.rglob("__init__.py"):
            rel = init.parent.relative_to(folder)
            found.add(".".join([name, *rel.parts]) if rel.parts else name)
    assert found - listed == set(), sorted(found - listed)
    assert (root / "gsverse_format" / "py.typed").is_file()
    assert "py.typed" in config["setuptools"]["package-data"]["gsverse_format"]
