"""Compiled (numba) twins of the projection and the tile compositing of the reference renderer.

:func:`project_kernel` is :func:`gsverse_format.render.project_reference.project` per Gaussian
(same formulas, float64, parallel over Gaussians); :func:`bin_tiles` lists, per 16×16 tile, the
Gaussians whose footprint touches it in front-to-back order; :func:`composite_tiles` blends
each tile's list (parallel over tiles) with the rules of
:func:`gsverse_format.render.raster.composite_reference`: within a tile it walks the list once,
each Gaussian visiting only the pixels where its alpha can reach 1/255, with per-pixel
transmittance and termination flags, so every pixel still sees its Gaussians front to back.
Compiled code is cached on disk.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

__all__ = ["project_kernel", "bin_tiles", "composite_tiles"]

_C0 = 0.28209479177387814
_C1 = 0.4886025119029199
_C2 = (1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792,
       0.5462742152960396)
_C3 = (-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154,
       -0.4570457994644658, 1.445305721320277, -0.5900435899266435)


@njit(cache=True, parallel=True)
def project_kernel(means, cov, sh, rot, eye, fx, fy, cx, cy, limx, limy, near, far, dilation,
                   extent_sigma, min_extent, means2d, conics, depths, radii, colors):
    n = means.shape[0]
    k = sh.shape[1]
    for i in prange(n):
        px = means[i, 0] - eye[0]
        py = means[i, 1] - eye[1]
        pz = means[i, 2] - eye[2]
        tx = rot[0, 0] * px + rot[0, 1] * py + rot[0, 2] * pz
        ty = rot[1, 0] * px + rot[1, 1] * py + rot[1, 2] * pz
        tz = rot[2, 0] * px + rot[2, 1] * py + rot[2, 2] * pz
        depths[i] = tz
        radii[i] = 0
        if not (tz > near and tz < far):
            continue
        txc = min(max(tx / tz, -1.3 * limx), 1.3 * limx) * tz
        tyc = min(max(ty / tz, -1.3 * limy), 1.3 * limy) * tz
        j00 = fx / tz
        j02 = -fx * txc / (tz * tz)
        j11 = fy / tz
        j12 = -fy * tyc / (tz * tz)
        # M = J R (2x3)
        m0 = np.empty(3)
        m1 = np.empty(3)
        for c in range(3):
            m0[c] = j00 * rot[0, c] + j02 * rot[2, c]
            m1[c] = j11 * rot[1, c] + j12 * rot[2, c]
        a = 0.0
        b = 0.0
        cc = 0.0
        for r in range(3):
            s0 = 0.0
            s1 = 0.0
            for c in range(3):
                s0 += cov[i, r, c] * m0[c]
                s1 += cov[i, r, c] * m1[c]
            a += m0[r] * s0
            b += m0[r] * s1
            cc += m1[r] * s1
        a += dilation
        cc += dilation
        det = a * cc - b * b
        if not det > 0.0:
            continue
        conics[i, 0] = cc / det
        conics[i, 1] = -b / det
        conics[i, 2] = a / det
        mid = 0.5 * (a + cc)
        lam1 = mid + math.sqrt(max(0.1, mid * mid - det))
        if min_extent > 0.0 and math.sqrt(max(lam1, 0.0)) < min_extent:
            continue
        radii[i] = np.int32(math.ceil(extent_sigma * math.sqrt(max(lam1, 0.0))))
        means2d[i, 0] = fx * tx / tz + cx
        means2d[i, 1] = fy * ty / tz + cy
        norm = math.sqrt(px * px + py * py + pz * pz)
        if norm < 1e-30:
            norm = 1e-30
        x = px / norm
        y = py / norm
        z = pz / norm
        for ch in range(3):
            v = 0.5 + _C0 * sh[i, 0, ch]
            if k >= 4:
                v += -_C1 * y * sh[i, 1, ch] + _C1 * z * sh[i, 2, ch] - _C1 * x * sh[i, 3, ch]
            if k >= 9:
                xx = x * x
                yy = y * y
                zz = z * z
                v += (_C2[0] * x * y * sh[i, 4, ch] + _C2[1] * y * z * sh[i, 5, ch]
                      + _C2[2] * (2 * zz - xx - yy) * sh[i, 6, ch] + _C2[3] * x * z * sh[i, 7, ch]
                      + _C2[4] * (xx - yy) * sh[i, 8, ch])
                if k >= 16:
                    v += (_C3[0] * y * (3 * xx - yy) * sh[i, 9, ch]
                          + _C3[1] * x * y * z * sh[i, 10, ch]
                          + _C3[2] * y * (4 * zz - xx - yy) * sh[i, 11, ch]
                          + _C3[3] * z * (2 * zz - 3 * xx - 3 * yy) * sh[i, 12, ch]
                          + _C3[4] * x * (4 * zz - xx - yy) * sh[i, 13, ch]
                          + _C3[5] * z * (xx - yy) * sh[i, 14, ch]
                          + _C3[6] * x * (xx - 3 * yy) * sh[i, 15, ch])
            colors[i, ch] = max(v, 0.0)


@njit(cache=True)
def bin_tiles(order, rects, tiles_x, n_tiles):
    """(offsets (T+1,), ids) with ids[offsets[t]:offsets[t+1]] the Gaussians touching tile t in
    the order of ``order`` (front to back)."""
    counts = np.zeros(n_tiles + 1, np.int64)
    for j in range(order.shape[0]):
        i = order[j]
        for ty in range(rects[i, 1], rects[i, 3]):
            for tx in range(rects[i, 0], rects[i, 2]):
                counts[ty * tiles_x + tx + 1] += 1
    offsets = np.cumsum(counts)
    ids = np.empty(offsets[-1], np.int32)
    fill = offsets[:-1].copy()
    for j in range(order.shape[0]):
        i = order[j]
        for ty in range(rects[i, 1], rects[i, 3]):
            for tx in range(rects[i, 0], rects[i, 2]):
                t = ty * tiles_x + tx
                ids[fill[t]] = i
                fill[t] += 1
    return offsets, ids


@njit(cache=True, parallel=True)
def composite_tiles(offsets, ids, means2d, conics, opacities, colors, depths, width, height,
                    tile, tiles_x, cutoff2, min_alpha, max_alpha, min_t, rgb, alpha, depth):
    """Front-to-back blending per pixel: C = Σ c_i α_i T_i, T_{i+1} = T_i (1 − α_i),
    α_i = min(max_alpha, o_i exp(−½ dᵀ Σ'⁻¹ d)); α_i < min_alpha is skipped; a pixel stops
    before the Gaussian that would take T below ``min_t``. Writes premultiplied colour, alpha
    = 1 − T and the α-weighted depth Σ z_i α_i T_i (divided by the alpha later)."""
    n_tiles = offsets.shape[0] - 1
    for t in prange(n_tiles):
        ty0 = (t // tiles_x) * tile
        tx0 = (t % tiles_x) * tile
        ty1 = min(ty0 + tile, height)
        tx1 = min(tx0 + tile, width)
        tw = tx1 - tx0
        npix = (ty1 - ty0) * tw
        # Splat-major within the tile (per pixel the order is the same front-to-back order):
        # each Gaussian visits only the pixels of the bounding box of the ellipse outside of
        # which its alpha is below min_alpha (or beyond the cutoff), plus one pixel of margin.
        tr = np.ones(npix)
        acc = np.zeros((npix, 4))
        done = np.zeros(npix, np.bool_)
        ndone = 0
        for j in range(offsets[t], offsets[t + 1]):
            i = ids[j]
            op = opacities[i]
            if not op * 1.0 >= min_alpha:
                continue
            k2 = min(2.0 * math.log(op / min_alpha), cutoff2)
            ca = conics[i, 0]
            cb = conics[i, 1]
            cc = conics[i, 2]
            det = ca * cc - cb * cb
            if not det > 0.0:
                continue
            hx = math.sqrt(k2 * cc / det) + 1.0
            hy = math.sqrt(k2 * ca / det) + 1.0
            mx = means2d[i, 0]
            my = means2d[i, 1]
            x0 = max(tx0, int(math.floor(mx - hx - 0.5)))
            x1 = min(tx1, int(math.ceil(mx + hx + 0.5)))
            y0 = max(ty0, int(math.floor(my - hy - 0.5)))
            y1 = min(ty1, int(math.ceil(my + hy + 0.5)))
            for py in range(y0, y1):
                dy = my - (py + 0.5)
                row = (py - ty0) * tw - tx0
                for px in range(x0, x1):
                    q = row + px
                    if done[q]:
                        continue
                    dx = mx - (px + 0.5)
                    power = -0.5 * (ca * dx * dx + cc * dy * dy) - cb * dx * dy
                    if power > 0.0:
                        continue
                    if -2.0 * power > cutoff2:
                        continue
                    a = min(max_alpha, op * math.exp(power))
                    if a < min_alpha:
                        continue
                    t0 = tr[q]
                    test_t = t0 * (1.0 - a)
                    if test_t < min_t:
                        done[q] = True
                        ndone += 1
                        continue
                    w = a * t0
                    acc[q, 0] += colors[i, 0] * w
                    acc[q, 1] += colors[i, 1] * w
                    acc[q, 2] += colors[i, 2] * w
                    acc[q, 3] += depths[i] * w
                    tr[q] = test_t
            if ndone == npix:
                break
        for py in range(ty0, ty1):
            for px in range(tx0, tx1):
                q = (py - ty0) * tw + px - tx0
                rgb[py, px, 0] = acc[q, 0]
                rgb[py, px, 1] = acc[q, 1]
                rgb[py, px, 2] = acc[q, 2]
                alpha[py, px] = 1.0 - tr[q]
                depth[py, px] = acc[q, 3]
