"""Reading a glTF scene as one triangle mesh (an anchor mesh supplied as ``.glb``/``.gltf``)."""
from __future__ import annotations

import os
from typing import Any

import numpy as np

from ... import quaternion as quat
from ...codes import Code
from ...errors import FormatError
from ...model import TriangleMesh
from .container import DEFAULT_MAX_BYTES, as_index, gltf_error, is_int
from .document import Document, open_document
from .reader import TRIANGLES, SplatReader, input_errors

__all__ = ["mesh_instances", "read_gltf_triangles"]


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

    Without scenes, every mesh once with the identity. Node cycles are an error.
    """
    return [(m, world) for _, m, world in node_instances(doc)]


def node_instances(doc: dict) -> list[tuple[int | None, int, np.ndarray]]:
    """(node index or None, mesh index, global matrix), as :func:`mesh_instances`."""
    nodes = _array(doc.get("nodes"), "nodes", "/nodes")
    meshes = _array(doc.get("meshes"), "meshes", "/meshes")
    scenes = _array(doc.get("scenes"), "scenes", "/scenes")
    if not scenes:
        return [(None, m, np.eye(4)) for m in range(len(meshes))]
    chosen = doc.get("scene")
    s = chosen if isinstance(chosen, int) and is_int(chosen) and 0 <= chosen < len(scenes) else 0
    scene = scenes[s]
    if not isinstance(scene, dict):
        raise gltf_error(Code.GLTF_SCHEMA_VIOLATION, f"scenes[{s}] must be an object",
                         f"/scenes/{s}")
    roots = _array(scene.get("nodes"), f"scenes[{s}].nodes", f"/scenes/{s}/nodes")
    out: list[tuple[int | None, int, np.ndarray]] = []
    stack = [(as_index(n, len(nodes), "scene node", f"/scenes/{s}/nodes/{k}"), np.eye(4), 0)
             for k, n in enumerate(roots)]
    while stack:
        i, parent, depth = stack.pop()
        if depth > len(nodes):
            raise gltf_error(Code.GLTF_SCHEMA_VIOLATION, "the node hierarchy has a cycle",
                             f"/nodes/{i}")
        node = nodes[i]
        world = parent @ _node_matrix(nodes, i)
        if node.get("mesh") is not None:
            out.append((i, as_index(node["mesh"], len(meshes), f"nodes[{i}].mesh",
                                    f"/nodes/{i}/mesh"), world))
        children = _array(node.get("children"), f"nodes[{i}].children", f"/nodes/{i}/children")
        for k, child in enumerate(children):
            stack.append((as_index(child, len(nodes), f"nodes[{i}].children",
                                   f"/nodes/{i}/children/{k}"), world, depth + 1))
    return out


def scene_triangles(document: Document) -> TriangleMesh:
    """All TRIANGLES primitives of the default scene of an opened document as one mesh."""
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
    order: meshes in scene traversal order, primitives and triangles in file order. Skins and
    morph targets are not applied (the bind pose is used); a scene drawing one skinned and/or
    morphed primitive keeps them as ``TriangleMesh.rig`` (:func:`.rig.read_rig`). Same
    hardening and errors as :func:`~.reader.read_gltf`.
    """
    spath = os.fspath(path)
    from .rig import read_rig

    with input_errors(spath, "mesh"):
        document = open_document(spath, max_bytes)
        mesh = scene_triangles(document)
        mesh.rig = read_rig(document, node_instances(document.doc))
    return mesh
