"""Splat primitives whose rest pose is an SPZ stream (``KHR_gaussian_splatting_compression_spz_2``,
spec/README.md §SPZ-compressed rest pose).

The placeholders and the stream are checked by the reader's own rules
(:func:`gsverse_format.io.gltf.spz.placeholder_count` and
:func:`~gsverse_format.io.gltf.spz.decode_primitive`, the stream's limits among them), so the
validator and the reader cannot disagree; the decoded rest pose then goes through the value
checks of every splat primitive, and the anchor checks (derived anchors included) use it. A
compressed primitive with stored anchors (explicit ``local`` or ``games``) is
``SPZ_EXPLICIT_ANCHORS``.
"""
from __future__ import annotations

from typing import Any

from gsverse_format.codes import Code
from gsverse_format.io.gltf import GltfFormatError
from gsverse_format.io.gltf.reader import sh_degree_of
from gsverse_format.io.gltf.spz import decode_primitive, placeholder_count
from gsverse_format.vocabulary import KHR, SPZ_EXTENSION

from .container import Context
from .khr import SplatData, check_primitive_json, tok
from .values import check_nonnegative, check_opacities, check_unit_quaternions

__all__ = ["check_compressed_primitive", "check_compressed_anchor"]


def check_compressed_primitive(ctx: Context, m: int, p: int, prim: dict, khr: Any) -> SplatData:
    """Check one compressed splat primitive and decode its rest pose."""
    pointer = f"/meshes/{m}/primitives/{p}"
    where = f"meshes[{m}].primitives[{p}]"
    data = SplatData(m, p, pointer)
    attrs = check_primitive_json(ctx, prim, khr, pointer)
    if attrs is None or not isinstance(khr, dict):
        return data
    color_space = khr.get("colorSpace")
    try:
        degree = sh_degree_of(attrs, where, f"{pointer}/attributes")
        count = placeholder_count(ctx.reader, attrs, degree, where, pointer)
        data.count = count
        if ctx.options.max_splats is not None and count > ctx.options.max_splats:
            ctx.issues.add(Code.SPLAT_COUNT_LIMIT, f"the primitive has {count} splats, more than "
                           f"--max-splats {ctx.options.max_splats}; its stream was not decoded",
                           pointer=f"{pointer}/attributes/POSITION")
            return data
        cloud = decode_primitive(ctx.reader, khr, attrs, count, degree,
                                 color_space if isinstance(color_space, str) else "",
                                 where, pointer)
    except GltfFormatError as err:
        if err.code not in (Code.KHR_SH_INCOMPLETE, Code.KHR_UNKNOWN_SEMANTIC,
                            Code.KHR_ATTRIBUTE_MISSING):   # check_semantics reported those
            ctx.add_error(err, pointer=pointer)
        return data
    attributes = f"{pointer}/attributes"
    ok_r = check_unit_quaternions(ctx, cloud.rotations, 0.0,
                                  f"{attributes}/{tok(KHR + ':ROTATION')}", "ROTATION")
    ok_s = check_nonnegative(ctx, cloud.scales, f"{attributes}/{tok(KHR + ':SCALE')}", "SCALE")
    check_opacities(ctx, cloud.opacities, f"{attributes}/{tok(KHR + ':OPACITY')}", "OPACITY")
    data.attributes = {name: ref for name, ref in attrs.items() if isinstance(ref, int)}
    data.means, data.rotations, data.scales = cloud.means, cloud.rotations, cloud.scales
    data.rest_ok = ok_r and ok_s
    return data


def check_compressed_anchor(ctx: Context, obj: Any, pointer: str) -> None:
    """``SPZ_EXPLICIT_ANCHORS`` for stored anchors on a compressed primitive (the anchor
    object at ``pointer``): only derived ``local`` anchors may sit on one."""
    if not isinstance(obj, dict):
        return
    stored = "barycentrics" in obj or obj.get("profile") == "games"
    if stored:
        what = "games anchors" if obj.get("profile") == "games" else "explicit local anchors"
        ctx.issues.add(Code.SPZ_EXPLICIT_ANCHORS, f"a primitive whose rest pose is SPZ-compressed "
                       f"({SPZ_EXTENSION}) carries {what}: stored anchors fix the rest pose "
                       f"to their remap within 1e-5 of the mesh diagonal, which SPZ's "
                       f"quantization exceeds; only derived (compact) local anchors may sit on "
                       f"a compressed primitive", pointer=pointer)

