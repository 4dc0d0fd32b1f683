"""In-memory data model: free splats, triangle meshes, anchors, assets.

Conventions (the same as ``KHR_gaussian_splatting``; see ``spec/README.md``):

* ``means``      (N, 3) float32, in the asset's local coordinate system (glTF: metres, +Y up).
* ``rotations``  (N, 4) float32 unit quaternions, **(x, y, z, w)**.
* ``scales``     (N, 3) float32 **linear** standard deviations along the rotated axes (never log).
* ``opacities``  (N,)   float32 **linear** in [0, 1] (post-sigmoid).
* ``sh``         (N, K, 3) float32 real spherical-harmonic coefficients, **coefficient-major**,
  K = (degree + 1)², degree 0..3, coefficient ``k = l² + (m + l)``; ``sh[:, 0]`` is the raw
  3DGS ``f_dc`` (colour = 0.5 + 0.28209479177387814 · sh[:, 0]).

Covariance of splat i is ``R_i diag(scales_i)² R_iᵀ``.
"""
from __future__ import annotations

import json
import sys
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Literal, Union

import numpy as np

from .errors import FormatError, UsageError
from .rig import AnchorRig
from .rows import permute_rows_in_place, take_rows

__all__ = [
    "check_primitive",
    "face_order",
    "prim_label",
    "splat_problem",
    "nested_extension_problem",
    "KhrProperties",
    "SplatCloud",
    "TriangleMesh",
    "Collider",
    "Physics",
    "Ground",
    "LocalAnchors",
    "GamesAnchors",
    "Anchors",
    "Anchoring",
    "SplatPrimitive",
    "SplatAsset",
    "sh_coefficient_count",
    "sh_degree_for_count",
    "COLOR_SPACES",
]

#: The colour spaces ``KHR_gaussian_splatting`` defines (open enumeration).
COLOR_SPACES = ("srgb_rec709_display", "lin_rec709_display")

DeformationLaw = Literal["affine", "rigid"]


def sh_coefficient_count(degree: int) -> int:
    """Number of SH coefficients per colour channel for ``degree`` (0..3): (degree+1)²."""
    if degree not in (0, 1, 2, 3):
        raise ValueError(f"SH degree must be 0..3, got {degree}")
    return (degree + 1) ** 2


def sh_degree_for_count(count: int) -> int:
    """Inverse of :func:`sh_coefficient_count`; raises ``ValueError`` for other counts."""
    for degree in range(4):
        if (degree + 1) ** 2 == count:
            return degree
    raise ValueError(f"{count} SH coefficients per channel is not (d+1)^2 for d in 0..3")


def face_order(face_index: np.ndarray) -> np.ndarray:
    """The order that groups splats by face, faces ascending, splats of a face in their order
    (spec §Ordering): ``np.argsort(face_index, kind="stable")``, the same indices, computed
    for 65,536 or more non-negative integer keys below 2³² as a radix sort on two 16-bit digits
    (numpy's stable sort is a radix sort for 16-bit keys and a timsort for wider ones: 4M
    splats on 100k faces, 0.33 against 0.15 s)."""
    f = np.asarray(face_index)
    if f.ndim != 1 or f.size < 65_536 or f.dtype.kind not in "iu" or int(f.min()) < 0 \
            or int(f.max()) >= 2**32:
        return np.argsort(f, kind="stable")
    if int(f.max()) < 65_536:
        return np.argsort(f.astype(np.uint16), kind="stable")
    f = f.astype(np.uint32, copy=False)
    low = np.argsort((f & 0xFFFF).astype(np.uint16), kind="stable")
    return low[np.argsort((f >> 16).astype(np.uint16)[low], kind="stable")]


def _as(array, dtype, shape_tail: tuple, name: str, n: int | None = None) -> np.ndarray:
    a = np.ascontiguousarray(np.asarray(array), dtype=dtype)
    if a.ndim != 1 + len(shape_tail) or tuple(a.shape[1:]) != shape_tail:
        raise ValueError(f"{name} must have shape (N, {', '.join(map(str, shape_tail))}), got {a.shape}"
                         if shape_tail else f"{name} must have shape (N,), got {a.shape}")
    if n is not None and a.shape[0] != n:
        raise ValueError(f"{name} has {a.shape[0]} rows, expected {n}")
    return a


@dataclass
class SplatCloud:
    """Free (unanchored) Gaussian splats in the ``KHR_gaussian_splatting`` convention.

    ``extra`` keeps per-splat properties a source file carried that have no place in the
    model (for example ``filter_3D`` or ``binding_0``), as float arrays of length N, so
    writers that can store them do.
    """

    means: np.ndarray
    rotations: np.ndarray
    scales: np.ndarray
    opacities: np.ndarray
    sh: np.ndarray
    color_space: str = "srgb_rec709_display"
    extra: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.means = _as(self.means, np.float32, (3,), "means")
        n = self.means.shape[0]
        self.rotations = _as(self.rotations, np.float32, (4,), "rotations", n)
        self.scales = _as(self.scales, np.float32, (3,), "scales", n)
        self.opacities = _as(self.opacities, np.float32, (), "opacities", n)
        sh = np.ascontiguousarray(np.asarray(self.sh), dtype=np.float32)
        if sh.ndim != 3 or sh.shape[0] != n or sh.shape[2] != 3:
            raise ValueError(f"sh must have shape (N, K, 3) with N={n}, got {sh.shape}")
        sh_degree_for_count(sh.shape[1])  # raises for invalid K
        self.sh = sh
        self.extra = {k: _as(v, np.float32, (), f"extra[{k!r}]", n) for k, v in self.extra.items()}

    def __len__(self) -> int:
        return int(self.means.shape[0])

    @property
    def sh_degree(self) -> int:
        return sh_degree_for_count(self.sh.shape[1])

    def covariances(self) -> np.ndarray:
        """(N, 3, 3) float64 covariance matrices R diag(s)² Rᵀ."""
        from .quaternion import to_matrix

        r = to_matrix(self.rotations)
        rs = r * self.scales.astype(np.float64)[:, None, :]
        return rs @ np.swapaxes(rs, -1, -2)

    def subset(self, index) -> "SplatCloud":
        """Splats selected by an index array or boolean mask (copies)."""
        return SplatCloud(take_rows(self.means, index), take_rows(self.rotations, index),
                          take_rows(self.scales, index), take_rows(self.opacities, index),
                          take_rows(self.sh, index), self.color_space,
                          {k: take_rows(v, index) for k, v in self.extra.items()})

    def permute(self, order: np.ndarray) -> None:
        """Reorder the splats in place: row ``i`` becomes row ``order[i]`` (``order`` a
        permutation of ``0..N-1``; ``ValueError`` otherwise), as ``subset(order)`` would, without
        a second copy of the cloud alive. Each small array is replaced by its reordered copy in
        turn (arrays this cloud shares with others stay as they are); the SH coefficients, most
        of the memory, are reordered in their own array a block of columns at a time when this
        cloud owns that array, it is writeable and nothing else refers to it (else replaced
        like the others)."""
        order = np.asarray(order)
        n = len(self)
        if (order.shape != (n,) or order.dtype.kind not in "iu"
                or (n and (order.min() < 0 or order.max() >= n
                           or not np.all(np.bincount(order, minlength=n) == 1)))):
            raise ValueError(f"order must be a permutation of the {n} splats")
        if n == 0:
            return
        self.means = take_rows(self.means, order)
        self.rotations = take_rows(self.rotations, order)
        self.scales = take_rows(self.scales, order)
        self.opacities = take_rows(self.opacities, order)
        self.extra = {k: take_rows(v, order) for k, v in self.extra.items()}
        if self.owns_sh():
            permute_rows_in_place(self.sh, order)
        else:
            self.sh = take_rows(self.sh, order)

    def owns_sh(self) -> bool:
        """Whether the SH array may be changed in place: an array no one else sees, owned,
        writeable, C-contiguous and referenced by this cloud alone (another cloud or a view
        of it would hold a second reference; ``getrefcount``'s own argument is the other one
        counted here)."""
        return (sys.getrefcount(self.sh) <= 2 and self.sh.flags.owndata
                and self.sh.flags.writeable and self.sh.flags.c_contiguous)

    def with_sh_degree(self, degree: int) -> "SplatCloud":
        """A copy truncated (or zero-padded) to SH ``degree``."""
        k = sh_coefficient_count(degree)
        sh = np.zeros((len(self), k, 3), np.float32)
        keep = min(k, self.sh.shape[1])
        sh[:, :keep] = self.sh[:, :keep]
        return SplatCloud(self.means, self.rotations, self.scales, self.opacities, sh,
                          self.color_space, dict(self.extra))

    @staticmethod
    def concatenate(clouds: "list[SplatCloud]") -> "SplatCloud":
        """Join clouds (SH padded to the highest degree; extras kept where all have them)."""
        if not clouds:
            raise ValueError("nothing to concatenate")
        degree = max(c.sh_degree for c in clouds)
        clouds = [c.with_sh_degree(degree) for c in clouds]
        common = set.intersection(*(set(c.extra) for c in clouds))
        return SplatCloud(
            np.concatenate([c.means for c in clouds]),
            np.concatenate([c.rotations for c in clouds]),
            np.concatenate([c.scales for c in clouds]),
            np.concatenate([c.opacities for c in clouds]),
            np.concatenate([c.sh for c in clouds]),
            clouds[0].color_space,
            {k: np.concatenate([c.extra[k] for c in clouds]) for k in sorted(common)},
        )


@dataclass
class TriangleMesh:
    """An indexed triangle mesh: ``vertices`` (V, 3) float32, ``faces`` (F, 3) uint32.

    Face ``f`` has corners ``vertices[faces[f, 0]]``, ``[f, 1]``, ``[f, 2]`` — the order
    fixes the triangle frame (``spec/README.md`` §Triangle frame). Vertices are stored as
    float32 because that is what files hold; computations promote them to float64.
    """

    vertices: np.ndarray
    faces: np.ndarray
    #: skin/morph targets/animations of an animated anchor mesh (:mod:`gsverse_format.rig`);
    #: a mesh made from this one with other vertices does not keep it
    rig: AnchorRig | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        self.vertices = _as(self.vertices, np.float32, (3,), "vertices")
        faces = np.asarray(self.faces)
        if faces.ndim != 2 or faces.shape[1] != 3:
            raise ValueError(f"faces must have shape (F, 3), got {faces.shape}")
        if faces.size and (faces.min() < 0 or faces.max() >= len(self.vertices)):
            raise FormatError(f"face indices must be in [0, {len(self.vertices)}), "
                              f"found range [{faces.min()}, {faces.max()}]")
        self.faces = np.ascontiguousarray(faces, dtype=np.uint32)

    @property
    def face_count(self) -> int:
        return int(self.faces.shape[0])

    def triangles(self, vertices: np.ndarray | None = None) -> np.ndarray:
        """(F, 3, 3) float64 corner positions, from ``vertices`` (default: the rest vertices)."""
        v = self.vertices if vertices is None else np.asarray(vertices)
        return np.asarray(v, dtype=np.float64)[self.faces.astype(np.intp)]


@dataclass
class LocalAnchors:
    """``local`` profile: each splat stored relative to its triangle's frame.

    * ``face_index``     (N,) uint32 — triangle of the anchor mesh.
    * ``barycentrics``   (N, 2) float32 — weights (b1, b2) of corners 1 and 2; b0 = 1 − b1 − b2.
      They locate the foot point of the splat in the triangle's plane (may lie outside the
      triangle when the nearest point is on an edge or corner).
    * ``normal_offset``  (N,) float32 — signed distance along the unit normal at rest.
    * ``local_rotation`` (N, 4) float32 — unit quaternion (x, y, z, w) relative to the rest frame.
    * ``local_scale``    (N, 3) float32 — linear scales at rest (equal to the rest-pose SCALE).
    * ``deformation``    ``"affine"`` or ``"rigid"`` (spec §Deformation laws).
    """

    face_index: np.ndarray
    barycentrics: np.ndarray
    normal_offset: np.ndarray
    local_rotation: np.ndarray
    local_scale: np.ndarray
    deformation: DeformationLaw = "affine"
    profile: Literal["local"] = field(default="local", init=False)

    def __post_init__(self) -> None:
        self.face_index = _as(self.face_index, np.uint32, (), "face_index")
        n = self.face_index.shape[0]
        self.barycentrics = _as(self.barycentrics, np.float32, (2,), "barycentrics", n)
        self.normal_offset = _as(self.normal_offset, np.float32, (), "normal_offset", n)
        self.local_rotation = _as(self.local_rotation, np.float32, (4,), "local_rotation", n)
        self.local_scale = _as(self.local_scale, np.float32, (3,), "local_scale", n)
        if self.deformation not in ("affine", "rigid"):
            raise ValueError(f"deformation must be 'affine' or 'rigid', got {self.deformation!r}")

    def __len__(self) -> int:
        return int(self.face_index.shape[0])

    @classmethod
    def deferred(cls, face_index: np.ndarray, local_scale: np.ndarray,
                 deformation: DeformationLaw,
                 derive: Callable[[], tuple[np.ndarray, np.ndarray, np.ndarray]]
                 ) -> "LocalAnchors":
        """Anchors whose ``barycentrics``, ``normal_offset`` and ``local_rotation`` are
        derived when first read: ``derive()`` returns them (the rule of
        :func:`gsverse_format.anchors_derive.derive_local`, from the rest pose they were bound
        in). The binder returns these for a compact glTF, which stores none of the three (its
        readers derive them); anything that reads one gets all three, as the eager binder
        would have computed them."""
        anchors = cls.__new__(cls)
        anchors.face_index = _as(face_index, np.uint32, (), "face_index")
        anchors.local_scale = _as(local_scale, np.float32, (3,), "local_scale",
                                  anchors.face_index.shape[0])
        if deformation not in ("affine", "rigid"):
            raise ValueError(f"deformation must be 'affine' or 'rigid', got {deformation!r}")
        anchors.deformation = deformation
        anchors.__dict__["_derive"] = derive
        return anchors

    if not TYPE_CHECKING:       # (a __getattr__ would make every attribute name type-check)
        def __getattr__(self, name: str) -> Any:
            # called only for attributes the instance lacks: those of deferred() not derived
            derive = self.__dict__.get("_derive")
            if derive is None or name not in _DERIVED_FIELDS:
                raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
            bary, offset, rotation = derive()
            n = self.face_index.shape[0]
            self.__dict__.update(
                barycentrics=_as(bary, np.float32, (2,), "barycentrics", n),
                normal_offset=_as(offset, np.float32, (), "normal_offset", n),
                local_rotation=_as(rotation, np.float32, (4,), "local_rotation", n))
            del self.__dict__["_derive"]
            return self.__dict__[name]

    @property
    def derived(self) -> bool:
        """False for anchors of :meth:`deferred` whose three derived arrays were not read."""
        return "_derive" not in self.__dict__

    def subset(self, index) -> "LocalAnchors":
        return LocalAnchors(take_rows(self.face_index, index),
                            take_rows(self.barycentrics, index),
                            take_rows(self.normal_offset, index),
                            take_rows(self.local_rotation, index),
                            take_rows(self.local_scale, index), self.deformation)


#: The arrays of :class:`LocalAnchors` that :meth:`LocalAnchors.deferred` derives when read.
_DERIVED_FIELDS = ("barycentrics", "normal_offset", "local_rotation")


@dataclass
class GamesAnchors:
    """``games`` profile (GaMeS / GS-Verse): frame and scales rebuilt from the triangle.

    * ``face_index``   (N,) uint32.
    * ``barycentrics`` (N, 2) float32 — normalized GaMeS weights (α1, α2); α0 = 1 − α1 − α2.
    * ``rho``          (N,) float32 — GaMeS scalar scale ρ (multiplies all three axes).
    """

    face_index: np.ndarray
    barycentrics: np.ndarray
    rho: np.ndarray
    profile: Literal["games"] = field(default="games", init=False)

    def __post_init__(self) -> None:
        self.face_index = _as(self.face_index, np.uint32, (), "face_index")
        n = self.face_index.shape[0]
        self.barycentrics = _as(self.barycentrics, np.float32, (2,), "barycentrics", n)
        self.rho = _as(self.rho, np.float32, (), "rho", n)

    def __len__(self) -> int:
        return int(self.face_index.shape[0])

    def subset(self, index) -> "GamesAnchors":
        return GamesAnchors(take_rows(self.face_index, index),
                            take_rows(self.barycentrics, index), take_rows(self.rho, index))


Anchors = Union[LocalAnchors, GamesAnchors]


@dataclass
class Anchoring:
    """Binds the splats of one primitive to an anchor ``mesh`` (its rest pose)."""

    mesh: TriangleMesh
    anchors: Anchors

    def __post_init__(self) -> None:
        fi = self.anchors.face_index
        if fi.size and int(fi.max()) >= self.mesh.face_count:
            raise FormatError(f"anchor face index {int(fi.max())} out of range for a mesh "
                              f"with {self.mesh.face_count} faces")


def _holds_integer(value: Any) -> bool:
    if isinstance(value, bool):
        return False
    if isinstance(value, int):
        return True
    if isinstance(value, dict):
        return any(_holds_integer(v) for v in value.values())
    if isinstance(value, list):
        return any(_holds_integer(v) for v in value)
    return False


def nested_extension_problem(name: str, obj: Any) -> str | None:
    """Why the nested extension object ``obj`` (named ``name``) cannot be copied into a
    rewritten file, or None when it can.

    glTF refers to accessors, buffer views and meshes by integer index, and a writer renumbers
    them all; an unknown extension's integers may be such indices (they are in every splat
    compression or per-splat data extension), so copying them would make it point at the wrong
    data. An object holding no integer at all (a marker like ``{}``, strings, floats) refers to
    nothing in the file and is carried as it is.
    """
    if not isinstance(obj, dict):
        return f"nested extension {name} is not a JSON object"
    try:
        json.dumps(obj, allow_nan=False)
    except (TypeError, ValueError):
        return f"nested extension {name} is not plain JSON (it holds NaN, infinity or objects)"
    if _holds_integer(obj):
        return (f"nested extension {name} holds integer values, which may index accessors, "
                f"buffer views or meshes that a rewritten file renumbers (and per-splat data "
                f"that reordered splats no longer match); it cannot be carried over")
    return None


@dataclass
class KhrProperties:
    """The ``KHR_gaussian_splatting`` properties of a primitive besides ``colorSpace`` (which
    is :attr:`SplatCloud.color_space`).

    ``kernel``, ``projection`` and ``sorting_method`` are open enumerations: other extensions
    define further values, and a value this library does not know is kept as it is.
    ``extensions`` holds the nested extension objects other than the anchor extension, by
    name, as JSON (:meth:`carry_problem` says whether a writer can copy them);
    ``attributes`` names the primitive's attributes that belong to them (``NAME:SEMANTIC``),
    whose data are not read: an extension with such attributes cannot be carried.
    """

    kernel: str = "ellipse"
    projection: str = "perspective"
    sorting_method: str = "cameraDistance"
    extensions: dict[str, Any] = field(default_factory=dict)
    attributes: tuple[str, ...] = ()

    def carry_problem(self) -> str | None:
        """Why these nested extensions cannot be copied into a rewritten file, or None."""
        if self.attributes:
            return (f"nested extension {self.attributes[0].split(':')[0]} has per-splat "
                    f"attribute(s) {', '.join(self.attributes)}, which are not carried over")
        return next((p for p in (nested_extension_problem(n, o)
                                 for n, o in self.extensions.items())
                     if p is not None), None)

    @property
    def is_default(self) -> bool:
        """Whether these are the base extension's values with no other extension."""
        return self == KhrProperties()

    def differences(self) -> list[str]:
        """What differs from the base extension's defaults, for messages."""
        out = [f"{key} {value!r}" for key, value, default in (
            ("kernel", self.kernel, "ellipse"), ("projection", self.projection, "perspective"),
            ("sortingMethod", self.sorting_method, "cameraDistance")) if value != default]
        return out + [f"nested extension {name}" for name in self.extensions]


@dataclass
class SplatPrimitive:
    """One splat primitive of an asset: splats (rest pose), optionally their anchoring, and
    the ``KHR_gaussian_splatting`` properties they are rendered with (:class:`KhrProperties`)."""

    splats: SplatCloud
    anchoring: Anchoring | None = None
    name: str | None = None
    khr: KhrProperties = field(default_factory=KhrProperties)
    #: How the object moves in a physics engine (glTF: ``KHR_physics_rigid_bodies`` on its node).
    physics: Physics | None = None

    def __post_init__(self) -> None:
        if self.anchoring is not None and len(self.anchoring.anchors) != len(self.splats):
            raise ValueError(f"{len(self.anchoring.anchors)} anchors for {len(self.splats)} splats")


@dataclass
class Collider:
    """A collision mesh for the anchor mesh ``anchor`` (the same object as an anchored
    primitive's ``anchoring.mesh``): ``kind`` says how it was made (``"hull"``: its convex
    hull). Writers store it beside the anchor mesh, marked as its collider (spec/README.md
    §Colliders); it is never drawn."""

    mesh: TriangleMesh
    anchor: TriangleMesh
    kind: str = "hull"


@dataclass
class Physics:
    """How an anchored object moves in a physics engine (spec/README.md §Physics): ``kind``
    one of :data:`gsverse_format.physics.PHYSICS_KINDS`, ``mass`` in kilograms (None: the
    engine computes it from the collider). Its collider is the :class:`Collider` of its anchor
    mesh."""

    kind: str
    mass: float | None = None


@dataclass
class Ground:
    """A static, invisible ground box (spec/README.md §Physics): ``size`` (x, y, z) and the
    ``translation`` of its centre, in the asset's frame."""

    size: tuple[float, float, float]
    translation: tuple[float, float, float]


@dataclass
class SplatAsset:
    """What one file holds: splat primitives, anchored or plain (static), the colliders
    of its anchor meshes and the ground under them (``ground``, or None). ``frame`` is the coordinate frame the values are in (a key of
    :data:`gsverse_format.io.registry.FRAMES`): ``"gltf"`` (+Y up), or the source's frame for
    an asset converted without the frame change (``gsverse-convert --no-frame-change``),
    recorded in the file (glTF ``asset.extras.gsverse.frame``, USD ``customLayerData``) so
    that posed outputs are written in that frame too."""

    primitives: list[SplatPrimitive] = field(default_factory=list)
    generator: str | None = None
    colliders: list[Collider] = field(default_factory=list)
    frame: str = "gltf"
    ground: Ground | None = None

    @property
    def anchored(self) -> list[SplatPrimitive]:
        return [p for p in self.primitives if p.anchoring is not None]

    @property
    def static(self) -> list[SplatPrimitive]:
        return [p for p in self.primitives if p.anchoring is None]

    def splat_count(self) -> int:
        return sum(len(p.splats) for p in self.primitives)


def _require_finite(name: str, *arrays: np.ndarray) -> None:
    for a in arrays:
        if not np.all(np.isfinite(a)):
            raise UsageError(f"{name} has non-finite values (NaN or infinity)")


def splat_problem(c: SplatCloud) -> str | None:
    """What makes the splats ``c`` invalid ``KHR_gaussian_splatting`` data (completing "has
    ..."), or None: no splats, non-finite values, negative scales, opacities outside [0, 1]."""
    if len(c) == 0:
        return "no splats"
    for name in ("means", "rotations", "scales", "opacities", "sh"):
        values = getattr(c, name)
        # NaN and infinity reach the minimum or the maximum: no temporary the size of values
        if not (np.isfinite(values.min()) and np.isfinite(values.max())):
            bad = int(np.count_nonzero(~np.isfinite(values).reshape(len(c), -1).all(axis=1)))
            return f"non-finite {name} (NaN or infinity) in {bad} of {len(c)} splats"
    negative = int(np.count_nonzero((c.scales < 0).any(axis=1)))
    if negative:
        return (f"negative scales in {negative} of {len(c)} splats (KHR_gaussian_splatting "
                f"scales are linear and non-negative; log-space scales, as some older "
                f"exporters wrote, need exp())")
    outside = int(np.count_nonzero((c.opacities < 0) | (c.opacities > 1)))
    if outside:
        return (f"opacities outside [0, 1] in {outside} of {len(c)} splats "
                f"(KHR_gaussian_splatting opacities are linear, after the sigmoid)")
    return None


def prim_label(i: int, prim: SplatPrimitive) -> str:
    """How messages name primitive ``i``: ``primitive 0 ('name')``."""
    return f"primitive {i}" + (f" ({prim.name!r})" if prim.name else "")


def check_primitive(i: int, prim: SplatPrimitive) -> None:
    """Raise :class:`~gsverse_format.errors.UsageError` when primitive ``i`` cannot be written:
    splats with a :func:`splat_problem`, anchors that do not match the splats or the anchor
    mesh."""
    label = prim_label(i, prim)
    c = prim.splats
    problem = splat_problem(c)
    if problem is not None:
        if len(c) == 0:
            problem += " (glTF accessors need at least one element)"
        raise UsageError(f"{label} has {problem}")
    if prim.anchoring is None:
        return
    mesh, anchors = prim.anchoring.mesh, prim.anchoring.anchors
    if len(anchors) != len(c):
        raise UsageError(f"{label} has {len(anchors)} anchors for {len(c)} splats")
    if mesh.face_count == 0:
        raise UsageError(f"{label} is anchored to a mesh with no triangles")
    _require_finite(f"{label} anchor mesh", mesh.vertices)
    if mesh.faces.size and int(mesh.faces.max()) >= len(mesh.vertices):
        raise UsageError(f"{label} anchor mesh has face indices out of range")
    if int(anchors.face_index.max()) >= mesh.face_count:
        raise UsageError(f"{label} has anchor face index {int(anchors.face_index.max())} out "
                         f"of range for a mesh with {mesh.face_count} faces")
    if isinstance(anchors, LocalAnchors):
        # deferred anchors not read yet are not derived for this check: the binder bound them
        # to faces regular at rest, where the rule gives finite values for finite splats
        derived = ((anchors.barycentrics, anchors.normal_offset, anchors.local_rotation)
                   if anchors.derived else ())
        _require_finite(f"{label} anchors", *derived, anchors.local_scale)
    elif isinstance(anchors, GamesAnchors):
        _require_finite(f"{label} anchors", anchors.barycentrics, anchors.rho)
    else:
        raise UsageError(f"{label} has anchors of unknown type {type(anchors).__name__}")
