"""Names from files cannot forge log lines: the validator's text report and the tools' error
lines escape control characters and line starts that CI runners read as commands."""
from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys

import pytest

from gsverse_format.examples import example_mesh, example_splats
from gsverse_format.io.gltf import asset_to_gltf, glb_bytes
from gsverse_format.model import SplatAsset, SplatPrimitive
from gsverse_format.textsafe import escape, safe_line, safe_text

ROOT = pathlib.Path(__file__).resolve().parents[1]
#: A name a hostile file could carry: a new line with a GitHub Actions workflow command, a
#: terminal escape sequence (clear screen, red), a bell, a C1 control sequence introducer, a
#: Unicode line separator and a right-to-left override.
HOSTILE = ("x\n::error file=app.py,line=1::forged\r\x1b[2J\x1b[31mred\x07\x9b31m"
           "\u2028::warning::also\u202eevil")


@pytest.mark.parametrize("text, expected", [
    ("plain name", "plain name"),
    ("a\nb", "a\\nb"),
    ("a\rb\tc", "a\\rb\\tc"),
    ("\x1b[31m", "\\x1b[31m"),
    ("\x00\x7f\x9b", "\\x00\\x7f\\x9b"),
    ("line\u2028sep\u2029", "line\\u2028sep\\u2029"),
    ("\u202egnp.exe", "\\u202egnp.exe"),
    ("C:\\path\\é ü 中", "C:\\path\\é ü 中"),  # printable text, backslashes included, unchanged
])
def test_escape(text, expected):
    assert escape(text) == expected


@pytest.mark.parametrize("line, expected", [
    ("::error file=a::b", "\\x3a:error file=a::b"),
    ("   ::warning::x", "   \\x3a:warning::x"),
    ("##[error]x", "\\x23#[error]x"),
    ("##vso[task.logissue]x", "\\x23#vso[task.logissue]x"),
    ("file.glb: 0 errors ::x", "file.glb: 0 errors ::x"),
    ("a\n::error::b", "a\\n::error::b"),
])
def test_safe_line(line, expected):
    assert safe_line(line) == expected


def test_safe_text_keeps_line_breaks_only():
    assert safe_text("one\n::error::two\nthree\x1b") == "one\n\\x3a:error::two\nthree\\x1b"


def _hostile_glb(path: pathlib.Path) -> None:
    """A valid asset plus an unknown attribute and an unknown extension named HOSTILE (both
    are reported by name)."""
    mesh = example_mesh(0)
    gltf = asset_to_gltf(SplatAsset([SplatPrimitive(example_splats(mesh, 8), None, "a")]))
    doc = json.loads(gltf.to_json())
    prim = doc["meshes"][0]["primitives"][0]
    prim["attributes"]["KHR_gaussian_splatting:" + HOSTILE] = prim["attributes"]["POSITION"]
    prim["extensions"][HOSTILE] = {}
    doc["extensionsUsed"].append(HOSTILE)
    path.write_bytes(glb_bytes(json.dumps(doc).encode(), gltf.binary_blob()))


def _check_log(text: str, hostile_lines: int) -> None:
    for line in text.splitlines():
        assert not line.lstrip().startswith(("::", "##")), line
        assert "\x1b" not in line and "\x07" not in line and "\x9b" not in line
        assert "\u2028" not in line and "\u202e" not in line and "\r" not in line
    assert text.count("\\x1b[2J") >= hostile_lines


def test_validator_text_report_escapes_names_from_the_file(tmp_path):
    path = tmp_path / "hostile.glb"
    _hostile_glb(path)
    proc = subprocess.run([sys.executable, "-m", "gsverse_format.validators.cli", str(path)],
                          capture_output=True, text=True, cwd=ROOT, timeout=300)
    report = json.loads(subprocess.run(
        [sys.executable, "-m", "gsverse_format.validators.cli", "--format", "json", str(path)],
        capture_output=True, text=True, cwd=ROOT, timeout=300).stdout)
    messages = report["reports"][0]["issues"]["messages"]
    named = [m for m in messages if HOSTILE in m["message"] or HOSTILE in m.get("pointer", "")]
    assert named, messages  # the names are reported (JSON keeps them exactly) ...
    lines = proc.stdout.splitlines()
    assert len(lines) == 1 + len(messages)  # ... and the text has one line per finding
    _check_log(proc.stdout, len(named))


def test_validator_summary_line_escapes_the_file_name(tmp_path):
    folder = tmp_path / "::error file=x::forged"
    folder.mkdir()
    path = folder / "a\x1b[31m.glb"
    _hostile_glb(path)
    proc = subprocess.run([sys.executable, "-m", "gsverse_format.validators.cli", "-q",
                           os.path.relpath(path, tmp_path)], capture_output=True, text=True,
                          cwd=tmp_path, timeout=300,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.stdout.startswith("\\x3a:error file=x::forged/a\\x1b[31m.glb: "), proc.stdout
    _check_log(proc.stdout, 0)


def test_convert_error_line_escapes_names(tmp_path):
    path = tmp_path / ("::error::x\x1b[31m" + ".ply")
    path.write_bytes(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float " +
                     HOSTILE.replace("\n", " ").encode() + b"\nend_header\n1\n")
    proc = subprocess.run([sys.executable, "-m", "gsverse_format.cli.convert", path.name,
                           "out.glb"], capture_output=True, text=True, cwd=tmp_path,
                          timeout=300, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.returncode == 1, proc.stderr
    assert len(proc.stderr.splitlines()) == 1, proc.stderr
    assert proc.stderr.startswith("gsverse-convert: error: ::error::x\\x1b[31m.ply: ")
    assert "\x1b" not in proc.stderr and not (tmp_path / "out.glb").exists()
