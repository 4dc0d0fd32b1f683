"""Remap cases at the extremes: zero-area current triangles (segments, points, ties), faces
degenerate at rest, slivers, inverted (folded and mirrored) triangles, 100× stretch, 0.01×
compression, coordinates offset by 10⁵, very small and very large splats, nearly coincident
vertices — each for every profile and law (:data:`.case_tools.LAWS`).
"""
from __future__ import annotations

import numpy as np

from ..model import Anchors, TriangleMesh
from .case_tools import (LAWS, Pose, RemapCase, bend, case_rng, face_sizes, faces_from_counts,
                         games_anchors, law_id, law_tags, local_anchors, make_anchors, make_case,
                         random_barycentrics, random_rotation, regular_triangles, rest_pose,
                         shake, soup_mesh, soup_poses, stretch, stretch_along, tube_mesh, twist)
from .skin import tube

__all__ = ["extreme_cases"]


def _zero_area_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{law_id(profile, law)}-zero-area-pose"
    rng = case_rng(cid)
    base = regular_triangles(rng, 8).astype(np.float32).astype(np.float64)
    mesh = soup_mesh(base)

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

    poses = soup_poses(base, [("segments and ties", segments),
                              ("points and axis-aligned segments", points_and_axes),
                              ("segments in a general direction", general)], mesh)
    counts = np.full(8, 5)
    face = faces_from_counts(counts)
    anchors = make_anchors(profile, law, mesh, face, random_barycentrics(rng, len(face)), rng)
    return make_case(cid, f"{profile} profile{f', {law} law' if law else ''}: triangles posed to "
                     f"zero area: segments (with equal-length ties between edges), single points, "
                     f"axis-aligned segments (ties in the perpendicular axis rule), and the games "
                     f"case v1 = centroid. The degenerate-triangle rules of the spec apply.",
                     law_tags(profile, law) + ["extreme:zero-area", "degenerate:current"], mesh,
                     anchors, poses, rng, 1)


def _degenerate_rest_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{law_id(profile, law)}-degenerate-rest"
    rng = case_rng(cid)
    base = regular_triangles(rng, 6).astype(np.float64)
    base[0, 2] = 0.5 * (base[0, 0] + base[0, 1])  # segment
    base[1, 1] = base[1, 0]                        # v1 = v0
    base[2, :] = base[2, 0]                        # a point
    base[3, 2] = base[3, 1]                        # v2 = v1
    base = base.astype(np.float32).astype(np.float64)
    mesh = soup_mesh(base)
    opened = rng.normal(0.0, 0.4, (4, 3, 3))
    r = random_rotation(rng)

    def moved(t):
        return (t.reshape(-1, 3) @ r.T + np.array([0.5, -1.0, 2.0])).reshape(-1, 3, 3)

    def opened_up(t):
        t[:4] += opened
        return t

    def opened_stretched(t):
        t[:4] += opened
        return stretch(t.reshape(-1, 3), (1.6, 0.7, 1.2), (4, 0, 2)).reshape(-1, 3, 3)

    poses = soup_poses(base, [("rigid motion, still degenerate", moved),
                              ("opened into triangles", opened_up),
                              ("opened and stretched", opened_stretched)], mesh)
    face = faces_from_counts([6, 6, 6, 6, 3, 3])
    anchors = make_anchors(profile, law, mesh, face, random_barycentrics(rng, len(face)), rng)
    rule = ("the local rule for faces degenerate at rest applies (G := I, k := 1: the splat "
            "moves and rotates with the current frame, unscaled)"
            if profile == "local" else "games rebuilds frames from the current triangle only")
    return make_case(cid, f"{profile} profile{f', {law} law' if law else ''}: splats bound to "
                     f"faces that are degenerate at rest (a segment, a zero edge, a point; writers "
                     f"must not do this, readers must still produce finite output): {rule}.",
                     law_tags(profile, law) + ["extreme:degenerate-rest", "degenerate:rest",
                                               "degenerate:current"], mesh, anchors, poses, rng, 0,
                     validator_codes=["ANCHOR_BOUND_TO_DEGENERATE", "MESH_DEGENERATE_TRIANGLES"],
                     note="gsverse-validate reports this asset (writers MUST NOT bind splats to "
                     "faces degenerate at rest), but a plugin MUST NOT refuse it: spec "
                     "section 'Faces degenerate at rest' requires finite output by the rule "
                     "above.")


def _sliver_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{law_id(profile, law)}-sliver"
    rng = case_rng(cid)
    base = regular_triangles(rng, 8)
    for i, h in zip(range(4), (1e-2, 1e-3, 1e-3, 2e-3)):
        v0, v1 = base[i, 0], base[i, 1]
        e = v1 - v0
        perp = np.cross(e, rng.normal(size=3))
        perp /= np.linalg.norm(perp)
        base[i, 2] = v0 + rng.uniform(0.2, 0.8) * e + h * np.linalg.norm(e) * perp
    base = base.astype(np.float32).astype(np.float64)
    mesh = soup_mesh(base)
    r = random_rotation(rng)

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

    poses = soup_poses(base, [("rotated", rotated), ("squashed and stretched", squashed),
                              ("slivers opened", opened)], mesh)
    face = faces_from_counts(np.full(8, 5))
    kw = {"scale": 0.05} if profile == "local" else {}
    anchors = make_anchors(profile, law, mesh, face, random_barycentrics(rng, len(face)), rng, **kw)
    return make_case(cid, f"{profile} profile{f', {law} law' if law else ''}: sliver triangles "
                     f"(height 1e-3 to 1e-2 of the longest edge, above the 1e-6 degenerate "
                     f"threshold) at rest and posed, stretched along their length, and opened.",
                     law_tags(profile, law) + ["extreme:sliver"], mesh, anchors, poses, rng, 2)


def _inverted_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{law_id(profile, law)}-inverted"
    rng = case_rng(cid)
    base = regular_triangles(rng, 8).astype(np.float32).astype(np.float64)
    mesh = soup_mesh(base)

    def reflect(p, a, b):
        e = (b - a) / np.linalg.norm(b - a)
        foot = a + np.dot(p - a, e) * e
        return 2 * foot - p

    def fold_v2(t):
        for i in range(0, 8, 2):
            t[i, 2] = reflect(t[i, 2], t[i, 0], t[i, 1])
        return t

    r = random_rotation(rng)

    def fold_v1_rotated(t):
        for i in range(1, 8, 2):
            t[i, 1] = reflect(t[i, 1], t[i, 0], t[i, 2]) * 1.0
            t[i, 1] += 0.2 * (t[i, 1] - t[i, 0])
        return (t.reshape(-1, 3) @ r.T).reshape(-1, 3, 3)

    def mirrored(t):
        t[..., 0] *= -1.0
        return t

    poses = soup_poses(base, [("v2 folded across e1", fold_v2),
                              ("v1 folded across e2, stretched, rotated", fold_v1_rotated),
                              ("whole mesh mirrored in x", mirrored)], mesh)
    face = faces_from_counts(np.full(8, 5))
    anchors = make_anchors(profile, law, mesh, face, random_barycentrics(rng, len(face)), rng)
    return make_case(cid, f"{profile} profile{f', {law} law' if law else ''}: inverted triangles "
                     f"(a corner folded across the opposite edge, and the whole mesh mirrored): "
                     f"the frame follows the winding, no reflection is applied.",
                     law_tags(profile, law) + ["extreme:inverted"], mesh, anchors, poses, rng, 3)


def _stretch100_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{law_id(profile, law)}-stretch-100x"
    rng = case_rng(cid)
    mesh = tube_mesh()
    v = mesh.vertices.astype(np.float64)
    c = (0.0, 0.5, 0.0)
    poses = [rest_pose(mesh)] + [
        Pose(label, verts, {"kind": "analytic", "name": "stretch", "label": label})
        for label, verts in [("100x along y", stretch(v, (1, 100, 1), c)),
                             ("100x along x", stretch(v, (100, 1, 1), c)),
                             ("100x along (1, 1, 0)", stretch_along(v, (1, 1, 0), 100.0, c))]]
    face = faces_from_counts(rng.integers(0, 3, mesh.face_count))
    anchors = make_anchors(profile, law, mesh, face, random_barycentrics(rng, len(face)), rng)
    return make_case(cid, f"{profile} profile{f', {law} law' if law else ''}: the tube stretched "
                     f"100x along one direction.", law_tags(profile, law) + ["extreme:stretch-100x"],
                     mesh, anchors, poses, rng, 1)


def _compress_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{law_id(profile, law)}-compress-0.01x"
    rng = case_rng(cid)
    mesh = tube_mesh()
    v = mesh.vertices.astype(np.float64)
    c = (0.0, 0.5, 0.0)
    poses = [rest_pose(mesh)] + [
        Pose(label, verts, {"kind": "analytic", "name": "compress", "label": label})
        for label, verts in [("0.01x along y", stretch(v, (1, 0.01, 1), c)),
                             ("0.01x along x", stretch(v, (0.01, 1, 1), c)),
                             ("0.01x uniformly", stretch(v, (0.01, 0.01, 0.01), c))]]
    face = faces_from_counts(rng.integers(0, 3, mesh.face_count))
    anchors = make_anchors(profile, law, mesh, face, random_barycentrics(rng, len(face)), rng)
    return make_case(cid, f"{profile} profile{f', {law} law' if law else ''}: the tube compressed "
                     f"to 0.01x along one direction and uniformly.",
                     law_tags(profile, law) + ["extreme:compress-0.01x"], mesh, anchors, poses,
                     rng, 2)


def _offset_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{law_id(profile, law)}-offset-1e5"
    rng = case_rng(cid)
    offset = np.array([1.0e5, 1.0e5, -1.0e5])
    v0, faces = tube(5, 8, 2.0, 8.0)
    mesh = TriangleMesh(v0 + offset, faces)
    v = mesh.vertices.astype(np.float64) - offset   # float32 positions, relative to the offset
    poses = [rest_pose(mesh)] + [
        Pose(label, verts + offset, {"kind": "analytic", "name": label})
        for label, verts in [("twist 90", twist(v, 90, (0, 0, 0), 0, 8)),
                             ("bend 90", bend(v, 90, (0, 0, 0), 0, 8)),
                             ("shake", shake(v, rng, (0, 4, 0), 0.05, 1.0))]]
    face = faces_from_counts(rng.integers(0, 3, mesh.face_count))
    anchors = make_anchors(profile, law, mesh, face, random_barycentrics(rng, len(face)), rng)
    return make_case(cid, f"{profile} profile{f', {law} law' if law else ''}: a tube of radius 2 "
                     f"with coordinates offset by 1e5 (float32 spacing 0.0078 there). Compute "
                     f"relative to the triangle's first corner: edges and centroids subtracted "
                     f"first keep their accuracy.", law_tags(profile, law) + ["extreme:offset-1e5"],
                     mesh, anchors, poses, rng, 0)


def _extreme_scale_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{law_id(profile, law)}-extreme-scales"
    rng = case_rng(cid)
    mesh = tube_mesh()
    face = faces_from_counts(np.full(mesh.face_count, 2))
    n = len(face)
    size = face_sizes(mesh)[face]
    kind = np.arange(n) % 4
    if profile == "local":
        mag = np.select([kind == 0, kind == 1, kind == 2], [1e-6, 1e3, 1.0], 1.0)
        scales = size[:, None] * mag[:, None] * np.exp(rng.normal(0.0, 0.5, (n, 3)))
        mixed = kind == 3     # one axis tiny, one huge
        scales[mixed] = size[mixed, None] * np.array([1e-6, 1.0, 1e3])
        anchors: Anchors = local_anchors(mesh, face, random_barycentrics(rng, n), rng, law,
                                         scales=scales)
    else:
        rho = np.select([kind == 0, kind == 1, kind == 2], [1e-6, 1e3, 0.0], 1.0) \
            * rng.uniform(0.5, 1.5, n)
        anchors = games_anchors(mesh, face, random_barycentrics(rng, n), rng, rho=rho)
    v = mesh.vertices.astype(np.float64)
    poses = [rest_pose(mesh),
             Pose("twist 90", twist(v, 90, (0, 0, 0), 0, 1), {"kind": "analytic", "name": "twist"}),
             Pose("stretch", stretch(v, (2.0, 0.5, 1.0), (0, 0.5, 0)),
                  {"kind": "analytic", "name": "stretch"})]
    what = ("scales from 1e-6 to 1e3 times the face size, and splats with one axis at 1e-6 "
            "and another at 1e3" if profile == "local"
            else "rho of 1e-6, 1e3 and 0 (the scales then fall to the GaMeS floor 1e-8)")
    return make_case(cid, f"{profile} profile{f', {law} law' if law else ''}: very small and very "
                     f"large splats: {what}.", law_tags(profile, law) + ["extreme:scales"], mesh,
                     anchors, poses, rng, 3)


def _near_coincident_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{law_id(profile, law)}-near-coincident-vertices"
    rng = case_rng(cid)
    tris = []
    for i in range(6):   # micro triangles (edges ~1e-5) near coordinates of size 1
        c = np.array([0.7, 0.3, -0.4]) + 0.01 * i
        tris.append(c + regular_triangles(rng, 1, size=1e-5)[0])
    for i in range(4):   # micro triangles (edges ~1e-7) at the origin
        tris.append(regular_triangles(rng, 1, size=1e-7)[0] + 1e-6 * i)
    big = regular_triangles(rng, 2, spacing=2.0)
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
    r = random_rotation(rng)
    poses = [rest_pose(mesh),
             Pose("rigid motion", v @ r.T + np.array([0.1, -0.2, 0.3]),
                  {"kind": "analytic", "name": "rigid"}),
             Pose("stretch x 2", stretch(v, (2.0, 1.0, 1.0), (0.5, 0.0, 0.0)),
                  {"kind": "analytic", "name": "stretch"}),
             Pose("twist 45", twist(v, 45, (0.7, 0, -0.4), -1, 1),
                  {"kind": "analytic", "name": "twist"})]
    face = faces_from_counts(np.full(mesh.face_count, 4))
    anchors = make_anchors(profile, law, mesh, face, random_barycentrics(rng, len(face)), rng)
    return make_case(cid, f"{profile} profile{f', {law} law' if law else ''}: nearly coincident "
                     f"vertices: micro triangles with edges of 1e-5 at coordinates near 1 and of "
                     f"1e-7 near the origin (the degenerate test is relative, never absolute), and "
                     f"a seam whose duplicated vertices are one float32 step apart.",
                     law_tags(profile, law) + ["extreme:near-coincident"], mesh, anchors, poses,
                     rng, 1)


def extreme_cases() -> list[RemapCase]:
    """The cases of this module, in suite order."""
    out = []
    for make in (_zero_area_case, _degenerate_rest_case, _sliver_case, _inverted_case,
                 _stretch100_case, _compress_case, _offset_case, _extreme_scale_case,
                 _near_coincident_case):
        for profile, law in LAWS:
            out.append(make(profile, law))
    return out
