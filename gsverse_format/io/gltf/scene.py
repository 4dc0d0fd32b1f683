"""Reading a glTF scene as one triangle mesh (an anchor mesh supplied as ``.glb``/``.gltf``)."""
from __future__ import annotations

import os
from typing import Any

import numpy as np

from ... import quaternion as quat
from ...codes import Code
from ...errors import FormatError
from ...limits import MAX_NODE_DEPTH, MAX_SCENE_INSTANCES, MAX_SCENE_TRIANGLES, MAX_SCENE_VERTICES
from ...model import TriangleMesh
from .container import DEFAULT_MAX_BYTES, as_index, gltf_error, is_int
from .document import Document, open_document
from .reader import TRIANGLES, SplatReader, input_errors

__all__ = ["check_instancing", "instance_counts", "scene_depth", "mesh_instances", "node_instances",
           "read_gltf_triangles"]


def _array(value: Any, what: str, pointer: str) -> list:
    if value is None:
        return []
    if not isinstance(value, list):
        raise gltf_error(Code.GLTF_SCHEMA_VIOLATION, f"{what} must be an array", pointer)
    return value


def _numbers(nodes: list, i: int, key: str, size: int, default: list[float]) -> np.ndarray:
    value = nodes[i].get(key)
    if value is None:
        return np.asarray(default, dtype=np.float64)
    if not isinstance(value, list) or len(value) != size or not all(
            isinstance(v, (int, float)) for v in value):
        raise gltf_error(Code.GLTF_SCHEMA_VIOLATION, f"nodes[{i}].{key} must be an array of "
                         f"{size} numbers", f"/nodes/{i}/{key}")
    return np.asarray(value, dtype=np.float64)


def _node_matrix(nodes: list, i: int) -> np.ndarray:
    """Local 4x4 matrix of node ``i`` (``matrix`` is column-major; else T·R·S)."""
    if nodes[i].get("matrix") is not None:
        return _numbers(nodes, i, "matrix", 16, []).reshape(4, 4).T
    out = np.eye(4)
    s = _numbers(nodes, i, "scale", 3, [1, 1, 1])
    r = _numbers(nodes, i, "rotation", 4, [0, 0, 0, 1])
    t = _numbers(nodes, i, "translation", 3, [0, 0, 0])
    out[:3, :3] = quat.to_matrix(r) * s[None, :]
    out[:3, 3] = t
    return out


def mesh_instances(doc: dict) -> list[tuple[int, np.ndarray]]:
    """(mesh index, global matrix) for every node of the default scene that has a mesh.

    Without scenes, every mesh once with the identity. Node cycles are an error, and so is a
    node graph that instantiates more meshes than :data:`~gsverse_format.limits.
    MAX_SCENE_INSTANCES` (counted before anything is expanded, see :func:`instance_counts`).
    """
    return [(m, world) for _, m, world in node_instances(doc)]


def _scene_roots(doc: dict) -> tuple[list, list[int], int] | None:
    """(nodes, root node indices, scene index) of the default scene; None without scenes."""
    nodes = _array(doc.get("nodes"), "nodes", "/nodes")
    scenes = _array(doc.get("scenes"), "scenes", "/scenes")
    if not scenes:
        return None
    chosen = doc.get("scene")
    s = chosen if isinstance(chosen, int) and is_int(chosen) and 0 <= chosen < len(scenes) else 0
    scene = scenes[s]
    if not isinstance(scene, dict):
        raise gltf_error(Code.GLTF_SCHEMA_VIOLATION, f"scenes[{s}] must be an object",
                         f"/scenes/{s}")
    roots = _array(scene.get("nodes"), f"scenes[{s}].nodes", f"/scenes/{s}/nodes")
    return nodes, [as_index(n, len(nodes), "scene node", f"/scenes/{s}/nodes/{k}")
                   for k, n in enumerate(roots)], s


def _children(nodes: list, i: int) -> list[int]:
    node = nodes[i]
    if not isinstance(node, dict):
        raise gltf_error(Code.GLTF_SCHEMA_VIOLATION, f"nodes[{i}] must be an object",
                         f"/nodes/{i}")
    children = _array(node.get("children"), f"nodes[{i}].children", f"/nodes/{i}/children")
    return [as_index(c, len(nodes), f"nodes[{i}].children", f"/nodes/{i}/children/{k}")
            for k, c in enumerate(children)]


def instance_counts(doc: dict) -> dict[int, int]:
    """node index -> how many times the default scene reaches it (paths from its roots).

    Dynamic programming over the node graph in topological order, nothing expanded: a node
    graph where each node lists the next one several times (legal JSON, an exponential
    number of paths) costs one pass over its edges. Counts saturate just above
    :data:`~gsverse_format.limits.MAX_SCENE_INSTANCES`. A cycle is an error
    (``GLTF_SCHEMA_VIOLATION`` at the node that closes it). Without scenes: empty.
    """
    found = _scene_order(doc)
    if found is None:
        return {}
    roots, children, order = found
    cap = MAX_SCENE_INSTANCES + 1
    counts: dict[int, int] = dict.fromkeys(order, 0)
    for root in roots:
        counts[root] = min(cap, counts[root] + 1)
    for i in reversed(order):
        for c in children[i]:
            counts[c] = min(cap, counts[c] + counts[i])
    return counts


def scene_depth(doc: dict) -> tuple[int, int | None]:
    """(levels, deepest node) of the default scene's node graph: the longest path from a root,
    a root alone being one level; (0, None) without scenes. One pass, as
    :func:`instance_counts`."""
    found = _scene_order(doc)
    if found is None:
        return 0, None
    roots, children, order = found
    depth: dict[int, int] = dict.fromkeys(order, 0)
    for root in roots:
        depth[root] = 1
    for i in reversed(order):
        for c in children[i]:
            depth[c] = max(depth[c], depth[i] + 1)
    deepest = max(depth, key=depth.__getitem__, default=None)
    return (depth[deepest] if deepest is not None else 0), deepest


def _scene_order(doc: dict) -> tuple[list[int], dict[int, list[int]], list[int]] | None:
    """(roots, children, post-order) of the default scene's node graph, every node after all
    of its descendants; None without scenes; ``GLTF_SCHEMA_VIOLATION`` for a cycle."""
    found = _scene_roots(doc)
    if found is None:
        return None
    nodes, roots, _ = found
    children: dict[int, list[int]] = {}
    state: dict[int, int] = {}  # 1: on the current path, 2: done
    order: list[int] = []       # post-order: every node after all of its descendants
    for root in roots:
        if root in state:
            continue
        state[root] = 1
        children[root] = _children(nodes, root)
        stack = [(root, 0)]
        while stack:
            i, k = stack[-1]
            if k < len(children[i]):
                stack[-1] = (i, k + 1)
                c = children[i][k]
                seen = state.get(c)
                if seen == 1:
                    raise gltf_error(Code.GLTF_SCHEMA_VIOLATION, f"the node hierarchy has a "
                                     f"cycle: nodes[{i}] lists its ancestor nodes[{c}] as a "
                                     f"child", f"/nodes/{i}/children/{k}")
                if seen is None:
                    state[c] = 1
                    children[c] = _children(nodes, c)
                    stack.append((c, 0))
            else:
                state[i] = 2
                order.append(i)
                stack.pop()
    return roots, children, order


def _primitive_size(doc: dict, prim: Any) -> tuple[int, int]:
    """(vertices, triangles) a TRIANGLES primitive declares (0, 0 for other modes), read from
    the accessor counts of the raw JSON; nothing is decoded."""
    if not isinstance(prim, dict) or prim.get("mode", TRIANGLES) != TRIANGLES:
        return 0, 0
    accessors = doc.get("accessors")
    accessors = accessors if isinstance(accessors, list) else []

    def count(ref: Any) -> int:
        if is_int(ref) and 0 <= ref < len(accessors) and isinstance(accessors[ref], dict):
            value = accessors[ref].get("count")
            return int(value) if is_int(value) and value > 0 else 0
        return 0

    attrs = prim.get("attributes")
    vertices = count(attrs.get("POSITION")) if isinstance(attrs, dict) else 0
    indices = prim.get("indices")
    return vertices, (count(indices) if indices is not None else vertices) // 3


def check_instancing(doc: dict) -> None:
    """Raise ``SIZE_LIMIT_EXCEEDED`` when flattening the default scene would visit more node
    instances, or make more mesh instances, vertices or triangles, or is deeper, than the
    limits of :mod:`gsverse_format.limits` (counted by :func:`instance_counts`,
    :func:`scene_depth` and the accessor counts, before any expansion);
    ``GLTF_SCHEMA_VIOLATION`` for a node cycle."""
    meshes = _array(doc.get("meshes"), "meshes", "/meshes")
    found = _scene_roots(doc)
    uses: list[tuple[int | None, Any, int]]
    if found is None:
        uses = [(None, m, 1) for m in range(len(meshes))]
    else:
        nodes = found[0]
        levels, deepest = scene_depth(doc)
        if levels > MAX_NODE_DEPTH:
            raise gltf_error(Code.SIZE_LIMIT_EXCEEDED, f"the scene's node hierarchy is {levels} "
                             f"levels deep, more than {MAX_NODE_DEPTH}", f"/nodes/{deepest}")
        counts = instance_counts(doc)
        visits = 0
        for node, n in counts.items():  # every node visit costs a matrix, mesh or not
            visits += n
            if visits > MAX_SCENE_INSTANCES:
                raise gltf_error(Code.SIZE_LIMIT_EXCEEDED, f"the scene's node graph expands to "
                                 f"more than {MAX_SCENE_INSTANCES} node instances (nodes listed "
                                 f"as children several times)", f"/nodes/{node}")
        uses = [(i, nodes[i]["mesh"], n) for i, n in counts.items()
                if n and nodes[i].get("mesh") is not None]
    instances = vertices = triangles = 0
    for i, m, n in uses:
        instances += n
        if instances > MAX_SCENE_INSTANCES:
            raise gltf_error(Code.SIZE_LIMIT_EXCEEDED, f"the scene instantiates meshes more "
                             f"than {MAX_SCENE_INSTANCES} times (node graph expanded by "
                             f"repeated children)", f"/nodes/{i}")
        if not (is_int(m) and 0 <= m < len(meshes)) or not isinstance(meshes[m], dict):
            continue  # reported where the instance is expanded
        prims = meshes[m].get("primitives")
        for prim in prims if isinstance(prims, list) else []:
            v, t = _primitive_size(doc, prim)
            vertices += n * v
            triangles += n * t
        if vertices > MAX_SCENE_VERTICES or triangles > MAX_SCENE_TRIANGLES:
            raise gltf_error(Code.SIZE_LIMIT_EXCEEDED, f"the scene's instances hold more than "
                             f"{MAX_SCENE_VERTICES} vertices or {MAX_SCENE_TRIANGLES} triangles "
                             f"(the limits of a flattened mesh)",
                             f"/nodes/{i}" if i is not None else f"/meshes/{m}")


def node_instances(doc: dict) -> list[tuple[int | None, int, np.ndarray]]:
    """(node index or None, mesh index, global matrix), as :func:`mesh_instances`."""
    meshes = _array(doc.get("meshes"), "meshes", "/meshes")
    found = _scene_roots(doc)
    if found is None:
        return [(None, m, np.eye(4)) for m in range(len(meshes))]
    nodes, roots, _ = found
    if sum(instance_counts(doc).values()) > MAX_SCENE_INSTANCES:  # cycles, before expanding
        check_instancing(doc)  # raises, naming the limit
    out: list[tuple[int | None, int, np.ndarray]] = []
    stack = [(i, np.eye(4)) for i in roots]
    while stack:
        i, parent = stack.pop()
        node = nodes[i]
        world = parent @ _node_matrix(nodes, i)
        if node.get("mesh") is not None:
            out.append((i, as_index(node["mesh"], len(meshes), f"nodes[{i}].mesh",
                                    f"/nodes/{i}/mesh"), world))
        for child in _children(nodes, i):
            stack.append((child, world))
    return out


def scene_triangles(document: Document) -> TriangleMesh:
    """All TRIANGLES primitives of the default scene of an opened document as one mesh."""
    check_instancing(document.doc)  # limits checked on the raw JSON, before expanding
    reader = SplatReader(document)
    vertices, faces, offset = [], [], 0
    for m, world in mesh_instances(document.doc):
        for p, prim in enumerate(reader.meshes[m].get("primitives", [])):
            if prim.get("mode", TRIANGLES) != TRIANGLES:
                continue
            tri = reader.triangles(m, p)
            v = tri.vertices.astype(np.float64) @ world[:3, :3].T + world[:3, 3]
            if np.linalg.det(world[:3, :3]) < 0:  # a mirroring node flips the winding
                f = tri.faces[:, ::-1]
            else:
                f = tri.faces
            vertices.append(v)
            faces.append(f.astype(np.int64) + offset)
            offset += len(v)
    if not faces:
        raise FormatError("the file has no triangle primitives in its scene")
    return TriangleMesh(np.concatenate(vertices), np.concatenate(faces))


def read_gltf_triangles(path: str | os.PathLike, *,
                        max_bytes: int = DEFAULT_MAX_BYTES) -> TriangleMesh:
    """All TRIANGLES primitives of the default scene as one mesh, node transforms applied.

    For reading an anchor mesh supplied as ``.glb``/``.gltf`` (e.g. a TRELLIS export). Face
    order: meshes in scene traversal order, primitives and triangles in file order. A scene
    with skins, morph targets or animated mesh nodes is read as what glTF draws at rest (a
    skinned primitive skinned with the skeleton at its nodes' values, not placed by its node's
    transform, which glTF ignores) and keeps its rig as ``TriangleMesh.rig``
    (:func:`.rig_read.read_rig`). Same hardening and errors as :func:`~.reader.read_gltf`.
    """
    spath = os.fspath(path)
    from .rig_read import read_rig

    with input_errors(spath, "mesh"):
        document = open_document(spath, max_bytes)
        mesh = scene_triangles(document)
        found = read_rig(document, node_instances(document.doc))
        if found is not None:
            rig, rest = found
            if np.abs(rest).max(initial=0.0) > np.finfo(np.float32).max:
                raise FormatError("skinning the mesh at rest gives vertex coordinates beyond "
                                  "the float32 range")
            mesh = TriangleMesh(rest, mesh.faces, rig=rig)
    return mesh
