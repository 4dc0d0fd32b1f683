"""The invalid assets of the conformance suite: valid assets edited to break one rule.

Every *invalid case* is a small valid asset (:func:`invalid_base_case`) whose JSON document or
binary chunk an edit changes so that it breaks one rule of ``spec/README.md`` that a plugin
must enforce before remapping; a plugin must refuse it. Each names the rule and the code
``gsverse-validate`` reports for it.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .case_tools import (RemapCase, case_rng, faces_from_counts, make_anchors, make_case,
                         random_barycentrics, rest_pose, tube_mesh)
from .glb import (BYTE, FLOAT, SHORT, UNSIGNED_SHORT, accessor_bytes, anchor_extension,
                  anchor_primitive, anchored_primitive, append_accessor, patch_accessor)

__all__ = ["InvalidCase", "invalid_cases", "invalid_base_case"]


@dataclass
class InvalidCase:
    """A valid asset (built from ``base``) edited by ``mutate`` to break ``rule``."""

    id: str
    description: str
    rule: str
    base: str
    mutate: Callable[[dict, bytes], tuple[dict, bytes]]
    validator_code: str | None = None
    tags: list[str] = field(default_factory=list)


def _m_face_out_of_range(doc, blob):
    e = anchor_extension(doc)
    face = accessor_bytes(doc, blob, e["faceIndex"])
    face[0] = len(accessor_bytes(doc, blob, anchor_primitive(doc)["indices"])) // 3
    return doc, patch_accessor(doc, blob, e["faceIndex"], face)


def _m_count_mismatch(doc, blob):
    doc["accessors"][anchor_extension(doc)["barycentrics"]]["count"] -= 1
    return doc, blob


def _m_not_triangles(doc, blob):
    anchor_primitive(doc)["mode"] = 1
    return doc, blob


def _m_set(key, value):
    def mutate(doc, blob):
        anchor_extension(doc)[key] = value
        return doc, blob
    return mutate


def _m_delete(key):
    def mutate(doc, blob):
        del anchor_extension(doc)[key]
        return doc, blob
    return mutate


def _m_mesh_out_of_range(doc, blob):
    anchor_extension(doc)["mesh"] = len(doc["meshes"])
    return doc, blob


def _m_bary_signed(doc, blob):
    e = anchor_extension(doc)
    b = accessor_bytes(doc, blob, e["barycentrics"]).astype(np.float64)
    e["barycentrics"], blob = append_accessor(doc, blob, np.round(b * 127), BYTE, "VEC2", True)
    return doc, blob


def _m_face_float(doc, blob):
    e = anchor_extension(doc)
    f = accessor_bytes(doc, blob, e["faceIndex"]).astype(np.float32)
    e["faceIndex"], blob = append_accessor(doc, blob, f, FLOAT, "SCALAR")
    return doc, blob


def _m_face_normalized(doc, blob):
    doc["accessors"][anchor_extension(doc)["faceIndex"]]["normalized"] = True
    return doc, blob


def _m_sparse(doc, blob):
    e = anchor_extension(doc)
    idx, blob = append_accessor(doc, blob, np.array([0], np.uint32), 5125, "SCALAR")
    val, blob = append_accessor(doc, blob, np.array([[0.25, 0.25]], np.float32), FLOAT, "VEC2")
    doc["accessors"][e["barycentrics"]]["sparse"] = {
        "count": 1,
        "indices": {"bufferView": doc["accessors"][idx]["bufferView"], "componentType": 5125},
        "values": {"bufferView": doc["accessors"][val]["bufferView"]}}
    return doc, blob


def _m_indices_out_of_range(doc, blob):
    prim = anchor_primitive(doc)
    idx = accessor_bytes(doc, blob, prim["indices"])
    idx[4] = doc["accessors"][prim["attributes"]["POSITION"]]["count"]
    return doc, patch_accessor(doc, blob, prim["indices"], idx)


def _m_index_count(doc, blob):
    doc["accessors"][anchor_primitive(doc)["indices"]]["count"] -= 1
    return doc, blob


def _m_position_short(doc, blob):
    prim = anchor_primitive(doc)
    pos = accessor_bytes(doc, blob, prim["attributes"]["POSITION"]).astype(np.float64)
    codes = np.round(np.clip(pos, -1, 1) * 32767)
    prim["attributes"]["POSITION"], blob = append_accessor(doc, blob, codes, SHORT, "VEC3", True)
    return doc, blob


def _m_offset_short(doc, blob):
    e = anchor_extension(doc)
    d = accessor_bytes(doc, blob, e["normalOffset"]).astype(np.float64)
    e["normalOffset"], blob = append_accessor(doc, blob, np.round(np.clip(d, -1, 1) * 32767),
                                              SHORT, "SCALAR", True)
    return doc, blob


def _m_rotation_vec3(doc, blob):
    e = anchor_extension(doc)
    q = accessor_bytes(doc, blob, e["localRotation"])[:, :3]
    e["localRotation"], blob = append_accessor(doc, blob, q, FLOAT, "VEC3")
    return doc, blob


def _m_out_of_bounds(doc, blob):
    acc = doc["accessors"][anchor_extension(doc)["barycentrics"]]
    acc["byteOffset"] = doc["bufferViews"][acc["bufferView"]]["byteLength"]
    return doc, blob


def _m_nan_offset(doc, blob):
    e = anchor_extension(doc)
    d = accessor_bytes(doc, blob, e["normalOffset"])
    d[len(d) // 2] = np.nan
    return doc, patch_accessor(doc, blob, e["normalOffset"], d)


def _m_inf_position(doc, blob):
    pos = anchor_primitive(doc)["attributes"]["POSITION"]
    acc = doc["accessors"][pos]
    bounds = (acc.get("min"), acc.get("max"))
    v = accessor_bytes(doc, blob, pos)
    v[3, 1] = np.inf
    blob = patch_accessor(doc, blob, pos, v)
    acc["min"], acc["max"] = bounds   # keep the JSON bounds finite
    return doc, blob


def _m_rho_u16(doc, blob):
    e = anchor_extension(doc)
    r = accessor_bytes(doc, blob, e["rho"]).astype(np.float64)
    e["rho"], blob = append_accessor(doc, blob, np.round(np.clip(r / 2, 0, 1) * 65535),
                                     UNSIGNED_SHORT, "SCALAR", True)
    return doc, blob


def _m_zero_rotation(doc, blob):
    e = anchor_extension(doc)
    q = accessor_bytes(doc, blob, e["localRotation"])
    q[len(q) // 2] = 0.0
    return doc, patch_accessor(doc, blob, e["localRotation"], q)


def _m_negative_scale(doc, blob):
    e = anchor_extension(doc)   # the base shares localScale with KHR_gaussian_splatting:SCALE
    s = accessor_bytes(doc, blob, e["localScale"])
    s[len(s) // 3, 1] = -s[len(s) // 3, 1]
    return doc, patch_accessor(doc, blob, e["localScale"], s)


def _m_rest_value(attribute: str, row: int, column: int, value: float):
    def mutate(doc, blob):
        index = anchored_primitive(doc)["attributes"][attribute]
        acc = doc["accessors"][index]
        bounds = (acc.get("min"), acc.get("max"))
        v = accessor_bytes(doc, blob, index)
        v[row, column] = value
        blob = patch_accessor(doc, blob, index, v)
        if bounds[0] is not None:
            acc["min"], acc["max"] = bounds   # keep the JSON bounds finite
        return doc, blob
    return mutate


def _m_splat_not_points(doc, blob):
    anchored_primitive(doc)["mode"] = 4
    return doc, blob


def _m_splat_mode_absent(doc, blob):
    del anchored_primitive(doc)["mode"]
    return doc, blob


def _m_anchor_mesh_instance_outside_scenes(doc, blob):
    m = anchor_extension(doc)["mesh"]
    doc["nodes"].append({"mesh": m, "name": "anchor mesh instance in the default scene"})
    doc["scenes"][doc.get("scene", 0)]["nodes"].append(len(doc["nodes"]) - 1)
    doc["nodes"].append({"mesh": m, "name": "anchor mesh instance in no scene"})
    return doc, blob


def _m_no_buffer_view(doc, blob):
    accessor = doc["accessors"][anchor_extension(doc)["barycentrics"]]
    del accessor["bufferView"]
    accessor.pop("byteOffset", None)
    return doc, blob


def _m_anchor_mesh_two_nodes(doc, blob):
    m = anchor_extension(doc)["mesh"]
    for name in ("anchor mesh instance 1", "anchor mesh instance 2"):
        doc["nodes"].append({"mesh": m, "name": name})
        doc["scenes"][doc.get("scene", 0)]["nodes"].append(len(doc["nodes"]) - 1)
    return doc, blob


def _m_counts_and_index(doc, blob):
    e = anchor_extension(doc)
    counts = accessor_bytes(doc, blob, e["faceCounts"]).astype(np.int64).ravel()
    e["faceIndex"], blob = append_accessor(doc, blob, faces_from_counts(counts), UNSIGNED_SHORT,
                                           "SCALAR")
    return doc, blob


def _m_counts_length(doc, blob):
    e = anchor_extension(doc)
    counts = accessor_bytes(doc, blob, e["faceCounts"]).astype(np.int64).ravel()
    # one count fewer than triangles, the last face's splats moved to the first face
    counts[0] += counts[-1]
    e["faceCounts"], blob = append_accessor(doc, blob, counts[:-1], UNSIGNED_SHORT, "SCALAR")
    return doc, blob


def _m_counts_sum(doc, blob):
    e = anchor_extension(doc)
    counts = accessor_bytes(doc, blob, e["faceCounts"]).copy()
    counts.ravel()[int(np.argmax(counts.ravel()))] += 1
    return doc, patch_accessor(doc, blob, e["faceCounts"], counts)


def _m_counts_float(doc, blob):
    e = anchor_extension(doc)
    counts = accessor_bytes(doc, blob, e["faceCounts"]).astype(np.float32)
    e["faceCounts"], blob = append_accessor(doc, blob, counts, FLOAT, "SCALAR")
    return doc, blob


def _m_derived_with_offset(doc, blob):
    e = anchor_extension(doc)
    count = doc["accessors"][anchored_primitive(doc)["attributes"]["POSITION"]]["count"]
    e["normalOffset"], blob = append_accessor(doc, blob, np.zeros(count), FLOAT, "SCALAR")
    return doc, blob


def _m_derived_on_degenerate(doc, blob):
    """Collapse corner 2 of the first face holding splats onto its corner 0 (rest mesh)."""
    e = anchor_extension(doc)
    counts = accessor_bytes(doc, blob, e["faceCounts"]).astype(np.int64).ravel()
    f = int(np.flatnonzero(counts)[0])
    prim = anchor_primitive(doc)
    idx = accessor_bytes(doc, blob, prim["indices"]).astype(np.int64).ravel()
    pos = accessor_bytes(doc, blob, prim["attributes"]["POSITION"]).copy()
    pos[idx[3 * f + 2]] = pos[idx[3 * f]]
    return doc, patch_accessor(doc, blob, prim["attributes"]["POSITION"], pos)


def _m_rest_rotation_zero(doc, blob):
    index = anchored_primitive(doc)["attributes"]["KHR_gaussian_splatting:ROTATION"]
    q = accessor_bytes(doc, blob, index)
    q[len(q) // 2] = 0
    return doc, patch_accessor(doc, blob, index, q)


def _m_rest_scale_negative(doc, blob):
    index = anchored_primitive(doc)["attributes"]["KHR_gaussian_splatting:SCALE"]
    s = accessor_bytes(doc, blob, index)
    s[len(s) // 3, 2] = -s[len(s) // 3, 2]
    return doc, patch_accessor(doc, blob, index, s)


def invalid_cases() -> list[InvalidCase]:
    """Assets a plugin must refuse, each breaking one rule of ``spec/README.md``."""
    spec = "spec/README.md"
    return [
        InvalidCase("invalid-face-index-out-of-range", "faceIndex of splat 0 equals the "
                    "triangle count F.", f"{spec} §The anchor mesh: every faceIndex value MUST "
                    "be < F", "local", _m_face_out_of_range,
                    "ANCHOR_FACE_OUT_OF_RANGE"),
        InvalidCase("invalid-anchor-count-mismatch", "The barycentrics accessor has one element "
                    "fewer than POSITION.", f"{spec} §Properties: every anchor accessor MUST have "
                    "count equal to the count of POSITION", "local", _m_count_mismatch,
                    "ANCHOR_ACCESSOR_COUNT"),
        InvalidCase("invalid-anchor-mesh-not-triangles", "The anchor primitive has mode 1 "
                    "(LINES).", f"{spec} §The anchor mesh: the anchor primitive MUST have mode "
                    "TRIANGLES (4)", "local", _m_not_triangles,
                    "ANCHOR_MESH_NOT_TRIANGLES"),
        InvalidCase("invalid-unknown-profile", "profile is \"global\".", f"{spec} §Properties: "
                    "profile is \"local\" or \"games\"", "local", _m_set("profile", "global"),
                    "ANCHOR_SCHEMA_VIOLATION"),
        InvalidCase("invalid-unknown-deformation", "deformation is \"elastic\".", f"{spec} "
                    "§Properties: deformation is \"affine\" or \"rigid\"", "local",
                    _m_set("deformation", "elastic"),
                    "ANCHOR_SCHEMA_VIOLATION"),
        InvalidCase("invalid-games-with-deformation", "A games primitive carries "
                    "\"deformation\": \"rigid\".", f"{spec} §Properties: deformation MUST NOT be "
                    "present with games", "games", _m_set("deformation", "rigid"),
                    "ANCHOR_SCHEMA_VIOLATION"),
        InvalidCase("invalid-local-missing-local-rotation", "A local primitive without "
                    "localRotation.", f"{spec} §Properties: localRotation is required with local",
                    "local", _m_delete("localRotation"),
                    "ANCHOR_SCHEMA_VIOLATION"),
        InvalidCase("invalid-games-missing-rho", "A games primitive without rho.", f"{spec} "
                    "§Properties: rho is required with games", "games", _m_delete("rho"),
                    "ANCHOR_SCHEMA_VIOLATION"),
        InvalidCase("invalid-anchor-mesh-index-out-of-range", "mesh points past the last mesh.",
                    f"{spec} §Properties: mesh is the index of a mesh", "local",
                    _m_mesh_out_of_range,
                    "UNRESOLVED_REFERENCE"),
        InvalidCase("invalid-anchor-primitive-index-out-of-range", "primitive is 5 while the "
                    "anchor mesh has one primitive.", f"{spec} §Properties: primitive is the "
                    "index of a primitive of that mesh", "local", _m_set("primitive", 5),
                    "UNRESOLVED_REFERENCE"),
        InvalidCase("invalid-barycentrics-signed-byte", "barycentrics stored as normalized "
                    "BYTE.", f"{spec} §Accessor component types: barycentrics are FLOAT, "
                    "normalized UNSIGNED_BYTE or normalized UNSIGNED_SHORT", "games",
                    _m_bary_signed,
                    "ANCHOR_ACCESSOR_FORMAT"),
        InvalidCase("invalid-face-index-float", "faceIndex stored as FLOAT.", f"{spec} "
                    "§Accessor component types: faceIndex is UNSIGNED_BYTE, UNSIGNED_SHORT or "
                    "UNSIGNED_INT, not normalized", "local", _m_face_float,
                    "ANCHOR_ACCESSOR_FORMAT"),
        InvalidCase("invalid-face-index-normalized", "faceIndex is a normalized UNSIGNED_BYTE.",
                    f"{spec} §Accessor component types: faceIndex is not normalized", "local",
                    _m_face_normalized,
                    "ANCHOR_ACCESSOR_FORMAT"),
        InvalidCase("invalid-normal-offset-quantized", "normalOffset stored as normalized "
                    "SHORT.", f"{spec} §Accessor component types: normalOffset is FLOAT",
                    "local", _m_offset_short,
                    "ANCHOR_ACCESSOR_FORMAT"),
        InvalidCase("invalid-rho-quantized", "rho stored as normalized UNSIGNED_SHORT.",
                    f"{spec} §Accessor component types: rho is FLOAT", "games", _m_rho_u16,
                    "ANCHOR_ACCESSOR_FORMAT"),
        InvalidCase("invalid-local-rotation-vec3", "localRotation is a VEC3 accessor.",
                    f"{spec} §Properties: localRotation is a VEC4 accessor", "local",
                    _m_rotation_vec3,
                    "ANCHOR_ACCESSOR_FORMAT"),
        InvalidCase("invalid-anchor-accessor-sparse", "The barycentrics accessor is sparse.",
                    f"{spec} §Properties: anchor accessors MUST NOT be sparse", "games",
                    _m_sparse,
                    "ACCESSOR_UNSUPPORTED"),
        InvalidCase("invalid-anchor-indices-out-of-range", "An index of the anchor primitive "
                    "equals its vertex count.", "glTF 2.0 §3.7.2.1: indices MUST be < the "
                    "vertex count", "local", _m_indices_out_of_range,
                    "ANCHOR_MESH_INDICES_INVALID"),
        InvalidCase("invalid-anchor-index-count", "The anchor primitive has 3F - 1 indices.",
                    f"{spec} §The anchor mesh: F is the index count divided by three "
                    "(TRIANGLES needs a multiple of 3)", "games", _m_index_count,
                    "ANCHOR_MESH_INDICES_INVALID"),
        InvalidCase("invalid-anchor-position-not-float", "The anchor POSITION is normalized "
                    "SHORT.", f"{spec} §The anchor mesh: POSITION of component type FLOAT",
                    "local", _m_position_short,
                    "ANCHOR_MESH_POSITION_INVALID"),
        InvalidCase("invalid-anchor-accessor-out-of-bounds", "The barycentrics accessor starts "
                    "at the end of its bufferView.", "glTF 2.0 §3.6.2.4: accessors MUST fit "
                    "their bufferView", "local", _m_out_of_bounds,
                    "ACCESSOR_OUT_OF_BOUNDS"),
        InvalidCase("invalid-non-finite-normal-offset", "One normalOffset value is NaN.",
                    "glTF 2.0 accessor data must be finite (Khronos glTF-Validator: "
                    "ACCESSOR_INVALID_FLOAT); a remap of NaN anchors has no finite output",
                    "local", _m_nan_offset, "NON_FINITE_VALUE"),
        InvalidCase("invalid-non-finite-anchor-position", "One anchor mesh vertex has an "
                    "infinite coordinate.", "glTF 2.0 accessor data must be finite (Khronos "
                    "glTF-Validator: ACCESSOR_INVALID_FLOAT); the triangles using it have no "
                    "frame", "games", _m_inf_position, "NON_FINITE_VALUE"),
        InvalidCase("invalid-local-rotation-zero", "The localRotation of one splat is (0, 0, 0, "
                    "0).", f"{spec} §Accessor component types and dequantization (Quaternions): a "
                    "localRotation of length zero (after dequantization) has no rotation; "
                    "readers MUST refuse the asset",
                    "local", _m_zero_rotation, "ROTATION_NOT_UNIT"),
        InvalidCase("invalid-local-scale-negative", "One component of one splat's localScale "
                    "(shared with KHR_gaussian_splatting:SCALE) is negative.", f"{spec} "
                    "§Accessor component types and dequantization (Scales): every localScale "
                    "component MUST be >= 0 after dequantization; readers MUST refuse an asset "
                    "with a negative one", "local", _m_negative_scale, "SCALE_NEGATIVE"),
        InvalidCase("invalid-non-finite-rest-position", "One splat's rest POSITION holds a NaN.",
                    f"{spec} §Properties: the rest pose (POSITION, KHR_gaussian_splatting:"
                    "ROTATION, :SCALE) MUST be finite; readers MUST refuse a non-finite value",
                    "local", _m_rest_value("POSITION", 5, 2, np.nan), "NON_FINITE_VALUE"),
        InvalidCase("invalid-non-finite-rest-rotation", "One splat's rest "
                    "KHR_gaussian_splatting:ROTATION holds an infinity.", f"{spec} §Properties: "
                    "the rest pose (POSITION, KHR_gaussian_splatting:ROTATION, :SCALE) MUST be "
                    "finite; readers MUST refuse a non-finite value", "local",
                    _m_rest_value("KHR_gaussian_splatting:ROTATION", 7, 0, np.inf),
                    "NON_FINITE_VALUE"),
        InvalidCase("invalid-non-finite-rest-scale", "One splat's rest "
                    "KHR_gaussian_splatting:SCALE holds an infinity (games: SCALE is not an "
                    "anchor accessor).", f"{spec} §Properties: the rest pose (POSITION, "
                    "KHR_gaussian_splatting:ROTATION, :SCALE) MUST be finite; readers MUST "
                    "refuse a non-finite value", "games",
                    _m_rest_value("KHR_gaussian_splatting:SCALE", 3, 1, np.inf),
                    "NON_FINITE_VALUE"),
        InvalidCase("invalid-splat-primitive-not-points", "The anchored splat primitive has mode "
                    "4 (TRIANGLES) and no indices; everything else is valid.", f"{spec} "
                    "§Where the extension object lives: the splat primitive MUST have mode "
                    "POINTS (0); readers MUST refuse an asset whose anchored primitive has "
                    "another mode", "local", _m_splat_not_points,
                    "KHR_PRIMITIVE_NOT_POINTS"),
        InvalidCase("invalid-splat-primitive-mode-absent", "The anchored splat primitive has no "
                    "mode, so glTF's default TRIANGLES (4); everything else is valid.", f"{spec} "
                    "§Where the extension object lives: a splat primitive without mode has mode "
                    "4; readers MUST refuse an anchored splat primitive whose mode is absent",
                    "local", _m_splat_mode_absent, "KHR_PRIMITIVE_NOT_POINTS"),
        InvalidCase("invalid-anchor-mesh-instance-outside-scenes", "Two nodes instantiate the "
                    "anchor mesh: one in the default scene, one that no scene lists.",
                    f"{spec} §The anchor mesh (which nodes count): every element of nodes counts "
                    "towards the instances, whichever scene lists it, or none", "local",
                    _m_anchor_mesh_instance_outside_scenes, "ANCHOR_MESH_MULTIPLE_INSTANCES"),
        InvalidCase("invalid-anchor-accessor-no-buffer-view", "The barycentrics accessor has "
                    "no bufferView (glTF reads it as all zeros).", f"{spec} §Accessors without "
                    "bufferView: anchor accessors MUST have a bufferView; readers MUST refuse an "
                    "asset whose anchor accessor lacks one", "games", _m_no_buffer_view,
                    "ACCESSOR_UNSUPPORTED"),
        InvalidCase("invalid-anchor-mesh-multiple-instances", "Two nodes instantiate the anchor "
                    "mesh.", f"{spec} §The anchor mesh: the anchor mesh MUST NOT be instantiated "
                    "by more than one node (which instance's skin or morph weights would drive "
                    "the splats is ambiguous); readers MUST refuse such an asset", "games",
                    _m_anchor_mesh_two_nodes, "ANCHOR_MESH_MULTIPLE_INSTANCES"),
        InvalidCase("invalid-face-index-and-face-counts", "A compact local primitive carries "
                    "both faceCounts and a faceIndex accessor.", f"{spec} §Properties: exactly "
                    "one of faceIndex and faceCounts MUST be present", "local-compact",
                    _m_counts_and_index, "ANCHOR_SCHEMA_VIOLATION"),
        InvalidCase("invalid-no-face-index-nor-counts", "A local primitive without faceIndex "
                    "and without faceCounts.", f"{spec} §Properties: exactly one of faceIndex "
                    "and faceCounts MUST be present", "local", _m_delete("faceIndex"),
                    "ANCHOR_SCHEMA_VIOLATION"),
        InvalidCase("invalid-face-counts-count", "faceCounts has one element fewer than the "
                    "anchor mesh has triangles (its sum still equals the splat count).",
                    f"{spec} §Properties: the count of faceCounts MUST equal the number of "
                    "triangles", "local-compact", _m_counts_length,
                    "ANCHOR_FACE_COUNTS_COUNT"),
        InvalidCase("invalid-face-counts-sum", "faceCounts sums to the splat count plus one.",
                    f"{spec} §Properties: the faceCounts values MUST sum to the POSITION count",
                    "games-compact", _m_counts_sum, "ANCHOR_FACE_COUNTS_SUM"),
        InvalidCase("invalid-face-counts-float", "faceCounts stored as FLOAT.", f"{spec} "
                    "§Accessor component types: faceCounts is UNSIGNED_BYTE, UNSIGNED_SHORT or "
                    "UNSIGNED_INT, not normalized", "local-compact", _m_counts_float,
                    "ANCHOR_ACCESSOR_FORMAT"),
        InvalidCase("invalid-derived-with-normal-offset", "A local primitive without "
                    "barycentrics (derived anchors) carries a normalOffset.", f"{spec} "
                    "§Properties: without barycentrics, normalOffset, localRotation and "
                    "localScale MUST be absent", "local-compact", _m_derived_with_offset,
                    "ANCHOR_SCHEMA_VIOLATION"),
        InvalidCase("invalid-derived-on-degenerate-face", "Derived local anchors: a face that "
                    "holds splats is degenerate at rest (its corner 2 moved onto corner 0).",
                    f"{spec} §Derived local anchors: a derived splat on a face degenerate at "
                    "rest is invalid; readers MUST refuse the asset", "local-compact",
                    _m_derived_on_degenerate, "ANCHOR_DERIVED_ON_DEGENERATE"),
        InvalidCase("invalid-derived-zero-rest-rotation", "Derived local anchors: one splat's "
                    "rest KHR_gaussian_splatting:ROTATION is (0, 0, 0, 0), so its derived "
                    "localRotation has length zero.", f"{spec} §Derived local anchors: derived "
                    "anchors are used exactly as stored ones, and a localRotation of length zero "
                    "makes the asset invalid", "local-compact", _m_rest_rotation_zero,
                    "ROTATION_NOT_UNIT"),
        InvalidCase("invalid-derived-negative-rest-scale", "Derived local anchors: one "
                    "component of one splat's rest KHR_gaussian_splatting:SCALE (its derived "
                    "localScale) is negative.", f"{spec} §Derived local anchors: derived anchors "
                    "are used exactly as stored ones, and a negative localScale component makes "
                    "the asset invalid", "local-compact", _m_rest_scale_negative,
                    "SCALE_NEGATIVE"),
    ]


def invalid_base_case(kind: str) -> RemapCase:
    """The small valid asset an invalid case is derived from (``local`` or ``games``, written
    with explicit anchors; ``local-compact`` or ``games-compact``: with compact ones;
    ``local-spz``: compact, the rest pose SPZ-compressed)."""
    rng = case_rng(f"invalid-base-{kind}")
    kind, _, encoding = kind.partition("-")
    compress = "spz" if encoding == "spz" else None
    encoding = "compact" if compress else encoding
    mesh = tube_mesh()
    face = faces_from_counts(np.arange(mesh.face_count) % 3 == 0)
    law = "affine" if kind == "local" else None
    anchors = make_anchors(kind, law, mesh, face, random_barycentrics(rng, len(face)), rng)
    return make_case(f"invalid-base-{kind}", "base of the invalid cases", [], mesh, anchors,
                     [rest_pose(mesh)], rng, 0, encoding=encoding or "explicit",
                     compress=compress)
