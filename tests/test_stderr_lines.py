"""Nothing on stderr but the command's own lines: what native libraries print past Python
(screened Poisson's ``[WARNING] Found out-of-bound points``), Pillow's DecompressionBombWarning
at an image size our own limit refuses. Every input is built here."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from test_hostile_rigs import assert_refused


def test_sog_webp_past_pillows_bomb_warning_gives_our_line_alone(tmp_path):
    """10⁴ × 10⁴ pixels: above Pillow's DecompressionBombWarning size (89 M pixels), refused
    by our own limit in one line, without Pillow's warning."""
    from splat_writers import _webp, write_sog
    from test_hostile_web_formats import _patched_webp_size, _sog_members, _write_zip

    from helpers import random_splats

    good = tmp_path / "good.sog"
    write_sog(random_splats(64, seed=2, sh_degree=1), good)
    members = _sog_members(good)
    good.unlink()
    members["quats.webp"] = _patched_webp_size(_webp(np.zeros((8, 8, 4), np.uint8)),
                                               10000, 10000)
    path = tmp_path / "pixels.sog"
    _write_zip(path, members)
    err = assert_refused(path, tmp_path, "10000x10000", "quats.webp", extra=("--to", "glb"))
    assert "Warning" not in err, err


_PRINTS = """
import ctypes, os, sys
from gsverse_format.native_output import native_output
libc = ctypes.CDLL(None)
with native_output(("[WARNING] Found ",)) as printed:
    libc.printf(b"[WARNING] Found out-of-bound points: %d\\n", 3)
    os.write(2, b"[WARNING] Found zero-length normals: 4\\n")
    libc.printf(b"a line of its own\\n")
print("held:", printed.held)
"""


def test_native_prints_are_held_and_the_others_written_back():
    """What C code prints on descriptors 1 and 2 (here libc's printf, block-buffered into a
    file, and a raw write) is held when it starts with a named prefix; any other line reaches
    stderr after the block, and the descriptors are the terminal's again."""
    proc = subprocess.run([sys.executable, "-c", _PRINTS], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == "a line of its own\n", proc.stderr
    assert proc.stdout == ("held: ['[WARNING] Found out-of-bound points: 3', "
                           "'[WARNING] Found zero-length normals: 4']\n"), proc.stdout


@pytest.fixture(scope="module")
def capsule_glb(tmp_path_factory):
    """The example's splats anchored to its mesh, built here."""
    import gsverse_format as gv

    root = Path(__file__).resolve().parent.parent / "examples" / "capsule"
    path = tmp_path_factory.mktemp("capsule") / "capsule.glb"
    gv.convert(root / "splats.ply", path, mesh=str(root / "mesh.obj"))
    return path


@pytest.mark.parametrize("command, args, words", [
    ("render", ("--camera", "eye=1e300,0,0 target=0,0,0"), ("eye=", "within ±1e+12")),
    ("render", ("--camera", "eye=0,0,3 target=0,0,0 up=1e300,0,0"), ("up=", "within")),
    ("render", ("--deform", "stretch=1e300"), ("stretch factor must lie in",)),
    ("pose", ("--deform", "shake=1e300", "--times", "0", "0.5"), ("shake amount must lie in",)),
    ("pose", ("--deform", "stretch=1e300"), ("stretch factor must lie in",)),
])
def test_extreme_cameras_and_quick_looks_are_usage_errors_without_numpy_warnings(
        tmp_path, capsule_glb, command, args, words):
    """Amounts whose products overflow float64 (NumPy printed RuntimeWarnings with its own
    file paths) are refused before any work: exit 2, one line, nothing written."""
    out = tmp_path / ("out.png" if command == "render" else "out.ply")
    proc = subprocess.run([sys.executable, "-m", f"gsverse_format.cli.{command}",
                           str(capsule_glb), str(out), *args], capture_output=True, text=True,
                          timeout=600)
    err = proc.stderr.strip()
    assert proc.returncode == 2, err
    assert len(err.splitlines()) == 1 and err.startswith(f"gsverse-{command}: error: "), err
    for word in words:
        assert word in err, err
    assert not list(tmp_path.iterdir())
