"""SOG: PlayCanvas's "spatially ordered Gaussians" — a ``.sog`` zip archive (or a folder) of a
``meta.json`` and lossless WebP images, every image holding one splat per pixel in row-major
order. Frame: the 3DGS capture frame (+Y down), as splat-transform writes it from a PLY.

Version 2 (``"version": 2``, ``"count"``)
    * ``means``: two images ``files[0]`` (low bytes) and ``files[1]`` (high bytes); r, g, b
      give 16-bit ``u`` per axis; ``v = mins + (maxs − mins) · u / 65535`` (a zero range counts
      as 1) and the position is ``sign(v) · (e^|v| − 1)``.
    * ``quats``: r, g, b are three components ``(byte / 255 · 2 − 1) / √2`` and a = 252 + the
      index of the largest component of ``(w, x, y, z)``, rebuilt from the unit norm; the
      others fill the remaining slots in order. Another alpha is the identity.
    * ``scales``: r, g, b index the 256-entry ``codebook`` of log-scales.
    * ``sh0``: r, g, b index the ``codebook`` of ``f_dc``; ``opacity = a / 255``.
    * ``shN`` (optional; ``bands`` 1..3, ``count`` palette entries): ``files[1]`` (labels)
      holds a 16-bit palette index in r (low) and g (high); ``files[0]`` (centroids) is
      64 entries wide, entry ``e`` at row ``e // 64``, columns ``(e % 64) · K + j`` for
      coefficient ``j`` (K = 3, 8, 15), whose r, g, b index the 256-entry ``codebook``.
Version 1 (no ``version``)
    The same images, with linear ``mins``/``maxs`` per channel instead of codebooks:
    ``scales`` and ``sh0`` (whose alpha is the opacity logit) and ``shN`` (one range).

Quantization: positions 1/65535 of the log range; rotation components 1/255 · √2;
log-scales, colours and SH by codebook (256 values each); opacity 1/255.
"""
from __future__ import annotations

import os
from typing import Any

import numpy as np

from ...errors import FormatError
from .common import Decoded, splat_cloud
from .container import Bundle, decode_webp, open_bundle

__all__ = ["is_sog_meta", "read_sog"]

_SH_COEFFS = {0: 0, 1: 3, 2: 8, 3: 15}
_OTHERS = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])
#: V1 files say their SH bands only through the width of the centroid image.
_V1_BANDS = {192: 1, 512: 2, 960: 3}


def is_sog_meta(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` (a ``.json`` file) is the ``meta.json`` of an unbundled SOG scene."""
    try:
        with open(path, "rb") as f:
            head = f.read(1 << 16)
    except OSError:
        return False
    return b'"means"' in head and b'"quats"' in head


class _Reader:
    def __init__(self, bundle: Bundle, meta: dict[str, Any], path: str):
        self.bundle, self.meta, self.path = bundle, meta, path

    def field(self, *keys: str) -> Any:
        node: Any = self.meta
        for key in keys:
            if not isinstance(node, dict) or key not in node:
                raise FormatError(f"meta.json has no {'.'.join(keys)}", self.path)
            node = node[key]
        return node

    def numbers(self, *keys: str, length: int | None = None) -> np.ndarray:
        value = self.field(*keys)
        try:
            array = np.asarray(value, np.float64)
        except (TypeError, ValueError):
            raise FormatError(f"meta.json {'.'.join(keys)} is not a list of numbers",
                              self.path) from None
        if (length is not None and array.shape != (length,)) or not np.isfinite(array).all():
            raise FormatError(f"meta.json {'.'.join(keys)} must be {length} finite numbers",
                              self.path)
        return array

    def number(self, *keys: str) -> float:
        value = self.field(*keys)
        try:   # float() of an integer past 1e308 overflows (numpy refused a 2**64 one)
            number = float(value) if isinstance(value, (int, float)) \
                and not isinstance(value, bool) else float("nan")
        except OverflowError:
            number = float("inf")
        if not np.isfinite(number):
            raise FormatError(f"meta.json {'.'.join(keys)} is not a finite number", self.path)
        return number

    def image(self, group: str, index: int, count: int) -> np.ndarray:
        files = self.field(group, "files")
        if not isinstance(files, list) or len(files) <= index:
            raise FormatError(f"meta.json {group}.files names no file {index}", self.path)
        rgba = decode_webp(self.bundle.read(files[index]), files[index], self.path)
        return rgba

    def pixels(self, group: str, index: int, count: int) -> np.ndarray:
        rgba = self.image(group, index, count).reshape(-1, 4)
        if len(rgba) < count:
            raise FormatError(f"image {group} has {len(rgba)} pixels for {count} splats",
                              self.path)
        return rgba[:count].astype(np.int64)


def _positions(r: _Reader, n: int) -> np.ndarray:
    lo, hi = r.pixels("means", 0, n), r.pixels("means", 1, n)
    u = (lo[:, :3] | (hi[:, :3] << 8)).astype(np.float64)
    mins, maxs = r.numbers("means", "mins", length=3), r.numbers("means", "maxs", length=3)
    span = np.where(maxs - mins == 0, 1.0, maxs - mins)
    v = mins + span * (u / 65535.0)
    return np.sign(v) * np.expm1(np.abs(v))


def _rotations(r: _Reader, n: int) -> np.ndarray:
    q = r.pixels("quats", 0, n)
    tag = q[:, 3]
    valid = (tag >= 252) & (tag <= 255)
    largest = np.where(valid, tag - 252, 0)
    abc = (q[:, :3] / 255.0 * 2.0 - 1.0) / np.sqrt(2.0)
    wxyz = np.zeros((n, 4))
    wxyz[np.arange(n)[:, None], _OTHERS[largest]] = abc
    wxyz[np.arange(n), largest] = np.sqrt(np.maximum(0.0, 1.0 - (abc * abc).sum(axis=1)))
    wxyz[~valid] = [1.0, 0.0, 0.0, 0.0]
    return wxyz


def _codebook(r: _Reader, group: str) -> np.ndarray:
    book = r.numbers(group, "codebook")
    if book.shape != (256,):
        raise FormatError(f"meta.json {group}.codebook must hold 256 numbers, not "
                          f"{book.size}", r.path)
    return book


def _sh_rest(r: _Reader, n: int, version: int) -> tuple[int, np.ndarray | None]:
    if "shN" not in r.meta:
        return 0, None
    centroids = r.image("shN", 0, 0)
    height, width = centroids.shape[:2]
    if version == 2:
        bands = r.field("shN", "bands")
        if bands not in (1, 2, 3):
            raise FormatError(f"meta.json shN.bands {bands!r} is not 1, 2 or 3", r.path)
        palette = r.field("shN", "count")
        book = _codebook(r, "shN")
    else:
        bands = _V1_BANDS.get(width, 0)
        if not bands:
            raise FormatError(f"the shN centroid image is {width} pixels wide, not 192, 512 "
                              "or 960", r.path)
        palette = (width // _SH_COEFFS[bands]) * height
        lo, hi = r.number("shN", "mins"), r.number("shN", "maxs")
        book = lo + (hi - lo) * np.arange(256) / 255.0
    k = _SH_COEFFS[bands]
    if width != 64 * k:
        raise FormatError(f"the shN centroid image is {width} pixels wide, not {64 * k} for "
                          f"{bands} bands", r.path)
    if not isinstance(palette, int) or not 0 < palette <= 64 * height:
        raise FormatError(f"meta.json shN.count {palette!r} does not fit the centroid image",
                          r.path)
    labels = r.pixels("shN", 1, n)
    label = labels[:, 0] | (labels[:, 1] << 8)
    if (label >= palette).any():
        row = int(np.argmax(label >= palette))
        raise FormatError(f"splat {row} uses SH palette entry {int(label[row])} of {palette}",
                          r.path)
    rows, cols = label // 64, (label % 64) * k
    idx = cols[:, None] + np.arange(k)[None, :]          # (n, k)
    values = centroids[rows[:, None], idx, :3]           # (n, k, 3) codebook indices
    return bands, book[values]


def read_sog(path: str | os.PathLike[str]) -> Decoded:
    """The splats of a SOG scene (a ``.sog`` archive or a ``meta.json``), in the file's frame
    (the 3DGS frame)."""
    path = os.fspath(path)
    bundle, meta = open_bundle(path)
    try:
        r = _Reader(bundle, meta, path)
        version = meta.get("version")
        if version not in (None, 2):
            raise FormatError(f"SOG version {version!r} is not supported (1 and 2 are)", path)
        if version == 2:
            n = r.field("count")
        else:
            shape = r.field("means", "shape")
            n = shape[0] if isinstance(shape, list) and shape else None
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise FormatError(f"splat count {n!r} is not a whole number", path)
        means = _positions(r, n)
        wxyz = _rotations(r, n)
        scale_px = r.pixels("scales", 0, n)
        sh0 = r.pixels("sh0", 0, n)
        if version == 2:
            log_scales = _codebook(r, "scales")[scale_px[:, :3]]
            dc = _codebook(r, "sh0")[sh0[:, :3]]
            opacity = sh0[:, 3] / 255.0
        else:
            lo, hi = r.numbers("scales", "mins", length=3), r.numbers("scales", "maxs", length=3)
            log_scales = lo + (hi - lo) * scale_px[:, :3] / 255.0
            lo, hi = r.numbers("sh0", "mins", length=4), r.numbers("sh0", "maxs", length=4)
            values = lo + (hi - lo) * sh0 / 255.0
            dc, opacity = values[:, :3], 1.0 / (1.0 + np.exp(-values[:, 3]))
        bands, rest = _sh_rest(r, n, 2 if version == 2 else 1)
        sh = np.zeros((n, (bands + 1) ** 2, 3))
        sh[:, 0] = dc
        if rest is not None:
            sh[:, 1:] = rest
        cloud = splat_cloud(means, wxyz, np.exp(log_scales), opacity, sh, path)
        parts = dict(bundle.sizes)
    finally:
        bundle.close()
    return Decoded(cloud, f"SOG v{2 if version == 2 else 1}", parts)
