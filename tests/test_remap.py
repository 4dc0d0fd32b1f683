"""The reference remap: rest reproduction, rigid motions, scaling, GaMeS formulas, extremes."""
from __future__ import annotations

import numpy as np
import pytest

from gsverse_format import quaternion as quat
from gsverse_format.binding import bind_local
from gsverse_format.frames import EPS_DEGENERATE, games_frames, local_frames
from gsverse_format.model import Anchoring, GamesAnchors, LocalAnchors, TriangleMesh
from gsverse_format.remapping.reference import remap

from helpers import bumpy_sphere, max_rel_cov_error, random_rotation, surface_splats

F32_REL = 2e-6  # float32 storage of anchors: a few units of float32 roundoff (2^-23 ≈ 1.2e-7)


@pytest.fixture(scope="module")
def mesh():
    return bumpy_sphere(2, seed=1)


@pytest.fixture(scope="module")
def splats(mesh):
    return surface_splats(mesh, 3000, seed=2, offset=0.05)


def _games(mesh, n=2000, seed=3):
    rng = np.random.default_rng(seed)
    alpha = rng.dirichlet([1, 1, 1], n)
    return Anchoring(mesh, GamesAnchors(rng.integers(0, mesh.face_count, n), alpha[:, 1:],
                                        rng.uniform(0.2, 3.0, n)))


@pytest.mark.parametrize("law", ["affine", "rigid"])
def test_local_remap_at_rest_reproduces_splats(mesh, splats, law):
    bound = bind_local(splats, mesh, deformation=law)
    r = remap(Anchoring(mesh, bound.anchors))
    size = np.linalg.norm(np.ptp(mesh.vertices, axis=0))
    assert np.max(np.abs(r.means - splats.means)) <= F32_REL * size
    assert max_rel_cov_error(r.covariances, splats.covariances()) <= F32_REL
    # The reported rotation/scale pair is the stored one (up to quaternion sign).
    assert np.allclose(r.scales, splats.scales, rtol=F32_REL)
    dots = np.abs(np.sum(r.rotations * quat.normalize(splats.rotations), axis=1))
    assert np.min(dots) > 1 - 1e-6


def test_games_remap_at_rest_is_stable_through_float32(mesh):
    anchoring = _games(mesh)
    first = remap(anchoring)
    # Storing the rest pose as float32 and comparing with a fresh remap: float32 precision.
    stored_means = first.means.astype(np.float32).astype(np.float64)
    again = remap(anchoring)
    assert np.max(np.abs(again.means - stored_means)) <= 1e-6
    assert np.array_equal(first.covariances, again.covariances)


@pytest.mark.parametrize("profile", ["affine", "rigid", "games"])
def test_rigid_motion_moves_and_rotates_every_splat_exactly(mesh, splats, profile):
    if profile == "games":
        anchoring = _games(mesh)
    else:
        anchoring = Anchoring(mesh, bind_local(splats, mesh, deformation=profile).anchors)
    rest = remap(anchoring)
    rot = random_rotation(7)
    shift = np.array([0.3, -2.0, 5.0])
    moved = mesh.vertices.astype(np.float64) @ rot.T + shift
    r = remap(anchoring, moved)
    assert np.allclose(r.means, rest.means @ rot.T + shift, atol=1e-12, rtol=0)
    expected = rot @ rest.covariances @ rot.T
    assert max_rel_cov_error(r.covariances, expected) < 1e-9


@pytest.mark.parametrize("profile", ["affine", "rigid", "games"])
def test_uniform_scaling_scales_every_splat(mesh, splats, profile):
    if profile == "games":
        anchoring = _games(mesh)
    else:
        anchoring = Anchoring(mesh, bind_local(splats, mesh, deformation=profile).anchors)
    rest = remap(anchoring)
    c = 2.5
    r = remap(anchoring, mesh.vertices.astype(np.float64) * c)
    assert np.allclose(r.means, rest.means * c, atol=1e-12, rtol=1e-12)
    if profile == "games":
        # GaMeS's absolute ε = 1e-8 (scene units) does not scale: the in-plane scales scale up
        # to ε relative; the normal-axis scale (ρ ε + ε) stays as it is.
        assert np.allclose(r.scales[:, 1:], rest.scales[:, 1:] * c, rtol=1e-6, atol=0)
        assert np.allclose(r.scales[:, 0], rest.scales[:, 0], rtol=1e-12, atol=0)
    else:
        assert max_rel_cov_error(r.covariances, rest.covariances * c * c) < 1e-12


def test_games_matches_hand_computed_triangle():
    # v0=(0,0,0), v1=(3,0,0), v2=(0,3,0): centroid c=(1,1,0), v1−c=(2,−1,0), |v1−c|=√5,
    # n=(0,0,1), b1=(2,−1,0)/√5, w=v2−c=(−1,2,0), Gram–Schmidt residual (0.6,1.2,0) -> b2=(1,2,0)/√5,
    # base scales (ε, (√5+ε)/2, <w,b2>/2 = 3/(2√5)). With α=(0.2,0.3,0.5), ρ=2:
    mesh = TriangleMesh([[0, 0, 0], [3, 0, 0], [0, 3, 0]], [[0, 1, 2]])
    anchoring = Anchoring(mesh, GamesAnchors([0], [[0.3, 0.5]], [2.0]))
    r = remap(anchoring)
    eps = 1e-8
    s5 = np.sqrt(5.0)
    assert np.allclose(r.means[0], [0.9, 1.5, 0.0], atol=1e-7)  # α stored as float32
    assert np.allclose(r.scales[0], [2 * eps + eps, 2 * (s5 + eps) / 2 + eps, 2 * 3 / (2 * s5) + eps],
                       rtol=1e-12, atol=1e-20)
    frame = np.array([[0, 0, 1], [2 / s5, -1 / s5, 0], [1 / s5, 2 / s5, 0]]).T  # columns n, b1, b2
    assert np.allclose(quat.to_matrix(r.rotations[0]), frame, atol=1e-12)
    rotation, base, centroid = games_frames(mesh.triangles())
    assert np.allclose(centroid[0], [1, 1, 0])
    assert np.allclose(base[0], [eps, (s5 + eps) / 2, 3 / (2 * s5)])


def test_affine_law_applies_the_triangle_deformation_gradient():
    # A flat square of two triangles in the xy plane stretched 2x along x: F = diag(2, 1, √2)
    # (normal axis k = sqrt(area ratio) = √2).
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    mesh = TriangleMesh(v, [[0, 1, 2], [0, 2, 3]])
    rng = np.random.default_rng(5)
    n = 50
    q = quat.normalize(rng.normal(size=(n, 4)))
    s = rng.uniform(0.01, 0.1, (n, 3))
    anchors = LocalAnchors(rng.integers(0, 2, n), rng.uniform(0, 0.5, (n, 2)),
                           rng.uniform(-0.1, 0.1, n), q, s, "affine")
    anchoring = Anchoring(mesh, anchors)
    rest = remap(anchoring)
    stretched = v * [2.0, 1.0, 1.0]
    r = remap(anchoring, stretched)
    f = np.diag([2.0, 1.0, np.sqrt(2.0)])
    assert np.allclose(r.means, rest.means @ f.T, atol=1e-7)
    assert max_rel_cov_error(r.covariances, f @ rest.covariances @ f.T) < 1e-6


def test_rigid_law_keeps_shape_and_scales_with_area():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    mesh = TriangleMesh(v, [[0, 1, 2]])
    anchors = LocalAnchors([0], [[0.2, 0.3]], [0.05], [[0, 0, 0, 1]], [[0.1, 0.02, 0.01]], "rigid")
    r = remap(Anchoring(mesh, anchors), v * [4.0, 1.0, 1.0])  # area x4 -> k = 2
    assert np.allclose(r.scales[0], [0.2, 0.04, 0.02], rtol=1e-6)
    assert np.allclose(r.means[0], [0.8, 0.3, 0.1], atol=1e-7)


def _check_sound(r):
    assert np.all(np.isfinite(r.means)) and np.all(np.isfinite(r.covariances))
    assert np.all(np.isfinite(r.rotations)) and np.all(np.isfinite(r.scales))
    assert np.allclose(np.linalg.norm(r.rotations, axis=1), 1.0, atol=1e-12)
    assert np.allclose(r.covariances, np.swapaxes(r.covariances, 1, 2), atol=0, rtol=0) or \
        np.max(np.abs(r.covariances - np.swapaxes(r.covariances, 1, 2))) <= \
        1e-12 * np.max(np.abs(r.covariances))
    eig = np.linalg.eigvalsh(r.covariances)
    assert np.all(eig >= -1e-12 * np.maximum(eig.max(axis=1, keepdims=True), 1e-300))


@pytest.mark.parametrize("profile", ["affine", "rigid", "games"])
def test_degenerate_inverted_and_collapsed_triangles_stay_finite(profile):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    mesh = TriangleMesh(v, [[0, 1, 2]])
    rng = np.random.default_rng(9)
    n = 20
    if profile == "games":
        anchors = GamesAnchors(np.zeros(n), rng.dirichlet([1, 1, 1], n)[:, 1:], rng.uniform(0.5, 2, n))
    else:
        anchors = LocalAnchors(np.zeros(n), rng.uniform(-0.2, 1, (n, 2)), rng.uniform(-0.1, 0.1, n),
                               quat.normalize(rng.normal(size=(n, 4))), rng.uniform(0.01, 0.1, (n, 3)),
                               profile)
    anchoring = Anchoring(mesh, anchors)
    poses = {
        "segment": [[0, 0, 0], [1, 0, 0], [2, 0, 0]],
        "sliver": [[0, 0, 0], [1, 0, 0], [0.5, 1e-9, 0]],
        "point": [[1, 1, 1], [1, 1, 1], [1, 1, 1]],
        "two_coincident": [[0, 0, 0], [0, 0, 0], [0, 1, 0]],
        "inverted": [[0, 0, 0], [0, 1, 0], [1, 0, 0]],
        "huge_stretch": [[0, 0, 0], [100, 0, 0], [0, 1, 0]],
        "offset_1e5": [[1e5, 1e5, 1e5], [1e5 + 1, 1e5, 1e5], [1e5, 1e5 + 1, 1e5]],
    }
    for name, pose in poses.items():
        r = remap(anchoring, np.array(pose, float))
        _check_sound(r)
    # An inverted triangle flips the normal: offsets go to the other side, no reflection.
    if profile != "games":
        r = remap(anchoring, np.array(poses["inverted"], float))
        assert np.all(np.linalg.det(quat.to_matrix(r.rotations)) > 0)


def test_degenerate_rule_constants():
    tri = np.array([[[0, 0, 0], [1, 0, 0], [0.5, 0.9 * EPS_DEGENERATE, 0]],
                    [[0, 0, 0], [1, 0, 0], [0.5, 1.1 * EPS_DEGENERATE, 0]]])
    frames = local_frames(tri)
    assert list(frames.regular) == [False, True]
    assert np.allclose(np.linalg.det(frames.rotation), 1.0)


def test_remap_is_deterministic(mesh, splats):
    anchoring = Anchoring(mesh, bind_local(splats, mesh).anchors)
    v = mesh.vertices * np.array([1.5, 0.7, 1.0], np.float32)
    a, b = remap(anchoring, v), remap(anchoring, v)
    assert np.array_equal(a.means, b.means) and np.array_equal(a.covariances, b.covariances)
