"""Bad input that used to surface as an internal error or to be carried silently into the
output: a compressed PLY whose chunk bound is a list property, and ``--mesh`` rigs with NaN
or decreasing key times, NaN morph deltas or inverse bind matrices, channels aimed at missing
nodes, out-of-range JOINTS_0 and morph weights that do not match the targets. Each is refused
when read, in one line naming the file and what is wrong, exit 1, nothing written; the
validator reports the same things in an output file by the same checks
(:mod:`gsverse_format.rig_checks`). Every input is built here."""
from __future__ import annotations

import struct

import numpy as np
import pytest

from test_hostile_web_formats import assert_refused

_CHUNK = ("min_x", "min_y", "min_z", "max_x", "max_y", "max_z", "min_scale_x", "min_scale_y",
          "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z")


def compressed_ply_with_a_list_bound(path, count: int, n: int = 4) -> None:
    """A compressed PLY of ``n`` splats whose ``chunk.min_x`` is a list of ``count`` floats."""
    header = ["ply", "format binary_little_endian 1.0", "element chunk 1"]
    body = b""
    for name in _CHUNK:
        if name == "min_x":
            header.append(f"property list uchar float {name}")
            body += struct.pack(f"<B{count}f", count, *([0.5] * count))
        else:
            header.append(f"property float {name}")
            body += struct.pack("<f", 0.0 if name.startswith("min") else 1.0)
    header.append(f"element vertex {n}")
    header += [f"property uint {p}" for p in ("packed_position", "packed_rotation",
                                               "packed_scale", "packed_color")]
    header.append("end_header")
    packed = np.random.default_rng(0).integers(0, 2 ** 32, (n, 4), dtype=np.uint32)
    path.write_bytes(("\n".join(header) + "\n").encode() + body + packed.astype("<u4").tobytes())


@pytest.mark.parametrize("count", [0, 1, 2])
def test_compressed_ply_chunk_bound_that_is_a_list(tmp_path, count):
    src = tmp_path / "bounds.compressed.ply"
    compressed_ply_with_a_list_bound(src, count)
    assert_refused(src, tmp_path, "chunk.min_x is a list")
