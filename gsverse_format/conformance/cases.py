"""The remap cases of the conformance suite: meshes, anchors, poses.

Every *remap case* is one anchored splat primitive (its anchor mesh, its anchors, opacities
and SH) plus a list of poses of the anchor mesh (vertex arrays; pose 0 is always the rest
pose). The invalid assets a plugin must refuse are in :mod:`.invalid_cases`.

Everything is deterministic: random numbers come from generators seeded by the case id.
Coordinates are in the asset's local space (glTF: metres, +Y up); poses are produced in
float64 and rounded once to float32, which is what the suite stores and what every
implementation consumes.

Remap cases cover (see :func:`remap_cases`):

* profiles and laws: ``local``/``affine``, ``local``/``rigid``, ``games``;
* deformation sources: analytic stretch, twist, bend, shake, and a skinned glTF animation
  sampled with linear blend skinning (:mod:`.skin`);
* SH degrees 0–3, 1 to 6 splats per face, splats at corners and on edges (and, for ``local``,
  feet outside the triangle), quantized anchor accessors, 8/16/32-bit face indices;
* extremes: zero-area current triangles (segments, points, ties), faces degenerate at rest,
  slivers, inverted (folded and mirrored) triangles, 100× stretch, 0.01× compression,
  coordinates offset by 10⁵, very small and very large splats, nearly coincident vertices;
* the rules of spec v1.1 (:mod:`.cases_rules`) and the other valid encodings a reader must
  accept (:mod:`.cases_encodings`: integer localScale, quantized rest pose, byteStride, a
  non-indexed anchor mesh, node transforms).
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..frames import local_frames
from ..model import GamesAnchors, LocalAnchors, TriangleMesh
from .skin import sample_skin, skinned_tube, tube

__all__ = ["Pose", "RemapCase", "remap_cases", "LAWS"]

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
    skinned_asset: bytes | None = None
    #: codes ``gsverse-validate`` reports for the asset although a plugin must remap it
    validator_codes: list[str] = field(default_factory=list)
    note: str = ""
    #: applied to the written, rest-consistent GLB (JSON document, binary chunk): re-encodes
    #: data in other valid layouts (byteStride, quantized rest pose, no indices, node
    #: transforms); the expected outputs are computed from the edited file as read back
    edit: Callable[[dict, bytes], tuple[dict, bytes]] | None = None


# --------------------------------------------------------------------------- small helpers

def _rng(name: str) -> np.random.Generator:
    return np.random.default_rng(zlib.crc32(name.encode("utf-8")))


def _law_id(profile: str, law: str | None) -> str:
    return f"local-{law}" if profile == "local" else "games"


def _law_tags(profile: str, law: str | None) -> list[str]:
    return [f"profile:{profile}"] + ([f"deformation:{law}"] if law else [])


def _random_quaternions(rng: np.random.Generator, n: int) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return np.where(q[:, 3:4] < 0, -q, q)


def _rotation(rng: np.random.Generator) -> np.ndarray:
    x, y, z, w = _random_quaternions(rng, 1)[0]
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _face_sizes(mesh: TriangleMesh) -> np.ndarray:
    """A length per face: sqrt(area) for regular faces, half the longest edge otherwise."""
    tri = mesh.triangles()
    frames = local_frames(tri)
    edges = np.stack([tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], tri[:, 2] - tri[:, 1]], 1)
    longest = np.linalg.norm(edges, axis=2).max(axis=1)
    size = np.where(frames.regular, np.sqrt(frames.area2 / 2.0), 0.5 * longest)
    fallback = float(np.median(size[size > 0])) if np.any(size > 0) else 1.0
    return np.where(size > 0, size, fallback)


def _dirichlet(rng: np.random.Generator, n: int) -> np.ndarray:
    return rng.dirichlet([1.0, 1.0, 1.0], n)[:, 1:]


def _faces_from_counts(counts) -> np.ndarray:
    counts = np.asarray(counts, dtype=np.int64)
    return np.repeat(np.arange(len(counts)), counts)


def _local(mesh: TriangleMesh, face, bary, rng, law: str, *, scale: float = 0.25,
           offset: float = 0.3, scales: np.ndarray | None = None,
           offsets: np.ndarray | None = None) -> LocalAnchors:
    """``local`` anchors: random rotations, anisotropic scales ~ ``scale`` × face size,
    normal offsets uniform in ±``offset`` × face size (explicit arrays override)."""
    face = np.asarray(face, dtype=np.int64)
    n = len(face)
    size = _face_sizes(mesh)[face]
    if scales is None:
        scales = scale * size[:, None] * np.exp(rng.normal(0.0, 0.6, (n, 3)))
    if offsets is None:
        offsets = offset * size * rng.uniform(-1.0, 1.0, n)
    return LocalAnchors(face, bary, offsets, _random_quaternions(rng, n), scales, law)


def _games(mesh: TriangleMesh, face, bary, rng, *, rho: np.ndarray | None = None) -> GamesAnchors:
    face = np.asarray(face, dtype=np.int64)
    if rho is None:
        rho = rng.uniform(0.3, 1.3, len(face))
    return GamesAnchors(face, bary, rho)


def _anchors(profile: str, law: str | None, mesh: TriangleMesh, face, bary, rng, **kw):
    if profile == "local":
        return _local(mesh, face, bary, rng, law, **kw)
    kw = {k: v for k, v in kw.items() if k == "rho"}
    return _games(mesh, face, bary, rng, **kw)


def _sorted(anchors):
    """Anchors sorted by face index (stable), as writers store them (spec §Ordering)."""
    order = np.argsort(anchors.face_index, kind="stable")
    return anchors.subset(order)


def _appearance(rng: np.random.Generator, n: int, degree: int) -> tuple[np.ndarray, np.ndarray]:
    opacities = rng.uniform(0.02, 1.0, n).astype(np.float32)
    sh = rng.normal(0.0, 0.35, (n, (degree + 1) ** 2, 3)).astype(np.float32)
    return opacities, sh


def _case(case_id: str, description: str, tags: list[str], mesh: TriangleMesh, anchors,
          poses: list[Pose], rng, degree: int, **kw) -> RemapCase:
    anchors = _sorted(anchors)
    opacities, sh = _appearance(rng, len(anchors), degree)
    tags = tags + [f"sh_degree:{degree}"]
    return RemapCase(case_id, description, tags, mesh, anchors, opacities, sh, poses, **kw)


# --------------------------------------------------------------------------- deformations

def stretch(v: np.ndarray, factors, center) -> np.ndarray:
    """Scale about ``center`` by per-axis ``factors``."""
    c = np.asarray(center, dtype=np.float64)
    return c + (v - c) * np.asarray(factors, dtype=np.float64)


def stretch_along(v: np.ndarray, direction, factor: float, center) -> np.ndarray:
    """Scale by ``factor`` along unit ``direction`` about ``center``."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    rel = v - np.asarray(center, dtype=np.float64)
    along = rel @ d
    return v + (factor - 1.0) * along[:, None] * d[None, :]


def taper(v: np.ndarray, center, y0: float, y1: float, top: float) -> np.ndarray:
    """Scale x and z about the +Y axis through ``center`` by 1 → ``top`` from y0 to y1."""
    c = np.asarray(center, dtype=np.float64)
    s = 1.0 + (top - 1.0) * np.clip((v[:, 1] - y0) / (y1 - y0), 0.0, 1.0)
    out = v.copy()
    out[:, 0] = c[0] + (v[:, 0] - c[0]) * s
    out[:, 2] = c[2] + (v[:, 2] - c[2]) * s
    return out


def twist(v: np.ndarray, degrees: float, center, y0: float, y1: float) -> np.ndarray:
    """Rotate about the +Y axis through ``center`` by an angle growing linearly from 0 at
    y0 to ``degrees`` at y1."""
    c = np.asarray(center, dtype=np.float64)
    a = np.radians(degrees) * (v[:, 1] - y0) / (y1 - y0)
    x, z = v[:, 0] - c[0], v[:, 2] - c[2]
    out = v.copy()
    out[:, 0] = c[0] + np.cos(a) * x + np.sin(a) * z
    out[:, 2] = c[2] - np.sin(a) * x + np.cos(a) * z
    return out


def bend(v: np.ndarray, degrees: float, center, y0: float, y1: float) -> np.ndarray:
    """Bend the +Y axis through ``center`` (from y0 to y1) into a circular arc of total angle
    ``degrees`` in the XY plane, keeping arc length on the axis."""
    c = np.asarray(center, dtype=np.float64)
    theta_total = np.radians(degrees)
    radius = (y1 - y0) / theta_total
    s = v[:, 1] - y0
    xr = v[:, 0] - c[0]
    theta = s / radius
    out = v.copy()
    out[:, 0] = c[0] - radius + (radius + xr) * np.cos(theta)
    out[:, 1] = y0 + (radius + xr) * np.sin(theta)
    return out


def shake(v: np.ndarray, rng: np.random.Generator, center, amplitude: float,
          move: float) -> np.ndarray:
    """A random rigid motion about ``center`` (translation up to ``move``) plus independent
    per-vertex noise of standard deviation ``amplitude``."""
    c = np.asarray(center, dtype=np.float64)
    r = _rotation(rng)
    t = rng.uniform(-move, move, 3)
    return (v - c) @ r.T + c + t + rng.normal(0.0, amplitude, v.shape)


def _rest_pose(mesh: TriangleMesh) -> Pose:
    return Pose("rest", mesh.vertices, {"kind": "rest"})


# --------------------------------------------------------------------------- meshes

_TUBE = dict(rings=5, segments=8, radius=0.25, height=1.0)


def _tube_mesh(center=(0.0, 0.0, 0.0), **kw) -> TriangleMesh:
    p = dict(_TUBE, **kw)
    v, f = tube(p["rings"], p["segments"], p["radius"], p["height"], center)
    return TriangleMesh(v, f)


def _soup(triangles) -> TriangleMesh:
    t = np.asarray(triangles, dtype=np.float64).reshape(-1, 3)
    return TriangleMesh(t, np.arange(len(t)).reshape(-1, 3))


def _regular_triangles(rng: np.random.Generator, n: int, spacing: float = 3.0,
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


def _soup_poses(base: np.ndarray, edits: list[tuple[str, Callable[[np.ndarray], np.ndarray]]],
                mesh: TriangleMesh) -> list[Pose]:
    poses = [_rest_pose(mesh)]
    for label, edit in edits:
        tri = edit(base.copy())
        poses.append(Pose(label, tri.reshape(-1, 3), {"kind": "analytic", "name": label}))
    return poses


# --------------------------------------------------------------------------- source families

def _source_poses(source: str, mesh: TriangleMesh, rng) -> list[Pose]:
    v = mesh.vertices.astype(np.float64)
    c = (0.0, 0.0, 0.0)
    h = _TUBE["height"]
    poses = [_rest_pose(mesh)]
    if source == "stretch":
        specs = [("stretch y 1.5x", stretch(v, (1.0, 1.5, 1.0), c)),
                 ("stretch x 0.6x, z 1.4x", stretch(v, (0.6, 1.0, 1.4), c)),
                 ("taper to 2.5x at the top", taper(v, c, 0.0, h, 2.5))]
    elif source == "twist":
        specs = [(f"twist {d} deg", twist(v, d, c, 0.0, h)) for d in (30, 90, 180)]
    elif source == "bend":
        specs = [(f"bend {d} deg", bend(v, d, c, 0.0, h)) for d in (45, 90, 180)]
    elif source == "shake":
        specs = [(f"shake {i}", shake(v, rng, (0, 0.5, 0), 0.01 * (i + 1), 0.5))
                 for i in range(3)]
    else:
        raise ValueError(source)
    for label, verts in specs:
        poses.append(Pose(label, verts, {"kind": "analytic", "name": source, "label": label}))
    return poses


def _source_cases() -> list[RemapCase]:
    out = []
    degrees = {"stretch": 0, "twist": 1, "bend": 2, "shake": 3}
    text = {"stretch": "uniform-axis and tapering stretches",
            "twist": "twists of 30, 90 and 180 degrees about the tube axis",
            "bend": "bends of 45, 90 and 180 degrees",
            "shake": "random rigid motions plus per-vertex noise (as a physics solver jitters)"}
    for profile, law in LAWS:
        for source in ("stretch", "twist", "bend", "shake"):
            cid = f"{_law_id(profile, law)}-{source}"
            rng = _rng(cid)
            mesh = _tube_mesh()
            counts = rng.integers(0, 4, mesh.face_count)
            face = _faces_from_counts(counts)
            anchors = _anchors(profile, law, mesh, face, _dirichlet(rng, len(face)), rng)
            poses = _source_poses(source, mesh, rng)
            out.append(_case(cid, f"{profile} profile{f', {law} law' if law else ''}: a tube "
                             f"under {text[source]}.", _law_tags(profile, law) +
                             [f"source:{source}"], mesh, anchors, poses, rng, degrees[source]))
        out.append(_skinned_case(profile, law))
    return out


def _skinned_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{_law_id(profile, law)}-skinned"
    rng = _rng(cid)
    glb, vertices, faces, duration = skinned_tube()
    mesh = TriangleMesh(vertices, faces)
    counts = rng.integers(0, 3, mesh.face_count)
    face = _faces_from_counts(counts)
    anchors = _anchors(profile, law, mesh, face, _dirichlet(rng, len(face)), rng)
    poses = [_rest_pose(mesh)]
    for t in (0.3, 0.75, 1.0):
        poses.append(Pose(f"skin t={t}s", sample_skin(glb, t),
                          {"kind": "skin", "asset": "skinned.glb", "animation": 0, "time": t}))
    degree = {"affine": 3, "rigid": 0, None: 2}[law]
    return _case(cid, f"{profile} profile{f', {law} law' if law else ''}: poses sampled from "
                 f"the skinned animation in skinned.glb (three joints, linear blend skinning, "
                 f"times 0.3, 0.75 and 1.0 s).", _law_tags(profile, law) + ["source:skin"],
                 mesh, anchors, poses, rng, degree, skinned_asset=glb)


def _per_face_cases() -> list[RemapCase]:
    out = []
    for profile, law in LAWS:
        cid = f"{_law_id(profile, law)}-splats-per-face-1-to-6"
        rng = _rng(cid)
        mesh = _tube_mesh()
        face = _faces_from_counts(np.arange(mesh.face_count) % 6 + 1)
        anchors = _anchors(profile, law, mesh, face, _dirichlet(rng, len(face)), rng)
        v = mesh.vertices.astype(np.float64)
        poses = [_rest_pose(mesh),
                 Pose("twist 60 + bend 60",
                      bend(twist(v, 60, (0, 0, 0), 0, 1), 60, (0, 0, 0), 0, 1),
                      {"kind": "analytic", "name": "twist+bend"}),
                 Pose("shake", shake(v, rng, (0, 0.5, 0), 0.02, 0.3),
                      {"kind": "analytic", "name": "shake"})]
        out.append(_case(cid, f"{profile} profile{f', {law} law' if law else ''}: face f carries "
                         f"(f mod 6) + 1 splats, so every count from 1 to 6 occurs.",
                         _law_tags(profile, law) + ["splats_per_face:1-6"], mesh, anchors, poses,
                         rng, (1, 2, 3)[LAWS.index((profile, law))]))
    return out


def _vertex_edge_cases() -> list[RemapCase]:
    out = []
    corners = np.array([[0, 0], [1, 0], [0, 1]], np.float64)
    mids = np.array([[0.5, 0], [0.5, 0.5], [0, 0.5]], np.float64)
    for profile, law in LAWS:
        cid = f"{_law_id(profile, law)}-vertices-and-edges"
        rng = _rng(cid)
        mesh = _tube_mesh()
        faces = rng.choice(mesh.face_count, 14, replace=False)
        bary, face = [], []
        for f in faces:
            s = rng.uniform(0.1, 0.9, 3)
            on_edges = np.array([[s[0], 0.0], [1.0 - s[1], s[1]], [0.0, s[2]]])
            pts = [corners, mids, on_edges]
            if profile == "local":  # feet beyond an edge or corner, as binding produces
                pts.append(np.array([[-0.05, 0.3], [0.6, 0.55], [1.1, -0.08]]))
            pts = np.concatenate(pts)
            bary.append(pts)
            face += [f] * len(pts)
        bary = np.concatenate(bary)
        anchors = _anchors(profile, law, mesh, face, bary, rng)
        v = mesh.vertices.astype(np.float64)
        poses = [_rest_pose(mesh),
                 Pose("bend 120", bend(v, 120, (0, 0, 0), 0, 1),
                      {"kind": "analytic", "name": "bend"}),
                 Pose("shake", shake(v, rng, (0, 0.5, 0), 0.03, 0.2),
                      {"kind": "analytic", "name": "shake"})]
        out.append(_case(cid, f"{profile} profile{f', {law} law' if law else ''}: splats exactly "
                         f"at triangle corners, edge midpoints and other edge points"
                         + (", and feet just outside the triangle" if profile == "local" else "")
                         + ".", _law_tags(profile, law) + ["placement:vertices-edges"], mesh,
                         anchors, poses, rng, (2, 3, 0)[LAWS.index((profile, law))]))
    return out


def _quantized_cases() -> list[RemapCase]:
    specs = [("local", "affine", {"barycentrics": "unsigned_short", "localRotation": "short"}, 1),
             ("local", "rigid", {"barycentrics": "unsigned_byte", "localRotation": "byte"}, 2),
             ("local", "affine", {"barycentrics": "unsigned_byte", "localRotation": "short"}, 0),
             ("games", None, {"barycentrics": "unsigned_short"}, 3),
             ("games", None, {"barycentrics": "unsigned_byte"}, 1)]
    out = []
    for profile, law, quant, degree in specs:
        short = {"unsigned_short": "u16", "unsigned_byte": "u8", "short": "i16", "byte": "i8"}
        name = "-".join(f"{'bary' if k == 'barycentrics' else 'rot'}-{short[v]}"
                        for k, v in quant.items())
        cid = f"{_law_id(profile, law)}-quantized-{name}"
        rng = _rng(cid)
        # a coarse tube: edges as long as the coordinates, so that a dequantization off by
        # one code step in 65535 moves the means by more than float32 rounding does
        mesh = _tube_mesh(rings=3, segments=5, radius=0.6, center=(0.0, -0.5, 0.0))
        face = _faces_from_counts(rng.integers(2, 7, mesh.face_count))
        anchors = _anchors(profile, law, mesh, face, _dirichlet(rng, len(face)), rng)
        v = mesh.vertices.astype(np.float64)
        c = (0.0, -0.5, 0.0)
        poses = [_rest_pose(mesh),
                 Pose("twist 90", twist(v, 90, c, -0.5, 0.5),
                      {"kind": "analytic", "name": "twist"}),
                 Pose("bend 90 + stretch", stretch(bend(v, 90, c, -0.5, 0.5), (1.3, 0.8, 1.0), c),
                      {"kind": "analytic", "name": "bend+stretch"})]
        desc = ", ".join(f"{k} stored as normalized {v.upper()}" for k, v in quant.items())
        out.append(_case(cid, f"{profile} profile{f', {law} law' if law else ''}: quantized "
                         f"anchor accessors ({desc}); dequantize per glTF and renormalize "
                         f"quaternions.", _law_tags(profile, law) +
                         [f"quantized:{k}={v}" for k, v in quant.items()], mesh, anchors, poses,
                         rng, degree, quantize=quant))
    return out


def _face_index_cases() -> list[RemapCase]:
    out = []
    # 16-bit face indices: a long tube with 304 faces.
    cid = "games-face-index-u16"
    rng = _rng(cid)
    mesh = _tube_mesh(rings=20, height=3.0)
    face = np.concatenate([rng.choice(np.arange(256, mesh.face_count), 40, replace=False),
                           rng.choice(256, 20, replace=False)])
    anchors = _games(mesh, face, _dirichlet(rng, len(face)), rng)
    v = mesh.vertices.astype(np.float64)
    poses = [_rest_pose(mesh), Pose("bend 150", bend(v, 150, (0, 0, 0), 0, 3.0),
                                    {"kind": "analytic", "name": "bend"})]
    out.append(_case(cid, "games profile: 304 faces, so faceIndex is UNSIGNED_SHORT; splats on "
                     "faces above 255.", _law_tags("games", None) + ["face_index:u16"], mesh,
                     anchors, poses, rng, 0))

    # 32-bit face indices: 65 600 faces over a 9 x 9 vertex sheet (faces repeat).
    cid = "local-rigid-face-index-u32"
    rng = _rng(cid)
    n = 9
    g = np.arange(n)
    xs, zs = np.meshgrid(g / (n - 1.0), g / (n - 1.0), indexing="ij")
    verts = np.stack([xs.ravel(), np.zeros(n * n), zs.ravel()], axis=1)
    base = []
    for i in range(n - 1):
        for j in range(n - 1):
            p, q, r, s = i * n + j, (i + 1) * n + j, (i + 1) * n + j + 1, i * n + j + 1
            base += [(p, s, r), (p, r, q)]
    base = np.asarray(base)
    count = 65600
    faces = base[np.arange(count) % len(base)]
    shift = (np.arange(count) // len(base)) % 3
    faces = np.take_along_axis(faces, (np.arange(3)[None, :] - shift[:, None]) % 3, axis=1)
    mesh = TriangleMesh(verts, faces)
    face = np.concatenate([np.arange(count - 48, count), rng.choice(count - 48, 24, replace=False)])
    anchors = _local(mesh, face, _dirichlet(rng, len(face)), rng, "rigid")
    v = mesh.vertices.astype(np.float64)
    wave = v.copy()
    wave[:, 1] = 0.2 * np.sin(3.0 * v[:, 0]) * np.cos(2.0 * v[:, 2])
    poses = [_rest_pose(mesh),
             Pose("wave", wave, {"kind": "analytic", "name": "wave"}),
             Pose("twist 90", twist(v[:, [0, 2, 1]], 90, (0.5, 0, 0.0), 0, 1)[:, [0, 2, 1]],
                  {"kind": "analytic", "name": "twist"})]
    out.append(_case(cid, "local profile, rigid law: 65 600 faces, so faceIndex is "
                     "UNSIGNED_INT; splats on faces above 65 535.", _law_tags("local", "rigid")
                     + ["face_index:u32"], mesh, anchors, poses, rng, 1))
    return out


# --------------------------------------------------------------------------- extremes

def _zero_area_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{_law_id(profile, law)}-zero-area-pose"
    rng = _rng(cid)
    base = _regular_triangles(rng, 8).astype(np.float32).astype(np.float64)
    mesh = _soup(base)

    def segments(t):
        t[0, 2] = 0.5 * (t[0, 0] + t[0, 1])          # v2 at the middle of v0v1
        t[1, 2] = t[1, 0] + 1.5 * (t[1, 1] - t[1, 0])  # v2 beyond v1 on the same line
        t[2, 1] = t[2, 0]                              # v1 = v0: |e2| = |v2 - v1| tie
        t[3, 2] = t[3, 1]                              # v2 = v1: |e1| = |e2| tie
        t[4, 2] = t[4, 0]                              # v2 = v0: |e1| = |v2 - v1| tie
        t[5, :] = t[5].mean(axis=0)                    # a point
        t[6] += 0.25                                   # controls: regular, moved
        return t

    def points_and_axes(t):
        for i in range(3):
            t[i, :] = t[i, 0]                           # points
        o = np.array([1.0, 2.0, 0.5])
        t[3] = o + np.array([[0.0, 0, 0], [1.0, 0, 0], [0.25, 0, 0]])   # along +x: perp ties
        t[4] = o + np.array([[0.0, 0, 0], [0.5, 0.5, 0.5], [1.0, 1.0, 1.0]])  # (1,1,1)
        t[5] = o + np.array([[-0.25, -0.5, 0], [0.0, 0, 0], [0.25, 0.5, 0]])  # v1 = centroid
        return t

    def general(t):
        d = np.array([0.3, -0.7, 0.45])
        for i in range(6):
            p = t[i, 0]
            t[i] = p + np.outer([0.0, 1.0 + 0.1 * i, 0.4 + 0.05 * i], d)
        t[6, 1] = t[6, 0] + 0.01 * (t[6, 1] - t[6, 0])  # regular but small
        return t

    poses = _soup_poses(base, [("segments and ties", segments),
                               ("points and axis-aligned segments", points_and_axes),
                               ("segments in a general direction", general)], mesh)
    counts = np.full(8, 5)
    face = _faces_from_counts(counts)
    anchors = _anchors(profile, law, mesh, face, _dirichlet(rng, len(face)), rng)
    return _case(cid, f"{profile} profile{f', {law} law' if law else ''}: triangles posed to "
                 f"zero area: segments (with equal-length ties between edges), single points, "
                 f"axis-aligned segments (ties in the perpendicular axis rule), and the games "
                 f"case v1 = centroid. The degenerate-triangle rules of the spec apply.",
                 _law_tags(profile, law) + ["extreme:zero-area", "degenerate:current"], mesh,
                 anchors, poses, rng, 1)


def _degenerate_rest_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{_law_id(profile, law)}-degenerate-rest"
    rng = _rng(cid)
    base = _regular_triangles(rng, 6).astype(np.float64)
    base[0, 2] = 0.5 * (base[0, 0] + base[0, 1])  # segment
    base[1, 1] = base[1, 0]                        # v1 = v0
    base[2, :] = base[2, 0]                        # a point
    base[3, 2] = base[3, 1]                        # v2 = v1
    base = base.astype(np.float32).astype(np.float64)
    mesh = _soup(base)
    opened = rng.normal(0.0, 0.4, (4, 3, 3))
    r = _rotation(rng)

    def moved(t):
        return (t.reshape(-1, 3) @ r.T + np.array([0.5, -1.0, 2.0])).reshape(-1, 3, 3)

    def opened_up(t):
        t[:4] += opened
        return t

    def opened_stretched(t):
        t[:4] += opened
        return stretch(t.reshape(-1, 3), (1.6, 0.7, 1.2), (4, 0, 2)).reshape(-1, 3, 3)

    poses = _soup_poses(base, [("rigid motion, still degenerate", moved),
                               ("opened into triangles", opened_up),
                               ("opened and stretched", opened_stretched)], mesh)
    face = _faces_from_counts([6, 6, 6, 6, 3, 3])
    anchors = _anchors(profile, law, mesh, face, _dirichlet(rng, len(face)), rng)
    rule = ("the local rule for faces degenerate at rest applies (G := I, k := 1: the splat "
            "moves and rotates with the current frame, unscaled)"
            if profile == "local" else "games rebuilds frames from the current triangle only")
    return _case(cid, f"{profile} profile{f', {law} law' if law else ''}: splats bound to faces "
                 f"that are degenerate at rest (a segment, a zero edge, a point; writers must "
                 f"not do this, readers must still produce finite output): {rule}.",
                 _law_tags(profile, law) + ["extreme:degenerate-rest", "degenerate:rest",
                                            "degenerate:current"], mesh, anchors, poses, rng, 0,
                 validator_codes=["ANCHOR_BOUND_TO_DEGENERATE", "MESH_DEGENERATE_TRIANGLES"],
                 note="gsverse-validate reports this asset (writers MUST NOT bind splats to "
                      "faces degenerate at rest), but a plugin MUST NOT refuse it: spec "
                      "section 'Faces degenerate at rest' requires finite output by the rule "
                      "above.")


def _sliver_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{_law_id(profile, law)}-sliver"
    rng = _rng(cid)
    base = _regular_triangles(rng, 8)
    for i, h in zip(range(4), (1e-2, 1e-3, 1e-3, 2e-3)):
        v0, v1 = base[i, 0], base[i, 1]
        e = v1 - v0
        perp = np.cross(e, rng.normal(size=3))
        perp /= np.linalg.norm(perp)
        base[i, 2] = v0 + rng.uniform(0.2, 0.8) * e + h * np.linalg.norm(e) * perp
    base = base.astype(np.float32).astype(np.float64)
    mesh = _soup(base)
    r = _rotation(rng)

    def rotated(t):
        return (t.reshape(-1, 3) @ r.T).reshape(-1, 3, 3)

    def squashed(t):
        for i in range(4, 8):   # regular triangles squashed to height 1e-3 of their base
            v0, v1, v2 = t[i]
            e = v1 - v0
            foot = v0 + np.dot(v2 - v0, e) / np.dot(e, e) * e
            t[i, 2] = foot + 1e-3 * np.linalg.norm(e) * (v2 - foot) / np.linalg.norm(v2 - foot)
        for i in range(4):      # slivers stretched 3x along their long edge
            c = t[i].mean(axis=0)
            t[i] = stretch_along(t[i], t[i, 1] - t[i, 0], 3.0, c)
        return t

    def opened(t):
        for i in range(4):      # slivers opened to regular triangles
            v0, v1, v2 = t[i]
            e = v1 - v0
            foot = v0 + np.dot(v2 - v0, e) / np.dot(e, e) * e
            t[i, 2] = foot + 0.5 * np.linalg.norm(e) * (v2 - foot) / np.linalg.norm(v2 - foot)
        return t

    poses = _soup_poses(base, [("rotated", rotated), ("squashed and stretched", squashed),
                               ("slivers opened", opened)], mesh)
    face = _faces_from_counts(np.full(8, 5))
    kw = {"scale": 0.05} if profile == "local" else {}
    anchors = _anchors(profile, law, mesh, face, _dirichlet(rng, len(face)), rng, **kw)
    return _case(cid, f"{profile} profile{f', {law} law' if law else ''}: sliver triangles "
                 f"(height 1e-3 to 1e-2 of the longest edge, above the 1e-6 degenerate "
                 f"threshold) at rest and posed, stretched along their length, and opened.",
                 _law_tags(profile, law) + ["extreme:sliver"], mesh, anchors, poses, rng, 2)


def _inverted_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{_law_id(profile, law)}-inverted"
    rng = _rng(cid)
    base = _regular_triangles(rng, 8).astype(np.float32).astype(np.float64)
    mesh = _soup(base)

    def reflect(p, a, b):
        e = (b - a) / np.linalg.norm(b - a)
        foot = a + np.dot(p - a, e) * e
        return 2 * foot - p

    def fold_v2(t):
        for i in range(0, 8, 2):
            t[i, 2] = reflect(t[i, 2], t[i, 0], t[i, 1])
        return t

    r = _rotation(rng)

    def fold_v1_rotated(t):
        for i in range(1, 8, 2):
            t[i, 1] = reflect(t[i, 1], t[i, 0], t[i, 2]) * 1.0
            t[i, 1] += 0.2 * (t[i, 1] - t[i, 0])
        return (t.reshape(-1, 3) @ r.T).reshape(-1, 3, 3)

    def mirrored(t):
        t[..., 0] *= -1.0
        return t

    poses = _soup_poses(base, [("v2 folded across e1", fold_v2),
                               ("v1 folded across e2, stretched, rotated", fold_v1_rotated),
                               ("whole mesh mirrored in x", mirrored)], mesh)
    face = _faces_from_counts(np.full(8, 5))
    anchors = _anchors(profile, law, mesh, face, _dirichlet(rng, len(face)), rng)
    return _case(cid, f"{profile} profile{f', {law} law' if law else ''}: inverted triangles "
                 f"(a corner folded across the opposite edge, and the whole mesh mirrored): "
                 f"the frame follows the winding, no reflection is applied.",
                 _law_tags(profile, law) + ["extreme:inverted"], mesh, anchors, poses, rng, 3)


def _stretch100_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{_law_id(profile, law)}-stretch-100x"
    rng = _rng(cid)
    mesh = _tube_mesh()
    v = mesh.vertices.astype(np.float64)
    c = (0.0, 0.5, 0.0)
    poses = [_rest_pose(mesh)] + [
        Pose(label, verts, {"kind": "analytic", "name": "stretch", "label": label})
        for label, verts in [("100x along y", stretch(v, (1, 100, 1), c)),
                             ("100x along x", stretch(v, (100, 1, 1), c)),
                             ("100x along (1, 1, 0)", stretch_along(v, (1, 1, 0), 100.0, c))]]
    face = _faces_from_counts(rng.integers(0, 3, mesh.face_count))
    anchors = _anchors(profile, law, mesh, face, _dirichlet(rng, len(face)), rng)
    return _case(cid, f"{profile} profile{f', {law} law' if law else ''}: the tube stretched "
                 f"100x along one direction.", _law_tags(profile, law) + ["extreme:stretch-100x"],
                 mesh, anchors, poses, rng, 1)


def _compress_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{_law_id(profile, law)}-compress-0.01x"
    rng = _rng(cid)
    mesh = _tube_mesh()
    v = mesh.vertices.astype(np.float64)
    c = (0.0, 0.5, 0.0)
    poses = [_rest_pose(mesh)] + [
        Pose(label, verts, {"kind": "analytic", "name": "compress", "label": label})
        for label, verts in [("0.01x along y", stretch(v, (1, 0.01, 1), c)),
                             ("0.01x along x", stretch(v, (0.01, 1, 1), c)),
                             ("0.01x uniformly", stretch(v, (0.01, 0.01, 0.01), c))]]
    face = _faces_from_counts(rng.integers(0, 3, mesh.face_count))
    anchors = _anchors(profile, law, mesh, face, _dirichlet(rng, len(face)), rng)
    return _case(cid, f"{profile} profile{f', {law} law' if law else ''}: the tube compressed "
                 f"to 0.01x along one direction and uniformly.",
                 _law_tags(profile, law) + ["extreme:compress-0.01x"], mesh, anchors, poses,
                 rng, 2)


def _offset_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{_law_id(profile, law)}-offset-1e5"
    rng = _rng(cid)
    offset = np.array([1.0e5, 1.0e5, -1.0e5])
    v0, faces = tube(5, 8, 2.0, 8.0)
    mesh = TriangleMesh(v0 + offset, faces)
    v = mesh.vertices.astype(np.float64) - offset   # float32 positions, relative to the offset
    poses = [_rest_pose(mesh)] + [
        Pose(label, verts + offset, {"kind": "analytic", "name": label})
        for label, verts in [("twist 90", twist(v, 90, (0, 0, 0), 0, 8)),
                             ("bend 90", bend(v, 90, (0, 0, 0), 0, 8)),
                             ("shake", shake(v, rng, (0, 4, 0), 0.05, 1.0))]]
    face = _faces_from_counts(rng.integers(0, 3, mesh.face_count))
    anchors = _anchors(profile, law, mesh, face, _dirichlet(rng, len(face)), rng)
    return _case(cid, f"{profile} profile{f', {law} law' if law else ''}: a tube of radius 2 "
                 f"with coordinates offset by 1e5 (float32 spacing 0.0078 there). Compute "
                 f"relative to the triangle's first corner: edges and centroids subtracted "
                 f"first keep their accuracy.", _law_tags(profile, law) + ["extreme:offset-1e5"],
                 mesh, anchors, poses, rng, 0)


def _extreme_scale_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{_law_id(profile, law)}-extreme-scales"
    rng = _rng(cid)
    mesh = _tube_mesh()
    face = _faces_from_counts(np.full(mesh.face_count, 2))
    n = len(face)
    size = _face_sizes(mesh)[face]
    kind = np.arange(n) % 4
    if profile == "local":
        mag = np.select([kind == 0, kind == 1, kind == 2], [1e-6, 1e3, 1.0], 1.0)
        scales = size[:, None] * mag[:, None] * np.exp(rng.normal(0.0, 0.5, (n, 3)))
        mixed = kind == 3     # one axis tiny, one huge
        scales[mixed] = size[mixed, None] * np.array([1e-6, 1.0, 1e3])
        anchors = _local(mesh, face, _dirichlet(rng, n), rng, law, scales=scales)
    else:
        rho = np.select([kind == 0, kind == 1, kind == 2], [1e-6, 1e3, 0.0], 1.0) \
            * rng.uniform(0.5, 1.5, n)
        anchors = _games(mesh, face, _dirichlet(rng, n), rng, rho=rho)
    v = mesh.vertices.astype(np.float64)
    poses = [_rest_pose(mesh),
             Pose("twist 90", twist(v, 90, (0, 0, 0), 0, 1), {"kind": "analytic", "name": "twist"}),
             Pose("stretch", stretch(v, (2.0, 0.5, 1.0), (0, 0.5, 0)),
                  {"kind": "analytic", "name": "stretch"})]
    what = ("scales from 1e-6 to 1e3 times the face size, and splats with one axis at 1e-6 "
            "and another at 1e3" if profile == "local"
            else "rho of 1e-6, 1e3 and 0 (the scales then fall to the GaMeS floor 1e-8)")
    return _case(cid, f"{profile} profile{f', {law} law' if law else ''}: very small and very "
                 f"large splats: {what}.", _law_tags(profile, law) + ["extreme:scales"], mesh,
                 anchors, poses, rng, 3)


def _near_coincident_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{_law_id(profile, law)}-near-coincident-vertices"
    rng = _rng(cid)
    tris = []
    for i in range(6):   # micro triangles (edges ~1e-5) near coordinates of size 1
        c = np.array([0.7, 0.3, -0.4]) + 0.01 * i
        tris.append(c + _regular_triangles(rng, 1, size=1e-5)[0])
    for i in range(4):   # micro triangles (edges ~1e-7) at the origin
        tris.append(_regular_triangles(rng, 1, size=1e-7)[0] + 1e-6 * i)
    big = _regular_triangles(rng, 2, spacing=2.0)
    tris += [big[0], big[1]]
    verts = np.concatenate(tris).astype(np.float32)
    faces = np.arange(len(verts)).reshape(-1, 3)
    # a seam: a triangle sharing an edge of big[0] through duplicated vertices one float32
    # step apart (different indices, nearly the same position)
    a = np.nextafter(verts[-6], np.float32(np.inf))
    b = np.nextafter(verts[-5], np.float32(-np.inf))
    far = (verts[-6] + verts[-5]) / 2 + np.float32(0.8) * (verts[-6] - verts[-4])
    verts = np.concatenate([verts, np.stack([a, b, far]).astype(np.float32)])
    faces = np.concatenate([faces, [[len(verts) - 2, len(verts) - 3, len(verts) - 1]]])
    mesh = TriangleMesh(verts, faces)
    v = mesh.vertices.astype(np.float64)
    r = _rotation(rng)
    poses = [_rest_pose(mesh),
             Pose("rigid motion", v @ r.T + np.array([0.1, -0.2, 0.3]),
                  {"kind": "analytic", "name": "rigid"}),
             Pose("stretch x 2", stretch(v, (2.0, 1.0, 1.0), (0.5, 0.0, 0.0)),
                  {"kind": "analytic", "name": "stretch"}),
             Pose("twist 45", twist(v, 45, (0.7, 0, -0.4), -1, 1),
                  {"kind": "analytic", "name": "twist"})]
    face = _faces_from_counts(np.full(mesh.face_count, 4))
    anchors = _anchors(profile, law, mesh, face, _dirichlet(rng, len(face)), rng)
    return _case(cid, f"{profile} profile{f', {law} law' if law else ''}: nearly coincident "
                 f"vertices: micro triangles with edges of 1e-5 at coordinates near 1 and of "
                 f"1e-7 near the origin (the degenerate test is relative, never absolute), and "
                 f"a seam whose duplicated vertices are one float32 step apart.",
                 _law_tags(profile, law) + ["extreme:near-coincident"], mesh, anchors, poses,
                 rng, 1)


def _extreme_cases() -> list[RemapCase]:
    out = []
    for make in (_zero_area_case, _degenerate_rest_case, _sliver_case, _inverted_case,
                 _stretch100_case, _compress_case, _offset_case, _extreme_scale_case,
                 _near_coincident_case):
        for profile, law in LAWS:
            out.append(make(profile, law))
    return out


def remap_cases() -> list[RemapCase]:
    """All remap cases, in suite order."""
    from .cases_encodings import encoding_cases   # these modules build on the helpers of
    from .cases_rules import rule_cases           # this one

    return (_source_cases() + _per_face_cases() + _vertex_edge_cases() + _quantized_cases()
            + _face_index_cases() + _extreme_cases() + rule_cases() + encoding_cases())
