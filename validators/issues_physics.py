"""Catalogue rows of the physics checks (:mod:`.physics`: ``KHR_physics_rigid_bodies`` and
``KHR_implicit_shapes`` as spec/README.md §Physics uses them), in the format of
:mod:`.issues_rows`."""
from __future__ import annotations

from gsverse_format.codes import Code
from gsverse_format.physics import PHYSICS, PHYSICS_KINDS, SHAPES

from .issues_rows import Row

__all__ = ["PHYSICS_ENTRIES"]

_KINDS = ", ".join(PHYSICS_KINDS)

PHYSICS_ENTRIES: list[Row] = [
    (Code.PHYSICS_GEOMETRY_INVALID, "ERROR", "Physics", f"A {PHYSICS} collider (or trigger) "
     "geometry that names no usable geometry: not exactly one of `shape` and `node`, a `node` "
     "index that does not exist or whose node holds no mesh with a TRIANGLES primitive, a "
     f"`shape` index outside the top-level {SHAPES} `shapes`.",
     "/nodes/{n}/extensions/" + PHYSICS + "/collider/geometry",
     "Point the geometry at a node holding the collider mesh (it may stay outside every "
     "scene) or at an existing implicit shape."),
    (Code.PHYSICS_SHAPE_INVALID, "ERROR", "Physics", f"A {SHAPES} shape that engines cannot "
     "build: an unknown `type`, no parameter object for its type, or a degenerate or "
     "non-finite size (box sizes, radii and heights must be numbers above 0; the extension "
     "prohibits degenerate shapes).",
     "/extensions/" + SHAPES + "/shapes/{s}",
     "Give the shape a known type and positive, finite dimensions."),
    (Code.PHYSICS_MOTION_INVALID, "ERROR", "Physics", f"A {PHYSICS} `motion` with values "
     "engines cannot use: not an object, `isKinematic` not a boolean, a number that is not "
     "finite, a negative `mass` or `inertiaDiagonal` component (0 means infinite), a vector "
     "of the wrong length.",
     "/nodes/{n}/extensions/" + PHYSICS + "/motion",
     "Write finite values of the documented types, or leave the property out (the engine then "
     "computes mass and inertia from the collider)."),
    (Code.PHYSICS_KIND_UNKNOWN, "ERROR", "Physics", "A node's `extras.gsverse.physics` is not "
     f"one of {_KINDS}.", "/nodes/{n}/extras/gsverse/physics",
     f"Write one of {_KINDS} (or remove it)."),
    (Code.PHYSICS_KIND_MISMATCH, "WARNING", "Physics", "A node's `extras.gsverse.physics` "
     f"disagrees with its {PHYSICS} object: the kind is given without the object, `static` "
     "with a `motion`, `rigid` or `soft` without a `motion` or with `isKinematic`, "
     "`kinematic` without `isKinematic`. Readers that know only rigid bodies simulate what "
     "the extension object says.",
     "/nodes/{n}/extras/gsverse/physics",
     "Write the rigid-body object the kind stands for (spec/README.md §Physics), or the kind "
     "the object says."),
    (Code.PHYSICS_SOFT_NOT_ANCHORED, "ERROR", "Physics", "A node marked "
     "`extras.gsverse.physics = \"soft\"` whose mesh holds no anchored splat primitive: a "
     "soft body simulates the anchor mesh of the node's splats, and there is none.",
     "/nodes/{n}/extras/gsverse/physics",
     "Put the soft kind on the node of an anchored splat primitive, or make the object rigid."),
]
