"""The splat/mesh fit check (gsverse_format.fit) on generated splats around a generated mesh."""
from __future__ import annotations

import numpy as np
import pytest

from gsverse_format.fit import MIN_EXTENT_RATIO, NEAR_FRACTION, assess_fit
from gsverse_format.nearest import nearest_triangles


def _box_mesh(size=(1.0, 1.6, 0.8)):
    """A closed box (12 triangles) centred on the origin, elongated along y."""
    sx, sy, sz = (s / 2 for s in size)
    v = np.array([[x, y, z] for x in (-sx, sx) for y in (-sy, sy) for z in (-sz, sz)], float)
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return v, f


def _splats_on(v, f, n=2000, noise=0.01, seed=0):
    rng = np.random.default_rng(seed)
    tri = v[f[rng.integers(0, len(f), n)]]
    w = rng.dirichlet((1, 1, 1), n)
    return np.einsum("nk,nkj->nj", w, tri) + rng.normal(0, noise, (n, 3))


def _fit(means, v, f):
    return assess_fit(means, v, nearest_triangles(means, v, f, method="numpy").distance)


def test_matching_mesh_passes_with_numbers():
    v, f = _box_mesh()
    r = _fit(_splats_on(v, f), v, f)
    assert r.ok and r.message() == ""
    assert r.near_share > 0.99
    assert r.mesh_diagonal == pytest.approx(np.linalg.norm([1, 1.6, 0.8]))


def test_moved_mesh_is_far_and_names_the_offset():
    v, f = _box_mesh()
    means = _splats_on(v, f)
    moved = v + [40 * np.linalg.norm(v.max(0) - v.min(0)), 0, 0]
    r = _fit(means, moved, f)
    assert not r.ok
    assert r.near_share < 0.01 and r.median_distance > 30
    assert "0% of the splats" in r.problem and "offset by (-82," in r.hint


def test_mesh_in_other_units_names_the_factor():
    v, f = _box_mesh()
    means = _splats_on(v, f)
    r = _fit(means, v * 100, f)     # the mesh in centimetres, the splats in metres
    assert not r.ok and r.splat_diagonal / r.mesh_diagonal < MIN_EXTENT_RATIO
    assert "larger than the splats" in r.problem and "by 100" in r.hint


def test_mesh_in_another_frame_names_the_turn():
    v, f = _box_mesh()
    means = _splats_on(v, f)
    z_up = v @ np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], float).T   # y-up -> z-up
    r = _fit(means, z_up, f)
    assert not r.ok
    assert "turned (x, y, z) -> (x, -z, y)" in r.hint or "turned (x, y, z) -> (x, z, -y)" in r.hint


def test_scene_around_a_small_object_is_not_a_mismatch():
    """A capture of a room around an anchored object: most splats are far, which is fine."""
    v, f = _box_mesh()
    rng = np.random.default_rng(3)
    room = rng.uniform(-20, 20, (20000, 3))
    means = np.concatenate([_splats_on(v, f, 1000), room])
    r = _fit(means, v, f)
    assert r.ok, r.message()
    assert NEAR_FRACTION * r.mesh_diagonal > 0 and 0.01 < r.near_share < 0.5


def test_floaters_do_not_make_a_scale_mismatch():
    v, f = _box_mesh()
    means = _splats_on(v, f)
    means[:5] = 1e4            # five floaters far away
    assert _fit(means, v, f).ok
