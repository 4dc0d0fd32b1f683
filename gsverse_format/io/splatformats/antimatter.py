"""``.splat``: the layout of antimatter15's WebGL splat viewer (also written by many tools).

A headerless array of 32-byte little-endian records, one per splat, in the 3DGS capture frame
(the PLY's frame: +Y down)::

    position  3 × float32     x, y, z
    scale     3 × float32     linear standard deviations (exp of the PLY's log-scales)
    colour    4 × uint8       r, g, b = 255 · (0.5 + SH_C0 · f_dc), clamped; a = 255 · opacity
    rotation  4 × uint8       (w, x, y, z) of the unit quaternion, 128 + 128 · q, clamped

Decoding: ``f_dc = (rgb / 255 − 0.5) / SH_C0``, ``opacity = a / 255``, ``q = (byte − 128) /
128`` then normalized (a zero quaternion — all four bytes 128 — is the identity). No SH beyond
degree 0. Quantization: colour and opacity steps of 1/255, quaternion components of 1/128
(≈ 0.45° of rotation).
"""
from __future__ import annotations

import os

import numpy as np

from ...errors import FormatError
from .common import Decoded, color_to_dc, splat_cloud
from .container import read_bytes

__all__ = ["RECORD", "read_antimatter_splat"]

#: One record of a ``.splat`` file.
RECORD = np.dtype([("position", "<f4", 3), ("scale", "<f4", 3), ("rgba", "u1", 4),
                   ("rotation", "u1", 4)])


def read_antimatter_splat(path: str | os.PathLike[str]) -> Decoded:
    """The splats of a ``.splat`` file, in the file's frame (the 3DGS frame)."""
    path = os.fspath(path)
    data = read_bytes(path)
    if len(data) % RECORD.itemsize:
        raise FormatError(f"{len(data)} bytes is not a whole number of 32-byte .splat records "
                          "(a truncated file, or not a .splat file)", path)
    rec = np.frombuffer(data, RECORD)
    rgba = rec["rgba"].astype(np.float64) / 255.0
    rot = (rec["rotation"].astype(np.float64) - 128.0) / 128.0
    sh = color_to_dc(rgba[:, :3])[:, None, :]
    cloud = splat_cloud(rec["position"], rot, rec["scale"], rgba[:, 3], sh, path)
    n = len(rec)
    return Decoded(cloud, "antimatter15 32-byte records",
                   {"position": 12 * n, "scale": 12 * n, "colour+opacity": 4 * n,
                    "rotation": 4 * n})
