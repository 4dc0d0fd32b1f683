"""Catalogue rows of the SPZ-compressed rest pose (``KHR_gaussian_splatting_compression_spz_2``,
spec/README.md §SPZ-compressed rest pose, version 1.2), in the format of :mod:`.issues_rows`.
Limits on what a stream may decode to are ``SIZE_LIMIT_EXCEEDED`` (README §Limits,
``MAX_SPZ_AMPLIFICATION``)."""
from __future__ import annotations

from gsverse_format.codes import Code
from gsverse_format.vocabulary import KHR, SPZ_EXTENSION

from .issues_rows import Row

__all__ = ["SPZ_ENTRIES"]

_G = "SPZ compression"
_PRIM = "/meshes/{m}/primitives/{p}"
_EXT = _PRIM + f"/extensions/{KHR}/extensions/{SPZ_EXTENSION}"

SPZ_ENTRIES: list[Row] = [
    (Code.SPZ_STREAM_INVALID, "ERROR", _G, "The buffer view of a compressed primitive does not "
     "hold one whole gzip member with an SPZ stream of version 2 or 3 of exactly the length its "
     "splats need: broken or truncated gzip, data after the member, no NGSP magic, another "
     "version (4 is zstd), extension records (flag bit 1), or a stream longer or shorter than "
     "its header's splats need (inflation stops at the bytes the declared count needs).",
     _EXT + "/bufferView", "Write one gzip member of a version 3 SPZ stream (gsverse-convert "
     "--compress spz) and point the extension's bufferView at it."),
    (Code.SPZ_COUNT_MISMATCH, "ERROR", _G, "The stream's splat count differs from the count of "
     "the primitive's placeholder accessors, or the placeholders' counts differ among "
     "themselves.", _PRIM + "/attributes", "Give every placeholder accessor the stream's splat "
     "count."),
    (Code.SPZ_SH_MISMATCH, "ERROR", _G, "The stream's SH degree differs from the degrees of "
     "the primitive's SH_DEGREE_l_COEF_n placeholders (they must be exactly degrees 0 to the "
     "stream's).", _PRIM + "/attributes", "Declare one placeholder per SH coefficient of the "
     "stream's degree."),
    (Code.SPZ_BUFFER_VIEW_INVALID, "ERROR", _G, "The extension object is not an object with a "
     "bufferView index in range.", _EXT, "Point bufferView at the buffer view holding the "
     "stream."),
    (Code.SPZ_EXPLICIT_ANCHORS, "ERROR", _G, "A compressed primitive carries stored anchors "
     "(explicit local, or games): they fix the rest pose to their remap within 1e-5 of the "
     "anchor mesh's diagonal, which SPZ's quantization exceeds, so writers must not compress "
     "it.", _PRIM + f"/extensions/{KHR}/extensions/GSVERSE_gaussian_splatting_mesh_anchor",
     "Write compact (derived) local anchors with the compressed rest pose, or leave the rest "
     "pose uncompressed."),
]
