"""Plain 3DGS PLY source: splats from any 3DGS-layout PLY, anchored to a given mesh.

With ``--mesh`` the mesh is read as is, assumed to be in the same frame as the PLY, and both
are rotated into the glTF frame together; every splat is then bound to its nearest triangle by
the pipeline. Without a mesh, :mod:`gsverse_format.converters.reconstruct` builds one from the
splats themselves.
"""
from __future__ import annotations

from ..io.mesh import read_mesh
from ..io.ply import read_splat_ply
from ..transform import PLY_TO_GLTF, rotate_mesh, rotate_splats
from .base import SourceOptions, SourceResult


def load(input_path: str, mesh_path: str | None, options: SourceOptions) -> SourceResult:
    if mesh_path is None:
        from . import reconstruct

        return reconstruct.load(input_path, None, options)
    splats = read_splat_ply(input_path)
    mesh = read_mesh(mesh_path)
    notes = []
    if options.frame_change:
        splats = rotate_splats(splats, PLY_TO_GLTF)
        mesh = rotate_mesh(mesh, PLY_TO_GLTF)
        notes.append("3DGS frame (+Y down) rotated 180 degrees about Z into glTF (+Y up)")
    return SourceResult(splats, mesh, None, notes)
