"""The worked examples printed in spec/README.md, recomputed by the reference remap."""
from __future__ import annotations

import numpy as np
import pytest

from gsverse_format import quaternion as quat
from gsverse_format.model import Anchoring, GamesAnchors, LocalAnchors, TriangleMesh
from gsverse_format.remapping.reference import remap

REST = TriangleMesh([[0, 0, 0], [2, 0, 0], [0, 1, 0]], [[0, 1, 2]])
SCALE = [[0.125, 0.375, 0.0625]]


@pytest.mark.parametrize("law,cov,scales", [
    ("affine", [0.140625, 0.0625, 0.0078125], [0.25, 0.375, 0.0883883476]),
    ("rigid", [0.28125, 0.03125, 0.0078125], [0.1767766953, 0.5303300859, 0.0883883476]),
])
def test_example_1(law, cov, scales):
    anchors = LocalAnchors([0], [[0.25, 0.5]], [0.125], [[0, 0, 0, 1]], SCALE, law)
    r = remap(Anchoring(REST, anchors), np.array([[0, 0, 0], [0, 4, 0], [-1, 0, 0]], float))
    assert np.allclose(r.means[0], [-0.5, 1, 0.1767766953], atol=1e-10)
    assert np.allclose(r.covariances[0], np.diag(cov), atol=1e-12)
    assert np.allclose(r.scales[0], scales, atol=1e-10)
    assert np.allclose(np.abs(r.rotations[0]), [0, 0, 0.7071067812, 0.7071067812], atol=1e-10)


@pytest.mark.parametrize("law,cov", [
    ("affine", [[0.1504155097, -0.0800643672, -0.1319521019],
                [-0.0800643672, 0.0710522307, 0.0785591657],
                [-0.1319521019, 0.0785591657, 0.1271967727]]),
    ("rigid", [[0.1516519468, -0.0306877600, -0.1007813439],
               [-0.0306877600, 0.0320743478, 0.0301091211],
               [-0.1007813439, 0.0301091211, 0.0804442972]]),
])
def test_example_2(law, cov):
    q = [[0.102597833, 0.205195665, 0.307793498, 0.923380494]]
    anchors = LocalAnchors([0], [[0.25, 0.5]], [0.125], q, SCALE, law)
    current = np.array([[0.5, 0.25, 0.125], [2.25, 1, 0.5], [-0.25, 1.5, 1]])
    r = remap(Anchoring(REST, anchors), current)
    assert np.allclose(r.means[0], [0.5716245404, 0.9742961090, 0.7900765932], atol=2e-10)
    assert np.allclose(r.covariances[0], cov, atol=2e-10)


def test_example_3_games():
    mesh = TriangleMesh([[0, 0, 0], [3, 0, 0], [0, 3, 0]], [[0, 1, 2]])
    r = remap(Anchoring(mesh, GamesAnchors([0], [[0.3, 0.5]], [2.0])))
    assert np.allclose(r.means[0], [0.9, 1.5, 0], atol=1e-7)
    assert np.allclose(r.scales[0], [3e-8, 2.2360679975, 1.3416407965], rtol=1e-10, atol=1e-17)
    expected = [[0, 0.8944271910, 0.4472135955], [0, -0.4472135955, 0.8944271910], [1, 0, 0]]
    assert np.allclose(quat.to_matrix(r.rotations[0]), expected, atol=1e-10)


@pytest.mark.parametrize("law", ["affine", "rigid"])
def test_example_4_degenerate_at_rest(law):
    """Spec v1.1: a face degenerate at rest follows its current frame unscaled (G := I)."""
    mesh = TriangleMesh([[0, 0, 0], [2, 0, 0], [1, 0, 0]], [[0, 1, 2]])
    anchors = LocalAnchors([0], [[0.25, 0.25]], [0.125], [[0, 0, 0, 1]], SCALE, law)
    r = remap(Anchoring(mesh, anchors), np.array([[0, 0, 0], [0, 2, 0], [0, 1, 0]], float))
    assert np.allclose(r.means[0], [0, 0.75, -0.125], atol=1e-12)
    assert np.allclose(r.covariances[0], np.diag([0.140625, 0.015625, 0.00390625]), atol=1e-12)
    assert np.allclose(r.scales[0], SCALE[0], atol=1e-12)
    assert np.allclose(np.abs(r.rotations[0]), [0.7071067812, 0.7071067812, 0, 0], atol=1e-10)
    rest = remap(Anchoring(mesh, anchors))          # the stored splat comes back at rest
    assert np.allclose(rest.means[0], [0.75, 0, 0.125], atol=1e-12)
    assert np.allclose(rest.covariances[0], np.diag([0.015625, 0.140625, 0.00390625]), atol=1e-12)


def test_example_5_games_midpoint():
    """Spec v1.1: v1 at the centroid of a flat triangle: the splat lies along w."""
    mesh = TriangleMesh([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]])
    r = remap(Anchoring(mesh, GamesAnchors([0], [[0.3, 0.5]], [2.0])))
    assert np.allclose(r.means[0], [1.300000012, 0, 0], atol=1e-9)
    assert np.allclose(r.scales[0], [3e-8, 2e-8, 1.00000001], rtol=1e-10, atol=1e-17)
    expected = [[0, 0, 1], [1, 0, 0], [0, 1, 0]]
    assert np.allclose(quat.to_matrix(r.rotations[0]), expected, atol=1e-12)
    assert np.allclose(r.covariances[0], np.diag([1.00000002, 9e-16, 4e-16]), rtol=1e-9,
                       atol=1e-20)
