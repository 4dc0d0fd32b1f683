"""Catalogue rows of the animated anchor mesh checks (:mod:`.rig`; spec/README.md
§Animated anchor meshes), in the format of :mod:`.issues_rows`."""
from __future__ import annotations

from gsverse_format.codes import Code

from .issues_rows import Row

__all__ = ["RIG_ENTRIES"]

_G = "Animated anchor mesh"
_PRIM = "/meshes/{m}/primitives/{p}"

RIG_ENTRIES: list[Row] = [
    (Code.ANCHOR_SKIN_INVALID, "ERROR", _G, "The skin of the anchor node does not resolve: its "
     "index, a joint node, or an inverseBindMatrices accessor whose count differs from the "
     "number of joints.", "/skins/{s}", "Write one inverse bind matrix per joint, joints that "
     "exist."),
    (Code.ANCHOR_SKIN_ATTRIBUTES_INVALID, "ERROR", _G, "The skinned anchor primitive lacks "
     "JOINTS_0/WEIGHTS_0, their counts differ from POSITION's, or a joint index is not below "
     "the skin's joint count.", _PRIM + "/attributes/{name}",
     "Write JOINTS_0 and WEIGHTS_0 for every vertex, indexing the skin's joints."),
    (Code.ANCHOR_SKIN_WEIGHTS_NOT_NORMALIZED, "WARNING", _G, "The WEIGHTS_0 of a vertex of "
     "the skinned anchor primitive do not sum to 1 within 2·10⁻³ (glTF 2.0: they SHOULD), or "
     "are all zero. Readers normalize them (each vertex's weights divided by their sum; all "
     "zero: weight 1 on its first influence), as three.js does; engines that use them as they "
     "are pose the vertex elsewhere.", _PRIM + "/attributes/WEIGHTS_0",
     "Normalize the skin weights (gsverse-convert does); weight every vertex."),
    (Code.ANCHOR_MORPH_TARGETS_INVALID, "ERROR", _G, "A morph target of the anchor primitive has "
     "a POSITION whose count differs from the anchor mesh's, or the default weights' count "
     "differs from the number of targets.", _PRIM + "/targets/{k}/POSITION",
     "Write one delta per vertex and one weight per target."),
    (Code.ANCHOR_ANIMATION_TARGET_INVALID, "ERROR", _G, "An animation channel targets a node "
     "that does not exist, or animates the morph weights of an anchor node whose mesh has no "
     "morph targets.", "/animations/{a}/channels/{c}/target",
     "Target existing nodes; animate weights only of morphed meshes."),
    (Code.ANCHOR_ANIMATION_SAMPLER_INVALID, "ERROR", _G, "The sampler of a channel that moves "
     "a node or the anchor node's morph weights has no key times or key times that decrease "
     "(glTF 2.0 asks for increasing times), an unknown interpolation, or a value count other "
     "than the key count times the values per key (three times for CUBICSPLINE). NaN or "
     "infinity there is NON_FINITE_VALUE.", "/animations/{a}/samplers/{s}/{input|output}",
     "Write increasing key times and one value per key (three for CUBICSPLINE)."),
]
