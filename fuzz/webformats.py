"""Structure-aware fuzzing of the web splat formats and of the JS reader.

Kinds of input (pseudo-suffixes: the file is written as ``input`` + the kind, so that the
registry still picks the reader by its real suffix):

* ``.spz``: version 2 (one gzip stream: the payload is inflated, edited and deflated again)
  and version 4 (header, extension records, table of ``(compressed, size)`` uint64 pairs,
  zstd streams): header fields (version, count, SH degree, fractional bits, flags, stream
  count, table offset), table entries (0, off by one, 2³², 2⁶³, the file's size), streams
  replaced by compressed zeros of a large declared size, extension records (huge lengths,
  thousands of empty ones, the coordinate-system record with any value);
* ``.sog``: zip members (``meta.json`` edited as JSON — numbers, keys, types, nesting —,
  members dropped, duplicated, renamed, stored with another compression method) and the
  WebP headers inside (RIFF size, chunk tag, the VP8L width and height bits);
* ``.ksplat``: the main and section header fields at their documented offsets (version,
  section count, splat counts, compression level, bucket sizes and counts, quantization
  range, SH degree) and the bucket tables;
* ``.compressed.ply``: the PLY header (element counts, property types, a chunk bound made a
  list) and the chunk bounds (NaN, infinities, min above max);
* ``.js.glb``: the glTF mutations of :mod:`fuzz.mutations`, read by the web plugin's reader
  (``plugins/web``) in one long-lived Node process (:mod:`fuzz.js_worker`).

About half of the inputs of each kind get a structure-aware edit, the rest a generic byte
edit (:func:`fuzz.mutations.mutate`).
"""
from __future__ import annotations

import gzip
import importlib.util
import io
import lzma
import os
import pathlib
import random
import struct
import tempfile
import warnings
import zipfile
import zlib

from fuzz.mutations import INTERESTING_U32, _mutate_json, _mutate_ply_header, mutate

__all__ = ["WEB_KINDS", "web_seeds", "mutate_any", "web_targets", "JS_KIND"]

#: The kind whose inputs go to the JS reader (GLB and glTF bytes).
JS_KIND = ".js.glb"
#: The web kinds and the reader of each (a key of ``io.splatformats.DECODERS``; None: JS).
WEB_KINDS = {".spz": "spz", ".sog": "sog", ".ksplat": "ksplat",
             ".compressed.ply": "compressed-ply", JS_KIND: None}
_ROOT = pathlib.Path(__file__).resolve().parents[1]
INTERESTING_U64 = (0, 1, 2, 8, 2 ** 31, 2 ** 32, 2 ** 32 + 1, 2 ** 40, 2 ** 63 - 1, 2 ** 63,
                   2 ** 64 - 1)


def _writers():
    """The test suite's writers of web formats (``tests/splat_writers.py``: one writer of
    each format, shared with the format tests)."""
    spec = importlib.util.spec_from_file_location("splat_writers",
                                                  _ROOT / "tests" / "splat_writers.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _spz_v4(n: int, degree: int, rng: random.Random) -> bytes:
    import zstandard

    sizes = (9 * n, n, 3 * n, 3 * n, 4 * n, 3 * n * ((degree + 1) ** 2 - 1))
    streams = [bytes(rng.randrange(256) for _ in range(s)) for s in sizes if s]
    packed = [zstandard.ZstdCompressor(level=3).compress(s) for s in streams]
    ext = struct.pack("<III", 0xADBE0003, 4, 1)
    toc = 32 + len(ext)
    head = struct.pack("<4sIIBBBBI", b"NGSP", 4, n, degree, 12, 2, len(packed), toc)
    head += b"\0" * (32 - len(head))
    table = b"".join(struct.pack("<QQ", len(p), len(s)) for p, s in zip(packed, streams))
    return head + ext + table + b"".join(packed)


def _compressed_ply(n: int, degree: int, rng: random.Random) -> bytes:
    chunks = (n + 255) // 256
    bounds = ["min_x", "min_y", "min_z", "max_x", "max_y", "max_z", "min_scale_x",
              "min_scale_y", "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z",
              "min_r", "min_g", "min_b", "max_r", "max_g", "max_b"]
    rest = 3 * ((degree + 1) ** 2 - 1)
    head = (["ply", "format binary_little_endian 1.0", f"element chunk {chunks}"]
            + [f"property float {b}" for b in bounds]
            + [f"element vertex {n}"]
            + [f"property uint {p}" for p in ("packed_position", "packed_rotation",
                                               "packed_scale", "packed_color")])
    if rest:
        head += [f"element sh {n}"] + [f"property uchar f_rest_{i}" for i in range(rest)]
    body = b"".join(struct.pack("<18f", -1, -1, -1, 1, 1, 1, -5, -5, -5, -1, -1, -1,
                                0, 0, 0, 1, 1, 1) for _ in range(chunks))
    body += b"".join(struct.pack("<4I", *(rng.getrandbits(32) for _ in range(4)))
                     for _ in range(n))
    body += bytes(rng.randrange(256) for _ in range(n * rest))
    return ("\n".join(head) + "\nend_header\n").encode() + body


def web_seeds() -> list[tuple[str, bytes]]:
    """(kind, bytes) of small valid files of each web kind; the JS kind's seeds are the glTF
    seeds of :func:`fuzz.seeds.seeds`, added by the caller."""
    from gsverse_format.examples import example_mesh, example_splats
    from gsverse_format.model import SplatCloud

    w = _writers()
    rng = random.Random(7)
    mesh = example_mesh(subdivisions=0)
    out: list[tuple[str, bytes]] = []
    with tempfile.TemporaryDirectory() as tmp:
        def written(name, write, *args, **kw) -> bytes:
            path = os.path.join(tmp, name)
            write(*args, path, **kw)
            return pathlib.Path(path).read_bytes()

        for degree in (0, 1):
            cloud = example_splats(mesh, 20, seed=3 + degree)     # SH degree 1
            if degree == 0:
                cloud = SplatCloud(cloud.means, cloud.rotations, cloud.scales,
                                   cloud.opacities, cloud.sh[:, :1])
            out.append((".spz", _no_mtime(written("a.spz", w.write_spz_v2, cloud))))
            out.append((".spz", _spz_v4(20, degree, rng)))
            out.append((".sog", _fixed_dates(written("a.sog", w.write_sog, cloud,
                                                     version=2 - degree))))
            out.append((".ksplat", written("a.ksplat", w.write_ksplat, cloud, level=0)))
            out.append((".ksplat", written("b.ksplat", w.write_ksplat, cloud, level=1 + degree,
                                           bucket_capacity=8)))
            out.append((".compressed.ply", _compressed_ply(300 if degree else 20, degree, rng)))
    out.append((".spz", written_v2_with_records(w, example_splats(mesh, 5, seed=9))))
    return out


def _no_mtime(stream: bytes) -> bytes:
    """The gzip stream written again without its time stamp (seeds the same in every run)."""
    return gzip.compress(gzip.decompress(stream), mtime=0)


def _fixed_dates(archive: bytes) -> bytes:
    """The zip archive with every member dated 2020-01-01 (seeds the same in every run)."""
    out = io.BytesIO()
    with zipfile.ZipFile(io.BytesIO(archive)) as src, \
            zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as dst:
        for info in src.infolist():
            fixed = zipfile.ZipInfo(info.filename, date_time=(2020, 1, 1, 0, 0, 0))
            fixed.compress_type = info.compress_type
            dst.writestr(fixed, src.read(info))
    return out.getvalue()


def written_v2_with_records(w, cloud) -> bytes:
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "r.spz")
        w.write_spz_v2(cloud, path, extensions=w.spz_coordinate_system(2)
                       + struct.pack("<II", 0x1234, 3) + b"abc")
        return _no_mtime(pathlib.Path(path).read_bytes())


# ---------------------------------------------------------------------------- mutations

def _u32(rng: random.Random, data: bytes, extra: tuple = ()) -> int:
    return rng.choice(INTERESTING_U32 + (len(data), len(data) + 1) + extra) & 0xFFFFFFFF


def _records(rng: random.Random) -> bytes:
    """spz extension records: few or many, empty or with lying lengths."""
    choice = rng.randrange(4)
    if choice == 0:
        return struct.pack("<II", rng.getrandbits(32), 0) * rng.choice((2, 1025, 100000))
    if choice == 1:
        return struct.pack("<II", rng.getrandbits(32), rng.choice(INTERESTING_U32))
    if choice == 2:
        return struct.pack("<III", 0xADBE0003, 4, rng.choice((0, 1, 2, 3, 4, 5, 6, 7, 8, 255,
                                                             2 ** 32 - 1)))
    return struct.pack("<II", 0xADBE0003, rng.choice((0, 3, 5, 8))) + b"\1" * rng.randrange(9)


def _mutate_spz_v2(rng: random.Random, data: bytes, pool: list) -> bytes:
    try:   # at most 16 MiB: a mutated stream may be a bomb
        payload = bytearray(zlib.decompressobj(31).decompress(data, 2 ** 24))
    except zlib.error:
        return mutate(rng, ".spz", data, pool)
    if len(payload) < 16:
        return data
    r = rng.randrange(6)
    if r == 0:   # header field: version, count, degree, fractional bits, flags
        field = rng.choice(((4, "<I"), (8, "<I"), (12, "<B"), (13, "<B"), (14, "<B")))
        value = rng.choice(INTERESTING_U32 + (len(payload), 2, 3, 4)) % (
            256 if field[1] == "<B" else 2 ** 32)
        struct.pack_into(field[1], payload, field[0], value)
    elif r == 1:   # extension records after the attributes
        payload[14] |= 2
        payload += _records(rng)
    elif r == 2:
        del payload[rng.randrange(16, len(payload) + 1):]
    elif r == 3:   # more splats than the data holds, data of zeros
        struct.pack_into("<I", payload, 8, rng.choice((10 ** 6, 10 ** 7, 2 ** 31)))
        payload += bytes(rng.choice((0, 1000, 10 ** 6)))
    else:
        return gzip.compress(bytes(payload), mtime=0)[:rng.choice((None, len(data) // 2))] \
            if r == 4 else mutate(rng, ".spz", gzip.compress(bytes(payload), mtime=0), pool)
    return gzip.compress(bytes(payload), compresslevel=1, mtime=0)


def _mutate_spz_v4(rng: random.Random, data: bytes, pool: list) -> bytes:
    buf = bytearray(data)
    if len(buf) < 32:
        return data
    count, toc = buf[15], struct.unpack_from("<I", buf, 16)[0]
    r = rng.randrange(6)
    if r == 0:   # header fields
        field = rng.choice(((4, "<I"), (8, "<I"), (12, "<B"), (13, "<B"), (14, "<B"),
                            (15, "<B"), (16, "<I")))
        value = rng.choice(INTERESTING_U32 + (len(buf), toc + 8, 0, 5, 6, 7))
        struct.pack_into(field[1], buf, field[0], value % (256 if field[1] == "<B" else 2 ** 32))
    elif r == 1 and count and toc + 16 * count <= len(buf):   # a table entry
        pos = toc + 16 * rng.randrange(count) + rng.choice((0, 8))
        old = struct.unpack_from("<Q", buf, pos)[0]
        value = rng.choice(INTERESTING_U64 + (old + 1, max(old - 1, 0), len(buf), 2 * old))
        struct.pack_into("<Q", buf, pos, value & (2 ** 64 - 1))
    elif r == 2 and count and toc + 16 * count <= len(buf):   # a stream of zstd zeros
        import zstandard

        size = rng.choice((10 ** 6, 10 ** 7, 2 ** 27))
        zeros = zstandard.ZstdCompressor(level=1).compress(bytes(size))
        table = bytearray(buf[toc:toc + 16 * count])
        struct.pack_into("<QQ", table, 0, len(zeros), size)
        first = struct.unpack_from("<Q", buf, toc)[0]
        start = toc + 16 * count
        return bytes(buf[:toc]) + bytes(table) + zeros + bytes(buf[start + first:])
    elif r == 3:   # extension records before the table
        records = _records(rng)
        struct.pack_into("<I", buf, 16, (toc + len(records)) & 0xFFFFFFFF)
        buf[14] |= 2
        return bytes(buf[:toc]) + records + bytes(buf[toc:])
    else:
        return mutate(rng, ".spz", bytes(buf), pool)
    return bytes(buf)


def _mutate_webp(rng: random.Random, data: bytes) -> bytes:
    buf = bytearray(data)
    if len(buf) < 30:
        return data
    r = rng.randrange(4)
    if r == 0:   # VP8L width-1 / height-1 (14 bits each after the 0x2f signature byte)
        bits = struct.unpack_from("<I", buf, 21)[0]
        w, h = rng.choice((0, 1, 8191, 16383)), rng.choice((0, 1, 8191, 16383))
        bits = (bits & ~0x0FFFFFFF) | w | (h << 14)
        struct.pack_into("<I", buf, 21, bits)
    elif r == 1:   # RIFF size or chunk size
        struct.pack_into("<I", buf, rng.choice((4, 16)), _u32(rng, data))
    elif r == 2:   # chunk tag
        buf[12:16] = rng.choice((b"VP8 ", b"VP8X", b"ALPH", b"XXXX"))
    else:
        del buf[rng.randrange(12, len(buf)):]
    return bytes(buf)


def _mutate_sog(rng: random.Random, data: bytes, pool: list) -> bytes:
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            if sum(i.file_size for i in archive.infolist()) > 2 ** 24:
                return mutate(rng, ".sog", data, pool)
            members = [(i.filename, archive.read(i)) for i in archive.infolist()]
    except (zipfile.BadZipFile, OSError, ValueError, EOFError, NotImplementedError,
            RuntimeError, zlib.error, lzma.LZMAError):
        return mutate(rng, ".sog", data, pool)
    if not members:
        return data
    r = rng.randrange(7)
    k = rng.randrange(len(members))
    method = zipfile.ZIP_DEFLATED
    if r <= 2:   # meta.json
        for i, (name, body) in enumerate(members):
            if name == "meta.json":
                if r == 2 and rng.random() < 0.3:
                    body = b"[" * rng.choice((65, 1000, 100000)) + body
                else:
                    try:
                        body = _mutate_json(rng, body)
                    except RecursionError:   # an earlier input nested it deeply: keep it
                        pass
                members[i] = (name, body)
    elif r == 3:   # a WebP header
        name, body = members[k]
        members[k] = (name, _mutate_webp(rng, body))
    elif r == 4:   # drop, duplicate or rename a member
        name, body = members[k]
        choice = rng.randrange(3)
        if choice == 0:
            del members[k]
        elif choice == 1:
            members.append((name, body))
        else:
            members[k] = (rng.choice(("../" + name, "/" + name, name.upper(), "")), body)
    elif r == 5:   # another compression method
        method = rng.choice((zipfile.ZIP_STORED, zipfile.ZIP_BZIP2, zipfile.ZIP_LZMA))
    else:
        return mutate(rng, ".sog", data, pool)
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", method) as archive, warnings.catch_warnings():
        warnings.simplefilter("ignore")   # a duplicated member is the point
        for name, body in members:
            if name:   # a fixed date: the same mutation gives the same bytes
                info = zipfile.ZipInfo(name, date_time=(2020, 1, 1, 0, 0, 0))
                info.compress_type = method
                archive.writestr(info, body)
    return out.getvalue()


#: .ksplat header fields: (offset, format) in the main header, then in the section header.
_KSPLAT_MAIN = ((0, "<B"), (1, "<B"), (4, "<I"), (8, "<I"), (12, "<I"), (16, "<I"), (20, "<H"),
                (36, "<f"), (40, "<f"))
_KSPLAT_SECTION = ((0, "<I"), (4, "<I"), (8, "<I"), (12, "<I"), (16, "<f"), (20, "<H"),
                   (24, "<I"), (32, "<I"), (36, "<I"), (40, "<H"))


def _mutate_ksplat(rng: random.Random, data: bytes, pool: list) -> bytes:
    buf = bytearray(data)
    if len(buf) < 4096 + 1024:
        return mutate(rng, ".ksplat", data, pool)
    r = rng.randrange(4)
    if r <= 1:
        base, fields = (0, _KSPLAT_MAIN) if r == 0 else (4096, _KSPLAT_SECTION)
        off, fmt = rng.choice(fields)
        if fmt == "<f":
            value = rng.choice((0.0, -1.0, 1e-30, 1e30, float("nan"), float("inf")))
        else:
            value = rng.choice(INTERESTING_U32 + (3, 5)) % {"<B": 256, "<H": 65536}.get(fmt,
                                                                                    2 ** 32)
        struct.pack_into(fmt, buf, base + off, value)
    elif r == 2:   # the bucket tables right after the section header
        if len(buf) >= 5124:
            struct.pack_into("<I", buf, 5120, _u32(rng, data))
    else:
        return mutate(rng, ".ksplat", data, pool)
    return bytes(buf)


def _mutate_compressed_ply(rng: random.Random, data: bytes, pool: list) -> bytes:
    end = data.find(b"end_header\n")
    if end < 0:
        return mutate(rng, ".ply", data, pool)
    r = rng.randrange(4)
    if r == 0:
        return _mutate_ply_header(rng, data)
    if r == 1:   # a chunk bound, or a packed property, made a list or another type
        head = data[:end].split(b"\n")
        props = [i for i, line in enumerate(head) if line.startswith(b"property ")]
        if props:
            i = rng.choice(props)
            name = head[i].split()[-1]
            head[i] = b"property " + rng.choice((b"list uchar float", b"list uint uint",
                                                  b"double", b"uchar", b"int")) + b" " + name
        return b"\n".join(head) + data[end:]
    if r == 2:   # chunk bounds
        body = bytearray(data[end + 11:])
        if len(body) >= 72:
            struct.pack_into("<f", body, 4 * rng.randrange(18),
                             rng.choice((float("nan"), float("inf"), -float("inf"), 1e38,
                                         -1e38, 100.0)))
        return data[:end + 11] + bytes(body)
    return mutate(rng, ".ply", data, pool)


def mutate_any(rng: random.Random, suffix: str, data: bytes,
               pool: list[tuple[str, bytes]]) -> bytes:
    """One mutation of ``data`` of kind ``suffix``: structure-aware for about half of the web
    kinds' inputs, else :func:`fuzz.mutations.mutate`."""
    if suffix == JS_KIND:
        return mutate(rng, ".glb" if data[:4] == b"glTF" else ".gltf", data, pool)
    if suffix not in WEB_KINDS or rng.random() < 0.4:
        return mutate(rng, suffix, data, pool)
    if suffix == ".spz":
        return (_mutate_spz_v4 if data[:4] == b"NGSP" else _mutate_spz_v2)(rng, data, pool)
    return {".sog": _mutate_sog, ".ksplat": _mutate_ksplat,
            ".compressed.ply": _mutate_compressed_ply}[suffix](rng, data, pool)


# ---------------------------------------------------------------------------- targets

def web_targets() -> dict[str, list]:
    """Target name and function per web kind: the format's decoder with the asset built from
    it (what ``gsverse-convert`` reads), and ``read`` (the registry's choice by suffix and
    content). The JS kind's target is marked by ``None`` (run by :mod:`fuzz.js_worker`)."""
    from gsverse_format.api import read
    from gsverse_format.io.splatformats import decode

    def decoder(name: str):
        def run(path: str):
            return decode(name, path).asset(os.path.basename(path))
        return run

    out: dict[str, list] = {}
    for kind, name in WEB_KINDS.items():
        if name is None:
            out[kind] = [("js_reader", None)]
        else:
            out[kind] = [(f"read_{name.replace('-', '_')}", decoder(name)), ("read", read)]
    return out

