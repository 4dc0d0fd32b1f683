"""Catalogue entry of the splat/mesh fit check (:func:`gsverse_format.fit.assess_fit`, run by
:func:`.values.check_anchor_values` for glTF and USD alike): (code, severity name, group,
trigger, pointer, fix), made into a :class:`.issues.CodeInfo` entry by :mod:`.issues`, with
the USD location in :data:`FIT_USD`."""
from __future__ import annotations

from gsverse_format.codes import Code
from gsverse_format.fit import MAX_SPLATS_JUDGED, MIN_EXTENT_RATIO, MIN_NEAR_SHARE, NEAR_FRACTION

__all__ = ["FIT_ENTRIES", "FIT_USD"]

FIT_ENTRIES: list[tuple[Code, str, str, str, str, str]] = [
    (Code.ANCHOR_MESH_MISFIT, "WARNING", "Anchor extension", "The anchor mesh does not fit its "
     f"splats: fewer than {100 * MIN_NEAR_SHARE:g} % of the splats' rest means lie within "
     f"{NEAR_FRACTION:g} × D of their anchor triangle (D: the anchor mesh's bounding-box "
     "diagonal), or the splats' extent (their 1st–99th percentile box) is below "
     f"{MIN_EXTENT_RATIO:g} × D, or few splats are near and a quarter or half turn makes the "
     "two boxes fit. The message gives the numbers and the likely cause (an offset, other "
     "units, another frame). Above "
     f"{MAX_SPLATS_JUDGED:,} splats an evenly spaced subset of that many is judged.",
     "/meshes/{m}/primitives/{p}/attributes/POSITION",
     "Convert the mesh into the splats' frame and units (or bind the splats to the mesh they "
     "were captured with), then re-bind."),
]

#: The USD location of each entry's finding, and its severity for foreign prims (None: the
#: catalogue's).
FIT_USD = {Code.ANCHOR_MESH_MISFIT: ("{prim}.positions", None)}
