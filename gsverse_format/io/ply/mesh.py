"""Triangle meshes in PLY files, built on the PLY container (:mod:`.container`).

A mesh is a ``vertex`` element with scalar ``x y z`` properties (any numeric type) and a
``face`` element with a list property ``vertex_indices`` (or ``vertex_index``) of integers;
every other element and property is ignored. Vertex and face order are kept as the file has
them. The reader is strict: every problem is a one-line
:class:`~gsverse_format.errors.FormatError` naming the file.
"""
from __future__ import annotations

import os

import numpy as np

from ...errors import FormatError
from ...model import TriangleMesh
from .container import PlyData, read_ply_elements

__all__ = ["FACE_LISTS", "ply_triangles", "read_ply_mesh"]

#: The names a ``face`` element's vertex-index list goes by, in order of preference.
FACE_LISTS = ("vertex_indices", "vertex_index")


def _fan(polygons: list[np.ndarray], path: str | None) -> np.ndarray:
    """Fan-triangulate polygons in order: ``(v0, v1, v2), (v0, v2, v3), …`` per polygon."""
    triangles = []
    for number, polygon in enumerate(polygons):
        if len(polygon) < 3:
            raise FormatError(f"face {number} has {len(polygon)} vertices; a face needs at "
                              "least 3", path)
        corners = np.asarray(polygon, np.int64)
        fan = np.empty((len(corners) - 2, 3), np.int64)
        fan[:, 0] = corners[0]
        fan[:, 1] = corners[1:-1]
        fan[:, 2] = corners[2:]
        triangles.append(fan)
    return np.concatenate(triangles) if triangles else np.zeros((0, 3), np.int64)


def ply_triangles(data: PlyData, *, triangulate: bool = False) -> np.ndarray:
    """``(F, 3)`` int64 vertex indices of the ``face`` element of ``data``.

    Polygons are a ``FormatError`` unless ``triangulate`` is true; then each polygon is
    fan-triangulated in file order (a face with fewer than 3 vertices is still an error).
    """
    faces = data.elements.get("face")
    if faces is None:
        raise FormatError("no 'face' element", data.path)
    for name in FACE_LISTS:
        if faces.dtype.names and name in faces.dtype.names:
            break
    else:
        raise FormatError("the 'face' element has no vertex_indices list", data.path)
    column = faces[name]
    declared = data.header.element("face")
    prop = declared.property(name) if declared is not None else None
    if prop is None or not prop.is_list or prop.type[0] not in "iu":
        raise FormatError(f"face {name} must be a list of integers", data.path)
    if len(column) == 0:
        return np.zeros((0, 3), np.int64)
    if column.dtype == object:
        if triangulate:
            return _fan(list(column), data.path)
        lengths = sorted({len(v) for v in column})
        raise FormatError(f"faces are not all triangles (polygons with {lengths} vertices); "
                          "triangulate the mesh first", data.path)
    if column.shape[1] != 3:
        if triangulate and column.shape[1] > 3:  # every face has L > 3 corners
            corners = column.astype(np.int64)
            fan = np.empty((len(corners), corners.shape[1] - 2, 3), np.int64)
            fan[:, :, 0] = corners[:, :1]
            fan[:, :, 1] = corners[:, 1:-1]
            fan[:, :, 2] = corners[:, 2:]
            return fan.reshape(-1, 3)
        raise FormatError(f"faces are not triangles ({column.shape[1]} vertices each); "
                          "triangulate the mesh first", data.path)
    return column.astype(np.int64)


def read_ply_mesh(path: str | os.PathLike[str], *, triangulate: bool = False) -> TriangleMesh:
    """Read a triangle mesh (``vertex`` x/y/z and ``face`` vertex index lists) from a PLY file.

    Polygons are refused unless ``triangulate`` is true (then fan-triangulated, see
    :func:`ply_triangles`).
    """
    path = os.fspath(path)
    data = read_ply_elements(path)
    vertex = data.elements.get("vertex")
    if vertex is None or not all(n in (vertex.dtype.names or ()) for n in "xyz"):
        raise FormatError("no vertex element with x, y, z", path)
    if any(vertex.dtype[n] == object or vertex.dtype[n].shape for n in "xyz"):
        raise FormatError("vertex x/y/z must be scalar properties", path)
    with np.errstate(invalid="ignore"):  # signalling NaNs: reported just below
        xyz = np.stack([vertex[n].astype(np.float64) for n in "xyz"], axis=1)
    if not np.all(np.isfinite(xyz)):
        bad = int(np.count_nonzero(~np.isfinite(xyz).all(axis=1)))
        raise FormatError(f"mesh has {bad} vertices with NaN or Inf coordinates", path)
    if np.abs(xyz).max(initial=0.0) > np.finfo(np.float32).max:
        raise FormatError("vertex coordinates exceed the float32 range", path)
    faces = ply_triangles(data, triangulate=triangulate)
    if faces.size == 0:
        raise FormatError("mesh has no faces", path)
    try:
        return TriangleMesh(xyz.astype(np.float32), faces)
    except FormatError as exc:
        raise exc.with_path(path) from None
