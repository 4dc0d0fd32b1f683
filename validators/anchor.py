"""``GSVERSE_gaussian_splatting_mesh_anchor`` checks: schema, accessors, anchor mesh, values,
and the rest-pose consistency of spec §Rest-pose consistency.

The anchor mesh is checked once per anchor primitive (mode, positions, indices; degenerate,
sliver and duplicate triangles). For every anchored splat primitive the anchor accessors are
checked against the spec's format table (``gsverse_format.vocabulary.ANCHOR_FIELDS``),
their values per profile, and finally the reference remap at the rest mesh
(:func:`gsverse_format.remapping.reference.iter_moments`) is compared with the stored rest pose.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from gsverse_format.codes import Code
from gsverse_format.io.gltf import AccessorLayout, describe_format, format_allowed
from gsverse_format.model import TriangleMesh
from gsverse_format.vocabulary import (ANCHOR_FIELDS, DERIVED_KEYS, EXTENSION, FACE_COUNTS,
                                       FIELDS_BY_KEY, FLOAT, KHR, NODE_VISIBILITY, PROFILES,
                                       UNSIGNED_BYTE, UNSIGNED_INT, UNSIGNED_SHORT,
                                       gltf_required_keys)

from .compact import derived_arrays, faces_from_counts
from .container import Context
from .khr import SplatData, quantization_step
from .schema import schema_errors
from .rig import check_rig
from .values import (AnchorMesh, AnchorValues, check_anchor_values, check_finite,
                     check_triangles)

__all__ = ["AnchorMesh", "check_anchor", "anchor_mesh"]

ANCHOR = EXTENSION
_INDEX_TYPES = (UNSIGNED_BYTE, UNSIGNED_SHORT, UNSIGNED_INT)
#: The properties every profile has (checked when the profile itself is not valid).
_COMMON = tuple(f.key for f in ANCHOR_FIELDS if set(f.profiles) == set(PROFILES))


def anchor_mesh(ctx: Context, m: int, p: int) -> AnchorMesh:
    """Check anchor primitive ``p`` of mesh ``m`` once; cached per (m, p)."""
    key = ("anchor", m, p)
    if key in ctx.cache:
        return ctx.cache[key]
    result = AnchorMesh(None)
    ctx.cache[key] = result
    pointer = f"/meshes/{m}/primitives/{p}"
    prim = ctx.array("meshes")[m]["primitives"][p]
    mode = prim.get("mode", 4)
    if mode != 4:
        ctx.issues.add(Code.ANCHOR_MESH_NOT_TRIANGLES, f"the anchor primitive has mode {mode!r}; "
                       f"it must be TRIANGLES (4)", pointer=f"{pointer}/mode")
        return result
    attrs = prim.get("attributes", {})
    if "POSITION" not in attrs:
        ctx.issues.add(Code.ANCHOR_MESH_POSITION_INVALID, "the anchor primitive has no POSITION",
                       pointer=f"{pointer}/attributes")
        return result
    lay = ctx.accessor(attrs["POSITION"], f"{pointer}/attributes/POSITION")
    if lay is None:
        return result
    if not format_allowed(lay, "VEC3", [(FLOAT, False)]):
        ctx.issues.add(Code.ANCHOR_MESH_POSITION_INVALID, f"anchor POSITION is "
                       f"{describe_format(lay)}; it must be VEC3 FLOAT",
                       pointer=f"{pointer}/attributes/POSITION")
        return result
    vertices = ctx.floats(lay, f"{pointer} POSITION")
    if vertices is None or not check_finite(ctx, vertices, f"{pointer}/attributes/POSITION",
                                            "anchor mesh POSITION"):
        return result
    ipointer = f"{pointer}/indices"
    if prim.get("indices") is not None:
        ilay = ctx.accessor(prim["indices"], ipointer)
        if ilay is None:
            return result
        if ilay.gtype != "SCALAR" or ilay.component_type not in _INDEX_TYPES or ilay.normalized:
            ctx.issues.add(Code.ANCHOR_MESH_INDICES_INVALID, f"anchor indices are "
                           f"{describe_format(ilay)}; they must be SCALAR UNSIGNED_BYTE, "
                           f"UNSIGNED_SHORT or UNSIGNED_INT", pointer=ipointer)
            return result
        raw = ctx.read(ilay, f"{pointer} indices")
        if raw is None:
            return result
        idx = raw[:, 0].astype(np.int64)
        if len(idx) % 3:
            ctx.issues.add(Code.ANCHOR_MESH_INDICES_INVALID, f"{len(idx)} anchor indices, not a "
                           f"multiple of 3", pointer=ipointer)
            return result
        bad = np.flatnonzero(idx >= len(vertices))
        if bad.size:
            ctx.issues.add(Code.ANCHOR_MESH_INDICES_INVALID, f"{bad.size} anchor indices are out "
                           f"of range for {len(vertices)} vertices", pointer=ipointer,
                           count=int(bad.size),
                           examples=ctx.examples(bad, index=np.arange(len(idx)), value=idx))
            return result
        faces = idx.reshape(-1, 3)
    else:
        if len(vertices) % 3:
            ctx.issues.add(Code.ANCHOR_MESH_INDICES_INVALID, f"the anchor primitive is not indexed "
                           f"and has {len(vertices)} vertices, not a multiple of 3",
                           pointer=f"{pointer}/attributes/POSITION")
            return result
        faces = np.arange(len(vertices), dtype=np.int64).reshape(-1, 3)
    checked = check_triangles(ctx, TriangleMesh(vertices, faces), pointer)
    result.mesh, result.degenerate = checked.mesh, checked.degenerate
    result.diagonal, result.largest = checked.diagonal, checked.largest
    users = [n for n, node in enumerate(ctx.array("nodes"))
             if isinstance(node, dict) and node.get("mesh") == m]
    for n in users:
        if _hidden(ctx.array("nodes")[n]):
            continue   # spec §Animated anchor meshes: hidden with KHR_node_visibility
        ctx.issues.add(Code.ANCHOR_MESH_INSTANTIATED, f"node {n} instantiates the anchor mesh "
                       f"{m}; KHR-only viewers draw its triangles over the splats",
                       pointer=f"/nodes/{n}/mesh")
    if len(users) == 1:
        check_rig(ctx, m, p, users[0], len(vertices))
    if len(users) > 1:
        ctx.issues.add(Code.ANCHOR_MESH_MULTIPLE_INSTANCES, f"{len(users)} nodes ("
                       f"{', '.join(map(str, users))}) instantiate the anchor mesh {m}; at most "
                       f"one may (which instance drives the splats would be ambiguous)",
                       pointer=f"/nodes/{users[1]}/mesh")
    return result


def _index(ctx: Context, value: Any, size: int, what: str, pointer: str) -> int | None:
    if isinstance(value, int) and not isinstance(value, bool) and 0 <= value < size:
        return value
    ctx.issues.add(Code.UNRESOLVED_REFERENCE, f"{what} {value!r:.40} does not exist (there are "
                   f"{size})", pointer=pointer)
    return None


def check_anchor(ctx: Context, splat: SplatData, obj: Any, pointer: str) -> None:
    """Check the anchor extension object ``obj`` of ``splat`` (found at ``pointer``)."""
    errors = schema_errors(obj, pointer)
    for where, message in errors:
        ctx.issues.add(Code.ANCHOR_SCHEMA_VIOLATION, f"{ANCHOR}: {message}", pointer=where)
    if not isinstance(obj, dict):
        return
    bad_props = {where[len(pointer) + 1:].split("/")[0] for where, _ in errors if where != pointer}

    # -- the anchor mesh ------------------------------------------------------------
    mesh_info: AnchorMesh | None = None
    meshes = ctx.array("meshes")
    if "mesh" in obj and "mesh" not in bad_props:
        m = _index(ctx, obj["mesh"], len(meshes), "anchor mesh", f"{pointer}/mesh")
        if m is not None:
            prims = meshes[m].get("primitives", [])
            p_value = obj.get("primitive", 0)
            p = None
            if "primitive" not in bad_props:
                p = _index(ctx, p_value, len(prims), "anchor primitive", f"{pointer}/primitive")
            if m == splat.mesh:
                ctx.issues.add(Code.ANCHOR_MESH_SAME_AS_SPLAT, f"the anchor primitive is in mesh "
                               f"{m}, the splat primitive's own mesh", pointer=f"{pointer}/mesh")
            if p is not None:
                mesh_info = anchor_mesh(ctx, m, p)

    profile = obj.get("profile") if obj.get("profile") in PROFILES else None
    # version 1.2: faceCounts instead of faceIndex; local anchors derived from the rest pose
    counts = FACE_COUNTS.key in obj and "faceIndex" not in obj
    derived = profile == "local" and "barycentrics" not in obj
    face_key = FACE_COUNTS.key if counts else "faceIndex"
    props = list(gltf_required_keys(profile, counts=counts, derived=derived)) if profile \
        else [face_key] + [k for k in _COMMON if k != "faceIndex"]
    vertex_attributes = set(splat.attributes.values())

    # -- accessors --------------------------------------------------------------------
    layouts: dict[str, AccessorLayout] = {}
    for prop in props:
        if prop not in obj or prop in bad_props:
            continue
        ppointer = f"{pointer}/{prop}"
        lay = ctx.accessor(obj[prop], ppointer)
        if lay is None:
            continue
        spec = FIELDS_BY_KEY.get(prop, FACE_COUNTS)
        if not format_allowed(lay, spec.accessor, spec.formats):
            ctx.issues.add(Code.ANCHOR_ACCESSOR_FORMAT, f"{prop} is {describe_format(lay)}; see "
                           f"the spec's table of accessor component types", pointer=ppointer)
            continue
        if prop == FACE_COUNTS.key:
            faces = mesh_info.mesh.face_count if mesh_info and mesh_info.mesh else None
            if faces is not None and lay.count != faces:
                ctx.issues.add(Code.ANCHOR_FACE_COUNTS_COUNT, f"faceCounts has {lay.count} "
                               f"elements but the anchor mesh has {faces} triangles",
                               pointer=ppointer)
                continue
        elif splat.count is not None and lay.count != splat.count:
            ctx.issues.add(Code.ANCHOR_ACCESSOR_COUNT, f"{prop} has {lay.count} elements but the "
                           f"primitive has {splat.count} splats", pointer=ppointer)
            continue
        view = ctx.array("bufferViews")[lay.view]
        if view.get("target") is not None and lay.accessor not in vertex_attributes:
            ctx.issues.add(Code.ANCHOR_ACCESSOR_TARGET, f"bufferViews[{lay.view}] of {prop} sets "
                           f"target {view.get('target')}; anchor data are not vertex attributes",
                           pointer=ppointer)
        layouts[prop] = lay
    scale_accessor = splat.attributes.get(f"{KHR}:SCALE")
    if profile == "local" and "localScale" in layouts and scale_accessor is not None \
            and layouts["localScale"].accessor != scale_accessor:
        ctx.issues.add(Code.LOCAL_SCALE_NOT_SHARED, f"localScale uses accessor "
                       f"{layouts['localScale'].accessor}, not the SCALE accessor "
                       f"{scale_accessor}", pointer=f"{pointer}/localScale")
    if splat.count is None or (ctx.options.max_splats is not None
                               and splat.count > ctx.options.max_splats):
        return

    # -- values -----------------------------------------------------------------------
    arrays: dict[str, np.ndarray] = {}
    for prop, lay in layouts.items():
        if prop in ("faceIndex", FACE_COUNTS.key):
            raw = ctx.read(lay, f"{pointer}/{prop}")
            face = None if raw is None else raw[:, 0].astype(np.int64) if prop == "faceIndex" \
                else faces_from_counts(ctx, raw[:, 0], splat.count, f"{pointer}/{prop}")
            if face is not None:
                arrays["faceIndex"] = face
            continue
        arr = ctx.floats(lay, f"{pointer}/{prop}")
        if arr is not None and check_finite(ctx, arr, f"{pointer}/{prop}", prop):
            arrays[prop] = arr
    locations = {prop: f"{pointer}/{prop}" for prop in props}
    locations["faceIndex"] = f"{pointer}/{face_key}"
    if derived:
        locations.update({key: pointer for key in DERIVED_KEYS})
        arrays.update(derived_arrays(ctx, mesh_info, arrays.get("faceIndex"), splat.rest_pose(),
                                     f"{pointer}/{face_key}"))
    values = AnchorValues(profile, arrays, locations,
                          {prop: quantization_step(lay) for prop, lay in layouts.items()},
                          obj.get("deformation", "affine"))
    check_anchor_values(ctx, values, mesh_info, splat.rest_pose(), consistent=not errors)


def _hidden(node: dict) -> bool:
    """Whether ``node`` is hidden by ``KHR_node_visibility`` (``visible: false``)."""
    ext = (node.get("extensions") or {}).get(NODE_VISIBILITY)
    return isinstance(ext, dict) and ext.get("visible") is False
