"""SH rotation and rigid frame changes of splats."""
from __future__ import annotations

import numpy as np
import pytest

from gsverse_format import quaternion as quat
from gsverse_format.io.registry import Z_UP_TO_GLTF
from gsverse_format.sh import rotate_sh, sh_basis, sh_rotation_matrix, signed_permutation
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


def _generic_rotate_sh(sh, r):
    """The coefficient rotation as one float64 matrix product, rounded once to float32."""
    d = sh_rotation_matrix(r, int(round(np.sqrt(sh.shape[1]))) - 1)
    return np.einsum("ij,njc->nic", d, sh.astype(np.float64)).astype(np.float32)


_QUARTER_Z = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
_HALF_X = np.diag([1.0, -1.0, -1.0])


@pytest.mark.parametrize("rotation", [PLY_TO_GLTF, _QUARTER_Z, _HALF_X, np.eye(3)],
                         ids=["180z", "90z", "180x", "identity"])
@pytest.mark.parametrize("degree", [1, 2, 3])
def test_signed_permutation_rotation_matches_the_generic_product_exactly(rotation, degree):
    d = sh_rotation_matrix(rotation, degree)
    assert signed_permutation(d) is not None      # these take the reordering path
    rng = np.random.default_rng(degree)
    sh = (rng.normal(size=(3000, (degree + 1) ** 2, 3)) * 10.0 ** rng.uniform(-30, 30, (3000, 1, 1))
          ).astype(np.float32)
    fast = rotate_sh(sh, rotation)
    assert fast.dtype == np.float32 and fast.shape == sh.shape
    assert np.array_equal(fast, _generic_rotate_sh(sh, rotation))
    assert not np.shares_memory(fast, sh)


@pytest.mark.parametrize("rotation", [Z_UP_TO_GLTF, "random"])
def test_other_rotations_take_the_generic_product(rotation):
    r = random_rotation(7) if isinstance(rotation, str) else rotation
    d = sh_rotation_matrix(r, 3)
    assert signed_permutation(d) is None           # band 2 mixes coefficients: not a permutation
    rng = np.random.default_rng(8)
    sh = rng.normal(size=(70_000, 16, 3)).astype(np.float32)   # more than one block
    # float64 sums in another order: equal up to one float32 rounding of each coefficient
    np.testing.assert_allclose(rotate_sh(sh, r), _generic_rotate_sh(sh, r), rtol=2e-7, atol=1e-6)


def test_signed_permutation_detection():
    assert signed_permutation(np.diag([1.0, -1.0, 1.0])) is not None
    index, sign = signed_permutation(np.array([[0.0, -1.0], [1.0, 0.0]]))
    assert index.tolist() == [1, 0] and sign.tolist() == [-1.0, 1.0]
    assert signed_permutation(np.array([[0.0, 2.0], [1.0, 0.0]])) is None     # not ±1
    assert signed_permutation(np.array([[1.0, 1.0], [0.0, 0.0]])) is None     # a row of two
    assert signed_permutation(np.array([[1.0, 0.0], [1.0, 0.0]])) is None     # a column of two


@pytest.mark.parametrize("rotation", [PLY_TO_GLTF, _QUARTER_Z, Z_UP_TO_GLTF, "random"])
def test_rotate_splats_means_match_the_float64_product(rotation):
    r = random_rotation(3) if isinstance(rotation, str) else rotation
    cloud = random_splats(500, seed=9, sh_degree=3)
    moved = rotate_splats(cloud, r)
    assert moved.means.dtype == np.float32
    want = (cloud.means.astype(np.float64) @ np.asarray(r, np.float64).T).astype(np.float32)
    assert np.array_equal(moved.means, want)
    assert np.allclose(moved.sh, _generic_rotate_sh(cloud.sh, r), rtol=2e-7, atol=1e-6)


@pytest.mark.parametrize("rotation", [PLY_TO_GLTF, _QUARTER_Z, Z_UP_TO_GLTF, "random"])
def test_consumed_cloud_rotates_in_its_own_sh_array(rotation):
    """rotate_splats(consume=True): the same splats, bit for bit; the SH written into the
    given cloud's array where only that cloud refers to it (signs and general rotations; a
    reordering of coefficients makes a new array), never into an array someone else holds."""
    r = random_rotation(4) if isinstance(rotation, str) else rotation
    want = rotate_splats(random_splats(300, seed=4, sh_degree=3), r)
    cloud = random_splats(300, seed=4, sh_degree=3)
    address = cloud.sh.__array_interface__["data"][0]
    moved = rotate_splats(cloud, r, consume=True)
    for name in ("means", "rotations", "scales", "opacities", "sh"):
        assert np.array_equal(getattr(moved, name), getattr(want, name)), name
    reordered = signed_permutation(sh_rotation_matrix(r, 3)) is not None and \
        not np.array_equal(signed_permutation(sh_rotation_matrix(r, 3))[0], np.arange(16))
    assert (moved.sh.__array_interface__["data"][0] == address) is not reordered

    shared = random_splats(300, seed=4, sh_degree=3)
    held = shared.sh                                  # a second reference: not the cloud's alone
    before = held.copy()
    moved = rotate_splats(shared, r, consume=True)
    assert np.array_equal(held, before) and np.array_equal(moved.sh, want.sh)
