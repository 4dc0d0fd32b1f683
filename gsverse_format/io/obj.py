"""A vectorised reader for the plain subset of Wavefront OBJ that anchor meshes use.

``v`` positions and ``f`` polygons, with ``vt``/``vn``/``vp`` records, ``o`` and ``s``
statements and comments ignored as an anchor mesh needs none of them. The result is what
trimesh returns for the same bytes (``process=False``, ``maintain_order=True``,
``skip_materials=True``), vertex for vertex and face for face; ``tests/test_mesh_obj.py``
checks this against trimesh on generated files. (Indented statements, tabs after the keyword
and comments after a record are read as the grammar says, where trimesh drops such face lines
or fails.) The triangulation follows trimesh's, which is not one rule:

* a file of triangles only: the faces as they are;
* a file of quads only: the first triangle ``(a, b, c)`` of every quad in file order, then
  the second ``(c, d, a)`` of every quad;
* any other mix: polygon by polygon in file order, a quad as ``(a, b, c), (c, d, a)``, a
  polygon of five or more corners as the fan ``(a, p[i], p[i + 1])``.

Whatever lies outside that subset, :func:`read_obj_triangles` does not guess: it returns
None and the caller reads the file with trimesh. That covers groups and materials (``g``,
``usemtl``: trimesh then splits and reorders vertices), negative (relative) or out-of-range
indices, polygons with fewer than three corners, vertices with other than three or six
numbers (six: trimesh reads the last three as a colour), anything that is not a number, and
any other statement, and corners that name a texture coordinate or a normal (``7/3/2``,
``7//2`` with ``vn`` records: trimesh then rebuilds the vertex list, dropping unreferenced
vertices). The caller handles continuation lines and ``mtllib`` before
(:func:`gsverse_format.io.mesh.strip_material_libraries`).

This module knows nothing of what a mesh means: it returns float64 vertices and int64 faces,
unchecked for finiteness, for :func:`gsverse_format.io.mesh.read_mesh` to check.

Why not always trimesh: on a 100,000-face OBJ trimesh's import (it pulls in scipy.spatial and
networkx) and parse take about 0.9 s; this reader takes about a tenth of that.
"""
from __future__ import annotations

import re

import numpy as np

__all__ = ["read_obj_triangles"]

#: A line whose statement is outside the subset (leading blanks allowed; blank lines and
#: comments are inside it).
#: ``(?=([ \t]*))\1`` takes all the leading blanks and never gives one back (Python 3.10 has no
#: possessive ``*+``), so an indented statement is judged by its keyword.
_OTHER = re.compile(rb"^(?=([ \t]*))\1(?!(?:v|f)[ \t]|(?:vt|vn|vp|o|s)(?:[ \t\r]|$)|#|\r?$)",
                    re.MULTILINE)
#: The numbers of a ``v`` line and the corners of an ``f`` line (up to a comment).
_VERTEX = re.compile(rb"^[ \t]*v[ \t]+([^\n#]*)", re.MULTILINE)
_FACE = re.compile(rb"^[ \t]*f[ \t]+([^\n#]*)", re.MULTILINE)
#: A corner with a texture index (``7/3``, ``7/3/2``): trimesh then rebuilds the vertices.
_TEXTURED = re.compile(rb"[^/ \t\r\n]/[^/ \t\r\n]")
#: A texture coordinate or normal record: corners that name one make trimesh rebuild the
#: vertices too (unreferenced ones dropped).
_ATTRIBUTES = re.compile(rb"^[ \t]*v[tn][ \t]", re.MULTILINE)
#: The texture and normal indices of a corner (``7/3/2``, ``7//2`` -> ``7``).
_CORNER_TAIL = re.compile(rb"/[^ \t\r\n]*")


def _numbers(text: bytes, dtype: type) -> tuple[np.ndarray, np.ndarray] | None:
    """The numbers of ``text`` (one record a line) as one flat array and their count per
    line (None when one is not a number of ``dtype``)."""
    if not text:
        return np.zeros(0, dtype), np.zeros(0, np.int64)
    raw = np.frombuffer(text, np.uint8)
    blank = (raw == ord(" ")) | (raw == ord("\t")) | (raw == ord("\r")) | (raw == ord("\n"))
    starts = ~blank
    starts[1:] &= blank[:-1]                          # the first byte of each number
    newlines = np.flatnonzero(raw == ord("\n"))
    before = np.concatenate([[0], np.cumsum(starts, dtype=np.int64)])   # numbers before a byte
    counts = before[np.append(newlines, raw.size)] - before[np.concatenate([[0], newlines + 1])]
    if dtype is np.int64 or b"(" not in text:
        # numpy's C parser: 10x faster than converting the tokens (60 -> 7 ms for 300k
        # corners; 15 -> 9.5 ms for 150k coordinates). It refuses a token that is not a
        # whole decimal number (integers) or a decimal float, ``inf`` or ``nan`` (floats);
        # the token conversion below then decides, as it does when the count differs. Where
        # it accepts what the conversion refuses: an integer beyond int64 saturates, and the
        # index range check turns the file down all the same; ``nan(...)``, the one float
        # token, is left to the conversion (the check above).
        fast: np.ndarray | None
        try:
            fast = np.fromstring(text, dtype=dtype, sep=" ")
        except ValueError:
            fast = None
        if fast is not None and fast.size == int(counts.sum()):
            return fast, counts
    tokens = text.split()
    try:
        values: np.ndarray = np.array(tokens, dtype=dtype) if tokens else np.zeros(0, dtype)
    except (ValueError, OverflowError):
        return None
    return values, counts


def _triangulate(corners: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Triangles of the polygons (``corners`` flat, ``counts`` corners per polygon), in
    trimesh's order (see the module docstring)."""
    if counts.size == 0:
        return np.zeros((0, 3), np.int64)
    if np.all(counts == 3):
        return corners.reshape(-1, 3)
    if np.all(counts == 4):
        quads = corners.reshape(-1, 4)
        return np.concatenate([quads[:, [0, 1, 2]], quads[:, [2, 3, 0]]])
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    per = counts - 2                                  # triangles per polygon
    first = np.repeat(starts, per)                    # the polygon's first corner
    step = np.arange(int(per.sum())) - np.repeat(np.cumsum(per) - per, per)   # 0 .. per-1
    tri = np.stack([first, first + step + 1, first + step + 2], axis=1)
    quad = np.repeat(counts == 4, per)
    second = quad & (step == 1)                       # (c, d, a) instead of the fan's (a, c, d)
    tri[second] = np.stack([first[second] + 2, first[second] + 3, first[second]], axis=1)
    return corners[tri]


def _records_regex(data: bytes) -> tuple[bytes, bytes] | None:
    """The ``v`` and the ``f`` records' texts (one record a line, comments cut), or None when
    a statement lies outside the subset: the reference of :func:`_records`."""
    if _OTHER.search(data) is not None:
        return None
    return b"\n".join(_VERTEX.findall(data)), b"\n".join(_FACE.findall(data))


_INDENTED = object()
_B = {c: ord(c) for c in " \t\r\n#vfotnps"}


def _records(data: bytes) -> tuple[bytes, bytes] | None | object:
    """:func:`_records_regex` for files whose lines all start with their keyword, decided on
    the bytes with numpy (about four times faster: 33 against 124 ms for 100k faces): the
    texts the regular expressions' ``findall`` give, up to the blanks after the keyword, or
    None where they find a statement outside the subset. ``_INDENTED`` when a line starts
    with a blank (the regular expressions then decide)."""
    raw = np.frombuffer(data, np.uint8)
    n = raw.size
    nl = np.flatnonzero(raw == _B["\n"])
    starts = np.concatenate([[0], nl + 1])
    ends = np.append(nl, n)
    if starts[-1] == n:                        # nothing after the last newline
        starts, ends = starts[:-1], ends[:-1]
    length = ends - starts
    pad = np.concatenate([raw, np.zeros(3, np.uint8)])
    c0 = np.where(length >= 1, pad[starts], 0)
    c1 = np.where(length >= 2, pad[starts + 1], 0)
    c2 = np.where(length >= 3, pad[starts + 2], 0)
    if np.any((c0 == _B[" "]) | (c0 == _B["\t"])):
        return _INDENTED
    blank1 = (c1 == _B[" "]) | (c1 == _B["\t"])
    vrec = (c0 == _B["v"]) & blank1
    frec = (c0 == _B["f"]) & blank1
    ok = ((length == 0) | ((length == 1) & (c0 == _B["\r"])) | (c0 == _B["#"]) | vrec | frec
          | ((c0 == _B["v"]) & ((c1 == _B["t"]) | (c1 == _B["n"]) | (c1 == _B["p"]))
             & ((length == 2) | (c2 == _B[" "]) | (c2 == _B["\t"]) | (c2 == _B["\r"])))
          | (((c0 == _B["o"]) | (c0 == _B["s"]))
             & ((length == 1) | blank1 | (c1 == _B["\r"]))))
    if not ok.all():
        return None
    cut = ends.copy()                          # a record ends at its line's first '#'
    hashes = np.flatnonzero(raw == _B["#"])
    if hashes.size:
        line = np.searchsorted(starts, hashes, side="right") - 1
        first_line, first = np.unique(line, return_index=True)
        cut[first_line] = np.minimum(cut[first_line], hashes[first])

    def text(rec: np.ndarray) -> bytes:
        if not rec.any():
            return b""
        delta = np.zeros(n + 1, np.int8)
        delta[starts[rec] + 2] = 1
        delta[cut[rec]] -= 1
        keep = np.cumsum(delta[:n], dtype=np.int8).astype(bool)
        sep = ends[rec]
        keep[sep[sep < n]] = True              # the newline after each record
        out = raw[keep].tobytes()
        return out[:-1] if out.endswith(b"\n") else out

    return text(vrec), text(frec)


def read_obj_triangles(data: bytes) -> tuple[np.ndarray, np.ndarray] | None:
    """``(vertices (V, 3) float64, faces (F, 3) int64)`` of an OBJ in the plain subset (see
    the module docstring), or None when the file needs trimesh's reader."""
    records = _records(data)
    if records is _INDENTED:
        records = _records_regex(data)
    if records is None:
        return None
    assert isinstance(records, tuple)
    vertex_text, face_text = records
    parsed = _numbers(vertex_text, np.float64)
    if parsed is None:
        return None
    values, counts = parsed
    if counts.size and not (np.all(counts == 3) or np.all(counts == 6)):
        return None
    width = int(counts[0]) if counts.size else 3
    vertices = values.reshape(-1, width)[:, :3]
    if b"/" in face_text:
        if _TEXTURED.search(face_text) or _ATTRIBUTES.search(data):
            return None
        face_text = _CORNER_TAIL.sub(b"", face_text)
    parsed = _numbers(face_text, np.int64)
    if parsed is None:
        return None
    corners, corner_counts = parsed
    if corner_counts.size and corner_counts.min() < 3:
        return None
    if corners.size and (corners.min() < 1 or corners.max() > len(vertices)):
        return None
    return np.ascontiguousarray(vertices), _triangulate(corners - 1, corner_counts)
