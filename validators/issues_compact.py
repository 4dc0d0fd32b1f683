"""Catalogue rows of the compact anchor encodings (spec/README.md §Properties,
`faceCounts` and §Derived `local` anchors, version 1.2), in the format of :mod:`.issues_rows`.
Both or neither of ``faceIndex``/``faceCounts``, and derived anchors with some of
``normalOffset``, ``localRotation``, ``localScale`` present, are schema rules
(``ANCHOR_SCHEMA_VIOLATION``)."""
from __future__ import annotations

from gsverse_format.codes import Code
from gsverse_format.vocabulary import EXTENSION, KHR

from .issues_rows import Row

__all__ = ["COMPACT_ENTRIES"]

_G = "Anchor extension"
_EXT = "/meshes/{m}/primitives/{p}" + f"/extensions/{KHR}/extensions/{EXTENSION}"

COMPACT_ENTRIES: list[Row] = [
    (Code.ANCHOR_FACE_COUNTS_COUNT, "ERROR", _G, "The faceCounts accessor's count differs from "
     "the number of triangles of the anchor primitive (one count per triangle).",
     _EXT + "/faceCounts", "Write one count per anchor triangle, zeros included."),
    (Code.ANCHOR_FACE_COUNTS_SUM, "ERROR", _G, "The faceCounts values (summed in 64-bit "
     "integers) do not add up to the splat primitive's POSITION count, so the splats cannot "
     "be assigned to faces.", _EXT + "/faceCounts",
     "Store the splats grouped by face in face order and count every splat once."),
    (Code.ANCHOR_DERIVED_ON_DEGENERATE, "ERROR", _G, "A local primitive without barycentrics "
     "(derived anchors) has splats on a triangle degenerate at rest (a ≤ ε_deg ℓ²): its "
     "anchors cannot be derived (C_r is singular); readers refuse the asset.",
     _EXT + "/faceCounts", "Bind no splat to a degenerate triangle, or store explicit anchors."),
]
