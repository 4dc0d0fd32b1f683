"""The USD names of the mapping (spec/usd.md), the ``pxr`` import and the schema plugin.

The anchor attributes' names come from :mod:`gsverse_format.vocabulary`; this module adds only
what is USD's own: the Sdf/Vt value types of each anchor field, the rest-pose attributes of
``ParticleField3DGaussianSplat``, the API schema names. ``pxr`` (usd-core, an optional
dependency) is imported on first use by :func:`pxr`, which also registers the codeless schema
plugin in ``gsverse_format/usd_schema`` (:func:`register_schema`).
"""
from __future__ import annotations

import pathlib
import re
import types
import warnings
from dataclasses import dataclass
from importlib import resources

from ...errors import UsageError
from ...vocabulary import (ANCHOR_FIELDS, DEFORMATIONS, USD_DEFORMATION, USD_MESH,
                           USD_PROFILE, AnchorField, allowed_fields)

__all__ = ["USD_SUFFIXES", "MISSING_USD_CORE", "SCHEMA_DIR", "ANCHOR_API", "COLOR_SPACE_API",
           "ROOT_PRIM", "DEFAULT_COLOR_SPACE", "MESH_REL", "COLOR_SPACE_ATTR", "SPLAT_TYPE",
           "SH_COEFFS", "SH_DEGREE", "INT32_MAX", "UsdType", "USD_TYPES", "USD_OPTIONAL",
           "FIELDS", "API_ATTRIBUTE_TYPES",
           "RestAttribute", "REST_ATTRS", "components", "usd_required", "usd_allowed_names",
           "anchor_attribute_names", "UsdSchemaWarning", "import_pxr", "pxr",
           "register_schema", "schema_registered", "pxr_errors", "pxr_message"]

#: File suffixes of USD files (``.usd`` is written as binary ``usdc``).
USD_SUFFIXES = (".usda", ".usdc", ".usd", ".usdz")

#: The one-line message when ``pxr`` cannot be imported, for a package installed from an
#: index (:func:`gsverse_format.install.missing_usd_core` gives the line that fits this copy).
MISSING_USD_CORE = "USD support needs usd-core: pip install 'gsverse-format[usd]'"

#: The codeless schema plugin (``plugInfo.json`` + ``generatedSchema.usda``).
SCHEMA_DIR = pathlib.Path(str(resources.files("gsverse_format") / "usd_schema"))

ANCHOR_API = "GsVerseMeshAnchorAPI"
COLOR_SPACE_API = "GsVerseColorSpaceAPI"
ROOT_PRIM = "Asset"
DEFAULT_COLOR_SPACE = "srgb_rec709_display"
MESH_REL = USD_MESH
COLOR_SPACE_ATTR = "gsverse:colorSpace"

SPLAT_TYPE = "ParticleField3DGaussianSplat"
SH_COEFFS = "radiance:sphericalHarmonicsCoefficients"
SH_DEGREE = "radiance:sphericalHarmonicsDegree"
INT32_MAX = 2 ** 31 - 1


@dataclass(frozen=True)
class UsdType:
    """How one anchor field is stored: its Sdf value type name and Vt array type name."""

    sdf: str
    vt: str


#: Anchor field (:attr:`AnchorField.attribute` of the vocabulary) -> its USD value types.
USD_TYPES: dict[str, UsdType] = {
    "face_index": UsdType("IntArray", "IntArray"),
    "barycentrics": UsdType("Float2Array", "Vec2fArray"),
    "normal_offset": UsdType("FloatArray", "FloatArray"),
    "local_rotation": UsdType("QuatfArray", "QuatfArray"),
    "local_scale": UsdType("Float3Array", "Vec3fArray"),
    "rho": UsdType("FloatArray", "FloatArray"),
}

#: Anchor fields a USD prim may leave unauthored although its profile requires them: the rest
#: scales stand for absent ``gsverse:anchor:localScales`` (spec/usd.md).
USD_OPTIONAL = frozenset({"local_scale"})


#: The anchor fields by data-model attribute (``"face_index"``, ...).
FIELDS: dict[str, AnchorField] = {f.attribute: f for f in ANCHOR_FIELDS}

#: Every attribute of the GsVerse API schemas -> its Sdf value type name, in schema order.
API_ATTRIBUTE_TYPES: dict[str, str] = {
    USD_PROFILE: "Token", USD_DEFORMATION: "Token",
    **{f.usd: USD_TYPES[f.attribute].sdf for f in ANCHOR_FIELDS},
    COLOR_SPACE_ATTR: "Token"}


def components(field: AnchorField) -> int:
    """Values per splat of ``field``: 0 for scalars, else the vector size."""
    return 0 if field.accessor == "SCALAR" else int(field.accessor[3:])


def usd_required(profile: str) -> tuple[AnchorField, ...]:
    """The anchor fields a USD prim with ``profile`` must author."""
    return tuple(f for f in allowed_fields(profile) if f.attribute not in USD_OPTIONAL)


def usd_allowed_names(profile: str) -> frozenset[str]:
    """Every ``gsverse:anchor:*`` attribute a prim with ``profile`` may author."""
    names = {f.usd for f in allowed_fields(profile)} | {USD_PROFILE}
    if profile == "local" and DEFORMATIONS:
        names.add(USD_DEFORMATION)
    return frozenset(names)


def anchor_attribute_names() -> tuple[str, ...]:
    """Every ``gsverse:anchor:*`` attribute of ``GsVerseMeshAnchorAPI``, profile first."""
    return tuple(name for name in API_ATTRIBUTE_TYPES if name != COLOR_SPACE_ATTR)


@dataclass(frozen=True)
class RestAttribute:
    """A rest-pose attribute of ``ParticleField3DGaussianSplat``: its half-precision variant,
    its values per particle (0: scalar) and the schema's default value (None: required)."""

    half: str
    components: int
    default: tuple[float, ...] | float | None


REST_ATTRS: dict[str, RestAttribute] = {
    "positions": RestAttribute("positionsh", 3, None),
    "orientations": RestAttribute("orientationsh", 4, (0.0, 0.0, 0.0, 1.0)),
    "scales": RestAttribute("scalesh", 3, (1.0, 1.0, 1.0)),
    "opacities": RestAttribute("opacitiesh", 0, 1.0),
}

_SCHEMA_TOO_LATE = (
    "the GsVerse USD schemas could not be registered: this process used USD's schema registry "
    "before gsverse_format.io.usd did; files are written identically without them, but to use "
    "the schema API here, call gsverse_format.io.usd.register_schema() before any other USD "
    f"use, or set PXR_PLUGINPATH_NAME={SCHEMA_DIR} before the process starts")


class UsdSchemaWarning(UserWarning):
    """The GsVerse schemas could not be registered in this process (see :func:`register_schema`)."""


_PXR: types.SimpleNamespace | None = None
_REGISTERED: bool | None = None


def import_pxr() -> types.SimpleNamespace:
    """The ``pxr`` modules used here; :class:`UsageError` without (a recent enough) usd-core."""
    global _PXR
    if _PXR is None:
        try:
            from pxr import Gf, Kind, Plug, Sdf, Tf, Usd, UsdGeom, UsdUtils, UsdVol, Vt
        except ImportError:
            from ...install import missing_usd_core  # the install line that fits this copy

            raise UsageError(missing_usd_core()) from None
        if not hasattr(UsdVol, SPLAT_TYPE):
            raise UsageError("USD support needs usd-core 26.03 or later (for UsdVol."
                             f"{SPLAT_TYPE}): pip install -U 'gsverse-format[usd]'")
        _PXR = types.SimpleNamespace(Gf=Gf, Kind=Kind, Plug=Plug, Sdf=Sdf, Tf=Tf, Usd=Usd,
                                     UsdGeom=UsdGeom, UsdUtils=UsdUtils, UsdVol=UsdVol, Vt=Vt)
    return _PXR


def register_schema() -> bool:
    """Register the GsVerse schema plugin with USD; return whether the schemas are known.

    Called by every function of this package before it touches a USD stage. Registration
    only takes effect if USD's schema registry has not been used yet in this process (opening
    a stage with prims or defining a prim counts as a use); otherwise this returns ``False``
    and issues a :class:`UsdSchemaWarning` once, and the writer authors the schema metadata by
    hand, producing the same file. Call it early (or set ``PXR_PLUGINPATH_NAME`` to
    :data:`SCHEMA_DIR`) in applications that use USD themselves. Raises :class:`UsageError`
    without usd-core.
    """
    global _REGISTERED
    if _REGISTERED is None:
        px = import_pxr()
        px.Plug.Registry().RegisterPlugins(str(SCHEMA_DIR))
        # The check must come after the registration: it initialises the registry itself.
        _REGISTERED = px.Usd.SchemaRegistry().FindAppliedAPIPrimDefinition(ANCHOR_API) is not None
        if not _REGISTERED:
            warnings.warn(_SCHEMA_TOO_LATE, UsdSchemaWarning, stacklevel=2)
    return _REGISTERED


def schema_registered() -> bool:
    """Whether :func:`register_schema` registered the schemas (False before it ran)."""
    return bool(_REGISTERED)


def pxr() -> types.SimpleNamespace:
    """The ``pxr`` modules, with the schemas registered (if they still can be)."""
    px = import_pxr()
    register_schema()
    return px


def pxr_errors() -> tuple[type[BaseException], ...]:
    """What USD raises for data it cannot read or write: ``Tf.ErrorException`` (the errors of
    the C++ library) and ``UnicodeDecodeError`` (text of the file, such as a name or a token,
    that is not valid UTF-8 and so cannot become a Python string)."""
    return (import_pxr().Tf.ErrorException, UnicodeDecodeError)


#: Characters of a USD error message looked at: the USD library can describe a corrupt file of
#: a few kilobytes in a message of over 100 MB (one entry per bad spec), and searching or
#: splitting all of it would take longer than reading the file.
MAX_MESSAGE_CHARS = 4000


def pxr_message(err: BaseException) -> str:
    """The first message of a ``Tf.ErrorException`` (or any exception), on one line, from its
    first :data:`MAX_MESSAGE_CHARS` characters."""
    try:
        text = str(err)[:MAX_MESSAGE_CHARS]
    except UnicodeDecodeError:  # USD quotes the file's bytes, which need not be UTF-8
        return f"{type(err).__name__} (its message is not valid UTF-8)"
    found = re.search(r" : '(.*?)'(?:\n|$)", text, re.S)
    if found:
        text = found.group(1)
    return " ".join(text.split()) or type(err).__name__
