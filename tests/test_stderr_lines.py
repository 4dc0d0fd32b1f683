"""Nothing on stderr but the command's own lines: what native libraries print past Python
(screened Poisson's ``[WARNING] Found out-of-bound points``), Pillow's DecompressionBombWarning
at an image size our own limit refuses. Every input is built here."""
from __future__ import annotations

import subprocess
import sys

import numpy as np

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
