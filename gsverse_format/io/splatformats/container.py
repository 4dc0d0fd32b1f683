"""The byte layer of the web splat formats: whole files, gzip streams, SOG bundles, WebP images.

Nothing here knows what a splat is. Every problem is a one-line
:class:`~gsverse_format.errors.FormatError` naming the file (a missing file is a
:class:`~gsverse_format.errors.UsageError`).

Limits (each guards against a file that claims more than it holds, or a decompression bomb):

* :data:`MAX_INFLATED_BYTES` — the most bytes a gzip stream (``.spz``) or one SOG member may
  inflate to: 4 GiB, above the largest real captures (≈ 60 million splats of SH degree 0 in
  ``.spz``, whose splats take 64 bytes each at degree 3).
* :data:`MAX_IMAGE_PIXELS` — the most pixels of one SOG WebP image: 2²⁸ (16384²), the WebP
  format's own limit on each side.
* :func:`inflation_limit` — below both caps, what a compressed stream may inflate to in
  proportion to its own size: :data:`MAX_INFLATION_RATIO` times its compressed bytes plus
  :data:`INFLATION_SLACK`. Real splat data compresses 1–4× (gzip of ``.spz``, zstd streams,
  lossless WebP of quantized attributes, deflated zip members); only a bomb (a few kilobytes
  of zeros declaring millions of splats, a 38-byte WebP declaring 8192² pixels) inflates a
  hundredfold beyond the slack. Checked on declared sizes before anything is inflated, and
  while inflating where nothing is declared (gzip).
* SOG archive members are read only when stored or deflated (zipfile's deflate reader honours
  a bound on its output; its bzip2 and LZMA readers inflate whole chunks at once), and folder
  members only when their real path (symbolic links resolved) lies in the folder.
* :data:`MAX_JSON_NESTING` — how deep ``meta.json`` may nest; integers in it are limited by
  Python's own 4300-digit rule, reported as bad input.
"""
from __future__ import annotations

import io
import json
import os
import warnings
import zipfile
import zlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...errors import FormatError, UsageError

__all__ = ["MAX_INFLATED_BYTES", "MAX_IMAGE_PIXELS", "MAX_INFLATION_RATIO", "INFLATION_SLACK",
           "MAX_JSON_NESTING", "inflation_limit", "read_bytes", "gunzip", "Bundle",
           "open_bundle", "decode_webp", "Fields", "parse_json"]

MAX_INFLATED_BYTES = 4 << 30
MAX_IMAGE_PIXELS = 1 << 28
MAX_INFLATION_RATIO = 100
INFLATION_SLACK = 64 << 20
MAX_JSON_NESTING = 64
_ZIP_METHODS = {zipfile.ZIP_STORED: "stored", zipfile.ZIP_DEFLATED: "deflated"}


def inflation_limit(compressed_bytes: int) -> int:
    """The most bytes ``compressed_bytes`` of a stream may inflate to (see the module)."""
    return min(MAX_INFLATED_BYTES, INFLATION_SLACK + MAX_INFLATION_RATIO * compressed_bytes)


def _limit_text(compressed_bytes: int) -> str:
    return (f"{inflation_limit(compressed_bytes)} bytes ({MAX_INFLATION_RATIO}x its "
            f"{compressed_bytes} compressed bytes plus {INFLATION_SLACK >> 20} MiB)")


def read_bytes(path: str) -> bytes:
    """The whole file (a missing file is a :class:`UsageError`, other failures a
    :class:`FormatError`)."""
    try:
        with open(path, "rb") as f:
            return f.read()
    except FileNotFoundError:
        raise UsageError("file not found", path) from None
    except IsADirectoryError:
        raise FormatError("is a folder, not a file", path) from None
    except OSError as exc:
        raise FormatError(f"cannot read the file ({exc.strerror or exc})", path) from None


def gunzip(data: bytes, path: str, limit: int | None = None) -> bytes:
    """The content of a gzip stream, at most ``limit`` bytes (default
    :func:`inflation_limit` of the stream's size)."""
    bound = f"{limit} bytes" if limit is not None else _limit_text(len(data))
    limit = inflation_limit(len(data)) if limit is None else limit
    inflater = zlib.decompressobj(16 + zlib.MAX_WBITS)
    try:
        out = inflater.decompress(data, limit)
        if inflater.unconsumed_tail:
            raise FormatError(f"the gzip stream inflates to more than {bound}", path)
        out += inflater.flush()
    except zlib.error as exc:
        raise FormatError(f"broken gzip stream ({exc})", path) from None
    if not inflater.eof:
        raise FormatError("truncated gzip stream", path)
    return out


@dataclass
class Bundle:
    """The files of a SOG scene: a ``.sog`` zip archive, or the folder of a ``meta.json``.
    ``sizes`` gives each member's stored size in bytes."""

    path: str
    zip: zipfile.ZipFile | None
    folder: str | None
    sizes: dict[str, int] = field(default_factory=dict)

    def read(self, name: str) -> bytes:
        """Member ``name`` (a relative path without ``..``), at most
        :data:`MAX_INFLATED_BYTES` bytes."""
        if not isinstance(name, str) or not name or name.startswith(("/", "\\")) \
                or ".." in name.replace("\\", "/").split("/"):
            raise FormatError(f"meta.json names a file {name!r} outside the bundle", self.path)
        if self.zip is not None:
            try:
                info = self.zip.getinfo(name)
            except KeyError:
                raise FormatError(f"the archive has no member {name!r}", self.path) from None
            if info.compress_type not in _ZIP_METHODS:
                raise FormatError(f"member {name!r} is compressed with zip method "
                                  f"{info.compress_type}; SOG members are stored or deflated",
                                  self.path)
            if info.flag_bits & 0x1:
                raise FormatError(f"member {name!r} is encrypted", self.path)
            if info.file_size > inflation_limit(info.compress_size):
                raise FormatError(f"member {name!r} declares {info.file_size} bytes, more "
                                  f"than {_limit_text(info.compress_size)}", self.path)
            try:
                return self.zip.read(info)
            except (zipfile.BadZipFile, zlib.error, NotImplementedError, OSError, EOFError,
                    ValueError, RuntimeError) as exc:   # RuntimeError: encryption flags
                raise FormatError(f"cannot read member {name!r} ({exc})", self.path) from None
        assert self.folder is not None
        member = os.path.join(self.folder, name)
        root = os.path.realpath(self.folder)
        if os.path.commonpath([root, os.path.realpath(member)]) != root:
            raise FormatError(f"meta.json names {name!r}, a link to a file outside its folder",
                              self.path)
        if not os.path.isfile(member):
            raise FormatError(f"meta.json names {name!r}, which is not beside it", self.path)
        data = read_bytes(member)
        self.sizes[name] = len(data)
        return data

    def close(self) -> None:
        if self.zip is not None:
            self.zip.close()


def open_bundle(path: str) -> tuple[Bundle, dict[str, Any]]:
    """The bundle at ``path`` (a zip archive, or a ``meta.json`` whose images lie beside it)
    and its parsed ``meta.json``."""
    data = read_bytes(path)
    if data[:4] == b"PK\x03\x04":
        try:
            archive = zipfile.ZipFile(io.BytesIO(data))
        except (zipfile.BadZipFile, UnicodeDecodeError, ValueError, EOFError,
                NotImplementedError, OSError) as exc:   # NotImplementedError: zip version
            raise FormatError(f"broken zip archive ({exc})", path) from None
        bundle = Bundle(path, archive, None,
                        {i.filename: i.compress_size for i in archive.infolist()})
        meta_bytes = bundle.read("meta.json")
    else:
        folder = os.path.dirname(os.path.abspath(path))
        bundle = Bundle(path, None, folder, {os.path.basename(path): len(data)})
        meta_bytes = data
    try:
        meta = parse_json(meta_bytes, "meta.json", path)
    except FormatError:
        bundle.close()
        raise
    if not isinstance(meta, dict):
        bundle.close()
        raise FormatError("meta.json is not a JSON object", path)
    return bundle, meta


def _nesting(data: bytes) -> int:
    """The deepest nesting of ``[``/``{`` in JSON bytes (brackets inside strings counted too:
    an upper bound, enough to refuse before the recursive parser runs)."""
    codes = np.frombuffer(data, np.uint8)
    steps = (np.isin(codes, (0x5B, 0x7B)).astype(np.int64)
             - np.isin(codes, (0x5D, 0x7D)).astype(np.int64))
    return int(np.cumsum(steps).max()) if len(steps) else 0


def parse_json(data: bytes, what: str, path: str) -> Any:
    """JSON ``data`` (UTF-8) of the file ``what`` in ``path``; :class:`FormatError` for text
    that is not JSON, nests deeper than :data:`MAX_JSON_NESTING` or holds an integer of more
    than 4300 digits (Python's limit)."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise FormatError(f"{what} is not UTF-8 text ({exc})", path) from None
    if _nesting(data) > MAX_JSON_NESTING:
        raise FormatError(f"{what} nests deeper than {MAX_JSON_NESTING} levels", path)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise FormatError(f"{what} is not valid JSON ({exc})", path) from None
    except ValueError as exc:  # an integer beyond sys.get_int_max_str_digits()
        raise FormatError(f"{what}: {exc}", path) from None


def decode_webp(data: bytes, name: str, path: str) -> np.ndarray:
    """An image (WebP, or any format Pillow reads) as an (H, W, 4) uint8 RGBA array.

    Pillow decodes WebP through libwebp, which its wheels carry: SOG images are lossless
    WebP, so every byte comes back exactly as written."""
    from PIL import Image, UnidentifiedImageError

    try:
        # Pillow warns (on stderr, DecompressionBombWarning) at an image size ours refuse
        # below (MAX_IMAGE_PIXELS, inflation_limit): the check that applies is ours.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            image = Image.open(io.BytesIO(data))
        with image:
            if image.width * image.height > MAX_IMAGE_PIXELS:
                raise FormatError(f"image {name!r} has {image.width}x{image.height} pixels, "
                                  f"more than {MAX_IMAGE_PIXELS}", path)
            if 4 * image.width * image.height > inflation_limit(len(data)):
                raise FormatError(f"image {name!r} declares {image.width}x{image.height} "
                                  f"pixels, more than {_limit_text(len(data))} hold", path)
            rgba = np.asarray(image.convert("RGBA"), dtype=np.uint8)
    except (UnidentifiedImageError, OSError, ValueError, Image.DecompressionBombError) as exc:
        raise FormatError(f"cannot decode image {name!r} ({exc})", path) from None
    return rgba


class Fields:
    """Little-endian fixed-layout reading of a header: ``u8/u16/u32/f32(offset)``."""

    def __init__(self, data: bytes, path: str, what: str):
        self.data, self.path, self.what = data, path, what

    def _get(self, fmt: str, offset: int) -> Any:
        size = np.dtype(fmt).itemsize
        if offset + size > len(self.data):
            raise FormatError(f"truncated {self.what}", self.path)
        return np.frombuffer(self.data, fmt, 1, offset)[0].item()

    def u8(self, offset: int) -> int:
        return int(self._get("u1", offset))

    def u16(self, offset: int) -> int:
        return int(self._get("<u2", offset))

    def u32(self, offset: int) -> int:
        return int(self._get("<u4", offset))

    def f32(self, offset: int) -> float:
        return float(self._get("<f4", offset))
