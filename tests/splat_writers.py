"""Encoders for the web splat formats and variants that splat-transform cannot write
(``.splat``, ``.ksplat``, spz v2 with extension records, SOG v1) and for SOG v2 with one SH
palette entry per splat: the tests make files with them and compare what
:mod:`gsverse_format.io.splatformats` and splat-transform decode from the same bytes.

Each follows its format's reference writer (antimatter15's ``convert.py``, GaussianSplats3D's
``SplatBuffer``, Niantic's ``packGaussians``) for the layouts the readers document; they take
a :class:`~gsverse_format.model.SplatCloud` in the file's frame.
"""
from __future__ import annotations

import gzip
import struct

import numpy as np

from gsverse_format.model import SplatCloud
from gsverse_format.vocabulary import SH_C0


def _u8(value: np.ndarray) -> np.ndarray:
    return np.clip(np.round(value), 0, 255).astype(np.uint8)


def _wxyz(cloud: SplatCloud) -> np.ndarray:
    q = cloud.rotations.astype(np.float64)
    q = q / np.linalg.norm(q, axis=1)[:, None]
    return q[:, [3, 0, 1, 2]]


def write_antimatter_splat(cloud: SplatCloud, path) -> None:
    n = len(cloud)
    rec = np.zeros(n, [("position", "<f4", 3), ("scale", "<f4", 3), ("rgba", "u1", 4),
                       ("rotation", "u1", 4)])
    rec["position"] = cloud.means
    rec["scale"] = cloud.scales
    rec["rgba"][:, :3] = _u8((0.5 + SH_C0 * cloud.sh[:, 0].astype(np.float64)) * 255)
    rec["rgba"][:, 3] = _u8(cloud.opacities * 255.0)
    rec["rotation"] = _u8(_wxyz(cloud) * 128 + 128)
    with open(path, "wb") as f:
        f.write(rec.tobytes())


def _ksplat_sh(cloud: SplatCloud, degree: int) -> np.ndarray:
    """(N, components) in the ksplat order: band by band, channel by channel."""
    cols = []
    for band in range(1, degree + 1):
        for c in range(3):
            for j in range(2 * band + 1):
                cols.append(cloud.sh[:, band * band + j, c])
    return np.stack(cols, axis=1).astype(np.float64) if cols else np.zeros((len(cloud), 0))


def write_ksplat(cloud: SplatCloud, path, level: int = 0, bucket_capacity: int = 256,
                 sh_range: tuple[float, float] = (-1.5, 1.5)) -> None:
    """One section; at levels 1 and 2 the splats are cut into buckets of ``bucket_capacity``
    in file order, the last one partial when the count is not a multiple."""
    n, degree = len(cloud), min(cloud.sh_degree, 3)
    qrange = 1 if level == 0 else 32767
    full, rest = divmod(n, bucket_capacity) if level else (0, 0)
    partial = 1 if rest else 0
    buckets = full + partial if level else 0
    means = cloud.means.astype(np.float64)
    sh = _ksplat_sh(cloud, degree)
    if level == 0:
        body = [means.astype("<f4").view(np.uint8).reshape(n, 12),
                cloud.scales.astype("<f4").view(np.uint8).reshape(n, 12),
                np.ascontiguousarray(_wxyz(cloud), "<f4").view(np.uint8).reshape(n, 16)]
        block, centres = 0.0, np.zeros((0, 3))
    else:
        owner = np.arange(n) // bucket_capacity
        lo = np.array([means[owner == b].min(axis=0) for b in range(buckets)])
        hi = np.array([means[owner == b].max(axis=0) for b in range(buckets)])
        centres = (lo + hi) / 2
        block = float(2.0 * np.abs(means - centres[owner]).max() * 1.001 + 1e-6)
        q = np.round((means - centres[owner]) / (block / 2.0 / qrange)) + qrange
        body = [np.clip(q, 0, 65535).astype("<u2").view(np.uint8).reshape(n, 6),
                cloud.scales.astype("<f2").view(np.uint8).reshape(n, 6),
                np.ascontiguousarray(_wxyz(cloud), "<f2").view(np.uint8).reshape(n, 8)]
    rgba = np.zeros((n, 4), np.uint8)
    rgba[:, :3] = _u8((0.5 + SH_C0 * cloud.sh[:, 0].astype(np.float64)) * 255)
    rgba[:, 3] = _u8(cloud.opacities * 255.0)
    body.append(rgba)
    if sh.shape[1]:
        if level == 0:
            body.append(np.ascontiguousarray(sh, "<f4").view(np.uint8).reshape(n, -1))
        elif level == 1:
            body.append(np.ascontiguousarray(sh, "<f2").view(np.uint8).reshape(n, -1))
        else:
            t = (np.clip(sh, *sh_range) - sh_range[0]) / (sh_range[1] - sh_range[0])
            body.append(_u8(t * 255))
    records = np.concatenate(body, axis=1)
    main = bytearray(4096)
    struct.pack_into("<BBxxIII", main, 0, 0, 1, 1, 1, n)   # version 0.1, 1 section, capacity n
    struct.pack_into("<IH", main, 16, n, level)
    struct.pack_into("<ff", main, 36, *sh_range)
    section = bytearray(1024)
    struct.pack_into("<IIIIfHxxI", section, 0, n, n, bucket_capacity if level else 0, buckets,
                     block, 12 if level else 0, qrange)
    struct.pack_into("<IIH", section, 32, full, partial, degree)
    meta = struct.pack(f"<{partial}I", *([rest] if partial else [])) + \
        centres.astype("<f4").tobytes()
    with open(path, "wb") as f:
        f.write(bytes(main) + bytes(section) + meta + records.tobytes())


def spz_coordinate_system(code: int) -> bytes:
    """An ``SPZ_ADOBE_coordinate_system`` extension record (type, byte length, enum value)."""
    return struct.pack("<III", 0xADBE0003, 4, code)


def write_spz_v2(cloud: SplatCloud, path, fractional_bits: int = 12,
                 extensions: bytes = b"") -> None:
    """spz version 2 (quaternion x, y, z with w ≥ 0, one gzip stream); ``extensions`` are
    extension records appended after the attributes (flag bit 1)."""
    n, degree = len(cloud), min(cloud.sh_degree, 3)
    fixed = np.round(cloud.means.astype(np.float64) * (1 << fractional_bits)).astype(np.int64)
    fixed &= 0xFFFFFF
    pos = np.stack([(fixed >> s) & 0xFF for s in (0, 8, 16)], axis=-1).astype(np.uint8)
    alphas = _u8(cloud.opacities.astype(np.float64) * 255.0)
    colours = _u8((cloud.sh[:, 0].astype(np.float64) * 0.15 + 0.5) * 255.0)
    scales = _u8((np.log(cloud.scales.astype(np.float64)) + 10.0) * 16.0)
    xyzw = cloud.rotations.astype(np.float64)
    xyzw = xyzw / np.linalg.norm(xyzw, axis=1)[:, None]
    xyzw = np.where(xyzw[:, 3:] < 0, -xyzw, xyzw)
    rots = _u8(xyzw[:, :3] * 127.5 + 127.5)
    k = (degree + 1) ** 2
    sh = _u8(cloud.sh[:, 1:k].astype(np.float64) * 128.0 + 128.0)
    flags = 2 if extensions else 0
    payload = struct.pack("<IIIBBBB", 0x5053474E, 2, n, degree, fractional_bits, flags, 0) + \
        b"".join(a.tobytes() for a in (pos, alphas, colours, scales, rots, sh)) + extensions
    with open(path, "wb") as f:
        f.write(gzip.compress(payload))


def _webp(rgba: np.ndarray) -> bytes:
    """Lossless WebP (``exact``: colours under a zero alpha are kept, as SOG needs)."""
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(rgba, np.uint8), "RGBA").save(
        buf, "WEBP", lossless=True, exact=True, quality=100)
    return buf.getvalue()


def write_sog(cloud: SplatCloud, path, version: int = 2) -> None:
    """A SOG archive (``.sog``) or, for a path ending in ``meta.json``, its unbundled folder;
    version 2 (codebooks) or 1 (per-channel ranges). Every splat gets its own SH palette
    entry. Follows the layout ``gsverse_format.io.splatformats.sog`` documents."""
    import json
    import math
    import os
    import zipfile

    n, degree = len(cloud), min(cloud.sh_degree, 3)
    width = max(1, math.ceil(math.sqrt(n)))
    height = max(1, math.ceil(n / width))

    def image(channels: np.ndarray, w: int = width, h: int = height) -> np.ndarray:
        out = np.zeros((w * h, 4), np.uint8)
        out[:, 3] = 255
        out[:len(channels), :channels.shape[1]] = channels
        return out.reshape(h, w, 4)

    def levels(values: np.ndarray, lo, hi, top: int) -> np.ndarray:
        span = np.where(np.asarray(hi) - np.asarray(lo) == 0, 1.0, np.asarray(hi) - np.asarray(lo))
        return np.clip(np.round((values - lo) / span * top), 0, top).astype(np.int64)

    files: dict[str, bytes] = {}
    means = cloud.means.astype(np.float64)
    v = np.sign(means) * np.log1p(np.abs(means))
    mins, maxs = v.min(axis=0), v.max(axis=0)
    u = levels(v, mins, maxs, 65535)
    files["means_l.webp"] = _webp(image(u & 255))
    files["means_u.webp"] = _webp(image(u >> 8))
    q = _wxyz(cloud)
    largest = np.abs(q).argmax(axis=1)
    q = np.where(q[np.arange(n), largest][:, None] < 0, -q, q)
    others = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])[largest]
    abc = q[np.arange(n)[:, None], others]
    quat = np.concatenate([_u8((abc * np.sqrt(2) * 0.5 + 0.5) * 255),
                           (252 + largest)[:, None].astype(np.uint8)], axis=1)
    files["quats.webp"] = _webp(image(quat))
    log_scales = np.log(cloud.scales.astype(np.float64))
    dc = cloud.sh[:, 0].astype(np.float64)
    meta: dict = {"means": {"mins": mins.tolist(), "maxs": maxs.tolist(),
                            "files": ["means_l.webp", "means_u.webp"]},
                  "quats": {"files": ["quats.webp"]}}
    rest = cloud.sh[:, 1:(degree + 1) ** 2].astype(np.float64)     # (n, k, 3)
    k = rest.shape[1]
    if version == 2:
        book_s = np.linspace(log_scales.min(), log_scales.max(), 256)
        book_c = np.linspace(dc.min(), dc.max(), 256)
        files["scales.webp"] = _webp(image(levels(log_scales, book_s[0], book_s[-1], 255)))
        sh0 = np.concatenate([levels(dc, book_c[0], book_c[-1], 255),
                              _u8(cloud.opacities.astype(np.float64) * 255)[:, None]], axis=1)
        files["sh0.webp"] = _webp(image(sh0))
        meta.update({"version": 2, "count": n,
                     "scales": {"codebook": book_s.tolist(), "files": ["scales.webp"]},
                     "sh0": {"codebook": book_c.tolist(), "files": ["sh0.webp"]}})
    else:
        logit = np.log(np.clip(cloud.opacities, 1e-6, 1 - 1e-6) /
                       (1 - np.clip(cloud.opacities, 1e-6, 1 - 1e-6))).astype(np.float64)
        c4 = np.concatenate([dc, logit[:, None]], axis=1)
        files["scales.webp"] = _webp(image(levels(log_scales, log_scales.min(axis=0),
                                                  log_scales.max(axis=0), 255)))
        files["sh0.webp"] = _webp(image(levels(c4, c4.min(axis=0), c4.max(axis=0), 255)))
        meta["means"]["shape"] = [n, 3]
        meta.update({"scales": {"mins": log_scales.min(axis=0).tolist(),
                                "maxs": log_scales.max(axis=0).tolist(), "files": ["scales.webp"]},
                     "sh0": {"mins": c4.min(axis=0).tolist(), "maxs": c4.max(axis=0).tolist(),
                             "files": ["sh0.webp"]}})
    if k:
        lo, hi = float(rest.min()), float(rest.max())
        rows = math.ceil(n / 64)
        idx = levels(rest, lo, hi, 255)
        centroids = np.zeros((rows * 64, k, 3), np.int64)
        centroids[:n] = idx
        cimg = np.zeros((rows, 64 * k, 4), np.uint8)
        cimg[..., 3] = 255
        cimg[..., :3] = centroids.reshape(rows, 64 * k, 3)
        labels = np.arange(n)
        files["shN_centroids.webp"] = _webp(cimg)
        files["shN_labels.webp"] = _webp(image(np.stack([labels & 255, labels >> 8], axis=1)))
        shn: dict = {"files": ["shN_centroids.webp", "shN_labels.webp"]}
        if version == 2:
            shn.update({"count": n, "bands": degree,
                        "codebook": np.linspace(lo, hi, 256).tolist()})
        else:
            shn.update({"mins": lo, "maxs": hi})
        meta["shN"] = shn
    text = json.dumps(meta).encode()
    path = os.fspath(path)
    if path.endswith("meta.json"):
        folder = os.path.dirname(path)
        for name, data in files.items():
            with open(os.path.join(folder, name), "wb") as f:
                f.write(data)
        with open(path, "wb") as f:
            f.write(text)
        return
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("meta.json", text)
        for name, data in files.items():
            archive.writestr(name, data)
