"""Stand-in for ``gsverse-convert --physics ... --ground``: add the physics records to a scene the
converter wrote with ``--mesh ... --collider hull``.

Each splat node of an object gets ``extensions.KHR_physics_rigid_bodies`` (the Khronos draft):
``motion`` (``{}`` for rigid and soft, ``{"isKinematic": true}`` for kinematic, none for static)
and a ``collider`` whose ``geometry.node`` is a new node outside every scene holding the
object's convex hull (the converter's ``extras.gsverse.collider`` mesh, in the splat node's local
space) with ``convexHull: true``; ``extras.gsverse.physics`` is the object's kind. With
``ground``, a node ``ground`` in the scene holds a static box collider (``KHR_implicit_shapes``)
whose top face is at the lowest point of the scene. Once the converter writes these records
itself, this module goes.
"""
from __future__ import annotations

import json
import struct

import numpy as np

RIGID_BODIES = "KHR_physics_rigid_bodies"
IMPLICIT_SHAPES = "KHR_implicit_shapes"
KINDS = ("rigid", "soft", "kinematic", "static")
#: the ground box's thickness and its margin around the scene, relative to the scene's largest
#: horizontal extent
GROUND_THICKNESS = 0.1
GROUND_MARGIN = 0.5


def _read_glb(path: str) -> tuple[dict, bytes]:
    data = open(path, "rb").read()
    magic, _version, _length = struct.unpack_from("<III", data, 0)
    if magic != 0x46546C67:
        raise ValueError(f"{path}: not a GLB")
    n, kind = struct.unpack_from("<II", data, 12)
    if kind != 0x4E4F534A:
        raise ValueError(f"{path}: the first GLB chunk is not JSON")
    json_doc = json.loads(data[20:20 + n])
    rest = data[20 + n:]
    return json_doc, rest


def _write_glb(path: str, doc: dict, rest: bytes) -> None:
    from gsverse_format.atomic import atomic_write

    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    header = struct.pack("<III", 0x46546C67, 2, 12 + 8 + len(text) + len(rest))
    with atomic_write(path, "wb") as handle:
        handle.write(header + struct.pack("<II", len(text), 0x4E4F534A) + text + rest)


def _anchor_mesh(mesh: dict) -> int | None:
    for prim in mesh.get("primitives", []):
        nested = prim.get("extensions", {}).get("KHR_gaussian_splatting", {}).get("extensions", {})
        anchor = nested.get("GSVERSE_gaussian_splatting_mesh_anchor")
        if anchor is not None:
            return anchor["mesh"]
    return None


def _scene_bounds(doc: dict) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of every POSITION of the meshes the scene's nodes draw (their accessors' min and
    max; the converter writes them, and its nodes carry no transform)."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for node in doc["nodes"]:
        if "mesh" not in node:
            continue
        if any(k in node for k in ("matrix", "translation", "rotation", "scale")):
            raise ValueError("a node with a transform: the stand-in handles the converter's output only")
        for prim in doc["meshes"][node["mesh"]]["primitives"]:
            acc = doc["accessors"][prim["attributes"]["POSITION"]]
            lo = np.minimum(lo, acc["min"])
            hi = np.maximum(hi, acc["max"])
    return lo, hi


def add_physics_records(path: str, kinds: dict[str, str], ground: bool = True) -> None:
    """Add the physics records to the GLB at ``path`` in place; ``kinds`` maps each object's
    name (the ``--mesh`` file stem, the start of its splat node's name) to its kind."""
    doc, rest = _read_glb(path)
    nodes, meshes = doc["nodes"], doc["meshes"]
    hulls = {m["extras"]["gsverse"]["for"]: i for i, m in enumerate(meshes)
             if m.get("extras", {}).get("gsverse", {}).get("collider") == "hull"}
    done = set()
    for node in list(nodes):
        if "mesh" not in node:
            continue
        anchor = _anchor_mesh(meshes[node["mesh"]])
        if anchor is None:
            continue
        name = next((k for k in kinds if node.get("name", "").split(" ")[0] == k), None)
        if name is None:
            raise ValueError(f"{path}: splat node {node.get('name')!r} matches no object of {sorted(kinds)}")
        kind = kinds[name]
        if kind not in KINDS:
            raise ValueError(f"{name}: physics kind must be one of {KINDS}, not {kind!r}")
        nodes.append({"name": f"{name} collider", "mesh": hulls[anchor]})
        record: dict = {"collider": {"geometry": {"node": len(nodes) - 1, "convexHull": True}}}
        if kind in ("rigid", "soft"):
            record["motion"] = {}
        elif kind == "kinematic":
            record["motion"] = {"isKinematic": True}
        node.setdefault("extensions", {})[RIGID_BODIES] = record
        node.setdefault("extras", {}).setdefault("gsverse", {})["physics"] = kind
        done.add(name)
    missing = set(kinds) - done
    if missing:
        raise ValueError(f"{path}: no splat node for {sorted(missing)}")
    used = doc.setdefault("extensionsUsed", [])
    used.append(RIGID_BODIES)
    if ground:
        lo, hi = _scene_bounds(doc)
        size = hi - lo
        width = (1 + 2 * GROUND_MARGIN) * max(size[0], size[2])
        t = GROUND_THICKNESS * max(size[0], size[2])
        shapes = doc.setdefault("extensions", {}).setdefault(IMPLICIT_SHAPES, {}).setdefault("shapes", [])
        shapes.append({"type": "box", "box": {"size": [width, t, width]}})
        centre = 0.5 * (lo + hi)
        nodes.append({"name": "ground", "translation": [float(centre[0]), float(lo[1] - t / 2), float(centre[2])],
                      "extensions": {RIGID_BODIES: {"collider": {"geometry": {"shape": len(shapes) - 1}}}}})
        doc["scenes"][doc.get("scene", 0)]["nodes"].append(len(nodes) - 1)
        used.append(IMPLICIT_SHAPES)
    _write_glb(path, doc, rest)
