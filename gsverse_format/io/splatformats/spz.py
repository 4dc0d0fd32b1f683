"""``.spz``: Niantic's compressed splat format, versions 2 and 3 (one gzip stream).

The gzip stream holds a 16-byte header — magic ``NGSP`` (0x5053474e), version, splat count,
SH degree (0..3), fractional bits, flags (bit 0: antialiased, bit 1: extensions follow),
reserved — then the attributes, each for all splats in turn:

============  ===========  ===============================================================
positions     3 × 3 bytes  24-bit signed fixed point, ``value / 2^fractional_bits``
alphas        1 byte       ``opacity = byte / 255`` (the file stores sigmoid(logit) · 255)
colours       3 bytes      ``f_dc = (byte / 255 − 0.5) / 0.15`` (spz's own colour scale)
scales        3 bytes      ``log-scale = byte / 16 − 10``, ``scale = exp(log-scale)``
rotations     3 bytes v2   (x, y, z) of the unit quaternion with w ≥ 0: ``byte / 127.5 − 1``,
                           ``w = sqrt(1 − x² − y² − z²)``
              4 bytes v3   "smallest three": the top 2 bits index the largest component
                           (rebuilt from the unit norm); three 10-bit fields (sign bit, 9-bit
                           magnitude ``m``: ``±m / 511 · √½``) give the others, in
                           x, y, z, w order, lowest bits last
sh            3 bytes per  coefficient-major, channels interleaved (coefficient 1..K−1,
              coefficient  then r, g, b): ``(byte − 128) / 128``
============  ===========  ===============================================================

Frame: the spz specification stores splats in the RUB frame (+X right, +Y up, +Z back); spz's
own PLY converter flips y and z of a 3DGS PLY (+Y down, +Z forward) into it. The registry's
frame ``spz-rub`` takes RUB to the glTF frame so that an spz file and the PLY it was made from
land in the same place (180° about Y; see :data:`gsverse_format.io.registry.FRAMES`).
PlayCanvas splat-transform 3.x writes the PLY's coordinates unchanged into its spz files
(no conversion, and nothing in the file says so): such a file comes out turned 180° about X
— read it with ``--no-frame-change`` and the PLY frame in mind, or convert it from the PLY.

Version 4 (the default of splat-transform 3.x) stores the same attributes, uncompressed
header first: a 32-byte header (magic, version, count, SH degree, fractional bits, flags,
stream count, table offset), optional extensions, a table of ``(compressed, uncompressed)``
uint64 sizes per stream at the table offset, then each non-empty attribute as its own zstd
stream in the order above (rotations as in v3). Decoding zstd needs the ``zstandard``
package (a dependency: Python's standard library has no zstd before 3.14).

A file whose ``SPZ_ADOBE_coordinate_system`` extension says its splats are stored in another
right-handed frame (RDF, the PLY's, for example) is turned into RUB on reading, so that every
spz file comes out of the reader in RUB; a left-handed storage frame is refused.

Not kept: the antialiased flag (the model renders every splat with the default kernel) and
other extensions (a note says how many records were skipped).
The unreleased version 1 (float16 positions) is refused.
"""
from __future__ import annotations

import os

import numpy as np

from ...errors import FormatError
from ...transform import rotate_splats
from ..spz_stream import (COLOR_SCALE, HEADER_BYTES, MAGIC, SpzHeader, attribute_sizes, decode,
                          parse_header, split_stream, unpack_smallest_three)
from .common import Decoded, splat_cloud
from .container import (INFLATION_SLACK, MAX_INFLATION_RATIO, Fields, gunzip, inflation_limit,
                        read_bytes)

__all__ = ["MAGIC", "COLOR_SCALE", "COORDINATE_SYSTEMS", "read_spz", "storage_to_rub",
           "unpack_smallest_three_spz"]

#: The version-3 rotation decoder under its earlier name.
unpack_smallest_three_spz = unpack_smallest_three
#: Extension records (other than the coordinate system) skipped at most; real files hold a
#: handful, and each costs a Python loop turn.
MAX_EXTENSION_RECORDS = 1024
V4_HEADER_BYTES = 32


def _legacy_streams(raw: bytes, path: str) -> tuple[SpzHeader, dict[str, np.ndarray], bytes]:
    """A v2/v3 file: its header, each attribute's bytes and the extension records."""
    data = gunzip(raw, path)
    if len(data) < 4 or data[:4] != b"NGSP":
        raise FormatError("not an spz file (no NGSP magic in the gzip stream)", path)
    header = parse_header(data, path)
    parts, extensions = split_stream(data, header, path)
    return header, parts, extensions


def _sizes(fields: dict[str, int], path: str) -> dict[str, int]:
    if fields["degree"] > 3:
        raise FormatError(f"SH degree {fields['degree']} is not supported (0..3)", path)
    if fields["frac"] > 24:
        raise FormatError(f"{fields['frac']} fractional bits is more than the 24 a position "
                          "has", path)
    return attribute_sizes(fields["version"], fields["n"], fields["degree"])


def _v4_streams(raw: bytes, path: str) -> tuple[dict[str, int], dict[str, bytes]]:
    """A v4 file: header fields and each attribute's bytes, inflated from zstd."""
    head = Fields(raw, path, "spz v4 header")
    fields = {"version": head.u32(4), "n": head.u32(8), "degree": head.u8(12),
              "frac": head.u8(13), "flags": head.u8(14)}
    if fields["version"] != 4:
        raise FormatError(f"spz version {fields['version']} is not supported (2, 3 and 4 "
                          "are)", path)
    streams, toc = head.u8(15), head.u32(16)
    sizes = _sizes(fields, path)
    names = [k for k, v in sizes.items() if v]
    if streams != len(names):
        raise FormatError(f"{streams} streams for the {len(names)} non-empty attributes", path)
    if toc < V4_HEADER_BYTES or toc + 16 * streams > len(raw):
        raise FormatError("the stream table lies outside the file", path)
    table = np.frombuffer(raw, "<u8", 2 * streams, toc).reshape(streams, 2)
    try:
        import zstandard
    except ImportError:
        raise FormatError("spz version 4 needs the zstandard package: pip install zstandard",
                          path) from None
    offset = toc + 16 * streams
    declared = int(table[:, 1].sum()) if streams else 0
    if declared > inflation_limit(len(raw)):
        raise FormatError(f"{fields['n']} splats declare {declared} bytes of streams, more than "
                          f"{inflation_limit(len(raw))} ({MAX_INFLATION_RATIO}x the file's "
                          f"{len(raw)} bytes plus {INFLATION_SLACK >> 20} MiB)", path)
    out: dict[str, bytes] = {}
    for name, (packed, size) in zip(names, table.tolist()):
        if size != sizes[name] or packed > len(raw) - offset:
            raise FormatError(f"the {name} stream does not fit the header's {fields['n']} "
                              "splats", path)
        try:
            out[name] = zstandard.ZstdDecompressor().decompress(
                raw[offset:offset + packed], max_output_size=size)
        except zstandard.ZstdError as exc:
            raise FormatError(f"broken zstd stream of {name} ({exc})", path) from None
        except MemoryError:   # zstandard's answer to some corrupt frame headers; the size
            # it may inflate to is bounded above, so this is the frame, not the machine
            raise FormatError(f"broken zstd stream of {name} (corrupt frame header)",
                              path) from None
        if len(out[name]) != size:
            raise FormatError(f"the {name} stream inflates to {len(out[name])} bytes, not "
                              f"{size}", path)
        offset += packed
    for name in sizes:
        out.setdefault(name, b"")
    out["extensions"] = raw[V4_HEADER_BYTES:toc]
    return fields, out


#: The coordinate systems of ``SPZ_ADOBE_coordinate_system``, by their enum value (1..16):
#: the letters give the directions of the x, y, z axes (Right/Left, Up/Down, Back/Front).
COORDINATE_SYSTEMS = ("LDB", "RDB", "LUB", "RUB", "LDF", "RDF", "LUF", "RUF",
                      "LFD", "RFD", "LFU", "RFU", "LBD", "RBD", "LBU", "RBU")
_EXT_COORDINATE_SYSTEM = 0xADBE0003
_DIRECTION = {"R": (1, 0, 0), "L": (-1, 0, 0), "U": (0, 1, 0), "D": (0, -1, 0),
              "B": (0, 0, 1), "F": (0, 0, -1)}


def storage_to_rub(name: str) -> np.ndarray:
    """The matrix taking coordinates in the named frame (``"RDF"``, ...) to RUB: its columns
    are the frame's axes written in RUB (a rotation, or a reflection for left-handed frames)."""
    return np.array([_DIRECTION[letter] for letter in name], np.float64).T


def _extensions(data: bytes, path: str) -> tuple[str | None, int]:
    """The storage frame an ``SPZ_ADOBE_coordinate_system`` record declares (None without
    one) and how many other extension records there are. Records: type (u32), byte length
    (u32), payload."""
    storage, skipped, offset = None, 0, 0
    while len(data) - offset >= 8:
        if skipped >= MAX_EXTENSION_RECORDS:
            raise FormatError(f"more than {MAX_EXTENSION_RECORDS} spz extension records",
                              path)
        kind, length = np.frombuffer(data, "<u4", 2, offset).tolist()
        offset += 8
        if length > len(data) - offset:
            raise FormatError(f"an spz extension record of {length} bytes runs past the end",
                              path)
        if kind == _EXT_COORDINATE_SYSTEM and length >= 4:
            code = int(np.frombuffer(data, "<u4", 1, offset)[0])
            if code > len(COORDINATE_SYSTEMS):
                raise FormatError(f"unknown coordinate system {code} in "
                                  "SPZ_ADOBE_coordinate_system", path)
            storage = COORDINATE_SYSTEMS[code - 1] if code else None
        else:
            skipped += 1
        offset += length
    return storage, skipped


def read_spz(path: str | os.PathLike[str]) -> Decoded:
    """The splats of an spz file (v2, v3, v4), in the file's frame (RUB)."""
    path = os.fspath(path)
    raw = read_bytes(path)
    if raw[:4] == b"NGSP":
        fields, streams = _v4_streams(raw, path)
        extensions = streams.pop("extensions")
        header = SpzHeader(4, fields["n"], fields["degree"], fields["frac"], fields["flags"])
        parts = {k: np.frombuffer(v, np.uint8) for k, v in streams.items()}
        stored = {"header and table": 32}
    elif raw[:2] == b"\x1f\x8b":
        header, parts, extensions = _legacy_streams(raw, path)
        stored = {"header": HEADER_BYTES}
    else:
        raise FormatError("not an spz file (neither a gzip stream nor an NGSP header)", path)
    sizes = attribute_sizes(header.version, header.count, header.degree)
    if not header.flags & 2:
        extensions = b""
    arrays = decode(header, parts)
    notes = []
    if header.flags & 1:
        notes.append("the file is marked antialiased; the splats are read with the default "
                     "kernel")
    storage, skipped = _extensions(extensions, path)
    if skipped:
        notes.append(f"{skipped} spz extension record(s) not read (only "
                     "SPZ_ADOBE_coordinate_system is)")
    cloud = splat_cloud(arrays.means, arrays.rotations[:, [3, 0, 1, 2]], arrays.scales,
                        arrays.opacities, arrays.sh, path)
    if storage not in (None, "RUB"):
        to_rub = storage_to_rub(storage)
        if np.linalg.det(to_rub) < 0:
            raise FormatError(f"the splats are stored in the left-handed {storage} frame "
                              "(SPZ_ADOBE_coordinate_system); only right-handed storage "
                              "frames are read", path)
        cloud = rotate_splats(cloud, to_rub)
        notes.append(f"stored in {storage} (SPZ_ADOBE_coordinate_system), turned into RUB")
    return Decoded(cloud, f"spz v{header.version}",
                   {"file": len(raw), **stored, **{k: v for k, v in sizes.items() if v}},
                   notes)
