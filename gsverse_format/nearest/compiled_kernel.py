"""Compiled point–triangle kernel of the exact nearest-triangle search (numba).

The scalar building blocks of :mod:`gsverse_format.nearest.compiled`: the distance kernel, the
per-face records it reads, and the float32 rounding helpers of the tree (the atomic counter
that hands out work is :func:`gsverse_format.compiled_chunks.fetch_add`).

Point–triangle distance
    The kernel is a scalar transcription of the reference kernel (``_face_table`` and
    ``_kernel`` in :mod:`gsverse_format.nearest.reference`): the same per-face constants (``a``,
    ``ab``, ``ac``, the dual basis ``e_v``, ``e_w`` and the degenerate flag), the same
    Voronoi-region precedence (vertex A, vertex B, edge AB, vertex C, edge AC, edge BC, face),
    the same edge-segment fallback for degenerate triangles and for face-region results outside
    the simplex, and the same order of every floating-point operation. Compiled without
    fast-math, nothing is reassociated or fused, so each distance equals the reference's in
    float64.

Face record (one row of :data:`RECORD_WIDTH` float64 per face): ``a`` (0:3), ``ab`` (3:6),
``ac`` (6:9), ``e_v`` (9:12), ``e_w`` (12:15) and the degenerate flag (15).

Compiled code is cached on disk (``cache=True``). Numba checks only a function's own source
file for changes: after editing this module, delete the cached ``compiled.*`` entries of
:mod:`gsverse_format.nearest.compiled` (``__pycache__`` next to it, or under
``NUMBA_CACHE_DIR``), since they inline these functions.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..backend import configure_numba
from .reference import DEGENERATE_RATIO

configure_numba()

__all__ = ["RECORD_WIDTH", "min3", "max3", "f32_down", "f32_up", "closest_point",
           "face_record", "face_records"]

#: float64 columns of a face record.
RECORD_WIDTH = 16
_R_DEG = 15               # column of the degenerate flag

# --------------------------------------------------------------------------- helpers

@njit(cache=True, inline="always")
def _nanmax(a, b):
    """``np.maximum`` for scalars (NaN propagates)."""
    if a != a or b != b:
        return np.nan
    return a if a >= b else b


@njit(cache=True, inline="always")
def _clip01(t):
    return min(max(t, 0.0), 1.0)


@njit(cache=True, inline="always")
def min3(a: float, b: float, c: float) -> float:
    return min(min(a, b), c)


@njit(cache=True, inline="always")
def max3(a: float, b: float, c: float) -> float:
    return max(max(a, b), c)


_F32_MAX = 3.4028234663852886e38
_F32_TINY = 1.1754943508222875e-38        # smallest normal float32


@njit(cache=True, inline="always")
def f32_down(x: float) -> np.float32:
    """A float32 not above ``x`` (the nearest one, or up to two steps below it).

    ``g - |g| 2^-23`` is exact in float64 and lies one to two float32 steps below ``g``, so
    its rounding is at or below ``g``'s predecessor, which is below ``x`` when ``g > x`` (for
    normal ``g``; zero, subnormals and overflow take ``nextafter``).
    """
    f = np.float32(x)
    g = np.float64(f)
    if g > x:
        if _F32_TINY <= abs(g) <= _F32_MAX:
            f = np.float32(g - abs(g) * 1.1920928955078125e-07)
        else:
            f = np.nextafter(f, np.float32(-np.inf))
    return f


@njit(cache=True, inline="always")
def f32_up(x: float) -> np.float32:
    """A float32 not below ``x`` (mirror of :func:`f32_down`)."""
    f = np.float32(x)
    g = np.float64(f)
    if g < x:
        if _F32_TINY <= abs(g) <= _F32_MAX:
            f = np.float32(g + abs(g) * 1.1920928955078125e-07)
        else:
            f = np.nextafter(f, np.float32(np.inf))
    return f


# --------------------------------------------------------------------------- kernel

@njit(cache=True)
def _segments(apx, apy, apz, abx, aby, abz, acx, acy, acz, abab, acac):
    """Closest point among the three edges as (v, w): the reference ``_segments``, scalar."""
    t1 = (abx * apx + aby * apy + abz * apz) / abab if abab > 0 else 0.0
    t1 = _clip01(t1)
    ex, ey, ez = apx - t1 * abx, apy - t1 * aby, apz - t1 * abz
    best = ex * ex + ey * ey + ez * ez
    v, w = t1, 0.0
    t2 = (acx * apx + acy * apy + acz * apz) / acac if acac > 0 else 0.0
    t2 = _clip01(t2)
    ex, ey, ez = apx - t2 * acx, apy - t2 * acy, apz - t2 * acz
    d2 = ex * ex + ey * ey + ez * ez
    if d2 < best:
        best = d2
        v, w = 0.0, t2
    bcx, bcy, bcz = acx - abx, acy - aby, acz - abz
    bpx, bpy, bpz = apx - abx, apy - aby, apz - abz
    bcbc = bcx * bcx + bcy * bcy + bcz * bcz
    t3 = (bcx * bpx + bcy * bpy + bcz * bpz) / bcbc if bcbc > 0 else 0.0
    t3 = _clip01(t3)
    ex, ey, ez = bpx - t3 * bcx, bpy - t3 * bcy, bpz - t3 * bcz
    d2 = ex * ex + ey * ey + ez * ez
    if d2 < best:
        v, w = 1.0 - t3, t3
    return v, w


@njit(cache=True)
def closest_point(r: np.ndarray, px: float, py: float, pz: float) -> tuple[float, float, float]:
    """(v, w, squared distance) of the closest point of face record ``r`` to ``p``.

    Scalar transcription of the reference ``_kernel``: the region tests in order of precedence,
    every expression in the reference's operation order.
    """
    ax, ay, az = r[0], r[1], r[2]
    abx, aby, abz = r[3], r[4], r[5]
    acx, acy, acz = r[6], r[7], r[8]
    apx, apy, apz = px - ax, py - ay, pz - az
    abab = abx * abx + aby * aby + abz * abz
    acac = acx * acx + acy * acy + acz * acz
    if r[_R_DEG] != 0.0:
        v, w = _segments(apx, apy, apz, abx, aby, abz, acx, acy, acz, abab, acac)
    else:
        abac = abx * acx + aby * acy + abz * acz
        d1 = abx * apx + aby * apy + abz * apz
        d2 = acx * apx + acy * apy + acz * apz
        d3 = d1 - abab
        d4 = d2 - abac
        d5 = d1 - abac
        d6 = d2 - acac
        if d1 <= 0 and d2 <= 0:                                        # vertex A
            v, w = 0.0, 0.0
        elif d3 >= 0 and d4 <= d3:                                     # vertex B
            v, w = 1.0, 0.0
        elif (d1 * d4 - d3 * d2) <= 0 and d1 >= 0 and d3 <= 0:         # edge AB
            den = d1 - d3
            v, w = _clip01(d1 / den if den > 0 else 0.0), 0.0
        elif d6 >= 0 and d5 <= d6:                                     # vertex C
            v, w = 0.0, 1.0
        elif (d5 * d2 - d1 * d6) <= 0 and d2 >= 0 and d6 <= 0:         # edge AC
            den = d2 - d6
            v, w = 0.0, _clip01(d2 / den if den > 0 else 0.0)
        else:
            e43, e56 = d4 - d3, d5 - d6
            if (d3 * d6 - d5 * d4) <= 0 and e43 >= 0 and e56 >= 0:     # edge BC
                den = e43 + e56
                t = _clip01(e43 / den if den > 0 else 0.0)
                v, w = 1.0 - t, t
            else:                                                      # face
                v = apx * r[9] + apy * r[10] + apz * r[11]
                w = apx * r[12] + apy * r[13] + apz * r[14]
                if not (v >= 0 and w >= 0 and v + w <= 1):
                    v, w = _segments(apx, apy, apz, abx, aby, abz, acx, acy, acz, abab, acac)
    cx = ax + v * abx + w * acx
    cy = ay + v * aby + w * acy
    cz = az + v * abz + w * acz
    ex, ey, ez = px - cx, py - cy, pz - cz
    return v, w, ex * ex + ey * ey + ez * ez



# --------------------------------------------------------------------------- face records

@njit(cache=True)
def face_record(V: np.ndarray, F: np.ndarray, f: int, r: np.ndarray) -> tuple[float, float, float]:
    """Kernel constants of face ``f`` into ``r`` (the arithmetic of the reference ``_face_table``).

    Returns the (unnormalised) normal ``ab × ac``.
    """
    i0, i1, i2 = F[f, 0], F[f, 1], F[f, 2]
    ax, ay, az = V[i0, 0], V[i0, 1], V[i0, 2]
    abx, aby, abz = V[i1, 0] - ax, V[i1, 1] - ay, V[i1, 2] - az
    acx, acy, acz = V[i2, 0] - ax, V[i2, 1] - ay, V[i2, 2] - az
    abab = abx * abx + aby * aby + abz * abz
    acac = acx * acx + acy * acy + acz * acz
    nx = aby * acz - abz * acy
    ny = abz * acx - abx * acz
    nz = abx * acy - aby * acx
    nn = nx * nx + ny * ny + nz * nz
    bcx, bcy, bcz = acx - abx, acy - aby, acz - abz
    lmax2 = _nanmax(_nanmax(abab, acac), bcx * bcx + bcy * bcy + bcz * bcz)
    t = DEGENERATE_RATIO * lmax2
    regular = np.isfinite(nn) and nn > t * t
    inv = 1.0 / nn if regular else 0.0
    r[0], r[1], r[2] = ax, ay, az
    r[3], r[4], r[5] = abx, aby, abz
    r[6], r[7], r[8] = acx, acy, acz
    r[9] = (acy * nz - acz * ny) * inv
    r[10] = (acz * nx - acx * nz) * inv
    r[11] = (acx * ny - acy * nx) * inv
    r[12] = (ny * abz - nz * aby) * inv
    r[13] = (nz * abx - nx * abz) * inv
    r[14] = (nx * aby - ny * abx) * inv
    r[15] = 0.0 if regular else 1.0
    return nx, ny, nz


@njit(cache=True)
def face_records(V: np.ndarray, F: np.ndarray, face_of: np.ndarray, rec: np.ndarray) -> None:
    """Kernel constants of face ``face_of[k]`` into ``rec[k]``."""
    for k in range(face_of.shape[0]):
        face_record(V, F, face_of[k], rec[k])
