"""Physics in glTF's own terms, written once: ``KHR_physics_rigid_bodies`` and
``KHR_implicit_shapes`` (Khronos drafts, pull request #2424 of KhronosGroup/glTF, revision of
2025-07-11) as ``gsverse-convert --physics`` and ``--ground`` write them (spec/README.md
§Physics).

* :data:`PHYSICS_KINDS`: how an object moves. ``rigid``, ``kinematic`` and ``static`` are the
  rigid-body extension's own (a motion, a motion with ``isKinematic``, no motion); ``soft`` is
  written as ``rigid`` (the safe fallback for readers that know only rigid bodies) and marked
  ``extras.gsverse.physics = "soft"`` for engines that simulate the anchor mesh itself.
* :func:`parse_physics` / :func:`parse_mass`: the grammar of ``--physics`` and ``--mass`` (and
  of the manifest keys of the same names).
* :func:`body_object`, :func:`ground_object`, :func:`box_shape`: the JSON objects written;
  :func:`kind_of`: the kind a reader finds back.
* :func:`ground_box`: where the ground goes under a scene.

This module knows JSON and numbers only; the writer and reader of ``io/gltf/physics.py``, the
validator (``validators/physics.py``) and the pipeline take the rules from here.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from .errors import UsageError

__all__ = ["PHYSICS", "SHAPES", "PHYSICS_KINDS", "MOVING_KINDS", "GROUND_NAME",
           "GROUND_THICKNESS", "GROUND_EXTENT", "parse_physics", "parse_mass", "body_object",
           "ground_object", "box_shape", "kind_of", "ground_box"]

#: The rigid-body extension (node-level ``motion`` and ``collider``).
PHYSICS = "KHR_physics_rigid_bodies"
#: The implicit-shape extension (top-level ``shapes``), used by the ground's box.
SHAPES = "KHR_implicit_shapes"
#: Physics kinds of an object (``--physics KIND``).
PHYSICS_KINDS: tuple[str, ...] = ("rigid", "soft", "kinematic", "static")
#: The kinds written with a ``motion`` (the others: a collider only), which take a mass.
MOVING_KINDS: tuple[str, ...] = ("rigid", "soft", "kinematic")
#: The name of the ground node.
GROUND_NAME = "ground"
#: The ground box's thickness as a fraction of the scene's diagonal (the box of all splat
#: means): thin enough not to matter visually, thick enough that a fast body does not tunnel
#: through it in one step of a usual engine (a thin box is safer than an infinite plane).
GROUND_THICKNESS = 0.01
#: The ground's x and z extent as a multiple of the scene's (centred under the scene).
GROUND_EXTENT = 3.0


def _objects_text(names: Sequence[str]) -> str:
    return ", ".join(names) if names else "(none)"


def _pairs(value: str, flag: str) -> list[tuple[str, str]]:
    pairs = []
    for part in value.split(","):
        name, eq, item = part.partition("=")
        name, item = name.strip(), item.strip()
        if not eq or not name or not item:
            raise UsageError(f"{flag} {value!r}: expected NAME=VALUE[,NAME=VALUE...]")
        pairs.append((name, item))
    return pairs


def _check_kind(kind: str, flag: str) -> str:
    if kind not in PHYSICS_KINDS:
        raise UsageError(f"{flag}: unknown kind {kind!r}; choose from {', '.join(PHYSICS_KINDS)}")
    return kind


def _by_name(pairs: list[tuple[str, str]], names: Sequence[str],
             flag: str) -> dict[str, str]:
    out: dict[str, str] = {}
    for name, item in pairs:
        if name not in names:
            raise UsageError(f"{flag} {name}={item}: no object is named {name!r} (the objects "
                             f"are the --mesh file stems: {_objects_text(names)})")
        if names.count(name) > 1:
            raise UsageError(f"{flag} {name}={item}: several --mesh files are named {name!r}; "
                             f"give the kinds in --mesh order instead")
        if name in out:
            raise UsageError(f"{flag}: object {name!r} is given twice")
        out[name] = item
    return out


def parse_physics(values: Sequence[str] | None, names: Sequence[str]) -> dict[str, str]:
    """Object name -> physics kind from the ``--physics`` values (the flag given once per
    value), for the objects ``names`` (the ``--mesh`` file stems, in order).

    Grammar: every value a KIND (one of :data:`PHYSICS_KINDS`): given once, it applies to every
    object; given once per object, in object order. Or every value ``NAME=KIND[,NAME=KIND...]``:
    by object name; objects not named get no physics. Mixing the two forms, a count that is
    neither 1 nor the number of objects, an unknown kind or name: :class:`UsageError`."""
    values = [str(v).strip() for v in values or ()]
    if not values:
        return {}
    named = ["=" in v for v in values]
    if any(named) and not all(named):
        raise UsageError("--physics: give either kinds (--physics rigid, or one per --mesh in "
                         "order) or NAME=KIND pairs (--physics fox=soft,chair=rigid), not both")
    if all(named):
        pairs = [p for v in values for p in _pairs(v, "--physics")]
        return {name: _check_kind(kind, "--physics")
                for name, kind in _by_name(pairs, list(names), "--physics").items()}
    kinds = [_check_kind(v, "--physics") for v in values]
    if len(kinds) == 1:
        return {name: kinds[0] for name in names}
    if len(kinds) != len(names):
        raise UsageError(f"--physics is given {len(kinds)} times for {len(names)} objects "
                         f"({_objects_text(names)}): give it once (every object), once per "
                         f"--mesh in the same order, or as NAME=KIND pairs")
    if len(set(names)) != len(names):
        # the same stem twice: the kinds are per position, which a name cannot say
        raise UsageError("--physics per --mesh needs distinct mesh file stems (object names)")
    return dict(zip(names, kinds))


def parse_mass(values: Sequence[str] | None, kinds: dict[str, str],
               names: Sequence[str]) -> dict[str, float]:
    """Object name -> mass in kilograms from the ``--mass NAME=KG[,NAME=KG...]`` values: a
    finite number above 0, for an object whose physics kind moves (:data:`MOVING_KINDS`)."""
    out: dict[str, float] = {}
    for value in values or ():
        for name, text in _by_name(_pairs(str(value).strip(), "--mass"), list(names),
                                   "--mass").items():
            if name in out:
                raise UsageError(f"--mass: object {name!r} is given twice")
            try:
                kg = float(text)
            except ValueError:
                raise UsageError(f"--mass {name}={text}: not a number") from None
            if not (math.isfinite(kg) and kg > 0):
                raise UsageError(f"--mass {name}={text}: must be a finite number above 0 "
                                 f"(kilograms; leave it out to let the engine compute the mass "
                                 f"from the collider's volume)")
            kind = kinds.get(name)
            if kind not in MOVING_KINDS:
                raise UsageError(f"--mass {name}={text}: {name} has "
                                 f"{'no --physics' if kind is None else 'static physics'}; a "
                                 f"mass applies to {', '.join(MOVING_KINDS)} objects")
            out[name] = kg
    return out


def body_object(kind: str, collider_node: int, mass: float | None = None) -> dict[str, Any]:
    """The ``KHR_physics_rigid_bodies`` object of an object's splat node: a convex-hull
    collider of ``collider_node`` (a node drawn by no scene, holding the collider mesh) and,
    unless ``static``, a motion (``isKinematic`` for ``kinematic``; ``soft`` as ``rigid``)."""
    body: dict[str, Any] = {}
    if kind != "static":
        motion: dict[str, Any] = {"isKinematic": True} if kind == "kinematic" else {}
        if mass is not None:
            motion["mass"] = float(mass)
        body["motion"] = motion
    body["collider"] = {"geometry": {"node": int(collider_node), "convexHull": True}}
    return body


def ground_object(shape: int) -> dict[str, Any]:
    """The ``KHR_physics_rigid_bodies`` object of the ground node: a static collider of the
    implicit shape ``shape``."""
    return {"collider": {"geometry": {"shape": int(shape)}}}


def box_shape(size: Sequence[float]) -> dict[str, Any]:
    """A ``KHR_implicit_shapes`` box of ``size`` (x, y, z; all above 0)."""
    return {"type": "box", "box": {"size": [float(s) for s in size]}}


def kind_of(body: Any, extras_kind: Any) -> str | None:
    """The physics kind of a node with the rigid-body object ``body`` and
    ``extras.gsverse.physics`` ``extras_kind``: the recorded kind when it is one of
    :data:`PHYSICS_KINDS`, else what the rigid-body object says (``kinematic`` for
    ``motion.isKinematic``, ``rigid`` for another motion, ``static`` for a collider alone);
    None for a node that is not a body."""
    if extras_kind in PHYSICS_KINDS:
        return str(extras_kind)
    if not isinstance(body, dict):
        return None
    motion = body.get("motion")
    if isinstance(motion, dict):
        return "kinematic" if motion.get("isKinematic") is True else "rigid"
    return "static" if isinstance(body.get("collider"), dict) else None


def ground_box(means: np.ndarray) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """(size, translation) of the ground box under splats at ``means`` ((N, 3), glTF frame,
    +Y up), in float64: its top face at the lowest mean, thickness :data:`GROUND_THICKNESS` of
    the diagonal of the means' box, x/z extent :data:`GROUND_EXTENT` times the box's (each at
    least the thickness, so that a flat scene still gets a box), centred under the scene.
    :class:`UsageError` when the means span nothing (a box of size 0 is not allowed)."""
    pts = np.asarray(means, dtype=np.float64).reshape(-1, 3)
    if len(pts) == 0:
        raise UsageError("--ground: the scene has no splats to put a ground under")
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    diagonal = float(np.linalg.norm(hi - lo))
    if not (diagonal > 0 and math.isfinite(diagonal)):
        raise UsageError("--ground: the splats span no space (all at one point); a ground box "
                         "needs a size")
    t = GROUND_THICKNESS * diagonal
    size = (GROUND_EXTENT * max(float(hi[0] - lo[0]), t), t,
            GROUND_EXTENT * max(float(hi[2] - lo[2]), t))
    centre = (float(lo[0] + hi[0]) / 2, float(lo[1]) - t / 2, float(lo[2] + hi[2]) / 2)
    return size, centre
