"""PLY files: a container layer free of meaning, and the splat and mesh layers built on it.

* :mod:`.header`, :mod:`.binary_body`, :mod:`.ascii_body`, :mod:`.container`: any PLY file
  (ascii, binary little/big endian, list properties) to one structured numpy array per
  element and back (:func:`read_ply_header`, :func:`read_ply_elements`, :func:`write_ply`),
  strict and bounded: every problem is a one-line ``FormatError`` naming the file.
* :mod:`.splat`: the 3D Gaussian splatting layout (``f_dc``/``f_rest`` channel-major SH,
  opacity logits, log scales, ``rot_0..3`` quaternions, normals, the SH degree):
  :func:`read_splat_ply` (:func:`read_splat_means` for the positions alone),
  :func:`write_splat_ply`, :func:`describe_ply`, and the round-trip
  accuracy the writer guarantees.
* :mod:`.mesh`: triangle meshes (:func:`read_ply_mesh`).

The package registers the ``ply`` format in :mod:`gsverse_format.io.registry`: a splat asset in
the file's own frame (the 3DGS frame); the convert pipeline decides any frame change.
"""
from __future__ import annotations

from ..registry import register_format
from .container import PlyData, read_ply_elements, write_ply
from .header import PlyElement, PlyHeader, PlyProperty, read_ply_header
from .mesh import ply_triangles, read_ply_mesh
from .splat import (OPACITY_CLAMP, SCALE_FLOOR, SH_C0, describe_ply, read_ply_asset,
                    read_splat_means, read_splat_ply, write_ply_asset, write_splat_ply)

__all__ = [
    "PlyProperty",
    "PlyElement",
    "PlyHeader",
    "PlyData",
    "read_ply_header",
    "read_ply_elements",
    "write_ply",
    "ply_triangles",
    "read_ply_mesh",
    "read_splat_ply",
    "read_splat_means",
    "describe_ply",
    "write_splat_ply",
    "read_ply_asset",
    "write_ply_asset",
    "SH_C0",
    "OPACITY_CLAMP",
    "SCALE_FLOOR",
]

register_format("ply", (".ply",), read=read_ply_asset, write=write_ply_asset, frame="3dgs")
