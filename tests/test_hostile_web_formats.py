"""Bombs and hostile structure in the web splat formats (``.spz``, ``.sog``): one line, exit 1,
bounded time and memory, nothing written.

Every input is built here, small: a few kilobytes of compressed zeros declaring millions of
splats, a WebP whose header declares 8192² pixels, a bzip2 member, a symbolic link out of a
SOG folder, deeply nested or huge-integer ``meta.json``, an spz file of many empty extension
records. The limits are those of ``io/splatformats/container.py`` (README §Limits)."""
from __future__ import annotations

import gzip
import io
import json
import os
import struct
import zipfile
from pathlib import Path

import numpy as np
import pytest

from helpers import random_splats
from hostile_tools import CHILD_CPU_S, CHILD_PEAK_MIB, convert_measured
from splat_writers import _webp, write_sog, write_spz_v2


def assert_refused(source: Path, tmp_path: Path, *words: str, extra: tuple = ()) -> str:
    out = tmp_path / "out.glb"
    code, err, cpu, peak = convert_measured(source, out, *extra)
    assert code == 1, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert str(source) in err or source.name in err, err
    for word in words:
        assert word in err, err
    assert cpu < CHILD_CPU_S and peak < CHILD_PEAK_MIB, (cpu, peak)
    assert not out.exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    return err


def spz_v4(n: int, streams: dict[str, bytes], *, flags: int = 0, extensions: bytes = b"",
           degree: int = 0) -> bytes:
    """An spz v4 file: header, extension records, table of (compressed, size), zstd streams."""
    import zstandard

    packed = [zstandard.ZstdCompressor(level=19).compress(v) for v in streams.values()]
    toc = 32 + len(extensions)
    head = struct.pack("<4sIIBBBBI", b"NGSP", 4, n, degree, 12, flags, len(packed), toc)
    head += b"\0" * (32 - len(head))
    table = b"".join(struct.pack("<QQ", len(p), len(v)) for p, v in zip(packed, streams.values()))
    return head + extensions + table + b"".join(packed)


def zero_streams(n: int) -> dict[str, bytes]:
    sizes = {"positions": 9 * n, "alphas": n, "colours": 3 * n, "scales": 3 * n,
             "rotations": 4 * n}
    return {k: bytes(v) for k, v in sizes.items()}


def test_spz_v4_of_compressed_zeros_declaring_ten_million_splats(tmp_path):
    path = tmp_path / "bomb.spz"
    path.write_bytes(spz_v4(10_000_000, zero_streams(10_000_000)))
    assert path.stat().st_size < 64 * 1024
    assert_refused(path, tmp_path, "declare", "100x")


def test_a_million_splats_at_one_point_are_not_reconstructed(tmp_path):
    """Within the ratio (20 MB of streams), but every splat at the origin: the mesh
    reconstruction refuses it instead of building a k-d tree of a million equal points."""
    path = tmp_path / "point.spz"
    path.write_bytes(spz_v4(1_000_000, zero_streams(1_000_000)))
    assert_refused(path, tmp_path, "distinct splat positions", extra=("--json",))


def test_spz_gzip_of_zeros_inflating_past_the_ratio(tmp_path):
    n = 2_000_000  # SH degree 3: 65 bytes a splat, 130 MB of zeros in about 130 KB of gzip
    payload = struct.pack("<IIIBBBB", 0x5053474E, 2, n, 3, 12, 0, 0) + bytes(65 * n)
    path = tmp_path / "bomb.spz"
    path.write_bytes(gzip.compress(payload, 9))
    assert_refused(path, tmp_path, "gzip stream inflates to more than")


def test_spz_with_a_flood_of_empty_extension_records(tmp_path):
    n = 4
    rng = np.random.default_rng(0)
    streams = {k: rng.integers(0, 255, len(v), dtype=np.uint8).tobytes()
               for k, v in zero_streams(n).items()}
    path = tmp_path / "records.spz"
    path.write_bytes(spz_v4(n, streams, flags=2, extensions=bytes(8 * 200_000)))
    assert_refused(path, tmp_path, "extension records")


def _patched_webp_size(data: bytes, width: int, height: int) -> bytes:
    """A lossless WebP with the image size in its VP8L header replaced (nothing decoded)."""
    at = data.index(b"VP8L") + 8 + 1  # chunk id, chunk size, signature byte 0x2f
    bits = int.from_bytes(data[at:at + 4], "little")
    bits = (bits & ~((1 << 28) - 1)) | (width - 1) | ((height - 1) << 14)
    return data[:at] + bits.to_bytes(4, "little") + data[at + 4:]


def _sog_members(path: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as z:
        return {i.filename: z.read(i) for i in z.infolist()}


def _write_zip(path: Path, members: dict[str, bytes], method: dict[str, int] | None = None):
    with zipfile.ZipFile(path, "w") as z:
        for name, data in members.items():
            z.writestr(name, data, compress_type=(method or {}).get(name, zipfile.ZIP_DEFLATED))


@pytest.fixture()
def sog(tmp_path) -> Path:
    path = tmp_path / "good.sog"
    write_sog(random_splats(64, seed=2, sh_degree=1), path)
    return path


def test_sog_webp_declaring_8192_squared_pixels(sog, tmp_path):
    members = _sog_members(sog)
    members["quats.webp"] = _patched_webp_size(_webp(np.zeros((8, 8, 4), np.uint8)), 8192, 8192)
    from PIL import Image
    with Image.open(io.BytesIO(members["quats.webp"])) as im:
        assert im.size == (8192, 8192)  # the header says so; nothing is decoded
    path = tmp_path / "pixels.sog"
    _write_zip(path, members)
    assert_refused(path, tmp_path, "8192x8192", "quats.webp")


def test_sog_members_must_be_stored_or_deflated(sog, tmp_path):
    members = _sog_members(sog)
    path = tmp_path / "bzip2.sog"
    _write_zip(path, members, {"meta.json": zipfile.ZIP_BZIP2})
    assert_refused(path, tmp_path, "meta.json", "stored or deflated")


def test_sog_member_declaring_more_than_the_ratio(sog, tmp_path):
    members = _sog_members(sog)
    meta = json.loads(members["meta.json"])
    meta["padding"] = " " * (80 << 20)  # 80 MiB of spaces deflate to about 80 KB
    members["meta.json"] = json.dumps(meta).encode()
    path = tmp_path / "ratio.sog"
    _write_zip(path, members)
    assert_refused(path, tmp_path, "meta.json", "declares")


@pytest.mark.parametrize("meta", ["[" * 100_000 + "]" * 100_000,
                                  '{"version": 2, "count": ' + "9" * 5000 + "}"])
def test_sog_meta_json_too_deep_or_a_huge_integer(sog, tmp_path, meta):
    members = _sog_members(sog)
    members["meta.json"] = meta.encode()
    path = tmp_path / "meta.sog"
    _write_zip(path, members)
    err = assert_refused(path, tmp_path, "meta.json")
    assert "nests deeper" in err or "digits" in err


def test_sog_folder_member_linking_out_of_the_folder(tmp_path):
    folder = tmp_path / "scene"
    write_sog(random_splats(64, seed=2, sh_degree=1), folder / "meta.json") \
        if folder.mkdir() is None else None
    outside = tmp_path / "outside"
    outside.mkdir()
    os.replace(folder / "quats.webp", outside / "quats.webp")
    os.symlink(outside / "quats.webp", folder / "quats.webp")
    assert_refused(folder / "meta.json", tmp_path, "outside its folder")
