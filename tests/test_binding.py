"""Binding picks the true nearest non-degenerate triangle and reproduces the splats at rest."""
from __future__ import annotations

import numpy as np
import pytest

from gsverse_format.binding import bind_local
from gsverse_format.errors import BindingError
from gsverse_format.frames import degenerate_mask, local_frames, regular_mask
from gsverse_format.model import Anchoring, TriangleMesh
from gsverse_format.nearest import closest_points_on_triangles
from gsverse_format.remapping.reference import remap

from helpers import bumpy_sphere, max_rel_cov_error, random_splats


def _brute_force(points, mesh, allowed):
    tri = mesh.triangles()[allowed]
    ids = np.flatnonzero(allowed)
    n, f = len(points), len(tri)
    p = np.repeat(points, f, axis=0)
    _, _, dist = closest_points_on_triangles(p, np.tile(tri[:, 0], (n, 1)), np.tile(tri[:, 1], (n, 1)),
                                             np.tile(tri[:, 2], (n, 1)))
    dist = dist.reshape(n, f)
    return ids[np.argmin(dist, axis=1)], dist.min(axis=1)


def test_binding_matches_brute_force_and_skips_degenerate_faces():
    base = bumpy_sphere(1, seed=3)
    v = base.vertices.astype(np.float64)
    # Add degenerate faces right where splats are: collinear and collapsed triangles.
    extra_v = np.array([[0, 0, 1.5], [0.1, 0, 1.5], [0.2, 0, 1.5], [0, 0, -1.5]])
    verts = np.vstack([v, extra_v])
    k = len(v)
    faces = np.vstack([base.faces, [[k, k + 1, k + 2], [k + 3, k + 3, k + 3]]])
    mesh = TriangleMesh(verts, faces)
    splats = random_splats(300, seed=5, spread=1.6)
    splats.means[:5] = [0.05, 0, 1.5]  # right on the degenerate segment
    bound = bind_local(splats, mesh)
    allowed = ~degenerate_mask(mesh.triangles())
    assert not allowed[-1] and not allowed[-2]
    face, dist = _brute_force(splats.means.astype(np.float64), mesh, allowed)
    assert np.array_equal(bound.distance, dist)
    assert np.array_equal(bound.anchors.face_index.astype(np.int64), face)
    assert bound.degenerate_faces == 2
    r = remap(Anchoring(mesh, bound.anchors))
    assert np.max(np.abs(r.means - splats.means)) < 1e-5
    assert max_rel_cov_error(r.covariances, splats.covariances()) < 2e-6


def test_binding_refuses_meshes_without_usable_triangles():
    mesh = TriangleMesh([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]])
    with pytest.raises(BindingError, match="degenerate"):
        bind_local(random_splats(3, seed=1), mesh)


def test_binding_far_splats_and_edge_feet():
    # A single triangle and splats beyond its edges: the foot point lies outside the triangle,
    # yet remap at rest reproduces the splat exactly (barycentrics outside the simplex).
    mesh = TriangleMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    splats = random_splats(50, seed=8, spread=3.0)
    bound = bind_local(splats, mesh)
    b = bound.anchors.barycentrics
    assert np.any(b < 0) or np.any(b.sum(axis=1) > 1)
    r = remap(Anchoring(mesh, bound.anchors))
    assert np.max(np.abs(r.means - splats.means)) < 1e-5


def test_regular_mask_is_the_frames_regularity():
    """``regular_mask`` (what compact anchors and the writer check) decides as ``local_frames``
    does: regular triangles, slivers at the threshold, segments, points and non-finite ones."""
    rng = np.random.default_rng(3)
    tri = rng.normal(size=(400, 3, 3))
    tri[:40, 2] = tri[:40, 0]                                      # two corners equal
    tri[40:50] = 0.0                                               # a point
    tri[50:60, 1] = 0.5 * (tri[50:60, 0] + tri[50:60, 2])          # collinear
    tri[60:70, 2] = tri[60:70, 1] + 1e-9 * rng.normal(size=(10, 3))  # slivers near the bound
    tri[70, 0, 0] = np.nan
    want = local_frames(tri).regular
    assert np.array_equal(regular_mask(tri), want) and 0 < want.sum() < len(tri)
    assert not want[70] and not regular_mask(tri)[70]


def test_anchors_in_face_order_are_the_same_anchors_reordered():
    """bind_local(in_face_order=True): the anchors of bind_local taken in face order, bit for
    bit, the order given, the distances left in the splats' order; derive_local(order=) at
    several chunk sizes and threads takes the same rows."""
    from gsverse_format.anchors_derive import derive_local
    from gsverse_format.model import face_order

    mesh = bumpy_sphere(2, seed=6)
    splats = random_splats(2_000, seed=7, spread=1.3)
    plain = bind_local(splats, mesh)
    assert plain.order is None
    grouped = bind_local(splats, mesh, in_face_order=True)
    order = face_order(plain.anchors.face_index)
    assert np.array_equal(grouped.order, order)
    assert grouped.distance.tobytes() == plain.distance.tobytes()
    expected = plain.anchors.subset(order)
    for name in ("face_index", "barycentrics", "normal_offset", "local_rotation", "local_scale"):
        assert getattr(grouped.anchors, name).tobytes() == getattr(expected, name).tobytes(), name
    face = plain.anchors.face_index.astype(np.int64)
    whole = derive_local(mesh, face, splats.means, splats.rotations)
    shuffled = np.random.default_rng(8).permutation(len(face))
    for chunk, threads in ((7, 1), (300, 3), (5_000, 2)):
        part = derive_local(mesh, face, splats.means, splats.rotations, chunk=chunk,
                            threads=threads, order=shuffled)
        for name in ("barycentrics", "normal_offset", "local_rotation"):
            assert getattr(part, name).tobytes() == getattr(whole, name)[shuffled].tobytes()
    with pytest.raises(ValueError, match="order"):
        derive_local(mesh, face, splats.means, splats.rotations, order=shuffled[:-1])
    empty = bind_local(random_splats(0, seed=1), mesh, in_face_order=True)
    assert empty.order is not None and empty.order.size == 0


def test_deferred_anchors_are_derived_when_first_read(monkeypatch):
    """bind_local(derive=False): nothing derived until one of the three derived arrays is read;
    then all three, the eager binder's values bit for bit; a compact glTF conversion never
    reads them, an explicit one does."""
    import gsverse_format.binding as binding
    from gsverse_format.model import LocalAnchors

    calls = []
    real = binding.derive_local
    monkeypatch.setattr(binding, "derive_local", lambda *a, **k: calls.append(1) or real(*a, **k))
    mesh = bumpy_sphere(2, seed=9)
    splats = random_splats(1_500, seed=10, spread=1.3)
    eager = bind_local(splats, mesh, in_face_order=True)
    assert len(calls) == 1 and eager.anchors.derived
    lazy = bind_local(splats, mesh, in_face_order=True, derive=False)
    assert len(calls) == 1 and not lazy.anchors.derived
    assert lazy.anchors.face_index.tobytes() == eager.anchors.face_index.tobytes()
    assert lazy.anchors.local_scale.tobytes() == eager.anchors.local_scale.tobytes()
    assert len(lazy.anchors) == len(splats) and lazy.anchors.profile == "local"
    with pytest.raises(AttributeError, match="no_such"):
        lazy.anchors.no_such
    assert not lazy.anchors.derived
    assert lazy.anchors.normal_offset.tobytes() == eager.anchors.normal_offset.tobytes()
    assert len(calls) == 2 and lazy.anchors.derived
    for name in ("barycentrics", "local_rotation"):
        assert getattr(lazy.anchors, name).tobytes() == getattr(eager.anchors, name).tobytes()
    assert len(calls) == 2
    with pytest.raises(ValueError, match="deformation"):
        LocalAnchors.deferred(np.zeros(1), np.ones((1, 3)), "bent", lambda: None)


@pytest.mark.parametrize("layout, derived", [(None, 0), ("explicit", 1)])
def test_a_compact_gltf_conversion_derives_no_anchor(tmp_path, monkeypatch, layout, derived):
    import gsverse_format.binding as binding
    from gsverse_format.examples import example_mesh, example_splats, write_obj
    from gsverse_format.io.gltf import read_gltf
    from gsverse_format.io.ply import write_splat_ply
    from gsverse_format.pipeline import ConvertOptions, convert

    mesh = example_mesh(subdivisions=2)
    write_splat_ply(example_splats(mesh, count=400, seed=2), tmp_path / "s.ply")
    write_obj(mesh, str(tmp_path / "m.obj"))
    calls = []
    real = binding.derive_local
    monkeypatch.setattr(binding, "derive_local", lambda *a, **k: calls.append(1) or real(*a, **k))
    summary = convert(str(tmp_path / "s.ply"), str(tmp_path / "o.glb"),
                      ConvertOptions(mesh=str(tmp_path / "m.obj"), anchors=layout))
    assert summary.anchors == (layout or "compact") and len(calls) == derived
    (prim,) = read_gltf(tmp_path / "o.glb").anchored          # readable, anchors derived
    assert np.all(np.isfinite(prim.anchoring.anchors.barycentrics))
