"""Plain 3DGS PLY source: splats from any 3DGS-layout PLY, anchored to a given mesh.

With ``--mesh`` the mesh is read as is and taken to be in the same frame as the PLY (the 3DGS
frame, +Y down); the pipeline rotates both into the glTF frame together and binds every splat
to its nearest triangle. Without a mesh the result has none, and the pipeline reconstructs one
from the splats (:mod:`gsverse_format.converters.reconstruct`).
"""
from __future__ import annotations

from gsverse_format.converters.base import SourceOptions, SourceResult
from gsverse_format.converters.registry import register_source
from gsverse_format.io.mesh import read_mesh
from gsverse_format.io.ply import read_splat_ply

__all__ = ["load", "detect"]


def load(input_path: str, mesh_path: str | None, options: SourceOptions) -> SourceResult:
    """The PLY's splats and the mesh (if any), both in the 3DGS frame."""
    splats = read_splat_ply(input_path, keep_nonfinite=options.keep_nonfinite)
    mesh = read_mesh(mesh_path) if mesh_path is not None else None
    return SourceResult(splats, mesh, None, [], frame="3dgs")


def detect(input_path: str, mesh_path: str | None) -> str:
    """Every input not claimed by another source (no other layout with its evidence) is a
    plain 3DGS PLY."""
    return "plain 3DGS PLY (no other source recognised it; --from names one)"


register_source("3dgs", load, detect=detect, priority=100)
