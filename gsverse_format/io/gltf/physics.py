"""Physics in glTF: ``KHR_physics_rigid_bodies`` and ``KHR_implicit_shapes`` written beside the
splats and read back (spec/README.md §Physics; the rules in :mod:`gsverse_format.physics`).

Written: on the node of each anchored primitive with :attr:`~gsverse_format.model.
SplatPrimitive.physics`, the rigid-body object (:func:`~gsverse_format.physics.body_object`)
whose collider geometry is a node outside every scene holding the collider mesh of its anchor
mesh, and ``extras.gsverse.physics``; for :attr:`~gsverse_format.model.SplatAsset.ground`, a
scene node ``ground`` (no mesh) whose collider is a ``KHR_implicit_shapes`` box. Read: the
same, into the model; a node or shape that does not fit this layout is left out (the
validator reports what is wrong with it).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import pygltflib

from ...errors import UsageError
from ...model import Collider, Ground, Physics, SplatAsset, SplatPrimitive
from ...physics import (GROUND_NAME, PHYSICS, PHYSICS_KINDS, SHAPES, body_object, box_shape,
                        ground_object, kind_of)
from ...vocabulary import EXTENSION, KHR

__all__ = ["PhysicsOutput", "write_physics", "read_physics"]

TRIANGLES = 4


@dataclass
class PhysicsOutput:
    """What the physics adds to a document: ``nodes`` appended after the others (collider
    nodes, in no scene, then the ground), the ``roots`` the scene lists, the top-level
    ``extensions`` and the names for ``extensionsUsed``."""

    nodes: list[pygltflib.Node] = field(default_factory=list)
    roots: list[int] = field(default_factory=list)
    extensions: dict[str, Any] = field(default_factory=dict)
    used: list[str] = field(default_factory=list)


def write_physics(asset: SplatAsset, prim_nodes: list[pygltflib.Node],
                  collider_mesh: dict[int, int], first_node: int) -> PhysicsOutput:
    """The physics of ``asset``: sets the rigid-body object and ``extras.gsverse.physics`` on
    ``prim_nodes[i]`` (the node of primitive ``i``) and returns the nodes to append from index
    ``first_node`` on. ``collider_mesh``: ``id(anchor mesh)`` -> the glTF mesh index of its
    collider. :class:`UsageError` for physics the file cannot hold."""
    out = PhysicsOutput()
    for i, prim in enumerate(asset.primitives):
        body = prim.physics
        if body is None:
            continue
        if body.kind not in PHYSICS_KINDS:
            raise UsageError(f"primitive {i}: unknown physics kind {body.kind!r}")
        if body.mass is not None and not (math.isfinite(body.mass) and body.mass > 0):
            raise UsageError(f"primitive {i}: a mass must be finite and above 0, not "
                             f"{body.mass!r}")
        c = collider_mesh.get(id(prim.anchoring.mesh)) if prim.anchoring is not None else None
        if c is None:
            raise UsageError(f"primitive {i}: physics needs an anchored primitive with a "
                             f"collider of its anchor mesh (SplatAsset.colliders)")
        h = first_node + len(out.nodes)
        out.nodes.append(pygltflib.Node(name=f"{prim.name or f'primitive {i}'} collider", mesh=c,
                                        children=None))
        node = prim_nodes[i]
        node.extensions = {PHYSICS: body_object(body.kind, h,
                                                body.mass if body.kind != "static" else None)}
        node.extras = {"gsverse": {"physics": body.kind}}
    if out.nodes:
        out.used.append(PHYSICS)
    if asset.ground is not None:
        size = [float(s) for s in asset.ground.size]
        if not all(math.isfinite(s) and s > 0 for s in size):
            raise UsageError(f"the ground box's size must be finite and above 0, not {size}")
        out.extensions[SHAPES] = {"shapes": [box_shape(size)]}
        out.roots.append(first_node + len(out.nodes))
        out.nodes.append(pygltflib.Node(
            name=GROUND_NAME, translation=[float(t) for t in asset.ground.translation],
            extensions={PHYSICS: ground_object(0)}, children=None))
        if PHYSICS not in out.used:
            out.used.append(PHYSICS)
        out.used.append(SHAPES)
    return out


def _index(value: Any, size: int) -> int | None:
    ok = isinstance(value, int) and not isinstance(value, bool) and 0 <= value < size
    return value if ok else None


def _dict(value: Any) -> dict:
    return value if isinstance(value, dict) else {}


def _anchor_mesh_index(mesh: dict, p: int) -> int | None:
    """The anchor mesh index of primitive ``p`` of the glTF mesh ``mesh``, or None."""
    prims = mesh.get("primitives")
    if not isinstance(prims, list) or _index(p, len(prims)) is None:
        return None
    ext = _dict(_dict(_dict(_dict(prims[p]).get("extensions")).get(KHR)).get("extensions"))
    m = _dict(ext.get(EXTENSION)).get("mesh")
    return m if isinstance(m, int) and not isinstance(m, bool) else None


def _triangle_mesh(reader: Any, node: Any) -> int | None:
    """The mesh index of ``node`` when its first primitive is TRIANGLES, else None."""
    m = _index(_dict(node).get("mesh"), len(reader.meshes))
    if m is None:
        return None
    prims = reader.meshes[m].get("primitives")
    if not isinstance(prims, list) or not prims or \
            _dict(prims[0]).get("mode", TRIANGLES) != TRIANGLES:
        return None
    return m


def _ground(doc: dict, nodes: list) -> Ground | None:
    """The first node laid out as :func:`write_physics` writes the ground, as a Ground."""
    shapes = _dict(_dict(doc.get("extensions")).get(SHAPES)).get("shapes")
    shapes = shapes if isinstance(shapes, list) else []
    for node in nodes:
        node = _dict(node)
        body = _dict(_dict(node.get("extensions")).get(PHYSICS))
        if not body or "motion" in body or node.get("mesh") is not None or \
                any(k in node for k in ("matrix", "rotation", "scale")):
            continue
        s = _index(_dict(_dict(body.get("collider")).get("geometry")).get("shape"), len(shapes))
        shape = _dict(shapes[s]) if s is not None else {}
        size = _dict(shape.get("box")).get("size")
        if shape.get("type") != "box" or not isinstance(size, list) or len(size) != 3 or \
                not all(isinstance(v, (int, float)) and math.isfinite(v) and v > 0
                        for v in size):
            continue
        t = node.get("translation", [0.0, 0.0, 0.0])
        if not (isinstance(t, list) and len(t) == 3 and
                all(isinstance(v, (int, float)) and math.isfinite(v) for v in t)):
            continue
        return Ground(tuple(float(v) for v in size), tuple(float(v) for v in t))
    return None


def read_physics(reader: Any, primitives: list[SplatPrimitive],
                 sources: list[tuple[int, int]]) -> tuple[list[Collider], Ground | None]:
    """Physics of a document read by the glTF ``reader`` (a :class:`~.reader.SplatReader`):
    sets :attr:`~gsverse_format.model.SplatPrimitive.physics` of each anchored primitive
    (from mesh and primitive ``sources[i]``) whose node is a body with a mesh collider, and
    returns the colliders (those of the bodies, and the meshes marked
    ``extras.gsverse.collider`` for an anchor mesh) and the ground."""
    nodes = reader.nodes
    by_mesh: dict[int, dict] = {}
    for node in nodes:
        m = _dict(node).get("mesh")
        if isinstance(m, int) and m not in by_mesh:
            by_mesh[m] = node
    colliders: list[Collider] = []
    done: set[tuple[int, int]] = set()  # (collider mesh, anchor mesh) already read

    def collider(c: int, a: int, anchor: Any) -> Collider | None:
        if (c, a) in done:
            return next(x for x in colliders if x.anchor is anchor)
        kind = _dict(_dict(reader.meshes[c].get("extras")).get("gsverse")).get("collider")
        found = Collider(reader.triangles(c, 0), anchor, kind if isinstance(kind, str) else "hull")
        colliders.append(found)
        done.add((c, a))
        return found

    anchors: dict[int, Any] = {}
    for prim, (m, p) in zip(primitives, sources):
        a = _anchor_mesh_index(reader.meshes[m], p)
        if prim.anchoring is None or a is None:
            continue
        anchors.setdefault(a, prim.anchoring.mesh)
        node = _dict(by_mesh.get(m))
        body = _dict(node.get("extensions")).get(PHYSICS)
        kind = kind_of(body, _dict(_dict(node.get("extras")).get("gsverse")).get("physics"))
        geometry = _dict(_dict(_dict(body).get("collider")).get("geometry"))
        h = _index(geometry.get("node"), len(nodes))
        c = _triangle_mesh(reader, nodes[h]) if h is not None else None
        if kind is None or c is None:
            continue
        collider(c, a, prim.anchoring.mesh)
        motion = _dict(_dict(body).get("motion"))
        mass = motion.get("mass")
        ok = isinstance(mass, (int, float)) and not isinstance(mass, bool) and \
            math.isfinite(mass) and mass > 0
        prim.physics = Physics(kind, float(mass) if ok and kind != "static" else None)
    for c, mesh in enumerate(reader.meshes):  # colliders marked for older readers
        marked = _dict(_dict(mesh.get("extras")).get("gsverse"))
        a = marked.get("for")
        if "collider" in marked and isinstance(a, int) and a in anchors and \
                _triangle_mesh(reader, {"mesh": c}) is not None:
            collider(c, a, anchors[a])
    return colliders, _ground(reader.document.doc, nodes)
