"""Packaging: subpackage mapping, package data, console script."""
from __future__ import annotations

import importlib.util
import json
import shutil
import subprocess
import sys
from importlib import resources
from pathlib import Path


def test_converters_and_validators_are_subpackages_only(tmp_path):
    """The checkout's converters/ and validators/ folders are installed as subpackages of
    gsverse_format, never as top-level names ("validators" is a popular PyPI package). Looked
    at in a fresh interpreter that sees only the installation (``-I``: no current folder,
    no PYTHONPATH, started outside the checkout), so that neither how the tests are run nor
    where the checkout lies changes the answer."""
    assert importlib.util.find_spec("gsverse_format.converters") is not None
    assert importlib.util.find_spec("gsverse_format.validators") is not None
    code = ("import importlib.util, json\n"
            "specs = {n: importlib.util.find_spec(n) for n in ('converters', 'validators')}\n"
            "print(json.dumps({n: s and s.origin for n, s in specs.items()}))")
    proc = subprocess.run([sys.executable, "-I", "-c", code], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120, check=True)
    root = Path(__file__).resolve().parents[1]
    for name, origin in json.loads(proc.stdout).items():
        if origin is not None:  # another distribution's package of that name is no concern
            assert root / name not in Path(origin).resolve().parents, (name, origin)
def test_package_data_is_installed():
    schema = resources.files("gsverse_format") / "schema"
    assert (schema / "primitive.KHR_gaussian_splatting.GSVERSE_gaussian_splatting_mesh_anchor.schema.json").is_file()
    usd = resources.files("gsverse_format") / "usd_schema"
    assert (usd / "plugInfo.json").is_file() and (usd / "generatedSchema.usda").is_file()
    # the compiled extensions' type stubs, beside the extensions
    package = resources.files("gsverse_format")
    assert (package / "_rows.pyi").is_file() and (package / "nearest" / "_native.pyi").is_file()


def test_console_script_runs():
    exe = shutil.which("gsverse-convert")
    cmd = [exe] if exe else [sys.executable, "-m", "gsverse_format.cli.convert"]
    proc = subprocess.run(cmd + ["--version"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and "gsverse-convert" in proc.stdout


def test_every_subpackage_is_listed_for_installation():
    """pyproject lists its packages explicitly: a new subpackage must be added there, or a
    regular (non-editable) install would silently miss it."""
    import tomllib

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
