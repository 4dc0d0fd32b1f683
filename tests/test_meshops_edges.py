"""Edge valence of a triangle list: the keyed 1-D unique equals the row-wise unique."""
from __future__ import annotations

import numpy as np

from gsverse_format.meshops import edge_valence


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
