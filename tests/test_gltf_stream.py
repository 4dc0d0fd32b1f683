"""The GLB writer streams its buffer into the file: the bytes equal the in-memory serialization."""
from __future__ import annotations

import io
import struct

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gsverse_format.io.gltf import (BufferBuilder, asset_to_gltf, gltf_to_bytes, read_gltf,
                                    write_gltf)
from gsverse_format.io.gltf.accessors import COMPONENT_DTYPES
from gsverse_format.io.gltf.writer import write_glb
from gsverse_format.model import (Anchoring, LocalAnchors, SplatAsset, SplatPrimitive,
                                  TriangleMesh)
from gsverse_format.vocabulary import FLOAT, SHORT, UNSIGNED_BYTE, UNSIGNED_INT, UNSIGNED_SHORT

from helpers import bumpy_sphere, random_splats, surface_splats


def _reference_blob(parts) -> bytes:
    """The buffer as the builder used to assemble it: each part converted whole, 4-aligned."""
    blob = bytearray()
    for array, ctype in parts:
        blob += b"\0" * (-len(blob) % 4)
        blob += np.ascontiguousarray(np.asarray(array), dtype=COMPONENT_DTYPES[ctype]).tobytes()
    blob += b"\0" * (-len(blob) % 4)
    return bytes(blob)


def test_buffer_builder_streams_the_same_bytes_in_small_blocks():
    rng = np.random.default_rng(0)
    sh = rng.normal(size=(1001, 16, 3))
    parts = [
        (sh[:, 5, :], FLOAT),                                   # strided view, float64 -> float32
        (rng.integers(0, 255, 7), UNSIGNED_BYTE),               # 7 bytes: padding follows
        (rng.normal(size=(333, 4)).astype(np.float32), FLOAT),  # contiguous, written as is
        (rng.integers(-300, 300, (5, 3)), SHORT),
        (np.arange(3, dtype=np.uint16)[::-1], UNSIGNED_SHORT),  # negative stride
        (np.zeros((0, 3), np.float32), FLOAT),                  # empty accessor
        (rng.integers(0, 2**31, 11), UNSIGNED_INT),
        (np.float32(2.5), FLOAT),                               # a scalar: one element
    ]
    b = BufferBuilder()
    b.WRITE_BLOCK = 100          # many blocks per part
    for array, ctype in parts:
        b.add(array, ctype, "SCALAR")
    expected = _reference_blob(parts)
    assert b.finish() == expected
    assert b.length == len(expected)
    out = io.BytesIO()
    assert b.write_to(out) == len(expected) and out.getvalue() == expected
    offsets = [v["byteOffset"] for v in b.views]
    assert all(o % 4 == 0 for o in offsets) and offsets == sorted(offsets)


@pytest.mark.parametrize("block", [100, 4 << 20])
def test_buffer_builder_copies_column_views_in_c_with_the_same_bytes(monkeypatch, block):
    """Views of some columns of a float32 array in the component type (one SH coefficient of
    every splat, as the writer adds them) are made contiguous by the C extension
    (gsverse_format.rows.contiguous_rows), here for every block: the same bytes."""
    from gsverse_format import rows

    calls = []
    module = rows._module()
    assert module is not None, "gsverse_format._rows was not built"

    class Spy:
        def columns(self, *args):
            calls.append(args[1:5])
            return module.columns(*args)

    monkeypatch.setattr(rows, "_module", lambda: Spy())
    monkeypatch.setattr(rows, "NATIVE_MIN_BYTES", 0)
    rng = np.random.default_rng(1)
    sh = rng.normal(size=(1001, 16, 3)).astype(np.float32)
    parts = [(sh[:, k, :], FLOAT) for k in range(16)] + [(sh[:, 2:4, 1], FLOAT)]
    b = BufferBuilder()
    b.WRITE_BLOCK = block
    for array, ctype in parts:
        b.add(array, ctype, "VEC3")
    assert b.finish() == _reference_blob(parts)
    assert {c[1] for c in calls} == {12 * k for k in range(16)}   # every coefficient in C
    assert all(c[0] == 192 and c[2] == 12 for c in calls)


def test_buffer_builder_minmax_of_the_stored_values():
    b = BufferBuilder()
    values = np.array([[0.1, -2.0, 3.0], [1e-40, 5.0, -7.25]])   # float64, rounded when stored
    b.add(values, FLOAT, "VEC3", minmax=True)
    stored = values.astype(np.float32).astype(np.float64)
    assert b.accessors[0]["min"] == stored.min(axis=0).tolist()
    assert b.accessors[0]["max"] == stored.max(axis=0).tolist()


def _assets():
    mesh = bumpy_sphere(1, 2)
    cloud = surface_splats(mesh, 301, 2, sh_degree=3)
    rng = np.random.default_rng(2)
    n = len(cloud)
    anchors = LocalAnchors(np.sort(rng.integers(0, mesh.face_count, n)), rng.uniform(0, 0.5, (n, 2)),
                           rng.normal(0, 0.01, n), Rotation.random(n, random_state=2).as_quat(),
                           cloud.scales, "affine")
    anchored = SplatAsset([SplatPrimitive(cloud, Anchoring(mesh, anchors), "body"),
                           SplatPrimitive(random_splats(13, 3, sh_degree=3), None, "bg")])
    tiny = TriangleMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    one = SplatAsset([SplatPrimitive(random_splats(1, 5, sh_degree=0), None, "one")])
    return {"plain": SplatAsset([SplatPrimitive(random_splats(257, 4, sh_degree=2), None, "p")]),
            "anchored": anchored, "one": one,
            "mesh-only-anchor": SplatAsset([SplatPrimitive(
                random_splats(3, 6, sh_degree=1),
                Anchoring(tiny, LocalAnchors(np.zeros(3, np.int64), np.full((3, 2), 0.25),
                                             np.zeros(3), np.tile([0, 0, 0, 1.0], (3, 1)),
                                             np.ones((3, 3)), "rigid")), "t")])}


@pytest.mark.parametrize("name", list(_assets()))
@pytest.mark.parametrize("quantize", [None, {"barycentrics": "unsigned_byte",
                                              "localRotation": "short"}])
def test_streamed_glb_equals_the_in_memory_bytes(tmp_path, name, quantize):
    asset = _assets()[name]
    expected = gltf_to_bytes(asset_to_gltf(asset, quantize=quantize))
    path = tmp_path / "out.glb"
    write_gltf(asset, path, quantize=quantize)
    data = path.read_bytes()
    assert data == expected
    magic, version, total = struct.unpack_from("<4sII", data)
    assert (magic, version, total) == (b"glTF", 2, len(data))
    assert len(read_gltf(path).primitives) == len(asset.primitives)
    gltf = tmp_path / "out.gltf"
    write_gltf(asset, gltf, quantize=quantize)
    assert gltf.read_bytes() == gltf_to_bytes(asset_to_gltf(asset, quantize=quantize), binary=False)


def test_write_glb_without_a_buffer_has_no_bin_chunk():
    out = io.BytesIO()
    total = write_glb(out, b'{"asset":{"version":"2.0"}}', BufferBuilder())
    data = out.getvalue()
    assert total == len(data) and len(data) % 4 == 0
    json_length, kind = struct.unpack_from("<II", data, 12)
    assert 20 + json_length == len(data) and kind == 0x4E4F534A
