"""The structure-aware fuzz targets of the web splat formats (``.spz``, ``.sog``, ``.ksplat``,
compressed PLY) and of the web plugin's JS reader: short seeded runs find no internal error or
hang (the long runs are ``python -m fuzz --runs 100000 --kinds spz`` and so on), the
mutations reach the structures they name, and the inputs the long runs found are refused as
bad input."""
from __future__ import annotations

import io
import json
import random
import shutil
import struct
import subprocess
import sys
import warnings
import zipfile

import pytest

from helpers import fuzz_module
from test_validate_fuzz import ROOT, _counts, _run

web = fuzz_module("webformats")


@pytest.mark.parametrize("kind, seed, targets", [
    ("spz", 21, {"read_spz", "read"}),
    ("sog", 22, {"read_sog", "read"}),
    ("ksplat", 23, {"read_ksplat", "read"}),
    ("cply", 24, {"read_compressed_ply", "read"}),
])
def test_short_web_format_fuzz_run_has_no_internal_error(tmp_path, kind, seed, targets):
    counts = _counts(_run(tmp_path, kind, 200, seed))
    assert set(counts) == targets
    for stats in counts.values():
        assert stats["runs"] == 200 and stats["internal"] == stats["hang"] == 0
        assert stats["ok"] > 0 and stats["refused"] > 0   # seeds read; mutations reach checks


@pytest.mark.skipif(shutil.which("node") is None, reason="needs Node")
def test_short_js_reader_fuzz_run_has_no_internal_error(tmp_path):
    counts = _counts(_run(tmp_path, "js", 200, 25))
    assert set(counts) == {"js_reader"}
    stats = counts["js_reader"]
    assert stats["runs"] == 200 and stats["internal"] == stats["hang"] == 0
    assert stats["ok"] > 0 and stats["refused"] > 0


@pytest.mark.skipif(shutil.which("node") is None, reason="needs Node")
def test_js_worker_tells_a_refusal_from_an_internal_error(tmp_path):
    """An AnchorError is a refusal; the Node process dying is an internal error."""
    js = fuzz_module("js_worker")
    worker = js.JsWorker(60.0)
    try:
        bad = tmp_path / "bad.glb"
        bad.write_bytes(b"glTF" + struct.pack("<II", 2, 12))
        [(name, outcome, detail, codes)] = worker.run(str(bad), ["js_reader"])
        assert (name, outcome, codes) == ("js_reader", "refused", ("GLB_FIRST_CHUNK_NOT_JSON",))
        good = tmp_path / "good.glb"
        good.write_bytes(next(d for s, d in fuzz_module("seeds").seeds() if s == ".glb"))
        assert worker.run(str(good), ["js_reader"])[0][1] == "ok"
        worker.proc.kill()   # the process gone: that input's outcome is internal
        worker.proc.wait()
        outcome = worker._ended()
        assert outcome[0] == "internal" and "ended with status" in outcome[1]
    finally:
        worker.close()


def test_web_mutations_are_deterministic_and_structure_aware():
    seeds = web.web_seeds()
    kinds = {k for k, _ in seeds}
    assert kinds == {".spz", ".sog", ".ksplat", ".compressed.ply"}
    assert any(d[:4] == b"NGSP" for k, d in seeds if k == ".spz")   # v4 beside gzip v2
    pool = [(k, d) for k, d in seeds]
    for kind, data in seeds:
        a = [web.mutate_any(random.Random(i), kind, data, pool) for i in range(40)]
        b = [web.mutate_any(random.Random(i), kind, data, pool) for i in range(40)]
        assert a == b
        assert sum(m != data for m in a) >= 30
    # spz v4: table entries and header fields are reached
    v4 = next(d for k, d in seeds if k == ".spz" and d[:4] == b"NGSP")
    toc = struct.unpack_from("<I", v4, 16)[0]
    changed = set()
    for i in range(300):
        m = web._mutate_spz_v4(random.Random(i), v4, pool)
        if len(m) == len(v4):
            changed |= {j for j in range(len(v4)) if m[j] != v4[j]}
    assert changed & set(range(toc, toc + 16)) and changed & set(range(4, 20))
    # sog: meta.json edited, members dropped or renamed, methods changed
    sog = next(d for k, d in seeds if k == ".sog")
    names = set()
    methods = set()
    for i in range(200):
        try:
            with zipfile.ZipFile(io.BytesIO(web._mutate_sog(random.Random(i), sog, pool))) as z:
                names.add(tuple(sorted(z.namelist())))
                methods |= {info.compress_type for info in z.infolist()}
        except zipfile.BadZipFile:
            pass
    assert len(names) > 3 and {zipfile.ZIP_BZIP2, zipfile.ZIP_LZMA} <= methods


def _compressed_ply_with_list_bound(path) -> None:
    bounds = ["min_x", "min_y", "min_z", "max_x", "max_y", "max_z", "min_scale_x",
              "min_scale_y", "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z",
              "min_r"]
    head = ["ply", "format binary_little_endian 1.0", "element chunk 1"]
    head += [f"property float {b}" for b in bounds[:-1]] + ["property list uint uint min_r"]
    head += ["property float min_g", "property float min_b", "property float max_r",
             "property float max_g", "property float max_b", "element vertex 2"]
    head += [f"property uint {p}" for p in ("packed_position", "packed_rotation",
                                             "packed_scale", "packed_color")]
    body = struct.pack("<12f", *([0.0] * 12)) + struct.pack("<I", 0) + struct.pack("<5f", *[0.0] * 5)
    body += bytes(32)
    path.write_bytes(("\n".join(head) + "\nend_header\n").encode() + body)


def test_found_by_fuzzing_are_refused_as_bad_input(tmp_path):
    """Inputs of the long runs that were internal errors: a compressed PLY colour bound that is
    a list property, a zip archive of a later zip version, an encrypted member, a SOG number
    that is an integer too large for a float; and a WebP a little past Pillow's own
    pixel limit is decoded without Pillow's warning reaching the user."""
    from gsverse_format.errors import FormatError
    from gsverse_format.io.splatformats import decode

    cply = tmp_path / "list.compressed.ply"
    _compressed_ply_with_list_bound(cply)
    with pytest.raises(FormatError, match=r"chunk\.min_r is a list"):
        decode("compressed-ply", cply)

    sog = next(d for k, d in web.web_seeds() if k == ".sog")
    buf = bytearray(sog)
    central = buf.rfind(b"PK\x01\x02")
    struct.pack_into("<H", buf, central + 6, 84)      # version needed to extract: 8.4
    path = tmp_path / "v84.sog"
    path.write_bytes(bytes(buf))
    with pytest.raises(FormatError, match="broken zip archive"):
        decode("sog", path)
    buf = bytearray(sog)
    for at in (0, buf.find(b"PK\x01\x02") + 2):   # general purpose flags: encrypted
        struct.pack_into("<H", buf, at + 6, 1)
    path.write_bytes(bytes(buf))
    with pytest.raises(FormatError, match="member 'meta.json' is encrypted"):
        decode("sog", path)

    v1 = [d for k, d in web.web_seeds() if k == ".sog"][1]   # version 1, SH: shN.mins/maxs
    for huge in (2 ** 64, 10 ** 400):
        out = io.BytesIO()
        with zipfile.ZipFile(io.BytesIO(v1)) as src, zipfile.ZipFile(out, "w") as dst:
            for name in src.namelist():
                body = src.read(name)
                if name == "meta.json":
                    meta = json.loads(body)
                    meta["shN"]["maxs"] = huge
                    body = json.dumps(meta).encode()
                dst.writestr(name, body)
        path.write_bytes(out.getvalue())
        if huge < 2 ** 1024:   # a finite float: read (numpy's isfinite refused the integer)
            decode("sog", path)
            continue
        with pytest.raises(FormatError, match="shN.maxs is not a finite number"):
            decode("sog", path)

    from PIL import Image

    from gsverse_format.io.splatformats.container import decode_webp

    small = io.BytesIO()
    Image.new("RGBA", (1, 1)).save(small, "WEBP", lossless=True)
    webp = bytearray(small.getvalue())
    assert webp[12:16] == b"VP8L" and webp[20] == 0x2F
    bits = struct.unpack_from("<I", webp, 21)[0] & ~0x0FFFFFFF
    struct.pack_into("<I", webp, 21, bits | 9999 | (8999 << 14))   # 10000 x 9000: 90 M pixels
    with warnings.catch_warnings():
        warnings.simplefilter("error")   # Pillow warns above 89 M pixels
        with pytest.raises(FormatError, match="declares 10000x9000 pixels"):
            decode_webp(bytes(webp), "x.webp", "x.sog")


def test_python_dash_m_fuzz_runs_the_harness(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "fuzz", "--runs", "3", "--kinds", "ksplat",
                           "--quiet", "--crash-dir", str(tmp_path / "c")], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("inputs: 3  internal errors: 0  hangs: 0")
    bad = subprocess.run([sys.executable, "-m", "fuzz", "--kinds", "zip"], cwd=ROOT,
                         capture_output=True, text=True, timeout=600)
    assert bad.returncode == 2 and "cply" in bad.stderr and "js" in bad.stderr


#: A 578-byte .spz v4 of the long run (seed 12) whose zstd frame made zstandard raise MemoryError.
SPZ_V4_MEMORYERROR = bytes.fromhex(
    "4e4753500400000014000000000c02052c0000000000000000000000000000000300bead0400000001000000"
    "bd00000000000000b4000000000000001d00000000000000140000000000000045000000000000003c000000"
    "0000000045000000000000003c000000000000005900000000000000500000000000000028b52ffd20b4a105"
    "00a54dca182530bb1d6d132cded6237b2ed91e3f721fcb1971174494d6493c9d5c3460be31201e69fedaa0ee"
    "e8b9997f5c7c2999fdafe593253cd654af4dfad71427a0aeb3fee9232f8af2211f9ee491c5b10becb5563bfc"
    "1e6f93427ecbc8fe2955e5cd8e46dc8ed4b7c2764d2a5a4d767706f85d8690024ad6bda3401be9c8cbccc935"
    "f6cd1f61226ae15338ae1a34004d33ba0d246ac04c81b1baf23e3bf9eef5f79f2b4934af87f5520b69b94b0d"
    "982e85bb5528b52ffd2014a10000b672a872637acd7466fcb60e0e8ff18463b0e4b228b52ffd203ce10100ba"
    "29703474f064ac68f700f5b02b3dc666f45bdeaa2ccaedcd2b5157410e4dee4af2b34f430a073447de636c0e"
    "806c957ba684d6431fb5ead7424d0928b52ffdd15e46070a11bffca320000080ffe15d024c5848f23d1fa6f7"
    "361d7f618d1532e70e20e2a6668de7f47e8467e546d53ec8e2a1257bdb256c9b3e4fbb498146ef7030cbf953"
    "7252dccead28b52ffd2050810200d764b6a32fbb09adeae109c4a997203975352b878b145c8a42d884cf4cfd"
    "a72d8e1d5dd92589082d852a7122873ee805add58942167a385286195c679f9c6994e45b8ab1098012070961"
    "f37de436ddfd")


def test_spz_v4_corrupt_zstd_frame_is_bad_input(tmp_path):
    from gsverse_format.errors import FormatError
    from gsverse_format.io.splatformats import decode

    path = tmp_path / "frame.spz"
    path.write_bytes(SPZ_V4_MEMORYERROR)
    with pytest.raises(FormatError, match="broken zstd stream"):
        decode("spz", path)
