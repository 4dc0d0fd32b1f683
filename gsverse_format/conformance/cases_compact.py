"""Remap cases of the compact anchor encodings (extension version 1.2).

* ``*-face-counts``: ``faceCounts`` instead of ``faceIndex`` (the splats grouped by face in
  face order, faces without splats counted as 0), with explicit anchors (``local`` and
  ``games``; the ``games`` one has a face holding 260 splats: counts as UNSIGNED_SHORT);
* ``local-*-derived``: ``faceCounts`` and no other anchor data: the anchors are derived from
  the rest pose (spec §Derived `local` anchors), for both laws;
* ``local-*-derived-face-index``: derived anchors with a ``faceIndex`` (any splat order);
* ``local-*-derived-rest-quantized``: derived anchors from a rest pose whose ``ROTATION`` is a
  normalized SHORT or BYTE (the derivation uses the dequantized, renormalized rotation).

A broken implementation that ignores the order of ``faceCounts`` or derives with the wrong
sign fails them (``tests/test_conformance.py``).
"""
from __future__ import annotations

import numpy as np

from .case_tools import (Pose, RemapCase, bend, case_rng, faces_from_counts, law_id, law_tags,
                         make_anchors, make_case, random_barycentrics, rest_pose, stretch,
                         tube_mesh, twist)
from .glb import (UNSIGNED_BYTE, UNSIGNED_SHORT, accessor_bytes, anchor_extension,
                  anchor_primitive, append_accessor)

__all__ = ["compact_cases"]

_DERIVED = ("barycentrics", "normalOffset", "localRotation", "localScale")


def _poses(mesh, c=(0.0, 0.0, 0.0)) -> list[Pose]:
    v = mesh.vertices.astype(np.float64)
    return [rest_pose(mesh),
            Pose("twist 80", twist(v, 80, c, 0.0, 1.0), {"kind": "analytic", "name": "twist"}),
            Pose("bend 100 + stretch", stretch(bend(v, 100, c, 0.0, 1.0), (1.2, 0.85, 1.1), c),
                 {"kind": "analytic", "name": "bend+stretch"})]


def _counts_instead_of_index(doc: dict, blob: bytes) -> tuple[dict, bytes]:
    """Replace ``faceIndex`` by ``faceCounts`` (the splats are already sorted by face)."""
    e = anchor_extension(doc)
    face = accessor_bytes(doc, blob, e.pop("faceIndex")).astype(np.int64).ravel()
    faces = len(accessor_bytes(doc, blob, anchor_primitive(doc)["indices"])) // 3
    counts = np.bincount(face, minlength=faces)
    ctype = UNSIGNED_BYTE if counts.max() < 256 else UNSIGNED_SHORT
    e["faceCounts"], blob = append_accessor(doc, blob, counts, ctype, "SCALAR")
    return doc, blob


def _index_instead_of_counts(doc: dict, blob: bytes) -> tuple[dict, bytes]:
    """Replace ``faceCounts`` by ``faceIndex`` (UNSIGNED_SHORT, to vary the type too)."""
    e = anchor_extension(doc)
    counts = accessor_bytes(doc, blob, e.pop("faceCounts")).astype(np.int64).ravel()
    e["faceIndex"], blob = append_accessor(doc, blob, faces_from_counts(counts),
                                           UNSIGNED_SHORT, "SCALAR")
    return doc, blob


def _face_counts_cases() -> list[RemapCase]:
    out = []
    for profile, law, degree in (("local", "rigid", 1), ("games", None, 0)):
        cid = f"{law_id(profile, law)}-face-counts"
        rng = case_rng(cid)
        mesh = tube_mesh()
        # many faces empty; games: one crowded face (260 splats: counts need UNSIGNED_SHORT)
        counts = np.where(rng.random(mesh.face_count) < 0.4, 0, rng.integers(1, 4, mesh.face_count))
        crowded = ""
        if profile == "games":
            counts[7] = 260
            crowded = " and face 7 holds 260 splats (UNSIGNED_SHORT counts)"
        face = faces_from_counts(counts)
        anchors = make_anchors(profile, law, mesh, face, random_barycentrics(rng, len(face)), rng)
        # local: the writer's explicit layout edited to counts; games: the writer's compact one
        edit = _counts_instead_of_index if profile == "local" else None
        encoding = "compact" if profile == "games" else "explicit"
        out.append(make_case(cid, f"{profile} profile{f', {law} law' if law else ''}: "
                             f"faceCounts instead of faceIndex, explicit anchors; faces without "
                             f"splats count 0{crowded}.",
                             law_tags(profile, law) + ["encoding:face-counts"],
                             mesh, anchors, _poses(mesh)[:2], rng, degree, edit=edit,
                             encoding=encoding))
    return out


def _derived_cases() -> list[RemapCase]:
    out = []
    for law, degree in (("affine", 0), ("rigid", 2)):
        cid = f"local-{law}-derived"
        rng = case_rng(cid)
        mesh = tube_mesh(rings=4, segments=7, radius=0.3)
        face = faces_from_counts(rng.integers(0, 6, mesh.face_count))
        # feet outside the triangle too (nearest point on an edge): barycentrics beyond [0, 1]
        bary = random_barycentrics(rng, len(face)) * 1.3 - 0.1
        anchors = make_anchors("local", law, mesh, face, bary, rng)
        out.append(make_case(cid, f"local profile, {law} law: faceCounts and no other anchor "
                             f"data; readers derive the anchors from the rest pose in binary64.",
                             law_tags("local", law) + ["encoding:derived"], mesh, anchors,
                             _poses(mesh), rng, degree, encoding="compact"))
    cid = "local-rigid-derived-face-index"
    rng = case_rng(cid)
    mesh = tube_mesh()
    face = rng.permutation(faces_from_counts(rng.integers(0, 4, mesh.face_count)))
    anchors = make_anchors("local", "rigid", mesh, face, random_barycentrics(rng, len(face)), rng)
    out.append(make_case(cid, "local profile, rigid law: derived anchors (no barycentrics, "
                         "normalOffset, localRotation, localScale) with a faceIndex accessor "
                         "(UNSIGNED_SHORT) instead of faceCounts.",
                         law_tags("local", "rigid") + ["encoding:derived"], mesh, anchors,
                         _poses(mesh), rng, 1, encoding="compact", edit=_index_instead_of_counts))
    for law, ctype, degree in (("affine", "short", 1), ("rigid", "byte", 0)):
        cid = f"local-{law}-derived-rest-quantized"
        rng = case_rng(cid)
        mesh = tube_mesh(rings=3, segments=6, radius=0.5)
        face = faces_from_counts(rng.integers(1, 4, mesh.face_count))
        anchors = make_anchors("local", law, mesh, face, random_barycentrics(rng, len(face)),
                               rng)
        out.append(make_case(cid, f"local profile, {law} law: derived anchors from a quantized "
                             f"rest pose (ROTATION normalized {ctype.upper()}): derive from the "
                             f"dequantized, renormalized rotation.",
                             law_tags("local", law) + ["encoding:derived",
                                                       f"quantized:ROTATION={ctype}"],
                             mesh, anchors, _poses(mesh)[:2], rng, degree, encoding="compact",
                             quantize={"ROTATION": ctype}))
    return out


def compact_cases() -> list[RemapCase]:
    """The cases of the compact encodings, in suite order."""
    return _face_counts_cases() + _derived_cases()
