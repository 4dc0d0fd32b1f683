"""The SPZ stream: Niantic's quantized splat attributes, versions 2 and 3, in one gzip member.

This is the byte layer shared by the ``.spz`` file format (:mod:`.splatformats.spz`) and the
glTF extension ``KHR_gaussian_splatting_compression_spz_2`` (:mod:`.gltf.spz`); it knows
nothing of files or of glTF. The inflated stream is a 16-byte header — magic ``NGSP``
(0x5053474e), version, splat count (u32), SH degree, fractional bits, flags, reserved (u8
each), little-endian — then each attribute for all splats in turn:

============  =================  ============================================================
positions     3 × 3 bytes        24-bit two's complement fixed point, ``value = q / 2^fb``
alphas        1 byte             ``opacity = byte / 255``
colours       3 bytes            ``f_dc = (byte / 255 − 0.5) / 0.15``
scales        3 bytes            ``scale = exp(byte / 16 − 10)``
rotations     3 bytes (v2)       x, y, z of the quaternion with w ≥ 0: ``byte / 127.5 − 1``,
                                 ``w = sqrt(max(0, 1 − x² − y² − z²))``
              4 bytes (v3)       "smallest three", one u32: bits 30–31 the index (x, y, z, w =
                                 0..3) of the largest component, rebuilt as
                                 ``sqrt(max(0, 1 − Σ others²))``; the other three in index
                                 order, the last one in the lowest 10 bits, each a sign bit
                                 (bit 9) and a magnitude ``m`` (bits 0–8): ``±m / 511 · √½``
sh            3 bytes per        coefficient ``k = 1 .. (d+1)² − 1``, channels interleaved
              coefficient        (byte ``3(k − 1) + c`` of a splat): ``(byte − 128) / 128``
============  =================  ============================================================

Coordinates are those of the producer's frame (RUB by the SPZ convention); this layer does not
turn them. :func:`encode` writes version 3 with the quantization of the spz library's
defaults (SH degree 1 kept to 5 bits, degrees 2 and 3 to 4 bits), rounding to nearest; the
largest error each attribute gets is :func:`quantization_bounds`.
"""
from __future__ import annotations

import gzip
import math
import struct
import zlib
from dataclasses import dataclass

import numpy as np

from ..errors import FormatError, UsageError

__all__ = ["MAGIC", "HEADER_BYTES", "COLOR_SCALE", "SH_BITS", "DEFAULT_FRACTIONAL_BITS",
           "SpzHeader", "SpzArrays", "attribute_sizes", "stream_bytes", "parse_header",
           "split_stream", "decode", "encode", "inflate_bounded", "choose_fractional_bits",
           "quantization_bounds", "unpack_smallest_three"]

MAGIC = 0x5053474E
HEADER_BYTES = 16
#: spz's scale of the DC colour: ``byte = 255 · (0.5 + COLOR_SCALE · f_dc)``.
COLOR_SCALE = 0.15
#: Bits :func:`encode` keeps of each SH coefficient, by degree 1, 2, 3 (the spz library's
#: defaults): a coefficient is rounded to the nearest multiple of ``2^(8 − bits)`` codes.
SH_BITS = (5, 4, 4)
#: Fractional bits of a position when the coordinates allow (1/4096 of a unit; the spz
#: library's default): up to ±2048 units.
DEFAULT_FRACTIONAL_BITS = 12
#: Largest magnitude of a 24-bit two's complement position code.
_FIXED_MAX = (1 << 23) - 1
_SQRT1_2 = 0.7071067811865476
#: Smallest and largest scale a byte holds: ``exp(−10)`` and ``exp(255/16 − 10)``.
SCALE_RANGE = (math.exp(-10.0), math.exp(255 / 16 - 10.0))


@dataclass(frozen=True)
class SpzHeader:
    """The 16-byte header of an inflated stream."""

    version: int
    count: int
    degree: int
    fractional_bits: int
    flags: int

    @property
    def rotation_bytes(self) -> int:
        return 4 if self.version >= 3 else 3


@dataclass
class SpzArrays:
    """Decoded attributes in the stream's frame: means (N, 3), quaternions (N, 4) x, y, z, w,
    linear scales (N, 3), opacities (N,) in float64, and SH (N, K, 3) with ``f_dc`` first in
    float32 (the coefficients above degree 0 are exact in binary32; ``f_dc`` is rounded once
    from binary64). :func:`encode` takes float32 or float64."""

    means: np.ndarray
    rotations: np.ndarray
    scales: np.ndarray
    opacities: np.ndarray
    sh: np.ndarray


def attribute_sizes(version: int, count: int, degree: int) -> dict[str, int]:
    """Bytes of each attribute of ``count`` splats, in stream order."""
    rest = (degree + 1) ** 2 - 1
    return {"positions": 9 * count, "alphas": count, "colours": 3 * count,
            "scales": 3 * count, "rotations": (4 if version >= 3 else 3) * count,
            "sh": 3 * rest * count}


def stream_bytes(version: int, count: int, degree: int) -> int:
    """Length of the inflated stream (header and attributes, no extension records)."""
    return HEADER_BYTES + sum(attribute_sizes(version, count, degree).values())


def parse_header(data: bytes, where: str) -> SpzHeader:
    """The header of an inflated stream; :class:`FormatError` for a missing magic, a version
    other than 2 or 3, an SH degree above 3 or more than 24 fractional bits."""
    if len(data) < HEADER_BYTES:
        raise FormatError(f"the SPZ stream holds {len(data)} bytes, less than its "
                          f"{HEADER_BYTES}-byte header", where)
    magic, version, count, degree, frac, flags, _ = struct.unpack_from("<IIIBBBB", data, 0)
    if magic != MAGIC:
        raise FormatError("not an SPZ stream (no NGSP magic)", where)
    if version not in (2, 3):
        raise FormatError(f"SPZ version {version} in a gzip stream is not supported "
                          "(versions 2 and 3 are)", where)
    if degree > 3:
        raise FormatError(f"SPZ SH degree {degree} is not supported (0..3)", where)
    if frac > 24:
        raise FormatError(f"{frac} fractional bits is more than the 24 a position has", where)
    return SpzHeader(version, count, degree, frac, flags)


def split_stream(data: bytes, header: SpzHeader, where: str) -> tuple[dict[str, np.ndarray],
                                                                      bytes]:
    """Each attribute's bytes (uint8 views of ``data``, no copy) and what follows them (the
    extension records, when flag bit 1 is set). :class:`FormatError` for a short stream."""
    sizes = attribute_sizes(header.version, header.count, header.degree)
    need = HEADER_BYTES + sum(sizes.values())
    if len(data) < need:
        raise FormatError(f"truncated SPZ stream: {header.count} splats need {need} bytes, the "
                          f"stream holds {len(data)}", where)
    parts: dict[str, np.ndarray] = {}
    offset = HEADER_BYTES
    for name, size in sizes.items():
        parts[name] = np.frombuffer(data, np.uint8, size, offset)
        offset += size
    return parts, bytes(data[offset:])


def unpack_smallest_three(words: np.ndarray) -> np.ndarray:
    """(N,) uint32 version-3 rotations -> (N, 4) float64 quaternions (x, y, z, w)."""
    comp = words.astype(np.uint32)
    largest = (comp >> 30).astype(np.intp)
    q = np.zeros((len(comp), 4))
    sum_sq = np.zeros(len(comp))
    for i in (3, 2, 1, 0):
        skip = largest == i
        mag = (comp & 511).astype(np.float64)
        neg = ((comp >> 9) & 1).astype(bool)
        value = _SQRT1_2 * mag / 511.0
        value = np.where(neg, -value, value)
        q[:, i] = np.where(skip, 0.0, value)
        sum_sq += np.where(skip, 0.0, value * value)
        comp = np.where(skip, comp, comp >> 10)
    q[np.arange(len(q)), largest] = np.sqrt(np.maximum(0.0, 1.0 - sum_sq))
    return q


def decode(header: SpzHeader, parts: dict[str, np.ndarray]) -> SpzArrays:
    """The attributes of :func:`split_stream` as numbers (the table of the module docstring)."""
    n = header.count
    b = parts["positions"].reshape(n, 3, 3).astype(np.int64)
    fixed = b[..., 0] | (b[..., 1] << 8) | (b[..., 2] << 16)
    fixed = np.where(fixed & 0x800000, fixed - (1 << 24), fixed)
    means = fixed / float(1 << header.fractional_bits)
    scales = np.exp(parts["scales"].reshape(n, 3) / 16.0 - 10.0)
    opacity = parts["alphas"] / 255.0
    dc = (parts["colours"].reshape(n, 3) / 255.0 - 0.5) / COLOR_SCALE
    if header.version >= 3:
        xyzw = unpack_smallest_three(parts["rotations"].view("<u4"))
    else:
        xyz = parts["rotations"].reshape(n, 3) / 127.5 - 1.0
        w = np.sqrt(np.maximum(0.0, 1.0 - (xyz * xyz).sum(axis=1)))
        xyzw = np.concatenate([xyz, w[:, None]], axis=1)
    rest = (header.degree + 1) ** 2 - 1
    # float32: (b − 128) / 128 is exact in binary32, and f_dc is rounded once from binary64
    sh = np.empty((n, rest + 1, 3), np.float32)
    sh[:, 0] = dc
    np.subtract(parts["sh"].reshape(n, rest, 3), np.float32(128.0), out=sh[:, 1:],
                dtype=np.float32)
    sh[:, 1:] *= np.float32(1.0 / 128.0)
    return SpzArrays(means, xyzw, scales, opacity, sh)


def choose_fractional_bits(means: np.ndarray) -> int:
    """:data:`DEFAULT_FRACTIONAL_BITS`, or fewer where a coordinate would not fit 24 bits;
    :class:`UsageError` when no number of bits holds the coordinates."""
    largest = float(np.abs(np.asarray(means, np.float64)).max()) if len(means) else 0.0
    for bits in range(DEFAULT_FRACTIONAL_BITS, -1, -1):
        if largest * (1 << bits) + 0.5 <= _FIXED_MAX:
            return bits
    raise UsageError(f"a splat coordinate of {largest:g} does not fit SPZ's 24-bit positions "
                     f"(at most {_FIXED_MAX})")


def _pack_smallest_three(xyzw: np.ndarray) -> np.ndarray:
    q = np.asarray(xyzw, np.float64)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    largest = np.argmax(np.abs(q), axis=1)
    q = np.where(q[np.arange(len(q)), largest][:, None] < 0, -q, q)
    words = largest.astype(np.uint32)
    for i in range(4):
        keep = largest != i
        mag = np.minimum(np.round(np.abs(q[:, i]) / _SQRT1_2 * 511.0), 511).astype(np.uint32)
        field = ((q[:, i] < 0).astype(np.uint32) << 9) | mag
        words = np.where(keep, (words << 10) | field, words)
    return words


def _quantize_sh(values: np.ndarray, bits: int) -> np.ndarray:
    codes = np.round(np.asarray(values, np.float64) * 128.0 + 128.0)
    step = 1 << (8 - bits)
    if step > 1:
        codes = np.round(codes / step) * step
    return np.clip(codes, 0, 255).astype(np.uint8)


def encode(arrays: SpzArrays, *, fractional_bits: int | None = None, level: int = 6) -> bytes:
    """A version-3 stream of ``arrays`` (float values in the stream's frame), gzipped
    (``level``; no file name, time 0, so the bytes depend on the splats only). Scales outside
    :data:`SCALE_RANGE` and colours outside a byte are clamped; callers that care count them
    first (:func:`clamped_counts`)."""
    n = len(arrays.means)
    degree = math.isqrt(arrays.sh.shape[1]) - 1
    bits = choose_fractional_bits(arrays.means) if fractional_bits is None else fractional_bits
    fixed = np.round(np.asarray(arrays.means, np.float64) * (1 << bits)).astype(np.int64)
    if fixed.size and int(np.abs(fixed).max()) > _FIXED_MAX:
        raise UsageError(f"positions do not fit 24 bits with {bits} fractional bits")
    fixed &= 0xFFFFFF
    positions = np.stack([fixed & 0xFF, (fixed >> 8) & 0xFF, fixed >> 16], axis=-1)
    alphas = np.clip(np.round(np.asarray(arrays.opacities, np.float64) * 255.0), 0, 255)
    colours = np.clip(np.round((np.asarray(arrays.sh[:, 0], np.float64) * COLOR_SCALE + 0.5)
                               * 255.0), 0, 255)
    with np.errstate(divide="ignore"):
        log_scales = np.log(np.asarray(arrays.scales, np.float64))
    scales = np.clip(np.round((log_scales + 10.0) * 16.0), 0, 255)
    rotations = _pack_smallest_three(arrays.rotations).astype("<u4")
    sh = np.empty((n, max(0, arrays.sh.shape[1] - 1), 3), np.uint8)
    for k in range(1, arrays.sh.shape[1]):
        sh[:, k - 1] = _quantize_sh(arrays.sh[:, k], SH_BITS[math.isqrt(k) - 1])
    header = struct.pack("<IIIBBBB", MAGIC, 3, n, degree, bits, 0, 0)
    body = b"".join(np.ascontiguousarray(a, np.uint8).tobytes() for a in (
        positions, alphas, colours, scales)) + rotations.tobytes() + sh.tobytes()
    return gzip.compress(header + body, compresslevel=level, mtime=0)


def clamped_counts(arrays: SpzArrays) -> dict[str, int]:
    """Splats whose scale or DC colour :func:`encode` clamps (outside what a byte holds)."""
    s = np.asarray(arrays.scales, np.float64)
    low, high = SCALE_RANGE
    dc = np.asarray(arrays.sh[:, 0], np.float64) * COLOR_SCALE + 0.5
    return {"scale": int(np.count_nonzero(np.any((s < low * math.exp(-1 / 32))
                                                 | (s > high * math.exp(1 / 32)), axis=1))),
            "colour": int(np.count_nonzero(np.any((dc < -0.5 / 255) | (dc > 1 + 0.5 / 255),
                                                  axis=1)))}


def quantization_bounds(fractional_bits: int) -> dict[str, float]:
    """The largest error :func:`encode` adds to each attribute (rounding to nearest; values
    inside the ranges a byte holds):

    * ``position``: per coordinate, half a step ``2^−(fb+1)``; ``mean`` the distance,
      ``√3`` times that;
    * ``scale``: relative, ``e^(1/32) − 1`` (half a step of 1/16 in the natural log);
    * ``rotation``: the angle (radians) between the stored and the decoded rotation. Each of
      the three small components is off by at most ``δ = √½ / 1022``; the rebuilt largest one
      (at least ½) by at most ``3δ``; so ``|Δq| ≤ √12 δ`` and the angle ``≤ 4 asin(|Δq| / 2)``;
    * ``opacity``: ``1/510``; ``dc``: ``1 / (510 · 0.15)``; ``sh1``: ``(2^(8−5) / 2) / 128``
      = 1/32, ``sh23``: 1/16 (the kept bits of :data:`SH_BITS`; one code more where rounding
      to a byte and to the step meet);
    * ``covariance``: ``‖ΔΣ‖_F / ‖Σ‖_F ≤ (1 + scale)² − 1 + 2 · rotation`` (Σ = R S² Rᵀ:
      the scale part changes S² by that factor, the rotation part moves R by at most the
      angle, twice).
    """
    delta = _SQRT1_2 / 1022.0
    dq = math.sqrt(12.0) * delta
    angle = 4.0 * math.asin(dq / 2.0)
    scale = math.exp(1 / 32) - 1.0
    step = 2.0 ** -(fractional_bits + 1)
    return {"position": step, "mean": math.sqrt(3.0) * step, "scale": scale,
            "rotation": angle, "opacity": 1 / 510, "dc": 1 / (510 * COLOR_SCALE),
            "sh1": (2 ** (8 - SH_BITS[0]) / 2 + 1) / 128, "sh23": (2 ** (8 - SH_BITS[1]) / 2 + 1) / 128,
            "covariance": (1.0 + scale) ** 2 - 1.0 + 2.0 * angle}


def inflate_bounded(raw: bytes | memoryview, limit: int, where: str) -> bytes:
    """The content of the single gzip member ``raw``, refused (:class:`FormatError`) past
    ``limit`` bytes without inflating further, when broken, truncated, or followed by more
    data; the work is bounded by ``limit``, whatever the member declares."""
    inflater = zlib.decompressobj(wbits=16 + zlib.MAX_WBITS)
    try:
        out = inflater.decompress(bytes(raw), limit + 1)
    except zlib.error as exc:
        raise FormatError(f"broken gzip stream of SPZ data ({exc})", where) from None
    if len(out) > limit:
        raise FormatError(f"the SPZ stream inflates to more than the {limit} bytes its splats "
                          f"hold", where)
    if not inflater.eof:
        raise FormatError("truncated gzip stream of SPZ data (the member does not end)", where)
    if inflater.unused_data.strip(b"\0"):
        raise FormatError(f"{len(inflater.unused_data)} bytes follow the gzip member of SPZ "
                          "data", where)
    return out
