"""Catalogue row of the splat/mesh fit check (:func:`gsverse_format.fit.assess_fit`, run by
:func:`.values.check_anchor_values` for glTF and USD alike), in the format of
:mod:`.issues_rows`, with the USD location in :data:`FIT_USD`."""
from __future__ import annotations

from gsverse_format.codes import Code
from gsverse_format.fit import (AROUND_FRACTION, MAX_SPLATS_JUDGED, MIN_AROUND_NEAR_SHARE,
                                MIN_EXTENT_RATIO, MIN_NEAR_SHARE, MIN_SPAN_RATIO, NEAR_FRACTION)

from .issues_rows import Row, UsdLocation

__all__ = ["FIT_ENTRIES", "FIT_USD"]

FIT_ENTRIES: list[Row] = [
    (Code.ANCHOR_MESH_MISFIT, "WARNING", "Anchor extension", "The anchor mesh does not fit its "
     f"splats: fewer than {100 * MIN_NEAR_SHARE:g} % of the splats' rest means lie within "
     f"{NEAR_FRACTION:g} × D of their anchor triangle (D: the anchor mesh's bounding-box "
     "diagonal), or the splats' extent (their 1st–99th percentile box) is below "
     f"{MIN_EXTENT_RATIO:g} × D, or few splats are near and a quarter or half turn makes the "
     f"two boxes fit, or the splats span less than {MIN_SPAN_RATIO:g} × D (the mesh is much "
     f"larger than the object), or fewer than {100 * MIN_AROUND_NEAR_SHARE:g} % of the splats "
     f"inside the mesh's box grown by {AROUND_FRACTION:g} × D lie near the mesh (an unrelated "
     "mesh under the splats). The message gives the numbers and the likely cause (an offset, other "
     "units, another frame). Above "
     f"{MAX_SPLATS_JUDGED:,} splats an evenly spaced subset of that many is judged.",
     "/meshes/{m}/primitives/{p}/attributes/POSITION",
     "Convert the mesh into the splats' frame and units (or bind the splats to the mesh they "
     "were captured with), then re-bind."),
]

#: The USD location of each entry's finding, and its severity for foreign prims (None: the
#: catalogue's).
FIT_USD: dict[Code, UsdLocation] = {Code.ANCHOR_MESH_MISFIT: ("{prim}.positions", None)}
