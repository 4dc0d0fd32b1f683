"""What the remap cases of the conformance suite are made of: the case records, seeded random
anchors and appearance, analytic deformations, and the meshes the cases use.

:mod:`.cases`, :mod:`.cases_extreme`, :mod:`.cases_rules`, :mod:`.cases_encodings` and
:mod:`.invalid_cases` build their cases from these. Everything is deterministic: random numbers
come from generators seeded by the case id (:func:`case_rng`).
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence, cast

import numpy as np
from numpy.typing import ArrayLike

from ..frames import local_frames
from ..model import Anchors, DeformationLaw, GamesAnchors, LocalAnchors, TriangleMesh
from ..poses.analytic import (bend, random_quaternions, random_rotation, shake, stretch,
                               stretch_along, taper, twist)
from .skin import tube

__all__ = ["LAWS", "Pose", "RemapCase", "case_rng", "law_id", "law_tags", "random_quaternions",
           "random_rotation", "face_sizes", "random_barycentrics", "faces_from_counts",
           "local_anchors", "games_anchors", "make_anchors", "sorted_by_face", "appearance",
           "make_case", "stretch", "stretch_along", "taper", "twist", "bend", "shake",
           "rest_pose", "TUBE", "tube_mesh", "soup_mesh", "regular_triangles", "soup_poses"]

#: (profile, deformation law) of every family of cases; law None for ``games``.
LAWS = (("local", "affine"), ("local", "rigid"), ("games", None))


@dataclass
class Pose:
    """One pose of the anchor mesh: ``vertices`` (V, 3) float32, and where it comes from."""

    label: str
    vertices: np.ndarray
    source: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.vertices = np.ascontiguousarray(self.vertices, dtype=np.float32)


@dataclass
class RemapCase:
    """One anchored primitive and the poses it is remapped onto."""

    id: str
    description: str
    tags: list[str]
    mesh: TriangleMesh
    anchors: LocalAnchors | GamesAnchors
    opacities: np.ndarray
    sh: np.ndarray
    poses: list[Pose]
    quantize: dict | None = None
    #: how the writer stores the anchors: ``explicit`` or ``compact`` (version 1.2)
    encoding: str = "explicit"
    #: ``"spz"``: the rest pose written as an SPZ stream (version 1.2; compact anchors only)
    compress: str | None = None
    skinned_asset: bytes | None = None
    #: codes ``gsverse-validate`` reports for the asset although a plugin must remap it
    validator_codes: list[str] = field(default_factory=list)
    note: str = ""
    #: applied to the written, rest-consistent GLB (JSON document, binary chunk): re-encodes
    #: data in other valid layouts (byteStride, quantized rest pose, no indices, node
    #: transforms); the expected outputs are computed from the edited file as read back
    edit: Callable[[dict, bytes], tuple[dict, bytes]] | None = None
    #: rig cases (:mod:`.cases_rig`): the layout of the animated anchor mesh (a ``RigSpec``);
    #: their animated poses are sampled from the written asset (:mod:`.rig_export`)
    rig: Any = None


# --------------------------------------------------------------------------- small helpers

def case_rng(name: str) -> np.random.Generator:
    """A generator seeded by ``name`` (the case id): every case is reproducible."""
    return np.random.default_rng(zlib.crc32(name.encode("utf-8")))


def law_id(profile: str, law: str | None) -> str:
    """``local-affine``, ``local-rigid`` or ``games``: the first part of case ids."""
    return f"local-{law}" if profile == "local" else "games"


def law_tags(profile: str, law: str | None) -> list[str]:
    """The profile and deformation tags of a case."""
    return [f"profile:{profile}"] + ([f"deformation:{law}"] if law else [])


def face_sizes(mesh: TriangleMesh) -> np.ndarray:
    """A length per face: sqrt(area) for regular faces, half the longest edge otherwise."""
    tri = mesh.triangles()
    frames = local_frames(tri)
    edges = np.stack([tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], tri[:, 2] - tri[:, 1]], 1)
    longest = np.linalg.norm(edges, axis=2).max(axis=1)
    size = np.where(frames.regular, np.sqrt(frames.area2 / 2.0), 0.5 * longest)
    fallback = float(np.median(size[size > 0])) if np.any(size > 0) else 1.0
    return np.where(size > 0, size, fallback)


def random_barycentrics(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` uniformly random points of a triangle as (b1, b2)."""
    return rng.dirichlet([1.0, 1.0, 1.0], n)[:, 1:]


def faces_from_counts(counts: ArrayLike) -> np.ndarray:
    """Face indices with face f repeated ``counts[f]`` times."""
    counts = np.asarray(counts, dtype=np.int64)
    return np.repeat(np.arange(len(counts)), counts)


def local_anchors(mesh: TriangleMesh, face_index: ArrayLike, bary: ArrayLike,
                  rng: np.random.Generator, law: str | None, *, scale: float = 0.25,
                  offset: float = 0.3, scales: np.ndarray | None = None,
                  offsets: np.ndarray | None = None) -> LocalAnchors:
    """``local`` anchors: random rotations, anisotropic scales ~ ``scale`` × face size,
    normal offsets uniform in ±``offset`` × face size (explicit arrays override)."""
    face = np.asarray(face_index, dtype=np.int64)
    n = len(face)
    size = face_sizes(mesh)[face]
    if scales is None:
        scales = scale * size[:, None] * np.exp(rng.normal(0.0, 0.6, (n, 3)))
    if offsets is None:
        offsets = offset * size * rng.uniform(-1.0, 1.0, n)
    return LocalAnchors(face, np.asarray(bary), offsets, random_quaternions(rng, n), scales,
                        cast(DeformationLaw, law))


def games_anchors(mesh: TriangleMesh, face_index: ArrayLike, bary: ArrayLike,
                  rng: np.random.Generator, *, rho: np.ndarray | None = None) -> GamesAnchors:
    """``games`` anchors with ρ uniform in [0.3, 1.3] (unless given)."""
    face = np.asarray(face_index, dtype=np.int64)
    if rho is None:
        rho = rng.uniform(0.3, 1.3, len(face))
    return GamesAnchors(face, np.asarray(bary), rho)


def make_anchors(profile: str, law: str | None, mesh: TriangleMesh, face_index: ArrayLike,
                 bary: ArrayLike, rng: np.random.Generator, **kw: Any) -> Anchors:
    """Anchors of ``profile`` (``law`` for ``local``); ``kw`` go to :func:`local_anchors`
    (or only ``rho`` to :func:`games_anchors`)."""
    if profile == "local":
        return local_anchors(mesh, face_index, bary, rng, law, **kw)
    kw = {k: v for k, v in kw.items() if k == "rho"}
    return games_anchors(mesh, face_index, bary, rng, **kw)


def sorted_by_face(anchors: Anchors) -> Anchors:
    """Anchors sorted by face index (stable), as writers store them (spec §Ordering)."""
    order = np.argsort(anchors.face_index, kind="stable")
    return anchors.subset(order)


def appearance(rng: np.random.Generator, n: int, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Random opacities (n,) and SH coefficients (n, (degree + 1)², 3), float32."""
    opacities = rng.uniform(0.02, 1.0, n).astype(np.float32)
    sh = rng.normal(0.0, 0.35, (n, (degree + 1) ** 2, 3)).astype(np.float32)
    return opacities, sh


def make_case(case_id: str, description: str, tags: list[str], mesh: TriangleMesh,
              anchors: Anchors, poses: list[Pose], rng: np.random.Generator, degree: int,
              **kw: Any) -> RemapCase:
    """A remap case: ``anchors`` sorted by face, random opacities and SH of ``degree``."""
    anchors = sorted_by_face(anchors)
    opacities, sh = appearance(rng, len(anchors), degree)
    tags = tags + [f"sh_degree:{degree}"]
    return RemapCase(case_id, description, tags, mesh, anchors, opacities, sh, poses, **kw)


# --------------------------------------------------------------------------- deformations
# stretch, stretch_along, taper, twist, bend and shake live in gsverse_format.poses.analytic

def rest_pose(mesh: TriangleMesh) -> Pose:
    """Pose 0 of every case: the rest mesh."""
    return Pose("rest", mesh.vertices, {"kind": "rest"})


# --------------------------------------------------------------------------- meshes

#: The standard tube: rings, segments, radius, height.
TUBE: dict[str, Any] = dict(rings=5, segments=8, radius=0.25, height=1.0)


def tube_mesh(center: tuple[float, float, float] = (0.0, 0.0, 0.0), **kw: Any) -> TriangleMesh:
    """The standard tube of the suite (:data:`TUBE`; ``kw`` override its parameters)."""
    p = dict(TUBE, **kw)
    v, f = tube(p["rings"], p["segments"], p["radius"], p["height"], center)
    return TriangleMesh(v, f)


def soup_mesh(triangles: ArrayLike) -> TriangleMesh:
    """A mesh of separate triangles (n, 3, 3): no shared vertices."""
    t = np.asarray(triangles, dtype=np.float64).reshape(-1, 3)
    return TriangleMesh(t, np.arange(len(t)).reshape(-1, 3))


def regular_triangles(rng: np.random.Generator, n: int, spacing: float = 3.0,
                      size: float = 1.0) -> np.ndarray:
    """``n`` well-shaped random triangles (n, 3, 3) on a grid ``spacing`` apart."""
    out = np.empty((n, 3, 3))
    for i in range(n):
        while True:
            corners = rng.normal(0.0, size * 0.6, (3, 3))
            e1, e2 = corners[1] - corners[0], corners[2] - corners[0]
            a = np.linalg.norm(np.cross(e1, e2))
            longest = max(np.linalg.norm(e1), np.linalg.norm(e2), np.linalg.norm(e2 - e1))
            if a > 0.3 * longest ** 2 and longest > 0.5 * size:
                break
        out[i] = corners + np.array([spacing * (i % 4), 0.0, spacing * (i // 4)])
    return out


def soup_poses(base: np.ndarray, edits: Sequence[tuple[str, Callable[[np.ndarray], np.ndarray]]],
               mesh: TriangleMesh) -> list[Pose]:
    """The rest pose and one pose per (label, edit of the (n, 3, 3) triangles ``base``)."""
    poses = [rest_pose(mesh)]
    for label, edit in edits:
        tri = edit(base.copy())
        poses.append(Pose(label, tri.reshape(-1, 3), {"kind": "analytic", "name": label}))
    return poses
