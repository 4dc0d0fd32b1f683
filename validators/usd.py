"""Validate one USD file (``.usda``, ``.usdc``, ``.usd``, ``.usdz``) against spec/usd.md.

The structural checks are those of :func:`gsverse_format.io.usd.inspect_usd` (what a reader
requires, the writer rules, OpenUSD's own validators), run in a child process so that a file
that crashes the USD library becomes a finding; they report catalogue codes (``USD_*`` codes,
or the glTF code of the same check). The data it read are then checked
like glTF data (:mod:`.values`): unit quaternions, non-negative scales, opacities in [0, 1],
anchor-mesh triangle quality, anchor values and rest-pose consistency. Locations are USD
paths: a prim (``/Asset/body``), a property (``/Asset/body.gsverse:anchor:faceIndices``) or
``""`` for the root layer.

Prims without a GsVerse API schema are foreign data: the writer rules and the value checks
that readers repair (orientations, scales, opacities) report warnings for them instead of
errors (:attr:`CodeInfo.foreign_severity`).
"""
from __future__ import annotations

import os

import numpy as np

from gsverse_format.codes import Code
from gsverse_format.errors import FormatError, UsageError
from gsverse_format.io import usd as U
from gsverse_format.model import LocalAnchors, SplatPrimitive
from gsverse_format.vocabulary import ANCHOR_FIELDS, DEFORMATIONS, allowed_fields

from .context import CheckContext
from .issues import CATALOGUE, Severity
from .values import (AnchorMesh, AnchorValues, RestPose, check_anchor_values,
                     check_nonnegative, check_opacities, check_triangles,
                     check_unit_quaternions)

__all__ = ["USD_MIME", "validate_usd", "usd_mime_type"]

#: Media types reported for USD files (``model/vnd.usda`` and ``model/vnd.usdz+zip`` are
#: registered with IANA; binary crate files have no registered type).
USD_MIME = {"usda": "model/vnd.usda", "usdc": "model/x-usdc", "usdz": "model/vnd.usdz+zip"}

_FACE_INDEX, _LOCAL_SCALE = (next(f for f in ANCHOR_FIELDS if f.attribute == name)
                             for name in ("face_index", "local_scale"))


def usd_mime_type(path: str) -> str:
    """The media type of a USD file: by suffix, and by content for ``.usd``."""
    ext = os.path.splitext(path)[1].lower().lstrip(".")
    if ext == "usd":
        try:
            with open(path, "rb") as handle:
                ext = "usdc" if handle.read(8) == b"PXR-USDC" else "usda"
        except OSError:
            ext = "usda"
    return USD_MIME.get(ext, USD_MIME["usda"])


def _report_problem(ctx: CheckContext, problem: U.UsdProblem) -> None:
    code = problem.code
    message = f"{problem.validator}: {problem.message}" if problem.validator else problem.message
    info = CATALOGUE[code]
    foreign = (problem.severity == "warning" and info.severity == Severity.ERROR
               and info.foreign_severity is not None)
    ctx.issues.foreign = foreign
    try:
        ctx.issues.add(code, message[:500], pointer=problem.location)
    finally:
        ctx.issues.foreign = False


def validate_usd(ctx: CheckContext, info: dict) -> None:
    """Validate ``ctx.path`` (an existing USD file); fill ``info``."""
    path = ctx.path
    size = os.path.getsize(path)
    if size > ctx.options.max_bytes:
        ctx.issues.add(Code.SIZE_LIMIT_EXCEEDED, f"the file has {size} bytes, more than "
                       f"--max-bytes {ctx.options.max_bytes}")
        return
    info["bytes"] = size
    try:
        found = U.inspect_usd(path)
    except UsageError as err:
        ctx.issues.add(Code.USD_SUPPORT_MISSING, err.cause)
        return
    except FormatError as err:
        ctx.issues.add(Code.USD_UNREADABLE, err.cause)
        return
    for problem in found.problems:
        _report_problem(ctx, problem)
    if any(p.code == Code.USD_LAYER_OUTSIDE_FOLDER for p in found.problems):
        return
    meshes: dict[str, AnchorMesh] = {}
    total = 0
    for primitive, where in zip(found.asset.primitives, found.prims):
        total += len(primitive.splats)
        ctx.issues.foreign = not where.gsverse
        try:
            _check_primitive(ctx, primitive, where, meshes)
        finally:
            ctx.issues.foreign = False
    info.update({"splatPrimitives": len(found.prims),
                 "anchoredPrimitives": sum(1 for p in found.prims if p.mesh_path),
                 "splats": total, "anchorPrimitives": len(meshes)})
    if found.asset.generator:
        info["generator"] = found.asset.generator


def _check_primitive(ctx: CheckContext, primitive: SplatPrimitive, where: U.UsdPrimInfo,
                     meshes: dict[str, AnchorMesh]) -> None:
    """The value checks of one splat prim and, when anchored, of its anchors and mesh."""
    prim = where.path
    cloud = primitive.splats
    n = len(cloud)
    if ctx.options.max_splats is not None and n > ctx.options.max_splats:
        ctx.issues.add(Code.SPLAT_COUNT_LIMIT, f"the prim has {n} splats, more than --max-splats "
                       f"{ctx.options.max_splats}; its values were not checked",
                       pointer=f"{prim}.positions")
        return
    rotations_ok = check_unit_quaternions(ctx, cloud.rotations, 0.0, f"{prim}.orientations",
                                          "orientations")
    scales_ok = check_nonnegative(ctx, cloud.scales, f"{prim}.scales", "scales")
    check_opacities(ctx, cloud.opacities, f"{prim}.opacities", "opacities")
    anchoring = primitive.anchoring
    if anchoring is None or where.mesh_path is None:
        return
    if where.mesh_path not in meshes:
        meshes[where.mesh_path] = check_triangles(ctx, anchoring.mesh, where.mesh_path)
    a = anchoring.anchors
    arrays: dict[str, np.ndarray] = {}
    for field in allowed_fields(a.profile):  # by glTF key, as the glTF checks read them
        value = np.asarray(getattr(a, field.attribute))
        if field is _FACE_INDEX:
            value = value.astype(np.int64)
        elif value.ndim == 1:
            value = value.reshape(-1, 1)
        arrays[field.key] = value
    locations = {f.key: f"{prim}.{f.usd}" for f in ANCHOR_FIELDS}
    deformation = DEFORMATIONS[0]
    if isinstance(a, LocalAnchors):
        deformation = a.deformation
        if np.array_equal(a.local_scale, cloud.scales):  # not authored: read from scales
            locations[_LOCAL_SCALE.key] = f"{prim}.scales"
            if not scales_ok:
                del arrays[_LOCAL_SCALE.key]  # already reported at scales
    values = AnchorValues(a.profile, arrays, locations, {}, deformation)
    rest = None
    if rotations_ok and scales_ok:
        rest = RestPose(cloud.means, cloud.rotations, cloud.scales, f"{prim}.positions",
                        f"{prim}.orientations")
    check_anchor_values(ctx, values, meshes[where.mesh_path], rest)
