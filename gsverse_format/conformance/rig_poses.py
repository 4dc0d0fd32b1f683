"""The poses of the rig cases: sampled from the asset's own animation, shipped as the deformed
vertices p′ and the splat node's matrix, and brought into the splat primitive's local space.

spec/README.md §Animated anchor meshes: at time t an engine morphs and skins the anchor mesh
(p′; skinned vertices are in the scene's global space, glTF ignores the transform of the node
that instantiates a skinned mesh), then, for a skinned mesh, takes M⁻¹ · p′ (M the global
matrix of the splat node); a morph-only mesh's p′ is already splat-local. The suite ships p′
per pose (``poses/deformed_NNN.f32``, float32) and M (``rig.splat_node_matrix``), so that a
harness without a glTF animation sampler still performs the M⁻¹ step itself
(:func:`splat_local`); one with a sampler samples ``asset.glb`` at the pose's ``time``
(:func:`sample_rig`) and must match the same expected outputs.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..poses.gltf_animation import GltfAnimation, Instance
from ..poses.gltf_source import anchor_instances
from .glb import unpack_glb
from .skin import float_accessor

__all__ = ["RigPose", "RigPoses", "rig_pose_list", "DEFORMED_FILE", "rig_layout", "sample_rig", "splat_local",
           "splat_node_matrix"]

#: The deformed vertices p′ of pose NNN of a rig case, relative to the case folder.
DEFORMED_FILE = "poses/deformed_{:03d}.f32"


@dataclass
class RigPose:
    """One pose of a rig case: where it comes from, p′ and the splat-local vertices (V, 3)
    float64."""

    label: str
    source: dict
    deformed: np.ndarray
    local: np.ndarray

    @property
    def vertices(self) -> np.ndarray:
        """The splat-local vertices the expected outputs are computed from."""
        return self.local


@dataclass
class RigPoses:
    """The poses of a rig case and the ``rig`` block of its manifest."""

    poses: list[RigPose]
    layout: dict


def _splat_node(doc: dict) -> int | None:
    for m, mesh in enumerate(doc.get("meshes") or []):
        if any("KHR_gaussian_splatting" in (p.get("extensions") or {})
               for p in mesh.get("primitives", [])):
            users = [i for i, n in enumerate(doc.get("nodes") or []) if n.get("mesh") == m]
            return users[0] if users else None
    return None


def _anchor(doc: dict, blob: bytes, animation: int | None,
            weights: Callable[[np.ndarray], np.ndarray] | None) -> tuple[GltfAnimation, Instance]:
    anim = GltfAnimation(doc, lambda i: float_accessor(doc, blob, i), animation, weights=weights)
    instances = anchor_instances(anim)
    if len(instances) != 1:
        raise ValueError(f"expected one instantiated anchor mesh, found {len(instances)}")
    return anim, instances[0]


def rig_layout(glb: bytes) -> dict:
    """The ``rig`` block of a rig case's manifest: the splat node and its global matrix M at
    rest (column-major, as glTF's ``node.matrix``), the anchor node, whether the anchor mesh is
    skinned (then the local vertices are M⁻¹ · p′) or morph-only (p′), hidden or drawn."""
    doc, blob = unpack_glb(glb)
    anim, inst = _anchor(doc, blob, None, None)
    splat = _splat_node(doc)
    m = anim.node_matrix(splat) if splat is not None else np.eye(4)
    node = doc["nodes"][inst.node]
    prim = doc["meshes"][inst.mesh]["primitives"][inst.primitive]
    skinned = node.get("skin") is not None
    hidden = (node.get("extensions") or {}).get("KHR_node_visibility", {}).get("visible") is False
    return {"splat_node": splat, "anchor_node": inst.node, "skinned": skinned,
            "morphed": bool(prim.get("targets")), "anchor_node_hidden": hidden,
            "splat_node_matrix": [float(v) for v in m.T.reshape(-1)],
            "local_vertices": "M^-1 p'" if skinned else "p'"}


def splat_node_matrix(rig: dict) -> np.ndarray:
    """M (4, 4) float64 from a manifest's ``rig`` block."""
    return np.asarray(rig["splat_node_matrix"], dtype=np.float64).reshape(4, 4).T


def splat_local(deformed: np.ndarray, rig: dict) -> np.ndarray:
    """Step 3 in float64: M⁻¹ · p′ for a skinned anchor mesh, p′ for a morph-only one."""
    p = np.asarray(deformed, dtype=np.float64)
    if not rig["skinned"]:
        return p
    inv = np.linalg.inv(splat_node_matrix(rig))
    return p @ inv[:3, :3].T + inv[:3, 3]


def sample_rig(glb: bytes, sources: list[dict], *,
               weights: Callable[[np.ndarray], np.ndarray] | None = None,
               inverse: bool = True) -> list[tuple[np.ndarray, np.ndarray]]:
    """(p′, splat-local vertices) float64 for every pose ``source`` (``{"kind": "rest"}``, or
    ``{"kind": "animation", "animation": a, "time": t}``) of the asset ``glb``.

    ``weights`` replaces the normalization of the skin weights and ``inverse=False`` skips
    M⁻¹: both only to build the broken engines the suite must catch."""
    doc, blob = unpack_glb(glb)
    out = []
    cache: dict = {}
    splat = _splat_node(doc)
    for src in sources:
        a = src.get("animation") if src["kind"] == "animation" else None
        if a not in cache:
            cache[a] = _anchor(doc, blob, a, weights)
        anim, inst = cache[a]
        t = src["time"] if src["kind"] == "animation" else None
        deformed, local = anim.anchor_pose(t, inst, splat if inverse else None)
        out.append((deformed, local))
    return out


def rig_pose_list(case, asset_path) -> RigPoses:
    """The poses of rig case ``case`` (a ``RemapCase`` with ``rig``) sampled from its written
    asset: the rest, then the file's animation ``case.rig.animation`` at ``case.rig.times``."""
    with open(asset_path, "rb") as handle:
        glb = handle.read()
    spec = case.rig
    sources = [{"kind": "rest"}] + [{"kind": "animation", "animation": spec.animation,
                                     "time": float(t)} for t in spec.times]
    labels = ["rest"] + [f"animation {spec.animation} at t={t}s" for t in spec.times]
    sampled = sample_rig(glb, sources)
    layout = dict(rig_layout(glb), animation=spec.animation)
    return RigPoses([RigPose(label, src, d, loc) for label, src, (d, loc)
                     in zip(labels, sources, sampled)], layout)
