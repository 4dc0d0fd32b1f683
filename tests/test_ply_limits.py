"""PLY reading: the memory map, the limit on lists of varying length, float32 overflow."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from gsverse_format.errors import FormatError
from gsverse_format.io.ply import read_ply_elements, read_splat_ply, write_ply
from gsverse_format.io.ply.binary_body import MAX_RAGGED_ROWS

_SPLAT = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
          "rot_0", "rot_1", "rot_2", "rot_3"]


def _splat_table(n: int, dtype: str = "<f4", extra=()) -> np.ndarray:
    names = _SPLAT + list(extra)
    t = np.zeros((n, len(names)))
    t[:, names.index("rot_0")] = 1.0
    t[:, names.index("scale_0"):names.index("scale_2") + 1] = -3.0
    t[:, 0] = np.arange(n)
    return t.astype(dtype).view([(name, dtype) for name in names]).reshape(n)


def _expect(path, match, reader=read_ply_elements):
    with pytest.raises(FormatError) as info:
        reader(path)
    text = str(info.value)
    assert path.name in text and "\n" not in text and match in text, text


def _ragged_binary(path, rows: int, extra: bytes = b"") -> None:
    """``rows`` faces alternating 3 and 4 corners (uchar count, int corners)."""
    head = (f"ply\nformat binary_little_endian 1.0\nelement face {rows}\n"
            "property list uchar int vertex_indices\nend_header\n").encode()
    tri = np.array([3], "u1").tobytes() + np.arange(3, dtype="<i4").tobytes()
    quad = np.array([4], "u1").tobytes() + np.arange(4, dtype="<i4").tobytes()
    path.write_bytes(head + (tri + quad) * (rows // 2) + tri * (rows % 2) + extra)


def test_ragged_lists_over_the_limit_are_refused_before_parsing(tmp_path):
    path = tmp_path / "ragged.ply"
    _ragged_binary(path, MAX_RAGGED_ROWS + 1)
    _expect(path, f"varying length in {MAX_RAGGED_ROWS + 1} rows")
    text = tmp_path / "ragged_ascii.ply"
    text.write_bytes((f"ply\nformat ascii 1.0\nelement face {MAX_RAGGED_ROWS + 1}\n"
                      "property list uchar int vertex_indices\nend_header\n").encode()
                     + b"3 0 1 2\n4 0 1 2 3\n" * ((MAX_RAGGED_ROWS + 2) // 2))
    # one row too many in the body: the limit is met first, not the count mismatch
    _expect(text, "varying length")


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian", "binary_big_endian"])
def test_ragged_lists_under_the_limit_are_read(tmp_path, fmt):
    faces = np.empty(5, [("vertex_indices", object)])
    for i in range(5):
        faces[i] = (np.arange(3 + i % 2, dtype=np.int32),)
    path = tmp_path / "small.ply"
    write_ply(path, {"face": faces}, format=fmt)
    got = read_ply_elements(path)["face"]["vertex_indices"]
    assert [list(v) for v in got] == [list(v) for v in faces["vertex_indices"]]


def test_an_element_not_asked_for_is_checked_but_not_built(tmp_path):
    vertex = _splat_table(4)
    faces = np.empty(3, [("vertex_indices", object)])
    for i in range(3):
        faces[i] = (np.arange(3 + i, dtype=np.int32),)
    path = tmp_path / "both.ply"
    write_ply(path, {"vertex": vertex, "face": faces})
    assert len(read_splat_ply(path)) == 4
    assert list(read_ply_elements(path, elements=("vertex",)).elements) == ["vertex"]
    broken = tmp_path / "broken.ply"
    broken.write_bytes(path.read_bytes()[:-2])          # the ragged element is truncated
    _expect(broken, "truncated", reader=read_splat_ply)


def test_memory_mapped_rows_are_writable_and_never_change_the_file(tmp_path):
    path = tmp_path / "v.ply"
    write_ply(path, {"vertex": _splat_table(10)})
    before = path.read_bytes()
    rows = read_ply_elements(path)["vertex"]
    assert rows.flags.writeable
    rows["x"] = 123.0
    del rows
    assert path.read_bytes() == before
    big = tmp_path / "big_endian.ply"
    write_ply(big, {"vertex": _splat_table(10)}, format="binary_big_endian")
    rows = read_ply_elements(big)["vertex"]
    assert rows.dtype["x"] == np.dtype("f4") and rows["x"].tolist() == list(range(10))


def test_non_consecutive_and_mixed_type_fields_decode_the_same(tmp_path):
    t = _splat_table(6)
    shuffled = t[["rot_3", "x", "opacity", "f_dc_2", "y", "scale_1", "z", "rot_0", "f_dc_0",
                  "scale_0", "rot_2", "f_dc_1", "scale_2", "rot_1"]]
    mixed = np.empty(6, [(name, "<f8" if name in ("y", "f_dc_1") else "<f4") for name in _SPLAT])
    for name in _SPLAT:
        mixed[name] = t[name]
    unaligned = np.empty(6, [("flag", "u1")] + [(name, "<f4") for name in _SPLAT])
    unaligned["flag"] = 7
    for name in _SPLAT:
        unaligned[name] = t[name]
    want = read_splat_ply(_write(tmp_path / "plain.ply", t))
    for other in (shuffled, mixed, unaligned):
        got = read_splat_ply(_write(tmp_path / "other.ply", other))
        for field in ("means", "rotations", "scales", "opacities", "sh"):
            assert np.array_equal(getattr(got, field), getattr(want, field)), field


def _write(path, table):
    write_ply(path, {"vertex": np.ascontiguousarray(table)})
    return path


@pytest.mark.parametrize("name, match", [("x", "x, y, z exceed the float32 range"),
                                         ("f_dc_1", "f_dc exceed the float32 range"),
                                         ("filter_3D", "filter_3D exceed the float32 range")])
def test_doubles_beyond_float32_are_refused(tmp_path, name, match):
    t = _splat_table(5, "<f8", extra=("filter_3D",))
    t[name][2] = 1e300
    path = tmp_path / "dbl.ply"
    write_ply(path, {"vertex": t})
    _expect(path, match, reader=read_splat_ply)


def test_cli_refuses_float32_overflow_with_one_line_and_writes_nothing(tmp_path):
    t = _splat_table(5, "<f8")
    t["y"][1] = -1e300
    path = tmp_path / "dbl.ply"
    write_ply(path, {"vertex": t})
    out = tmp_path / "out.glb"
    proc = subprocess.run([sys.executable, "-W", "error", "-m", "gsverse_format.cli.convert",
                           str(path), str(out), "--plain"], capture_output=True, text=True)
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "dbl.ply" in lines[0] and "float32 range" in lines[0], proc.stderr
    assert not out.exists() and list(tmp_path.iterdir()) == [path]
