"""Remap cases that pin the precision and degenerate-case rules of spec v1.1.

Each family targets one rule that two readings of the v1 text could implement differently, and
each has a deliberately broken implementation in the tests that fails it:

* ``*-threshold-crossing``: current triangles squashed to just above and just below the
  degenerate threshold a = ε_deg ℓ², with a short second edge so that float32 resolves the
  cross product: the normal offset follows the scaled normal m = (e1 × e2)/√(a_c a_r), which has
  no branch at the threshold (v1 dropped it to 0 below the threshold);
* ``games-midpoint-degenerate``: v1 at the float32 midpoint of v0v2 (v1 − c is rounding noise):
  the relative tests and the Gram–Schmidt / midpoint rules of the games profile;
* ``local-*-longest-edge-ties``: faces degenerate at rest whose current segments have exactly
  tied longest edges pointing opposite ways, and axis-aligned segments (perp rule ties);
* ``*-scale-1e-4``, ``*-scale-1``, ``*-scale-1e4``: one asset at three scales (results agree
  after scaling; games within |1 − c|(1 + ρ)ε): no absolute epsilon anywhere else;
* ``local-*-rest-sliver-opened``: rest triangles just above the threshold (a = 1.1·10⁻⁶ ℓ²)
  opened 10⁵× in area: rest quantities must be computed in double precision;
* ``local-*-float-rotation-norm``: float ``localRotation`` whose length is off unit by up to
  the writer tolerance (10⁻⁵): readers renormalize every quaternion, float ones included;
* ``games-node-scale-1e-3``: a splat node scaled by 10⁻³: GaMeS's ε applies in mesh-local
  units, before node transforms.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..model import LocalAnchors, TriangleMesh
from .case_tools import (LAWS, Pose, RemapCase, bend, case_rng, faces_from_counts, law_id,
                         law_tags, local_anchors, make_anchors, make_case, random_barycentrics,
                         random_rotation, regular_triangles, soup_mesh, soup_poses, stretch,
                         tube_mesh, twist)
from .glb import accessor_bytes, anchor_extension, patch_accessor

__all__ = ["rule_cases", "SCALES"]

#: the scales of the ``*-scale-*`` family
SCALES = (1e-4, 1.0, 1e4)
_EPS_DEG = 1e-6
#: a/ℓ² of the squashed triangles of the threshold-crossing poses, in units of ε_deg
_THRESHOLD_TARGETS = (2.0, 1.3, 1.08, 0.92, 0.7, 0.5)


def _describe(profile: str, law: str | None) -> str:
    return f"{profile} profile{f', {law} law' if law else ''}"


def _squash(tri: np.ndarray, target: float, rng: np.random.Generator) -> np.ndarray:
    """A triangle with the first edge of ``tri`` and a short second edge (0.15 of the first)
    tilted so that a = target ε_deg ℓ², moved by a random rotation about its first corner."""
    v0, v1 = tri[0], tri[1]
    e1 = v1 - v0
    length = np.linalg.norm(e1)
    t = e1 / length
    side = np.cross(t, rng.normal(size=3))
    side /= np.linalg.norm(side)
    short = 0.15 * length
    sin = target * _EPS_DEG * length / short   # a = |e1| short sin = target ε ℓ², ℓ = |e1|
    v2 = v0 + short * (np.sqrt(1.0 - sin * sin) * t + sin * side)
    return np.stack([v0, v1, v2])


def _threshold_case(profile: str, law: str | None) -> RemapCase:
    cid = f"{law_id(profile, law)}-threshold-crossing"
    rng = case_rng(cid)
    # near the origin (overlapping is fine in a soup): float32 spacing ~1e-7 there
    base = regular_triangles(rng, 8, spacing=0.0).astype(np.float32).astype(np.float64)
    mesh = soup_mesh(base)
    edits = []
    for target in _THRESHOLD_TARGETS:
        def squash(t, target=target):
            local = np.random.default_rng(int(target * 1000))
            return np.stack([_squash(t[i], target, local) for i in range(len(t))])
        side = "above" if target > 1 else "below"
        edits.append((f"squashed to a = {target:g} eps_deg l^2 ({side} the threshold)", squash))
    poses = soup_poses(base, edits, mesh)
    face = faces_from_counts(np.full(8, 5))
    kw = {"offset": 0.6} if profile == "local" else {}
    anchors = make_anchors(profile, law, mesh, face, random_barycentrics(rng, len(face)), rng, **kw)
    return make_case(cid, f"{_describe(profile, law)}: every triangle squashed to a doubled area "
                     f"of 2, 1.3, 1.08, 0.92, 0.7 and 0.5 times eps_deg l^2, just above and just "
                     f"below the degenerate threshold, with a short second edge so that float32 "
                     f"resolves the cross product. The normal offset follows the scaled normal m = "
                     f"(e1 x e2) / sqrt(a_c a_r), continuous through the threshold (v1 set it to 0 "
                     f"below).", law_tags(profile, law) + ["rule:threshold"], mesh, anchors,
                     poses, rng, 0)


def _midpoint_case() -> RemapCase:
    cid = "games-midpoint-degenerate"
    rng = case_rng(cid)
    base = regular_triangles(rng, 8).astype(np.float32).astype(np.float64)
    mesh = soup_mesh(base)
    r = random_rotation(rng)

    def midpoint(t):
        for i in range(len(t)):
            mid = (t[i, 0].astype(np.float32) + t[i, 2].astype(np.float32)) / np.float32(2)
            t[i, 1] = mid.astype(np.float64)       # the float32 midpoint of v0 v2
        return t

    def near_midpoint(t):
        t = midpoint(t)
        for i in range(len(t)):                    # 3e-7 of the edge off the midpoint
            e = t[i, 2] - t[i, 0]
            off = np.cross(e, rng.normal(size=3))
            t[i, 1] += 3e-7 * np.linalg.norm(e) * off / np.linalg.norm(off)
        return t

    def moved(t):
        t = midpoint(t)
        return (t.reshape(-1, 3) @ r.T + np.array([0.25, -0.5, 0.75])).reshape(-1, 3, 3)

    poses = soup_poses(base, [("v1 at the float32 midpoint of v0 v2", midpoint),
                              ("v1 3e-7 of the edge off the midpoint", near_midpoint),
                              ("midpoint pose, rotated and moved", moved)], mesh)
    face = faces_from_counts(np.full(8, 5))
    anchors = make_anchors("games", None, mesh, face, random_barycentrics(rng, len(face)), rng)
    return make_case(cid, "games profile: v1 posed at the float32 midpoint of v0 v2 (and 3e-7 of "
                     "the edge off it), so that v1 - c is rounding noise. The relative test "
                     "|v1 - c| > eps_deg l fails and the splat lies along w = v2 - c with scale "
                     "rho |w| / 2, as GaMeS's regularized code gives; an absolute test points b1 "
                     "anywhere.", law_tags("games", None) + ["rule:games-degenerate",
                                                             "degenerate:current"],
                     mesh, anchors, poses, rng, 0)


def _ties_case(law: str) -> RemapCase:
    cid = f"local-{law}-longest-edge-ties"
    rng = case_rng(cid)
    base = regular_triangles(rng, 6).astype(np.float64)
    base[0, 2] = base[0, 0]          # v2 = v0: |e1| = |e3|, opposite directions
    base[1, 1] = base[1, 0]          # v1 = v0: |e2| = |e3|
    base[2, 2] = base[2, 1]          # v2 = v1: |e1| = |e2|
    base[3, 2] = base[3, 0]          # v2 = v0 again, other direction
    base = base.astype(np.float32).astype(np.float64)
    mesh = soup_mesh(base)
    r = random_rotation(rng)

    def moved(t):
        return (t.reshape(-1, 3) @ r.T + np.array([0.5, -1.0, 2.0])).reshape(-1, 3, 3)

    def axis_aligned(t):
        o = np.array([1.0, 2.0, 0.5])
        t[0] = o + np.array([[0.0, 0, 0], [1.5, 0, 0], [0.0, 0, 0]])      # along +x, v2 = v0
        t[1] = o + np.array([[0.0, 0, 0], [0.0, 0, 0], [0.0, 0.0, -2.0]])   # along -z, v1 = v0
        t[2] = o + np.array([[0.0, 0, 0], [0.0, 1.0, 0], [0.0, 1.0, 0]])    # along +y, v2 = v1
        t[3] = o + np.array([[0.0, 0, 0], [0.75, 0.75, 0], [0.0, 0, 0]])    # (1, 1, 0), v2 = v0
        return t

    def tie_opened(t):
        t[:4] = moved(t)[:4]
        t[4:] += 0.1
        return t

    poses = soup_poses(base, [("rigid motion, ties kept exactly", moved),
                              ("axis-aligned segments with ties", axis_aligned),
                              ("ties moved, other faces shifted", tie_opened)], mesh)
    face = faces_from_counts([6, 6, 6, 6, 3, 3])
    anchors = local_anchors(mesh, face, random_barycentrics(rng, len(face)), rng, law)
    return make_case(cid, f"local profile, {law} law: splats on faces degenerate at rest that stay "
                     f"segments whose longest edges tie exactly (v2 = v0 makes e1 and e3 = -e1 "
                     f"equally long): t is the first of e1, e2, e3 by squared length, and the perp "
                     f"rule takes the lowest axis on ties. On these faces G := I, so the frame "
                     f"decides the output.",
                     law_tags("local", law)
                     + ["rule:ties", "degenerate:rest", "degenerate:current"],
                     mesh, anchors, poses, rng, 0,
                     validator_codes=["ANCHOR_BOUND_TO_DEGENERATE", "MESH_DEGENERATE_TRIANGLES"],
                     note="gsverse-validate reports this asset (writers MUST NOT bind splats to "
                     "faces degenerate at rest), but a plugin MUST NOT refuse it.")


def _scale_case(profile: str, law: str | None, scale: float) -> RemapCase:
    name = {1e-4: "1e-4", 1.0: "1", 1e4: "1e4"}[scale]
    cid = f"{law_id(profile, law)}-scale-{name}"
    rng = case_rng(f"{law_id(profile, law)}-scale")       # the same asset at every scale
    mesh = tube_mesh()
    face = faces_from_counts(rng.integers(1, 3, mesh.face_count))
    anchors = make_anchors(profile, law, mesh, face, random_barycentrics(rng, len(face)), rng)
    v = mesh.vertices.astype(np.float64)
    shapes = [("twist 90", twist(v, 90, (0, 0, 0), 0, 1)),
              ("bend 90", bend(v, 90, (0, 0, 0), 0, 1)),
              ("stretch", stretch(v, (1.5, 0.6, 1.0), (0, 0.5, 0)))]
    scaled = TriangleMesh(v * scale, mesh.faces)
    if isinstance(anchors, LocalAnchors):
        anchors = replace(anchors, normal_offset=anchors.normal_offset.astype(np.float64) * scale,
                          local_scale=anchors.local_scale.astype(np.float64) * scale)
    poses = [Pose("rest", scaled.vertices, {"kind": "rest"})] + [
        Pose(label, verts * scale, {"kind": "analytic", "name": label, "scale": scale})
        for label, verts in shapes]
    return make_case(cid, f"{_describe(profile, law)}: the same asset and poses scaled by {name} "
                     f"(vertices, normal offsets and local scales). Results agree after scaling "
                     f"(games: within |1 - c|(1 + rho) eps, eps = 1e-8 applies in mesh-local "
                     f"units): no absolute epsilon may enter the remap.",
                     law_tags(profile, law) + ["rule:scale", f"scale:{name}"], scaled, anchors,
                     poses, rng, 0)


def _rest_sliver_case(law: str) -> RemapCase:
    cid = f"local-{law}-rest-sliver-opened"
    rng = case_rng(cid)
    base = regular_triangles(rng, 8, spacing=0.0)
    heights = (1.1e-6, 1.2e-6, 1.5e-6, 2e-6, 1.1e-6, 1.3e-6, 3e-6, 1.05e-6)
    for i, h in enumerate(heights):
        v0, v1 = base[i, 0], base[i, 1]
        e = v1 - v0
        perp = np.cross(e, rng.normal(size=3))
        perp /= np.linalg.norm(perp)
        base[i, 2] = v0 + rng.uniform(0.3, 0.7) * e + 1.6 * h * np.linalg.norm(e) * perp
    base = base.astype(np.float32).astype(np.float64)
    mesh = soup_mesh(base)

    def opened(factor):
        def edit(t):
            for i in range(len(t)):
                v0, v1, v2 = t[i]
                e = v1 - v0
                foot = v0 + np.dot(v2 - v0, e) / np.dot(e, e) * e
                t[i, 2] = foot + factor * (v2 - foot)
            return t
        return edit

    r = random_rotation(rng)

    def opened_rotated(t):
        return (opened(1e5)(t).reshape(-1, 3) @ r.T).reshape(-1, 3, 3)

    poses = soup_poses(base, [("heights x 1e3", opened(1e3)), ("heights x 1e5", opened(1e5)),
                              ("heights x 1e5, rotated", opened_rotated)], mesh)
    face = faces_from_counts(np.full(8, 5))
    anchors = local_anchors(mesh, face, random_barycentrics(rng, len(face)), rng, law, scale=0.3,
                            offset=0.5)
    return make_case(cid, f"local profile, {law} law: rest slivers just above the degenerate "
                     f"threshold (a from about 1.7e-6 to 5e-6 of l^2) opened 1e3x and 1e5x in "
                     f"area. The rest quantities (C_r^-1, a_r) must be computed in double "
                     f"precision: "
                     f"in float32 their rounding, amplified by the opening, moves the splats far "
                     f"beyond the tolerance.", law_tags("local", law) + ["rule:rest-precision",
                                                                         "extreme:sliver"],
                     mesh, anchors, poses, rng, 0,
                     validator_codes=["MESH_SLIVER_TRIANGLES"],
                     note="gsverse-validate warns about the rest slivers; a plugin remaps them.")


def _rotation_norm_case(law: str) -> RemapCase:
    cid = f"local-{law}-float-rotation-norm"
    rng = case_rng(cid)
    mesh = tube_mesh()
    face = faces_from_counts(rng.integers(1, 3, mesh.face_count))
    anchors = local_anchors(mesh, face, random_barycentrics(rng, len(face)), rng, law)
    off = rng.choice([-1.0, 1.0], len(face)) * rng.uniform(0.5e-5, 0.9e-5, len(face))

    def off_unit(doc, blob):
        """Scale the stored FLOAT localRotation by 1 + off (writers normalize them)."""
        ext = anchor_extension(doc)
        q = accessor_bytes(doc, blob, ext["localRotation"]).astype(np.float64)
        return doc, patch_accessor(doc, blob, ext["localRotation"],
                                   (q * (1.0 + off)[:, None]).astype(np.float32))
    v = mesh.vertices.astype(np.float64)
    poses = [Pose("rest", mesh.vertices, {"kind": "rest"}),
             Pose("twist 60", twist(v, 60, (0, 0, 0), 0, 1), {"kind": "analytic", "name": "twist"}),
             Pose("stretch", stretch(v, (1.4, 0.8, 1.1), (0, 0.5, 0)),
                  {"kind": "analytic", "name": "stretch"})]
    return make_case(cid, f"local profile, {law} law: FLOAT localRotation whose length is off unit "
                     f"by 5e-6 to 9e-6 (within the writers' tolerance of 1e-5). Readers normalize "
                     f"every quaternion, float ones included; without it the covariance is off by "
                     f"about 2e-5 relative.", law_tags("local", law) + ["rule:quaternion-norm"],
                     mesh, anchors, poses, rng, 0, edit=off_unit)


def _node_scale_case() -> RemapCase:
    cid = "games-node-scale-1e-3"
    rng = case_rng(cid)
    mesh = tube_mesh()
    face = faces_from_counts(rng.integers(1, 3, mesh.face_count))
    anchors = make_anchors("games", None, mesh, face, random_barycentrics(rng, len(face)), rng)
    v = mesh.vertices.astype(np.float64)
    poses = [Pose("rest", mesh.vertices, {"kind": "rest"}),
             Pose("twist 90", twist(v, 90, (0, 0, 0), 0, 1), {"kind": "analytic", "name": "twist"}),
             Pose("stretch", stretch(v, (1.5, 0.6, 1.0), (0, 0.5, 0)),
                  {"kind": "analytic", "name": "stretch"})]

    def node_scale(doc, blob):
        """The node of the splat mesh scales it by 1e-3 (a model in millimetres)."""
        splat_mesh = next(i for i, m in enumerate(doc["meshes"]) for p in m["primitives"]
                          if "KHR_gaussian_splatting" in p.get("extensions", {}))
        node = next(n for n in doc["nodes"] if n.get("mesh") == splat_mesh)
        node["scale"] = [1e-3, 1e-3, 1e-3]
        return doc, blob

    return make_case(cid, "games profile: the splat node scales the asset by 1e-3. GaMeS's eps = "
                     "1e-8 applies in mesh-local units, before node transforms: a remap done in "
                     "world space (eps after the node scale) moves the in-plane scales by about "
                     "1e-5 local units.", law_tags("games", None) + ["rule:games-epsilon-space"],
                     mesh, anchors, poses, rng, 0, edit=node_scale)


def rule_cases() -> list[RemapCase]:
    """The cases of this module, in suite order."""
    out = [_threshold_case(profile, law) for profile, law in LAWS]
    out.append(_midpoint_case())
    out += [_ties_case(law) for law in ("affine", "rigid")]
    out += [_scale_case(profile, law, scale) for profile, law in LAWS for scale in SCALES]
    out += [_rest_sliver_case(law) for law in ("affine", "rigid")]
    out += [_rotation_norm_case(law) for law in ("affine", "rigid")]
    out.append(_node_scale_case())
    return out
