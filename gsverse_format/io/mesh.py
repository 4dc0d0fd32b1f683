"""Reading anchor meshes (OBJ, PLY, STL, OFF, GLB/glTF) into :class:`TriangleMesh`.

Vertex and face order are kept as the file has them: converters that bind by face index
(SuGaR, GaMeS) depend on it. PLY meshes are read by the project's own strict PLY reader
(:func:`gsverse_format.io.ply.read_ply_mesh`; polygons are fan-triangulated in file order),
glTF scenes by its hardened glTF reader (flattened with their node transforms applied, URIs
never followed outside the asset's folder, instancing bounded), OBJ in the plain subset
anchor meshes use by :mod:`gsverse_format.io.obj` (vectorised, the same mesh trimesh would
return), other OBJ, STL and OFF by trimesh (``process=False``; polygons triangulated by
trimesh).

trimesh is handed the file's bytes, never its path: it has no way to open another file. OBJ
material libraries (``mtllib``, which may name any path, ``../..`` or absolute) are removed
from those bytes first; an anchor mesh needs no material, so no ``.mtl`` or texture is ever
read, inside the folder or outside it. Files larger than
:data:`~gsverse_format.limits.MAX_MESH_FILE_BYTES` are refused before they are read.
"""
from __future__ import annotations

import contextlib
import io
import os
import re
import struct
import warnings
from typing import Iterator

import numpy as np

from ..atomic import interruptions_immediate
from ..errors import FormatError, UsageError
from ..limits import MAX_MESH_FILE_BYTES
from ..model import TriangleMesh
from .obj import read_obj_triangles
from .ply.header import PlyHeader

MESH_EXTENSIONS = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")

#: An OBJ ``mtllib`` statement (a whole line; continuation lines joined first).
_MTLLIB = re.compile(rb"^[ \t]*mtllib\b.*$", re.MULTILINE)


def strip_material_libraries(data: bytes) -> bytes:
    """OBJ bytes without their ``mtllib`` statements (materials are never read), continuation
    lines joined. Each step runs only where its bytes occur (the regular expression took 15 ms
    over a 3.7 MB file without ``mtllib``)."""
    if b"\\" in data:
        data = data.replace(b"\\\r\n", b"").replace(b"\\\n", b"")
    if b"mtllib" not in data:
        return data
    return _MTLLIB.sub(b"", data)


def _file_bytes(path: str) -> bytes:
    """The bytes of ``path``, refused before reading beyond the mesh file limit."""
    size = os.path.getsize(path)
    if size > MAX_MESH_FILE_BYTES:
        raise FormatError(f"mesh file is {size} bytes, larger than the limit of "
                          f"{MAX_MESH_FILE_BYTES} bytes", path)
    with open(path, "rb") as handle:
        data = handle.read(MAX_MESH_FILE_BYTES + 1)
    if len(data) > MAX_MESH_FILE_BYTES:
        raise FormatError(f"mesh file is larger than the limit of {MAX_MESH_FILE_BYTES} bytes",
                          path)
    return data


#: Vertex properties that make a PLY a 3DGS splat file (the original 3DGS writer's names).
_SPLAT_PROPERTIES = ("scale_0", "rot_0", "opacity", "f_dc_0")


def _refuse_point_cloud(header: PlyHeader, path: str) -> None:
    """A PLY without faces is a point cloud, not a triangle mesh: refused with one line that
    says what it is (a 3DGS splat file is the usual mistake: the splats given as ``--mesh``)."""
    face = header.element("face")
    if face is not None and face.count > 0:
        return
    why = "no 'face' element" if face is None else "an empty 'face' element"
    vertex = header.element("vertex")
    count = vertex.count if vertex is not None else 0
    names = set(vertex.names) if vertex is not None else set()
    if names.issuperset(_SPLAT_PROPERTIES):
        raise FormatError(f"is a point cloud of {count} Gaussian splats (a 3DGS PLY: {why}), "
                          "not a triangle mesh; give the mesh the splats belong to (.obj, .ply "
                          "with faces, .stl, .off, .glb, .gltf), or no mesh to reconstruct one "
                          "from the splats", path)
    raise FormatError(f"is a point cloud of {count} vertices ({why}), not a triangle mesh",
                      path)


def _check_binary_stl(data: bytes, path: str) -> None:
    """Refuse a truncated binary STL (an 80-byte header, a uint32 triangle count, 50 bytes a
    triangle) before trimesh sees it: trimesh then tries the bytes as ASCII STL and fails
    with an unrelated cause. A file that begins ``solid`` and has a ``facet`` within its
    first kilobyte is ASCII STL and left to trimesh."""
    if data.lstrip()[:5].lower() == b"solid" and b"facet" in data[:1024].lower():
        return
    if len(data) < 84:
        raise FormatError(f"truncated binary STL: {len(data)} bytes, shorter than the 84-byte "
                          f"header and triangle count", path)
    count = struct.unpack_from("<I", data, 80)[0]
    if len(data) < 84 + 50 * count:
        raise FormatError(f"truncated binary STL: the header declares {count} triangles "
                          f"({84 + 50 * count} bytes) but the file has {len(data)} bytes", path)


#: The meshes read inside :func:`read_meshes_once`, by file identity (None outside it).
_READ_ONCE: dict[tuple, TriangleMesh] | None = None


@contextlib.contextmanager
def read_meshes_once() -> Iterator[None]:
    """Inside this block :func:`read_mesh` parses a file once: a second read of the same file
    (same device, inode, size and modification time) returns the mesh the first read
    returned, the same object. ``gsverse-convert`` wraps source detection and loading in it:
    a detector that looks at the ``--mesh`` file (SuGaR's counts its faces) and the loader then
    share one parse. Callers inside the block must not change the mesh in place. Blocks nest;
    the meshes are let go when the outermost block ends."""
    global _READ_ONCE
    outer = _READ_ONCE is None
    if outer:
        _READ_ONCE = {}
    try:
        yield
    finally:
        if outer:
            _READ_ONCE = None


def read_mesh(path: str | os.PathLike[str]) -> TriangleMesh:
    """Read a triangle mesh; raises :class:`FormatError` with a one-line cause on bad input
    (each file parsed once inside :func:`read_meshes_once`)."""
    path = os.fspath(path)
    if _READ_ONCE is None:
        return _read_mesh(path)
    try:
        st = os.stat(path)
    except OSError:
        return _read_mesh(path)   # its own one-line error
    key = (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)
    mesh = _READ_ONCE.get(key)
    if mesh is None:
        mesh = _READ_ONCE[key] = _read_mesh(path)
    return mesh


def _read_mesh(path: str) -> TriangleMesh:
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
    if ext == ".ply":
        # The strict PLY reader (declared counts checked before allocation, fuzzed).
        from .ply import read_ply_header, read_ply_mesh

        _refuse_point_cloud(read_ply_header(path), path)
        return read_ply_mesh(path, triangulate=True)
    try:
        data = _file_bytes(path)
    except OSError as exc:
        raise FormatError(f"cannot read mesh: {type(exc).__name__}: {exc}".splitlines()[0],
                          path) from None
    if ext == ".obj":
        data = strip_material_libraries(data)
        plain = read_obj_triangles(data)
        if plain is not None:
            del data
            return _triangle_mesh(*plain, path)
    elif ext == ".stl":
        _check_binary_stl(data, path)
    with interruptions_immediate():   # trimesh's import catches BaseException too
        import trimesh

    try:
        # trimesh's readers catch BaseException and retry on slower paths, which would
        # swallow an interruption raised inside them: there a stop signal ends the process
        with warnings.catch_warnings(), interruptions_immediate():
            warnings.simplefilter("ignore")
            # bytes, not the path: trimesh gets no resolver and cannot open other files
            loaded = trimesh.load(io.BytesIO(data), file_type=ext[1:], process=False,
                                  maintain_order=True, force="mesh", skip_materials=True)
        del data
    except FormatError:
        raise
    except ImportError as exc:   # an optional package trimesh needs for this file
        raise UsageError(f"reading this {ext} mesh needs the Python package "
                         f"{exc.name or exc}; install it with pip", path) from None
    except (ValueError, TypeError, KeyError, IndexError, AttributeError, OverflowError,
            UnicodeError, EOFError, OSError, struct.error) as exc:
        # what trimesh's parsers raise on malformed files (it has no error type of its own)
        raise FormatError(f"cannot read mesh: {type(exc).__name__}: {exc}".splitlines()[0], path)
    if not isinstance(loaded, trimesh.Trimesh):
        raise FormatError("file holds no triangle mesh", path)
    return _triangle_mesh(np.asarray(loaded.vertices, dtype=np.float64),
                          np.asarray(loaded.faces, dtype=np.int64), path)


def _triangle_mesh(vertices: np.ndarray, faces: np.ndarray, path: str) -> TriangleMesh:
    """The checked float32 / uint32 mesh of what a reader returned (refused with one line)."""
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
