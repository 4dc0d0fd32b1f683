"""The vectorised OBJ reader (gsverse_format.io.obj) against trimesh, its reference: the same
vertices and faces for every file in the plain subset, and None (trimesh reads it) outside."""
from __future__ import annotations

import io
import re

import numpy as np
import pytest

from gsverse_format.io.mesh import read_mesh
from gsverse_format.io.obj import read_obj_triangles

trimesh = pytest.importorskip("trimesh")


def _trimesh(data: bytes) -> tuple[np.ndarray, np.ndarray]:
    loaded = trimesh.load(io.BytesIO(data), file_type="obj", process=False,
                          maintain_order=True, force="mesh", skip_materials=True)
    return np.asarray(loaded.vertices, np.float64), np.asarray(loaded.faces, np.int64)


def _obj(rng: np.random.Generator, sizes: list[int], *, n_vertices: int = 12,
         colours: bool = False, tails: bool = False, extras: bool = False) -> bytes:
    lines = ["# generated", "o thing"] if extras else []
    for _ in range(n_vertices):
        xyz = " ".join(f"{x:.6g}" for x in rng.normal(size=3))
        lines.append(f"v {xyz}" + (" 0.5 0.25 1" if colours else ""))
        if extras:
            lines.append(f"vt {rng.uniform():.4f} {rng.uniform():.4f}")
            lines.append("vn 0 0 1")
    if extras:
        lines.append("s off")
    for k in sizes:
        corners = rng.choice(n_vertices, size=k, replace=False) + 1
        if tails:
            text = " ".join(f"{c}//{c}" for c in corners)
        else:
            text = " ".join(str(c) for c in corners)
        lines.append("f " + text)
    return ("\r\n" if extras else "\n").join(lines).encode() + b"\n"


@pytest.mark.parametrize("case", [
    dict(sizes=[3] * 9),
    dict(sizes=[4] * 7),
    dict(sizes=[5] * 4),
    dict(sizes=[6, 6, 6]),
    dict(sizes=[3, 4, 5, 4, 3, 7, 4]),
    dict(sizes=[4, 5, 4, 6]),
    dict(sizes=[4, 3, 3, 4], tails=True),
    dict(sizes=[3] * 5, colours=True),
    dict(sizes=[4, 4, 5, 3], extras=True),
])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_same_mesh_as_trimesh(case: dict, seed: int) -> None:
    data = _obj(np.random.default_rng(seed), **case)
    ours = read_obj_triangles(data)
    assert ours is not None
    vertices, faces = _trimesh(data)
    np.testing.assert_array_equal(ours[0], vertices)
    np.testing.assert_array_equal(ours[1], faces)


@pytest.mark.parametrize("data", [
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\ng part\nf 1 2 3\n",            # groups: trimesh splits
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n",        # materials
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n",                 # relative indices
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",                    # out of range
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n",                      # two corners
    b"v 0 0 0 1\nv 1 0 0 1\nv 0 1 0 1\nf 1 2 3\n",              # a w coordinate
    b"v 0 0 zero\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",                 # not a number
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3.5\n",
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\nf 1 2 3\n",             # another statement
    b"v\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\n",    # texture indices
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nvn 0 0 1\nf 1//1 2//1 3//1\n",   # normals
])
def test_outside_the_subset_goes_to_trimesh(data: bytes) -> None:
    assert read_obj_triangles(data) is None


@pytest.mark.parametrize("token", [b"1e-3", b"+.5", b"-2.", b"inf", b"-Infinity", b"NaN",
                                   b"1e400", b"1_0", b"nan(1)", b"0x10", b"1d5", b"1,5"])
def test_coordinates_read_as_the_token_conversion_reads_them(token: bytes) -> None:
    """numpy's text parser reads the coordinates where it can; a token it refuses, or
    ``nan(...)`` that it reads and Python's ``float`` refuses, is left to the conversion of
    the split tokens, so the result is that conversion's (None where it refuses one)."""
    data = b"v 0 0 0\nv 1 " + token + b" 0\nv 0 1 0\nf 1 2 3\n"
    ours = read_obj_triangles(data)
    try:
        value = float(token)
    except ValueError:
        assert ours is None
        return
    assert ours is not None
    np.testing.assert_array_equal(ours[0], [[0, 0, 0], [1, value, 0], [0, 1, 0]])


def test_blanks_and_trailing_comments() -> None:
    """Indented statements, tabs and comments after a record are read as OBJ's grammar says
    (trimesh drops such face lines or fails on them; this reader does not)."""
    data = _obj(np.random.default_rng(3), [4, 3, 5], tails=True)
    loose = b"\n".join(b"  " + line.replace(b" ", b"\t", 1) + b"   # note" if line else line
                        for line in data.split(b"\n"))
    ours, plain = read_obj_triangles(loose), read_obj_triangles(data)
    assert ours is not None and plain is not None
    np.testing.assert_array_equal(ours[0], plain[0])
    np.testing.assert_array_equal(ours[1], plain[1])


def test_read_mesh_uses_it_without_trimesh(tmp_path) -> None:
    """An OBJ in the subset is read without importing trimesh (a fresh process)."""
    import subprocess
    import sys

    path = tmp_path / "quad.obj"
    path.write_bytes(_obj(np.random.default_rng(5), [4, 4, 3], extras=True))
    code = ("import sys; from gsverse_format.io.mesh import read_mesh; "
            f"m = read_mesh({str(path)!r}); print(m.face_count, 'trimesh' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["5", "False"]
    mesh = read_mesh(path)
    vertices, faces = _trimesh(path.read_bytes())
    np.testing.assert_array_equal(mesh.vertices, vertices.astype(np.float32))
    np.testing.assert_array_equal(mesh.faces, faces.astype(np.uint32))


_LINES = [b"v 0 0 0", b"v\t1 0 0 # c", b"v 0 1 0#x", b"f 1 2 3", b"f\t1 2 3 # tail", b"#", b"# c",
          b"", b"\r", b"vt 0 0", b"vt", b"vn 0 0 1\r", b"vp 1", b"o", b"o thing", b"s off", b"s\r",
          b"s\t1", b"g part", b"v", b"f", b"f\r", b"vx 1", b"os", b"l 1 2", b"usemtl m", b"vt\t0",
          b"f 1//1 2//1 3//1", b"f 1/1 2/1 3/1", b"v 1 2 3 4 5 6", b"x"]


@pytest.mark.parametrize("seed", range(40))
def test_line_classifier_equals_the_regular_expressions(seed: int) -> None:
    """The numpy record split (:func:`_records`) gives the regular expressions' texts and
    verdicts, for every mix of the statements the subset admits and those it refuses."""
    from gsverse_format.io.obj import _INDENTED, _records, _records_regex

    rng = np.random.default_rng(seed)
    # mostly admitted lines, so that files of only admitted lines come up often
    weights = np.array([8.0 if not any(x.startswith(b) for b in (b"g", b"l", b"u", b"x"))
                        and x not in (b"v", b"f", b"f\r", b"vx 1", b"os") else 0.5
                        for x in _LINES])
    lines = [_LINES[i] for i in rng.choice(len(_LINES), rng.integers(0, 12),
                                            p=weights / weights.sum())]
    end = [b"", b"\n", b"\r\n"][seed % 3]
    data = (b"\r\n" if seed % 5 == 0 else b"\n").join(lines) + end
    fast, regex = _records(data), _records_regex(data)
    assert fast is not _INDENTED
    if regex is None:
        assert fast is None, data
        return
    assert isinstance(fast, tuple), data
    squeeze = lambda t: re.sub(rb"[ \t]+", b" ", t)   # noqa: E731
    assert [squeeze(x) for x in fast] == [squeeze(x) for x in regex], data


def test_indented_files_take_the_regular_expressions() -> None:
    from gsverse_format.io.obj import _INDENTED, _records

    assert _records(b"v 0 0 0\n  v 1 0 0\n") is _INDENTED
    assert _records(b"\tf 1 2 3\n") is _INDENTED
