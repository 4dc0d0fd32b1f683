"""``.ksplat``: the format of mkkellogg's GaussianSplats3D (Three.js viewer).

Layout (all little-endian), in the 3DGS capture frame (the PLY's frame, +Y down):

* a 4096-byte main header: version major (u8 @0, must be 0) and minor (u8 @1, ≥ 1), section
  count (u32 @4), splat count (u32 @16), compression level (u16 @20: 0, 1 or 2), the range of
  SH values at level 2 (f32 @36, @40; 0 means the default −1.5 and 1.5);
* one 1024-byte header per section: splats (u32 @0), capacity (u32 @4), bucket capacity
  (u32 @8), bucket count (u32 @12), bucket block size (f32 @16), bytes per bucket (u16 @20),
  position quantization range (u32 @24; 0: 1 at level 0, 32767 otherwise), full buckets
  (u32 @32), partially filled buckets (u32 @36), SH degree (u16 @40, 0..2, 3 read as well);
* per section: the partial buckets' sizes (u32 each), the bucket centres (3 × f32 each), then
  ``capacity`` records of

  ======== =========================== ==========================================================
  level    position / scale / rotation  colour, SH
  ======== =========================== ==========================================================
  0        3 × f32 / 3 × f32 / 4 × f32  4 × u8 rgba; SH f32
  1        3 × u16 / 3 × f16 / 4 × f16  4 × u8 rgba; SH f16
  2        3 × u16 / 3 × f16 / 4 × f16  4 × u8 rgba; SH u8: ``min + byte / 255 · (max − min)``
  ======== =========================== ==========================================================

  A quantized position is ``(u16 − range) · block_size / 2 / range + bucket centre``. Scales
  are linear; the rotation is ``(w, x, y, z)`` (normalized on reading); ``f_dc = (rgb / 255 −
  0.5) / SH_C0`` and ``opacity = a / 255``. SH are stored band by band, each band channel by
  channel: band 1 as r₁..r₃ g₁..g₃ b₁..b₃, band 2 as r₄..r₈ g₄..g₈ b₄..b₈ (band 3 the same).
  Splats past the full buckets belong to the partial buckets in order, each holding as many
  as its size says.
"""
from __future__ import annotations

import os

import numpy as np

from ...errors import FormatError
from .common import Decoded, color_to_dc, splat_cloud
from .container import Fields, read_bytes

__all__ = ["MAIN_HEADER_BYTES", "SECTION_HEADER_BYTES", "LEVELS", "read_ksplat",
           "sh_component_index"]

MAIN_HEADER_BYTES = 4096
SECTION_HEADER_BYTES = 1024
#: Per compression level: bytes of (position, scale, rotation, colour, one SH value) and the
#: default quantization range.
LEVELS = {0: (12, 12, 16, 4, 4, 1), 1: (6, 6, 8, 4, 2, 32767), 2: (6, 6, 8, 4, 1, 32767)}
_SH_COUNT = (0, 9, 24, 45)
#: More sections than this in a header is a corrupt file (GaussianSplats3D writes one per scene).
MAX_SECTIONS = 1 << 16


def sh_component_index(degree: int) -> tuple[np.ndarray, np.ndarray]:
    """For each stored SH component of a section of ``degree``: its (coefficient, channel)."""
    coeff, channel = [], []
    for band in range(1, degree + 1):
        first, width = band * band, 2 * band + 1
        for c in range(3):
            for j in range(width):
                coeff.append(first + j)
                channel.append(c)
    return np.array(coeff, np.intp), np.array(channel, np.intp)


def read_ksplat(path: str | os.PathLike[str]) -> Decoded:
    """The splats of a ``.ksplat`` file, in the file's frame (the 3DGS frame)."""
    path = os.fspath(path)
    data = read_bytes(path)
    if len(data) < MAIN_HEADER_BYTES:
        raise FormatError(f"{len(data)} bytes is shorter than the {MAIN_HEADER_BYTES}-byte "
                          ".ksplat header", path)
    head = Fields(data, path, ".ksplat header")
    major, minor = head.u8(0), head.u8(1)
    if major != 0 or minor < 1:
        raise FormatError(f".ksplat version {major}.{minor} is not supported (0.1 and later 0.x "
                          "are)", path)
    sections, total, level = head.u32(4), head.u32(16), head.u16(20)
    if level not in LEVELS:
        raise FormatError(f"compression level {level} is not one of 0, 1, 2", path)
    if sections > MAX_SECTIONS:
        raise FormatError(f"{sections} sections is more than {MAX_SECTIONS}", path)
    sh_min = head.f32(36) or -1.5
    sh_max = head.f32(40) or 1.5
    pos_b, scale_b, rot_b, color_b, sh_b, default_range = LEVELS[level]
    offset = MAIN_HEADER_BYTES + sections * SECTION_HEADER_BYTES
    if offset > len(data):
        raise FormatError(f"truncated: {sections} section headers do not fit", path)
    degrees = []
    for s in range(sections):
        sec = Fields(data, path, f"section {s} header")
        base = MAIN_HEADER_BYTES + s * SECTION_HEADER_BYTES
        if sec.u32(base) and sec.u16(base + 40) > 3:
            raise FormatError(f"section {s}: SH degree {sec.u16(base + 40)} is not 0..3", path)
        degrees.append(sec.u16(base + 40) if sec.u32(base) else 0)
    degree = max(degrees, default=0)
    means, scales, rots, rgba, shs = [], [], [], [], []
    parts = {"headers": offset, "buckets": 0, "positions": 0, "scales": 0, "rotations": 0,
             "colour+opacity": 0, "sh": 0}
    for s in range(sections):
        sec = Fields(data, path, f"section {s} header")
        base = MAIN_HEADER_BYTES + s * SECTION_HEADER_BYTES
        count, capacity = sec.u32(base), sec.u32(base + 4)
        bucket_cap, buckets = sec.u32(base + 8), sec.u32(base + 12)
        block = sec.f32(base + 16)
        bucket_bytes = sec.u16(base + 20)
        qrange = sec.u32(base + 24) or default_range
        full, partial = sec.u32(base + 32), sec.u32(base + 36)
        sdeg = degrees[s]
        n_sh = _SH_COUNT[sdeg]
        record = pos_b + scale_b + rot_b + color_b + n_sh * sh_b
        meta_bytes = bucket_bytes * buckets + 4 * partial
        end = offset + meta_bytes + record * capacity
        if count > capacity or end > len(data):
            raise FormatError(f"section {s}: {count} splats of {record} bytes (capacity "
                              f"{capacity}) do not fit in the file", path)
        if count == 0:
            offset = end
            continue
        if level and bucket_bytes < 12 * (buckets > 0):
            raise FormatError(f"section {s}: {bucket_bytes} bytes per bucket cannot hold its "
                              "centre (3 floats)", path)
        partial_sizes = np.frombuffer(data, "<u4", partial, offset).astype(np.int64)
        centres = np.frombuffer(data, "<f4", 3 * buckets, offset + 4 * partial) \
            .reshape(buckets, 3).astype(np.float64) if level else np.zeros((0, 3))
        rec = np.frombuffer(data, np.uint8, record * count, offset + meta_bytes) \
            .reshape(count, record)
        o = 0
        if level == 0:
            pos = rec[:, 0:12].copy().view("<f4").astype(np.float64)
        else:
            in_full = min(count, full * bucket_cap)
            bucket = np.empty(count, np.int64)
            bucket[:in_full] = np.arange(in_full) // max(bucket_cap, 1)
            rest = count - in_full
            if rest:
                if partial_sizes.sum() > capacity:
                    raise FormatError(f"section {s}: the partial buckets claim "
                                      f"{int(partial_sizes.sum())} splats, more than its "
                                      f"capacity {capacity}", path)
                owners = np.repeat(np.arange(full, full + partial), partial_sizes)
                if len(owners) < rest:
                    raise FormatError(f"section {s}: the partial buckets hold "
                                      f"{len(owners)} splats, {rest} are left", path)
                bucket[in_full:] = owners[:rest]
            if count and (bucket.max() >= buckets):
                raise FormatError(f"section {s}: bucket {int(bucket.max())} of {buckets}", path)
            q = rec[:, 0:6].copy().view("<u2").astype(np.float64)
            pos = (q - qrange) * (block / 2.0 / qrange) + centres[bucket]
        o += pos_b
        ftype = "<f4" if level == 0 else "<f2"
        scale = rec[:, o:o + scale_b].copy().view(ftype).astype(np.float64)
        o += scale_b
        rot = rec[:, o:o + rot_b].copy().view(ftype).astype(np.float64)
        o += rot_b
        col = rec[:, o:o + 4].astype(np.float64) / 255.0
        o += 4
        sh = np.zeros((count, (degree + 1) ** 2, 3))
        sh[:, 0] = color_to_dc(col[:, :3])
        if n_sh:
            raw = rec[:, o:o + n_sh * sh_b].copy()
            if level == 0:
                values = raw.view("<f4").astype(np.float64)
            elif level == 1:
                values = raw.view("<f2").astype(np.float64)
            else:
                values = sh_min + raw.astype(np.float64) / 255.0 * (sh_max - sh_min)
            coeff, channel = sh_component_index(sdeg)
            sh[:, coeff, channel] = values
        means.append(pos)
        scales.append(scale)
        rots.append(rot)
        rgba.append(col[:, 3])
        shs.append(sh)
        parts["buckets"] += meta_bytes
        for name, size in (("positions", pos_b), ("scales", scale_b), ("rotations", rot_b),
                           ("colour+opacity", color_b), ("sh", n_sh * sh_b)):
            parts[name] += size * capacity
        offset = end
    got = sum(len(m) for m in means)
    if got != total:
        raise FormatError(f"the header says {total} splats, the sections hold {got}", path)
    if not means:
        empty = np.zeros((0, 3))
        cloud = splat_cloud(empty, np.zeros((0, 4)), empty, np.zeros(0), np.zeros((0, 1, 3)),
                            path)
    else:
        cloud = splat_cloud(np.concatenate(means), np.concatenate(rots),
                            np.concatenate(scales), np.concatenate(rgba),
                            np.concatenate(shs), path)
    return Decoded(cloud, f"ksplat {major}.{minor}, compression level {level}",
                   {k: v for k, v in parts.items() if v})
