"""The compiled nearest-triangle searches (numba, and C) equal the numpy reference bit for bit.

Faces (including the smallest-index tie rule), distances, closest points and barycentrics must
be identical to ``nearest_triangles(..., method="numpy")``, bit for bit (signed zeros too), and
all must be the brute-force minimum (``check_result`` from ``test_nearest``; the extended-precision comparison of the
kernel itself lives in ``test_nearest``).
"""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

from gsverse_format.nearest import compiled as nf                         # noqa: E402
from gsverse_format.nearest import compiled_kernel as nk                  # noqa: E402
from gsverse_format.nearest import reference as nt                        # noqa: E402
from gsverse_format.nearest import (closest_points_on_triangles, nearest_faces,  # noqa: E402
                                    nearest_triangles)

from test_nearest import bumpy_icosphere, check_result, nasty_mesh, query_points  # noqa: E402

FIELDS = ("face", "distance", "closest", "barycentric")


def same_bits(a, b, what):
    """Equal arrays of equal dtype, float64 compared as bit patterns."""
    assert a.dtype == b.dtype and a.shape == b.shape, what
    if a.dtype == np.float64:
        a, b = a.view(np.int64), b.view(np.int64)
    np.testing.assert_array_equal(a, b, err_msg=what)


def native_levels() -> range:
    """The instruction levels of the C query loop this CPU runs (0 generic .. 2 AVX-512F)."""
    from gsverse_format.nearest import native as nn

    mod = nn._module()
    assert mod is not None, nn.native_unavailable_reason()
    return range(mod.level() + 1)


def both(points, vertices, faces, **kw):
    """Run the reference and both compiled searches (numba, C: as dispatched, and its query
    loop at every instruction level this CPU runs) and require identical results; returns the
    numba one."""
    from gsverse_format.nearest.native import nearest_faces_native, nearest_triangles_native

    ref = nearest_triangles(points, vertices, faces, method="numpy", **kw)
    fast = nearest_triangles(points, vertices, faces, method="numba", **kw)
    native = nearest_triangles(points, vertices, faces, method="native", **kw)
    for name in FIELDS:
        same_bits(getattr(fast, name), getattr(ref, name), f"numba {name}")
        same_bits(getattr(native, name), getattr(ref, name), f"native {name}")
    for level in native_levels():
        again = nearest_triangles_native(points, vertices, faces, _level=level, **kw)
        for name in FIELDS:
            same_bits(getattr(again, name), getattr(ref, name), f"native level {level} {name}")
        face, distance = nearest_faces_native(points, vertices, faces, _level=level, **kw)
        same_bits(face, ref.face, f"faces alone, level {level}")
        same_bits(distance, ref.distance, f"distances alone, level {level}")
    for method in ("numpy", "numba", "native", "auto"):
        face, distance = nearest_faces(points, vertices, faces, method=method, **kw)
        same_bits(face, ref.face, f"faces alone, {method}")
        same_bits(distance, ref.distance, f"distances alone, {method}")
    assert fast.face.dtype == np.int64 and fast.distance.dtype == np.float64
    return fast


# --------------------------------------------------------------------------- kernel

def test_face_records_equal_reference_table():
    v, f = nasty_mesh(seed=1)
    rec = np.empty((len(f), nk.RECORD_WIDTH))
    nk.face_records(v, f, np.arange(len(f)), rec)
    table = nt._face_table(v[f[:, 0]], v[f[:, 1]], v[f[:, 2]])
    columns = list(range(9)) + list(range(12, 19))       # a, ab, ac, e_v, e_w, degenerate flag
    np.testing.assert_array_equal(rec, table[columns].T)


@pytest.fixture(scope="module")
def pairwise():
    """Compiled pairwise kernel: (closest, barycentric, distance) like the reference's."""
    from numba import njit

    @njit(cache=False)
    def run(rec, p, out):
        for i in range(p.shape[0]):
            r = rec[i]
            v, w, d2 = nk.closest_point(r, p[i, 0], p[i, 1], p[i, 2])
            out[i, 0] = r[0] + v * r[3] + w * r[6]
            out[i, 1] = r[1] + v * r[4] + w * r[7]
            out[i, 2] = r[2] + v * r[5] + w * r[8]
            out[i, 3] = max(1.0 - v - w, 0.0)
            out[i, 4] = v
            out[i, 5] = w
            out[i, 6] = np.sqrt(d2)

    def kernel(p, a, b, c):
        m = len(p)
        V = np.concatenate([a, b, c])
        F = np.column_stack([np.arange(m), m + np.arange(m), 2 * m + np.arange(m)])
        rec = np.empty((m, nk.RECORD_WIDTH))
        nk.face_records(V, F, np.arange(m), rec)
        out = np.empty((m, 7))
        run(rec, np.ascontiguousarray(p, dtype=np.float64), out)
        return out[:, 0:3], out[:, 3:6], out[:, 6]

    return kernel


def test_kernel_bit_identical(pairwise):
    rng = np.random.default_rng(2)
    m = 6000
    a, b, c = (rng.normal(size=(m, 3)) for _ in range(3))
    # slivers, segments (collinear corners in every order), points, and shared corners
    k = m // 6
    c[:k] = a[:k] + rng.uniform(-0.5, 1.5, (k, 1)) * (b[:k] - a[:k]) + \
        10.0 ** rng.uniform(-9, -3, (k, 1)) * rng.normal(size=(k, 3))
    c[k:2 * k] = a[k:2 * k] + rng.uniform(-1, 2, (k, 1)) * (b[k:2 * k] - a[k:2 * k])
    a[2 * k:3 * k] = b[2 * k:3 * k] + 0.3 * (c[2 * k:3 * k] - b[2 * k:3 * k])
    b[3 * k:3 * k + 50] = c[3 * k:3 * k + 50] = a[3 * k:3 * k + 50]
    b[4 * k:4 * k + 50] = a[4 * k:4 * k + 50]
    p = 2.0 * rng.normal(size=(m, 3))
    p[5 * k:] = a[5 * k:] + rng.uniform(0, 1, (m - 5 * k, 1)) * (b[5 * k:] - a[5 * k:])  # on edges
    ref = closest_points_on_triangles(p, a, b, c)
    got = pairwise(p, a, b, c)
    for r, g in zip(ref, got):
        np.testing.assert_array_equal(g, r)


# --------------------------------------------------------------------------- hierarchy

def test_float32_outward_rounding():
    from numba import njit

    @njit(cache=False)
    def run(x, lo, hi):
        for i in range(x.shape[0]):
            lo[i] = nk.f32_down(x[i])
            hi[i] = nk.f32_up(x[i])

    rng = np.random.default_rng(28)
    x = np.concatenate([rng.normal(size=20000) * 10.0 ** rng.uniform(-45, 39, 20000),
                        [0.0, -0.0, 1e-46, -1e-46, 3.5e38, -3.5e38, 1e300, -1e300, 1.0, 2.0, 0.5]])
    small = x[:5000][np.abs(x[:5000]) < 3e38]
    x = np.concatenate([x, small.astype(np.float32).astype(np.float64)])    # exact float32s
    lo, hi = np.empty(len(x), np.float32), np.empty(len(x), np.float32)
    with np.errstate(over="ignore"):
        run(x, lo, hi)
        assert np.all(lo.astype(np.float64) <= x) and np.all(hi.astype(np.float64) >= x)
        near = np.float32(x)
        exact = near.astype(np.float64) == x
        assert np.all(lo[exact] == near[exact]) and np.all(hi[exact] == near[exact])
        finite = np.abs(x) < 3e38
        # at most two float32 steps away from the nearest float32
        step = np.spacing(np.abs(near[finite])).astype(np.float64)
        assert np.all(near[finite] - lo[finite].astype(np.float64) <= 2 * step + 1e-45)
        assert np.all(hi[finite].astype(np.float64) - near[finite] <= 2 * step + 1e-45)


@pytest.mark.parametrize("n_faces", [1, 4, 5, 9, 130, 1280])
def test_tree_bounds_contain_their_triangles(n_faces):
    """White-box check of the certificate: child boxes and leaf slabs hold their corners."""
    v, f = bumpy_icosphere(3, seed=26)
    f = f[np.random.default_rng(27).permutation(len(f))[:n_faces]]
    idx = np.arange(len(f))
    tree = nf.build_tree(v, f, idx)
    np.testing.assert_array_equal(np.sort(tree.face), idx)
    corners = v[f[tree.face]]                                   # (F, 3, 3) in tree order
    lo, hi = corners.min(axis=1), corners.max(axis=1)
    L = nf._LEAF
    for j in range(len(tree.slab)):
        c = corners[j * L:(j + 1) * L].reshape(-1, 3)
        n, h = tree.slab[j, :3], c @ tree.slab[j, :3]
        assert np.all(h >= tree.slab[j, 3] - 1e-12) and np.all(h <= tree.slab[j, 4] + 1e-12)
        assert abs(np.linalg.norm(n) - 1) < 1e-12
    assert tree.scale == np.abs(v[f]).max()

    def span(ref):                                              # face positions below a node
        if ref < 0:
            j = -ref - 1
            return j * L, min(j * L + L, len(f))
        return span(tree.child[ref, 0])[0], span(tree.child[ref, 1])[1]

    seen = []
    stack = [tree.root]
    while stack:
        ref = stack.pop()
        if ref < 0:
            seen.append(span(ref))
            continue
        for side in range(2):
            a, b = span(tree.child[ref, side])
            box = tree.cbox[ref, 6 * side:6 * side + 6]
            assert np.all(box[:3] <= lo[a:b].min(axis=0)) and np.all(box[3:] >= hi[a:b].max(axis=0))
            stack.append(tree.child[ref, side])
    assert sorted(seen) == [(j * L, min(j * L + L, len(f))) for j in range(len(tree.slab))]


# --------------------------------------------------------------------------- search

def test_icosphere_equals_reference():
    v, f = bumpy_icosphere(3, seed=4)
    p = query_points(v, f, 160, seed=5)
    check_result(both(p, v, f), p, v, f, reference=False)


@pytest.mark.parametrize("seed", [6, 30])
def test_nasty_mesh_equals_reference(seed):
    """Slivers, huge, zero-area and duplicated faces; near, far and on-surface points."""
    v, f = nasty_mesh(seed=seed)
    p = query_points(v, f, 240, seed=seed + 1)
    res = both(p, v, f)
    check_result(res, p, v, f, reference=False)
    import numba

    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        again = nearest_triangles(p, v, f, method="numba", chunk=37)      # one thread, chunks
    finally:
        numba.set_num_threads(threads)
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(again, name), getattr(res, name))
    for n in ("1", "7"):                                   # the C search: 1 and 7 threads
        with pytest.MonkeyPatch.context() as mp:
            mp.setenv("GSVERSE_THREADS", n)
            again = nearest_triangles(p, v, f, method="native", chunk=37)
        for name in FIELDS:
            same_bits(getattr(again, name), getattr(res, name), f"{n} threads {name}")


def test_float32_points_are_read_as_their_float64_values():
    """The C search reads float32 points without a float64 copy: the results are those of the
    same points converted first, at every method and level."""
    from gsverse_format.nearest import _native
    from gsverse_format.nearest.native import nearest_faces_native

    v, f = nasty_mesh(seed=11)
    p32 = query_points(v, f, 300, seed=12).astype(np.float32)
    ref = nearest_triangles(p32.astype(np.float64), v, f, method="numpy")
    for level in native_levels():
        face, distance = nearest_faces_native(p32, v, f, _level=level)
        same_bits(face, ref.face, f"float32 faces, level {level}")
        same_bits(distance, ref.distance, f"float32 distances, level {level}")
    res = nearest_triangles(p32, v, f, method="native")
    for name in FIELDS:
        same_bits(getattr(res, name), getattr(ref, name), f"float32 {name}")
    order, sorted_points = np.empty(2, np.int64), np.empty((2, 3))
    for bad in (np.zeros((2, 3), np.float16), np.zeros((2, 3), np.int64)):
        with pytest.raises(TypeError, match="float64 or float32"):
            _native.sort_queries(bad, order, sorted_points)
    with pytest.raises(ValueError, match="size"):
        _native.sort_queries(np.zeros(5, np.float32), order, sorted_points)


def test_offset_and_scaled_mesh():
    """Tiny triangles far from the origin: the float32 boxes are coarser than the faces."""
    v, f = bumpy_icosphere(2, seed=8)
    v = v * 1e-3 + np.array([1e5, -2e4, 5e3])
    p = query_points(v, f, 300, seed=9)
    check_result(both(p, v, f), p, v, f, reference=False)


def test_ties_and_duplicates():
    up = [[-1.0, -1.0, 1.0], [1.0, -1.0, 1.0], [0.0, 1.0, 1.0]]
    down = [[-1.0, -1.0, -1.0], [1.0, -1.0, -1.0], [0.0, 1.0, -1.0]]
    v = np.array(up + down + [[50.0, 50, 50], [51.0, 50, 50], [50.0, 51, 50]])
    origin = np.zeros((1, 3))
    for faces, expect in [([[0, 1, 2], [3, 4, 5]], 0), ([[3, 4, 5], [0, 1, 2]], 0),
                          ([[6, 7, 8], [3, 4, 5], [0, 1, 2]], 1)]:
        res = both(origin, v, np.array(faces))
        assert res.face[0] == expect and res.distance[0] == 1.0
    v, f = bumpy_icosphere(2, seed=10)
    rng = np.random.default_rng(11)
    f = np.concatenate([f, f, f])[rng.permutation(3 * len(f))]
    p = np.concatenate([query_points(v, f, 120, seed=12), v, 0.5 * (v[f[:200, 0]] + v[f[:200, 1]])])
    res = both(p, v, f)
    check_result(res, p, v, f, reference=False)
    first = {tuple(t): i for i, t in reversed(list(enumerate(map(tuple, f))))}
    assert all(first[tuple(f[i])] == i for i in res.face)


def test_exclude():
    v, f = nasty_mesh(seed=13)
    p = query_points(v, f, 200, seed=14)
    first = nearest_triangles(p, v, f, method="numba")
    exclude = np.zeros(len(f), bool)
    exclude[first.face[::2]] = True
    exclude[np.random.default_rng(15).choice(len(f), len(f) // 3, replace=False)] = True
    check_result(both(p, v, f, exclude=exclude), p, v, f, exclude, reference=False)
    only = np.ones(len(f), bool)
    only[17] = False
    res = both(p, v, f, exclude=only)
    assert np.all(res.face == 17)
    with pytest.raises(ValueError):
        nearest_triangles(p, v, f, exclude=np.ones(len(f), bool), method="numba")


@pytest.mark.parametrize("faces", [[[0, 1, 2]],
                                   [[0, 1, 3], [1, 1, 1], [4, 3, 0], [2, 2, 4]],
                                   [[0, 1, 2], [1, 3, 2], [0, 3, 4], [2, 4, 1], [4, 4, 4]]])
def test_tiny_and_degenerate_meshes(faces):
    """A single leaf as the root, zero-area faces only, and a two-leaf tree."""
    rng = np.random.default_rng(20)
    p = rng.normal(scale=4, size=(300, 3))
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [3, 0, 0]])
    f = np.array(faces)
    check_result(both(p, v, f), p, v, f)


def test_far_points_and_large_meshes_of_many_leaves():
    v, f = bumpy_icosphere(4, seed=21, bump=0.3)
    rng = np.random.default_rng(22)
    p = np.concatenate([rng.normal(scale=1e3, size=(50, 3)), 0.01 * rng.normal(size=(50, 3)),
                        query_points(v, f, 400, seed=23)])
    both(p, v, f)


def test_empty_points_progress_and_validation():
    v, f = bumpy_icosphere(1, seed=18)
    calls = []
    p = np.random.default_rng(19).normal(size=(10, 3))
    for method in ("numba", "native"):
        calls.clear()
        res = nearest_triangles(np.zeros((0, 3)), v, f, method=method,
                                progress=lambda d, t: calls.append((d, t)))
        assert calls == [(0, 0)] and res.face.shape == (0,) and res.closest.shape == (0, 3)
        calls.clear()
        nearest_triangles(p, v, f, chunk=4, method=method,
                          progress=lambda d, t: calls.append((d, t)))
        assert calls == [(4, 10), (8, 10), (10, 10)]
        for bad in (dict(faces=np.zeros((0, 3), np.int64)), dict(points=p[:, :2]),
                    dict(faces=f + len(v)), dict(points=np.full((1, 3), np.nan))):
            args = dict(points=p, vertices=v, faces=f) | bad
            with pytest.raises(ValueError):
                nearest_triangles(**args, method=method)
    with pytest.raises(ValueError, match="'native'"):
        nearest_triangles(p, v, f, method="fortran")


def test_dispatch(monkeypatch):
    from gsverse_format.nearest import native as nn

    v, f = bumpy_icosphere(1, seed=24)
    p = np.random.default_rng(25).normal(size=(20, 3))
    used = []
    real, real_native = nf.build_tree, nn.nearest_triangles_native
    monkeypatch.setattr(nf, "build_tree", lambda *a: used.append("numba") or real(*a))
    monkeypatch.setattr("gsverse_format.nearest.dispatch.nearest_triangles_native",
                        lambda *a, **k: used.append("native") or real_native(*a, **k))
    nearest_triangles(p, v, f)
    assert used == ["native"]                            # auto: the C search, at any size
    monkeypatch.setattr("gsverse_format.nearest.dispatch.native_available", lambda: False)
    nearest_triangles(p, v, f)
    assert used == ["native"]                  # without it, a small job: the reference
    monkeypatch.setattr("gsverse_format.nearest.dispatch.NEAREST_NUMPY_BELOW", 0)
    nearest_triangles(p, v, f)
    assert used == ["native", "numba"]                   # auto: numba when it imports
    monkeypatch.undo()
    used.clear()
    monkeypatch.setattr(nf, "build_tree", lambda *a: used.append("numba") or real(*a))
    monkeypatch.setattr("gsverse_format.nearest.dispatch.NEAREST_NUMPY_BELOW", 0)
    monkeypatch.setenv("GSVERSE_BACKEND", "numpy")
    nearest_triangles(p, v, f)
    assert used == []                                    # the environment forces the reference
    nearest_triangles(p, v, f, method="numba")
    assert used == ["numba"]                             # an explicit method wins
    monkeypatch.setenv("GSVERSE_BACKEND", "numba")
    nearest_triangles(p, v, f)
    assert used == ["numba", "numba"]                    # the environment asks for numba
    monkeypatch.setenv("GSVERSE_BACKEND", "auto")
    nearest_triangles(p, v, f)
    assert used == ["numba", "numba"]                    # auto again: the C search


def test_the_c_search_is_built_and_refused_when_absent(monkeypatch):
    """The package's set-up builds the C search (the suite runs where a C compiler is, as the
    native kernels' tests need one too); without it, asking for it names the reason."""
    from gsverse_format.backend import BackendUnavailableError
    from gsverse_format.nearest import native as nn

    assert nn.native_unavailable_reason() is None, nn.native_unavailable_reason()
    monkeypatch.setattr(nn, "_module", lambda: None)
    monkeypatch.setattr("gsverse_format.nearest.dispatch.native_available", nn.native_available)
    monkeypatch.setattr("gsverse_format.nearest.dispatch.native_unavailable_reason",
                        nn.native_unavailable_reason)
    v, f = bumpy_icosphere(1, seed=24)
    with pytest.raises(BackendUnavailableError, match="C compiler"):
        nearest_triangles(np.zeros((1, 3)), v, f, method="native")
    with pytest.raises(ImportError, match="C compiler"):
        nn.nearest_triangles_native(np.zeros((1, 3)), v, f)


def test_native_query_refuses_a_level_this_cpu_lacks():
    from gsverse_format.nearest.native import nearest_triangles_native

    v, f = bumpy_icosphere(1, seed=2)
    top = native_levels()[-1]
    assert top >= 0
    for bad in (-1, top + 1):
        with pytest.raises(ValueError, match="instruction level"):
            nearest_triangles_native(v[:5] + 0.01, v, f, _level=bad)


def test_native_threads(monkeypatch):
    from gsverse_format import threads as nn

    monkeypatch.delenv("GSVERSE_THREADS", raising=False)
    assert nn.native_threads() >= 1
    monkeypatch.setenv("GSVERSE_THREADS", " 3 ")
    assert nn.native_threads() == 3
    for bad in ("0", "-2", "many"):
        monkeypatch.setenv("GSVERSE_THREADS", bad)
        with pytest.raises(ValueError, match="GSVERSE_THREADS"):
            nn.native_threads()


def test_the_c_extension_refuses_calls_that_would_leave_its_arrays():
    """The extension's own checks (its one caller checks first): indices out of range, wrong
    dtypes and sizes raise instead of reading or writing outside the buffers."""
    from gsverse_format.nearest import _native

    v = np.eye(3)
    f = np.array([[0, 1, 2]], np.int64)
    with pytest.raises(ValueError, match="range"):
        _native.build(v, np.array([[0, 1, 3]], np.int64), np.array([0], np.int64), 1e-8, 1)
    with pytest.raises(ValueError, match="range"):
        _native.build(v, f, np.array([1], np.int64), 1e-8, 1)
    with pytest.raises(TypeError, match="float64"):
        _native.build(v.astype(np.float32), f, np.array([0], np.int64), 1e-8, 1)
    tree = _native.build(v, f, np.array([0], np.int64), 1e-8, 1)
    p = np.zeros((2, 3))
    out = (np.empty(2, np.int64), np.empty(2), np.empty((2, 3)), np.empty((2, 3)))
    with pytest.raises(ValueError, match="order"):
        _native.query(tree, p, np.array([0, 2], np.int64), 0, 2, 1e-11, 1, *out, 0)
    with pytest.raises(ValueError, match="range"):
        _native.query(tree, p, np.array([0, 1], np.int64), 0, 3, 1e-11, 1, *out, 0)
    with pytest.raises(ValueError, match="size"):
        _native.query(tree, p, np.array([0, 1], np.int64), 0, 2, 1e-11, 1,
                      out[0], out[1], out[2], np.empty((1, 3)), 0)
    with pytest.raises(ValueError, match="level"):
        _native.query(tree, p, np.array([0, 1], np.int64), 0, 2, 1e-11, 1, *out,
                      _native.level() + 1)
    with pytest.raises(TypeError):                 # the closest points: both or neither
        _native.query(tree, p, np.array([0, 1], np.int64), 0, 2, 1e-11, 1, out[0], out[1],
                      None, out[3], 0)
    face, distance = np.full(2, -1, np.int64), np.empty(2)
    _native.query(tree, p, np.array([1, 0], np.int64), 0, 2, 1e-11, 1, face, distance, None,
                  None, 0)
    assert list(face) == [0, 0] and np.allclose(distance, 1 / np.sqrt(3))
    for level in native_levels():
        out[0][:] = -1
        _native.query(tree, p, np.array([1, 0], np.int64), 0, 2, 1e-11, 1, *out, level)
        assert list(out[0]) == [0, 0] and np.allclose(out[1], 1 / np.sqrt(3))