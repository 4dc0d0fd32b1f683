"""Triggering assets of the codes of ``validators/issues_input.py`` (what a file holds besides
its splats), registered in :data:`validation_assets.TRIGGERS`."""
from __future__ import annotations

import numpy as np

from gsverse_format.vocabulary import KHR
from validation_assets import _edited, trigger


def _plain_mesh(d) -> int:
    """Add a triangle mesh (4 vertices, 2 triangles, 32-bit indices) and a node for it;
    returns the index of the new mesh."""
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float32)
    pos = d.add_accessor(vertices, 5126, "VEC3", minmax=True)
    idx = d.add_accessor(np.array([0, 1, 2, 1, 3, 2], np.uint32), 5125, "SCALAR")
    d.doc["meshes"].append({"primitives": [{"attributes": {"POSITION": pos}, "indices": idx}]})
    d.doc["nodes"].append({"mesh": len(d.doc["meshes"]) - 1})
    return len(d.doc["meshes"]) - 1


@trigger("NO_SPLATS")
def _(folder):
    def edit(d):  # every splat primitive holds zero splats: its accessors have count 0
        for mesh in d.doc["meshes"]:
            for prim in mesh["primitives"]:
                if KHR in prim.get("extensions", {}):
                    for ref in prim["attributes"].values():
                        d.doc["accessors"][ref]["count"] = 0
    return _edited(folder, "empty.glb", edit)


@trigger("MESH_INDEX_OUT_OF_RANGE")
def _(folder):
    def edit(d):
        m = _plain_mesh(d)
        d.values(d.doc["meshes"][m]["primitives"][0]["indices"])[4] = 9
    return _edited(folder, "mesh_index.glb", edit)


@trigger("NODE_GRAPH_INVALID")
def _(folder):
    def edit(d):
        _plain_mesh(d)
        last = len(d.doc["nodes"]) - 1
        d.doc["nodes"].append({"children": [last, last]})  # one child listed twice
    return _edited(folder, "dag.glb", edit)
