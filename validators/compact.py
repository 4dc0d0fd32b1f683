"""Checks of the compact anchor encodings (extension version 1.2; spec §Properties,
`faceCounts`, and §Derived `local` anchors), used by :mod:`.anchor`.

``faceCounts`` becomes the per-splat face index the value checks expect; derived ``local``
anchors are computed from the stored rest pose with the one derivation rule
(:func:`gsverse_format.anchors_derive.derive_local`), so that the value checks and the rest-pose
check of :mod:`.values` run on them as on stored anchors.
"""
from __future__ import annotations

import numpy as np

from gsverse_format.anchors_derive import degenerate_splats, derive_local
from gsverse_format.codes import Code

from .context import CheckContext
from .values import AnchorMesh, RestPose

__all__ = ["faces_from_counts", "derived_arrays"]


def faces_from_counts(ctx: CheckContext, counts: np.ndarray, splats: int,
                      location: str) -> np.ndarray | None:
    """The face of each splat from per-face ``counts`` (their count already checked against
    the triangle count), or None after reporting ANCHOR_FACE_COUNTS_SUM."""
    total = int(counts.astype(np.int64).sum())
    if total != splats:
        ctx.issues.add(Code.ANCHOR_FACE_COUNTS_SUM, f"faceCounts sums to {total} but the "
                       f"primitive has {splats} splats", pointer=location)
        return None
    return np.repeat(np.arange(len(counts), dtype=np.int64), counts.astype(np.int64))


def derived_arrays(ctx: CheckContext, mesh: AnchorMesh | None, face: np.ndarray | None,
                   rest: RestPose | None, location: str) -> dict[str, np.ndarray]:
    """The derived ``local`` anchors as the value checks take them (``barycentrics`` (N, 2),
    ``normalOffset`` (N, 1), ``localRotation`` (N, 4), ``localScale`` (N, 3)); empty when the
    faces, the anchor mesh or the rest pose are unusable (reported elsewhere) or a splat lies on
    a face degenerate at rest (ANCHOR_DERIVED_ON_DEGENERATE, at ``location``)."""
    if face is None or mesh is None or mesh.mesh is None or rest is None:
        return {}
    if face.size and (int(face.min()) < 0 or int(face.max()) >= mesh.mesh.face_count):
        return {}                       # ANCHOR_FACE_OUT_OF_RANGE is reported by the values
    bad = degenerate_splats(mesh.mesh, face)
    if bad.size:
        ctx.issues.add(Code.ANCHOR_DERIVED_ON_DEGENERATE, f"{bad.size} of {len(face)} splats "
                       f"without stored anchors lie on triangles degenerate at rest; their "
                       f"anchors cannot be derived", pointer=location, count=int(bad.size),
                       examples=ctx.examples(bad, splat=np.arange(len(face)), face=face))
        return {}
    d = derive_local(mesh.mesh, face, rest.means, rest.rotations)
    return {"barycentrics": d.barycentrics.astype(np.float32),
            "normalOffset": d.normal_offset.astype(np.float32)[:, None],
            "localRotation": d.local_rotation.astype(np.float32),
            "localScale": np.asarray(rest.scales, np.float32)}
