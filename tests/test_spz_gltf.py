"""The SPZ-compressed rest pose (``KHR_gaussian_splatting_compression_spz_2``, spec
§SPZ-compressed rest pose) in the Python writer and reader, ``gsverse-convert --compress spz``
and ``gsverse-pose --compress spz``: the stream layer against its stated bounds, the frame
change against the ``.spz`` file reader's, derived anchors from the decoded rest pose, and the
refusals of broken streams."""
from __future__ import annotations

import gzip
import json
import math
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from gsverse_format.cli.convert import main as convert_main
from gsverse_format.cli.pose import main as pose_main
from gsverse_format.codes import Code
from gsverse_format.conformance.glb import pack_glb, unpack_glb
from gsverse_format.errors import FormatError, UsageError
from gsverse_format.io import spz_stream
from gsverse_format.io.gltf import asset_to_gltf, gltf_to_bytes, read_gltf, write_gltf
from gsverse_format.io.gltf.spz import SH_SIGNS
from gsverse_format.io.registry import FRAMES
from gsverse_format.io.splatformats.spz import read_spz
from gsverse_format.model import SplatAsset, SplatCloud, SplatPrimitive
from gsverse_format.remapping.reference import remap
from gsverse_format.sh import sh_rotation_matrix
from gsverse_format.transform import rotate_splats
from gsverse_format.vocabulary import KHR, SPZ_EXTENSION

from validation_assets import games_asset, local_asset

ROOT = Path(__file__).resolve().parents[1]
CAPSULE = ROOT / "examples" / "capsule"


def _cloud(n: int, degree: int, seed: int = 0, spread: float = 3.0) -> SplatCloud:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    sh = rng.uniform(-0.9, 0.9, (n, (degree + 1) ** 2, 3))
    sh[:, 0] = rng.uniform(-3.0, 3.0, (n, 3))
    return SplatCloud(rng.uniform(-spread, spread, (n, 3)), q / np.linalg.norm(q, axis=1)[:, None],
                      np.exp(rng.uniform(-8.0, 4.0, (n, 3))), rng.uniform(0, 1, n), sh)


def _covariances(rotations: np.ndarray, scales: np.ndarray) -> np.ndarray:
    c = SplatCloud(np.zeros((len(scales), 3)), rotations, scales, np.ones(len(scales)),
                   np.zeros((len(scales), 1, 3)))
    return c.covariances().astype(np.float64)


# --------------------------------------------------------------------------- the stream layer

@pytest.mark.parametrize("degree", [0, 1, 3])
def test_stream_round_trip_within_the_stated_bounds(degree):
    """Every attribute decodes within :func:`quantization_bounds` of what was encoded, and
    the covariance within its stated relative bound."""
    c = _cloud(4000, degree, seed=degree)
    arrays = spz_stream.SpzArrays(c.means.astype(np.float64), c.rotations.astype(np.float64),
                                  c.scales.astype(np.float64), c.opacities.astype(np.float64),
                                  c.sh.astype(np.float64))
    data = spz_stream.inflate_bounded(spz_stream.encode(arrays), 10 ** 7, "test")
    header = spz_stream.parse_header(data, "test")
    assert (header.version, header.count, header.degree) == (3, 4000, degree)
    assert len(data) == spz_stream.stream_bytes(3, 4000, degree)
    d = spz_stream.decode(header, *spz_stream.split_stream(data, header, "test")[:1])
    bound = spz_stream.quantization_bounds(header.fractional_bits)
    assert np.abs(d.means - arrays.means).max() <= bound["position"] * (1 + 1e-9)
    assert np.abs(d.scales / arrays.scales - 1).max() <= bound["scale"] * (1 + 1e-9)
    angle = 2 * np.arccos(np.minimum(1.0, np.abs((d.rotations * arrays.rotations).sum(1))))
    assert angle.max() <= bound["rotation"]
    assert np.abs(d.opacities - arrays.opacities).max() <= bound["opacity"] + 1e-12
    assert np.abs(d.sh[:, 0] - arrays.sh[:, 0]).max() <= bound["dc"] + 1e-12
    if degree:
        assert np.abs(d.sh[:, 1:4] - arrays.sh[:, 1:4]).max() <= bound["sh1"]
    if degree > 1:
        assert np.abs(d.sh[:, 4:] - arrays.sh[:, 4:]).max() <= bound["sh23"]
    before = _covariances(arrays.rotations, arrays.scales)
    after = _covariances(d.rotations, d.scales)
    rel = np.linalg.norm(after - before, axis=(1, 2)) / np.linalg.norm(before, axis=(1, 2))
    assert rel.max() <= bound["covariance"]


def test_fractional_bits_follow_the_coordinates():
    assert spz_stream.choose_fractional_bits(np.array([[1.0, -2047.0, 0.0]])) == 12
    assert spz_stream.choose_fractional_bits(np.array([[5000.0, 0.0, 0.0]])) == 10
    with pytest.raises(UsageError, match="24-bit"):
        spz_stream.choose_fractional_bits(np.array([[1e7, 0.0, 0.0]]))


def test_inflation_stops_at_the_bound():
    """A gzip bomb is refused after the bound, without inflating the rest."""
    bomb = gzip.compress(b"\0" * (50 << 20), compresslevel=9)
    assert len(bomb) < 100_000
    with pytest.raises(FormatError, match="more than the 1000 bytes"):
        spz_stream.inflate_bounded(bomb, 1000, "bomb")
    with pytest.raises(FormatError, match="truncated"):
        spz_stream.inflate_bounded(bomb[: len(bomb) // 2], 60 << 20, "cut")
    with pytest.raises(FormatError, match="follow the gzip member"):
        spz_stream.inflate_bounded(gzip.compress(b"abc") + b"junk", 100, "trailing")
    assert spz_stream.inflate_bounded(gzip.compress(b"abc") + b"\0\0", 100, "padded") == b"abc"


def test_sh_signs_are_the_rotation_about_y():
    """The signs of spec §SPZ-compressed rest pose are the SH rotation of 180° about Y."""
    m = sh_rotation_matrix(np.diag([-1.0, 1.0, -1.0]), 3)
    assert np.allclose(m, np.diag(SH_SIGNS[:len(m)]), atol=1e-12)


# --------------------------------------------------------------------------- glTF write / read

@pytest.fixture(scope="module")
def compressed(tmp_path_factory):
    """A compact local asset written with and without compression."""
    folder = tmp_path_factory.mktemp("spz")
    asset = local_asset(200, seed=4)
    write_gltf(asset, folder / "plain.glb", anchors="compact")
    write_gltf(asset, folder / "spz.glb", anchors="compact", compress="spz")
    return folder, asset


def test_compressed_asset_layout(compressed):
    folder, _ = compressed
    doc, blob = unpack_glb((folder / "spz.glb").read_bytes())
    assert SPZ_EXTENSION in doc["extensionsUsed"]
    assert doc["extensionsRequired"] == [SPZ_EXTENSION]
    for prim in (m["primitives"][0] for m in doc["meshes"] if KHR in m["primitives"][0].get(
            "extensions", {})):
        ext = prim["extensions"][KHR]["extensions"][SPZ_EXTENSION]
        view = doc["bufferViews"][ext["bufferView"]]
        assert "target" not in view and "byteStride" not in view
        for name, i in prim["attributes"].items():
            acc = doc["accessors"][i]
            assert "bufferView" not in acc and "byteOffset" not in acc, name
        assert doc["accessors"][prim["attributes"]["POSITION"]]["min"]
        stream = blob[view.get("byteOffset", 0): view.get("byteOffset", 0) + view["byteLength"]]
        assert stream[:2] == b"\x1f\x8b"
    assert (folder / "spz.glb").stat().st_size < 0.5 * (folder / "plain.glb").stat().st_size


def test_reader_decodes_what_the_writer_derived_from(compressed):
    """The decoded rest pose is within the stated bounds of the uncompressed one, and the
    derived anchors reproduce the decoded rest pose at the rest mesh (float rounding only)."""
    folder, _ = compressed
    plain, spz = read_gltf(folder / "plain.glb"), read_gltf(folder / "spz.glb")
    for a, b in zip(plain.primitives, spz.primitives):
        assert len(a.splats) == len(b.splats)
        assert b.khr.extensions == {}
        assert np.abs(a.splats.means - b.splats.means).max() <= \
            spz_stream.quantization_bounds(12)["position"] * 1.001
        if b.anchoring is not None:
            r = remap(b.anchoring)
            assert np.abs(r.means - b.splats.means).max() < 1e-6
            assert np.array_equal(a.anchoring.anchors.face_index, b.anchoring.anchors.face_index)


def test_rewriting_a_compressed_asset_is_stable(compressed, tmp_path):
    """Decoded values encode to the same codes: compressing what was read gives the same
    splats back."""
    folder, _ = compressed
    first = read_gltf(folder / "spz.glb")
    write_gltf(first, tmp_path / "again.glb", anchors="compact", compress="spz")
    second = read_gltf(tmp_path / "again.glb")
    for a, b in zip(first.primitives, second.primitives):
        for name in ("means", "scales", "opacities", "sh"):
            assert np.array_equal(getattr(a.splats, name), getattr(b.splats, name)), name
        assert np.abs(a.splats.rotations - b.splats.rotations).max() < 1e-6


def test_frame_change_agrees_with_the_spz_file_reader(compressed, tmp_path):
    """The payload as a ``.spz`` file, read in SPZ's RUB frame and turned by the registry's
    ``spz-rub`` frame, gives the splats the glTF reader decodes."""
    folder, _ = compressed
    doc, blob = unpack_glb((folder / "spz.glb").read_bytes())
    prim = doc["meshes"][0]["primitives"][0]
    view = doc["bufferViews"][prim["extensions"][KHR]["extensions"][SPZ_EXTENSION]["bufferView"]]
    start = view.get("byteOffset", 0)
    (tmp_path / "payload.spz").write_bytes(blob[start:start + view["byteLength"]])
    rub = read_spz(tmp_path / "payload.spz").splats
    turned = rotate_splats(rub, FRAMES["spz-rub"].to_gltf)
    gltf = read_gltf(folder / "spz.glb").primitives[0].splats
    assert np.abs(turned.means - gltf.means).max() < 1e-6
    assert np.abs(turned.sh - gltf.sh).max() < 1e-6
    # (−x, y, −z, w) and the rotation composed with 180° about Y differ by a turn of the
    # splat's own x and z axes, which leaves its covariance unchanged: compare covariances
    a, b = turned.covariances().astype(np.float64), gltf.covariances().astype(np.float64)
    assert (np.linalg.norm(a - b, axis=(1, 2)) / np.linalg.norm(b, axis=(1, 2))).max() < 1e-5


def test_explicit_and_games_anchors_are_not_compressed(tmp_path):
    with pytest.raises(UsageError, match="explicit anchors"):
        asset_to_gltf(local_asset(30), anchors="explicit", compress="spz")
    with pytest.raises(UsageError, match="games anchors"):
        asset_to_gltf(games_asset(), anchors="compact", compress="spz")
    with pytest.raises(UsageError, match="compress must be"):
        asset_to_gltf(local_asset(30), anchors="compact", compress="zip")


def _mutated(path: Path, out: Path, change) -> Path:
    doc, blob = unpack_glb(path.read_bytes())
    prim = doc["meshes"][0]["primitives"][0]
    ext = prim["extensions"][KHR]["extensions"][SPZ_EXTENSION]
    view = doc["bufferViews"][ext["bufferView"]]
    start = view.get("byteOffset", 0)
    stream = bytes(blob[start:start + view["byteLength"]])
    new_stream = change(doc, prim, ext, stream)
    if new_stream is not None:
        blob = bytes(blob) + b"\0" * (-len(blob) % 4)
        view["byteOffset"], view["byteLength"] = len(blob), len(new_stream)
        blob += new_stream + b"\0" * (-len(new_stream) % 4)
        doc["buffers"][0]["byteLength"] = len(blob)
    out.write_bytes(pack_glb(doc, blob))
    return out


def _restream(stream: bytes, edit) -> bytes:
    data = bytearray(gzip.decompress(stream))
    return gzip.compress(bytes(edit(data)), mtime=0)


def _set_count(doc, prim, n):
    for i in prim["attributes"].values():
        doc["accessors"][i]["count"] = n


def _set_header(offset: int, fmt: str, value):
    def edit(data: bytearray) -> bytearray:
        struct.pack_into(fmt, data, offset, value)
        return data
    return edit


BROKEN = {
    "truncated": (Code.SPZ_STREAM_INVALID, "truncated gzip",
                  lambda d, p, e, s: s[: len(s) // 2]),
    "not gzip": (Code.SPZ_STREAM_INVALID, "broken gzip",
                 lambda d, p, e, s: b"\x1f\x8b\x08\x00" + b"\xff" * 40),
    "trailing data": (Code.SPZ_STREAM_INVALID, "follow the gzip member",
                      lambda d, p, e, s: s + b"more"),
    "bad magic": (Code.SPZ_STREAM_INVALID, "NGSP",
                  lambda d, p, e, s: _restream(s, _set_header(0, "<I", 0x12345678))),
    "version 4": (Code.SPZ_STREAM_INVALID, "version 4",
                  lambda d, p, e, s: _restream(s, _set_header(4, "<I", 4))),
    "extension records": (Code.SPZ_STREAM_INVALID, "extension records",
                          lambda d, p, e, s: _restream(s, _set_header(14, "<B", 2))),
    "short stream": (Code.SPZ_STREAM_INVALID, "inflates to",
                     lambda d, p, e, s: _restream(s, lambda b: b[:-7])),
    "long stream": (Code.SPZ_STREAM_INVALID, "inflates to",
                    lambda d, p, e, s: _restream(s, lambda b: b + b"\0" * 5)),
    "count": (Code.SPZ_COUNT_MISMATCH, "holds",
              lambda d, p, e, s: _restream(s, _set_header(8, "<I", 150))),
    "placeholder count": (Code.SPZ_COUNT_MISMATCH, "placeholders",
                          lambda d, p, e, s: d["accessors"][p["attributes"]["COLOR_0"]]
                          .update(count=3) or None),
    "sh degree": (Code.SPZ_SH_MISMATCH, "SH degree",
                  lambda d, p, e, s: _restream(s, _set_header(12, "<B", 0))),
    "buffer view": (Code.SPZ_BUFFER_VIEW_INVALID, "bufferView",
                    lambda d, p, e, s: e.update(bufferView=99) or None),
    "no buffer view": (Code.SPZ_BUFFER_VIEW_INVALID, "bufferView",
                       lambda d, p, e, s: e.pop("bufferView") and None or None),
}


@pytest.mark.parametrize("name", sorted(BROKEN))
def test_broken_streams_are_refused(compressed, tmp_path, name):
    folder, _ = compressed
    code, words, change = BROKEN[name]
    path = _mutated(folder / "spz.glb", tmp_path / "broken.glb", change)
    with pytest.raises(FormatError) as info:
        read_gltf(path)
    assert getattr(info.value, "code", None) == code, str(info.value)
    message = str(info.value)
    assert "broken.glb" in message and words in message and "\n" not in message


def test_bomb_inside_a_glb_is_bounded(compressed, tmp_path):
    """A stream declaring the asset's splat count but inflating to 200 MB is refused at the
    bytes that count needs; a declared count far beyond what the stream could hold is refused
    before inflating."""
    folder, _ = compressed
    bomb = gzip.compress(b"\0" * (200 << 20), compresslevel=9)
    path = _mutated(folder / "spz.glb", tmp_path / "bomb.glb", lambda d, p, e, s: bomb)
    with pytest.raises(FormatError, match="inflates to more than"):
        read_gltf(path)

    def huge(doc, prim, ext, stream):
        _set_count(doc, prim, 10 ** 9)
    path = _mutated(folder / "spz.glb", tmp_path / "huge.glb", huge)
    with pytest.raises(FormatError) as info:
        read_gltf(path)
    assert info.value.code == Code.SIZE_LIMIT_EXCEEDED


# --------------------------------------------------------------------------- the commands

def test_convert_compress_spz(tmp_path, capsys):
    out = tmp_path / "capsule.glb"
    assert convert_main([str(CAPSULE / "splats.ply"), str(out), "--mesh",
                         str(CAPSULE / "mesh.obj"), "--compress", "spz", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["compression"] == "spz" and summary["anchors"] == "compact"
    asset = read_gltf(out)
    assert asset.primitives[0].anchoring is not None
    plain = tmp_path / "plain.glb"
    assert convert_main([str(CAPSULE / "splats.ply"), str(plain), "--plain", "--compress",
                         "spz", "-q"]) == 0
    assert read_gltf(plain).primitives[0].anchoring is None
    assert plain.stat().st_size < out.stat().st_size


@pytest.mark.parametrize("flags,words", [
    (["--anchors", "explicit"], "needs compact anchors"),
    (["--keep-order"], "drop --keep-order"),
])
def test_convert_compress_refusals(tmp_path, capsys, flags, words):
    out = tmp_path / "out.glb"
    code = convert_main([str(CAPSULE / "splats.ply"), str(out), "--mesh",
                         str(CAPSULE / "mesh.obj"), "--compress", "spz", *flags])
    err = capsys.readouterr().err
    assert code != 0 and words in err and "Traceback" not in err
    assert not out.exists()


def test_convert_compress_needs_gltf_output(tmp_path, capsys):
    code = convert_main([str(CAPSULE / "splats.ply"), str(tmp_path / "out.ply"), "--plain",
                         "--compress", "spz"])
    assert code != 0 and "glTF output" in capsys.readouterr().err


def test_pose_compress_spz(tmp_path, capsys):
    asset = tmp_path / "capsule.glb"
    assert convert_main([str(CAPSULE / "splats.ply"), str(asset), "--mesh",
                         str(CAPSULE / "mesh.obj"), "-q"]) == 0
    frames = tmp_path / "frames"
    assert pose_main([str(asset), str(frames), "--to", "glb", "--deform", "stretch=1.4",
                      "--compress", "spz", "-q"]) == 0
    (frame,) = sorted(frames.glob("*.glb"))
    doc, _ = unpack_glb(frame.read_bytes())
    assert doc["extensionsRequired"] == [SPZ_EXTENSION]
    posed = read_gltf(frame).primitives[0].splats
    assert posed.means[:, 1].max() > 1.2 * read_gltf(asset).primitives[0].splats.means[:, 1].max()
    code = pose_main([str(asset), str(tmp_path / "ply"), "--to", "ply", "--deform",
                      "stretch=1.4", "--compress", "spz"])
    assert code != 0 and "glb and gltf" in capsys.readouterr().err


def test_info_reports_the_stream(compressed):
    """``gsverse-info`` counts the stream's bytes, not the placeholders' declared ones."""
    from gsverse_format.io.info import describe

    folder, _ = compressed
    info = describe(folder / "spz.glb")
    assert "splats SPZ stream" in info.parts
    assert not any(k.startswith("splats POSITION") for k in info.parts)
    assert sum(info.parts.values()) == (folder / "spz.glb").stat().st_size
    assert info.primitives[0]["compression"] == "spz"


def test_readers_without_the_extension_see_what_the_draft_says(compressed):
    """The Khronos glTF-Validator finds nothing wrong but the names of KHR attributes it does
    not know yet, and says it cannot check the SPZ extension; PlayCanvas's own glTF parser,
    which knows KHR_gaussian_splatting but not the draft, reads the placeholders as glTF
    defines accessors without bufferView: zeros (the draft's "other extensions may be
    providing the data"; our writers list the extension as required for that reason)."""
    from khr_tools import read_with_playcanvas, require_node_tools, validate_gltf

    require_node_tools()
    folder, _ = compressed
    report = validate_gltf(folder / "spz.glb")
    assert report["numUnexpectedErrors"] == 0, report["messages"][:5]
    assert any(m["code"] == "UNSUPPORTED_EXTENSION" and SPZ_EXTENSION in m["message"]
               for m in report["messages"])
    (first, *_) = read_with_playcanvas(folder / "spz.glb")
    assert first["count"] == len(read_gltf(folder / "spz.glb").primitives[0].splats)
    assert not np.any(first["position"]) and not np.any(first["scale"])
