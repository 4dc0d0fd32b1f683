"""The skinned test asset of the conformance suite, and a linear-blend-skinning sampler.

:func:`skinned_tube` writes a small glTF 2.0 asset: an open tube along +Y whose vertices are
weighted to a chain of three joints, with one animation that twists, bends and scales the
chain. :func:`sample_skin` evaluates such an asset at a time ``t`` with glTF semantics:

* node local transform = ``matrix``, or T·R·S from ``translation``/``rotation``/``scale``, with
  animated paths replaced by the sampled channel values (``LINEAR``: lerp for translation and
  scale, slerp for rotation; ``STEP``: the previous key; ``CUBICSPLINE``; times outside the
  keys clamp);
* global transform = product of the local transforms from the scene root down;
* joint matrix ``J_i = global(joint_i) · inverseBindMatrix_i``;
* skinned vertex ``v' = Σ_k w_k J_{j_k} · v`` (``JOINTS_0``/``WEIGHTS_0``, each vertex's
  weights divided by their sum, spec §Animated anchor meshes). As glTF prescribes,
  the transform of the node that instantiates the skinned mesh is not applied.

The skinned positions are in the scene's root space; the splat asset of a skinned case has its
splat node at the root with no transform, so they are the poses of its anchor mesh directly.
"""
from __future__ import annotations

import numpy as np

from ..poses.gltf_animation import GltfAnimation, Instance
from .glb import (FLOAT, UNSIGNED_BYTE, UNSIGNED_SHORT, BufferBuilder, accessor_bytes, pack_glb,
                  unpack_glb)

__all__ = ["tube", "skinned_tube", "sample_skin", "float_accessor"]


def tube(rings: int, segments: int, radius: float, height: float,
         center=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """An open tube along +Y: (vertices (rings·segments, 3) float64, faces (F, 3) uint32).

    Ring ``i`` lies at height ``height · i / (rings − 1)``; faces wind outward.
    """
    y = np.linspace(0.0, height, rings)
    a = 2.0 * np.pi * np.arange(segments) / segments
    v = np.stack([np.broadcast_to(radius * np.cos(a), (rings, segments)),
                  np.broadcast_to(y[:, None], (rings, segments)),
                  np.broadcast_to(-radius * np.sin(a), (rings, segments))], axis=-1)
    v = v.reshape(-1, 3) + np.asarray(center, dtype=np.float64)
    faces = []
    for i in range(rings - 1):
        for j in range(segments):
            p, q = i * segments + j, i * segments + (j + 1) % segments
            r, s = p + segments, q + segments
            faces += [(p, q, s), (p, s, r)]
    return v, np.asarray(faces, dtype=np.uint32)


def _axis_angle(axis, degrees: float) -> list[float]:
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    half = np.radians(degrees) / 2.0
    return [*(np.sin(half) * axis), float(np.cos(half))]


def skinned_tube(rings: int = 7, segments: int = 8, radius: float = 0.2,
                 height: float = 1.2) -> tuple[bytes, np.ndarray, np.ndarray, float]:
    """(GLB bytes, rest vertices float32 (V, 3), faces (F, 3), animation duration in s).

    Three joints at heights 0, h/3 and 2h/3 form a chain (root → middle → tip). Each vertex
    has two influences, blended linearly between the neighbouring joints. The animation
    (``LINEAR``, keys at 0, 0.5 and 1 s) moves and twists the root, bends the middle joint
    about Z, and bends and scales the tip joint.
    """
    vertices, faces = tube(rings, segments, radius, height)
    vertices = vertices.astype(np.float32)
    joint_y = np.array([0.0, height / 3.0, 2.0 * height / 3.0])
    y = vertices[:, 1].astype(np.float64)
    seg = np.clip(np.searchsorted(joint_y, y, side="right") - 1, 0, 1)
    frac = np.clip((y - joint_y[seg]) / (joint_y[seg + 1] - joint_y[seg]), 0.0, 1.0)
    joints = np.zeros((len(y), 4), np.uint8)
    weights = np.zeros((len(y), 4), np.float32)
    joints[:, 0], joints[:, 1] = seg, seg + 1
    weights[:, 0] = (1.0 - frac).astype(np.float32)
    weights[:, 1] = (1.0 - weights[:, 0].astype(np.float64)).astype(np.float32)
    joints[weights == 0.0] = 0   # glTF: unused influences have joint 0

    b = BufferBuilder()
    pos = b.add(vertices, FLOAT, "VEC3", target=34962, minmax=True)
    jnt = b.add(joints, UNSIGNED_BYTE, "VEC4", target=34962)
    wgt = b.add(weights, FLOAT, "VEC4", target=34962)
    idx = b.add(faces.reshape(-1), UNSIGNED_SHORT, "SCALAR", target=34963)
    ibm = np.zeros((3, 4, 4), np.float32)
    for j, yj in enumerate(joint_y):
        m = np.eye(4)
        m[1, 3] = -yj
        ibm[j] = m.T  # glTF matrices are column-major
    ibm_acc = b.add(ibm.reshape(3, 16), FLOAT, "MAT4")

    times = np.array([0.0, 0.5, 1.0], np.float32)
    t_acc = b.add(times, FLOAT, "SCALAR", minmax=True)
    root_t = b.add(np.array([[0, 0, 0], [0.1, 0.0, -0.05], [0.0, 0.08, 0.1]], np.float32),
                   FLOAT, "VEC3")
    root_r = b.add(np.array([_axis_angle((0, 1, 0), 0), _axis_angle((0, 1, 0), 25),
                             _axis_angle((0, 1, 0), -15)], np.float32), FLOAT, "VEC4")
    mid_r = b.add(np.array([_axis_angle((0, 0, 1), 0), _axis_angle((0, 0, 1), 40),
                            _axis_angle((0, 0, 1), 70)], np.float32), FLOAT, "VEC4")
    tip_r = b.add(np.array([_axis_angle((1, 0, 0), 0), _axis_angle((1, 0, 0), -45),
                            _axis_angle((1, 0.2, 0), 30)], np.float32), FLOAT, "VEC4")
    tip_s = b.add(np.array([[1, 1, 1], [1.3, 1.0, 1.3], [0.8, 1.25, 0.8]], np.float32),
                  FLOAT, "VEC3")
    blob = b.finish()
    step = float(height / 3.0)
    doc = {
        "asset": {"version": "2.0", "generator": "gsverse-conformance skinned test asset"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [
            {"name": "skinned tube", "mesh": 0, "skin": 0},
            {"name": "joint root", "children": [2]},
            {"name": "joint middle", "translation": [0.0, step, 0.0], "children": [3]},
            {"name": "joint tip", "translation": [0.0, step, 0.0]},
        ],
        "meshes": [{"name": "tube", "primitives": [{
            "attributes": {"POSITION": pos, "JOINTS_0": jnt, "WEIGHTS_0": wgt},
            "indices": idx, "mode": 4}]}],
        "skins": [{"joints": [1, 2, 3], "inverseBindMatrices": ibm_acc, "skeleton": 1}],
        "animations": [{"name": "bend", "samplers": [
            {"input": t_acc, "output": root_t, "interpolation": "LINEAR"},
            {"input": t_acc, "output": root_r, "interpolation": "LINEAR"},
            {"input": t_acc, "output": mid_r, "interpolation": "LINEAR"},
            {"input": t_acc, "output": tip_r, "interpolation": "LINEAR"},
            {"input": t_acc, "output": tip_s, "interpolation": "LINEAR"},
        ], "channels": [
            {"sampler": 0, "target": {"node": 1, "path": "translation"}},
            {"sampler": 1, "target": {"node": 1, "path": "rotation"}},
            {"sampler": 2, "target": {"node": 2, "path": "rotation"}},
            {"sampler": 3, "target": {"node": 3, "path": "rotation"}},
            {"sampler": 4, "target": {"node": 3, "path": "scale"}},
        ]}],
        "accessors": b.accessors,
        "bufferViews": b.views,
        "buffers": [{"byteLength": len(blob)}],
    }
    return pack_glb(doc, blob), vertices, faces, 1.0


# ------------------------------------------------------------------------------ sampling

def float_accessor(doc: dict, blob: bytes, index: int) -> np.ndarray:
    """Accessor ``index`` of a GLB's ``doc``/``blob`` as float64 (count, components),
    normalized integers dequantized (glTF 2.0 §3.11): the :data:`AccessorFn` of the suite."""
    acc = doc["accessors"][index]
    raw = accessor_bytes(doc, blob, index).astype(np.float64)
    if acc.get("normalized"):
        top = {5121: 255.0, 5123: 65535.0, 5120: 127.0, 5122: 32767.0}[acc["componentType"]]
        raw = np.maximum(raw / top, -1.0)
    return raw


def sample_skin(glb: bytes, t: float, *, animation: int = 0, node: int | None = None) -> np.ndarray:
    """Skinned vertex positions (V, 3) float64 of the first skinned node at time ``t`` (s).

    ``node`` picks the skinned node (default: the first node with both ``mesh`` and ``skin``).
    Linear blend skinning with glTF semantics (see the module docstring), evaluated by
    :class:`gsverse_format.poses.GltfAnimation` (primitive 0 of the node's mesh).
    """
    doc, blob = unpack_glb(glb)
    nodes = doc["nodes"]
    anim = GltfAnimation(doc, lambda i: float_accessor(doc, blob, i),
                         animation if doc.get("animations") else None)
    if node is None:
        node = next(i for i, n in enumerate(nodes) if "mesh" in n and "skin" in n)
    return anim.vertices(t, [Instance(node, int(nodes[node]["mesh"]), 0)])
