"""Catalogue rows of the splat primitive (``KHR_gaussian_splatting``: mode, extension object,
attributes and their values). Rows in the format of :mod:`.issues_rows`."""
from __future__ import annotations

from gsverse_format.codes import Code
from gsverse_format.vocabulary import EXTENSION, KHR

from .issues_rows import Row

__all__ = ["KHR_ENTRIES"]

_PRIM = "/meshes/{m}/primitives/{p}"
_EXT = _PRIM + f"/extensions/{KHR}/extensions/{EXTENSION}"

KHR_ENTRIES: list[Row] = [
    (Code.KHR_NO_SPLATS, "WARNING", "KHR_gaussian_splatting", "The file has no primitive with "
     "the KHR_gaussian_splatting extension.", "none", "Check that the right file was passed."),
    (Code.KHR_PRIMITIVE_NOT_POINTS, "ERROR", "KHR_gaussian_splatting", "A primitive with the "
     "extension does not have mode POINTS (0); a primitive without mode has glTF's default, "
     "TRIANGLES (4). Readers refuse such an anchored primitive.", _PRIM + "/mode",
     "Set \"mode\": 0."),
    (Code.KHR_PROPERTY_MISSING, "ERROR", "KHR_gaussian_splatting", "The extension object lacks a "
     "required property (kernel, colorSpace).", _PRIM + "/extensions/KHR_gaussian_splatting",
     "Add it (kernel \"ellipse\", colorSpace \"srgb_rec709_display\" or \"lin_rec709_display\")."),
    (Code.KHR_PROPERTY_INVALID, "ERROR", "KHR_gaussian_splatting", "The extension object, its "
     "extensions member, or kernel/colorSpace/projection/sortingMethod has the wrong JSON type.",
     _PRIM + "/extensions/KHR_gaussian_splatting/...", "Use an object and strings."),
    (Code.KHR_PROPERTY_UNKNOWN_VALUE, "WARNING", "KHR_gaussian_splatting", "kernel, colorSpace, "
     "projection or sortingMethod has a value the base extension does not define (another "
     "extension may define it; viewers fall back to the defaults).",
     _PRIM + "/extensions/KHR_gaussian_splatting/{property}", "Use a defined value, or declare "
     "the extension that defines it."),
    (Code.KHR_ATTRIBUTE_MISSING, "ERROR", "KHR_gaussian_splatting",
     "POSITION, KHR_gaussian_splatting:ROTATION, :SCALE, :OPACITY or :SH_DEGREE_0_COEF_0 is "
     "missing.", _PRIM + "/attributes", "Write every required attribute."),
    (Code.KHR_ATTRIBUTE_FORMAT, "ERROR", "KHR_gaussian_splatting", "A splat attribute's accessor "
     "type or component type is not allowed: POSITION FLOAT VEC3 (or the KHR_mesh_quantization "
     "types); ROTATION VEC4 FLOAT or BYTE/SHORT normalized; SCALE VEC3 FLOAT or "
     "UNSIGNED_BYTE/UNSIGNED_SHORT (normalized or not); OPACITY SCALAR FLOAT or "
     "UNSIGNED_BYTE/UNSIGNED_SHORT normalized; SH VEC3 FLOAT.", _PRIM + "/attributes/{name}",
     "Store the attribute in an allowed format."),
    (Code.KHR_UNKNOWN_SEMANTIC, "ERROR", "KHR_gaussian_splatting", "An attribute named "
     "KHR_gaussian_splatting:* is not ROTATION, SCALE, OPACITY or SH_DEGREE_l_COEF_n with l ≤ 3 "
     "and n ≤ 2l.", _PRIM + "/attributes/{name}", "Rename or remove the attribute."),
    (Code.KHR_SH_INCOMPLETE, "ERROR", "KHR_gaussian_splatting", "An SH degree is partially "
     "defined, or a degree is present while a lower one is missing.", _PRIM + "/attributes",
     "Write all 2l + 1 coefficients of every degree up to the highest."),
    (Code.ATTRIBUTE_COUNT_MISMATCH, "ERROR", "KHR_gaussian_splatting", "The attributes of one "
     "primitive have different counts.", _PRIM + "/attributes/{name}", "Give every attribute "
     "one element per splat."),
    (Code.ROTATION_NOT_UNIT, "ERROR", "KHR_gaussian_splatting", "A rotation quaternion "
     "(KHR_gaussian_splatting:ROTATION or localRotation) is not of unit length within the "
     "tolerance, or is zero.",
     _PRIM + "/attributes/KHR_gaussian_splatting:ROTATION or " + _EXT + "/localRotation",
     "Normalize the quaternions before writing."),
    (Code.SCALE_NEGATIVE, "ERROR", "KHR_gaussian_splatting",
     "A scale (KHR_gaussian_splatting:SCALE or localScale) is negative. Scales are linear "
     "standard deviations, never logs.",
     _PRIM + "/attributes/KHR_gaussian_splatting:SCALE or " + _EXT + "/localScale",
     "Store exp() of 3DGS log-scales."),
    (Code.OPACITY_OUT_OF_RANGE, "ERROR", "KHR_gaussian_splatting", "An opacity is outside [0, "
     "1]. Opacities are linear, after the sigmoid.",
     _PRIM + "/attributes/KHR_gaussian_splatting:OPACITY", "Store sigmoid() of 3DGS opacity "
     "logits."),
]
