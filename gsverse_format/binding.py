"""Binding free splats to an anchor mesh (``local`` profile).

Each splat is bound to its exact nearest triangle (certified, see :mod:`gsverse_format.nearest`);
faces that are degenerate at rest are never chosen. The splat's mean is then expressed in that
triangle's rest frame (spec §Triangle frames): the foot point of the mean in the triangle's
plane as barycentrics (b1, b2) — outside the triangle when the nearest point lies on an edge or
corner — plus the signed offset d along the unit normal. The splat's rotation is stored
relative to the rest frame and its scale as is, so that ``remap(rest vertices)`` reproduces the
input splats up to float32 rounding of the stored anchors.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .anchors_derive import derive_local
from .errors import BindingError
from .frames import local_frames
from .model import DeformationLaw, LocalAnchors, SplatCloud, TriangleMesh, face_order
from .nearest import nearest_faces
from .rows import take_rows
from .threads import native_threads

__all__ = ["BindResult", "bind_local"]


@dataclass
class BindResult:
    """Anchors plus what the binder measured: ``distance`` (N,) from each mean to its face,
    in the splats' order. ``order`` is None, or, when the binder was asked for anchors in face
    order, the order of the splats they follow (:func:`~gsverse_format.model.face_order` of
    the faces): anchor ``i`` is that of splat ``order[i]``."""

    anchors: LocalAnchors
    distance: np.ndarray
    degenerate_faces: int
    order: np.ndarray | None = None


def bind_local(splats: SplatCloud, mesh: TriangleMesh, *, deformation: str = "affine",
               progress: Callable[[int, int], None] | None = None,
               in_face_order: bool = False, derive: bool = True) -> BindResult:
    """Bind every splat of ``splats`` to its nearest non-degenerate face of ``mesh``.

    ``deformation`` is the law stored with the anchors, ``"affine"`` or ``"rigid"``
    (``ValueError`` otherwise); ``progress(done, total)`` follows the nearest-triangle search.
    Raises :class:`~gsverse_format.errors.BindingError` when the mesh has no usable triangle.

    ``in_face_order`` returns the anchors grouped by face (spec §Ordering), with that order
    in ``BindResult.order``: what a writer of compact anchors stores once the splats are
    reordered the same way, without reordering a second copy of the anchors. The anchors'
    values are the same, row by row.

    ``derive=False`` leaves the barycentrics, offsets and local rotations to be derived when
    first read (:meth:`LocalAnchors.deferred`), for a writer of compact glTF, which stores
    none of them: the same values then, from the means and rotations ``splats`` holds now
    (their arrays must not be changed in place until then; replacing them does no harm).
    """
    if deformation not in ("affine", "rigid"):
        raise ValueError(f"deformation must be 'affine' or 'rigid', got {deformation!r}")
    law: DeformationLaw = "rigid" if deformation == "rigid" else "affine"
    if mesh.face_count == 0:
        raise BindingError("the anchor mesh has no triangles")
    tri = mesh.triangles()
    frames = local_frames(tri)
    if not np.any(frames.regular):
        raise BindingError(f"all {mesh.face_count} triangles of the anchor mesh are degenerate")
    if len(splats) == 0:
        empty = np.zeros(0)
        return BindResult(LocalAnchors(np.zeros(0, np.uint32), np.zeros((0, 2)), empty,
                                       np.zeros((0, 4)), np.zeros((0, 3)), law), empty,
                          int(np.count_nonzero(~frames.regular)),
                          np.zeros(0, np.intp) if in_face_order else None)
    face, distance = nearest_faces(splats.means, mesh.vertices, mesh.faces,
                                   exclude=~frames.regular, progress=progress)
    # steps 2-3 of spec §Writing anchors: the rule readers of compact assets use too; float32
    # as stored, derived a chunk at a time (the float64 temporaries stay bounded)
    order = face_order(face) if in_face_order else None
    means, rotations = splats.means, splats.rotations

    def anchor_values() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        d = derive_local(mesh, face, means, rotations, frames=frames, dtype=np.float32,
                         threads=native_threads(), order=order)
        return d.barycentrics, d.normal_offset, d.local_rotation

    if order is None:
        anchor_face, scales = face.astype(np.uint32), splats.scales
    else:
        anchor_face, scales = face[order].astype(np.uint32), take_rows(splats.scales, order)
    anchors = (LocalAnchors(anchor_face, *anchor_values(), scales, law) if derive
               else LocalAnchors.deferred(anchor_face, scales, law, anchor_values))
    return BindResult(anchors, distance, int(np.count_nonzero(~frames.regular)), order)
