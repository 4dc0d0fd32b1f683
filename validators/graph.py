"""Checks of what a glTF file holds besides splats: the node hierarchy and the index ranges of
mesh primitives that are neither splats nor anchor meshes (those have their own checks).

glTF 2.0 requires the nodes to form disjoint strict trees: no node is the child of two nodes
(``NODE_GRAPH_INVALID``), no node is its own ancestor (a cycle anywhere among the nodes:
``GLTF_SCHEMA_VIOLATION``, as the scene reader reports it), and a scene lists only root nodes
(``NODE_GRAPH_INVALID``). A reader that follows such a graph loops forever or expands it
exponentially. An index of a mesh primitive must be less than the count of its
POSITION accessor (``MESH_INDEX_OUT_OF_RANGE``).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from gsverse_format.codes import Code
from gsverse_format.vocabulary import KHR

from .container import Context

__all__ = ["check_node_graph", "check_mesh_indices"]


def _index(value: Any, size: int) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and 0 <= value < size


def check_node_graph(ctx: Context) -> tuple[int, bool]:
    """Report child references that do not resolve, nodes with several parents, cycles and
    scene roots that are children; returns the number of nodes and whether there is a
    cycle."""
    nodes = ctx.array("nodes")
    n = len(nodes)
    parent = [-1] * n
    children: list[list[int]] = [[] for _ in range(n)]
    shared = 0
    first_shared = None
    for i, node in enumerate(nodes):
        kids = node.get("children", []) if isinstance(node, dict) else []
        if not isinstance(kids, list):
            ctx.issues.add(Code.GLTF_SCHEMA_VIOLATION, "children must be an array of node "
                           "indices", pointer=f"/nodes/{i}/children")
            continue
        for j, c in enumerate(kids):
            if not _index(c, n):
                ctx.issues.add(Code.UNRESOLVED_REFERENCE, f"node index {c!r:.40} does not "
                               f"exist (there are {n} nodes)", pointer=f"/nodes/{i}/children/{j}")
                continue
            children[i].append(c)
            if parent[c] >= 0:
                shared += 1
                if first_shared is None:
                    first_shared = (c, parent[c], i, j)
            else:
                parent[c] = i
    if first_shared is not None:
        c, a, b, j = first_shared
        what = (f"node {a} lists node {c} twice" if a == b else
                f"node {c} is a child of both node {a} and node {b}")
        ctx.issues.add(Code.NODE_GRAPH_INVALID, f"{what} ({shared} such reference(s)): nodes "
                       f"must form strict trees", pointer=f"/nodes/{b}/children/{j}")
    cycle = _find_cycle(children)
    if cycle is not None:
        shown = " -> ".join(map(str, cycle[:8])) + (" -> ..." if len(cycle) > 8 else "")
        ctx.issues.add(Code.GLTF_SCHEMA_VIOLATION, f"the node hierarchy has a cycle ({shown} -> "
                       f"{cycle[0]}): a node is its own ancestor",
                       pointer=f"/nodes/{cycle[-1]}/children")
    for s, scene in enumerate(ctx.array("scenes")):
        roots = scene.get("nodes", []) if isinstance(scene, dict) else []
        for k, r in enumerate(roots if isinstance(roots, list) else []):
            if not _index(r, n):
                ctx.issues.add(Code.UNRESOLVED_REFERENCE, f"node index {r!r:.40} does not exist "
                               f"(there are {n} nodes)", pointer=f"/scenes/{s}/nodes/{k}")
            elif parent[r] >= 0:
                ctx.issues.add(Code.NODE_GRAPH_INVALID, f"scene {s} lists node {r}, a child of "
                               f"node {parent[r]}: a scene lists root nodes only",
                               pointer=f"/scenes/{s}/nodes/{k}")
                break
    return n, cycle is not None


def _find_cycle(children: list[list[int]]) -> list[int] | None:
    """One cycle of the directed graph ``children`` (a list of its nodes), or None; iterative
    depth-first search, linear in nodes plus edges."""
    state = [0] * len(children)  # 0 new, 1 on the current path, 2 done
    for root in range(len(children)):
        if state[root]:
            continue
        path = [root]
        edges = [0]
        state[root] = 1
        while path:
            node = path[-1]
            if edges[-1] < len(children[node]):
                nxt = children[node][edges[-1]]
                edges[-1] += 1
                if state[nxt] == 1:
                    return path[path.index(nxt):]
                if state[nxt] == 0:
                    state[nxt] = 1
                    path.append(nxt)
                    edges.append(0)
            else:
                state[node] = 2
                path.pop()
                edges.pop()
    return None


def check_mesh_indices(ctx: Context) -> int:
    """Index ranges of the mesh primitives that are neither splats (``KHR_gaussian_splatting``)
    nor anchor meshes (checked with the anchors); returns how many primitives were checked."""
    checked = 0
    for m, mesh in enumerate(ctx.array("meshes")):
        prims = mesh.get("primitives", []) if isinstance(mesh, dict) else []
        for p, prim in enumerate(prims if isinstance(prims, list) else []):
            if not isinstance(prim, dict) or ("anchor", m, p) in ctx.cache:
                continue
            extensions = prim.get("extensions")
            if isinstance(extensions, dict) and KHR in extensions:
                continue
            attrs = prim.get("attributes")
            if not isinstance(attrs, dict) or "POSITION" not in attrs or "indices" not in prim:
                continue
            pointer = f"/meshes/{m}/primitives/{p}"
            positions = ctx.accessor(attrs["POSITION"], f"{pointer}/attributes/POSITION")
            indices = ctx.accessor(prim["indices"], f"{pointer}/indices")
            if positions is None or indices is None:
                continue
            checked += 1
            if indices.gtype != "SCALAR" or indices.dtype.kind not in "iu":
                ctx.issues.add(Code.MESH_INDEX_OUT_OF_RANGE, f"the indices accessor is "
                               f"{indices.gtype} of {indices.dtype}, not unsigned integer "
                               f"scalars", pointer=f"{pointer}/indices")
                continue
            values = ctx.read(indices, "indices")
            if values is None or not values.size:
                continue
            bad = int(np.count_nonzero(values.astype(np.int64) >= positions.count))
            if bad:
                ctx.issues.add(Code.MESH_INDEX_OUT_OF_RANGE, f"{bad} of {values.size} indices are "
                               f"not less than the POSITION count {positions.count} (largest "
                               f"{int(values.max())})", pointer=f"{pointer}/indices")
    return checked
