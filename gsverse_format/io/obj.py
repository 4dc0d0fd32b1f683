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


def read_obj_triangles(data: bytes) -> tuple[np.ndarray, np.ndarray] | None:
    """``(vertices (V, 3) float64, faces (F, 3) int64)`` of an OBJ in the plain subset (see
    the module docstring), or None when the file needs trimesh's reader."""
    if _OTHER.search(data) is not None:
        return None
    parsed = _numbers(b"\n".join(_VERTEX.findall(data)), np.float64)
    if parsed is None:
        return None
    values, counts = parsed
    if counts.size and not (np.all(counts == 3) or np.all(counts == 6)):
        return None
    width = int(counts[0]) if counts.size else 3
    vertices = values.reshape(-1, width)[:, :3]
    face_text = b"\n".join(_FACE.findall(data))
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
