"""Vertex-animation textures (VAT) in OpenEXR: reading and writing.

The layout is the one of the "soft body" VATs that Houdini's Labs Vertex Animation Textures
ROP, and the Unity and Unreal VAT shaders that play them, use: one texel per vertex and frame.

Layout (read and written)
-------------------------
* The image is ``W`` texels wide and ``H = T · R`` rows high for ``T`` frames of ``V``
  vertices, where ``R = ceil(V / W)`` is the number of rows one frame takes ("rows per frame").
  By default ``W = V`` (one row per frame) up to a width limit (8192, the largest texture width
  engines accept everywhere); a larger mesh wraps onto further rows.
* Vertex ``v`` of frame ``f`` is the texel in column ``v mod W`` of row ``f · R + v div W``.
  Row 0 is the first scanline of the EXR data window (the top of the image, EXR's increasing-Y
  line order); an engine with a bottom-left texture origin samples it at
  ``u = (column + 0.5) / W``, ``v = 1 − (row + 0.5) / H``. The texels after the last vertex of
  each frame's last row are 0.
* Channels ``R``, ``G``, ``B`` are ``x``, ``y``, ``z``, in the asset's frame (glTF: metres, +Y
  up; no axis change), as ``FLOAT`` (32-bit) or ``HALF`` (16-bit) pixels, ZIP compressed.
  With ``mode="position"`` they are positions, with ``mode="offset"`` offsets from the rest
  position of the vertex (the anchor mesh's rest pose; Houdini's default, which keeps HALF
  precision where the motion is small).
* ``normalized``: the values are stored as ``(value − boundsMin) / (boundsMax − boundsMin)``
  per component, in [0, 1] (for engines that store VATs in 8/16-bit formats; Houdini's
  "normalized" VATs); ``boundsMin``/``boundsMax`` are the header attributes below.

Header attributes written (all prefixed ``gsverseVat:``; the reader uses them when present and
the caller's arguments otherwise, so VATs from other tools read too):

=====================  =======  ============================================================
``version``            int      1
``mode``               string   ``position`` or ``offset``
``vertexCount``        int      V
``frameCount``         int      T
``rowsPerFrame``       int      R
``normalized``         int      1 when normalized, else 0
``boundsMin``          v3f      normalized VATs: the lower corner of the stored values
``boundsMax``          v3f      normalized VATs: the upper corner
``fps``                float    frames per second when the times are evenly spaced
``times``              string   the time of every frame in seconds, as a JSON list
=====================  =======  ============================================================
"""
from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from typing import Literal

import numpy as np

from ..atomic import atomic_write
from ..errors import FormatError, UsageError
from ..limits import MAX_VAT_WIDTH
from .caches import VertexCache

__all__ = ["write_vat", "read_vat", "vat_layout", "MAX_WIDTH", "PREFIX"]

MAX_WIDTH = 8192
PREFIX = "gsverseVat:"
Mode = Literal["position", "offset"]


def _openexr():
    try:
        import OpenEXR
    except ImportError:   # pragma: no cover - a dependency of the package
        raise UsageError("EXR vertex-animation textures need the Python package OpenEXR "
                         "(pip install OpenEXR)") from None
    return OpenEXR


def vat_layout(vertex_count: int, width: int | None = None) -> tuple[int, int]:
    """(width W, rows per frame R) for ``vertex_count`` vertices (see the module docstring)."""
    if vertex_count < 1:
        raise UsageError("a VAT needs at least one vertex")
    w = min(vertex_count, MAX_WIDTH) if width is None else int(width)
    if w < 1:
        raise UsageError(f"VAT width must be at least 1, got {w}")
    if w > MAX_VAT_WIDTH:
        raise UsageError(f"VAT width must be at most {MAX_VAT_WIDTH}, got {w}")
    return w, -(-vertex_count // w)


def write_vat(path: str | os.PathLike, times: np.ndarray, vertices: np.ndarray, *,
              rest: np.ndarray | None = None, mode: Mode = "position", half: bool = False,
              width: int | None = None, normalized: bool = False,
              protect: tuple[str | os.PathLike, ...] = ()) -> None:
    """Write poses ``vertices`` (T, V, 3) at ``times`` (T,) seconds as an EXR VAT, atomically.

    ``mode="offset"`` stores ``vertices − rest`` (``rest`` (V, 3) required); ``half`` stores
    16-bit floats; ``width`` overrides the texture width; ``normalized`` stores values scaled
    into [0, 1] with the bounds in the header.
    """
    OpenEXR = _openexr()
    v = np.asarray(vertices, dtype=np.float64)
    times = np.asarray(times, dtype=np.float64).reshape(-1)
    if v.ndim != 3 or v.shape[2] != 3 or len(times) != v.shape[0] or v.shape[0] == 0:
        raise UsageError(f"VAT poses must be (T, V, 3) with T times, got {v.shape} and "
                         f"{len(times)} times", path)
    if mode not in ("position", "offset"):
        raise UsageError(f"VAT mode must be 'position' or 'offset', not {mode!r}", path)
    if mode == "offset":
        if rest is None:
            raise UsageError("an offset VAT needs the rest positions", path)
        v = v - np.asarray(rest, dtype=np.float64)[None]
    frames, count = v.shape[0], v.shape[1]
    w, rows = vat_layout(count, width)
    attrs: dict = {"version": 1, "mode": mode, "vertexCount": count, "frameCount": frames,
                   "rowsPerFrame": rows, "normalized": int(bool(normalized)),
                   "times": json.dumps([float(t) for t in times])}
    if frames > 1:
        steps = np.diff(times)
        if np.allclose(steps, steps[0], rtol=1e-6, atol=0.0) and steps[0] > 0:
            attrs["fps"] = float(1.0 / steps[0])
    if normalized:
        lo, hi = v.min(axis=(0, 1)), v.max(axis=(0, 1))
        span = np.where(hi > lo, hi - lo, 1.0)
        v = (v - lo) / span
        attrs["boundsMin"] = lo.astype(np.float32)
        attrs["boundsMax"] = hi.astype(np.float32)
    dtype = np.float16 if half else np.float32
    if half and np.abs(v).max(initial=0.0) > np.finfo(np.float16).max:
        raise UsageError("values exceed the HALF range; write FLOAT, offsets or a normalized "
                         "VAT", path)
    image = np.zeros((frames, rows * w, 3), dtype)
    image[:, :count] = v.astype(dtype)
    image = image.reshape(frames * rows, w, 3)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    header.update({PREFIX + k: val for k, val in attrs.items()})
    spath = os.fspath(path)
    with tempfile.TemporaryDirectory(prefix="gsverse-vat-") as work:
        tmp = os.path.join(work, "vat.exr")   # OpenEXR writes by file name
        with OpenEXR.File(header, {"RGB": image}) as exr:
            exr.write(tmp)
        with open(tmp, "rb") as src, atomic_write(spath, "wb", protect=protect) as dst:
            shutil.copyfileobj(src, dst, 1 << 20)


def _attr(header: dict, key: str):
    return header.get(PREFIX + key)


def read_vat(path: str | os.PathLike, *, rest: np.ndarray | None = None,
             vertex_count: int | None = None, mode: Mode | None = None,
             bounds: tuple | None = None, fps: float = 24.0) -> VertexCache:
    """Read an EXR VAT (the layout of the module docstring) into a :class:`VertexCache` of
    positions.

    The header's ``gsverseVat:`` attributes win; for VATs of other tools give
    ``vertex_count`` (default: the width, one row per frame), ``mode`` (default ``position``),
    ``bounds`` ((min xyz), (max xyz)) for normalized textures, and ``fps`` (frames ``1/fps``
    apart). Offsets need ``rest`` (V, 3). :class:`FormatError` naming ``path`` for a file that
    is not such a VAT.
    """
    OpenEXR = _openexr()
    spath = os.fspath(path)
    try:
        with OpenEXR.File(spath) as exr:
            header = dict(exr.header())
            channels = exr.channels()
            if "RGB" in channels:
                pixels = np.asarray(channels["RGB"].pixels, dtype=np.float64)
            elif all(c in channels for c in "RGB"):
                pixels = np.stack([np.asarray(channels[c].pixels, dtype=np.float64)
                                   for c in "RGB"], axis=-1)
            else:
                raise FormatError(f"the EXR has no R, G, B channels (it has "
                                  f"{', '.join(channels) or 'none'})", spath)
    except FormatError:
        raise
    except Exception as err:   # OpenEXR raises plain exceptions for unreadable files
        raise FormatError(f"cannot read EXR: {' '.join(str(err).split())}", spath) from None
    if pixels.ndim != 3 or pixels.shape[2] < 3:
        raise FormatError(f"unexpected EXR pixel layout {pixels.shape}", spath)
    height, w = pixels.shape[:2]
    count = _attr(header, "vertexCount") or vertex_count or w
    count = int(count)
    mode = _attr(header, "mode") or mode or "position"
    if mode not in ("position", "offset"):
        raise FormatError(f"unknown VAT mode {mode!r}", spath)
    rows = int(_attr(header, "rowsPerFrame") or -(-count // w))
    if rows * w < count:
        raise FormatError(f"{rows} row(s) of {w} texels per frame cannot hold {count} vertices",
                          spath)
    if height % rows:
        raise FormatError(f"the image has {height} rows, not a multiple of {rows} rows per "
                          f"frame ({count} vertices in rows of {w})", spath)
    frames = height // rows
    values = pixels[:, :, :3].reshape(frames, rows * w, 3)[:, :count]
    if int(_attr(header, "normalized") or 0) or (bounds is not None
                                                 and _attr(header, "normalized") is None):
        lo = _attr(header, "boundsMin")
        hi = _attr(header, "boundsMax")
        if lo is None or hi is None:
            if bounds is None:
                raise FormatError("a normalized VAT needs its bounds (boundsMin/boundsMax)",
                                  spath)
            lo, hi = bounds
        lo = np.asarray(lo, dtype=np.float64).reshape(3)
        hi = np.asarray(hi, dtype=np.float64).reshape(3)
        values = lo + values * np.where(hi > lo, hi - lo, 0.0)
    if mode == "offset":
        if rest is None:
            raise UsageError("an offset VAT needs the rest positions of its mesh", spath)
        rest = np.asarray(rest, dtype=np.float64)
        if rest.shape != (count, 3):
            raise FormatError(f"the VAT has {count} vertices but the rest mesh has "
                              f"{len(rest)}", spath)
        values = values + rest[None]
    times_text = _attr(header, "times")
    try:
        times = (np.asarray(json.loads(times_text), dtype=np.float64) if times_text
                 else None)
    except (ValueError, TypeError):
        raise FormatError("the gsverseVat:times attribute is not a JSON list of numbers",
                          spath) from None
    if times is None or len(times) != frames:
        rate = float(_attr(header, "fps") or fps)
        if not (math.isfinite(rate) and rate > 0):
            raise FormatError(f"bad frame rate {rate}", spath)
        times = np.arange(frames, dtype=np.float64) / rate
    try:
        return VertexCache(times, values, spath)
    except FormatError as err:
        raise FormatError(err.cause, spath) from None
