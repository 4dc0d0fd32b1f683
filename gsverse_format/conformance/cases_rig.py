"""The rig cases of the conformance suite: anchor meshes animated by the asset itself.

Every *rig case* is an anchored splat primitive whose anchor mesh carries its own skin and/or
morph targets and an animation in ``asset.glb`` (spec/README.md §Animated anchor meshes): one
node, the *anchor node*, instantiates the anchor mesh with the skin or the morph weights, and
the splat node has a transform of its own (translation, rotation, uniform scale 1.3), so that
an engine must bring the skinned vertices, which glTF puts in the scene's global space, into
the splat primitive's local space by M⁻¹ (M the splat node's global matrix). Their poses are
the file's animation at two times, and the rest (the nodes' own values):
:mod:`.rig_export` samples the written asset with :mod:`gsverse_format.poses.gltf_animation`
(float64, weights normalized), ships the deformed vertices p′ and M, and computes the expected
outputs from M⁻¹ · p′.

Cases (:func:`rig_cases`): a skinned tube of four joints whose anchor node is drawn; the same
with a hidden anchor node (``KHR_node_visibility``) placed by a transform of its own (ignored);
a morph-only anchor mesh with animated weights placed by a non-identity node (p′ is already
splat-local: no M⁻¹); two skinned parts merged into one anchor mesh with one merged skin, as
``gsverse-convert --mesh`` writes a character of several parts; weights stored unnormalized
(sums 0.5 to 1.6, two vertices all zero), which readers normalize. :func:`rig_invalid_cases`
are the rig refusals: a skinned, and a morphed, anchor mesh instantiated by two nodes.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..model import TriangleMesh
from ..quaternion import to_matrix
from ..rig import WEIGHTS_PATH, AnchorRig, RigAnimation, RigChannel, RigNode
from ..vocabulary import NODE_VISIBILITY
from .case_tools import (Pose, RemapCase, case_rng, faces_from_counts, law_tags, make_anchors,
                         make_case, random_barycentrics, rest_pose)
from .glb import (FLOAT, UNSIGNED_BYTE, accessor_bytes, anchor_extension, anchor_primitive,
                  append_accessor)
from .invalid_cases import InvalidCase
from .skin import tube

__all__ = ["RigSpec", "rig_cases", "rig_invalid_cases", "RIG_TIMES", "SPLAT_NODE"]

#: The animation times (s) every rig case is sampled at, besides the rest.
RIG_TIMES = (0.35, 0.8)
#: Key times of the rig cases' animations (LINEAR keys; the sampled times fall between them).
_KEYS = np.array([0.0, 0.5, 1.0], np.float32)
#: The splat node of the rig cases: translation, rotation (x, y, z, w), uniform scale.
SPLAT_NODE: dict[str, Any] = {"translation": [0.4, -0.25, 0.3], "axis": (1.0, 2.0, 0.5), "degrees": 35.0,
              "scale": 1.3}


@dataclass
class RigSpec:
    """How a rig case's asset is laid out beyond its anchors: the splat node's transform, the
    anchor node's own transform (ignored for anchoring), whether it is hidden, the times."""

    splat_trs: dict
    anchor_trs: dict | None = None
    hidden: bool = True
    times: tuple[float, ...] = RIG_TIMES
    animation: int = 0
    skinned: bool = True
    notes: list[str] = field(default_factory=list)


def _quat(axis, degrees: float) -> np.ndarray:
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    half = np.radians(degrees) / 2.0
    return np.array([*(np.sin(half) * a), np.cos(half)])


def _trs(translation, axis, degrees: float, scale: float) -> dict:
    return {"translation": [float(v) for v in translation],
            "rotation": [float(v) for v in _quat(axis, degrees)],
            "scale": [float(scale)] * 3}


def trs_matrix(trs: dict) -> np.ndarray:
    """The 4×4 float64 matrix T·R·S of a node's ``translation``/``rotation``/``scale``."""
    m = np.eye(4)
    m[:3, :3] = to_matrix(np.asarray(trs["rotation"], np.float64)) * np.asarray(
        trs["scale"], np.float64)[None, :]
    m[:3, 3] = trs["translation"]
    return m


def _splat_trs() -> dict:
    s = SPLAT_NODE
    return _trs(s["translation"], s["axis"], s["degrees"], s["scale"])


# --------------------------------------------------------------------------- rigs

def _chain_weights(y: np.ndarray, joint_y: np.ndarray, first: int) -> tuple[np.ndarray, np.ndarray]:
    """JOINTS_0/WEIGHTS_0 blending linearly between consecutive joints at heights ``joint_y``
    (joint indices from ``first``)."""
    seg = np.clip(np.searchsorted(joint_y, y, side="right") - 1, 0, len(joint_y) - 2)
    frac = np.clip((y - joint_y[seg]) / (joint_y[seg + 1] - joint_y[seg]), 0.0, 1.0)
    joints = np.zeros((len(y), 4), np.uint16)
    weights = np.zeros((len(y), 4), np.float32)
    joints[:, 0], joints[:, 1] = first + seg, first + seg + 1
    weights[:, 0] = (1.0 - frac).astype(np.float32)
    weights[:, 1] = (1.0 - weights[:, 0].astype(np.float64)).astype(np.float32)
    joints[weights == 0.0] = 0
    return joints, weights


def _rot_keys(axis, degrees) -> np.ndarray:
    return np.array([_quat(axis, d) for d in degrees], np.float32)


def _bind(rig: AnchorRig) -> None:
    """Inverse bind matrices that make the skin draw M · POSITION at rest (M = ``root_matrix``,
    the splat node's matrix): the inverse of each joint's rest global matrix below M."""
    placed = rig.root_matrix
    rig.root_matrix = np.eye(4)
    rest = rig.rest_globals()
    rig.root_matrix = placed
    rig.inverse_bind = np.linalg.inv(rest[rig.joints])


def _chain_rig(vertices: np.ndarray, m_splat: np.ndarray, height: float) -> AnchorRig:
    """Four joints up a tube (root, lower, upper, tip), animated by rotations and a
    translation of the root."""
    step = height / 3.0
    nodes = [RigNode("root", children=[1]),
             RigNode("lower", translation=np.array([0.0, step, 0.0]), children=[2]),
             RigNode("upper", translation=np.array([0.0, step, 0.0]), children=[3]),
             RigNode("tip", translation=np.array([0.0, step, 0.0]))]
    joints, weights = _chain_weights(vertices[:, 1], np.array([0.0, step, 2 * step, 3 * step]), 0)
    channels = [
        RigChannel(0, "translation", _KEYS, np.array([[0, 0, 0], [0.12, 0.05, -0.08],
                                                      [-0.05, 0.1, 0.1]], np.float32)),
        RigChannel(0, "rotation", _KEYS, _rot_keys((0, 1, 0), (0, 30, -20))),
        RigChannel(1, "rotation", _KEYS, _rot_keys((0, 0, 1), (0, 35, 60))),
        RigChannel(2, "rotation", _KEYS, _rot_keys((1, 0, 0.3), (0, -40, 25))),
        RigChannel(3, "rotation", _KEYS, _rot_keys((0, 0.2, 1), (0, 50, -30))),
    ]
    rig = AnchorRig(nodes=nodes, roots=[0], joints=[0, 1, 2, 3], joints_0=joints,
                    weights_0=weights, animations=[RigAnimation("bend", channels)],
                    root_matrix=m_splat)
    _bind(rig)
    return rig


def _two_part_rig(body: np.ndarray, arm: np.ndarray, m_splat: np.ndarray,
                  height: float) -> AnchorRig:
    """The body tube on joints 0–2, an arm along +X on joints 3–4 (joint 3 a child of joint
    1): one merged skin over the concatenated vertices, body first."""
    step = height / 2.0
    nodes = [RigNode("hips", children=[1]),
             RigNode("chest", translation=np.array([0.0, step, 0.0]), children=[2, 3]),
             RigNode("head", translation=np.array([0.0, step, 0.0])),
             RigNode("shoulder", translation=np.array([0.25, 0.0, 0.0]), children=[4]),
             RigNode("hand", translation=np.array([0.35, 0.0, 0.0]))]
    jb, wb = _chain_weights(body[:, 1], np.array([0.0, step, 2 * step]), 0)
    ja, wa = _chain_weights(arm[:, 0], np.array([0.25, 0.6]), 3)
    channels = [
        RigChannel(0, "rotation", _KEYS, _rot_keys((0, 1, 0), (0, -25, 40))),
        RigChannel(1, "rotation", _KEYS, _rot_keys((1, 0, 0), (0, 30, -15))),
        RigChannel(3, "rotation", _KEYS, _rot_keys((0, 0, 1), (0, 55, 80))),
        RigChannel(4, "rotation", _KEYS, _rot_keys((0, 1, 0), (0, -45, 30))),
        RigChannel(4, "translation", _KEYS, np.array([[0.35, 0, 0], [0.45, 0, 0.05],
                                                      [0.3, 0.05, 0]], np.float32)),
    ]
    rig = AnchorRig(nodes=nodes, roots=[0], joints=[0, 1, 2, 3, 4],
                    joints_0=np.concatenate([jb, ja]), weights_0=np.concatenate([wb, wa]),
                    animations=[RigAnimation("wave", channels)], root_matrix=m_splat)
    _bind(rig)
    return rig


def _morph_rig(vertices: np.ndarray, height: float) -> AnchorRig:
    """Two morph targets (a bulge and a lean), default weights 0 (the rest is POSITION),
    animated weights."""
    y = vertices[:, 1] / height
    bulge = np.zeros_like(vertices)
    bulge[:, [0, 2]] = vertices[:, [0, 2]] * (0.8 * np.sin(np.pi * y))[:, None]
    lean = np.zeros_like(vertices)
    lean[:, 0] = 0.3 * y ** 2
    lean[:, 1] = -0.05 * y
    weights = np.array([[0.0, 0.0], [0.9, 0.4], [0.3, 1.0]], np.float32)
    return AnchorRig(targets=[bulge, lean], weights=[0.0, 0.0], animations=[
        RigAnimation("breathe", [RigChannel(None, WEIGHTS_PATH, _KEYS, weights)])])


# --------------------------------------------------------------------------- layout edits

def _nodes_of(doc: dict) -> tuple[int, int]:
    """(splat node, anchor node) of a written rig case."""
    ext = anchor_extension(doc)
    splat_mesh = next(m for m, mesh in enumerate(doc["meshes"])
                      if any("KHR_gaussian_splatting" in (p.get("extensions") or {})
                             for p in mesh["primitives"]))
    nodes = doc["nodes"]
    splat = next(i for i, n in enumerate(nodes) if n.get("mesh") == splat_mesh)
    anchor = next(i for i, n in enumerate(nodes) if n.get("mesh") == ext["mesh"])
    return splat, anchor


def _layout_edit(spec: RigSpec):
    """The edit that gives the written asset the layout of ``spec``: the splat node's
    transform, the anchor node's own transform, its visibility."""
    def edit(doc: dict, blob: bytes) -> tuple[dict, bytes]:
        splat, anchor = _nodes_of(doc)
        doc["nodes"][splat].update(spec.splat_trs)
        node = doc["nodes"][anchor]
        if spec.anchor_trs is not None:
            node.update(spec.anchor_trs)
        if not spec.hidden:
            node.pop("extensions", None)
            used = [e for e in doc.get("extensionsUsed", []) if e != NODE_VISIBILITY]
            doc["extensionsUsed"] = used
        return doc, blob
    return edit


# --------------------------------------------------------------------------- cases

def _case(cid: str, description: str, profile: str, law: str | None, mesh: TriangleMesh,
          spec: RigSpec, degree: int, tags: list[str], codes: list[str], note: str,
          per_face: int = 2) -> RemapCase:
    rng = case_rng(cid)
    face = faces_from_counts(rng.integers(1, per_face + 1, mesh.face_count))
    anchors = make_anchors(profile, law, mesh, face, random_barycentrics(rng, len(face)), rng)
    poses: list[Pose] = [rest_pose(mesh)]   # the rest; the animated poses come from the file
    case = make_case(cid, description, law_tags(profile, law) + ["source:animation"] + tags,
                     mesh, anchors, poses, rng, degree, edit=_layout_edit(spec),
                     validator_codes=codes, note=note)
    case.rig = spec
    return case


def rig_cases() -> list[RemapCase]:
    """All rig cases, in suite order."""
    m_splat = trs_matrix(_splat_trs())
    out = []
    h = 1.2
    v, f = tube(7, 8, 0.2, h)
    drawn = "the anchor node is drawn (no KHR_node_visibility): validators warn about it"
    mesh = TriangleMesh(v, f, rig=_chain_rig(v, m_splat, h))
    out.append(_case(
        "rig-skinned", "local profile, affine law: a tube skinned to four joints (root "
        "translation and rotations animated), the splat node translated, rotated and scaled "
        "1.3x: the skinned vertices are in the scene's global space and M^-1 brings them into "
        "the splat primitive's local space; the anchor node is drawn.", "local", "affine",
        mesh, RigSpec(_splat_trs(), hidden=False), 1, ["rig:skin", "rig:splat-node"],
        ["ANCHOR_MESH_INSTANTIATED"], drawn))

    mesh = TriangleMesh(v, f, rig=_chain_rig(v, m_splat, h))
    anchor_trs = _trs((-1.0, 0.5, 2.0), (0, 0, 1), 70.0, 0.5)
    out.append(_case(
        "rig-skinned-hidden-anchor-node", "local profile, rigid law: the skinned tube of "
        "rig-skinned with its anchor node hidden (KHR_node_visibility visible: false) and "
        "placed by a transform of its own, which is ignored: a hidden node is still skinned.",
        "local", "rigid", mesh, RigSpec(_splat_trs(), anchor_trs=anchor_trs), 0,
        ["rig:skin", "rig:splat-node", "rig:hidden-anchor-node"], [], ""))

    vm, fm = tube(6, 10, 0.25, 1.0)
    mesh = TriangleMesh(vm, fm, rig=_morph_rig(vm, 1.0))
    out.append(_case(
        "rig-morph-weights", "local profile, affine law: a morph-only anchor mesh (two "
        "targets, animated weights) whose anchor node and splat node both carry transforms: "
        "the morphed vertices are already in the splat primitive's local space (no M^-1, the "
        "anchor node's transform ignored).", "local", "affine", mesh,
        RigSpec(_splat_trs(), anchor_trs=_trs((0.5, 1.0, -0.5), (1, 0, 0), -30.0, 2.0),
                skinned=False), 2, ["rig:morph", "rig:splat-node"], [], ""))

    body, fb = tube(6, 8, 0.2, 1.0)
    arm, fa = tube(4, 6, 0.06, 0.4, (0.0, 0.0, 0.0))
    arm = arm[:, [1, 0, 2]] + np.array([0.22, 0.5, 0.0])     # along +X from the chest
    fa = fa[:, [0, 2, 1]]                                     # the axis swap mirrors: rewind
    parts_v = np.concatenate([body, arm])
    parts_f = np.concatenate([fb, fa + len(body)]).astype(np.uint32)
    mesh = TriangleMesh(parts_v, parts_f, rig=_two_part_rig(body, arm, m_splat, 1.0))
    out.append(_case(
        "rig-two-parts-merged", "games profile: a body and an arm, two skinned parts merged "
        "into one anchor mesh with one merged skin of five joints (what gsverse-convert --mesh "
        "writes for a character of several primitives), the splat node transformed.",
        "games", None, mesh, RigSpec(_splat_trs()), 0,
        ["rig:skin", "rig:splat-node", "rig:merged-parts"], [], ""))

    rig = _chain_rig(v, m_splat, h)
    joints, weights = rig.joints_0, rig.weights_0
    assert joints is not None and weights is not None
    rng = case_rng("rig-weights-unnormalized/weights")
    w = weights.astype(np.float64) * rng.uniform(0.5, 1.6, (len(v), 1))
    zero = [int(len(v) // 3), int(2 * len(v) // 3)]
    w[zero] = 0.0                   # all zero: weight 1 on the first influence (JOINTS_0[0])
    joints[zero, 0] = [1, 2]
    rig.weights_0 = w.astype(np.float32)
    mesh = TriangleMesh(v, f, rig=rig)
    out.append(_case(
        "rig-weights-unnormalized", "local profile, affine law: the skinned tube with its "
        "WEIGHTS_0 stored unnormalized (each vertex's sum between 0.5 and 1.6, two vertices "
        "all zero); readers divide each vertex's weights by their sum (all zero: weight 1 on "
        "JOINTS_0 component 0).", "local", "affine", mesh, RigSpec(_splat_trs()), 1,
        ["rig:skin", "rig:splat-node", "rig:weights-unnormalized"],
        ["ANCHOR_SKIN_WEIGHTS_NOT_NORMALIZED"], "the weights are stored unnormalized on "
        "purpose: validators warn, readers normalize them"))
    return out


# --------------------------------------------------------------------------- refusals

def _m_two_skinned_nodes(doc: dict, blob: bytes) -> tuple[dict, bytes]:
    """Give the anchor primitive a one-joint skin and instantiate it by two skinned nodes."""
    prim = anchor_primitive(doc)
    count = doc["accessors"][prim["attributes"]["POSITION"]]["count"]
    joints = np.zeros((count, 4), np.uint8)
    weights = np.zeros((count, 4), np.float32)
    weights[:, 0] = 1.0
    prim["attributes"]["JOINTS_0"], blob = append_accessor(doc, blob, joints, UNSIGNED_BYTE, "VEC4")
    prim["attributes"]["WEIGHTS_0"], blob = append_accessor(doc, blob, weights, FLOAT, "VEC4")
    joint = len(doc["nodes"])
    doc["nodes"].append({"name": "joint"})
    doc.setdefault("skins", []).append({"joints": [joint]})
    m = anchor_extension(doc)["mesh"]
    scene = doc["scenes"][doc.get("scene", 0)]["nodes"]
    scene.append(joint)
    for name in ("anchor node 1", "anchor node 2"):
        doc["nodes"].append({"mesh": m, "skin": len(doc["skins"]) - 1, "name": name})
        scene.append(len(doc["nodes"]) - 1)
    return doc, blob


def _m_two_morphed_nodes(doc: dict, blob: bytes) -> tuple[dict, bytes]:
    """Give the anchor primitive one morph target and instantiate it by two nodes with
    different morph weights."""
    prim = anchor_primitive(doc)
    pos = accessor_bytes(doc, blob, prim["attributes"]["POSITION"])
    delta = np.zeros_like(pos, dtype=np.float32)
    delta[:, 1] = 0.1
    target, blob = append_accessor(doc, blob, delta, FLOAT, "VEC3")
    doc["accessors"][target].update(min=[0.0, 0.1, 0.0], max=[0.0, 0.1, 0.0])
    prim["targets"] = [{"POSITION": target}]
    m = anchor_extension(doc)["mesh"]
    scene = doc["scenes"][doc.get("scene", 0)]["nodes"]
    for name, w in (("anchor node 1", 0.0), ("anchor node 2", 1.0)):
        doc["nodes"].append({"mesh": m, "weights": [w], "name": name})
        scene.append(len(doc["nodes"]) - 1)
    return doc, blob


def rig_invalid_cases() -> list[InvalidCase]:
    """The rig refusals: an animated anchor mesh instantiated by two nodes."""
    rule = ("spec/README.md §Animated anchor meshes: an animated anchor mesh MUST be "
            "instantiated by exactly one node; §The anchor mesh: readers MUST refuse an anchor "
            "mesh instantiated by more than one node")
    return [
        InvalidCase("invalid-rig-two-skinned-anchor-nodes", "The anchor mesh carries a skin "
                    "and two nodes instantiate it, each with the skin: which instance drives "
                    "the splats is ambiguous.", rule, "local", _m_two_skinned_nodes,
                    "ANCHOR_MESH_MULTIPLE_INSTANCES", ["rig:skin"]),
        InvalidCase("invalid-rig-two-morphed-anchor-nodes", "The anchor mesh carries a morph "
                    "target and two nodes with different morph weights instantiate it.", rule,
                    "games", _m_two_morphed_nodes, "ANCHOR_MESH_MULTIPLE_INSTANCES",
                    ["rig:morph"]),
    ]
