"""Exact nearest-triangle queries: point–triangle kernel, certified search, ties, exclusion."""
from __future__ import annotations

import numpy as np
import pytest

from gsverse_format.nearest import NearestResult, closest_points_on_triangles, nearest_triangles


@pytest.fixture(autouse=True, params=["auto", "auto-compiled"])
def auto_path(request, monkeypatch):
    """Every test runs ``method="auto"`` twice: as shipped (these small jobs take the numpy
    reference, see ``gsverse_format.backend.NEAREST_NUMPY_BELOW``) and with the size threshold
    at 0, so that ``auto`` takes the compiled search."""
    if request.param == "auto-compiled":
        from gsverse_format.backend import numba_available

        if not numba_available():
            pytest.skip("numba not installed")
        monkeypatch.setattr("gsverse_format.nearest.dispatch.NEAREST_NUMPY_BELOW", 0)
    return request.param


# --------------------------------------------------------------------------- references

def brute_force(points, vertices, faces, exclude=None):
    """(N, F) float64 distances with the same kernel, every pair; excluded faces get +inf."""
    p = np.repeat(points, len(faces), axis=0)
    tri = vertices[np.tile(faces, (len(points), 1))]
    _, _, d = closest_points_on_triangles(p, tri[:, 0], tri[:, 1], tri[:, 2])
    d = d.reshape(len(points), len(faces))
    if exclude is not None:
        d[:, exclude] = np.inf
    return d


def reference_distance(p, a, b, c):
    """Independent point–triangle distance in extended precision: inside projection or edges."""
    L = np.longdouble
    p, a, b, c = (np.asarray(x, L) for x in (p, a, b, c))
    ab, ac, ap = b - a, c - a, p - a

    def dot(x, y):
        return np.sum(x * y, axis=-1)

    def seg(s, e):
        d = e - s
        dd = dot(d, d)
        t = np.clip(np.divide(dot(p - s, d), dd, out=np.zeros_like(dd), where=dd > 0), 0, 1)
        r = p - s - t[:, None] * d
        return dot(r, r)

    best = np.minimum(np.minimum(seg(a, b), seg(a, c)), seg(b, c))
    aa, bb, cc, d1, d2 = dot(ab, ab), dot(ab, ac), dot(ac, ac), dot(ab, ap), dot(ac, ap)
    det = aa * cc - bb * bb
    ok = det > 1e-30 * aa * cc
    with np.errstate(divide="ignore", invalid="ignore"):
        v = (cc * d1 - bb * d2) / det
        w = (aa * d2 - bb * d1) / det
        inside = ok & (v >= 0) & (w >= 0) & (v + w <= 1)
        r = ap - v[:, None] * ab - w[:, None] * ac
        best = np.where(inside, np.minimum(best, dot(r, r)), best)
    return np.sqrt(best).astype(np.float64)


def check_result(res, points, vertices, faces, exclude=None, reference=True):
    """Exactness against brute force, the tie rule, and the geometry of the returned points.

    With ``reference`` the minimum is also checked against the extended-precision reference,
    to 1e-12 relative to the magnitude of the coordinates involved.
    """
    d = brute_force(points, vertices, faces, exclude)
    dmin = d.min(axis=1)
    if reference:
        p = np.repeat(points, len(faces), axis=0)
        tri = vertices[np.tile(faces, (len(points), 1))]
        ref = reference_distance(p, tri[:, 0], tri[:, 1], tri[:, 2]).reshape(len(points), -1)
        if exclude is not None:
            ref[:, exclude] = np.inf
        magnitude = np.abs(vertices).max() + np.abs(points).max(axis=1)
        assert np.all(np.abs(res.distance - ref.min(axis=1)) <= 1e-12 * magnitude)
    assert isinstance(res, NearestResult)
    assert res.face.dtype == np.int64 and res.face.shape == (len(points),)
    np.testing.assert_array_equal(res.distance, dmin)                      # the exact minimum
    np.testing.assert_array_equal(d[np.arange(len(points)), res.face], dmin)
    np.testing.assert_array_equal(res.face, np.argmax(d == dmin[:, None], axis=1))  # smallest index
    if exclude is not None:
        assert not exclude[res.face].any()
    tri = vertices[faces[res.face]]
    scale = np.abs(vertices).max() + np.abs(points).max(axis=1)
    b = res.barycentric
    assert np.all(b >= 0) and np.all(b <= 1)
    np.testing.assert_allclose(b.sum(axis=1), 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.closest, np.einsum("ni,nij->nj", b, tri), rtol=0,
                               atol=1e-12 * np.abs(vertices).max())
    err = np.abs(res.distance - np.linalg.norm(points - res.closest, axis=1))
    assert np.all(err <= 1e-12 * res.distance + 1e-14 * scale)
    return d


# --------------------------------------------------------------------------- meshes

def bumpy_icosphere(subdivisions=3, seed=0, bump=0.05):
    import trimesh

    ico = trimesh.creation.icosphere(subdivisions=subdivisions)
    rng = np.random.default_rng(seed)
    v = ico.vertices * (1.0 + bump * rng.uniform(-1, 1, size=(len(ico.vertices), 1)))
    return v, np.asarray(ico.faces, np.int64)


def nasty_mesh(seed=0):
    """Anisotropic noisy strip with slivers, huge, degenerate and duplicated triangles."""
    rng = np.random.default_rng(seed)
    nx, ny = 40, 8
    xs = np.cumsum(rng.choice([0.5, 1.0, 1e-7], size=nx, p=[0.45, 0.45, 0.1]))  # sliver columns
    x, y = np.meshgrid(xs, np.linspace(0, 0.3, ny), indexing="ij")
    z = 0.2 * np.sin(x) + 0.01 * rng.normal(size=x.shape)
    v = np.column_stack([x.ravel(), y.ravel() + 0.002 * rng.normal(size=x.size), z.ravel()])
    i = (np.arange(nx - 1)[:, None] * ny + np.arange(ny - 1)[None, :]).ravel()
    f = np.concatenate([np.column_stack([i, i + ny, i + 1]), np.column_stack([i + 1, i + ny, i + ny + 1])])
    n = len(v)
    extra = np.array([
        [-30, -30, 5], [60, -20, -4], [10, 40, 0.5],        # huge triangles crossing the strip
        [-5, 10, -30], [50, 5, 20], [20, -40, 10],
        [0, 0, 1], [1, 1, 2], [3, 3, 4],                    # collinear (middle vertex: b)
        [2, 5, 1], [4, 1, 3], [0, 9, -1],                   # collinear (middle vertex: a)
        [7, 7, 7],                                          # a lone point
    ], float)
    extra[9:12] = [[2.0, 5.0, 1.0], [1.0, 7.0, 0.0], [3.0, 3.0, 2.0]]      # a in the middle
    v = np.concatenate([v, extra])
    f = np.concatenate([f, [[n, n + 1, n + 2], [n + 3, n + 4, n + 5],
                            [n + 6, n + 7, n + 8], [n + 9, n + 10, n + 11],
                            [n + 12, n + 12, n + 12], [3, 3, 17], [5, 22, 5]]])
    dup = rng.choice(len(f), 25, replace=False)
    f = np.concatenate([f, f[dup]])                         # exact duplicates, later indices
    perm = rng.permutation(len(f))
    return v, f[perm]


def query_points(vertices, faces, n, seed):
    rng = np.random.default_rng(seed)
    scale = np.ptp(vertices, axis=0).max()
    fi = rng.integers(0, len(faces), n)
    bary = rng.dirichlet([1, 1, 1], n)
    surface = np.einsum("ni,nij->nj", bary, vertices[faces[fi]])
    near = surface + 0.01 * scale * rng.normal(size=(n, 3))
    mid = surface + 0.2 * scale * rng.normal(size=(n, 3))
    far = vertices.mean(axis=0) + 30 * scale * rng.normal(size=(n // 4, 3))
    return np.concatenate([near, mid, far, surface[: n // 4]])


# --------------------------------------------------------------------------- kernel

def test_kernel_matches_extended_precision_reference():
    rng = np.random.default_rng(1)
    m = 20000
    a, b, c = (rng.normal(size=(m, 3)) for _ in range(3))
    p = 2.0 * rng.normal(size=(m, 3))
    closest, bary, d = closest_points_on_triangles(p, a, b, c)
    ref = reference_distance(p, a, b, c)
    np.testing.assert_allclose(d, ref, rtol=1e-12, atol=1e-14)
    assert np.all(bary >= 0) and np.all(bary <= 1)
    np.testing.assert_allclose(bary.sum(axis=1), 1, atol=1e-12)
    np.testing.assert_allclose(closest, bary[:, :1] * a + bary[:, 1:2] * b + bary[:, 2:] * c, atol=1e-12)


def test_kernel_voronoi_regions():
    a, b, c = np.array([0.0, 0, 0]), np.array([2.0, 0, 0]), np.array([0.0, 2, 0])
    cases = [  # point, expected closest point
        ([0.5, 0.5, 1.0], [0.5, 0.5, 0]),        # face
        ([-1.0, -1.0, 0.3], [0, 0, 0]),          # vertex a
        ([3.0, -1.0, 0.0], [2, 0, 0]),           # vertex b
        ([-0.5, 3.0, -2.0], [0, 2, 0]),          # vertex c
        ([1.0, -1.0, 0.5], [1, 0, 0]),           # edge ab
        ([-1.0, 1.5, 0.0], [0, 1.5, 0]),         # edge ac
        ([2.0, 2.0, -1.0], [1, 1, 0]),           # edge bc
    ]
    p = np.array([q for q, _ in cases])
    closest, bary, d = closest_points_on_triangles(p, a, b, c)
    expect = np.array([e for _, e in cases], float)
    np.testing.assert_allclose(closest, expect, atol=1e-15)
    np.testing.assert_allclose(d, np.linalg.norm(p - expect, axis=1), rtol=1e-15)
    np.testing.assert_allclose(bary[1], [1, 0, 0]), np.testing.assert_allclose(bary[3], [0, 0, 1])


@pytest.mark.parametrize("order", [(0, 1, 2), (1, 0, 2), (2, 1, 0), (0, 2, 1)])
def test_kernel_zero_area_triangles(order):
    """Collinear corners are a segment and coincident ones a point; no NaN, exact answers."""
    rng = np.random.default_rng(2)
    ends = np.array([[-1.0, 2.0, 0.5], [3.0, -2.0, 1.5]])
    mid = 0.3 * ends[0] + 0.7 * ends[1]
    corners = np.stack([ends[0], mid, ends[1]])[list(order)]
    p = rng.normal(scale=3, size=(5000, 3))
    p[:50] = ends[0] + rng.uniform(-0.5, 1.5, (50, 1)) * (ends[1] - ends[0])   # on the line
    closest, bary, d = closest_points_on_triangles(p, *corners)
    seg = ends[1] - ends[0]
    t = np.clip((p - ends[0]) @ seg / (seg @ seg), 0, 1)
    expect = ends[0] + t[:, None] * seg
    assert np.all(np.isfinite(closest)) and np.all(np.isfinite(bary)) and np.all(np.isfinite(d))
    np.testing.assert_allclose(closest, expect, atol=1e-12)
    np.testing.assert_allclose(d, np.linalg.norm(p - expect, axis=1), rtol=1e-12, atol=1e-12)
    assert np.all(bary >= 0)
    np.testing.assert_allclose(bary @ corners, closest, atol=1e-12)
    # a point triangle and a triangle with two equal corners
    q = np.array([1.0, 1.0, 1.0])
    closest, bary, d = closest_points_on_triangles(p, q, q, q)
    np.testing.assert_array_equal(closest, np.broadcast_to(q, p.shape))
    np.testing.assert_allclose(d, np.linalg.norm(p - q, axis=1), rtol=1e-15)
    closest, bary, d = closest_points_on_triangles(p, ends[0], ends[0], ends[1])
    np.testing.assert_allclose(closest, expect, atol=1e-12)


def test_kernel_slivers_are_accurate():
    rng = np.random.default_rng(3)
    m = 5000
    a = rng.normal(size=(m, 3))
    b = a + rng.normal(size=(m, 3))
    h = 10.0 ** rng.uniform(-7, -3, size=(m, 1))
    c = a + rng.uniform(-0.5, 1.5, (m, 1)) * (b - a) + h * rng.normal(size=(m, 3))
    p = a + rng.normal(size=(m, 3))
    _, bary, d = closest_points_on_triangles(p, a, b, c)
    np.testing.assert_allclose(d, reference_distance(p, a, b, c), rtol=0, atol=1e-9)
    assert np.all(bary >= 0)


# --------------------------------------------------------------------------- search

def test_icosphere_exact():
    v, f = bumpy_icosphere(3, seed=4)
    p = query_points(v, f, 120, seed=5)
    check_result(nearest_triangles(p, v, f), p, v, f)


def test_nasty_mesh_exact_and_chunk_independent():
    v, f = nasty_mesh(seed=6)
    p = query_points(v, f, 240, seed=7)
    res = nearest_triangles(p, v, f)
    check_result(res, p, v, f)
    again = nearest_triangles(p, v, f, chunk=37)
    for name in ("face", "distance", "closest", "barycentric"):
        np.testing.assert_array_equal(getattr(again, name), getattr(res, name))


def test_offset_and_scaled_mesh_exact():
    v, f = bumpy_icosphere(2, seed=8)
    v = v * 1e-3 + np.array([1e4, -2e4, 5e3])
    p = query_points(v, f, 300, seed=9)
    check_result(nearest_triangles(p, v, f), p, v, f)


def test_ties_pick_smallest_index():
    # two mirror-image triangles at exactly the same float distance from the origin
    up = [[-1.0, -1.0, 1.0], [1.0, -1.0, 1.0], [0.0, 1.0, 1.0]]
    down = [[-1.0, -1.0, -1.0], [1.0, -1.0, -1.0], [0.0, 1.0, -1.0]]
    v = np.array(up + down + [[50.0, 50, 50], [51.0, 50, 50], [50.0, 51, 50]])
    origin = np.zeros((1, 3))
    for faces, expect in [([[0, 1, 2], [3, 4, 5]], 0), ([[3, 4, 5], [0, 1, 2]], 0),
                          ([[6, 7, 8], [3, 4, 5], [0, 1, 2]], 1)]:
        f = np.array(faces)
        d = brute_force(origin, v, f)
        res = nearest_triangles(origin, v, f)
        assert res.face[0] == expect and res.distance[0] == d.min() == 1.0
    # duplicated triangles anywhere in the list resolve to their first copy
    v, f = bumpy_icosphere(2, seed=10)
    rng = np.random.default_rng(11)
    f = np.concatenate([f, f])[rng.permutation(2 * len(f))]
    p = query_points(v, f, 200, seed=12)
    res = nearest_triangles(p, v, f)
    check_result(res, p, v, f)
    key = {tuple(t): i for i, t in reversed(list(enumerate(map(tuple, f))))}  # first index
    assert all(key[tuple(f[i])] == i for i in res.face)


def test_exclude():
    v, f = nasty_mesh(seed=13)
    p = query_points(v, f, 120, seed=14)
    first = nearest_triangles(p, v, f)
    exclude = np.zeros(len(f), bool)
    exclude[first.face[::2]] = True
    exclude[np.random.default_rng(15).choice(len(f), len(f) // 3, replace=False)] = True
    res = nearest_triangles(p, v, f, exclude=exclude)
    check_result(res, p, v, f, exclude)
    only = np.ones(len(f), bool)
    only[17] = False
    res = nearest_triangles(p, v, f, exclude=only)
    assert np.all(res.face == 17)
    check_result(res, p, v, f, only)
    with pytest.raises(ValueError):
        nearest_triangles(p, v, f, exclude=np.ones(len(f), bool))
    with pytest.raises(ValueError):
        nearest_triangles(p, v, f, exclude=np.zeros(len(f) - 1, bool))


def test_points_on_vertices_and_edges():
    v, f = bumpy_icosphere(2, seed=16)
    rng = np.random.default_rng(17)
    edges = f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)[rng.choice(3 * len(f), 300, replace=False)]
    t = rng.uniform(size=(len(edges), 1))
    p = np.concatenate([v, 0.5 * (v[edges[:, 0]] + v[edges[:, 1]]),
                        v[edges[:, 0]] + t * (v[edges[:, 1]] - v[edges[:, 0]])])
    res = nearest_triangles(p, v, f)
    check_result(res, p, v, f)
    assert res.distance.max() < 1e-14
    np.testing.assert_allclose(res.closest, p, atol=1e-14)


def test_empty_points_and_validation():
    v, f = bumpy_icosphere(1, seed=18)
    calls = []
    res = nearest_triangles(np.zeros((0, 3)), v, f, progress=lambda d, t: calls.append((d, t)))
    assert res.face.shape == (0,) and res.face.dtype == np.int64
    assert res.closest.shape == (0, 3) and res.barycentric.shape == (0, 3)
    assert res.distance.shape == (0,) and res.distance.dtype == np.float64
    p = np.random.default_rng(19).normal(size=(10, 3))
    calls.clear()
    nearest_triangles(p, v, f, chunk=4, progress=lambda d, t: calls.append((d, t)))
    assert calls == [(4, 10), (8, 10), (10, 10)]
    with pytest.raises(ValueError):
        nearest_triangles(p, v, np.zeros((0, 3), np.int64))
    with pytest.raises(ValueError):
        nearest_triangles(p[:, :2], v, f)
    with pytest.raises(ValueError):
        nearest_triangles(p, v, f + len(v))
    with pytest.raises(ValueError):
        nearest_triangles(np.full((1, 3), np.nan), v, f)


def test_single_and_degenerate_only_meshes():
    rng = np.random.default_rng(20)
    p = rng.normal(scale=4, size=(300, 3))
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [3, 0, 0]])
    for f in ([[0, 1, 2]], [[0, 1, 3], [1, 1, 1], [4, 3, 0], [2, 2, 4]]):
        f = np.array(f)
        res = nearest_triangles(p, v, f)
        check_result(res, p, v, f)
        tri = v[f[res.face]]
        np.testing.assert_allclose(res.distance, reference_distance(p, tri[:, 0], tri[:, 1], tri[:, 2]),
                                   rtol=1e-12)


@pytest.mark.parametrize("mesh", ["icosphere", "nasty"])
def test_hierarchy_bounds_contain_their_triangles(mesh):
    """White-box check of the certificate: every node's ball and cylinder hold its triangles."""
    from gsverse_format.nearest import reference as nt

    v, f = bumpy_icosphere(3, seed=21) if mesh == "icosphere" else nasty_mesh(seed=22)
    tree = nt._build(v[f[:, 0]], v[f[:, 1]], v[f[:, 2]], np.arange(len(f)))
    tol = 1e-12 * np.abs(v).max()
    node = np.repeat(np.arange(len(tree.start)), tree.count)
    pos = np.concatenate([np.arange(s, s + c) for s, c in zip(tree.start, tree.count)])
    x = v[f[tree.order[pos]]]                                        # (pairs, 3 corners, 3)
    c, n = tree.bound[0:3, node].T[:, None, :], tree.bound[3:6, node].T[:, None, :]
    d = x - c
    h = np.sum(d * n, axis=2)
    lat = np.linalg.norm(d - h[..., None] * n, axis=2)
    assert np.all(np.linalg.norm(d, axis=2) <= tree.bound[6, node][:, None] + tol)
    assert np.all(np.abs(h) <= tree.bound[7, node][:, None] + tol)
    assert np.all(lat <= tree.bound[8, node][:, None] + tol)
    # and the lower bound never exceeds the true distance to a node's triangles
    p = query_points(v, f, 8, seed=23)
    q = np.repeat(np.arange(len(p)), len(pos))
    nodes, faces = np.tile(node, len(p)), f[tree.order[np.tile(pos, len(p))]]
    dist = reference_distance(p[q], v[faces[:, 0]], v[faces[:, 1]], v[faces[:, 2]])
    lb = nt._lower_bounds(tree, np.ascontiguousarray(p.T), q, nodes)
    assert np.all(lb <= dist + 1e-12 * (np.abs(p[q]).max(axis=1) + np.abs(v).max()))
