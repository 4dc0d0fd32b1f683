"""The minimal reader's own SPZ decoding (``conformance/minimal_reader.py``, written without the
package) against the package's reader on compressed assets: the same float32 rest pose, bit for
bit, for SH degrees 0 to 3, version 2 and 3 streams, rigid and affine; the same derived anchors;
and a refusal of every broken stream the package's reader refuses."""
from __future__ import annotations

import gzip
import struct

import numpy as np
import pytest

from gsverse_format.conformance import minimal_reader
from gsverse_format.conformance.glb import pack_glb, unpack_glb
from gsverse_format.io.gltf import read_gltf, write_gltf
from gsverse_format.model import Anchoring, SplatAsset, SplatCloud, SplatPrimitive
from gsverse_format.vocabulary import KHR, SPZ_EXTENSION

from test_spz_gltf import BROKEN, _mutated
from validation_assets import local_asset


def _with_degree(asset: SplatAsset, degree: int, seed: int = 5) -> SplatAsset:
    """``asset`` with its anchored splats given random SH of ``degree``."""
    prim = asset.primitives[0]
    c = prim.splats
    rng = np.random.default_rng(seed)
    sh = rng.uniform(-0.9, 0.9, (len(c), (degree + 1) ** 2, 3)).astype(np.float32)
    sh[:, 0] = c.sh[:, 0]
    cloud = SplatCloud(c.means, c.rotations, c.scales, c.opacities, sh, c.color_space)
    return SplatAsset([SplatPrimitive(cloud, prim.anchoring, prim.name)])


def _assert_same(path) -> None:
    raw = minimal_reader.read_anchored_glb(path)
    prim = read_gltf(path).primitives[0]
    ours = prim.splats
    assert raw.compressed and raw.derived
    for mine, theirs in ((raw.positions, ours.means), (raw.rotations, ours.rotations),
                         (raw.scales, ours.scales), (raw.opacities, ours.opacities[:, None])):
        assert mine.component_type == minimal_reader.FLOAT and mine.values.dtype == np.float32
        np.testing.assert_array_equal(mine.values, theirs)
    np.testing.assert_array_equal(np.stack([s.values for s in raw.sh], axis=1), ours.sh)
    derived = minimal_reader.derive_local(raw)
    anchors = prim.anchoring.anchors
    np.testing.assert_array_equal(minimal_reader.face_index(raw), anchors.face_index)
    np.testing.assert_allclose(derived["barycentrics"], anchors.barycentrics, atol=1e-6)
    np.testing.assert_allclose(derived["normalOffset"], anchors.normal_offset, atol=1e-7)
    np.testing.assert_allclose(np.abs(np.sum(derived["localRotation"] * anchors.local_rotation,
                                             axis=1)), 1.0, atol=1e-6)
    np.testing.assert_array_equal(derived["localScale"], anchors.local_scale)


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
@pytest.mark.parametrize("deformation", ["affine", "rigid"])
def test_minimal_reader_decodes_what_the_package_reads(tmp_path, degree, deformation):
    path = tmp_path / "c.glb"
    write_gltf(_with_degree(local_asset(deformation=deformation, lift=0.03), degree), path,
               anchors="compact", compress="spz")
    _assert_same(path)


def _to_version_2(stream: bytes) -> bytes:
    """The same splats as a version-2 stream (three rotation bytes, w >= 0)."""
    data = bytearray(gzip.decompress(stream))
    _, _, n, degree, _, _, _ = struct.unpack_from("<IIIBBBB", data, 0)
    start = 16 + 16 * n
    words = np.frombuffer(bytes(data[start:start + 4 * n]), "<u4")
    from gsverse_format.io.spz_stream import unpack_smallest_three
    q = unpack_smallest_three(words)
    q = np.where(q[:, 3:] < 0, -q, q)
    codes = np.clip(np.round((q[:, :3] + 1.0) * 127.5), 0, 255).astype(np.uint8)
    struct.pack_into("<I", data, 4, 2)
    return gzip.compress(bytes(data[:start]) + codes.tobytes() + bytes(data[start + 4 * n:]),
                         mtime=0)


def test_minimal_reader_decodes_version_2_streams(tmp_path):
    path = tmp_path / "c.glb"
    write_gltf(_with_degree(local_asset(lift=0.03), 2), path, anchors="compact", compress="spz")
    v2 = _mutated(path, tmp_path / "v2.glb", lambda d, p, e, s: _to_version_2(s))
    doc, blob = unpack_glb(v2.read_bytes())
    view = doc["bufferViews"][doc["meshes"][0]["primitives"][0]["extensions"][KHR][
        "extensions"][SPZ_EXTENSION]["bufferView"]]
    head = gzip.decompress(bytes(blob[view["byteOffset"]:view["byteOffset"]
                                      + view["byteLength"]]))[:8]
    assert struct.unpack("<II", head)[1] == 2
    _assert_same(v2)


@pytest.mark.parametrize("name", sorted(BROKEN))
def test_minimal_reader_refuses_what_the_package_refuses(tmp_path, name):
    path = tmp_path / "c.glb"
    write_gltf(local_asset(), path, anchors="compact", compress="spz")
    _, words, change = BROKEN[name]
    broken = _mutated(path, tmp_path / "broken.glb", change)
    with pytest.raises(minimal_reader.Refused):
        minimal_reader.read_anchored_glb(broken)


def test_minimal_reader_inflates_no_further_than_the_count_needs(tmp_path):
    path = tmp_path / "c.glb"
    write_gltf(local_asset(), path, anchors="compact", compress="spz")
    bomb = gzip.compress(b"\0" * (64 << 20), compresslevel=9)
    broken = _mutated(path, tmp_path / "bomb.glb", lambda d, p, e, s: bomb)
    with pytest.raises(minimal_reader.Refused, match="inflates past the 3916 bytes"):
        minimal_reader.read_anchored_glb(broken)
