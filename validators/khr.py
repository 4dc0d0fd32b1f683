"""``KHR_gaussian_splatting`` checks the Khronos glTF-Validator does not make.

Per splat primitive: mode POINTS, the extension's required properties and their values, the
required attributes and their accessor formats (``vocabulary.KHR_ATTRIBUTE_FORMATS``),
SH degrees complete, equal attribute counts, 4-byte aligned vertex attributes, and the values:
finite, unit quaternions, non-negative linear scales, opacities in [0, 1].
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gsverse_format.codes import Code
from gsverse_format.io.gltf import (QUANTIZED_POSITION_FORMATS, AccessorLayout, describe_format,
                                    format_allowed, pointer_token)
from gsverse_format.model import COLOR_SPACES
from gsverse_format.vocabulary import (BYTE, COMPONENT_TYPE_NAMES, KHR, KHR_ATTRIBUTE_FORMATS,
                                       SHORT, UNSIGNED_BYTE, UNSIGNED_SHORT, Format)

from .container import Context
from .values import (RestPose, check_finite, check_nonnegative, check_opacities,
                     check_unit_quaternions)

__all__ = ["SplatData", "check_splat_primitive", "check_primitive_json", "check_properties",
           "check_semantics", "quantization_step"]

_SH_RE = re.compile(r"SH_DEGREE_(\d+)_COEF_(\d+)")
_REQUIRED = ("POSITION", f"{KHR}:ROTATION", f"{KHR}:SCALE", f"{KHR}:OPACITY",
             f"{KHR}:SH_DEGREE_0_COEF_0")
_PROPERTIES = (("kernel", ("ellipse",), True), ("colorSpace", COLOR_SPACES, True),
               ("projection", ("perspective",), False),
               ("sortingMethod", ("cameraDistance",), False))
_STEP = {BYTE: 1 / 127, SHORT: 1 / 32767, UNSIGNED_BYTE: 1 / 255, UNSIGNED_SHORT: 1 / 65535}


@dataclass
class SplatData:
    """What the checks of one splat primitive found out; arrays are ``None`` when unusable.

    ``rest_ok`` is True when POSITION, ROTATION and SCALE were read and are valid, so the
    rest-pose consistency check can use them.
    """

    mesh: int
    primitive: int
    pointer: str
    count: int | None = None
    attributes: dict[str, int] = field(default_factory=dict)
    means: np.ndarray | None = None
    rotations: np.ndarray | None = None
    scales: np.ndarray | None = None
    rest_ok: bool = False

    def rest_pose(self) -> RestPose | None:
        """The stored rest pose when it is valid (``rest_ok``), else None."""
        if not self.rest_ok or self.means is None or self.rotations is None \
                or self.scales is None:
            return None
        return RestPose(self.means, self.rotations, self.scales,
                        f"{self.pointer}/attributes/POSITION",
                        f"{self.pointer}/attributes/{tok(KHR + ':ROTATION')}")


def tok(name: Any) -> str:
    return pointer_token(name)


def quantization_step(layout: AccessorLayout) -> float:
    """One step of a normalized integer accessor (0 for FLOAT)."""
    return _STEP.get(layout.component_type, 0.0) if layout.normalized else 0.0


def check_properties(ctx: Context, khr: Any, pointer: str) -> None:
    if not isinstance(khr, dict):
        ctx.issues.add(Code.KHR_PROPERTY_INVALID, f"the {KHR} extension must be an object",
                       pointer=pointer)
        return
    for prop, known, required in _PROPERTIES:
        if prop not in khr:
            if required:
                ctx.issues.add(Code.KHR_PROPERTY_MISSING, f"{KHR} lacks the required property "
                               f"{prop!r}", pointer=pointer)
        elif not isinstance(khr[prop], str):
            ctx.issues.add(Code.KHR_PROPERTY_INVALID, f"{KHR}.{prop} must be a string, got "
                           f"{khr[prop]!r:.40}", pointer=f"{pointer}/{prop}")
        elif khr[prop] not in known:
            ctx.issues.add(Code.KHR_PROPERTY_UNKNOWN_VALUE, f"{KHR}.{prop} is {khr[prop]!r:.60}, "
                           f"which the base extension does not define (known: "
                           f"{', '.join(known)})", pointer=f"{pointer}/{prop}")
    nested = khr.get("extensions")
    if nested is not None and not isinstance(nested, dict):
        ctx.issues.add(Code.KHR_PROPERTY_INVALID, f"{KHR}.extensions must be an object",
                       pointer=f"{pointer}/extensions")


def check_semantics(ctx: Context, attrs: dict, pointer: str) -> None:
    present: set[tuple[int, int]] = set()
    for name in attrs:
        if not name.startswith(KHR + ":"):
            continue
        semantic = name[len(KHR) + 1:]
        if semantic in ("ROTATION", "SCALE", "OPACITY"):
            continue
        m = _SH_RE.fullmatch(semantic)
        if m and int(m.group(1)) <= 3 and int(m.group(2)) <= 2 * int(m.group(1)) \
                and str(int(m.group(1))) == m.group(1) and str(int(m.group(2))) == m.group(2):
            present.add((int(m.group(1)), int(m.group(2))))
            continue
        ctx.issues.add(Code.KHR_UNKNOWN_SEMANTIC, f"attribute {name!r:.80} is not a "
                       f"{KHR} semantic (ROTATION, SCALE, OPACITY, SH_DEGREE_l_COEF_n with "
                       f"l <= 3, n <= 2l)", pointer=f"{pointer}/attributes/{tok(name)}")
    missing = [a for a in _REQUIRED if a not in attrs]
    if missing:
        ctx.issues.add(Code.KHR_ATTRIBUTE_MISSING, f"required attribute(s) missing: "
                       f"{', '.join(missing)}", pointer=f"{pointer}/attributes")
    highest = max((level for level, _ in present), default=-1)
    for level in range(highest + 1):
        lacking = [n for n in range(2 * level + 1) if (level, n) not in present]
        if len(lacking) == 2 * level + 1 and level > 0:
            ctx.issues.add(Code.KHR_SH_INCOMPLETE, f"SH degree {highest} is present but degree "
                           f"{level} is missing", pointer=f"{pointer}/attributes")
        elif lacking and level > 0:
            ctx.issues.add(Code.KHR_SH_INCOMPLETE, f"SH degree {level} is partially defined "
                           f"(missing COEF_{', COEF_'.join(map(str, lacking))})",
                           pointer=f"{pointer}/attributes")


def _format_of(name: str, quantized_positions: bool) -> tuple[str, tuple[Format, ...]] | None:
    """(accessor type, allowed formats) of attribute ``name``; None for other attributes."""
    if name == "POSITION":
        accessor, formats = KHR_ATTRIBUTE_FORMATS["POSITION"]
        if quantized_positions:
            return accessor, formats + QUANTIZED_POSITION_FORMATS
        return accessor, formats
    if name in KHR_ATTRIBUTE_FORMATS:
        return KHR_ATTRIBUTE_FORMATS[name]
    if name.startswith(KHR + ":SH_DEGREE_"):
        return KHR_ATTRIBUTE_FORMATS["SH"]
    return None


def check_primitive_json(ctx: Context, prim: dict, khr: Any,
                         pointer: str) -> dict | None:
    """The checks of a splat primitive's JSON every storage shares (its mode, the
    ``KHR_gaussian_splatting`` properties, the attribute semantics); its attributes, or None
    when they are not an object."""
    if prim.get("mode", 4) != 0:
        ctx.issues.add(Code.KHR_PRIMITIVE_NOT_POINTS, f"a {KHR} primitive must have mode POINTS "
                       f"(0), not {prim.get('mode', 4)!r}", pointer=f"{pointer}/mode")
    check_properties(ctx, khr, f"{pointer}/extensions/{KHR}")
    attrs = prim.get("attributes", {})
    if not isinstance(attrs, dict):
        return None
    check_semantics(ctx, attrs, pointer)
    return attrs


def check_splat_primitive(ctx: Context, m: int, p: int, prim: dict, khr: Any) -> SplatData:
    """Check one primitive carrying ``KHR_gaussian_splatting`` and read its rest pose."""
    pointer = f"/meshes/{m}/primitives/{p}"
    data = SplatData(m, p, pointer)
    attrs = check_primitive_json(ctx, prim, khr, pointer)
    if attrs is None:
        return data
    used = ctx.doc.get("extensionsUsed", [])
    quantized_positions = isinstance(used, list) and "KHR_mesh_quantization" in used

    layouts: dict[str, AccessorLayout] = {}
    for name, ref in attrs.items():
        apointer = f"{pointer}/attributes/{tok(name)}"
        lay = ctx.accessor(ref, apointer)
        if lay is None:
            continue
        data.attributes[name] = lay.accessor
        fmt = _format_of(name, quantized_positions)
        if fmt is not None and not format_allowed(lay, *fmt):
            allowed = ", ".join(f"{fmt[0]} " + COMPONENT_TYPE_NAMES[c]
                                + ("" if n is False else " normalized" if n else
                                   " (normalized or not)")
                                for c, n in fmt[1])
            ctx.issues.add(Code.KHR_ATTRIBUTE_FORMAT, f"{name} is {describe_format(lay)}; allowed: "
                           f"{allowed}", pointer=apointer)
            continue
        if lay.start % 4 or lay.stride % 4:
            ctx.issues.add(Code.ACCESSOR_MISALIGNED, f"vertex attribute {name} (accessor "
                           f"{lay.accessor}) starts at byte {lay.start} with stride {lay.stride}; "
                           f"both must be multiples of 4", pointer=apointer)
        layouts[name] = lay

    if not layouts:
        return data
    reference = "POSITION" if "POSITION" in layouts else next(iter(layouts))
    count = layouts[reference].count
    for name, lay in list(layouts.items()):
        if lay.count != count:
            ctx.issues.add(Code.ATTRIBUTE_COUNT_MISMATCH, f"{name} has {lay.count} elements, "
                           f"{reference} has {count}",
                           pointer=f"{pointer}/attributes/{tok(name)}")
            del layouts[name]
    data.count = count
    if ctx.options.max_splats is not None and count > ctx.options.max_splats:
        ctx.issues.add(Code.SPLAT_COUNT_LIMIT, f"the primitive has {count} splats, more than "
                       f"--max-splats {ctx.options.max_splats}; its values were not checked",
                       pointer=f"{pointer}/attributes/{tok(reference)}")
        return data

    def values(name: str) -> tuple[np.ndarray | None, bool]:
        lay = layouts.get(name)
        if lay is None:
            return None, False
        arr = ctx.floats(lay, f"{pointer} {name}")
        if arr is None:
            return None, False
        return arr, check_finite(ctx, arr, f"{pointer}/attributes/{tok(name)}", name)

    means, ok_m = values("POSITION")
    rotations, ok_r = values(f"{KHR}:ROTATION")
    if rotations is not None and ok_r:
        ok_r = check_unit_quaternions(ctx, rotations,
                                      quantization_step(layouts[f"{KHR}:ROTATION"]),
                                      f"{pointer}/attributes/{tok(KHR + ':ROTATION')}", "ROTATION")
    scales, ok_s = values(f"{KHR}:SCALE")
    if scales is not None and ok_s:
        ok_s = check_nonnegative(ctx, scales, f"{pointer}/attributes/{tok(KHR + ':SCALE')}",
                                 "SCALE")
    opacity, ok_o = values(f"{KHR}:OPACITY")
    if opacity is not None and ok_o:
        check_opacities(ctx, opacity[:, 0], f"{pointer}/attributes/{tok(KHR + ':OPACITY')}",
                        "OPACITY")
    for name in layouts:
        if name.startswith(KHR + ":SH_DEGREE_"):
            values(name)
    data.means, data.rotations, data.scales = means, rotations, scales
    data.rest_ok = (means is not None and rotations is not None and scales is not None
                    and ok_m and ok_r and ok_s)
    return data
