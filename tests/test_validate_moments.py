"""The fast moments of the remap (used by the rest-pose check) equal the reference remap."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gsverse_format.binding import bind_local
from gsverse_format.model import Anchoring, GamesAnchors, LocalAnchors, TriangleMesh
from gsverse_format.remapping.reference import (covariance_entries, covariances_from,
                                               iter_moments, remap, remap_moments)

from helpers import bumpy_sphere, surface_splats


def _deformed(mesh: TriangleMesh, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    stretch = np.diag(rng.uniform(0.5, 1.8, 3)) @ Rotation.random(random_state=seed).as_matrix()
    return mesh.vertices.astype(np.float64) @ stretch.T + rng.normal(0, 0.03,
                                                                      mesh.vertices.shape)


def _close(got, want, scale):
    assert np.max(np.abs(got - want)) <= 1e-12 * scale


@pytest.mark.parametrize("deformation", ["affine", "rigid"])
def test_local_moments_equal_remap(deformation):
    mesh = bumpy_sphere(2, 0)
    cloud = surface_splats(mesh, 3000, 1)
    anchoring = Anchoring(mesh, bind_local(cloud, mesh, deformation=deformation).anchors)
    for vertices in (None, _deformed(mesh, 3), _deformed(mesh, 4)):
        ref = remap(anchoring, vertices)
        means, cov = remap_moments(anchoring, vertices)
        _close(means, ref.means, 1.0)
        _close(cov, ref.covariances, np.abs(ref.covariances).max())


def test_games_moments_equal_remap():
    mesh = bumpy_sphere(2, 1)
    rng = np.random.default_rng(0)
    n = 2000
    anchors = GamesAnchors(rng.integers(0, mesh.face_count, n), rng.dirichlet([1, 1, 1], n)[:, 1:],
                           rng.uniform(-0.5, 2.0, n))
    anchoring = Anchoring(mesh, anchors)
    for vertices in (None, _deformed(mesh, 5)):
        ref = remap(anchoring, vertices)
        means, cov = remap_moments(anchoring, vertices)
        _close(means, ref.means, 1.0)
        _close(cov, ref.covariances, np.abs(ref.covariances).max())


def test_degenerate_faces_zero_quaternions_and_blocks():
    # Faces degenerate at rest or now, zero and unnormalized quaternions, several blocks.
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [0, 0, 1], [0, 0, 1]], float)
    mesh = TriangleMesh(v, [[0, 1, 2], [0, 1, 3], [4, 4, 4], [0, 2, 4]])
    rng = np.random.default_rng(2)
    n = 70000
    q = rng.normal(size=(n, 4)) * rng.uniform(0.5, 2.0, (n, 1))
    q[:5] = 0.0
    anchors = LocalAnchors(rng.integers(0, 4, n), rng.uniform(-0.5, 1.5, (n, 2)),
                           rng.normal(0, 0.1, n), q, rng.uniform(0, 0.1, (n, 3)))
    anchoring = Anchoring(mesh, anchors)
    current = v + rng.normal(0, 0.1, v.shape)
    current[5] = current[4]
    for vertices in (None, current):
        ref = remap(anchoring, vertices)
        means, cov = remap_moments(anchoring, vertices)
        _close(means, ref.means, 1.0)
        _close(cov, ref.covariances, np.abs(ref.covariances).max())
    blocks = [sl for sl, _, _ in iter_moments(anchoring, block=1000)]
    assert blocks[0] == slice(0, 1000) and blocks[-1].stop == n


def test_covariance_entries_match_the_model():
    cloud = surface_splats(bumpy_sphere(1, 0), 500, 3)
    want = cloud.covariances()
    got = covariances_from(cloud.rotations, cloud.scales)
    _close(got, want, np.abs(want).max())
    c00, c01, c02, c11, c12, c22 = covariance_entries(cloud.rotations, cloud.scales)
    _close(np.stack([c00, c01, c02, c11, c12, c22], 1),
           want[:, [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]], np.abs(want).max())


def test_rest_moments_reproduce_a_bound_rest_pose():
    mesh = bumpy_sphere(2, 2)
    cloud = surface_splats(mesh, 2000, 5)
    anchoring = Anchoring(mesh, bind_local(cloud, mesh).anchors)
    means, cov = remap_moments(anchoring)
    assert np.max(np.linalg.norm(means - cloud.means, axis=1)) < 1e-6
    want = cloud.covariances()
    rel = np.linalg.norm(cov - want, axis=(1, 2)) / np.linalg.norm(want, axis=(1, 2))
    assert rel.max() < 1e-5
