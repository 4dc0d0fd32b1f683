"""glTF 2.0 animation with glTF semantics: keyframe sampling, node transforms, morph targets
and linear blend skinning.

Everything works on the plain JSON document (a ``dict``) and an accessor function
``accessor(index) -> (count, ncomp) float64`` that returns an accessor's elements dequantized
(glTF 2.0 §3.11); files are opened by :mod:`.gltf_source` with the package's hardened glTF
reader, the conformance suite passes its own GLB bytes.

* Channel sampling (glTF 2.0 §3.11 Animations): ``STEP`` takes the previous key, ``LINEAR``
  interpolates linearly (``rotation``: spherical linear interpolation, shortest arc),
  ``CUBICSPLINE`` is the cubic Hermite spline of the spec (in-tangent, value, out-tangent per
  key, tangents scaled by the key interval; rotations normalized afterwards). Times before the
  first key or after the last clamp to the first or last value.
* Node local transform: ``matrix`` (column-major), or T·R·S from
  ``translation``/``rotation``/``scale``; animated paths replace the node's values (a node with
  ``matrix`` is not animated, as glTF requires). Global transform = product from the scene
  root down.
* Morph targets: ``POSITION' = POSITION + Σ_i w_i · target_i.POSITION`` with the weights of
  the ``weights`` channel of the node, else ``node.weights``, else ``mesh.weights``, else 0.
* Skinning: joint matrix ``J_i = global(joint_i) · inverseBindMatrix_i``; skinned vertex
  ``v' = Σ_k w_k · J_{j_k} · v`` over every ``JOINTS_n``/``WEIGHTS_n`` set, the weights of a
  vertex normalized first (divided by their sum; all zero: weight 1 on its first influence),
  as three.js does and spec/README.md §Animated anchor meshes prescribes. As glTF prescribes,
  the transform of the node that instantiates a skinned mesh is not applied. A mesh without a
  skin is placed by its node's global transform.
* The anchor mesh of an anchored asset (:meth:`GltfAnimation.anchor_pose`, spec/README.md
  §Animated anchor meshes steps 1–3): the morphed and skinned vertices p′ (the anchor node's
  own transform ignored, skinned or not), then M⁻¹ · p′ for a skinned mesh, M the global matrix
  of the splat node at the same time; a morph-only mesh's p′ is already splat-local.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..errors import FormatError
from ..limits import MAX_NODE_DEPTH
from ..quaternion import to_matrix
from ..rig import normalized_weights

__all__ = ["AccessorFn", "Instance", "GltfAnimation", "slerp", "sample_channel",
           "INTERPOLATIONS"]

#: ``accessor(index)`` -> its elements as float64 (count, components), dequantized.
AccessorFn = Callable[[int], np.ndarray]
INTERPOLATIONS = ("LINEAR", "STEP", "CUBICSPLINE")
_TRIANGLES = 4


def slerp(a: np.ndarray, b: np.ndarray, s: float) -> np.ndarray:
    """Spherical linear interpolation of unit quaternions (x, y, z, w), shortest arc."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    dot = float(np.dot(a, b))
    if dot < 0.0:
        b, dot = -b, -dot
    if dot > 0.9995:
        q = a + s * (b - a)
        return q / np.linalg.norm(q)
    theta = np.arccos(dot)
    return (np.sin((1 - s) * theta) * a + np.sin(s * theta) * b) / np.sin(theta)


def sample_channel(times: np.ndarray, values: np.ndarray, mode: str, path: str,
                   t: float) -> np.ndarray:
    """The value of one animation sampler at time ``t`` (s).

    ``times`` (K,) key times; ``values`` (K, n) for ``LINEAR``/``STEP`` or (3K, n) for
    ``CUBICSPLINE`` (in-tangent, value, out-tangent per key); ``path`` is the target path
    (``rotation`` interpolates spherically and is normalized).
    """
    if mode not in INTERPOLATIONS:
        raise FormatError(f"animation sampler interpolation {mode!r} is not one of "
                          f"{', '.join(INTERPOLATIONS)}")
    k_count = len(times)
    cubic = mode == "CUBICSPLINE"
    if k_count == 0 or len(values) != (3 * k_count if cubic else k_count):
        raise FormatError(f"animation sampler has {len(times)} key times but {len(values)} "
                          f"output values (interpolation {mode})")

    def value(k: int) -> np.ndarray:
        return values[3 * k + 1] if cubic else values[k]

    if t <= times[0]:
        out = value(0)
    elif t >= times[-1]:
        out = value(k_count - 1)
    else:
        k = int(np.searchsorted(times, t, side="right") - 1)
        dt = float(times[k + 1] - times[k])
        s = (t - times[k]) / dt
        if mode == "STEP":
            out = value(k)
        elif cubic:
            s2, s3 = s * s, s * s * s
            out = ((2 * s3 - 3 * s2 + 1) * values[3 * k + 1]
                   + (s3 - 2 * s2 + s) * dt * values[3 * k + 2]
                   + (-2 * s3 + 3 * s2) * values[3 * k + 4]
                   + (s3 - s2) * dt * values[3 * k + 3])
        elif path == "rotation":
            out = slerp(value(k), value(k + 1), s)
        else:
            out = (1.0 - s) * value(k) + s * value(k + 1)
    if path == "rotation":
        norm = np.linalg.norm(out)
        out = out / norm if norm > 0 else np.array([0.0, 0.0, 0.0, 1.0])
    return np.asarray(out, dtype=np.float64)


@dataclass(frozen=True)
class Instance:
    """One drawn triangle primitive: ``node`` instantiates ``mesh``; ``primitive`` of it."""

    node: int
    mesh: int
    primitive: int


class GltfAnimation:
    """Poses of the triangle primitives of a glTF document at any time of one animation.

    ``doc`` is the JSON document, ``accessor`` an :data:`AccessorFn`; ``animation`` an index,
    a name, or None for no animation (the rest pose: node values and default weights).
    ``weights`` turns a skinned primitive's (V, n) skin weights into the ones blended; the
    default is the spec's normalization (:func:`gsverse_format.rig.normalized_weights`); the
    conformance suite passes the identity to build an engine that skips it.
    """

    def __init__(self, doc: dict, accessor: AccessorFn, animation: int | str | None = 0, *,
                 weights: Callable[[np.ndarray], np.ndarray] | None = None):
        self.doc = doc
        self.blend_weights = weights or (lambda w: normalized_weights(w).weights)
        self.accessor = accessor
        self.nodes: list[dict] = list(doc.get("nodes") or [])
        anims = list(doc.get("animations") or [])
        self.animation_names = [str(a.get("name", f"animation {i}")) for i, a in enumerate(anims)]
        self.animation: dict | None = None
        if animation is not None and anims:
            if isinstance(animation, str) and not animation.isdigit():
                if animation not in self.animation_names:
                    raise FormatError(f"no animation named {animation!r}; the file has "
                                      f"{', '.join(map(repr, self.animation_names))}")
                index = self.animation_names.index(animation)
            else:
                index = int(animation)
                if not 0 <= index < len(anims):
                    raise FormatError(f"animation {index} does not exist; the file has "
                                      f"{len(anims)}")
            self.animation = anims[index]
        self._cache: dict[int, np.ndarray] = {}
        self._rest_locals: dict[int, np.ndarray] = {}

    def _floats(self, index: int) -> np.ndarray:
        if index not in self._cache:
            self._cache[index] = np.asarray(self.accessor(index), dtype=np.float64)
        return self._cache[index]

    # ----------------------------------------------------------------- time

    def duration(self) -> float:
        """The last key time of the animation (0 without one)."""
        if self.animation is None:
            return 0.0
        ends = [float(self._floats(s["input"])[:, 0].max(initial=0.0))
                for s in self.animation.get("samplers", [])]
        return max(ends, default=0.0)

    def check_key_times(self) -> None:
        """:class:`FormatError` when a sampler of the animation has a key time that is not a
        finite number (its duration and every pose would be NaN)."""
        if self.animation is None:
            return
        for k, s in enumerate(self.animation.get("samplers", [])):
            if not np.all(np.isfinite(self._floats(s["input"]))):
                raise FormatError(f"animation {self.animation.get('name', '')!r} sampler {k}: "
                                  f"a key time is not a finite number (NaN or infinite)")

    def _overrides(self, t: float) -> dict[int, dict[str, np.ndarray]]:
        out: dict[int, dict[str, np.ndarray]] = {}
        if self.animation is None:
            return out
        samplers = self.animation.get("samplers", [])
        for ch in self.animation.get("channels", []):
            target = ch.get("target", {})
            if "node" not in target:
                continue   # channels of other extensions (KHR_animation_pointer)
            s = samplers[ch["sampler"]]
            path = target["path"]
            if path not in ("translation", "rotation", "scale", "weights"):
                continue
            times = self._floats(s["input"])[:, 0]
            values = self._floats(s["output"])
            mode = s.get("interpolation", "LINEAR")
            if path == "weights":   # K·n scalars (×3 for CUBICSPLINE): one row per key
                per = (3 if mode == "CUBICSPLINE" else 1) * len(times)
                values = values.reshape(per, -1)
            out.setdefault(int(target["node"]), {})[path] = sample_channel(
                times, values, mode, path, t)
        return out

    # ----------------------------------------------------------------- transforms

    def _local(self, i: int, animated: dict[str, np.ndarray]) -> np.ndarray:
        """Node ``i``'s local matrix; the nodes' own values computed once (a pose source of
        many nodes is posed many times, and only animated nodes change)."""
        if not animated:
            if i not in self._rest_locals:
                self._rest_locals[i] = self._compose(i, {})
            return self._rest_locals[i]
        return self._compose(i, animated)

    def _compose(self, i: int, animated: dict[str, np.ndarray]) -> np.ndarray:
        node = self.nodes[i]
        if node.get("matrix") is not None:
            return np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T
        t = np.asarray(animated.get("translation", node.get("translation", [0, 0, 0])), float)
        r = np.asarray(animated.get("rotation", node.get("rotation", [0, 0, 0, 1])), float)
        s = np.asarray(animated.get("scale", node.get("scale", [1, 1, 1])), float)
        m = np.eye(4)
        m[:3, :3] = to_matrix(r) * s[None, :]
        m[:3, 3] = t
        return m

    def _roots(self) -> list[int]:
        scenes = self.doc.get("scenes") or []
        if not scenes:
            children = {c for n in self.nodes for c in n.get("children", [])}
            return [i for i in range(len(self.nodes)) if i not in children]
        chosen = self.doc.get("scene", 0)
        return list(scenes[chosen if isinstance(chosen, int) and 0 <= chosen < len(scenes)
                           else 0].get("nodes", []))

    def _traverse(self, overrides: dict[int, dict[str, np.ndarray]]
                  ) -> tuple[dict[int, np.ndarray], list[int]]:
        """Global matrices of every node of the scene, and the nodes in visiting order (the
        order in which :func:`gsverse_format.io.mesh.read_mesh` concatenates glTF meshes)."""
        world: dict[int, np.ndarray] = {}
        order: list[int] = []
        stack = [(n, np.eye(4), 0) for n in self._roots()]
        while stack:
            i, parent, depth = stack.pop()
            if depth > len(self.nodes):
                raise FormatError("the node hierarchy has a cycle")
            if depth >= MAX_NODE_DEPTH:
                raise FormatError(f"the node hierarchy is more than {MAX_NODE_DEPTH} levels "
                                  f"deep (node {i})")
            world[i] = parent @ self._local(i, overrides.get(i, {}))
            order.append(i)
            stack.extend((c, world[i], depth + 1) for c in self.nodes[i].get("children", []))
        return world, order

    def instances(self) -> list[Instance]:
        """Every TRIANGLES primitive drawn by the scene, in reading order."""
        _, order = self._traverse({})
        out = []
        meshes = self.doc.get("meshes") or []
        for i in order:
            m = self.nodes[i].get("mesh")
            if m is None:
                continue
            for p, prim in enumerate(meshes[m].get("primitives", [])):
                if prim.get("mode", _TRIANGLES) == _TRIANGLES:
                    out.append(Instance(i, int(m), p))
        return out

    # ----------------------------------------------------------------- vertices

    def _morphed(self, inst: Instance, weights: np.ndarray | None) -> np.ndarray:
        mesh = self.doc["meshes"][inst.mesh]
        prim = mesh["primitives"][inst.primitive]
        v = self._floats(prim["attributes"]["POSITION"])[:, :3].copy()
        targets = prim.get("targets") or []
        if not targets:
            return v
        if weights is None:
            node = self.nodes[inst.node]
            weights = np.asarray(node.get("weights", mesh.get("weights", [0.0] * len(targets))),
                                 dtype=np.float64)
        if len(weights) != len(targets):
            raise FormatError(f"mesh {inst.mesh} has {len(targets)} morph targets but "
                              f"{len(weights)} weights")
        for w, target in zip(weights, targets):
            if w != 0.0 and "POSITION" in target:
                v += w * self._floats(target["POSITION"])[:, :3]
        return v

    def _skinned(self, inst: Instance, v: np.ndarray, world: dict[int, np.ndarray]) -> np.ndarray:
        node = self.nodes[inst.node]
        skin = self.doc["skins"][node["skin"]]
        joints = skin["joints"]
        if "inverseBindMatrices" in skin:
            ibm = self._floats(skin["inverseBindMatrices"]).reshape(-1, 4, 4)
            ibm = np.swapaxes(ibm, 1, 2)   # column-major storage
        else:
            ibm = np.broadcast_to(np.eye(4), (len(joints), 4, 4))
        missing = [j for j in joints if j not in world]
        if missing:
            raise FormatError(f"skin {node['skin']}: joint node {missing[0]} is not in the scene")
        mats = np.stack([world[j] @ ibm[k] for k, j in enumerate(joints)])
        attrs = self.doc["meshes"][inst.mesh]["primitives"][inst.primitive]["attributes"]
        homo = np.concatenate([v, np.ones((len(v), 1))], axis=1)
        sets_j, sets_w = [], []
        n = 0
        while f"JOINTS_{n}" in attrs and f"WEIGHTS_{n}" in attrs:
            jn = self._floats(attrs[f"JOINTS_{n}"]).astype(np.intp)
            if jn.size and (jn.min() < 0 or jn.max() >= len(joints)):
                raise FormatError(f"mesh {inst.mesh}: JOINTS_{n} refers to joint "
                                  f"{int(jn.max())} of a skin with {len(joints)} joints")
            sets_j.append(jn)
            sets_w.append(self._floats(attrs[f"WEIGHTS_{n}"]))
            n += 1
        if n == 0:
            raise FormatError(f"skinned mesh {inst.mesh} has no JOINTS_0/WEIGHTS_0")
        jn = np.concatenate(sets_j, axis=1)
        wt = self.blend_weights(np.concatenate(sets_w, axis=1))
        out = np.zeros((len(v), 4))
        for k in range(jn.shape[1]):
            out += wt[:, k:k + 1] * np.einsum("nij,nj->ni", mats[jn[:, k]], homo)
        return out[:, :3]

    def vertices(self, t: float | None, instances: list[Instance] | None = None) -> np.ndarray:
        """Posed vertex positions (V, 3) float64 of ``instances`` (default: all of
        :meth:`instances`) concatenated, at time ``t`` (None: the rest pose)."""
        overrides = self._overrides(float(t)) if t is not None else {}
        world, _ = self._traverse(overrides)
        parts = []
        for inst in (self.instances() if instances is None else instances):
            node = self.nodes[inst.node]
            v = self._morphed(inst, overrides.get(inst.node, {}).get("weights"))
            if node.get("skin") is not None:
                parts.append(self._skinned(inst, v, world))
            else:
                m = world[inst.node]
                parts.append(v @ m[:3, :3].T + m[:3, 3])
        if not parts:
            raise FormatError("the file has no triangle primitives in its scene")
        return np.concatenate(parts)

    def node_matrix(self, node: int, t: float | None = None) -> np.ndarray:
        """The global 4×4 matrix (float64) of ``node`` at time ``t`` (None: the nodes' own
        values); :class:`FormatError` when no scene reaches it."""
        world, _ = self._traverse(self._overrides(float(t)) if t is not None else {})
        if node not in world:
            raise FormatError(f"node {node} is not in the scene")
        return world[node]

    def anchor_pose(self, t: float | None, inst: Instance,
                    splat_node: int | None) -> tuple[np.ndarray, np.ndarray]:
        """The anchor mesh ``inst`` at time ``t`` (None: the rest pose), spec/README.md
        §Animated anchor meshes: (p′, vertices in the splat primitive's local space), (V, 3)
        float64 each. p′ is morphed and, when the node has a skin, skinned (scene global
        space); the anchor node's own transform is never applied. The local vertices are
        M⁻¹ · p′ for a skinned mesh (M the global matrix of ``splat_node`` at ``t``; the
        identity for None) and p′ for a morph-only one. :class:`FormatError` for a singular M."""
        overrides = self._overrides(float(t)) if t is not None else {}
        world, _ = self._traverse(overrides)
        v = self._morphed(inst, overrides.get(inst.node, {}).get("weights"))
        if self.nodes[inst.node].get("skin") is None:
            return v, v
        deformed = self._skinned(inst, v, world)
        if splat_node is None:
            return deformed, deformed
        m = world.get(splat_node)
        if m is None:
            raise FormatError(f"the splat node {splat_node} is not in the scene")
        if not (np.all(np.isfinite(m)) and abs(np.linalg.det(m[:3, :3])) > 0.0):
            raise FormatError(f"the global matrix of the splat node {splat_node} is singular")
        inv = np.linalg.inv(m)
        return deformed, deformed @ inv[:3, :3].T + inv[:3, 3]

    def animates(self, instances: list[Instance]) -> bool:
        """Whether any of ``instances`` has a skin or morph targets."""
        for inst in instances:
            prim = self.doc["meshes"][inst.mesh]["primitives"][inst.primitive]
            if self.nodes[inst.node].get("skin") is not None or prim.get("targets"):
                return True
        return False
