"""Checks of the physics objects a scene relies on (spec/README.md §Physics): the
``KHR_physics_rigid_bodies`` object of every node (collider and trigger geometry, motion
values), the ``KHR_implicit_shapes`` shapes, the ``extras.gsverse.physics`` kinds and their
agreement with the rigid-body objects, and that both extensions are declared when used.
Joints, filters and materials are not checked (nothing here writes them).
"""
from __future__ import annotations

import math
from typing import Any

from gsverse_format.codes import Code
from gsverse_format.physics import PHYSICS, PHYSICS_KINDS, SHAPES
from gsverse_format.vocabulary import EXTENSION, KHR

from .container import Context

__all__ = ["check_physics"]

#: Parameters of each implicit shape type that, when given, must be above 0 (box: 3 numbers).
_SHAPE_SIZES: dict[str, tuple[str, ...]] = {
    "box": ("size",), "sphere": ("radius",), "plane": ("sizeX", "sizeZ"),
    "capsule": ("height", "radiusTop", "radiusBottom"),
    "cylinder": ("height", "radiusTop", "radiusBottom")}
#: Motion vectors and their lengths.
_VECTORS = {"centerOfMass": 3, "inertiaDiagonal": 3, "inertiaOrientation": 4,
            "linearVelocity": 3, "angularVelocity": 3}


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _index(v: Any, size: int) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and 0 <= v < size


def _shape_problem(shape: Any) -> str | None:
    if not isinstance(shape, dict):
        return "is not an object"
    kind = shape.get("type")
    if kind not in _SHAPE_SIZES:
        return f"has an unknown type {kind!r:.40} ({', '.join(_SHAPE_SIZES)})"
    params = shape.get(kind)
    if not isinstance(params, dict):
        return f"has no {kind} object"
    for key in _SHAPE_SIZES[kind]:
        value = params.get(key)
        if value is None:  # left out: the extension's default
            continue
        values = value if key == "size" and isinstance(value, list) and len(value) == 3 \
            else [value] if key != "size" else [None]
        if not all(_number(v) and v > 0 for v in values):
            return f"{kind}.{key} {value!r:.60} is not finite and above 0 (degenerate)"
    return None


def _motion_problem(motion: Any) -> str | None:
    if not isinstance(motion, dict):
        return "is not an object"
    if "isKinematic" in motion and not isinstance(motion["isKinematic"], bool):
        return "isKinematic is not a boolean"
    for key in ("mass", "gravityFactor"):
        if key in motion and not _number(motion[key]):
            return f"{key} {motion[key]!r:.40} is not a finite number"
    if "mass" in motion and motion["mass"] < 0:
        return f"mass {motion['mass']} is negative (0 means infinite)"
    for key, size in _VECTORS.items():
        value = motion.get(key)
        if value is None:
            continue
        if not (isinstance(value, list) and len(value) == size and all(map(_number, value))):
            return f"{key} is not an array of {size} finite numbers"
        if key == "inertiaDiagonal" and min(value) < 0:
            return "inertiaDiagonal has a negative component (0 means infinite)"
    return None


def _check_geometry(ctx: Context, geometry: Any, nodes: list, shapes: int,
                    pointer: str) -> None:
    if not isinstance(geometry, dict) or ("shape" in geometry) == ("node" in geometry):
        ctx.issues.add(Code.PHYSICS_GEOMETRY_INVALID, "the geometry must have exactly one of "
                       "shape and node", pointer=pointer)
        return
    if "shape" in geometry:
        if not _index(geometry["shape"], shapes):
            ctx.issues.add(Code.PHYSICS_GEOMETRY_INVALID, f"shape {geometry['shape']!r:.40} "
                           f"does not exist (there are {shapes} {SHAPES} shapes)",
                           pointer=f"{pointer}/shape")
        return
    h = geometry["node"]
    if not _index(h, len(nodes)):
        ctx.issues.add(Code.PHYSICS_GEOMETRY_INVALID, f"node {h!r:.40} does not exist (there "
                       f"are {len(nodes)} nodes)", pointer=f"{pointer}/node")
        return
    meshes = ctx.array("meshes")
    m = nodes[h].get("mesh") if isinstance(nodes[h], dict) else None
    prims = meshes[m].get("primitives") if _index(m, len(meshes)) and \
        isinstance(meshes[m], dict) else None
    if not isinstance(prims, list) or not any(
            isinstance(p, dict) and p.get("mode", 4) == 4 for p in prims):
        ctx.issues.add(Code.PHYSICS_GEOMETRY_INVALID, f"node {h} holds no mesh with a "
                       f"TRIANGLES primitive to collide with", pointer=f"{pointer}/node")


def _anchored(ctx: Context, m: Any) -> bool:
    meshes = ctx.array("meshes")
    if not _index(m, len(meshes)) or not isinstance(meshes[m], dict):
        return False
    for prim in meshes[m].get("primitives") or []:
        khr = (prim.get("extensions") or {}).get(KHR) if isinstance(prim, dict) else None
        nested = khr.get("extensions") if isinstance(khr, dict) else None
        if isinstance(nested, dict) and EXTENSION in nested:
            return True
    return False


def _check_kind(ctx: Context, node: dict, body: Any, pointer: str) -> None:
    extras = node.get("extras")
    gsverse = extras.get("gsverse") if isinstance(extras, dict) else None
    if not isinstance(gsverse, dict) or "physics" not in gsverse:
        return
    kind, where = gsverse["physics"], f"{pointer}/extras/gsverse/physics"
    if kind not in PHYSICS_KINDS:
        ctx.issues.add(Code.PHYSICS_KIND_UNKNOWN, f"physics kind {kind!r:.40} is not one of "
                       f"{', '.join(PHYSICS_KINDS)}", pointer=where)
        return
    if kind == "soft" and not _anchored(ctx, node.get("mesh")):
        ctx.issues.add(Code.PHYSICS_SOFT_NOT_ANCHORED, "a soft body needs an anchored splat "
                       "primitive on its node (its anchor mesh is what is simulated)",
                       pointer=where)
    motion = body.get("motion") if isinstance(body, dict) else None
    kinematic = isinstance(motion, dict) and motion.get("isKinematic") is True
    problem = (f"there is no {PHYSICS} object" if not isinstance(body, dict) else
               "a static body has a motion" if kind == "static" and motion is not None else
               f"a {kind} body has no motion" if kind != "static" and motion is None else
               "a kinematic body's motion is not isKinematic" if kind == "kinematic"
               and not kinematic else
               f"a {kind} body's motion is isKinematic" if kind in ("rigid", "soft")
               and kinematic else None)
    if problem is not None:
        ctx.issues.add(Code.PHYSICS_KIND_MISMATCH, f"extras.gsverse.physics is {kind}, but "
                       f"{problem}", pointer=where)


def check_physics(ctx: Context, used: list) -> None:
    """Report what is wrong with the physics objects of the document in ``ctx``; ``used``:
    its ``extensionsUsed``."""
    nodes = ctx.array("nodes")
    top = ctx.doc.get("extensions")
    implicit = top.get(SHAPES) if isinstance(top, dict) else None
    shapes = implicit.get("shapes") if isinstance(implicit, dict) else None
    shapes = shapes if isinstance(shapes, list) else []
    for s, shape in enumerate(shapes):
        problem = _shape_problem(shape)
        if problem is not None:
            ctx.issues.add(Code.PHYSICS_SHAPE_INVALID, f"shape {s} {problem}",
                           pointer=f"/extensions/{SHAPES}/shapes/{s}")
    bodies: list[str] = []
    for n, node in enumerate(nodes):
        if not isinstance(node, dict):
            continue
        pointer = f"/nodes/{n}"
        extensions = node.get("extensions")
        body = extensions.get(PHYSICS) if isinstance(extensions, dict) else None
        if body is not None:
            bpointer = f"{pointer}/extensions/{PHYSICS}"
            bodies.append(bpointer)
            if isinstance(body, dict):
                for part in ("collider", "trigger"):
                    if isinstance(body.get(part), dict) and "geometry" in body[part]:
                        _check_geometry(ctx, body[part]["geometry"], nodes, len(shapes),
                                        f"{bpointer}/{part}/geometry")
                    elif part == "collider" and "collider" in body:
                        ctx.issues.add(Code.PHYSICS_GEOMETRY_INVALID, "the collider has no "
                                       "geometry", pointer=f"{bpointer}/collider")
                if "motion" in body:
                    problem = _motion_problem(body["motion"])
                    if problem is not None:
                        ctx.issues.add(Code.PHYSICS_MOTION_INVALID, f"the motion {problem}",
                                       pointer=f"{bpointer}/motion")
        _check_kind(ctx, node, body, pointer)
    for name, uses in ((PHYSICS, bodies), (SHAPES, [f"/extensions/{SHAPES}"] if implicit
                                           is not None else [])):
        if uses and name not in used:
            ctx.issues.add(Code.EXTENSION_NOT_DECLARED, f"{name} is used ({len(uses)} "
                           f"time(s)) but not listed in extensionsUsed", pointer=uses[0])
