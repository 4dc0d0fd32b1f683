"""Compressed PLY: the packed layout PlayCanvas SuperSplat and splat-transform write
(usually named ``*.compressed.ply``).

A binary little-endian PLY (read with the PLY container, :mod:`gsverse_format.io.ply.
container`, which knows nothing of splats) with three elements, in the 3DGS capture frame
(+Y down, like any 3DGS PLY):

* ``chunk``, one row per 256 splats (splat ``i`` uses chunk ``i // 256``): float bounds
  ``min_x..max_z`` of the positions, ``min_scale_x..max_scale_z`` of the log-scales and,
  in newer files, ``min_r..max_b`` of the colours;
* ``vertex``, four ``uint`` per splat:

  ================ ===========================================================================
  packed_position  11-10-11 bits (x high): ``lerp(min, max, field / (2^bits − 1))``
  packed_rotation  2 bits: index of the largest component of ``(w, x, y, z)`` (rebuilt from
                   the unit norm); three 10-bit fields, the others in order:
                   ``(field / 1023 − 0.5) · √2``
  packed_scale     11-10-11 bits of the log-scales, as positions; ``scale = exp(value)``
  packed_color     8-8-8-8 bits r, g, b, a (r high): colour ``lerp(min, max, byte / 255)``
                   (the byte / 255 itself without colour bounds), ``f_dc = (colour − 0.5) /
                   SH_C0``; ``opacity = a / 255``
  ================ ===========================================================================

* ``sh`` (optional), ``uchar f_rest_0..`` in the channel-major order of 3DGS PLY (9, 24 or 45
  of them): ``(t − 0.5) · 8`` with ``t = 0`` for byte 0, 1 for 255 and ``(byte + 0.5) / 256``
  otherwise.

Quantization: positions and log-scales 1/2047 (x, z) and 1/1023 (y) of each chunk's range;
rotation components ≈ 1/723; colour and opacity 1/255; SH 8/256.
"""
from __future__ import annotations

import os

import numpy as np

from ...errors import FormatError, GsverseError
from ..ply.container import read_ply_elements
from ..ply.header import read_ply_header
from .common import Decoded, color_to_dc, sh_rest_index, splat_cloud

__all__ = ["is_compressed_ply", "read_compressed_ply"]

_SQRT2 = float(np.sqrt(2.0))
_PACKED = ("packed_position", "packed_rotation", "packed_scale", "packed_color")
_CHUNK = ("min_x", "min_y", "min_z", "max_x", "max_y", "max_z", "min_scale_x", "min_scale_y",
          "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z")
_SH_DEGREE = {0: 0, 9: 1, 24: 2, 45: 3}


def is_compressed_ply(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a PLY file with a ``chunk`` element and packed vertices (False for
    anything unreadable: the PLY reader then reports it)."""
    try:
        with open(path, "rb") as f:
            if f.read(4) != b"ply\n":
                return False
        header = read_ply_header(path)
    except (OSError, GsverseError):
        return False
    vertex = header.element("vertex")
    return header.element("chunk") is not None and vertex is not None \
        and "packed_position" in vertex.names


def _unorm(value: np.ndarray, shift: int, bits: int) -> np.ndarray:
    return ((value >> shift) & ((1 << bits) - 1)).astype(np.float64) / ((1 << bits) - 1)


def _lerp(lo: np.ndarray, hi: np.ndarray, t: np.ndarray) -> np.ndarray:
    return lo * (1.0 - t) + hi * t


def read_compressed_ply(path: str | os.PathLike[str]) -> Decoded:
    """The splats of a compressed PLY, in the file's frame (the 3DGS frame)."""
    path = os.fspath(path)
    ply = read_ply_elements(path)
    if "chunk" not in ply or "vertex" not in ply:
        raise FormatError("a compressed PLY needs the elements 'chunk' and 'vertex'", path)
    chunk, vertex = ply["chunk"], ply["vertex"]
    missing = [p for p in _PACKED if p not in (vertex.dtype.names or ())] + \
        [p for p in _CHUNK if p not in (chunk.dtype.names or ())]
    if missing:
        raise FormatError(f"compressed PLY without property {missing[0]!r}", path)
    for element, el_name in ((chunk, "chunk"), (vertex, "vertex")) + \
            (((ply["sh"], "sh"),) if "sh" in ply else ()):
        for name in element.dtype.names or ():
            kind = element.dtype[name]
            if kind.shape != () or kind.kind not in "iuf":   # a list property
                raise FormatError(f"compressed PLY property {el_name} {name!r} must be a "
                                  f"number, not a list", path)
    n = len(vertex)
    if len(chunk) * 256 < n:
        raise FormatError(f"{len(chunk)} chunks cover {len(chunk) * 256} splats, the file has "
                          f"{n}", path)
    ci = np.arange(n) >> 8
    c = {name: chunk[name].astype(np.float64)[ci] for name in chunk.dtype.names or ()}
    pp, pr, ps, pc = (vertex[p].astype(np.uint32) for p in _PACKED)
    means = np.stack([_lerp(c["min_x"], c["max_x"], _unorm(pp, 21, 11)),
                      _lerp(c["min_y"], c["max_y"], _unorm(pp, 11, 10)),
                      _lerp(c["min_z"], c["max_z"], _unorm(pp, 0, 11))], axis=1)
    log_scales = np.stack([_lerp(c["min_scale_x"], c["max_scale_x"], _unorm(ps, 21, 11)),
                           _lerp(c["min_scale_y"], c["max_scale_y"], _unorm(ps, 11, 10)),
                           _lerp(c["min_scale_z"], c["max_scale_z"], _unorm(ps, 0, 11))], axis=1)
    abc = np.stack([(_unorm(pr, s, 10) - 0.5) * _SQRT2 for s in (20, 10, 0)], axis=1)
    largest = (pr >> 30).astype(np.intp)
    rest = 1.0 - (abc * abc).sum(axis=1)
    wxyz = np.zeros((n, 4))
    others = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])[largest]
    rows = np.arange(n)[:, None]
    wxyz[rows, others] = abc
    wxyz[np.arange(n), largest] = np.sqrt(np.maximum(0.0, rest))
    rgb = np.stack([_unorm(pc, s, 8) for s in (24, 16, 8)], axis=1)
    if all(k in c for k in ("min_r", "min_g", "min_b", "max_r", "max_g", "max_b")):
        rgb = np.stack([_lerp(c[f"min_{k}"], c[f"max_{k}"], rgb[:, i])
                        for i, k in enumerate("rgb")], axis=1)
    opacity = _unorm(pc, 0, 8)
    degree = 0
    sh_rest = None
    if "sh" in ply:
        sh_el = ply["sh"]
        names = [f"f_rest_{i}" for i in range(len(sh_el.dtype.names or ()))]
        if len(sh_el) != n or set(names) != set(sh_el.dtype.names or ()) \
                or len(names) not in _SH_DEGREE:
            raise FormatError(f"the 'sh' element must hold f_rest_0.. (9, 24 or 45 of them) for "
                              f"each of the {n} splats", path)
        degree = _SH_DEGREE[len(names)]
        raw = np.stack([sh_el[name].astype(np.float64) for name in names], axis=1)
        t = np.where(raw == 0, 0.0, np.where(raw == 255, 1.0, (raw + 0.5) / 256.0))
        sh_rest = (t - 0.5) * 8.0
    sh = np.zeros((n, (degree + 1) ** 2, 3))
    sh[:, 0] = color_to_dc(rgb)
    if sh_rest is not None:
        coeff, channel = sh_rest_index(degree)
        sh[:, coeff, channel] = sh_rest
    cloud = splat_cloud(means, wxyz, np.exp(log_scales), opacity, sh, path)
    parts = {"header": 0, "chunk": chunk.nbytes, "vertex": vertex.nbytes}
    if "sh" in ply:
        parts["sh"] = ply["sh"].nbytes
    parts["header"] = max(0, os.path.getsize(path) - sum(parts.values()))
    return Decoded(cloud, "compressed PLY", parts)
