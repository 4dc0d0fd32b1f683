"""Rigid changes of coordinate frame for splats and meshes.

3DGS PLY files follow the capture convention of the original 3DGS code (COLMAP-style camera
frame, +Y down), glTF is +Y up. Like PlayCanvas splat-transform, the converter maps PLY data to
glTF by a rotation of 180° about Z, ``(x, y, z) -> (−x, −y, z)``, and back when writing PLY.
Rotating splats rotates means, orientations and the view-dependent SH coefficients. A rotation
that permutes the axes with signs (the PLY/glTF turn) moves means and SH coefficients by
reordering and negating them in float32, which is exact; others go through float64.
"""
from __future__ import annotations

import numpy as np

from . import quaternion as quat
from .model import TriangleMesh, SplatCloud
from .sh import rotate_sh, signed_permutation

#: PLY (3DGS) frame -> glTF frame: 180° about +Z (its own inverse).
PLY_TO_GLTF = np.diag([-1.0, -1.0, 1.0])


def rotate_splats(cloud: SplatCloud, rotation: np.ndarray, *,
                  consume: bool = False) -> SplatCloud:
    """Splats rotated by the proper rotation matrix ``rotation`` (3x3) about the origin.

    ``consume``: the caller gives ``cloud`` up; where nothing else refers to its SH array
    (:meth:`~gsverse_format.model.SplatCloud.owns_sh`) the SH are rotated in that array
    (:func:`gsverse_format.sh.rotate_sh`), which the result then holds and ``cloud`` may no
    longer be used. The same values either way."""
    r = np.asarray(rotation, dtype=np.float64)
    if not np.allclose(r @ r.T, np.eye(3), atol=1e-12) or np.linalg.det(r) < 0:
        raise ValueError("rotation must be a proper rotation matrix")
    perm = signed_permutation(r)
    if perm is not None:   # an axis permutation with signs: exact in float32, no float64 copy
        means = np.take(cloud.means, perm[0], axis=1) * perm[1].astype(np.float32)
    else:
        means = cloud.means.astype(np.float64) @ r.T
    q = quat.canonical_sign(quat.multiply(quat.from_matrix(r), quat.normalize(cloud.rotations)))
    own = consume and cloud.owns_sh()     # asked before cloud.sh is an argument (a reference)
    sh = rotate_sh(cloud.sh, r, consume=own) if cloud.sh_degree > 0 else cloud.sh
    return SplatCloud(means, q, cloud.scales, cloud.opacities, sh, cloud.color_space,
                      dict(cloud.extra))


def rotate_mesh(mesh: TriangleMesh, rotation: np.ndarray) -> TriangleMesh:
    """Mesh with vertices rotated by ``rotation`` (faces and their corner order unchanged)."""
    rig = mesh.rig.transformed(rotation) if mesh.rig is not None else None
    return TriangleMesh(mesh.vertices.astype(np.float64) @ np.asarray(rotation, np.float64).T,
                        mesh.faces, rig)
