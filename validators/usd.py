"""Validate one USD file (``.usda``, ``.usdc``, ``.usd``, ``.usdz``) against spec/usd.md.

The structural checks are those of :func:`gsverse_format.io.usd.inspect_usd` (what a reader
requires, the writer rules, OpenUSD's own validators), run in a child process so that a file
that crashes the USD library becomes a finding; their codes are mapped onto the catalogue
(``USD_*`` codes, or the glTF code of the same check). The data it read are then checked
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

from gsverse_format.errors import FormatError, UsageError
from gsverse_format.io import usd as U
from gsverse_format.model import LocalAnchors

from .context import CheckContext
from .issues import CATALOGUE, Severity
from .values import (AnchorMesh, AnchorValues, RestPose, check_anchor_values,
                     check_nonnegative, check_opacities, check_triangles,
                     check_unit_quaternions)

__all__ = ["USD_MIME", "PROBLEM_CODES", "validate_usd", "usd_mime_type"]

#: Media types reported for USD files (``model/vnd.usda`` and ``model/vnd.usdz+zip`` are
#: registered with IANA; binary crate files have no registered type).
USD_MIME = {"usda": "model/vnd.usda", "usdc": "model/x-usdc", "usdz": "model/vnd.usdz+zip"}

#: The codes of :func:`gsverse_format.io.usd.check_usd` and their catalogue codes.
PROBLEM_CODES = {
    "TYPE_MISMATCH": "USD_TYPE_MISMATCH",
    "NOT_FINITE": "NON_FINITE_VALUE",
    "SKIPPED_PARTICLE_FIELD": "USD_PARTICLE_FIELD_SKIPPED",
    "BAD_UP_AXIS": "USD_UP_AXIS_INVALID",
    "CONVERTED_UP_AXIS": "USD_UP_AXIS_CONVERTED",
    "MISSING_UP_AXIS": "USD_UP_AXIS_MISSING",
    "BAD_METERS_PER_UNIT": "USD_METERS_PER_UNIT_INVALID",
    "CONVERTED_UNITS": "USD_UNITS_CONVERTED",
    "MISSING_METERS_PER_UNIT": "USD_METERS_PER_UNIT_MISSING",
    "MISSING_DEFAULT_PRIM": "USD_DEFAULT_PRIM_MISSING",
    "DEFAULT_PRIM_NOT_XFORM": "USD_DEFAULT_PRIM_NOT_XFORM",
    "MISSING_ATTRIBUTE": "USD_PROPERTY_MISSING",
    "LENGTH_MISMATCH": "USD_LENGTH_MISMATCH",
    "REPLACED_BY_DEFAULT": "USD_REPLACED_BY_DEFAULT",
    "TRUNCATED": "USD_TRUNCATED",
    "EMPTY_PRIM": "USD_EMPTY_PRIM",
    "BAD_SH_DEGREE": "USD_SH_DEGREE_INVALID",
    "BAD_PROFILE": "USD_PROFILE_INVALID",
    "EXCLUDED_ATTRIBUTE": "USD_PROPERTY_EXCLUDED",
    "FACE_INDEX_OUT_OF_RANGE": "ANCHOR_FACE_OUT_OF_RANGE",
    "ZERO_ROTATION": "ROTATION_NOT_UNIT",
    "NEGATIVE_SCALE": "SCALE_NEGATIVE",
    "BAD_DEFORMATION": "USD_DEFORMATION_INVALID",
    "BAD_MESH_TARGET": "USD_MESH_TARGET_INVALID",
    "NOT_TRIANGLES": "ANCHOR_MESH_NOT_TRIANGLES",
    "INDEX_OUT_OF_RANGE": "ANCHOR_MESH_INDICES_INVALID",
    "HOLES": "USD_MESH_HOLES",
    "BOTH_APIS": "USD_BOTH_APIS",
    "PLAIN_SPLATS": "USD_PLAIN_SPLATS",
    "SORTING_MODE": "USD_SORTING_MODE",
    "PROJECTION_MODE": "USD_PROJECTION_MODE",
    "MISSING_SH_DEGREE": "USD_SH_DEGREE_MISSING",
    "HALF_PRECISION": "USD_HALF_PRECISION",
    "NO_REST_POSE": "USD_NO_REST_POSE",
    "TIME_SAMPLED": "USD_TIME_SAMPLED",
    "MISSING_EXTENT": "USD_EXTENT_MISSING",
    "BAD_EXTENT": "USD_EXTENT_INVALID",
    "CUSTOM_ATTRIBUTE": "USD_CUSTOM_PROPERTY",
    "NOT_UNIFORM": "USD_NOT_UNIFORM",
    "REDUNDANT_LOCAL_SCALES": "USD_LOCAL_SCALES_REDUNDANT",
    "XFORM_OPS": "USD_XFORM_OPS",
    "USD_COLOR_SPACE": "USD_COLOR_SPACE_API_IGNORED",
    "OUTSIDE_DEFAULT_PRIM": "USD_OUTSIDE_DEFAULT_PRIM",
    "NESTED_GPRIM": "USD_NESTED_GPRIM",
    "MESH_PURPOSE": "USD_MESH_PURPOSE",
    "MESH_SUBDIVISION": "USD_MESH_SUBDIVISION",
    "MESH_ORIENTATION": "USD_MESH_ORIENTATION",
    "MISSING_TIME_CODES": "USD_TIME_CODES_MISSING",
    "LAYER_OUTSIDE_FOLDER": "USD_LAYER_OUTSIDE_FOLDER",
}

_ANCHOR_ATTRIBUTES = {"faceIndex": "gsverse:anchor:faceIndices",
                      "barycentrics": "gsverse:anchor:barycentrics",
                      "normalOffset": "gsverse:anchor:normalOffsets",
                      "localRotation": "gsverse:anchor:localOrientations",
                      "localScale": "gsverse:anchor:localScales",
                      "rho": "gsverse:anchor:rho"}


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
    if problem.code.startswith("usd:"):
        code = "USD_VALIDATOR_ERROR" if problem.severity == "error" else "USD_VALIDATOR_WARNING"
        message = f"{problem.code[4:]}: {problem.message}"
    else:
        code = PROBLEM_CODES.get(problem.code)
        message = problem.message
        if code is None:  # a code of the reader that the catalogue does not know: a bug here
            code, message = "INTERNAL_ERROR", f"[{problem.code}] {problem.message}"
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
        ctx.issues.add("SIZE_LIMIT_EXCEEDED", f"the file has {size} bytes, more than --max-bytes "
                       f"{ctx.options.max_bytes}")
        return
    info["bytes"] = size
    try:
        found = U.inspect_usd(path)
    except UsageError as err:
        ctx.issues.add("USD_SUPPORT_MISSING", err.cause)
        return
    except FormatError as err:
        ctx.issues.add("USD_UNREADABLE", err.cause)
        return
    for problem in found.problems:
        _report_problem(ctx, problem)
    if any(p.code == "LAYER_OUTSIDE_FOLDER" for p in found.problems):
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


def _check_primitive(ctx: CheckContext, primitive, where: U.UsdPrimInfo,
                     meshes: dict[str, AnchorMesh]) -> None:
    """The value checks of one splat prim and, when anchored, of its anchors and mesh."""
    prim = where.path
    cloud = primitive.splats
    n = len(cloud)
    if ctx.options.max_splats is not None and n > ctx.options.max_splats:
        ctx.issues.add("SPLAT_COUNT_LIMIT", f"the prim has {n} splats, more than --max-splats "
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
    arrays = {"faceIndex": np.asarray(a.face_index, dtype=np.int64),
              "barycentrics": np.asarray(a.barycentrics)}
    locations = {prop: f"{prim}.{name}" for prop, name in _ANCHOR_ATTRIBUTES.items()}
    deformation = "affine"
    if isinstance(a, LocalAnchors):
        arrays.update(normalOffset=np.asarray(a.normal_offset).reshape(-1, 1),
                      localRotation=np.asarray(a.local_rotation),
                      localScale=np.asarray(a.local_scale))
        deformation = a.deformation
        if np.array_equal(a.local_scale, cloud.scales):  # not authored: read from scales
            locations["localScale"] = f"{prim}.scales"
            if not scales_ok:
                del arrays["localScale"]  # already reported at scales
    else:
        arrays["rho"] = np.asarray(a.rho).reshape(-1, 1)
    values = AnchorValues(a.profile, arrays, locations, {}, deformation)
    rest = None
    if rotations_ok and scales_ok:
        rest = RestPose(cloud.means, cloud.rotations, cloud.scales, f"{prim}.positions",
                        f"{prim}.orientations")
    check_anchor_values(ctx, values, meshes[where.mesh_path], rest)
