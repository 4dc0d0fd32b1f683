"""Catalogue rows of what a file holds besides the splat data (:mod:`.graph` and
:mod:`.validate`): a file without splats, the node hierarchy and the index ranges of the other
meshes. Rows in the format of :mod:`.issues_rows`."""
from __future__ import annotations

from gsverse_format.codes import Code

from .issues_rows import Row

__all__ = ["INPUT_ENTRIES"]

_G = "What the file holds"

INPUT_ENTRIES: list[Row] = [
    (Code.NO_SPLATS, "ERROR", _G, "The file holds no splats: no KHR_gaussian_splatting "
     "primitive (glTF) or ParticleField3DGaussianSplat prim (USD), or only ones with no "
     "splats. The message says what was checked instead; a glTF file's materials, textures "
     "and animations are not checked by this validator.", "none",
     "Check that the right file was passed; converters refuse to write an asset without "
     "splats."),
    (Code.MESH_INDEX_OUT_OF_RANGE, "ERROR", _G, "A mesh primitive that is neither splats nor "
     "an anchor mesh has an index not less than its POSITION count, or indices that are not "
     "unsigned integer scalars.", "/meshes/{m}/primitives/{p}/indices",
     "Re-export the mesh; every index must name one of the primitive's vertices."),
    (Code.NODE_GRAPH_INVALID, "ERROR", _G, "The nodes do not form strict trees: a node is the "
     "child of two nodes (or twice the child of one), or a scene lists a node that is another "
     "node's child (a node that is its own ancestor is a GLTF_SCHEMA_VIOLATION). Readers that "
     "follow such a graph expand it exponentially.", "/nodes/{n}/children or /scenes/{s}/nodes",
     "Give every node at most one parent, with no cycles; list only root nodes in scenes."),
]
