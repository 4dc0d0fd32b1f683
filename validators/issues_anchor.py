"""Catalogue rows of the anchor extension object, the anchor mesh and the rest pose (spec
§Properties, §The anchor mesh, §Rest-pose consistency); the compact encodings of version 1.2
are in :mod:`.issues_compact`, the animated anchor mesh in :mod:`.issues_rig`. Rows in the
format of :mod:`.issues_rows`."""
from __future__ import annotations

from gsverse_format.codes import Code
from gsverse_format.vocabulary import EXTENSION, KHR

from .issues_rows import Row

__all__ = ["ANCHOR_ENTRIES"]

_PRIM = "/meshes/{m}/primitives/{p}"
_EXT = _PRIM + f"/extensions/{KHR}/extensions/{EXTENSION}"

ANCHOR_ENTRIES: list[Row] = [
    (Code.ANCHOR_SCHEMA_VIOLATION, "ERROR", "Anchor extension", "The extension object violates "
     "its JSON Schema: a required property is missing, or present where another excludes it "
     "(always mesh and profile, and exactly one of faceIndex and faceCounts; games: "
     "barycentrics and rho; local: barycentrics, normalOffset, localRotation and localScale, "
     "all four or none, none meaning derived anchors, version 1.2), a property has the wrong "
     "type or value, or deformation is present with the games profile.",
     _EXT + " or " + _EXT + "/{property}",
     "Follow spec/schema/primitive.KHR_gaussian_splatting.GSVERSE_gaussian_splatting_mesh_anchor"
     ".schema.json."),
    (Code.ANCHOR_EXTENSION_MISPLACED, "ERROR", "Anchor extension", "The anchor extension object "
     "is placed directly in primitive.extensions instead of inside "
     "primitive.extensions.KHR_gaussian_splatting.extensions, where readers look for it.",
     _PRIM + "/extensions/GSVERSE_gaussian_splatting_mesh_anchor", "Move it into the "
     "KHR_gaussian_splatting extension object's extensions."),
    (Code.ANCHOR_MESH_SAME_AS_SPLAT, "ERROR", "Anchor extension", "The anchor primitive is in "
     "the same glTF mesh as the splat primitive (some KHR loaders reject such meshes).",
     _EXT + "/mesh", "Put the anchor triangles in a mesh of their own."),
    (Code.ANCHOR_MESH_NOT_TRIANGLES, "ERROR", "Anchor mesh", "The anchor primitive's mode is not "
     "TRIANGLES (4).", _PRIM + "/mode", "Store the anchor mesh as TRIANGLES."),
    (Code.ANCHOR_MESH_POSITION_INVALID, "ERROR", "Anchor mesh", "The anchor primitive has no "
     "POSITION, or it is not FLOAT VEC3.", _PRIM + "/attributes", "Store FLOAT VEC3 positions."),
    (Code.ANCHOR_MESH_INDICES_INVALID, "ERROR", "Anchor mesh", "The anchor indices are not "
     "SCALAR UNSIGNED_BYTE/SHORT/INT (not normalized), their count is not a multiple of 3, an "
     "index is out of range, or a non-indexed vertex count is not a multiple of 3.",
     _PRIM + "/indices", "Write valid triangle indices."),
    (Code.ANCHOR_MESH_INSTANTIATED, "WARNING", "Anchor mesh", "A node not hidden by "
     "KHR_node_visibility instantiates the anchor mesh: viewers draw it over the splats.",
     "/nodes/{n}/mesh", "Remove the mesh from the node, or hide it with KHR_node_visibility."),
    (Code.ANCHOR_MESH_MULTIPLE_INSTANCES, "ERROR", "Anchor mesh", "More than one node "
     "instantiates the anchor mesh (the spec says MUST NOT; every entry of nodes counts, "
     "whichever scenes list it, none included): each instance may carry its own skin or morph "
     "weights, so which one drives the splats is ambiguous; readers refuse the asset.",
     "/nodes/{n}/mesh", "Instantiate the anchor mesh with at most one node (preferably none)."),
    (Code.ANCHOR_MESH_NOT_MANIFOLD, "INFO", "Anchor mesh", "The anchor mesh is not a closed "
     "2-manifold (after merging equal vertices): valid, but soft bodies and colliders need one.",
     _PRIM, "Convert with --watertight when physics needs it."),
    (Code.MESH_DEGENERATE_TRIANGLES, "WARNING", "Anchor mesh", "Triangles of the anchor mesh are "
     "degenerate at rest by the spec's rule (a ≤ ε_deg ℓ², ε_deg = 1e-6); count and examples. "
     "(Splats bound to them are ANCHOR_BOUND_TO_DEGENERATE.)", _PRIM, "Remove or repair them; "
     "binders never use them."),
    (Code.MESH_SLIVER_TRIANGLES, "INFO", "Anchor mesh", "Regular triangles that are nearly "
     "degenerate (a ≤ 1e-3 ℓ²): barycentric and affine remaps amplify noise on them.", _PRIM,
     "Remesh or decimate the anchor mesh."),
    (Code.MESH_DUPLICATE_TRIANGLES, "WARNING", "Anchor mesh", "Triangles with the same three "
     "corner positions as an earlier triangle (in any order); count and example pairs.", _PRIM,
     "Remove duplicate faces (the nearest triangle becomes ambiguous)."),
    (Code.ANCHOR_ACCESSOR_FORMAT, "ERROR", "Anchor extension", "An anchor accessor's type or "
     "component type differs from the spec's table (faceIndex and faceCounts SCALAR unsigned "
     "integer, not normalized; barycentrics VEC2 FLOAT or UNSIGNED_BYTE/SHORT normalized; "
     "normalOffset SCALAR FLOAT; localRotation VEC4 FLOAT or BYTE/SHORT normalized; localScale "
     "VEC3 as SCALE; rho SCALAR FLOAT).", _EXT + "/{property}",
     "Store the property in an allowed format."),
    (Code.ANCHOR_ACCESSOR_COUNT, "ERROR", "Anchor extension", "An anchor accessor other than "
     "faceCounts (ANCHOR_FACE_COUNTS_COUNT) has a count that differs from the splat "
     "primitive's POSITION count.", _EXT + "/{property}", "Write one anchor element per splat."),
    (Code.ANCHOR_ACCESSOR_TARGET, "WARNING", "Anchor extension", "The bufferView of an anchor "
     "accessor (that is not also a vertex attribute of the primitive) sets target (the spec says "
     "SHOULD NOT: the data are not vertex attributes).", _EXT + "/{property}", "Drop target "
     "from the bufferView."),
    (Code.ANCHOR_FACE_OUT_OF_RANGE, "ERROR", "Anchor extension", "A faceIndex is not less than "
     "the anchor primitive's triangle count; count and examples.", _EXT + "/faceIndex",
     "Bind every splat to an existing triangle."),
    (Code.ANCHOR_BOUND_TO_DEGENERATE, "ERROR", "Anchor extension", "Splats are bound to "
     "triangles that are degenerate at rest (writers MUST NOT do this); count and examples. "
     "(Derived anchors on such triangles are ANCHOR_DERIVED_ON_DEGENERATE.)",
     _EXT + "/faceIndex or " + _EXT + "/faceCounts",
     "Re-bind those splats to regular triangles."),
    (Code.GAMES_BARYCENTRICS_OUTSIDE_SIMPLEX, "ERROR", "Anchor extension", "A games splat's "
     "barycentrics (b1, b2, b0 = 1 − b1 − b2) are not all ≥ 0 within the tolerance (GaMeS "
     "weights are normalized, so they MUST lie in the triangle).", _EXT + "/barycentrics",
     "Re-export the GaMeS weights (softmax-normalized α)."),
    (Code.LOCAL_BARYCENTRICS_FAR, "INFO", "Anchor extension", "A local splat's foot point (its "
     "projection on its triangle's plane) lies far outside its triangle: its smallest "
     "barycentric weight is below −1, farther out than the triangle's own height over that "
     "edge. The spec allows it. Expected in converted assets: gsverse-convert binds every splat "
     "to its nearest triangle, and a splat lying off the surface next to an edge or corner of "
     "triangles smaller than its distance gets such weights (a few % of the splats of a real "
     "capture on a reconstructed or decimated mesh, more on finer meshes). Such a splat is "
     "rest-consistent and follows its triangle with a lever arm as long as its distance.",
     _EXT + "/barycentrics (derived anchors: " + _EXT + ")", "Nothing, for a converted "
     "asset, unless ANCHOR_MESH_MISFIT is reported too (the mesh does not sit where the splats "
     "are: fix its offset, units or frame and convert again) or the flagged splats are "
     "background or floaters far from the object, which swing with every deformation of the "
     "mesh: keep them static with gsverse-convert --max-distance (or drop them with "
     "--drop-unanchored). From another writer: also check that it binds each splat to a "
     "triangle near it."),
    (Code.LOCAL_SCALE_NOT_SHARED, "HINT", "Anchor extension", "localScale does not reference the "
     "accessor of KHR_gaussian_splatting:SCALE (writers SHOULD share it).", _EXT + "/localScale",
     "Reference the SCALE accessor to save space."),
    (Code.GAMES_RHO_NEGATIVE, "WARNING", "Anchor extension", "A games splat has ρ < 0: every "
     "scale collapses to the GaMeS floor ε = 1e-8.", _EXT + "/rho", "Check the export of ρ."),
    (Code.ANCHOR_NOT_SORTED, "HINT", "Anchor extension", "The splats of an anchored primitive "
     "are not sorted by faceIndex (writers SHOULD sort: about 2× faster per-frame remap; "
     "faceCounts stores them sorted).",
     _EXT + "/faceIndex", "Sort the splats by face (gsverse-convert does by default)."),
    (Code.REST_POSE_MEAN_MISMATCH, "ERROR", "Rest pose", "The remap at the rest anchor mesh does "
     "not reproduce a stored POSITION within |Δμ| ≤ 1e-5 · D + 8 ε₃₂ L; count and the worst "
     "splats. Checked only when the splat and anchor data are otherwise valid.",
     _PRIM + "/attributes/POSITION", "Re-bind the splats, or store the remapped rest pose."),
    (Code.REST_POSE_COVARIANCE_MISMATCH, "ERROR", "Rest pose", "The remap at the rest anchor "
     "mesh does not reproduce a stored covariance R diag(s)² Rᵀ within ‖ΔΣ‖_F ≤ 1e-4 ‖Σ‖_F; "
     "count and the worst splats. Checked only when the splat and anchor data are otherwise "
     "valid.", _PRIM + "/attributes/KHR_gaussian_splatting:ROTATION", "Re-bind the splats, or "
     "store the remapped rest pose."),
]
