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
  (:mod:`.cases_extreme`);
* the rules of spec v1.1 (:mod:`.cases_rules`) and the other valid encodings a reader must
  accept (:mod:`.cases_encodings`: integer localScale, quantized rest pose, byteStride, a
  non-indexed anchor mesh, node transforms).

The building blocks (case records, random anchors, deformations, meshes) are in
:mod:`.case_tools`.
"""
from __future__ import annotations

import numpy as np

from ..model import Anchors, TriangleMesh
from .case_tools import (LAWS, TUBE, Pose, RemapCase, bend, case_rng, faces_from_counts,
                         games_anchors, law_id, law_tags, local_anchors, make_anchors, make_case,
                         random_barycentrics, rest_pose, shake, stretch, taper, tube_mesh, twist)
from .cases_compact import compact_cases
from .cases_encodings import encoding_cases
from .cases_extreme import extreme_cases
from .cases_rules import rule_cases
from .cases_spz import spz_cases
from .skin import sample_skin, skinned_tube

__all__ = ["Pose", "RemapCase", "remap_cases", "LAWS"]


# --------------------------------------------------------------------------- source families

def _source_poses(source: str, mesh: TriangleMesh, rng) -> list[Pose]:
    v = mesh.vertices.astype(np.float64)
    c = (0.0, 0.0, 0.0)
    h = TUBE["height"]
    poses = [rest_pose(mesh)]
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
            cid = f"{law_id(profile, law)}-{source}"
            rng = case_rng(cid)
            mesh = tube_mesh()
            counts = rng.integers(0, 4, mesh.face_count)
            face = faces_from_counts(counts)
            bary = random_barycentrics(rng, len(face))
            anchors = make_anchors(profile, law, mesh, face, bary, rng)
            poses = _source_poses(source, mesh, rng)
            out.append(make_case(cid, f"{profile} profile{f', {law} law' if law else ''}: a tube "
                                 f"under {text[source]}.", law_tags(profile, law) +
                                 [f"source:{source}"], mesh, anchors, poses, rng, degrees[source]))
        out.append(_skinned_case(profile, law))
    return out


def _skinned_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{law_id(profile, law)}-skinned"
    rng = case_rng(cid)
    glb, vertices, faces, duration = skinned_tube()
    mesh = TriangleMesh(vertices, faces)
    counts = rng.integers(0, 3, mesh.face_count)
    face = faces_from_counts(counts)
    anchors = make_anchors(profile, law, mesh, face, random_barycentrics(rng, len(face)), rng)
    poses = [rest_pose(mesh)]
    for t in (0.3, 0.75, 1.0):
        poses.append(Pose(f"skin t={t}s", sample_skin(glb, t),
                          {"kind": "skin", "asset": "skinned.glb", "animation": 0, "time": t}))
    degree = {"affine": 3, "rigid": 0, None: 2}[law]
    return make_case(cid, f"{profile} profile{f', {law} law' if law else ''}: poses sampled from "
                     f"the skinned animation in skinned.glb (three joints, linear blend skinning, "
                     f"times 0.3, 0.75 and 1.0 s).", law_tags(profile, law) + ["source:skin"],
                     mesh, anchors, poses, rng, degree, skinned_asset=glb)


def _per_face_cases() -> list[RemapCase]:
    out = []
    for profile, law in LAWS:
        cid = f"{law_id(profile, law)}-splats-per-face-1-to-6"
        rng = case_rng(cid)
        mesh = tube_mesh()
        face = faces_from_counts(np.arange(mesh.face_count) % 6 + 1)
        anchors = make_anchors(profile, law, mesh, face, random_barycentrics(rng, len(face)), rng)
        v = mesh.vertices.astype(np.float64)
        poses = [rest_pose(mesh),
                 Pose("twist 60 + bend 60",
                      bend(twist(v, 60, (0, 0, 0), 0, 1), 60, (0, 0, 0), 0, 1),
                      {"kind": "analytic", "name": "twist+bend"}),
                 Pose("shake", shake(v, rng, (0, 0.5, 0), 0.02, 0.3),
                      {"kind": "analytic", "name": "shake"})]
        out.append(make_case(cid, f"{profile} profile{f', {law} law' if law else ''}: face f "
                             f"carries (f mod 6) + 1 splats, so every count from 1 to 6 occurs.",
                             law_tags(profile, law) + ["splats_per_face:1-6"], mesh, anchors, poses,
                             rng, (1, 2, 3)[LAWS.index((profile, law))]))
    return out


def _vertex_edge_cases() -> list[RemapCase]:
    out = []
    corners = np.array([[0, 0], [1, 0], [0, 1]], np.float64)
    mids = np.array([[0.5, 0], [0.5, 0.5], [0, 0.5]], np.float64)
    for profile, law in LAWS:
        cid = f"{law_id(profile, law)}-vertices-and-edges"
        rng = case_rng(cid)
        mesh = tube_mesh()
        faces = rng.choice(mesh.face_count, 14, replace=False)
        bary_parts: list[np.ndarray] = []
        face: list[int] = []
        for f in faces:
            s = rng.uniform(0.1, 0.9, 3)
            on_edges = np.array([[s[0], 0.0], [1.0 - s[1], s[1]], [0.0, s[2]]])
            parts = [corners, mids, on_edges]
            if profile == "local":  # feet beyond an edge or corner, as binding produces
                parts.append(np.array([[-0.05, 0.3], [0.6, 0.55], [1.1, -0.08]]))
            pts = np.concatenate(parts)
            bary_parts.append(pts)
            face += [f] * len(pts)
        bary = np.concatenate(bary_parts)
        anchors = make_anchors(profile, law, mesh, face, bary, rng)
        v = mesh.vertices.astype(np.float64)
        poses = [rest_pose(mesh),
                 Pose("bend 120", bend(v, 120, (0, 0, 0), 0, 1),
                      {"kind": "analytic", "name": "bend"}),
                 Pose("shake", shake(v, rng, (0, 0.5, 0), 0.03, 0.2),
                      {"kind": "analytic", "name": "shake"})]
        feet = ", and feet just outside the triangle" if profile == "local" else ""
        out.append(make_case(cid, f"{profile} profile{f', {law} law' if law else ''}: splats "
                             f"exactly at triangle corners, edge midpoints and other edge points"
                             + feet + ".", law_tags(profile, law) + ["placement:vertices-edges"],
                             mesh, anchors, poses, rng, (2, 3, 0)[LAWS.index((profile, law))]))
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
        cid = f"{law_id(profile, law)}-quantized-{name}"
        rng = case_rng(cid)
        # a coarse tube: edges as long as the coordinates, so that a dequantization off by
        # one code step in 65535 moves the means by more than float32 rounding does
        mesh = tube_mesh(rings=3, segments=5, radius=0.6, center=(0.0, -0.5, 0.0))
        face = faces_from_counts(rng.integers(2, 7, mesh.face_count))
        anchors = make_anchors(profile, law, mesh, face, random_barycentrics(rng, len(face)), rng)
        v = mesh.vertices.astype(np.float64)
        c = (0.0, -0.5, 0.0)
        poses = [rest_pose(mesh),
                 Pose("twist 90", twist(v, 90, c, -0.5, 0.5),
                      {"kind": "analytic", "name": "twist"}),
                 Pose("bend 90 + stretch", stretch(bend(v, 90, c, -0.5, 0.5), (1.3, 0.8, 1.0), c),
                      {"kind": "analytic", "name": "bend+stretch"})]
        desc = ", ".join(f"{k} stored as normalized {v.upper()}" for k, v in quant.items())
        out.append(make_case(cid, f"{profile} profile{f', {law} law' if law else ''}: quantized "
                             f"anchor accessors ({desc}); dequantize per glTF and renormalize "
                             f"quaternions.", law_tags(profile, law) +
                             [f"quantized:{k}={v}" for k, v in quant.items()], mesh, anchors, poses,
                             rng, degree, quantize=quant))
    return out


def _face_index_cases() -> list[RemapCase]:
    out = []
    # 16-bit face indices: a long tube with 304 faces.
    cid = "games-face-index-u16"
    rng = case_rng(cid)
    mesh = tube_mesh(rings=20, height=3.0)
    face = np.concatenate([rng.choice(np.arange(256, mesh.face_count), 40, replace=False),
                           rng.choice(256, 20, replace=False)])
    anchors: Anchors = games_anchors(mesh, face, random_barycentrics(rng, len(face)), rng)
    v = mesh.vertices.astype(np.float64)
    poses = [rest_pose(mesh), Pose("bend 150", bend(v, 150, (0, 0, 0), 0, 3.0),
                                   {"kind": "analytic", "name": "bend"})]
    out.append(make_case(cid, "games profile: 304 faces, so faceIndex is UNSIGNED_SHORT; splats on "
                         "faces above 255.", law_tags("games", None) + ["face_index:u16"], mesh,
                         anchors, poses, rng, 0))

    # 32-bit face indices: 65 600 faces over a 9 x 9 vertex sheet (faces repeat).
    cid = "local-rigid-face-index-u32"
    rng = case_rng(cid)
    n = 9
    g = np.arange(n)
    xs, zs = np.meshgrid(g / (n - 1.0), g / (n - 1.0), indexing="ij")
    verts = np.stack([xs.ravel(), np.zeros(n * n), zs.ravel()], axis=1)
    corners_of: list[tuple[int, int, int]] = []
    for i in range(n - 1):
        for j in range(n - 1):
            p, q, r, s = i * n + j, (i + 1) * n + j, (i + 1) * n + j + 1, i * n + j + 1
            corners_of += [(p, s, r), (p, r, q)]
    base = np.asarray(corners_of)
    count = 65600
    faces = base[np.arange(count) % len(base)]
    shift = (np.arange(count) // len(base)) % 3
    faces = np.take_along_axis(faces, (np.arange(3)[None, :] - shift[:, None]) % 3, axis=1)
    mesh = TriangleMesh(verts, faces)
    face = np.concatenate([np.arange(count - 48, count), rng.choice(count - 48, 24, replace=False)])
    anchors = local_anchors(mesh, face, random_barycentrics(rng, len(face)), rng, "rigid")
    v = mesh.vertices.astype(np.float64)
    wave = v.copy()
    wave[:, 1] = 0.2 * np.sin(3.0 * v[:, 0]) * np.cos(2.0 * v[:, 2])
    poses = [rest_pose(mesh),
             Pose("wave", wave, {"kind": "analytic", "name": "wave"}),
             Pose("twist 90", twist(v[:, [0, 2, 1]], 90, (0.5, 0, 0.0), 0, 1)[:, [0, 2, 1]],
                  {"kind": "analytic", "name": "twist"})]
    out.append(make_case(cid, "local profile, rigid law: 65 600 faces, so faceIndex is "
                         "UNSIGNED_INT; splats on faces above 65 535.", law_tags("local", "rigid")
                         + ["face_index:u32"], mesh, anchors, poses, rng, 1))
    return out


def remap_cases() -> list[RemapCase]:
    """All remap cases, in suite order."""
    return (_source_cases() + _per_face_cases() + _vertex_edge_cases() + _quantized_cases()
            + _face_index_cases() + extreme_cases() + rule_cases() + encoding_cases()
            + compact_cases() + spz_cases())
