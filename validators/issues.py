"""Findings, severities and the catalogue of every issue code ``gsverse-validate`` reports.

Reporting follows the Khronos glTF-Validator: every finding has a stable ``code``, a
``severity`` (error, warning, info, hint), a location (a JSON pointer into the glTF JSON, or a
byte ``offset`` into a GLB file) and a one-line ``message``. Findings about many splats or
triangles at once are aggregated: one finding with a ``count`` and a few ``examples``.

:data:`CATALOGUE` gives every code of :class:`gsverse_format.codes.Code` its severity, group,
trigger, location and fix (with :mod:`.issues_rig`); ``spec/validation.md`` is generated from it.
"""
from __future__ import annotations

import enum
from dataclasses import dataclass, field, replace
from typing import Any

from gsverse_format.codes import Code
from .issues_compact import COMPACT_ENTRIES as _COMPACT, RIG_ENTRIES as _RIG
from .issues_fit import FIT_ENTRIES as _FIT, FIT_USD as _FIT_USD
from .issues_input import INPUT_ENTRIES as _INPUT
from gsverse_format.vocabulary import EXTENSION, KHR

__all__ = ["Severity", "CodeInfo", "CATALOGUE", "Finding", "Issues", "TOLERANCES",
           "parse_severity"]


class Severity(enum.IntEnum):
    """Severities, numbered as in the Khronos glTF-Validator (0 is the most severe)."""

    ERROR = 0
    WARNING = 1
    INFO = 2
    HINT = 3

    @property
    def label(self) -> str:
        return self.name.lower()


def parse_severity(text: str) -> Severity | None:
    """``error``/``warning``/``info``/``hint`` (or 0..3) -> :class:`Severity`; ``ignore`` ->
    ``None``. Raises ``ValueError`` for anything else."""
    word = str(text).strip().lower()
    if word in ("ignore", "off", "none"):
        return None
    aliases = {"information": "info", "err": "error", "warn": "warning"}
    word = aliases.get(word, word)
    for sev in Severity:
        if word in (sev.label, str(int(sev))):
            return sev
    raise ValueError(f"unknown severity {text!r}; use error, warning, info, hint or ignore")


@dataclass(frozen=True)
class CodeInfo:
    """One catalogue entry: what triggers the code, where it points, how to fix the asset."""

    code: Code
    severity: Severity
    group: str
    trigger: str
    pointer: str
    fix: str
    fatal: bool = False  # validation of the file stops after it
    unreadable: bool = False  # the file could not be validated at all (exit status 2)
    #: The default severity for foreign USD prims (no GsVerse API schema), when it differs.
    foreign_severity: Severity | None = None
    #: Where the code points in a USD file, for codes shared with glTF ("" if not reported).
    usd: str = ""


#: Numerical tolerances used by the checks (documented in ``spec/validation.md``).
TOLERANCES: dict[str, tuple[float, str]] = {
    "unit_quaternion": (1e-5, "| ‖q‖ − 1 | allowed for FLOAT quaternions (ROTATION, "
                              "localRotation); normalized-integer quaternions are allowed one "
                              "quantization step more (1/127 for BYTE, 1/32767 for SHORT)"),
    "simplex": (1e-5, "how far below 0 a barycentric weight b0 = 1 − b1 − b2, b1 or b2 of a "
                      "`games` splat may lie; normalized-integer barycentrics are allowed one "
                      "quantization step more (1/255 or 1/65535)"),
    "local_far": (1.0, "a `local` splat whose smallest barycentric weight is below −1 has its "
                       "foot point farther outside its triangle than the triangle's own "
                       "height over that edge"),
    "sliver": (1e-3, "a regular triangle is a sliver when its doubled area a ≤ 1e-3 · ℓ² "
                     "(smallest height ≤ 0.1 % of the longest edge)"),
    "rest_mean": (1e-5, "spec §Rest-pose consistency: |Δμ| ≤ 1e-5 · D + 8 ε₃₂ L, D the "
                        "diagonal of the anchor mesh's bounding box, L its largest absolute "
                        "coordinate, ε₃₂ = 2⁻²³ (float32 rounding far from the origin)"),
    "rest_covariance": (1e-4, "spec §Rest-pose consistency: ‖ΔΣ‖_F ≤ 1e-4 · ‖Σ‖_F, plus an "
                              "absolute floor of (1e-7 · D)² for covariances below float32 "
                              "resolution"),
}


def _c(code: Code, severity: Severity, group: str, trigger: str, pointer: str, fix: str,
       **kw: Any) -> CodeInfo:
    return CodeInfo(code, severity, group, trigger, pointer, fix, **kw)


E, W, I, H = Severity.ERROR, Severity.WARNING, Severity.INFO, Severity.HINT
_PRIM = "/meshes/{m}/primitives/{p}"
_EXT = _PRIM + f"/extensions/{KHR}/extensions/{EXTENSION}"

_ENTRIES = [
    # -- file ------------------------------------------------------------------------
    _c(Code.IO_ERROR, E, "File", "The file does not exist, is a folder, or cannot be read.",
       "none", "Pass a readable .glb, .gltf or USD file.", fatal=True, unreadable=True),
    _c(Code.FILE_TYPE_UNSUPPORTED, E, "File", "The file name does not end in .glb, .gltf, .usda, "
       ".usdc, .usd or .usdz and the file does not start with the GLB magic.", "none",
       "Validate glTF and USD assets only (convert other formats with gsverse-convert).",
       fatal=True, unreadable=True),
    _c(Code.SIZE_LIMIT_EXCEEDED, E, "File", "The file plus its buffers exceed --max-bytes, or "
       "a count passes a README §Limits limit (a top-level array over 100,000 elements, a node "
       "graph over 100,000 node instances); checked before anything is allocated or expanded. "
       "(USD: the file itself.)", "none, /{array}, /nodes/{n} or /buffers/{i}/uri",
       "Raise --max-bytes if the asset is legitimately that large, or split it."),
    _c(Code.SPLAT_COUNT_LIMIT, E, "File", "A splat primitive declares more splats than "
       "--max-splats; its data are not read.", _PRIM + "/attributes/POSITION",
       "Raise --max-splats, or split the asset."),
    # -- GLB -------------------------------------------------------------------------
    _c(Code.GLB_TRUNCATED, E, "GLB container", "The file is shorter than the 12-byte GLB header, "
       "than its length field, or a chunk header runs past the end.", "byte offset",
       "Re-export the file; it was cut short.", fatal=True),
    _c(Code.GLB_BAD_MAGIC, E, "GLB container", "A .glb file does not start with the magic "
       "'glTF'.", "byte offset 0", "Make sure the file really is a GLB (a .gltf JSON file "
       "must be named .gltf).", fatal=True),
    _c(Code.GLB_UNSUPPORTED_VERSION, E, "GLB container", "The GLB container version is not 2.",
       "byte offset 4", "Re-export as glTF 2.0 binary.", fatal=True),
    _c(Code.GLB_LENGTH_MISMATCH, E, "GLB container", "The GLB length field is smaller than the "
       "file (trailing bytes).", "byte offset 8", "Strip the trailing bytes or fix the "
       "length field.", fatal=True),
    _c(Code.GLB_CHUNK_TOO_LONG, E, "GLB container", "A chunk's length runs past the end of the "
       "file.", "byte offset of the chunk header", "Re-export the file.", fatal=True),
    _c(Code.GLB_FIRST_CHUNK_NOT_JSON, E, "GLB container", "The GLB has no chunk, or its first "
       "chunk is not of type JSON.", "byte offset 12", "Write the JSON chunk first.",
       fatal=True),
    _c(Code.GLB_CHUNK_UNALIGNED, E, "GLB container", "A chunk length is not a multiple of 4.",
       "byte offset of the chunk header", "Pad the JSON chunk with spaces and the BIN chunk "
       "with zeros to a multiple of 4 bytes."),
    _c(Code.GLB_UNKNOWN_CHUNK, W, "GLB container", "A chunk has a type other than JSON or BIN; "
       "it is ignored.", "byte offset of the chunk type", "Remove the chunk."),
    _c(Code.GLB_UNEXPECTED_CHUNK, E, "GLB container", "A JSON chunk that is not the first chunk, "
       "or a BIN chunk that is not the second; it is ignored.",
       "byte offset of the chunk type", "Keep exactly one JSON chunk followed by at most one "
       "BIN chunk."),
    # -- JSON ------------------------------------------------------------------------
    _c(Code.JSON_NOT_UTF8, E, "JSON", "The glTF JSON is not valid UTF-8.", "none",
       "Write the JSON as UTF-8.", fatal=True),
    _c(Code.JSON_INVALID, E, "JSON", "The glTF JSON does not parse, or its root is not an "
       "object.", "none or \"\" (the root)", "Write valid JSON.", fatal=True),
    _c(Code.GLTF_SCHEMA_VIOLATION, E, "JSON", "A core glTF property has the wrong JSON type or an "
       "out-of-range value (for example a string byteOffset, 2.5 as an index, or a negative "
       "byteLength). Type errors stop validation; value errors are reported per object.",
       "the offending property", "Follow the glTF 2.0 JSON schema.", fatal=True),
    _c(Code.ASSET_VERSION_UNSUPPORTED, E, "JSON", "asset or asset.version is missing, or the "
       "version is not 2.x.", "/asset/version", "Write \"asset\": {\"version\": \"2.0\"}."),
    _c(Code.UNSUPPORTED_REQUIRED_EXTENSION, E, "JSON", "extensionsRequired lists a compression "
       "extension (Draco, meshopt, KHR_gaussian_splatting_*) whose data this toolkit cannot "
       "decode; such assets cannot be checked or converted.", "/extensionsRequired/{i}",
       "Decompress the asset first."),
    _c(Code.UNRESOLVED_REFERENCE, E, "JSON", "An index (accessor, bufferView, buffer, mesh, "
       "primitive) is not an integer or points past the end of its array.",
       "the referencing property", "Fix the index."),
    _c(Code.EXTENSION_NOT_DECLARED, E, "JSON", "KHR_gaussian_splatting or "
       "GSVERSE_gaussian_splatting_mesh_anchor is used but not listed in extensionsUsed "
       "(the Khronos validator does not detect this for nested extensions).",
       "the extension object", "Add the extension's name to extensionsUsed."),
    _c(Code.ANCHOR_EXTENSION_REQUIRED, E, "JSON", "GSVERSE_gaussian_splatting_mesh_anchor is "
       "listed in extensionsRequired (the spec forbids it: the rest pose is a complete "
       "fallback, and loaders refuse assets with unknown required extensions).",
       "/extensionsRequired/{i}", "Remove it from extensionsRequired."),
    # -- buffers ---------------------------------------------------------------------
    _c(Code.URI_SCHEME_REJECTED, E, "Buffers and URIs", "A buffer URI has a scheme other than "
       "data: (http:, file:, a drive letter, ...). Nothing is ever fetched.",
       "/buffers/{i}/uri", "Embed the buffer (GLB BIN chunk or data: URI) or use a relative "
       "path inside the asset's folder."),
    _c(Code.URI_ABSOLUTE_PATH, E, "Buffers and URIs", "A buffer URI is an absolute path (also "
       "percent-encoded, or //host).", "/buffers/{i}/uri", "Use a path relative to the "
       "asset's folder."),
    _c(Code.URI_OUTSIDE_FOLDER, E, "Buffers and URIs", "A relative buffer URI leaves the asset's "
       "folder ('..' segments, also percent-encoded, or a symbolic link pointing outside).",
       "/buffers/{i}/uri", "Move the buffer next to the asset."),
    _c(Code.URI_NOT_FOUND, E, "Buffers and URIs", "A relative buffer file does not exist.",
       "/buffers/{i}/uri", "Ship the buffer file with the asset."),
    _c(Code.URI_INVALID, E, "Buffers and URIs", "A URI is empty or holds a NUL byte, or a data: "
       "URI has no comma, is not base64, or does not decode.", "/buffers/{i}/uri",
       "Write a base64 data: URI (data:application/octet-stream;base64,...)."),
    _c(Code.DATA_URI_TOO_LARGE, E, "Buffers and URIs", "A data: URI decodes to more bytes than "
       "--max-data-uri-bytes (default 256 MiB; checked before parsing).", "/buffers/{i}/uri",
       "Store large buffers in a GLB, or raise the limit."),
    _c(Code.BUFFER_MISSING_DATA, E, "Buffers and URIs", "A buffer has no uri and is not buffer 0 "
       "of a GLB with a BIN chunk.", "/buffers/{i}", "Add the BIN chunk or a uri."),
    _c(Code.BUFFER_TOO_SHORT, E, "Buffers and URIs", "A buffer's data are shorter than its "
       "byteLength.", "/buffers/{i}", "Fix byteLength or the data."),
    _c(Code.BUFFER_VIEW_OUT_OF_BOUNDS, E, "Buffers and URIs", "A bufferView runs past the end of "
       "its buffer.", "/bufferViews/{i}", "Fix byteOffset/byteLength."),
    _c(Code.BUFFER_VIEW_STRIDE_INVALID, E, "Buffers and URIs", "byteStride is outside 4..252, "
       "not a multiple of 4, smaller than an element of an accessor using the view, or not a "
       "multiple of its component size.", "/bufferViews/{i}/byteStride",
       "Use a stride that is a multiple of 4 and at least the element size."),
    # -- accessors -------------------------------------------------------------------
    _c(Code.ACCESSOR_INVALID, E, "Accessors", "Unknown type or componentType, normalized set on "
       "a FLOAT or UNSIGNED_INT accessor, or count < 1.", "/accessors/{i}/...",
       "Write a valid accessor."),
    _c(Code.ACCESSOR_UNSUPPORTED, E, "Accessors", "An accessor holding splat, anchor or anchor "
       "mesh data is sparse or has no bufferView (compressed or placeholder data), which "
       "this toolkit cannot read.", "/accessors/{i}", "Store the data densely in a "
       "bufferView (decompress the asset)."),
    _c(Code.ACCESSOR_OUT_OF_BOUNDS, E, "Accessors", "byteOffset + byteStride × (count − 1) + "
       "element size exceeds the bufferView's byteLength.", "/accessors/{i}",
       "Fix count, byteOffset or the bufferView."),
    _c(Code.ACCESSOR_MISALIGNED, E, "Accessors", "accessor.byteOffset or bufferView.byteOffset + "
       "accessor.byteOffset is not a multiple of the component size, or a splat vertex "
       "attribute's offset or stride is not a multiple of 4.", "/accessors/{i}",
       "Align the data (the writer of this toolkit aligns every view to 4 bytes)."),
    _c(Code.NON_FINITE_VALUE, E, "Accessors", "NaN or infinity in splat data, anchor data or "
       "anchor mesh positions.", "the attribute or extension property",
       "Remove or repair the affected splats."),
    # -- KHR_gaussian_splatting ---------------------------------------------------------
    _c(Code.KHR_NO_SPLATS, W, "KHR_gaussian_splatting", "The file has no primitive with the "
       "KHR_gaussian_splatting extension.", "none", "Check that the right file was passed."),
    _c(Code.KHR_PRIMITIVE_NOT_POINTS, E, "KHR_gaussian_splatting", "A primitive with the "
       "extension does not have mode POINTS (0).", _PRIM + "/mode", "Set \"mode\": 0."),
    _c(Code.KHR_PROPERTY_MISSING, E, "KHR_gaussian_splatting", "The extension object lacks a "
       "required property (kernel, colorSpace).", _PRIM + "/extensions/KHR_gaussian_splatting",
       "Add it (kernel \"ellipse\", colorSpace \"srgb_rec709_display\" or "
       "\"lin_rec709_display\")."),
    _c(Code.KHR_PROPERTY_INVALID, E, "KHR_gaussian_splatting", "The extension object, its "
       "extensions member, or kernel/colorSpace/projection/sortingMethod has the wrong JSON "
       "type.", _PRIM + "/extensions/KHR_gaussian_splatting/...", "Use an object and strings."),
    _c(Code.KHR_PROPERTY_UNKNOWN_VALUE, W, "KHR_gaussian_splatting", "kernel, colorSpace, "
       "projection or sortingMethod has a value the base extension does not define (another "
       "extension may define it; viewers fall back to the defaults).",
       _PRIM + "/extensions/KHR_gaussian_splatting/{property}", "Use a defined value, or "
       "declare the extension that defines it."),
    _c(Code.KHR_ATTRIBUTE_MISSING, E, "KHR_gaussian_splatting", "POSITION, "
       "KHR_gaussian_splatting:ROTATION, :SCALE, :OPACITY or :SH_DEGREE_0_COEF_0 is missing.",
       _PRIM + "/attributes", "Write every required attribute."),
    _c(Code.KHR_ATTRIBUTE_FORMAT, E, "KHR_gaussian_splatting", "A splat attribute's accessor "
       "type or component type is not allowed: POSITION FLOAT VEC3 (or the "
       "KHR_mesh_quantization types); ROTATION VEC4 FLOAT or BYTE/SHORT normalized; SCALE VEC3 "
       "FLOAT or UNSIGNED_BYTE/UNSIGNED_SHORT (normalized or not); OPACITY SCALAR FLOAT or "
       "UNSIGNED_BYTE/UNSIGNED_SHORT normalized; SH VEC3 FLOAT.", _PRIM + "/attributes/{name}",
       "Store the attribute in an allowed format."),
    _c(Code.KHR_UNKNOWN_SEMANTIC, E, "KHR_gaussian_splatting", "An attribute named "
       "KHR_gaussian_splatting:* is not ROTATION, SCALE, OPACITY or SH_DEGREE_l_COEF_n with "
       "l ≤ 3 and n ≤ 2l.", _PRIM + "/attributes/{name}", "Rename or remove the attribute."),
    _c(Code.KHR_SH_INCOMPLETE, E, "KHR_gaussian_splatting", "An SH degree is partially defined, "
       "or a degree is present while a lower one is missing.", _PRIM + "/attributes",
       "Write all 2l + 1 coefficients of every degree up to the highest."),
    _c(Code.ATTRIBUTE_COUNT_MISMATCH, E, "KHR_gaussian_splatting", "The attributes of one "
       "primitive have different counts.", _PRIM + "/attributes/{name}",
       "Give every attribute one element per splat."),
    _c(Code.ROTATION_NOT_UNIT, E, "KHR_gaussian_splatting", "A rotation quaternion "
       "(KHR_gaussian_splatting:ROTATION or localRotation) is not of unit length within the "
       "tolerance, or is zero.", _PRIM + "/attributes/KHR_gaussian_splatting:ROTATION or "
       + _EXT + "/localRotation", "Normalize the quaternions before writing."),
    _c(Code.SCALE_NEGATIVE, E, "KHR_gaussian_splatting", "A scale (KHR_gaussian_splatting:SCALE "
       "or localScale) is negative. Scales are linear standard deviations, never logs.",
       _PRIM + "/attributes/KHR_gaussian_splatting:SCALE or " + _EXT + "/localScale",
       "Store exp() of 3DGS log-scales."),
    _c(Code.OPACITY_OUT_OF_RANGE, E, "KHR_gaussian_splatting", "An opacity is outside [0, 1]. "
       "Opacities are linear, after the sigmoid.", _PRIM + "/attributes/"
       "KHR_gaussian_splatting:OPACITY", "Store sigmoid() of 3DGS opacity logits."),
    # -- anchor extension ----------------------------------------------------------------
    _c(Code.ANCHOR_SCHEMA_VIOLATION, E, "Anchor extension", "The extension object violates its "
       "JSON Schema: a required property is missing (mesh, profile, faceIndex, barycentrics; "
       "normalOffset, localRotation, localScale for local; rho for games), a property has "
       "the wrong type or value, or deformation is present with the games profile.",
       _EXT + " or " + _EXT + "/{property}", "Follow spec/schema/primitive.KHR_gaussian_"
       "splatting.GSVERSE_gaussian_splatting_mesh_anchor.schema.json."),
    _c(Code.ANCHOR_EXTENSION_MISPLACED, E, "Anchor extension", "The anchor extension object is "
       "placed directly in primitive.extensions instead of inside "
       "primitive.extensions.KHR_gaussian_splatting.extensions, where readers look for it.",
       _PRIM + "/extensions/GSVERSE_gaussian_splatting_mesh_anchor",
       "Move it into the KHR_gaussian_splatting extension object's extensions."),
    _c(Code.ANCHOR_MESH_SAME_AS_SPLAT, E, "Anchor extension", "The anchor primitive is in the "
       "same glTF mesh as the splat primitive (some KHR loaders reject such meshes).",
       _EXT + "/mesh", "Put the anchor triangles in a mesh of their own."),
    _c(Code.ANCHOR_MESH_NOT_TRIANGLES, E, "Anchor mesh", "The anchor primitive's mode is not "
       "TRIANGLES (4).", "/meshes/{m}/primitives/{p}/mode", "Store the anchor mesh as "
       "TRIANGLES."),
    _c(Code.ANCHOR_MESH_POSITION_INVALID, E, "Anchor mesh", "The anchor primitive has no "
       "POSITION, or it is not FLOAT VEC3.", "/meshes/{m}/primitives/{p}/attributes",
       "Store FLOAT VEC3 positions."),
    _c(Code.ANCHOR_MESH_INDICES_INVALID, E, "Anchor mesh", "The anchor indices are not "
       "SCALAR UNSIGNED_BYTE/SHORT/INT (not normalized), their count is not a multiple of 3, "
       "an index is out of range, or a non-indexed vertex count is not a multiple of 3.",
       "/meshes/{m}/primitives/{p}/indices", "Write valid triangle indices."),
    _c(Code.ANCHOR_MESH_INSTANTIATED, W, "Anchor mesh", "A node not hidden by "
       "KHR_node_visibility instantiates the anchor mesh: viewers draw it over the splats.",
       "/nodes/{n}/mesh", "Remove the mesh from the node, or hide it with KHR_node_visibility."),
    _c(Code.ANCHOR_MESH_MULTIPLE_INSTANCES, E, "Anchor mesh", "More than one node instantiates "
       "the anchor mesh (the spec says MUST NOT): each instance may carry its own skin or morph "
       "weights, so which one drives the splats is ambiguous; readers refuse the asset.",
       "/nodes/{n}/mesh", "Instantiate the anchor mesh with at most one node (preferably none)."),
    _c(Code.ANCHOR_MESH_NOT_MANIFOLD, I, "Anchor mesh", "The anchor mesh is not a closed "
       "2-manifold (after merging equal vertices): valid, but soft bodies and colliders need one.",
       "/meshes/{m}/primitives/{p}", "Convert with --watertight when physics needs it."),
    _c(Code.MESH_DEGENERATE_TRIANGLES, W, "Anchor mesh", "Triangles of the anchor mesh are "
       "degenerate at rest by the spec's rule (a ≤ ε_deg ℓ², ε_deg = 1e-6); count and "
       "examples. (Splats bound to them are ANCHOR_BOUND_TO_DEGENERATE.)",
       "/meshes/{m}/primitives/{p}", "Remove or repair them; binders never use them."),
    _c(Code.MESH_SLIVER_TRIANGLES, I, "Anchor mesh", "Regular triangles that are nearly "
       "degenerate (a ≤ 1e-3 ℓ²): barycentric and affine remaps amplify noise on them.",
       "/meshes/{m}/primitives/{p}", "Remesh or decimate the anchor mesh."),
    _c(Code.MESH_DUPLICATE_TRIANGLES, W, "Anchor mesh", "Triangles with the same three corner "
       "positions as an earlier triangle (in any order); count and example pairs.",
       "/meshes/{m}/primitives/{p}", "Remove duplicate faces (the nearest triangle becomes "
       "ambiguous)."),
    _c(Code.ANCHOR_ACCESSOR_FORMAT, E, "Anchor extension", "An anchor accessor's type or component "
       "type differs from the spec's table (faceIndex SCALAR unsigned integer; barycentrics "
       "VEC2 FLOAT or UNSIGNED_BYTE/SHORT normalized; normalOffset SCALAR FLOAT; "
       "localRotation VEC4 FLOAT or BYTE/SHORT normalized; localScale VEC3 as SCALE; rho "
       "SCALAR FLOAT).", _EXT + "/{property}", "Store the property in an allowed format."),
    _c(Code.ANCHOR_ACCESSOR_COUNT, E, "Anchor extension", "An anchor accessor's count differs "
       "from the splat primitive's POSITION count.", _EXT + "/{property}",
       "Write one anchor element per splat."),
    _c(Code.ANCHOR_ACCESSOR_TARGET, W, "Anchor extension", "The bufferView of an anchor accessor "
       "(that is not also a vertex attribute of the primitive) sets target (the spec says "
       "SHOULD NOT: the data are not vertex attributes).", _EXT + "/{property}",
       "Drop target from the bufferView."),
    _c(Code.ANCHOR_FACE_OUT_OF_RANGE, E, "Anchor extension", "A faceIndex is not less than the "
       "anchor primitive's triangle count; count and examples.", _EXT + "/faceIndex",
       "Bind every splat to an existing triangle."),
    _c(Code.ANCHOR_BOUND_TO_DEGENERATE, E, "Anchor extension", "Splats are bound to triangles "
       "that are degenerate at rest (writers MUST NOT do this); count and examples.",
       _EXT + "/faceIndex", "Re-bind those splats to regular triangles."),
    _c(Code.GAMES_BARYCENTRICS_OUTSIDE_SIMPLEX, E, "Anchor extension", "A games splat's "
       "barycentrics (b1, b2, b0 = 1 − b1 − b2) are not all ≥ 0 within the tolerance "
       "(GaMeS weights are normalized, so they MUST lie in the triangle).",
       _EXT + "/barycentrics", "Re-export the GaMeS weights (softmax-normalized α)."),
    _c(Code.LOCAL_BARYCENTRICS_FAR, I, "Anchor extension", "A local splat's foot point lies far "
       "outside its triangle: its smallest barycentric weight is below −1. The spec allows "
       "weights outside the simplex (the foot of a splat nearest to an edge or corner), so "
       "this is information only: such splats sit far from the surface relative to their "
       "triangle and follow its deformation with a long lever arm.", _EXT + "/barycentrics",
       "Usually none; check for floaters far from the mesh."),
    _c(Code.LOCAL_SCALE_NOT_SHARED, H, "Anchor extension", "localScale does not reference the "
       "accessor of KHR_gaussian_splatting:SCALE (writers SHOULD share it).",
       _EXT + "/localScale", "Reference the SCALE accessor to save space."),
    _c(Code.GAMES_RHO_NEGATIVE, W, "Anchor extension", "A games splat has ρ < 0: every scale "
       "collapses to the GaMeS floor ε = 1e-8.", _EXT + "/rho", "Check the export of ρ."),
    _c(Code.ANCHOR_NOT_SORTED, H, "Anchor extension", "The splats of an anchored primitive are "
       "not sorted by faceIndex (writers SHOULD sort: about 2× faster per-frame remap).",
       _EXT + "/faceIndex", "Sort the splats by face (gsverse-convert does by default)."),
    # -- rest pose ---------------------------------------------------------------------
    _c(Code.REST_POSE_MEAN_MISMATCH, E, "Rest pose", "The remap at the rest anchor mesh does not "
       "reproduce a stored POSITION within |Δμ| ≤ 1e-5 · D + 8 ε₃₂ L; count and the worst splats. "
       "Checked only when the splat and anchor data are otherwise valid.",
       _PRIM + "/attributes/POSITION", "Re-bind the splats, or store the remapped rest pose."),
    _c(Code.REST_POSE_COVARIANCE_MISMATCH, E, "Rest pose", "The remap at the rest anchor mesh does "
       "not reproduce a stored covariance R diag(s)² Rᵀ within ‖ΔΣ‖_F ≤ 1e-4 ‖Σ‖_F; count and "
       "the worst splats. Checked only when the splat and anchor data are otherwise valid.",
       _PRIM + "/attributes/KHR_gaussian_splatting:ROTATION",
       "Re-bind the splats, or store the remapped rest pose."),
    # -- USD -------------------------------------------------------------------------
    _c(Code.USD_SUPPORT_MISSING, E, "USD", "A USD file was given but usd-core (the pxr modules) is "
       "not installed.", "none", "pip install 'gsverse-format[usd]'.", fatal=True,
       unreadable=True),
    _c(Code.USD_UNREADABLE, E, "USD", "The file cannot be opened as a USD stage: not USD, "
       "truncated or corrupt (a crash or memory exhaustion of the USD library while reading "
       "is caught and reported here).", "none", "Re-export the file.", fatal=True,
       unreadable=True),
    _c(Code.USD_LAYER_OUTSIDE_FOLDER, E, "USD", "A sublayer, reference, payload or value "
       "clip (of the root layer or of a layer it brings in) is a URI with a scheme, an absolute "
       "path, or a relative path leaving the file's folder. The stage is not composed: nothing "
       "outside the folder is ever opened.", "none", "Flatten the stage (usdcat --flatten) or "
       "move the layers next to the file.", fatal=True),
    _c(Code.USD_TYPE_MISMATCH, E, "USD", "A property has another type than spec/usd.md declares "
       "(for example float[] gsverse:anchor:faceIndices, or a non-array rest-pose attribute).",
       "{prim}.{property} or {mesh}.{property}", "Author the declared type (spec/usd.md "
       "§The schemas)."),
    _c(Code.USD_UP_AXIS_INVALID, E, "USD", "The stage's upAxis is neither Y nor Z.", "\"\" (the "
       "root layer)", "Author upAxis = \"Y\"."),
    _c(Code.USD_UP_AXIS_MISSING, E, "USD", "The stage does not author upAxis (writers MUST "
       "author \"Y\"; readers assume Y).", "\"\" (the root layer)", "Author upAxis = \"Y\"."),
    _c(Code.USD_UP_AXIS_CONVERTED, W, "USD", "The stage is Z-up; readers rotate it into +Y up.",
       "\"\" (the root layer)", "Write +Y-up stages (glTF's frame)."),
    _c(Code.USD_METERS_PER_UNIT_INVALID, E, "USD", "metersPerUnit is not a positive finite "
       "number.", "\"\" (the root layer)", "Author metersPerUnit = 1."),
    _c(Code.USD_METERS_PER_UNIT_MISSING, E, "USD", "The stage does not author metersPerUnit "
       "(writers MUST author 1; readers assume metres, not USD's centimetre fallback).",
       "\"\" (the root layer)", "Author metersPerUnit = 1."),
    _c(Code.USD_UNITS_CONVERTED, W, "USD", "metersPerUnit is not 1; readers scale the data to "
       "metres.", "\"\" (the root layer)", "Write stages in metres."),
    _c(Code.USD_DEFAULT_PRIM_MISSING, E, "USD", "The stage has no valid defaultPrim.",
       "\"\" (the root layer)", "Author defaultPrim naming the root Xform."),
    _c(Code.USD_DEFAULT_PRIM_NOT_XFORM, E, "USD", "The defaultPrim is not an Xform.",
       "the defaultPrim", "Make the root prim an Xform."),
    _c(Code.USD_OUTSIDE_DEFAULT_PRIM, E, "USD", "A splat prim or anchor Mesh is not a "
       "descendant of the defaultPrim (references to the file would miss it).",
       "{prim} or {mesh}", "Move it under the defaultPrim."),
    _c(Code.USD_NESTED_GPRIM, E, "USD", "A splat prim or anchor Mesh is nested under another "
       "Gprim (USD forbids nested Gprims).", "{prim} or {mesh}", "Make both children of an "
       "Xform."),
    _c(Code.USD_PROPERTY_MISSING, E, "USD", "An anchored prim lacks a rest-pose attribute or an "
       "attribute its profile requires, a prim with a GsVerse API schema lacks "
       "gsverse:colorSpace, or the anchor Mesh lacks points or topology.",
       "{prim}.{property} or {mesh}.{property}", "Author the property's default value."),
    _c(Code.USD_PROPERTY_EXCLUDED, E, "USD", "An anchor attribute the profile excludes is "
       "authored (for example gsverse:anchor:rho with the local profile).",
       "{prim}.{property}", "Remove it."),
    _c(Code.USD_LENGTH_MISMATCH, E, "USD", "An array of an anchored prim does not have one "
       "element per particle (N·K SH coefficients), or faceVertexIndices is not 3 per face.",
       "{prim}.{property} or {mesh}.faceVertexIndices", "Write one element per particle."),
    _c(Code.USD_SH_DEGREE_INVALID, E, "USD", "radiance:sphericalHarmonicsDegree of an anchored "
       "prim is outside 0..3.", "{prim}.radiance:sphericalHarmonicsDegree",
       "Author a degree in 0..3."),
    _c(Code.USD_SH_DEGREE_MISSING, E, "USD", "radiance:sphericalHarmonicsDegree is not authored "
       "(its fallback 3 makes DC-only data too short for renderers).",
       "{prim}.radiance:sphericalHarmonicsDegree", "Always author the degree.",
       foreign_severity=W),
    _c(Code.USD_PROFILE_INVALID, E, "USD", "gsverse:anchor:profile of an anchored prim is "
       "missing or neither local nor games.", "{prim}.gsverse:anchor:profile",
       "Author \"local\" or \"games\"."),
    _c(Code.USD_DEFORMATION_INVALID, E, "USD", "gsverse:anchor:deformation is neither affine nor "
       "rigid.", "{prim}.gsverse:anchor:deformation", "Author \"affine\" or \"rigid\"."),
    _c(Code.USD_MESH_TARGET_INVALID, E, "USD", "gsverse:anchor:mesh does not have exactly one "
       "target, or the target is not a Mesh prim.", "{prim}.gsverse:anchor:mesh",
       "Target the anchor Mesh."),
    _c(Code.USD_MESH_HOLES, E, "USD", "The anchor Mesh authors holeIndices (anchor triangles "
       "cannot be holes).", "{mesh}.holeIndices", "Remove the faces instead."),
    _c(Code.USD_BOTH_APIS, E, "USD", "A prim applies both GsVerseMeshAnchorAPI and "
       "GsVerseColorSpaceAPI (the first includes the second).", "{prim}",
       "Apply GsVerseMeshAnchorAPI only."),
    _c(Code.USD_CUSTOM_PROPERTY, E, "USD", "A gsverse: property is authored as custom (it must "
       "be the schema's property, custom = false).", "{prim}.{property}",
       "Author it without the custom keyword."),
    _c(Code.USD_NOT_UNIFORM, E, "USD", "A gsverse: attribute is not uniform.",
       "{prim}.{property}", "Author it as uniform."),
    _c(Code.USD_TIME_SAMPLED, E, "USD", "opacities, SH, gsverse: attributes or the anchor "
       "topology have time samples (only positions, orientations, scales, extent and the "
       "anchor points may be animated).", "{prim}.{property} or {mesh}.{property}",
       "Remove the time samples."),
    _c(Code.USD_NO_REST_POSE, E, "USD", "A rest-pose attribute has time samples but no default "
       "value.", "{prim}.{property}", "Author the rest pose as the default value."),
    _c(Code.USD_TIME_CODES_MISSING, E, "USD", "The stage has baked animation but does not author "
       "startTimeCode, endTimeCode or timeCodesPerSecond.", "\"\" (the root layer)",
       "Author the three time metadata."),
    _c(Code.USD_SORTING_MODE, E, "USD", "sortingModeHint is not authored as cameraDistance "
       "(KHR's sortingMethod; USD's fallback is zDepth).", "{prim}.sortingModeHint",
       "Author sortingModeHint = \"cameraDistance\".", foreign_severity=W),
    _c(Code.USD_PROJECTION_MODE, W, "USD", "projectionModeHint is not authored (SHOULD be "
       "perspective).", "{prim}.projectionModeHint",
       "Author projectionModeHint = \"perspective\"."),
    _c(Code.USD_HALF_PRECISION, E, "USD", "A half-precision rest-pose attribute (positionsh, "
       "...) is authored; writers use the float ones.", "{prim}.{property}",
       "Author the float attribute.", foreign_severity=W),
    _c(Code.USD_EXTENT_MISSING, E, "USD", "A splat prim or the anchor Mesh does not author "
       "extent.", "{prim}.extent or {mesh}.extent", "Author the bounding box of the "
       "positions.", foreign_severity=W),
    _c(Code.USD_EXTENT_INVALID, E, "USD", "A splat prim's extent does not contain every "
       "position.", "{prim}.extent", "Recompute the extent.", foreign_severity=W),
    _c(Code.USD_XFORM_OPS, W, "USD", "A splat prim or anchor Mesh authors xformOps (splat prims "
       "should carry none; anchoring ignores the Mesh's).", "{prim} or {mesh}",
       "Bake the transform into the data."),
    _c(Code.USD_COLOR_SPACE_API_IGNORED, W, "USD", "A splat prim authors UsdColorSpaceAPI "
       "colorSpace:name, which splat readers ignore (gsverse:colorSpace holds the KHR colour "
       "space).", "{prim}", "Author gsverse:colorSpace instead."),
    _c(Code.USD_LOCAL_SCALES_REDUNDANT, H, "USD", "gsverse:anchor:localScales equals scales "
       "(writers SHOULD NOT author it then).", "{prim}.gsverse:anchor:localScales",
       "Remove it: readers fall back to scales."),
    _c(Code.USD_MESH_PURPOSE, W, "USD", "The anchor Mesh's purpose is not guide (renderers "
       "would draw it over the splats).", "{mesh}.purpose", "Author purpose = \"guide\"."),
    _c(Code.USD_MESH_SUBDIVISION, W, "USD", "The anchor Mesh's subdivisionScheme is not none "
       "(the fallback catmullClark smooths the triangles away).",
       "{mesh}.subdivisionScheme", "Author subdivisionScheme = \"none\"."),
    _c(Code.USD_MESH_ORIENTATION, W, "USD", "The anchor Mesh's orientation is not rightHanded "
       "(ignored for anchoring).", "{mesh}.orientation", "Author rightHanded."),
    _c(Code.USD_PLAIN_SPLATS, I, "USD", "A ParticleField3DGaussianSplat prim has no GsVerse API "
       "schema (foreign data): it is read with colour space srgb_rec709_display, and the "
       "writer rules give warnings, not errors, for it.", "{prim}",
       "None for foreign data; writers of this format apply GsVerseColorSpaceAPI."),
    _c(Code.USD_PARTICLE_FIELD_SKIPPED, W, "USD", "A ParticleField prim that is not a "
       "ParticleField3DGaussianSplat (another kernel or radiance model) has no "
       "KHR_gaussian_splatting equivalent and is skipped.", "the prim",
       "Convert it to 3D Gaussian splats first."),
    _c(Code.USD_EMPTY_PRIM, W, "USD", "A splat prim has no particles (no positions) and is "
       "skipped.", "{prim}", "Remove the prim."),
    _c(Code.USD_REPLACED_BY_DEFAULT, W, "USD", "An array of a foreign splat prim is shorter than "
       "required (or the SH degree negative) and is replaced by the schema's default, as USD "
       "renderers do.", "{prim}.{property}", "Write one element per particle."),
    _c(Code.USD_TRUNCATED, W, "USD", "An array of a foreign splat prim is longer than required, "
       "or its SH degree above 3, and is truncated.", "{prim}.{property}",
       "Write one element per particle and SH degree 3 at most."),
    _c(Code.USD_VALIDATOR_ERROR, E, "USD", "An OpenUSD validator (pxr.UsdValidation, all "
       "registered validators) reports an error; the message names it.",
       "the prim or property it names, or \"\"", "Follow the named validator's rule."),
    _c(Code.USD_VALIDATOR_WARNING, W, "USD", "An OpenUSD validator reports a warning; the "
       "message names it.", "the prim or property it names, or \"\"",
       "Follow the named validator's rule."),
    # -- validator -------------------------------------------------------------------
    _c(Code.INTERNAL_ERROR, E, "Validator", "A check failed unexpectedly: a bug in "
       "gsverse-validate, not necessarily in the asset. The other checks still ran.", "none",
       "Report it with the file."),
] + [_c(c, Severity[s], g, t, p, f) for c, s, g, t, p, f in _RIG + _COMPACT + _FIT + _INPUT]

#: Where the codes shared with glTF point in USD files ({prim}: the splat prim, {mesh}: its
#: anchor Mesh), and the severity of the value checks for foreign USD prims, whose readers
#: normalize orientations, make scales positive and clamp opacities (spec/usd.md §Foreign data).
_USD_SHARED = {
    Code.IO_ERROR: ("none", None),
    Code.SIZE_LIMIT_EXCEEDED: ("none", None),
    Code.SPLAT_COUNT_LIMIT: ("{prim}.positions", None),
    Code.NON_FINITE_VALUE: ("{prim}.{property} or {mesh}.points", None),
    Code.ROTATION_NOT_UNIT: ("{prim}.orientations or {prim}.gsverse:anchor:localOrientations", W),
    Code.SCALE_NEGATIVE: ("{prim}.scales or {prim}.gsverse:anchor:localScales", W),
    Code.OPACITY_OUT_OF_RANGE: ("{prim}.opacities", W),
    Code.ANCHOR_MESH_NOT_TRIANGLES: ("{mesh}.faceVertexCounts", None),
    Code.ANCHOR_MESH_INDICES_INVALID: ("{mesh}.faceVertexIndices", None),
    Code.MESH_DEGENERATE_TRIANGLES: ("{mesh}", None),
    Code.MESH_SLIVER_TRIANGLES: ("{mesh}", None),
    Code.MESH_DUPLICATE_TRIANGLES: ("{mesh}", None),
    Code.ANCHOR_MESH_NOT_MANIFOLD: ("{mesh}", None),
    Code.ANCHOR_FACE_OUT_OF_RANGE: ("{prim}.gsverse:anchor:faceIndices", None),
    Code.ANCHOR_BOUND_TO_DEGENERATE: ("{prim}.gsverse:anchor:faceIndices", None),
    Code.ANCHOR_NOT_SORTED: ("{prim}.gsverse:anchor:faceIndices", None),
    Code.GAMES_BARYCENTRICS_OUTSIDE_SIMPLEX: ("{prim}.gsverse:anchor:barycentrics", None),
    Code.LOCAL_BARYCENTRICS_FAR: ("{prim}.gsverse:anchor:barycentrics", None),
    Code.GAMES_RHO_NEGATIVE: ("{prim}.gsverse:anchor:rho", None),
    Code.REST_POSE_MEAN_MISMATCH: ("{prim}.positions", None),
    Code.REST_POSE_COVARIANCE_MISMATCH: ("{prim}.orientations", None),
    Code.INTERNAL_ERROR: ("none", None), **_FIT_USD}
_ENTRIES = [replace(e, usd=_USD_SHARED[e.code][0], foreign_severity=_USD_SHARED[e.code][1])
            if e.code in _USD_SHARED else replace(e, usd=e.pointer) if e.group == "USD" else e
            for e in _ENTRIES]

#: Every code, in catalogue order.
CATALOGUE: dict[Code, CodeInfo] = {entry.code: entry for entry in _ENTRIES}
assert len(CATALOGUE) == len(_ENTRIES), "duplicate issue code"


@dataclass
class Finding:
    """One reported issue. ``count``/``examples`` are set for aggregated per-element issues."""

    code: Code
    severity: Severity
    message: str
    pointer: str | None = None
    offset: int | None = None
    count: int | None = None
    examples: list[dict] | None = None

    def to_json(self, location_key: str = "pointer") -> dict:
        """The Khronos-style message object; ``location_key`` names the location member
        (``pointer`` for JSON pointers, ``usdPath`` for USD paths)."""
        out: dict[str, Any] = {"code": str(self.code), "severity": self.severity.label,
                               "message": self.message}
        for key, value in ((location_key, self.pointer), ("offset", self.offset),
                           ("count", self.count)):
            if value is not None:
                out[key] = value
        if self.examples:
            out["examples"] = self.examples
        return out


@dataclass
class Issues:
    """Collects the findings of one file, applying severity overrides and the issue cap.

    ``overrides`` maps a code to its new severity, or to ``None`` to ignore it.
    """

    overrides: dict[Code, Severity | None] = field(default_factory=dict)
    max_issues: int | None = None
    findings: list[Finding] = field(default_factory=list)
    truncated: bool = False
    unreadable: bool = False
    #: Set while checking a foreign USD prim: codes with a ``foreign_severity`` default to it.
    foreign: bool = False

    def add(self, code: Code, message: str, *, pointer: str | None = None,
            offset: int | None = None, count: int | None = None,
            examples: list[dict] | None = None) -> None:
        """Record a finding of ``code`` (its severity: an override, else the catalogue's)."""
        info = CATALOGUE.get(code)
        if info is None:  # a code outside the catalogue is a bug of the validator itself
            message = f"[{code}] {message}"
            info = CATALOGUE[Code.INTERNAL_ERROR]
        code = info.code
        if info.unreadable:
            self.unreadable = True
        default = info.foreign_severity if self.foreign and info.foreign_severity is not None \
            else info.severity
        severity = self.overrides[code] if code in self.overrides else default
        if severity is None:
            return
        if self.max_issues is not None and len(self.findings) >= self.max_issues:
            self.truncated = True
            return
        self.findings.append(Finding(code, Severity(severity), message, pointer, offset, count,
                                     examples))

    def codes(self) -> set[Code]:
        return {f.code for f in self.findings}

    def count(self, severity: Severity) -> int:
        return sum(1 for f in self.findings if f.severity == severity)
