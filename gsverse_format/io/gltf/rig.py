"""Writing the skin, morph targets and animations of an animated anchor mesh
(:class:`gsverse_format.rig.AnchorRig`; spec/README.md §Animated anchor meshes). Reading them
from a ``--mesh character.glb`` is :mod:`.rig_read`.

Writing (:func:`write_rig`): the anchor mesh's primitive gets ``JOINTS_0``/``WEIGHTS_0`` and
``targets``, one node instances it with the skin, hidden by ``KHR_node_visibility``, at the
scene root beside the splat nodes; the rig's nodes follow (under a node holding
``root_matrix`` when that is not the identity), then the skin and the animations.
"""
from __future__ import annotations

from typing import Callable

import numpy as np
import pygltflib

from ...rig import WEIGHTS_PATH, AnchorRig
from ...vocabulary import FLOAT, NODE_VISIBILITY, UNSIGNED_BYTE, UNSIGNED_SHORT

__all__ = ["write_rig", "RigOutput"]

_GTYPE_OF = {1: "SCALAR", 3: "VEC3", 4: "VEC4"}


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
