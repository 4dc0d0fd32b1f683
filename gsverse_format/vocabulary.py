"""The extension's vocabulary, written once: names, fields, formats and constants.

Every layer that names a piece of ``GSVERSE_gaussian_splatting_mesh_anchor`` (the data model,
the glTF reader and writer, the USD mapping, the validator, the JSON Schema test) takes it from
here, so that one field has one name per layer and one set of rules:

* :data:`ANCHOR_FIELDS`: each per-splat anchor field with its data-model attribute, its glTF
  extension key, its USD attribute, its accessor type, the glTF component types it may use
  (spec §Accessor component types and dequantization) and the profiles that require it;
* :func:`required_fields` / :func:`allowed_fields`: what each profile requires and allows;
* :data:`KHR_ATTRIBUTE_FORMATS`: the accessor formats ``KHR_gaussian_splatting`` allows for the
  rest pose;
* the constants: extension names, glTF component types, the covariance entry order, SH_C0.

``conformance/minimal_reader.py`` and ``native/gsverse_remap.h`` keep their own copies on
purpose (they model an independent plugin); the tests compare them against this module.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

__all__ = ["EXTENSION", "KHR", "PROFILES", "DEFORMATIONS", "BYTE", "UNSIGNED_BYTE", "SHORT",
           "UNSIGNED_SHORT", "UNSIGNED_INT", "FLOAT", "COMPONENT_TYPE_NAMES", "COMPONENT_BITS",
           "AnchorField", "ANCHOR_FIELDS", "FIELDS_BY_KEY", "required_fields", "allowed_fields",
           "USD_PROFILE", "USD_DEFORMATION", "USD_MESH", "KHR_ATTRIBUTE_FORMATS", "COV6_ORDER",
           "COV6_INDEX", "SH_C0", "FACE_COUNTS", "DERIVED_KEYS", "ANCHOR_ENCODINGS",
           "gltf_required_keys", "RECORDED_FRAMES", "frame_record", "recorded_frame",
           "SPZ_EXTENSION"]

#: The anchor extension, nested in ``KHR_gaussian_splatting``.
EXTENSION = "GSVERSE_gaussian_splatting_mesh_anchor"
#: The base extension.
KHR = "KHR_gaussian_splatting"
#: The Khronos draft storing a splat primitive's attributes as one SPZ stream, nested in
#: ``KHR_gaussian_splatting`` (spec §SPZ-compressed rest pose).
SPZ_EXTENSION = "KHR_gaussian_splatting_compression_spz_2"
#: ratified glTF extension hiding a node (the anchor node of an animated anchor mesh)
NODE_VISIBILITY = "KHR_node_visibility"

Profile = Literal["local", "games"]
PROFILES: tuple[str, ...] = ("local", "games")
#: Deformation laws of the ``local`` profile (the first is the default).
DEFORMATIONS: tuple[str, ...] = ("affine", "rigid")

# glTF 2.0 component types
BYTE, UNSIGNED_BYTE, SHORT, UNSIGNED_SHORT, UNSIGNED_INT, FLOAT = 5120, 5121, 5122, 5123, 5125, 5126
COMPONENT_TYPE_NAMES: dict[int, str] = {
    BYTE: "BYTE", UNSIGNED_BYTE: "UNSIGNED_BYTE", SHORT: "SHORT",
    UNSIGNED_SHORT: "UNSIGNED_SHORT", UNSIGNED_INT: "UNSIGNED_INT", FLOAT: "FLOAT"}
#: Bits of each integer component type (normalized values divide by 2ⁿ − 1, or 2ⁿ⁻¹ − 1).
COMPONENT_BITS: dict[int, int] = {BYTE: 8, UNSIGNED_BYTE: 8, SHORT: 16, UNSIGNED_SHORT: 16,
                                  UNSIGNED_INT: 32}

#: A (componentType, normalized) pair; normalized None means "either".
Format = tuple[int, "bool | None"]


@dataclass(frozen=True)
class AnchorField:
    """One per-splat anchor field of the extension.

    ``attribute`` is the data model's name (:mod:`gsverse_format.model`), ``key`` the glTF
    extension property, ``usd`` the USD attribute; ``accessor`` the glTF accessor type and
    ``formats`` the allowed (componentType, normalized) pairs; ``profiles`` the profiles that
    require the field (``local`` also allows ``localScale`` to be absent in USD, where the rest
    scales stand for it).
    """

    attribute: str
    key: str
    usd: str
    accessor: str
    formats: tuple[Format, ...]
    profiles: tuple[str, ...]

    def allows(self, accessor: str, component_type: int, normalized: bool) -> bool:
        """True when the spec allows this accessor type and component type for the field."""
        return accessor == self.accessor and any(
            c == component_type and (n is None or n == bool(normalized)) for c, n in self.formats)


ANCHOR_FIELDS: tuple[AnchorField, ...] = (
    AnchorField("face_index", "faceIndex", "gsverse:anchor:faceIndices", "SCALAR",
                ((UNSIGNED_BYTE, False), (UNSIGNED_SHORT, False), (UNSIGNED_INT, False)),
                ("local", "games")),
    AnchorField("barycentrics", "barycentrics", "gsverse:anchor:barycentrics", "VEC2",
                ((FLOAT, False), (UNSIGNED_BYTE, True), (UNSIGNED_SHORT, True)),
                ("local", "games")),
    AnchorField("normal_offset", "normalOffset", "gsverse:anchor:normalOffsets", "SCALAR",
                ((FLOAT, False),), ("local",)),
    AnchorField("local_rotation", "localRotation", "gsverse:anchor:localOrientations", "VEC4",
                ((FLOAT, False), (BYTE, True), (SHORT, True)), ("local",)),
    AnchorField("local_scale", "localScale", "gsverse:anchor:localScales", "VEC3",
                ((FLOAT, False), (UNSIGNED_BYTE, None), (UNSIGNED_SHORT, None)), ("local",)),
    AnchorField("rho", "rho", "gsverse:anchor:rho", "SCALAR", ((FLOAT, False),), ("games",)),
)
#: glTF extension key -> field.
FIELDS_BY_KEY: dict[str, AnchorField] = {f.key: f for f in ANCHOR_FIELDS}

#: Version 1.2: per-face splat counts, the alternative to ``faceIndex`` (exactly one of the two;
#: ``count`` = the anchor triangle count, not the splat count). Not a per-splat field, so not
#: in :data:`ANCHOR_FIELDS` (USD keeps explicit arrays).
FACE_COUNTS = AnchorField("face_counts", "faceCounts", "", "SCALAR",
                          ((UNSIGNED_BYTE, False), (UNSIGNED_SHORT, False), (UNSIGNED_INT, False)),
                          ())
#: Version 1.2: the ``local`` properties a compact asset omits together; readers then derive
#: them from the rest pose (spec §Derived `local` anchors).
DERIVED_KEYS: tuple[str, ...] = ("barycentrics", "normalOffset", "localRotation", "localScale")
#: How a writer stores the anchors: ``explicit`` (version 1.1 layout) or ``compact``
#: (``faceCounts`` and, for ``local``, derived anchors).
ANCHOR_ENCODINGS: tuple[str, ...] = ("explicit", "compact")

#: USD attributes of the anchor API that are not per-splat arrays.
USD_PROFILE = "gsverse:anchor:profile"
USD_DEFORMATION = "gsverse:anchor:deformation"
USD_MESH = "gsverse:anchor:mesh"


def required_fields(profile: str) -> tuple[AnchorField, ...]:
    """The anchor fields ``profile`` requires (glTF: every one; USD: ``localScale`` may be
    omitted when the rest scales stand for it)."""
    return tuple(f for f in ANCHOR_FIELDS if profile in f.profiles)


def gltf_required_keys(profile: str, *, counts: bool, derived: bool) -> tuple[str, ...]:
    """The glTF properties an anchor object of ``profile`` must have: ``faceCounts``
    (``counts``) or ``faceIndex``, and the per-splat fields, without :data:`DERIVED_KEYS` when
    the ``local`` anchors are ``derived``."""
    face = FACE_COUNTS.key if counts else "faceIndex"
    rest = tuple(f.key for f in required_fields(profile) if f.key != "faceIndex"
                 and not (derived and profile == "local" and f.key in DERIVED_KEYS))
    return (face,) + rest


def allowed_fields(profile: str) -> tuple[AnchorField, ...]:
    """The anchor fields ``profile`` allows (the others MUST NOT be present in USD)."""
    return required_fields(profile)


#: ``KHR_gaussian_splatting`` rest-pose attributes: name -> (accessor type, allowed formats).
#: POSITION also allows the KHR_mesh_quantization types, which readers check separately.
KHR_ATTRIBUTE_FORMATS: dict[str, tuple[str, tuple[Format, ...]]] = {
    "POSITION": ("VEC3", ((FLOAT, False),)),
    f"{KHR}:ROTATION": ("VEC4", ((FLOAT, False), (BYTE, True), (SHORT, True))),
    f"{KHR}:SCALE": ("VEC3", ((FLOAT, False), (UNSIGNED_BYTE, None), (UNSIGNED_SHORT, None))),
    f"{KHR}:OPACITY": ("SCALAR", ((FLOAT, False), (UNSIGNED_BYTE, True), (UNSIGNED_SHORT, True))),
    "SH": ("VEC3", ((FLOAT, False),)),
}

#: Order of the six unique covariance entries wherever a covariance is stored flat.
COV6_ORDER: tuple[str, ...] = ("xx", "xy", "xz", "yy", "yz", "zz")
#: (row, column) of each entry of :data:`COV6_ORDER`.
COV6_INDEX: tuple[tuple[int, int], ...] = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))

#: Degree-0 spherical-harmonic constant: colour = 0.5 + SH_C0 · DC.
SH_C0 = 0.28209479177387814


#: The coordinate frames other than glTF's that a file records its values to be in (names of
#: :data:`gsverse_format.io.registry.FRAMES`): an asset converted without the frame change
#: (``gsverse-convert --no-frame-change``) from a source in one of them holds its values in it.
#: Recorded as ``{"frame": name}`` under the key ``gsverse`` of glTF ``asset.extras`` and of
#: the USD root layer's ``customLayerData``; no record means the glTF frame (+Y up).
RECORDED_FRAMES = ("3dgs", "z-up", "spz-rub")


def frame_record(frame: str) -> dict[str, str] | None:
    """The ``gsverse`` record of an asset whose values are in ``frame``; None for glTF's."""
    return {"frame": frame} if frame in RECORDED_FRAMES else None


def recorded_frame(record: object) -> str:
    """The frame a file's ``gsverse`` record names (:data:`RECORDED_FRAMES`), else ``"gltf"``
    (no record, or one this package does not know: extras are informative)."""
    frame = record.get("frame") if isinstance(record, dict) else None
    return frame if isinstance(frame, str) and frame in RECORDED_FRAMES else "gltf"
