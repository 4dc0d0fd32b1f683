"""The fast remap agrees with the float64 reference within the stated float32 bounds.

Bounds (``gsverse_format.remapping.bounds.float32_error_bounds``, u = 2⁻²⁴):
mean ``16 u (|v0| + |b1||e1| + |b2||e2| + |d| k) + |d| ν`` with
``ν = min(8 u P / √(a_c a_r), 6 √(u P / a_r))`` (P = |e1||e2|) on faces regular at rest;
``local`` covariance ``64 u ‖A‖_F² Σ s_l²`` (A = [E_c C_r⁻¹ | m], k R_c, or R_c on faces
degenerate at rest); ``games`` covariance ``64 u Σ scale²`` (Frobenius norms, per splat).
"""
from __future__ import annotations

import numpy as np
import pytest

from gsverse_format.remapping import fast as rf
from gsverse_format.backend import numba_available
from gsverse_format.binding import bind_local
from gsverse_format.model import Anchoring, GamesAnchors, LocalAnchors, TriangleMesh
from gsverse_format.remapping.reference import prepare_rest, remap
from gsverse_format.remapping.bounds import float32_error_bounds

from helpers import bumpy_sphere, random_rotation, surface_splats

needs_numba = pytest.mark.skipif(not numba_available(), reason="numba not installed")


@pytest.fixture(scope="module")
def mesh():
    return bumpy_sphere(2, seed=5)


@pytest.fixture(scope="module")
def anchorings(mesh):
    splats = surface_splats(mesh, 4000, seed=6, offset=0.05)
    out = {}
    for law in ("affine", "rigid"):
        anchors = bind_local(splats, mesh, deformation=law).anchors
        order = np.argsort(anchors.face_index, kind="stable")      # sorted by face, as files are
        out[law] = Anchoring(mesh, anchors.subset(order))
    rng = np.random.default_rng(7)
    alpha = rng.dirichlet([1, 1, 1], 3000)
    out["games"] = Anchoring(mesh, GamesAnchors(rng.integers(0, mesh.face_count, 3000),
                                                alpha[:, 1:], rng.uniform(0.2, 3.0, 3000)))
    return out


def _deformations(mesh: TriangleMesh):
    """Named current-vertex arrays: smooth, stretched, compressed, offset, degenerate, inverted."""
    v = mesh.vertices.astype(np.float64)
    rng = np.random.default_rng(11)
    out = {
        "rest": v,
        "noisy_affine": v @ (random_rotation(3) * [1.7, 0.6, 1.1]).T + rng.normal(0, 0.03, v.shape),
        "stretch_10x": v * [10.0, 1.0, 1.0],
        "compress_0.1x": v * [1.0, 0.1, 1.0],
        "offset_1e5": v + 1e5,
        "twist": _twist(v, 2.0),
    }
    collapse = v.copy()
    collapse[: len(v) // 3] = 0.0                 # many faces become segments or points
    out["collapse"] = collapse
    inverted = v.copy()
    inverted[:, 2] *= -1.0                       # every triangle folds over
    out["inverted"] = inverted
    return out


def _twist(v: np.ndarray, turns: float) -> np.ndarray:
    ang = turns * np.pi * (v[:, 1] - v[:, 1].min()) / np.ptp(v[:, 1])
    c, s = np.cos(ang), np.sin(ang)
    return np.stack([c * v[:, 0] - s * v[:, 2], v[:, 1], s * v[:, 0] + c * v[:, 2]], axis=1)


def _check_against_reference(anchoring, vertices, out):
    ref = remap(anchoring, vertices)
    mean_bound, cov_bound = float32_error_bounds(anchoring, vertices)
    mean_err = np.linalg.norm(out.means.astype(np.float64) - ref.means, axis=1)
    cov_err = np.linalg.norm(out.covariances() - ref.covariances, axis=(1, 2))
    assert np.all(np.isfinite(out.means)) and np.all(np.isfinite(out.cov6))
    assert np.all(mean_err <= mean_bound), float(np.max(mean_err / mean_bound))
    assert np.all(cov_err <= cov_bound), float(np.max(cov_err / cov_bound))
    return ref


@needs_numba
@pytest.mark.parametrize("kind", ["affine", "rigid", "games"])
def test_fast_matches_reference_on_deformed_meshes(mesh, anchorings, kind):
    anchoring = anchorings[kind]
    fast = rf.FastRemapper(anchoring, rotations=True, backend="numba")
    plain = rf.FastRemapper(anchoring, backend="numba")
    for name, vertices in _deformations(mesh).items():
        out = fast.remap(vertices)
        ref = _check_against_reference(anchoring, vertices, out)
        # Asking for rotations does not change means and covariances.
        single = plain.remap(vertices)
        assert np.array_equal(single.means, out.means) and np.array_equal(single.cov6, out.cov6)
        if name in ("stretch_10x", "compress_0.1x", "noisy_affine", "rest"):
            rel = np.linalg.norm(out.covariances() - ref.covariances, axis=(1, 2)) / \
                np.linalg.norm(ref.covariances, axis=(1, 2))
            assert np.max(rel) <= 1e-5, (name, float(np.max(rel)))
        if kind != "affine":
            qd = np.minimum(np.linalg.norm(out.rotations - ref.rotations, axis=1),
                            np.linalg.norm(out.rotations + ref.rotations, axis=1))
            assert np.max(qd) <= 1e-6, (name, float(np.max(qd)))
            assert np.allclose(np.linalg.norm(out.rotations, axis=1), 1.0, atol=1e-6)
            assert np.all(out.rotations[:, 3] >= 0.0)
            assert np.allclose(out.scales, ref.scales, rtol=1e-6, atol=1e-30), name


@needs_numba
def test_degenerate_rest_faces_and_quantized_anchors():
    # Face 1 is degenerate at rest (collinear corners): the spec's rule k = 1, m = n_c, A = R_c.
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [3, 0, 0]], np.float32)
    mesh = TriangleMesh(v, np.array([[0, 1, 2], [1, 3, 4]]))
    rng = np.random.default_rng(3)
    n = 200
    q = rng.normal(size=(n, 4))
    q = np.round(q / np.linalg.norm(q, axis=1, keepdims=True) * 32767) / 32767  # SHORT normalized
    bary = np.round(rng.uniform(0, 1, (n, 2)) * 65535) / 65535                 # USHORT normalized
    anchors = LocalAnchors(rng.integers(0, 2, n), bary, rng.normal(0, 0.1, n), q,
                           rng.uniform(0.01, 0.2, (n, 3)))
    for law in ("affine", "rigid"):
        anchors.deformation = law
        anchoring = Anchoring(mesh, anchors)
        fast = rf.FastRemapper(anchoring, rotations=True, backend="numba")
        cur = v * [3.0, 0.5, 1.0] + [0.0, 0.0, 0.25]
        _check_against_reference(anchoring, cur, fast.remap(cur))
        _check_against_reference(anchoring, None, fast.remap())


@needs_numba
def test_rest_sliver_just_above_threshold_opened_to_a_regular_triangle():
    """A rest sliver with a_r = 1.1e-6 ℓ² (just regular) opened to a regular triangle (area
    ×1e5, k ≈ 316): the normal term d·m stays within 1e-4 |d| of the reference because the
    rest quantities (C_r⁻¹, √a_r) are computed once in float64 from the stored float32 rest
    vertices. Computed in float32, a_r would carry a relative error of order u ℓ²/a_r (several
    per cent here), and the mean would be off by a sizeable fraction of k |d|."""
    q, _ = np.linalg.qr(np.random.default_rng(21).normal(size=(3, 3)))
    h = 1.1e-6                                   # ℓ = |e1| = 1, a = h
    flat = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.4, h, 0.0]])
    opened = flat.copy()
    opened[2, 1] = h * 1e5
    rest_v = (flat @ q.T + 0.5).astype(np.float32)
    cur_v = (opened @ q.T + 0.5).astype(np.float32)
    mesh = TriangleMesh(rest_v, np.array([[0, 1, 2]]))
    rest = prepare_rest(mesh.triangles())
    tri = mesh.triangles().astype(np.float64)
    ell2 = max(float(np.sum((tri[0, i] - tri[0, j]) ** 2)) for i, j in ((1, 0), (2, 0), (2, 1)))
    assert rest.regular[0] and 1e-6 < rest.area2[0] / ell2 < 1.2e-6       # just above threshold
    a_c = np.linalg.norm(np.cross(*(cur_v[1:].astype(np.float64) - cur_v[0])))
    assert 0.9e5 < a_c / rest.area2[0] < 1.1e5

    rng = np.random.default_rng(22)
    n = 400
    d = rng.choice([-1.0, 1.0], n) * rng.uniform(0.5, 2.0, n)
    for law in ("affine", "rigid"):
        anchors = LocalAnchors(np.zeros(n, np.int64), rng.uniform(0, 1, (n, 2)), d,
                               rng.normal(size=(n, 4)), rng.uniform(1e-3, 1e-2, (n, 3)), law)
        anchoring = Anchoring(mesh, anchors)
        fast = rf.FastRemapper(anchoring, backend="numba")
        # The rest table is float64 and holds exactly the float64 reference's rest quantities.
        table = fast._rest_table
        assert table.dtype == np.float64
        assert table[0, 3] == np.sqrt(rest.area2[0]) and table[0, 4] == 1.0
        assert (table[0, 0], table[0, 1], table[0, 2]) == (
            rest.inverse_shape[0, 0, 0], rest.inverse_shape[0, 0, 1], rest.inverse_shape[0, 1, 1])
        out = fast.remap(cur_v)
        ref = _check_against_reference(anchoring, cur_v, out)
        err = np.linalg.norm(out.means.astype(np.float64) - ref.means, axis=1)
        assert np.max(err / np.abs(d)) < 1e-4, (law, float(np.max(err / np.abs(d))))

    # For contrast: the same rest area computed in float32 arithmetic.
    e1 = rest_v[1] - rest_v[0]
    e2 = rest_v[2] - rest_v[0]
    cross32 = np.array([e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                        e1[0] * e2[1] - e1[1] * e2[0]], np.float32)
    area32 = float(np.sqrt(np.sum(cross32 * cross32, dtype=np.float32)))
    k = np.sqrt(a_c / rest.area2[0])
    # |Δm| = k |1 − √(a_r / a_r32)|: far beyond 1e-4 per unit |d|
    assert k * abs(1.0 - np.sqrt(rest.area2[0] / area32)) > 1e-2


@needs_numba
def test_face_order_thread_count_and_dtype_do_not_change_results(mesh, anchorings):
    import numba

    anchoring = anchorings["affine"]
    vertices = _deformations(mesh)["noisy_affine"]
    fast = rf.FastRemapper(anchoring, backend="numba")
    first = fast.remap(vertices).copy()
    again = fast.remap(vertices)
    assert again is fast.remap(vertices)                      # the buffers are reused
    assert np.array_equal(first.means, again.means) and np.array_equal(first.cov6, again.cov6)
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        single = fast.remap(vertices).copy()
    finally:
        numba.set_num_threads(threads)
    assert np.array_equal(first.means, single.means) and np.array_equal(first.cov6, single.cov6)
    # Any splat order gives the same per-splat results.
    perm = np.random.default_rng(0).permutation(len(anchoring.anchors))
    unsorted = rf.FastRemapper(Anchoring(anchoring.mesh, anchoring.anchors.subset(perm)),
                               backend="numba")
    shuffled = unsorted.remap(vertices)
    assert np.array_equal(shuffled.means, first.means[perm])
    assert np.array_equal(shuffled.cov6, first.cov6[perm])
    # float32 vertices: the bound still holds (the reference sees the same float32 input).
    v32 = vertices.astype(np.float32)
    _check_against_reference(anchoring, v32, fast.remap(v32))
    # A caller-provided output set.
    mine = fast.allocate()
    assert fast.remap(vertices, out=mine) is mine
    assert np.array_equal(mine.cov6, first.cov6)


def test_numpy_backend_matches_reference(mesh, anchorings, monkeypatch):
    vertices = _deformations(mesh)["noisy_affine"]
    for kind in ("affine", "rigid", "games"):
        anchoring = anchorings[kind]
        out = rf.FastRemapper(anchoring, rotations=True, backend="numpy").remap(vertices)
        ref = remap(anchoring, vertices)
        assert np.array_equal(out.means, ref.means.astype(np.float32))
        assert np.allclose(out.covariances(), ref.covariances, rtol=1e-6, atol=1e-12)
    monkeypatch.setenv("GSVERSE_BACKEND", "numpy")
    assert rf.FastRemapper(anchorings["games"]).backend == "numpy"
    out = rf.remap_auto(anchorings["games"], vertices)
    assert out.means.dtype == np.float32 and out.cov6.shape == (len(anchorings["games"].anchors), 6)


def test_auto_selects_numba_when_importable(anchorings):
    expected = "numba" if numba_available() else "numpy"
    assert rf.FastRemapper(anchorings["rigid"]).backend == expected


def test_bad_input_is_rejected(anchorings):
    fast = rf.FastRemapper(anchorings["affine"], backend="numpy")
    with pytest.raises(ValueError, match="vertices of shape"):
        fast.remap(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="backend"):
        rf.FastRemapper(anchorings["affine"], backend="cuda")


def test_cov6_round_trip():
    m = np.random.default_rng(0).normal(size=(5, 3, 3))
    m = m @ np.swapaxes(m, 1, 2)
    assert np.allclose(rf.cov6_to_matrix(rf.matrix_to_cov6(m)), m)
    assert rf.COV6_ORDER == ("xx", "xy", "xz", "yy", "yz", "zz")


@needs_numba
@pytest.mark.parametrize("kind", ["affine", "rigid", "games"])
def test_one_pass_over_runs_equals_two_passes(mesh, anchorings, kind):
    """Splats grouped by face take the one-pass kernels (runs of a face, chunks handed out
    dynamically); shuffled splats the two passes. Same bits for every splat, whatever the
    chunk size (runs split across chunks) and the thread count."""
    import numba

    from gsverse_format.remapping import compiled_runs as runs

    base = anchorings[kind]
    order = np.argsort(base.anchors.face_index, kind="stable")
    anchoring = Anchoring(mesh, base.anchors.subset(order))
    rot = kind != "affine"
    vertices = _deformations(mesh)["twist"]
    one = rf.FastRemapper(anchoring, rotations=rot, backend="numba")
    assert one.one_pass
    first = one.remap(vertices).copy()
    _check_against_reference(anchoring, vertices, first)
    perm = np.random.default_rng(3).permutation(len(anchoring.anchors))
    two = rf.FastRemapper(Anchoring(mesh, anchoring.anchors.subset(perm)), rotations=rot,
                          backend="numba")
    assert not two.one_pass                        # shuffled: more runs than faces
    shuffled = two.remap(vertices)
    fields = ["means", "cov6"] + (["rotations", "scales"] if rot else [])
    for name in fields:
        assert np.array_equal(getattr(shuffled, name), getattr(first, name)[perm]), name
    # small chunks: runs cut at chunk boundaries, faces computed once per piece
    plan = runs.plan_runs(one._face, mesh.face_count, chunk=64)
    assert plan is not None and plan.runs > one._plan.runs and plan.size == 64
    one._plan = plan
    one._table = np.zeros((plan.runs, one._table.shape[1]), np.float32)
    one._qface = np.zeros((plan.runs if one._qface.shape[0] else 0, 4), np.float32)
    threads = numba.get_num_threads()
    try:
        for th in sorted({1, threads}):
            numba.set_num_threads(th)
            again = one.remap(vertices)
            for name in fields:
                assert np.array_equal(getattr(again, name), getattr(first, name)), (th, name)
    finally:
        numba.set_num_threads(threads)


@needs_numba
@pytest.mark.parametrize("law", ["affine", "rigid", "games"])
def test_vectorised_loops_give_the_bits_of_the_scalar_rows(mesh, anchorings, law):
    """The one-pass kernels without rotations and scales run vectorised loops: the affine law's
    faces FACE_BLOCK at a time (compiled_runs._affine_block), and the splats of every run of
    at least SHORT_RUN splats, or of PAD_FROM splats padded into the following runs
    (compiled_runs._local_run_splats, _games_run_splats, _padded_count); the two passes use
    the scalar rows. Same bits on every deformation (collapsed faces: a_c = 0; inverted; far
    from the origin; float32 and float64 vertices), on faces degenerate at rest (recomputed
    by the scalar row), on runs of every length (about 12 splats a face here: runs padded
    over the next ones, runs too short to pad) and on blocks, runs and padding cut short by a
    run plan's small chunks (of FACE_BLOCK + 7 splats: no run is padded past a chunk's end,
    where another thread may be writing)."""
    from gsverse_format.remapping import compiled_runs as runs

    rng = np.random.default_rng(21)
    # A mesh with faces degenerate at rest among regular ones: every fifth face collinear.
    v = mesh.vertices.astype(np.float64)
    faces = mesh.faces.copy()
    faces[::5, 2] = faces[::5, 1]                 # two equal corners: zero rest area
    deg_mesh = TriangleMesh(v.astype(np.float32), faces)
    base = anchorings[law].anchors
    base = base.subset(np.argsort(base.face_index, kind="stable"))
    # Runs too short to pad: every seventh face keeps only its first one, two or three splats.
    face = base.face_index
    rank = np.arange(len(face)) - np.searchsorted(face, face)       # place in the face's run
    base = base.subset(np.flatnonzero((face % 7 != 0) | (rank < face % 3 + 1)))
    lengths = np.bincount(base.face_index)
    assert lengths.max() >= 2 * runs.SHORT_RUN and lengths[lengths > 0].min() < runs.PAD_FROM
    assert np.any((lengths >= runs.PAD_FROM) & (lengths % runs.SHORT_RUN != 0))
    for m in (mesh, deg_mesh):
        anchors = base.subset(np.argsort(base.face_index, kind="stable"))
        sorted_ = Anchoring(m, anchors)
        one = rf.FastRemapper(sorted_, backend="numba")
        assert one.one_pass and not one.rotations
        assert one.profile == "games" if law == "games" else one.law == law
        perm = rng.permutation(len(anchors))
        two = rf.FastRemapper(Anchoring(m, anchors.subset(perm)), backend="numba")
        assert not two.one_pass
        small = rf.FastRemapper(sorted_, backend="numba")
        small._plan = runs.plan_runs(small._face, m.face_count, chunk=runs.FACE_BLOCK + 7)
        small._table = np.zeros((small._plan.runs, small._table.shape[1]), np.float32)
        for name, cur in _deformations(m).items():
            for dtype in (np.float64, np.float32):
                cur_t = np.ascontiguousarray(cur, dtype=dtype)
                first = one.remap(cur_t).copy()
                shuffled = two.remap(cur_t)
                again = small.remap(cur_t)
                for field in ("means", "cov6"):
                    got = getattr(first, field)
                    assert np.array_equal(getattr(shuffled, field), got[perm], equal_nan=True), (
                        name, dtype, field)
                    assert np.array_equal(getattr(again, field), got, equal_nan=True), (
                        name, dtype, field)
        _check_against_reference(sorted_, None, one.remap())


def test_padded_count():
    """Runs of PAD_FROM splats on are rounded up to whole vectors of SHORT_RUN splats, never
    past the end of their chunk; shorter runs are left as they are."""
    from gsverse_format.remapping import compiled_runs as runs

    w = runs.SHORT_RUN
    assert runs.PAD_FROM <= w
    assert runs._padded_count(np.uint32(0), runs.PAD_FROM - 1, 4096) == runs.PAD_FROM - 1
    assert runs._padded_count(np.uint32(0), runs.PAD_FROM, 4096) == w
    assert runs._padded_count(np.uint32(40), w + 1, 4096) == 2 * w
    assert runs._padded_count(np.uint32(40), 2 * w, 4096) == 2 * w
    assert runs._padded_count(np.uint32(4090), 5, 4096) == 6         # cut at the chunk's end
    assert runs._padded_count(np.uint32(2**32 - 9), 5, 2**32 - 1) == 8


def test_run_plan():
    from gsverse_format.remapping.compiled_runs import plan_runs

    face = np.array([0, 0, 0, 2, 2, 5, 5, 5, 5, 5], np.int32)
    plan = plan_runs(face, 6, chunk=4)
    # runs start at every face change and at every multiple of the chunk size
    assert plan.face.tolist() == [0, 2, 2, 5, 5]
    assert plan.run_of.tolist() == [0, 0, 0, 1, 2, 3, 3, 3, 4, 4]
    assert plan.chunk.tolist() == [0, 2, 4, 5] and plan.size == 4
    assert plan.start.dtype == np.uint32 and plan.start.tolist() == [0, 3, 4, 5, 8, 10]
    assert plan_runs(np.array([0, 1, 0, 1, 0, 1], np.int32), 2, chunk=4) is None
    empty = plan_runs(np.zeros(0, np.int32), 3)
    assert empty.runs == 0 and empty.chunk.tolist() == [0]
