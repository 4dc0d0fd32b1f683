"""Reading anchor meshes (OBJ, PLY, STL, OFF, GLB/glTF) into :class:`TriangleMesh`.

Vertex and face order are kept as the file has them (``process=False``): converters that bind
by face index (SuGaR, GaMeS) depend on it. Polygons are fan-triangulated by trimesh. glTF
scenes are flattened with their node transforms applied (by the project's own hardened
glTF reader, which never follows URIs outside the asset's folder).
"""
from __future__ import annotations

import os
import warnings

import numpy as np

from ..errors import FormatError
from ..model import TriangleMesh

MESH_EXTENSIONS = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")


def read_mesh(path: str | os.PathLike) -> TriangleMesh:
    """Read a triangle mesh; raises :class:`FormatError` with a one-line cause on bad input."""
    import trimesh

    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower()
    if ext not in MESH_EXTENSIONS:
        raise FormatError(f"unsupported mesh format {ext or '(no extension)'}; "
                          f"use one of {', '.join(MESH_EXTENSIONS)}", path)
    if not os.path.isfile(path):
        raise FormatError("file not found", path)
    if ext in (".glb", ".gltf"):
        # The hardened glTF reader (bounds checks, URIs confined to the asset's folder).
        from .gltf import read_gltf_triangles

        return read_gltf_triangles(path)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            loaded = trimesh.load(path, process=False, maintain_order=True, force="mesh",
                                  skip_materials=True)
    except FormatError:
        raise
    except Exception as exc:  # trimesh raises many types for bad files
        raise FormatError(f"cannot read mesh: {type(exc).__name__}: {exc}".splitlines()[0], path)
    if not isinstance(loaded, trimesh.Trimesh):
        raise FormatError("file holds no triangle mesh", path)
    vertices = np.asarray(loaded.vertices, dtype=np.float64)
    faces = np.asarray(loaded.faces, dtype=np.int64)
    if faces.size == 0:
        raise FormatError("mesh has no faces", path)
    if not np.all(np.isfinite(vertices)):
        bad = int(np.count_nonzero(~np.isfinite(vertices).all(axis=1)))
        raise FormatError(f"mesh has {bad} vertices with NaN or Inf coordinates", path)
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise FormatError(f"face references vertex {int(faces.max())} but the mesh has "
                          f"{len(vertices)} vertices", path)
    if np.abs(vertices).max(initial=0.0) > np.finfo(np.float32).max:
        raise FormatError("vertex coordinates exceed the float32 range", path)
    return TriangleMesh(vertices.astype(np.float32), faces.astype(np.uint32))
