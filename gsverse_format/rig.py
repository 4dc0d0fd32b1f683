"""The animation data of an animated anchor mesh (:class:`AnchorRig`): a skin, its joint node
hierarchy, per-vertex joints and weights, morph targets and animations as sampler arrays.

Held by :attr:`gsverse_format.model.TriangleMesh.rig`; read from a skinned/morphed glTF mesh
(``--mesh character.glb``, :mod:`gsverse_format.io.gltf.rig`) and written back beside the anchor
mesh (spec/README.md §Animated anchor meshes). Indices are the rig's own (into
:attr:`AnchorRig.nodes`), never the source file's; a writer renumbers them.

Spaces: the mesh's vertices are the rest positions in the splat primitive's local space: what
glTF draws with the skeleton at its nodes' own values (spec §Animated anchor meshes), so that
the skinned vertex of glTF ``Σ w_k · global(joint_k) · inverseBind_k · v``, with ``global``
starting from ``root_matrix`` (the transform of the space the rig's root nodes live in: the
frame change the converter applied), is ``v`` itself at rest and in the splat primitive's
local space at every pose.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .quaternion import to_matrix

__all__ = ["RigNode", "RigChannel", "RigAnimation", "AnchorRig", "WEIGHTS_PATH",
           "WEIGHT_SUM_TOLERANCE", "normalized_weights", "WeightsNormalized"]

#: ``RigChannel.path`` of the morph-target weights of the anchor mesh's node.
WEIGHTS_PATH = "weights"

#: |Σ weights − 1| a vertex's skin weights may differ by and count as normalized: float32 sums of
#: four weights, and 8/16-bit normalized integers (steps 1/255: a sum of four rounded weights
#: may be off by 2/255 ≈ 8·10⁻³ in theory, exporters round to a sum of 255) stay within it.
WEIGHT_SUM_TOLERANCE = 2e-3


@dataclass(frozen=True)
class WeightsNormalized:
    """:func:`normalized_weights`: the weights (V, n) float64, how many vertices were not
    normalized (|Σ − 1| above :data:`WEIGHT_SUM_TOLERANCE`), the largest change of one weight,
    and the vertices whose weights are all zero."""

    weights: np.ndarray
    changed: int
    max_change: float
    max_sum_error: float
    all_zero: np.ndarray


def normalized_weights(weights: np.ndarray) -> WeightsNormalized:
    """Skin weights (V, n) as readers use them (spec/README.md §Animated anchor meshes, as
    three.js's ``SkinnedMesh.normalizeSkinWeights``): each vertex's weights divided by their
    sum (float64) when it is > 0; a vertex whose weights are all zero gets weight 1 on its first
    influence (listed in ``all_zero``: a writer refuses it rather than choose a joint)."""
    w = np.asarray(weights, dtype=np.float64)
    total = w.sum(axis=1, keepdims=True)
    zero = total[:, 0] <= 0.0
    out = np.divide(w, total, out=np.zeros_like(w), where=~zero[:, None])
    if w.shape[1]:
        out[zero, 0] = 1.0
    error = np.abs(total[:, 0] - 1.0)
    moved = np.abs(out - w).max(axis=1) if w.shape[1] else np.zeros(len(w))
    changed = ~(error <= WEIGHT_SUM_TOLERANCE) | zero
    return WeightsNormalized(out, int(np.count_nonzero(changed)),
                             float(moved.max()) if len(w) else 0.0,
                             float(error.max()) if len(w) else 0.0, np.flatnonzero(zero))


@dataclass
class RigNode:
    """A node of the joint hierarchy: local ``matrix`` (4, 4) or T·R·S, and its children
    (indices into :attr:`AnchorRig.nodes`)."""

    name: str | None
    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rotation: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]))
    scale: np.ndarray = field(default_factory=lambda: np.ones(3))
    matrix: np.ndarray | None = None
    children: list[int] = field(default_factory=list)

    def local(self) -> np.ndarray:
        """The node's local 4×4 matrix (``matrix``, else T·R·S), float64."""
        if self.matrix is not None:
            return np.asarray(self.matrix, dtype=np.float64)
        m = np.eye(4)
        m[:3, :3] = to_matrix(np.asarray(self.rotation, np.float64)) * np.asarray(
            self.scale, np.float64)[None, :]
        m[:3, 3] = self.translation
        return m


@dataclass
class RigChannel:
    """One animated property: ``node`` (index into the rig's nodes, or ``None`` for the
    anchor mesh's node, whose only animated ``path`` is ``weights``), key ``times`` (K,),
    ``values`` (K or 3K, n) and glTF ``interpolation``."""

    node: int | None
    path: str
    times: np.ndarray
    values: np.ndarray
    interpolation: str = "LINEAR"


@dataclass
class RigAnimation:
    name: str | None
    channels: list[RigChannel]


@dataclass
class AnchorRig:
    """Skin, morph targets and animations of an anchor mesh (see the module docstring)."""

    nodes: list[RigNode] = field(default_factory=list)
    roots: list[int] = field(default_factory=list)
    #: skin: joint node indices, (J, 4, 4) inverse bind matrices (row-major), optional skeleton
    joints: list[int] = field(default_factory=list)
    inverse_bind: np.ndarray | None = None
    skeleton: int | None = None
    #: per vertex (V, 4) joint indices (into ``joints``) and weights
    joints_0: np.ndarray | None = None
    weights_0: np.ndarray | None = None
    #: morph targets: POSITION deltas (V, 3) each, and the default weights
    targets: list[np.ndarray] = field(default_factory=list)
    weights: list[float] = field(default_factory=list)
    animations: list[RigAnimation] = field(default_factory=list)
    root_matrix: np.ndarray = field(default_factory=lambda: np.eye(4))
    #: what reading the rig changed or approximated (summary notes of the conversion)
    notes: list[str] = field(default_factory=list)

    def rest_globals(self) -> np.ndarray:
        """(N, 4, 4) float64 global matrices of :attr:`nodes` at their own values (the rest
        pose), from ``root_matrix`` down."""
        out = np.zeros((len(self.nodes), 4, 4))
        stack = [(r, np.asarray(self.root_matrix, np.float64)) for r in self.roots]
        seen = 0
        while stack:
            i, parent = stack.pop()
            seen += 1
            if seen > len(self.nodes):
                raise ValueError("the rig's node hierarchy has a cycle or a shared child")
            out[i] = parent @ self.nodes[i].local()
            stack.extend((c, out[i]) for c in self.nodes[i].children)
        return out

    @property
    def skinned(self) -> bool:
        return bool(self.joints)

    def transformed(self, linear: np.ndarray,
                    translation: np.ndarray | None = None) -> "AnchorRig":
        """The rig of the mesh whose vertices were mapped by the 3×3 ``linear`` and then moved
        by ``translation`` (a frame change, or an edit): the roots' space gets that affine
        map, the inverse bind matrices its inverse on the right, the morph deltas ``linear``;
        skinned vertices move by the same map."""
        m = np.eye(4)
        m[:3, :3] = np.asarray(linear, dtype=np.float64)
        if translation is not None:
            m[:3, 3] = np.asarray(translation, dtype=np.float64)
        inv = np.linalg.inv(m)
        ibm = None if self.inverse_bind is None else self.inverse_bind @ inv
        targets = [np.asarray(t, np.float64) @ m[:3, :3].T for t in self.targets]
        return replace(self, inverse_bind=ibm, targets=targets, root_matrix=m @ self.root_matrix)
