"""Reading the rig of a skinned, morphed or animated ``--mesh`` glTF as one anchor mesh
(:class:`gsverse_format.rig.AnchorRig`; spec/README.md §Animated anchor meshes).

Every TRIANGLES primitive the default scene draws is a *part* of the anchor mesh, in the order
of :func:`.scene.scene_triangles`. The scene is animated when a part has a skin or morph
targets, or an animation moves a part's node or one of its ancestors; then:

* **Rest pose = what glTF draws at rest.** A skinned part's rest vertices are its ``POSITION``
  skinned with the skeleton at its nodes' own values: ``Σ w_j · G_j · IBM_j · v`` (glTF ignores
  the transform of the node that draws a skinned mesh, so this is *not* ``node global · v``
  when that node carries a transform). Other parts are placed by their node's global matrix.
* **One skin for the whole character.** The anchor is one primitive and one node (the spec's
  rule), so the parts' skins are merged: the joints of every skin, plus the node of every
  unskinned part (weight 1 on its own node, so a part parented to an animated node follows it
  rigidly, exactly). The merged skin is bound at rest: ``IBM'_j = G_j⁻¹``, so the stored
  vertices come back at rest, as the spec asks, and a joint shared by two skins needs one
  matrix. When every joint that moves a vertex has the same ``G_j · IBM_j`` (the skeleton's
  rest is its bind pose, possibly up to a common placement), the animated vertices are the
  source's exactly; otherwise (a rest pose that is not the bind pose) this is the "apply pose
  as rest pose" of modelling tools, and a note gives the largest difference it can make.
* **Morph targets** of one node (its primitives all share its weights) are kept, deltas mapped
  like the vertices and zero on the other parts; morph targets on several nodes, and more than
  four joint influences per vertex (``JOINTS_1`` with non-zero ``WEIGHTS_1``), are refused.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...errors import FormatError
from ...rig import WEIGHTS_PATH, AnchorRig, RigAnimation, RigChannel, RigNode, normalized_weights
from ...limits import (MAX_MORPH_AMPLIFICATION, MAX_NODE_DEPTH, MAX_READ_AMPLIFICATION,
                       READ_AMPLIFICATION_SLACK)
from ...rig_checks import (is_index, joints_out_of_range, key_times_problem, non_finite_problem,
                           sampler_count_problem, weights_count_problem)
from .accessors import buffer_bytes, declared_bytes, dequantize
from .document import Document
from .reader import TRIANGLES

__all__ = ["read_rig", "REBIND_NOTE_TOLERANCE"]

_GTYPES = ("SCALAR", "VEC2", "VEC3", "VEC4", "MAT4")
_TRS = ("translation", "rotation", "scale")
#: rebinding differences below this fraction of the mesh's bounding-box diagonal get no note
REBIND_NOTE_TOLERANCE = 1e-4


@dataclass
class _Part:
    node: int
    mesh: int
    primitive: int
    world: np.ndarray
    start: int
    count: int


def read_rig(document: Document, instances: list[tuple[int | None, int, np.ndarray]]
             ) -> tuple[AnchorRig, np.ndarray] | None:
    """The rig of the scene ``instances`` draw (:func:`.scene.node_instances`) and the rest
    vertices (V, 3) float64 of all its parts in the order of :func:`.scene.scene_triangles`;
    None when nothing in the scene is skinned, morphed or animated (a static anchor mesh).
    :class:`FormatError` on malformed rig data and on what one anchor mesh cannot keep
    (see the module docstring)."""
    try:
        return _read_rig(document, instances)
    except (KeyError, IndexError, TypeError, ValueError, np.linalg.LinAlgError) as err:
        raise FormatError(f"malformed skin, morph target or animation data "
                          f"({type(err).__name__}: {' '.join(str(err).split())})") from None


def _read_rig(document: Document, instances: list[tuple[int | None, int, np.ndarray]]
              ) -> tuple[AnchorRig, np.ndarray] | None:
    doc = document.doc
    reader = document.reader
    meshes = doc.get("meshes") or []
    nodes = doc.get("nodes") or []
    skins = doc.get("skins") or []

    def floats(i: Any) -> np.ndarray:
        arr, ctype, normalized = reader.raw(i, f"accessor {i}", _GTYPES)
        return np.asarray(dequantize(arr, ctype, normalized), dtype=np.float64)

    parts: list[_Part] = []
    total = 0
    for n, m, world in instances:
        for p, prim in enumerate(meshes[m].get("primitives", [])):
            if prim.get("mode", TRIANGLES) != TRIANGLES:
                continue
            if n is None:
                return None   # no scene: no node can skin or animate anything
            count = int(reader.raw(prim["attributes"]["POSITION"], "POSITION",
                                   ("VEC3",))[0].shape[0])
            parts.append(_Part(n, m, p, world, total, count))
            total += count
    if not parts:
        return None
    parent = {c: i for i, node in enumerate(nodes) for c in (node.get("children") or [])}

    def chain(k: int | None) -> list[int]:
        """``k`` and its ancestors, at most :data:`~gsverse_format.limits.MAX_NODE_DEPTH`."""
        out: list[int] = []
        seen: set[int] = set()
        while k is not None and k not in seen:
            if len(out) == MAX_NODE_DEPTH:
                raise FormatError(f"node {out[0]} lies more than {MAX_NODE_DEPTH} levels deep "
                                  f"in the node hierarchy")
            out.append(k)
            seen.add(k)
            k = parent.get(k)
        return out

    def prim_of(part: _Part) -> dict:
        return meshes[part.mesh]["primitives"][part.primitive]

    moved = {ch.get("target", {}).get("node") for anim in doc.get("animations") or []
             for ch in anim.get("channels", []) if ch.get("target", {}).get("path") in _TRS}
    morph_nodes = sorted({pt.node for pt in parts if prim_of(pt).get("targets")})
    skinned = any(nodes[pt.node].get("skin") is not None for pt in parts) or any(
        moved.intersection(chain(pt.node)) for pt in parts)
    if not skinned and not morph_nodes:
        return None
    if len(morph_nodes) > 1:
        names = ", ".join(repr(nodes[n].get("name", f"node {n}")) for n in morph_nodes)
        raise FormatError(f"morph targets on {len(morph_nodes)} nodes ({names}): an anchor mesh "
                          f"has one set of morph weights, so only one node's morph targets can "
                          f"be kept (join the morphed meshes into one in the modelling tool)")
    morph_node = morph_nodes[0] if morph_nodes else None
    target_count = 0
    if morph_node is not None:
        counts = {len(prim_of(pt).get("targets") or []) for pt in parts if pt.node == morph_node}
        if len(counts) != 1:
            raise FormatError(f"the primitives of node {morph_node}'s mesh have different "
                              f"numbers of morph targets ({sorted(counts)})")
        target_count = counts.pop()
        _check_morph_amplification(doc, [prim_of(pt) for pt in parts if pt.node == morph_node],
                                   target_count, total)

    rig = AnchorRig()
    index: dict[int, int] = {}
    joints: list[int] = []       # merged skin, source node indices
    if skinned:
        for pt in parts:
            skin_i = nodes[pt.node].get("skin")
            for j in ([int(j) for j in skins[skin_i]["joints"]] if skin_i is not None
                      else [pt.node]):
                if j not in joints:
                    joints.append(j)
        keep = sorted({k for j in joints for k in chain(j)})
        index = {n: i for i, n in enumerate(keep)}
        for n in keep:
            src = nodes[n]
            rn = RigNode(src.get("name"), children=[index[c] for c in src.get("children") or []
                                                    if c in index])
            if src.get("matrix") is not None:
                rn.matrix = np.asarray(src["matrix"], np.float64).reshape(4, 4).T
            for key in _TRS:
                if src.get(key) is not None:
                    setattr(rn, key, np.asarray(src[key], np.float64))
            rig.nodes.append(rn)
        rig.roots = [index[n] for n in keep if parent.get(n) not in index]
        rig.joints = [index[j] for j in joints]
        used = {nodes[pt.node].get("skin") for pt in parts} - {None}
        if len(used) == 1 and all(nodes[pt.node].get("skin") is not None for pt in parts):
            skeleton = skins[used.pop()].get("skeleton")
            rig.skeleton = index.get(skeleton) if skeleton is not None else None
    globals_ = rig.rest_globals()
    joint_globals = globals_[rig.joints] if skinned else np.zeros((0, 4, 4))

    rest = np.empty((total, 3))
    linear = np.empty((total, 3, 3))
    joints_0 = np.zeros((total, 4), np.uint16)
    weights_0 = np.zeros((total, 4), np.float32)
    fallback: dict[int, np.ndarray] = {}   # merged joint -> a source inverse bind matrix
    spread = 0.0                 # how far a vertex's joints disagree about its rest place
    for pt in parts:
        prim = prim_of(pt)
        attrs = prim.get("attributes", {})
        v = floats(attrs["POSITION"])[:, :3]
        rows = slice(pt.start, pt.start + pt.count)
        skin_i = nodes[pt.node].get("skin")
        if skin_i is None:
            rest[rows] = v @ pt.world[:3, :3].T + pt.world[:3, 3]
            linear[rows] = pt.world[:3, :3]
            if skinned:
                joints_0[rows, 0] = joints.index(pt.node)
                weights_0[rows, 0] = 1.0
            continue
        skin = skins[skin_i]
        mine = [int(j) for j in skin["joints"]]
        if skin.get("inverseBindMatrices") is not None:
            ibm = np.swapaxes(floats(skin["inverseBindMatrices"]).reshape(-1, 4, 4), 1, 2)
            if len(ibm) < len(mine):
                raise FormatError(f"skin {skin_i} has {len(mine)} joints but "
                                  f"{len(ibm)} inverse bind matrices")
            problem = non_finite_problem(ibm, "matrices")
            if problem:
                raise FormatError(f"the inverse bind matrices of skin {skin_i} (accessor "
                                  f"{skin['inverseBindMatrices']}) {problem}")
        else:
            ibm = np.broadcast_to(np.eye(4), (len(mine), 4, 4))
        where = np.array([joints.index(j) for j in mine], np.intp)
        for k, j in enumerate(where):
            fallback.setdefault(int(j), ibm[k])
        jn, wt = _influences(attrs, floats, len(mine), pt.mesh, pt.primitive)
        # The rest a reader draws uses the weights as readers use them (normalized, spec
        # §Animated anchor meshes, Skin weights); the raw ones are kept for the converter to
        # note or refuse (gsverse_format.scene.normalize_skin_weights).
        used_wt = normalized_weights(wt).weights
        bind = joint_globals[where] @ ibm[:len(mine)]             # (J, 4, 4)
        blend = np.einsum("nk,nkij->nij", used_wt, bind[jn])     # (V, 4, 4)
        placed = np.einsum("nij,nj->ni", blend[:, :3, :3], v) + blend[:, :3, 3]
        for k in range(4):
            on = used_wt[:, k] > 0
            if on.any():
                b = bind[jn[on, k]]
                alone = np.einsum("nij,nj->ni", b[:, :3, :3], v[on]) + b[:, :3, 3]
                spread = max(spread, float(np.abs(alone - placed[on]).max()))
        rest[rows] = placed
        linear[rows] = blend[:, :3, :3]
        joints_0[rows] = where[jn]
        weights_0[rows] = wt
    if not np.isfinite(rest).all():
        raise FormatError("skinning the mesh at rest gives NaN or Inf vertex positions")

    if skinned:
        rig.inverse_bind = np.stack([_inverse(g, fallback.get(k)) for k, g in
                                     enumerate(joint_globals)])
        rig.joints_0, rig.weights_0 = joints_0, weights_0
        diag = float(np.linalg.norm(np.ptp(rest, axis=0))) or 1.0
        if spread > REBIND_NOTE_TOLERANCE * diag:
            rig.notes.append(
                f"the skeleton's rest pose (its nodes' own values) is not the pose its skin was "
                f"bound in: the anchor mesh was rebound to the rest pose glTF draws; away from "
                f"rest its skinning can differ from the source's by up to about {spread:.3g} "
                f"(vertices weighted to joints that moved apart)")
    if morph_node is not None:
        for k in range(target_count):
            delta = np.zeros((total, 3))
            for pt in parts:
                if pt.node != morph_node:
                    continue
                target = prim_of(pt)["targets"][k]
                if "POSITION" in target:
                    rows = slice(pt.start, pt.start + pt.count)
                    source = floats(target["POSITION"])[:, :3]
                    problem = non_finite_problem(source, "deltas")
                    if problem:
                        raise FormatError(f"the POSITION deltas of morph target {k} of mesh "
                                          f"{pt.mesh} primitive {pt.primitive} (accessor "
                                          f"{target['POSITION']}) {problem}")
                    delta[rows] = np.einsum("nij,nj->ni", linear[rows], source)
            rig.targets.append(delta.astype(np.float32))
        node = nodes[morph_node]
        mesh = meshes[node["mesh"]]
        for holder, owner in ((f"node {morph_node}", node), (f"mesh {node['mesh']}", mesh)):
            problem = None if "weights" not in owner else weights_count_problem(
                owner["weights"], target_count)
            if problem:
                raise FormatError(f"the default morph weights of {holder} {problem}")
        rig.weights = [float(w) for w in node.get("weights", mesh.get(
            "weights", [0.0] * target_count))]
    rig.animations = _animations(doc, floats, index, morph_node, target_count)
    return rig, rest


def _check_morph_amplification(doc: dict, prims: list[dict], target_count: int,
                               total: int) -> None:
    """Morph targets may share one accessor (legal glTF): 50,000 targets of one accessor made
    a 1.2 MB mesh a 1.23 GB anchor mesh. The accessor bytes the targets read (an accessor
    counted once per use), may be at most :data:`~gsverse_format.limits.MAX_READ_AMPLIFICATION`
    times the buffers' bytes plus :data:`~gsverse_format.limits.READ_AMPLIFICATION_SLACK`, as
    for splat primitives, and the deltas kept (one float32 (V, 3) array per target over the
    whole anchor mesh) :data:`~gsverse_format.limits.MAX_MORPH_AMPLIFICATION` times; declared
    sizes, checked before any target is read."""
    held = buffer_bytes(doc)
    read = sum(declared_bytes(doc, target.get("POSITION")) for prim in prims
               for target in prim.get("targets") or [] if isinstance(target, dict))
    kept = 12 * target_count * total
    for amount, what, ratio in ((read, "read", MAX_READ_AMPLIFICATION),
                                (kept, "keep as deltas", MAX_MORPH_AMPLIFICATION)):
        if amount > ratio * held + READ_AMPLIFICATION_SLACK:
            raise FormatError(f"{target_count} morph targets would {what} {amount} bytes, more "
                              f"than {ratio} times the {held} bytes of the buffers plus "
                              f"{READ_AMPLIFICATION_SLACK >> 20} MiB (morph targets sharing "
                              f"accessors)")


def _influences(attrs: dict, floats: Any, joint_count: int, mesh: int, primitive: int
                ) -> tuple[np.ndarray, np.ndarray]:
    """(V, 4) joint indices into the part's skin and (V, 4) weights; refused beyond four
    influences per vertex."""
    where = f"mesh {mesh} primitive {primitive}"
    if "JOINTS_0" not in attrs or "WEIGHTS_0" not in attrs:
        raise FormatError(f"{where} is skinned but has no JOINTS_0/WEIGHTS_0")
    n = 1
    while f"JOINTS_{n}" in attrs or f"WEIGHTS_{n}" in attrs:
        if f"WEIGHTS_{n}" in attrs and np.any(floats(attrs[f"WEIGHTS_{n}"]) != 0):
            raise FormatError(f"{where} has more than 4 joint influences per vertex "
                              f"(JOINTS_{n}/WEIGHTS_{n} with non-zero weights), which the "
                              f"anchor mesh does not keep: limit the influences to 4 per "
                              f"vertex in the modelling tool")
        n += 1   # all-zero extra sets change nothing and are left out
    jn = np.rint(floats(attrs["JOINTS_0"])).astype(np.intp)
    wt = floats(attrs["WEIGHTS_0"])
    if jn.shape[1:] != (4,) or wt.shape != jn.shape:
        raise FormatError(f"{where}: JOINTS_0/WEIGHTS_0 must be VEC4 of one count each")
    bad = joints_out_of_range(jn, joint_count)
    if bad.size:
        raise FormatError(f"{where}: JOINTS_0 (accessor {attrs['JOINTS_0']}) of {bad.size} "
                          f"vertices names a joint not below the skin's {joint_count} joints "
                          f"(vertex {int(bad[0])}: {jn[bad[0]].tolist()})")
    problem = non_finite_problem(wt, "vertices")
    if problem:
        raise FormatError(f"{where}: WEIGHTS_0 (accessor {attrs['WEIGHTS_0']}) {problem}")
    return jn, wt


def _inverse(matrix: np.ndarray, fallback: np.ndarray | None) -> np.ndarray:
    """The inverse of a joint's rest global matrix; a singular one (a joint scaled to zero at
    rest, which moves no vertex) keeps the source's inverse bind matrix."""
    scale = float(np.abs(matrix[:3, :3]).max())
    if scale > 0 and abs(np.linalg.det(matrix[:3, :3])) > 1e-12 * scale ** 3:
        return np.asarray(np.linalg.inv(matrix), np.float64)
    return np.eye(4) if fallback is None else np.asarray(fallback, np.float64)


def _animations(doc: dict, floats: Any, index: dict[int, int], morph_node: int | None,
                target_count: int) -> list[RigAnimation]:
    """The channels that move kept nodes or the morphed node's weights; refused: a channel
    aimed at a node that does not exist, and a kept channel whose sampler breaks a rule of
    :mod:`gsverse_format.rig_checks`."""
    out = []
    node_count = len(doc.get("nodes") or [])
    for a, anim in enumerate(doc.get("animations") or []):
        channels = []
        for c, ch in enumerate(anim.get("channels", [])):
            target = ch.get("target", {})
            tn, path = target.get("node"), target.get("path")
            if "node" in target and not is_index(tn, node_count):
                raise FormatError(f"animation {a} channel {c} targets node {tn!r}, which does "
                                  f"not exist (there are {node_count} nodes)")
            if tn in index and path in _TRS:
                rnode: int | None = index[tn]
            elif tn == morph_node and path == WEIGHTS_PATH and target_count:
                rnode = None
            else:
                continue
            sampler = anim["samplers"][ch["sampler"]]
            times = floats(sampler["input"]).reshape(-1)
            values = floats(sampler["output"])
            width = target_count if path == WEIGHTS_PATH else (4 if path == "rotation" else 3)
            interpolation = sampler.get("interpolation", "LINEAR")
            for what, problem in (
                    (f"key times (accessor {sampler['input']})", key_times_problem(times)),
                    (f"values (accessor {sampler['output']})",
                     sampler_count_problem(len(times), values.size, width, interpolation)
                     or non_finite_problem(values.reshape(-1, 1), "values"))):
                if problem:
                    raise FormatError(f"animation {a} channel {c} ({path} of node {tn}): its "
                                      f"{what} {problem}")
            channels.append(RigChannel(rnode, path, times, values.reshape(-1, width),
                                       interpolation))
        if channels:
            out.append(RigAnimation(anim.get("name", f"animation {a}"), channels))
    return out
