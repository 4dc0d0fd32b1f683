"""Edge valence of a triangle list: the keyed 1-D unique equals the row-wise unique; face
components: the numpy union–find equals scipy's connected components."""
from __future__ import annotations

import numpy as np

from gsverse_format.meshops import edge_valence, face_components


def _reference(faces):
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    e = e[e[:, 0] != e[:, 1]]
    return np.unique(e, axis=0, return_counts=True)


def test_edge_valence_matches_the_row_unique():
    rng = np.random.default_rng(5)
    faces = rng.integers(0, 400, (3000, 3))
    faces[:10, 1] = faces[:10, 0]                     # degenerate corners contribute no edge
    edges, counts = edge_valence(faces)
    want_edges, want_counts = _reference(faces)
    assert np.array_equal(edges, want_edges) and np.array_equal(counts, want_counts)
    assert edges.dtype == np.int64 and np.all(edges[:, 0] < edges[:, 1])
    big = faces.astype(np.int64) + 2**31               # large indices: keys stay in int64
    assert np.array_equal(edge_valence(big)[0], _reference(big)[0])
    empty = edge_valence(np.zeros((2, 3), np.int64))
    assert empty[0].shape == (0, 2) and empty[1].shape == (0,)


def _components_reference(faces, vertex_count):
    """scipy's connected components of the vertex graph, labels numbered by first face."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    f = np.asarray(faces, np.int64).reshape(-1, 3)
    rows, cols = np.concatenate([f[:, 0], f[:, 1]]), np.concatenate([f[:, 1], f[:, 2]])
    graph = coo_matrix((np.ones(rows.size, np.int8), (rows, cols)),
                       shape=(vertex_count, vertex_count))
    _, vlabel = connected_components(graph, directed=False)
    order = {}
    return np.array([order.setdefault(x, len(order)) for x in vlabel[f[:, 0]]], np.int64)


def test_face_components_match_scipy():
    rng = np.random.default_rng(9)
    cases = [rng.integers(0, n, (m, 3)) for n, m in ((50, 20), (400, 150), (3000, 900))]
    strip = np.stack([np.arange(500), np.arange(1, 501), np.arange(2, 502)], axis=1)
    perm = rng.permutation(800)              # a long strip in shuffled vertex order, and
    cases.append(perm[np.concatenate([strip, np.arange(502, 799).reshape(-1, 3)])])  # islands
    cases.append(np.array([[0, 0, 0], [1, 2, 1], [3, 4, 5], [5, 6, 3]]))   # repeated corners
    for faces in cases:
        n_vertices = int(faces.max()) + 3                # and vertices no face uses
        count, label = face_components(faces, n_vertices)
        want = _components_reference(faces, n_vertices)
        assert np.array_equal(label, want) and count == len(set(want.tolist()))
        assert label.dtype == np.int64
    count, label = face_components(np.zeros((0, 3), np.int64), 4)
    assert count == 0 and label.shape == (0,)
