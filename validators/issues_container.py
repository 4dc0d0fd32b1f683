"""Catalogue rows of the file and its glTF container: reading the file, the GLB chunks, the
JSON, buffers and URIs, accessors; and the validator's own failure (``INTERNAL_ERROR``). Rows
in the format of :mod:`.issues_rows`."""
from __future__ import annotations

from gsverse_format.codes import Code

from .issues_rows import Row

__all__ = ["CONTAINER_ENTRIES", "VALIDATOR_ENTRIES"]

_PRIM = "/meshes/{m}/primitives/{p}"

CONTAINER_ENTRIES: list[Row] = [
    (Code.IO_ERROR, "ERROR", "File", "The file does not exist, is a folder, or cannot be read.",
     "none", "Pass a readable .glb, .gltf or USD file.", {"fatal": True, "unreadable": True}),
    (Code.FILE_TYPE_UNSUPPORTED, "ERROR", "File", "The file name does not end in .glb, .gltf, "
     ".usda, .usdc, .usd or .usdz and the file does not start with the GLB magic.", "none",
     "Validate glTF and USD assets only (convert other formats with gsverse-convert).",
     {"fatal": True, "unreadable": True}),
    (Code.SIZE_LIMIT_EXCEEDED, "ERROR", "File", "The file plus its buffers exceed --max-bytes, "
     "or a count passes a README §Limits limit (a top-level array over 100,000 elements, a node "
     "graph over 100,000 node instances); checked before anything is allocated or expanded. "
     "(USD: the file itself.)", "none, /{array}, /nodes/{n} or /buffers/{i}/uri",
     "Raise --max-bytes if the asset is legitimately that large, or split it."),
    (Code.SPLAT_COUNT_LIMIT, "ERROR", "File", "A splat primitive declares more splats than "
     "--max-splats; its data are not read.", _PRIM + "/attributes/POSITION",
     "Raise --max-splats, or split the asset."),
    (Code.GLB_TRUNCATED, "ERROR", "GLB container", "The file is shorter than the 12-byte GLB "
     "header, than its length field, or a chunk header runs past the end.", "byte offset",
     "Re-export the file; it was cut short.", {"fatal": True}),
    (Code.GLB_BAD_MAGIC, "ERROR", "GLB container", "A .glb file does not start with the magic "
     "'glTF'.", "byte offset 0", "Make sure the file really is a GLB (a .gltf JSON file must be "
     "named .gltf).", {"fatal": True}),
    (Code.GLB_UNSUPPORTED_VERSION, "ERROR", "GLB container", "The GLB container version is not 2.",
     "byte offset 4", "Re-export as glTF 2.0 binary.", {"fatal": True}),
    (Code.GLB_LENGTH_MISMATCH, "ERROR", "GLB container", "The GLB length field is smaller than "
     "the file (trailing bytes).", "byte offset 8", "Strip the trailing bytes or fix the length "
     "field.", {"fatal": True}),
    (Code.GLB_CHUNK_TOO_LONG, "ERROR", "GLB container", "A chunk's length runs past the end of "
     "the file.", "byte offset of the chunk header", "Re-export the file.", {"fatal": True}),
    (Code.GLB_FIRST_CHUNK_NOT_JSON, "ERROR", "GLB container", "The GLB has no chunk, or its "
     "first chunk is not of type JSON.", "byte offset 12", "Write the JSON chunk first.",
     {"fatal": True}),
    (Code.GLB_CHUNK_UNALIGNED, "ERROR", "GLB container", "A chunk length is not a multiple of 4.",
     "byte offset of the chunk header", "Pad the JSON chunk with spaces and the BIN chunk with "
     "zeros to a multiple of 4 bytes."),
    (Code.GLB_UNKNOWN_CHUNK, "WARNING", "GLB container", "A chunk has a type other than JSON or "
     "BIN; it is ignored.", "byte offset of the chunk type", "Remove the chunk."),
    (Code.GLB_UNEXPECTED_CHUNK, "ERROR", "GLB container", "A JSON chunk that is not the first "
     "chunk, or a BIN chunk that is not the second; it is ignored.", "byte offset of the chunk "
     "type", "Keep exactly one JSON chunk followed by at most one BIN chunk."),
    (Code.JSON_NOT_UTF8, "ERROR", "JSON", "The glTF JSON is not valid UTF-8.", "none",
     "Write the JSON as UTF-8.", {"fatal": True}),
    (Code.JSON_INVALID, "ERROR", "JSON", "The glTF JSON does not parse, or its root is not an "
     "object.", "none or \"\" (the root)", "Write valid JSON.", {"fatal": True}),
    (Code.GLTF_SCHEMA_VIOLATION, "ERROR", "JSON", "A core glTF property has the wrong JSON type "
     "or an out-of-range value (for example a string byteOffset, 2.5 as an index, or a negative "
     "byteLength). Type errors stop validation; value errors are reported per object.",
     "the offending property", "Follow the glTF 2.0 JSON schema.", {"fatal": True}),
    (Code.ASSET_VERSION_UNSUPPORTED, "ERROR", "JSON", "asset or asset.version is missing, or the "
     "version is not 2.x.", "/asset/version", "Write \"asset\": {\"version\": \"2.0\"}."),
    (Code.UNSUPPORTED_REQUIRED_EXTENSION, "ERROR", "JSON", "extensionsRequired lists a "
     "compression extension (Draco, meshopt, KHR_gaussian_splatting_*) whose data this toolkit "
     "cannot decode; such assets cannot be checked or converted.", "/extensionsRequired/{i}",
     "Decompress the asset first."),
    (Code.UNRESOLVED_REFERENCE, "ERROR", "JSON", "An index (accessor, bufferView, buffer, mesh, "
     "primitive) is not an integer or points past the end of its array.", "the referencing "
     "property", "Fix the index."),
    (Code.EXTENSION_NOT_DECLARED, "ERROR", "JSON", "KHR_gaussian_splatting or "
     "GSVERSE_gaussian_splatting_mesh_anchor is used but not listed in extensionsUsed (the "
     "Khronos validator does not detect this for nested extensions).", "the extension object",
     "Add the extension's name to extensionsUsed."),
    (Code.ANCHOR_EXTENSION_REQUIRED, "ERROR", "JSON", "GSVERSE_gaussian_splatting_mesh_anchor is "
     "listed in extensionsRequired (the spec forbids it: the rest pose is a complete fallback, "
     "and loaders refuse assets with unknown required extensions).", "/extensionsRequired/{i}",
     "Remove it from extensionsRequired."),
    (Code.URI_SCHEME_REJECTED, "ERROR", "Buffers and URIs", "A buffer URI has a scheme other "
     "than data: (http:, file:, a drive letter, ...). Nothing is ever fetched.",
     "/buffers/{i}/uri", "Embed the buffer (GLB BIN chunk or data: URI) or use a relative path "
     "inside the asset's folder."),
    (Code.URI_ABSOLUTE_PATH, "ERROR", "Buffers and URIs", "A buffer URI is an absolute path "
     "(also percent-encoded, or //host).", "/buffers/{i}/uri", "Use a path relative to the "
     "asset's folder."),
    (Code.URI_OUTSIDE_FOLDER, "ERROR", "Buffers and URIs", "A relative buffer URI leaves the "
     "asset's folder ('..' segments, also percent-encoded, or a symbolic link pointing outside).",
     "/buffers/{i}/uri", "Move the buffer next to the asset."),
    (Code.URI_NOT_FOUND, "ERROR", "Buffers and URIs", "A relative buffer file does not exist.",
     "/buffers/{i}/uri", "Ship the buffer file with the asset."),
    (Code.URI_INVALID, "ERROR", "Buffers and URIs", "A URI is empty or holds a NUL byte, or a "
     "data: URI has no comma, is not base64, or does not decode.", "/buffers/{i}/uri",
     "Write a base64 data: URI (data:application/octet-stream;base64,...)."),
    (Code.DATA_URI_TOO_LARGE, "ERROR", "Buffers and URIs", "A data: URI decodes to more bytes "
     "than --max-data-uri-bytes (default 256 MiB; checked before parsing).", "/buffers/{i}/uri",
     "Store large buffers in a GLB, or raise the limit."),
    (Code.BUFFER_MISSING_DATA, "ERROR", "Buffers and URIs", "A buffer has no uri and is not "
     "buffer 0 of a GLB with a BIN chunk.", "/buffers/{i}", "Add the BIN chunk or a uri."),
    (Code.BUFFER_TOO_SHORT, "ERROR", "Buffers and URIs", "A buffer's data are shorter than its "
     "byteLength.", "/buffers/{i}", "Fix byteLength or the data."),
    (Code.BUFFER_VIEW_OUT_OF_BOUNDS, "ERROR", "Buffers and URIs", "A bufferView runs past the "
     "end of its buffer.", "/bufferViews/{i}", "Fix byteOffset/byteLength."),
    (Code.BUFFER_VIEW_STRIDE_INVALID, "ERROR", "Buffers and URIs", "byteStride is outside "
     "4..252, not a multiple of 4, smaller than an element of an accessor using the view, or not "
     "a multiple of its component size.", "/bufferViews/{i}/byteStride", "Use a stride that is "
     "a multiple of 4 and at least the element size."),
    (Code.ACCESSOR_INVALID, "ERROR", "Accessors", "Unknown type or componentType, normalized set "
     "on a FLOAT or UNSIGNED_INT accessor, or count < 1.", "/accessors/{i}/...", "Write a valid "
     "accessor."),
    (Code.ACCESSOR_UNSUPPORTED, "ERROR", "Accessors", "An accessor holding splat, anchor or "
     "anchor mesh data is sparse or has no bufferView (compressed or placeholder data). The "
     "spec forbids both for anchor accessors; for the rest pose and the anchor mesh they are "
     "valid glTF that this toolkit's readers refuse (spec §Accessor component types and "
     "dequantization).", "/accessors/{i}",
     "Store the data densely in a bufferView (decompress the asset)."),
    (Code.ACCESSOR_OUT_OF_BOUNDS, "ERROR", "Accessors", "byteOffset + byteStride × (count − 1) + "
     "element size exceeds the bufferView's byteLength.", "/accessors/{i}",
     "Fix count, byteOffset or the bufferView."),
    (Code.ACCESSOR_MISALIGNED, "ERROR", "Accessors", "accessor.byteOffset or "
     "bufferView.byteOffset + accessor.byteOffset is not a multiple of the component size, or a "
     "splat vertex attribute's offset or stride is not a multiple of 4.", "/accessors/{i}",
     "Align the data (the writer of this toolkit aligns every view to 4 bytes)."),
    (Code.NON_FINITE_VALUE, "ERROR", "Accessors", "NaN or infinity in splat data, anchor data, "
     "anchor mesh positions, or the rig of an animated anchor mesh (inverse bind matrices, "
     "morph target deltas, animation key times and values).", "the attribute or extension property", "Remove or repair the "
     "affected splats."),
]

VALIDATOR_ENTRIES: list[Row] = [
    (Code.INTERNAL_ERROR, "ERROR", "Validator", "A check failed unexpectedly: a bug in "
     "gsverse-validate, not necessarily in the asset. The other checks still ran.", "none",
     "Report it with the file."),
]
