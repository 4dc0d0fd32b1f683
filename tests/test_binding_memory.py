"""Binding and the face sort stay lean without changing a bit: the chunked derivation of
``local`` anchors equals the whole-array rule, its float64 temporaries are bounded by the
chunk, and the in-place reorder of a cloud equals ``subset`` (speed and memory at scale are
measured by ``python -m benchmarks.convert``)."""
from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from gsverse_format import rows
from gsverse_format import quaternion as quat
from gsverse_format.anchors_derive import DERIVE_CHUNK, derive_local
from gsverse_format.binding import bind_local
from gsverse_format.examples import example_mesh, example_splats
from gsverse_format.frames import local_frames
from gsverse_format.model import LocalAnchors, SplatCloud

from helpers import random_splats


def _whole_array_rule(mesh, face, means, rotations):
    """The spec's derivation over all splats at once, in binary64 (the form the chunked
    implementation is checked against)."""
    frames = local_frames(mesh.triangles())
    f = np.asarray(face, dtype=np.intp)
    rel = np.asarray(means, dtype=np.float64) - frames.origin[f]
    local = np.einsum("nji,nj->ni", frames.rotation[f], rel)
    c = frames.shape[f]
    b2 = local[:, 1] / c[:, 1, 1]
    b1 = (local[:, 0] - c[:, 0, 1] * b2) / c[:, 0, 0]
    q_frame = quat.from_matrix(frames.rotation)[f]
    q = quat.canonical_sign(quat.multiply(quat.conjugate(q_frame), quat.normalize(rotations)))
    return np.stack([b1, b2], axis=-1), local[:, 2], q


@pytest.fixture(scope="module")
def bound():
    mesh = example_mesh(subdivisions=2)
    cloud = example_splats(mesh, 5000, seed=7)
    return mesh, cloud, bind_local(cloud, mesh).anchors


@pytest.mark.parametrize("chunk, threads", [(1, 1), (7, 1), (7, 3), (400, 2), (4096, 1),
                                           (DERIVE_CHUNK, 1), (DERIVE_CHUNK, 2)])
def test_chunked_derivation_is_the_whole_array_rule_bit_for_bit(bound, chunk, threads):
    mesh, cloud, anchors = bound
    bary, offset, rotation = _whole_array_rule(mesh, anchors.face_index, cloud.means,
                                               cloud.rotations)
    d = derive_local(mesh, anchors.face_index, cloud.means, cloud.rotations, chunk=chunk,
                     threads=threads)
    assert d.barycentrics.dtype == np.float64
    assert d.barycentrics.tobytes() == bary.tobytes()
    assert d.normal_offset.tobytes() == offset.tobytes()
    assert d.local_rotation.tobytes() == rotation.tobytes()
    # float32 output: each binary64 result rounded once, as the binder stores it
    d32 = derive_local(mesh, anchors.face_index, cloud.means, cloud.rotations, chunk=chunk,
                       dtype=np.float32, threads=threads)
    assert d32.barycentrics.tobytes() == bary.astype(np.float32).tobytes()
    assert d32.normal_offset.tobytes() == offset.astype(np.float32).tobytes()
    assert d32.local_rotation.tobytes() == rotation.astype(np.float32).tobytes()
    # and the binder stores exactly these
    assert anchors.barycentrics.tobytes() == d32.barycentrics.tobytes()
    assert anchors.normal_offset.tobytes() == d32.normal_offset.tobytes()
    assert anchors.local_rotation.tobytes() == d32.local_rotation.tobytes()


def test_derivation_refuses_mismatched_inputs(bound):
    mesh, cloud, anchors = bound
    with pytest.raises(ValueError, match="must match"):
        derive_local(mesh, anchors.face_index[:-1], cloud.means, cloud.rotations)
    with pytest.raises(ValueError, match="chunk"):
        derive_local(mesh, anchors.face_index, cloud.means, cloud.rotations, chunk=0)


def test_derivation_temporaries_are_bounded_by_the_chunk():
    # 200k splats: the whole-array rule holds ~380 bytes of float64 temporaries a splat
    # (~72 MiB); chunked, the peak is the float32 result plus one chunk's temporaries.
    mesh = example_mesh(subdivisions=2)
    n, chunk = 200_000, 4096
    rng = np.random.default_rng(5)
    face = rng.integers(0, mesh.face_count, n)
    means = rng.normal(0, 1, (n, 3)).astype(np.float32)
    rotations = rng.normal(0, 1, (n, 4)).astype(np.float32)
    frames = local_frames(mesh.triangles())
    tracemalloc.start()
    try:
        d = derive_local(mesh, face, means, rotations, frames=frames, chunk=chunk,
                         dtype=np.float32)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    result = d.barycentrics.nbytes + d.normal_offset.nbytes + d.local_rotation.nbytes
    per_face = 40 * 8 * mesh.face_count           # the per-face quaternions and their copies
    assert peak < result + per_face + 1024 * chunk, (peak, result)


def _cloud(n: int, seed: int) -> SplatCloud:
    c = random_splats(n, seed=seed)
    rng = np.random.default_rng(seed)
    return SplatCloud(c.means, c.rotations, c.scales, c.opacities,
                      rng.normal(0, 1, (n, 16, 3)).astype(np.float32), c.color_space,
                      {"filter_3D": rng.uniform(0, 1, n).astype(np.float32)})


def _same(a: SplatCloud, b: SplatCloud) -> None:
    for name in ("means", "rotations", "scales", "opacities", "sh"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes(), name
    assert a.extra.keys() == b.extra.keys()
    for k in a.extra:
        assert a.extra[k].tobytes() == b.extra[k].tobytes()


def test_subset_by_index_array_mask_and_list_is_fancy_indexing():
    c = _cloud(500, 3)
    rng = np.random.default_rng(1)
    idx = rng.permutation(500)[:321]
    mask = rng.uniform(size=500) < 0.4
    for index in (idx, idx.astype(np.uint32), mask, list(idx[:9])):
        s = c.subset(index)
        for name in ("means", "rotations", "scales", "opacities", "sh"):
            assert getattr(s, name).tobytes() == getattr(c, name)[index].tobytes()
        assert s.extra["filter_3D"].tobytes() == c.extra["filter_3D"][index].tobytes()
    a = LocalAnchors(rng.integers(0, 10, 500), rng.normal(size=(500, 2)), rng.normal(size=500),
                     rng.normal(size=(500, 4)), rng.uniform(size=(500, 3)))
    sa = a.subset(idx)
    for name in ("face_index", "barycentrics", "normal_offset", "local_rotation", "local_scale"):
        assert getattr(sa, name).tobytes() == getattr(a, name)[idx].tobytes()


@pytest.mark.parametrize("blocks", [2, 3, 4, 5])   # 48 SH columns: 2-4 blocks, or whole rows
def test_permute_in_place_equals_subset_and_bounds_its_temporaries(monkeypatch, blocks):
    n = 50_000
    c = _cloud(n, 4)
    order = np.argsort(np.random.default_rng(2).integers(0, 999, n), kind="stable")
    expected = c.subset(order)
    address, nbytes = c.sh.__array_interface__["data"][0], c.sh.nbytes
    monkeypatch.setattr(rows, "PERMUTE_BLOCKS", blocks)
    tracemalloc.start()
    try:
        c.permute(order)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert c.sh.__array_interface__["data"][0] == address     # reordered in its own array
    _same(c, expected)
    # the reordered small arrays, one block of SH columns, the permutation check's counts; a
    # copy of the cloud would add sh.nbytes (9.6 MB) to the small arrays
    small = sum(getattr(c, k).nbytes for k in ("means", "rotations", "scales", "opacities"))
    small += c.extra["filter_3D"].nbytes
    block = nbytes // np.gcd(48, blocks)
    assert peak < small + block + 9 * n + 65536, (peak, small, block)


@pytest.mark.parametrize("share", ["view", "same array"])
def test_permute_replaces_a_shared_sh_instead_of_writing_into_it(share):
    c = _cloud(300, 6)
    base = c.sh.copy()
    other = SplatCloud(c.means, c.rotations, c.scales, c.opacities,
                       base[:] if share == "view" else base, c.color_space)
    assert (other.sh is base) == (share == "same array")
    order = np.random.default_rng(3).permutation(300)
    expected = other.subset(order)
    other.permute(order)
    _same(other, expected)
    assert base.tobytes() == c.sh.tobytes()       # the shared array is untouched
    assert c.means.tobytes() != other.means.tobytes()   # the shared means were replaced


@pytest.mark.parametrize("order", [np.array([0, 1, 1]), np.array([0, 1, 3]),
                                   np.array([-1, 0, 1]), np.array([0, 1]),
                                   np.array([0.0, 1.0, 2.0])])
def test_permute_refuses_what_is_not_a_permutation(order):
    c = _cloud(3, 1)
    before = c.sh.copy()
    with pytest.raises(ValueError, match="permutation"):
        c.permute(order)
    assert c.sh.tobytes() == before.tobytes()


def test_permute_of_an_empty_cloud_is_a_no_op():
    c = _cloud(0, 1)
    c.permute(np.zeros(0, np.int64))
    assert len(c) == 0 and c.sh.shape == (0, 16, 3)


@pytest.mark.parametrize("n, top, dtype", [(10, 5, np.uint32), (70_000, 60_000, np.uint32),
                                           (70_000, 65_536, np.uint32),
                                           (200_003, 3_000_000, np.int64),
                                           (100_000, 2**32 - 1, np.uint32),
                                           (80_000, 2**33, np.int64)])
def test_face_order_is_the_stable_argsort(n, top, dtype):
    """The radix sort of face_order gives numpy's stable argsort, index for index: random
    faces with many ties, below and above 2¹⁶ faces, past 2³² (argsort itself), and a
    sorted input."""
    from gsverse_format.model import face_order

    rng = np.random.default_rng(n)
    face = rng.integers(0, top, n, dtype=np.int64).astype(dtype)
    face[: n // 3] = face[n // 2]                  # a long tie
    for keys in (face, np.sort(face), face[::-1].copy()):
        assert np.array_equal(face_order(keys), np.argsort(keys, kind="stable"))
    assert np.array_equal(face_order(face.astype(np.int64) - 1),
                          np.argsort(face.astype(np.int64) - 1, kind="stable"))
