"""Reading and writing the skin, morph targets and animations of an animated anchor mesh
(:class:`gsverse_format.rig.AnchorRig`; spec/README.md §Animated anchor meshes).

Reading (``--mesh character.glb``): when the default scene draws exactly one TRIANGLES
primitive and it has a skin and/or morph targets, :func:`read_rig` takes the skin's joints and
their ancestors (the node hierarchy, renumbered), the inverse bind matrices, ``JOINTS_0`` /
``WEIGHTS_0``, the morph targets' POSITION deltas and the animation channels that target those
nodes or the mesh node's morph weights. The mesh reader applies the drawing node's global
matrix ``W`` to the vertices, so the rig gets ``W`` too (inverse bind matrices ``IBM·W⁻¹``,
deltas ``W₃·δ``): the skinned vertices stay the file's.

Writing (:func:`write_rig`): the anchor mesh's primitive gets ``JOINTS_0``/``WEIGHTS_0`` and
``targets``, one node instances it with the skin, hidden by ``KHR_node_visibility``, at the
scene root beside the splat nodes; the rig's nodes follow (under a node holding
``root_matrix`` when that is not the identity), then the skin and the animations.
"""
from __future__ import annotations

from typing import Any, Callable

import numpy as np
import pygltflib

from ...errors import FormatError
from ...rig import WEIGHTS_PATH, AnchorRig, RigAnimation, RigChannel, RigNode
from ...vocabulary import FLOAT, NODE_VISIBILITY, UNSIGNED_BYTE, UNSIGNED_SHORT
from .accessors import dequantize
from .document import Document
from .reader import TRIANGLES

__all__ = ["read_rig", "write_rig", "RigOutput"]

_GTYPES = ("SCALAR", "VEC2", "VEC3", "VEC4", "MAT4")
_TRS = ("translation", "rotation", "scale")
_GTYPE_OF = {1: "SCALAR", 3: "VEC3", 4: "VEC4"}


def read_rig(document: Document, instances: list[tuple[int | None, int, np.ndarray]]
             ) -> AnchorRig | None:
    """The rig of the one skinned/morphed primitive the scene draws; None (a static anchor
    mesh) when the scene draws several primitives, one without skin and morph targets, or a
    skin with more than 4 influences per vertex (JOINTS_1). A mesh node that is an ancestor
    of its joints is kept in the hierarchy as a plain node. :class:`FormatError` on malformed
    skin, morph target or animation data."""
    try:
        return _read_rig(document, instances)
    except (KeyError, IndexError, TypeError, ValueError) as err:
        raise FormatError(f"malformed skin, morph target or animation data "
                          f"({type(err).__name__}: {' '.join(str(err).split())})") from None


def _read_rig(document: Document, instances: list[tuple[int | None, int, np.ndarray]]
              ) -> AnchorRig | None:
    doc = document.doc
    meshes = doc.get("meshes") or []
    drawn = [(n, m, p, world) for n, m, world in instances
             for p, prim in enumerate(meshes[m].get("primitives", []))
             if prim.get("mode", TRIANGLES) == TRIANGLES]
    if len(drawn) != 1 or drawn[0][0] is None:
        return None   # several drawn primitives (or no scene): the anchor mesh is static
    found, m, p, world = drawn[0]
    assert found is not None
    node_i = found
    nodes = doc.get("nodes") or []
    node = nodes[node_i]
    prim = meshes[m]["primitives"][p]
    targets = prim.get("targets") or []
    skin_i = node.get("skin")
    if skin_i is None and not targets:
        return None
    reader = document.reader

    def floats(i: Any) -> np.ndarray:
        arr, ctype, normalized = reader.raw(i, f"accessor {i}", _GTYPES)
        return dequantize(arr, ctype, normalized).astype(np.float64)

    rig = AnchorRig()
    keep: list[int] = []
    if skin_i is not None:
        attrs = prim.get("attributes", {})
        if "JOINTS_1" in attrs or "JOINTS_0" not in attrs or "WEIGHTS_0" not in attrs:
            return None   # only one JOINTS_0/WEIGHTS_0 set is kept
        skin = (doc.get("skins") or [])[skin_i]
        joints = [int(j) for j in skin["joints"]]
        parent = {c: i for i, n in enumerate(nodes) for c in (n.get("children") or [])}
        wanted = set()
        for j in joints:
            k: int | None = j
            while k is not None and k not in wanted:
                wanted.add(k)
                k = parent.get(k)
        keep = sorted(wanted)
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
        if skin.get("skeleton") in index:
            rig.skeleton = index[skin["skeleton"]]
        if skin.get("inverseBindMatrices") is not None:
            ibm = np.swapaxes(floats(skin["inverseBindMatrices"]).reshape(-1, 4, 4), 1, 2)
        else:
            ibm = np.broadcast_to(np.eye(4), (len(joints), 4, 4))
        rig.inverse_bind = ibm @ np.linalg.inv(world)
        rig.joints_0 = np.rint(floats(attrs["JOINTS_0"])).astype(np.uint16)
        rig.weights_0 = floats(attrs["WEIGHTS_0"]).astype(np.float32)
    else:
        index = {}
    count = int(reader.raw(prim["attributes"]["POSITION"], "POSITION", ("VEC3",))[0].shape[0])
    for target in targets:
        delta = floats(target["POSITION"])[:, :3] if "POSITION" in target else \
            np.zeros((count, 3))
        rig.targets.append((delta @ world[:3, :3].T).astype(np.float32))
    rig.weights = [float(w) for w in node.get("weights", meshes[m].get(
        "weights", [0.0] * len(targets)))] if targets else []
    for a, anim in enumerate(doc.get("animations") or []):
        channels = []
        for ch in anim.get("channels", []):
            target = ch.get("target", {})
            tn, path = target.get("node"), target.get("path")
            if tn in index and path in _TRS:
                rnode: int | None = index[tn]
            elif tn == node_i and path == WEIGHTS_PATH and targets:
                rnode = None
            else:
                continue
            sampler = anim["samplers"][ch["sampler"]]
            times = floats(sampler["input"]).reshape(-1)
            values = floats(sampler["output"])
            width = len(targets) if path == WEIGHTS_PATH else (4 if path == "rotation" else 3)
            channels.append(RigChannel(rnode, path, times, values.reshape(-1, width),
                                       sampler.get("interpolation", "LINEAR")))
        if channels:
            rig.animations.append(RigAnimation(anim.get("name", f"animation {a}"), channels))
    return rig


class RigOutput:
    """What :func:`write_rig` adds to the document (pygltflib objects, file indices)."""

    def __init__(self) -> None:
        self.nodes: list[pygltflib.Node] = []
        self.roots: list[int] = []
        self.skins: list[pygltflib.Skin] = []
        self.animations: list[pygltflib.Animation] = []


def write_rig(add: Callable[..., int], rig: AnchorRig, gmesh: pygltflib.Mesh,
              mesh: int, first_node: int, out: RigOutput) -> None:
    """Write ``rig`` of the anchor mesh ``gmesh`` (index ``mesh``; its one primitive gets the
    attributes and targets, it gets the default weights) with ``add``
    (:meth:`BufferBuilder.add`); its nodes get file indices from ``first_node`` on and go to
    ``out``."""
    primitive = gmesh.primitives[0]
    name = gmesh.name or "anchor mesh"
    if rig.joints_0 is not None and rig.weights_0 is not None:
        ctype = UNSIGNED_BYTE if len(rig.joints) <= 256 else UNSIGNED_SHORT
        primitive.attributes.JOINTS_0 = add(rig.joints_0, ctype, "VEC4", target=34962)
        primitive.attributes.WEIGHTS_0 = add(rig.weights_0, FLOAT, "VEC4", target=34962)
    if rig.targets:
        gmesh.weights = [float(w) for w in rig.weights]
        primitive.targets = [{"POSITION": add(np.asarray(t, np.float32), FLOAT, "VEC3",
                                              target=34962, minmax=True)}
                             for t in rig.targets]
    anchor = first_node
    out.roots.append(anchor)
    skin = len(out.skins) if rig.skinned else None
    out.nodes.append(pygltflib.Node(name=name, mesh=mesh, skin=skin,
                                    extensions={NODE_VISIBILITY: {"visible": False}}))
    base = first_node + 1
    if rig.nodes and not np.allclose(rig.root_matrix, np.eye(4), atol=0, rtol=0):
        out.roots.append(base)
        out.nodes.append(pygltflib.Node(name=f"{name} frame", children=[
            base + 1 + r for r in rig.roots], matrix=[float(v) for v in rig.root_matrix.T.flat]))
        base += 1
    else:
        out.roots.extend(base + r for r in rig.roots)
    for rn in rig.nodes:
        node = pygltflib.Node(name=rn.name, children=[base + c for c in rn.children] or None)
        if rn.matrix is not None:
            node.matrix = [float(v) for v in rn.matrix.T.flat]
        else:
            node.translation = [float(v) for v in rn.translation]
            node.rotation = [float(v) for v in rn.rotation]
            node.scale = [float(v) for v in rn.scale]
        out.nodes.append(node)
    if rig.skinned:
        assert rig.inverse_bind is not None
        ibm = np.swapaxes(np.asarray(rig.inverse_bind, np.float64), 1, 2).reshape(-1, 16)
        out.skins.append(pygltflib.Skin(
            joints=[base + j for j in rig.joints], inverseBindMatrices=add(ibm, FLOAT, "MAT4"),
            skeleton=None if rig.skeleton is None else base + rig.skeleton))
    for anim in rig.animations:
        samplers, channels = [], []
        for ch in anim.channels:
            values = np.asarray(ch.values, np.float32)
            gtype = "SCALAR" if ch.path == WEIGHTS_PATH else _GTYPE_OF[values.shape[1]]
            if gtype == "SCALAR":
                values = values.reshape(-1)
            samplers.append(pygltflib.AnimationSampler(
                input=add(np.asarray(ch.times, np.float32), FLOAT, "SCALAR", minmax=True),
                output=add(values, FLOAT, gtype), interpolation=ch.interpolation))
            channels.append(pygltflib.AnimationChannel(
                sampler=len(samplers) - 1, target=pygltflib.AnimationChannelTarget(
                    node=anchor if ch.node is None else base + ch.node, path=ch.path)))
        out.animations.append(pygltflib.Animation(name=anim.name, samplers=samplers,
                                                  channels=channels))
