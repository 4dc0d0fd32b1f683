"""SH rotation and rigid frame changes of splats."""
from __future__ import annotations

import numpy as np
import pytest

from gsverse_format import quaternion as quat
from gsverse_format.sh import rotate_sh, sh_basis, sh_rotation_matrix
from gsverse_format.transform import PLY_TO_GLTF, rotate_splats

from helpers import random_rotation, random_splats


@pytest.mark.parametrize("degree", [1, 2, 3])
def test_rotated_sh_evaluates_like_rotated_directions(degree):
    rng = np.random.default_rng(degree)
    sh = rng.normal(size=(5, (degree + 1) ** 2, 3))
    r = random_rotation(degree)
    rotated = rotate_sh(sh, r).astype(np.float64)
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    # colour of the rotated splat along R d equals the original colour along d
    before = np.einsum("dk,nkc->ndc", sh_basis(d, degree), sh)
    after = np.einsum("dk,nkc->ndc", sh_basis(d @ r.T, degree), rotated)
    assert np.allclose(before, after, atol=1e-5)


def test_axis_rotation_is_exact_signs():
    d = sh_rotation_matrix(PLY_TO_GLTF, 3)
    assert set(np.unique(d)) <= {-1.0, 0.0, 1.0}
    assert np.array_equal(np.abs(d), np.eye(16))


def test_ply_frame_change_is_its_own_inverse_exactly():
    cloud = random_splats(100, seed=4, sh_degree=3)
    back = rotate_splats(rotate_splats(cloud, PLY_TO_GLTF), PLY_TO_GLTF)
    assert np.array_equal(back.means, cloud.means)
    assert np.array_equal(back.sh, cloud.sh)
    dots = np.abs(np.sum(back.rotations.astype(np.float64) * quat.normalize(cloud.rotations), axis=1))
    assert np.allclose(dots, 1.0, atol=1e-7)
    assert np.allclose(back.covariances(), cloud.covariances(), rtol=1e-5, atol=1e-12)
