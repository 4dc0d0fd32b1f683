"""Catalogue rows of USD files (spec/usd.md: reading, the schemas, the writer rules), and
:data:`USD_SHARED`: where the codes shared with glTF point in USD files. Rows in the format of
:mod:`.issues_rows`."""
from __future__ import annotations

from gsverse_format.codes import Code

from .issues_rows import Row, UsdLocation

__all__ = ["USD_ENTRIES", "USD_SHARED"]

USD_ENTRIES: list[Row] = [
    (Code.USD_SUPPORT_MISSING, "ERROR", "USD", "A USD file was given but usd-core (the pxr "
     "modules) is not installed.", "none", "pip install 'gsverse-format[usd]'.",
     {"fatal": True, "unreadable": True}),
    (Code.USD_UNREADABLE, "ERROR", "USD", "The file cannot be opened as a USD stage: not USD, "
     "truncated or corrupt (a crash or memory exhaustion of the USD library while reading is "
     "caught and reported here).", "none", "Re-export the file.",
     {"fatal": True, "unreadable": True}),
    (Code.USD_LAYER_OUTSIDE_FOLDER, "ERROR", "USD", "A sublayer, reference, payload or value "
     "clip (of the root layer or of a layer it brings in) is a URI with a scheme, an absolute "
     "path, or a relative path leaving the file's folder. The stage is not composed: nothing "
     "outside the folder is ever opened.", "none", "Flatten the stage (usdcat --flatten) or move "
     "the layers next to the file.", {"fatal": True}),
    (Code.USD_TYPE_MISMATCH, "ERROR", "USD", "A property has another type than spec/usd.md "
     "declares (for example float[] gsverse:anchor:faceIndices, or a non-array rest-pose "
     "attribute).", "{prim}.{property} or {mesh}.{property}", "Author the declared type "
     "(spec/usd.md §The schemas)."),
    (Code.USD_UP_AXIS_INVALID, "ERROR", "USD", "The stage's upAxis is neither Y nor Z.",
     "\"\" (the root layer)", "Author upAxis = \"Y\"."),
    (Code.USD_UP_AXIS_MISSING, "ERROR", "USD", "The stage does not author upAxis (writers MUST "
     "author \"Y\"; readers assume Y).", "\"\" (the root layer)", "Author upAxis = \"Y\"."),
    (Code.USD_UP_AXIS_CONVERTED, "WARNING", "USD", "The stage is Z-up; readers rotate it into +Y "
     "up.", "\"\" (the root layer)", "Write +Y-up stages (glTF's frame)."),
    (Code.USD_METERS_PER_UNIT_INVALID, "ERROR", "USD", "metersPerUnit is not a positive finite "
     "number.", "\"\" (the root layer)", "Author metersPerUnit = 1."),
    (Code.USD_METERS_PER_UNIT_MISSING, "ERROR", "USD", "The stage does not author metersPerUnit "
     "(writers MUST author 1; readers assume metres, not USD's centimetre fallback).",
     "\"\" (the root layer)", "Author metersPerUnit = 1."),
    (Code.USD_UNITS_CONVERTED, "WARNING", "USD", "metersPerUnit is not 1; readers scale the data "
     "to metres.", "\"\" (the root layer)", "Write stages in metres."),
    (Code.USD_DEFAULT_PRIM_MISSING, "ERROR", "USD", "The stage has no valid defaultPrim.",
     "\"\" (the root layer)", "Author defaultPrim naming the root Xform."),
    (Code.USD_DEFAULT_PRIM_NOT_XFORM, "ERROR", "USD", "The defaultPrim is not an Xform.",
     "the defaultPrim", "Make the root prim an Xform."),
    (Code.USD_OUTSIDE_DEFAULT_PRIM, "ERROR", "USD", "A splat prim or anchor Mesh is not a "
     "descendant of the defaultPrim (references to the file would miss it).", "{prim} or {mesh}",
     "Move it under the defaultPrim."),
    (Code.USD_NESTED_GPRIM, "ERROR", "USD", "A splat prim or anchor Mesh is nested under another "
     "Gprim (USD forbids nested Gprims).", "{prim} or {mesh}", "Make both children of an Xform."),
    (Code.USD_PROPERTY_MISSING, "ERROR", "USD", "An anchored prim lacks a rest-pose attribute or "
     "an attribute its profile requires, a prim with a GsVerse API schema lacks "
     "gsverse:colorSpace, or the anchor Mesh lacks points or topology.", "{prim}.{property} or "
     "{mesh}.{property}", "Author the property's default value."),
    (Code.USD_PROPERTY_EXCLUDED, "ERROR", "USD", "An anchor attribute the profile excludes is "
     "authored (for example gsverse:anchor:rho with the local profile).", "{prim}.{property}",
     "Remove it."),
    (Code.USD_LENGTH_MISMATCH, "ERROR", "USD", "An array of an anchored prim does not have one "
     "element per particle (N·K SH coefficients), or faceVertexIndices is not 3 per face.",
     "{prim}.{property} or {mesh}.faceVertexIndices", "Write one element per particle."),
    (Code.USD_SH_DEGREE_INVALID, "ERROR", "USD", "radiance:sphericalHarmonicsDegree of an "
     "anchored prim is outside 0..3.", "{prim}.radiance:sphericalHarmonicsDegree",
     "Author a degree in 0..3."),
    (Code.USD_SH_DEGREE_MISSING, "ERROR", "USD", "radiance:sphericalHarmonicsDegree is not "
     "authored (its fallback 3 makes DC-only data too short for renderers).",
     "{prim}.radiance:sphericalHarmonicsDegree", "Always author the degree.",
     {"foreign_severity": "WARNING"}),
    (Code.USD_PROFILE_INVALID, "ERROR", "USD", "gsverse:anchor:profile of an anchored prim is "
     "missing or neither local nor games.", "{prim}.gsverse:anchor:profile", "Author \"local\" "
     "or \"games\"."),
    (Code.USD_DEFORMATION_INVALID, "ERROR", "USD", "gsverse:anchor:deformation is neither affine "
     "nor rigid.", "{prim}.gsverse:anchor:deformation", "Author \"affine\" or \"rigid\"."),
    (Code.USD_MESH_TARGET_INVALID, "ERROR", "USD", "gsverse:anchor:mesh does not have exactly "
     "one target, or the target is not a Mesh prim.", "{prim}.gsverse:anchor:mesh",
     "Target the anchor Mesh."),
    (Code.USD_MESH_HOLES, "ERROR", "USD", "The anchor Mesh authors holeIndices (anchor triangles "
     "cannot be holes).", "{mesh}.holeIndices", "Remove the faces instead."),
    (Code.USD_BOTH_APIS, "ERROR", "USD", "A prim applies both GsVerseMeshAnchorAPI and "
     "GsVerseColorSpaceAPI (the first includes the second).", "{prim}",
     "Apply GsVerseMeshAnchorAPI only."),
    (Code.USD_CUSTOM_PROPERTY, "ERROR", "USD", "A gsverse: property is authored as custom (it "
     "must be the schema's property, custom = false).", "{prim}.{property}", "Author it without "
     "the custom keyword."),
    (Code.USD_NOT_UNIFORM, "ERROR", "USD", "A gsverse: attribute is not uniform.",
     "{prim}.{property}", "Author it as uniform."),
    (Code.USD_TIME_SAMPLED, "ERROR", "USD", "opacities, SH, gsverse: attributes or the anchor "
     "topology have time samples (only positions, orientations, scales, extent and the anchor "
     "points may be animated).", "{prim}.{property} or {mesh}.{property}", "Remove the time "
     "samples."),
    (Code.USD_NO_REST_POSE, "ERROR", "USD", "A rest-pose attribute has time samples but no "
     "default value.", "{prim}.{property}", "Author the rest pose as the default value."),
    (Code.USD_TIME_CODES_MISSING, "ERROR", "USD", "The stage has baked animation but does not "
     "author startTimeCode, endTimeCode or timeCodesPerSecond.", "\"\" (the root layer)",
     "Author the three time metadata."),
    (Code.USD_SORTING_MODE, "ERROR", "USD", "sortingModeHint is not authored as cameraDistance "
     "(KHR's sortingMethod; USD's fallback is zDepth).", "{prim}.sortingModeHint",
     "Author sortingModeHint = \"cameraDistance\".", {"foreign_severity": "WARNING"}),
    (Code.USD_PROJECTION_MODE, "WARNING", "USD", "projectionModeHint is not authored (SHOULD be "
     "perspective).", "{prim}.projectionModeHint", "Author projectionModeHint = \"perspective\"."),
    (Code.USD_HALF_PRECISION, "ERROR", "USD", "A half-precision rest-pose attribute (positionsh, "
     "...) is authored; writers use the float ones.", "{prim}.{property}", "Author the float "
     "attribute.", {"foreign_severity": "WARNING"}),
    (Code.USD_EXTENT_MISSING, "ERROR", "USD", "A splat prim or the anchor Mesh does not author "
     "extent.", "{prim}.extent or {mesh}.extent", "Author the bounding box of the positions.",
     {"foreign_severity": "WARNING"}),
    (Code.USD_EXTENT_INVALID, "ERROR", "USD", "A splat prim's extent does not contain every "
     "position.", "{prim}.extent", "Recompute the extent.", {"foreign_severity": "WARNING"}),
    (Code.USD_XFORM_OPS, "WARNING", "USD", "A splat prim or anchor Mesh authors xformOps (splat "
     "prims should carry none; anchoring ignores the Mesh's).", "{prim} or {mesh}",
     "Bake the transform into the data."),
    (Code.USD_COLOR_SPACE_API_IGNORED, "WARNING", "USD", "A splat prim authors UsdColorSpaceAPI "
     "colorSpace:name, which splat readers ignore (gsverse:colorSpace holds the KHR colour "
     "space).", "{prim}", "Author gsverse:colorSpace instead."),
    (Code.USD_LOCAL_SCALES_REDUNDANT, "HINT", "USD", "gsverse:anchor:localScales equals scales "
     "(writers SHOULD NOT author it then).", "{prim}.gsverse:anchor:localScales",
     "Remove it: readers fall back to scales."),
    (Code.USD_MESH_PURPOSE, "WARNING", "USD", "The anchor Mesh's purpose is not guide (renderers "
     "would draw it over the splats).", "{mesh}.purpose", "Author purpose = \"guide\"."),
    (Code.USD_MESH_SUBDIVISION, "WARNING", "USD", "The anchor Mesh's subdivisionScheme is not "
     "none (the fallback catmullClark smooths the triangles away).", "{mesh}.subdivisionScheme",
     "Author subdivisionScheme = \"none\"."),
    (Code.USD_MESH_ORIENTATION, "WARNING", "USD", "The anchor Mesh's orientation is not "
     "rightHanded (ignored for anchoring).", "{mesh}.orientation", "Author rightHanded."),
    (Code.USD_PLAIN_SPLATS, "INFO", "USD", "A ParticleField3DGaussianSplat prim has no GsVerse "
     "API schema (foreign data): it is read with colour space srgb_rec709_display, and the "
     "writer rules give warnings, not errors, for it.", "{prim}", "None for foreign data; "
     "writers of this format apply GsVerseColorSpaceAPI."),
    (Code.USD_PARTICLE_FIELD_SKIPPED, "WARNING", "USD", "A ParticleField prim that is not a "
     "ParticleField3DGaussianSplat (another kernel or radiance model) has no "
     "KHR_gaussian_splatting equivalent and is skipped.", "the prim", "Convert it to 3D "
     "Gaussian splats first."),
    (Code.USD_EMPTY_PRIM, "WARNING", "USD", "A splat prim has no particles (no positions) and is "
     "skipped.", "{prim}", "Remove the prim."),
    (Code.USD_REPLACED_BY_DEFAULT, "WARNING", "USD", "An array of a foreign splat prim is "
     "shorter than required (or the SH degree negative) and is replaced by the schema's default, "
     "as USD renderers do.", "{prim}.{property}", "Write one element per particle."),
    (Code.USD_TRUNCATED, "WARNING", "USD", "An array of a foreign splat prim is longer than "
     "required, or its SH degree above 3, and is truncated.", "{prim}.{property}",
     "Write one element per particle and SH degree 3 at most."),
    (Code.USD_VALIDATOR_ERROR, "ERROR", "USD", "An OpenUSD validator (pxr.UsdValidation, all "
     "registered validators) reports an error; the message names it.", "the prim or property it "
     "names, or \"\"", "Follow the named validator's rule."),
    (Code.USD_VALIDATOR_WARNING, "WARNING", "USD", "An OpenUSD validator reports a warning; the "
     "message names it.", "the prim or property it names, or \"\"", "Follow the named "
     "validator's rule."),
]

#: Where the codes shared with glTF point in USD files ({prim}: the splat prim, {mesh}: its
#: anchor Mesh), and the severity of the value checks for foreign USD prims, whose readers
#: normalize orientations, make scales positive and clamp opacities (spec/usd.md §Foreign data).
USD_SHARED: dict[Code, UsdLocation] = {
    Code.IO_ERROR: ("none", None),
    Code.SIZE_LIMIT_EXCEEDED: ("none", None),
    Code.SPLAT_COUNT_LIMIT: ("{prim}.positions", None),
    Code.NON_FINITE_VALUE: ("{prim}.{property} or {mesh}.points", None),
    Code.ROTATION_NOT_UNIT: ("{prim}.orientations or {prim}.gsverse:anchor:localOrientations",
                             "WARNING"),
    Code.SCALE_NEGATIVE: ("{prim}.scales or {prim}.gsverse:anchor:localScales", "WARNING"),
    Code.OPACITY_OUT_OF_RANGE: ("{prim}.opacities", "WARNING"),
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
    Code.INTERNAL_ERROR: ("none", None),
}
