"""Depth-sorted front-to-back alpha compositing on 16×16 tiles: the reference (numpy) and the
dispatch to the compiled path.

Order: Gaussians are drawn front to back by camera depth of their mean (a stable sort, so
equal depths keep file order). Each pixel (centre at half-integers) blends the Gaussians whose
tile rectangle (:func:`~gsverse_format.render.project_reference.tile_rects`) covers its tile:
α = min(0.99, opacity · exp(−½ dᵀ Σ'⁻¹ d)); α < 1/255 is skipped; colour accumulates
c α T and transmittance T ← T (1 − α); the pixel stops (early termination) before a Gaussian
that would bring T below 10⁻⁴ — exactly the rules of the 3DGS rasterizer.

Outputs (:class:`Image`): premultiplied colour in the splats' own colour encoding (see
:mod:`gsverse_format.render.output`), alpha = 1 − T, and depth = the α-weighted mean camera z of
what was drawn (+inf where nothing was).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..atomic import interruptions_immediate
from ..backend import resolve_backend
from .camera import Camera
from .project_reference import TILE, Projected, Settings, project, tile_rects

__all__ = ["Image", "render_gaussians", "composite_reference", "project_fast"]


@dataclass
class Image:
    """A rendered image: ``rgb`` (H, W, 3) premultiplied, ``alpha`` (H, W), ``depth`` (H, W)
    (camera z, +inf where empty); float32. ``color_space`` is the splats' KHR colour space."""

    rgb: np.ndarray
    alpha: np.ndarray
    depth: np.ndarray
    color_space: str = "srgb_rec709_display"


def project_fast(means, covariances, sh, camera: Camera, settings: Settings = Settings()) -> Projected:
    """The compiled projection (:func:`project_compiled.project_kernel`), same output as
    :func:`project_reference.project`."""
    n = len(means)
    means2d = np.zeros((n, 2))
    conics = np.zeros((n, 3))
    depths = np.zeros(n)
    radii = np.zeros(n, np.int32)
    colors = np.zeros((n, 3))
    fx, fy = camera.focal
    cx, cy = camera.center
    limx, limy = camera.tan_half_fov
    with interruptions_immediate():   # compiled code: no Python handler may raise inside
        from .project_compiled import project_kernel

        project_kernel(np.ascontiguousarray(means, np.float64),
                       np.ascontiguousarray(covariances, np.float64),
                       np.ascontiguousarray(sh, np.float32), camera.rotation(),
                       np.asarray(camera.eye, np.float64), fx, fy, cx, cy, limx, limy,
                       camera.near, camera.far, settings.dilation, settings.extent_sigma,
                       settings.min_extent, means2d, conics, depths, radii, colors)
    return Projected(means2d, conics, depths, radii, colors, radii > 0)


def _order(p: Projected) -> np.ndarray:
    idx = np.flatnonzero(p.valid)
    return idx[np.argsort(p.depths[idx], kind="stable")].astype(np.int64)


def composite_reference(p: Projected, opacities: np.ndarray, camera: Camera,
                        settings: Settings = Settings()) -> Image:
    """Plain numpy compositing (one Gaussian at a time over the pixels of its tiles)."""
    w, h = camera.width, camera.height
    rects = tile_rects(p.means2d, p.radii, p.valid, w, h)
    rgb = np.zeros((h, w, 3))
    depth = np.zeros((h, w))
    trans = np.ones((h, w))
    done = np.zeros((h, w), bool)
    cut2 = np.inf if settings.cutoff is None else settings.cutoff ** 2
    op = np.asarray(opacities, np.float64)
    for i in _order(p):
        x0, y0, x1, y1 = (int(v) for v in rects[i])
        if x1 <= x0 or y1 <= y0:
            continue
        xs = slice(x0 * TILE, min(x1 * TILE, w))
        ys = slice(y0 * TILE, min(y1 * TILE, h))
        gx = np.arange(xs.start, xs.stop) + 0.5
        gy = np.arange(ys.start, ys.stop) + 0.5
        dx = p.means2d[i, 0] - gx[None, :]
        dy = p.means2d[i, 1] - gy[:, None]
        a_, b_, c_ = p.conics[i]
        power = -0.5 * (a_ * dx * dx + c_ * dy * dy) - b_ * dx * dy
        alpha = np.minimum(settings.max_alpha, op[i] * np.exp(np.minimum(power, 0.0)))
        use = (power <= 0.0) & (-2.0 * power <= cut2) & (alpha >= settings.min_alpha) & ~done[ys, xs]
        t = trans[ys, xs]
        test = t * (1.0 - alpha)
        stop = use & (test < settings.min_transmittance)
        done[ys, xs] |= stop
        use &= ~stop
        wgt = np.where(use, alpha * t, 0.0)
        rgb[ys, xs] += wgt[..., None] * p.colors[i]
        depth[ys, xs] += wgt * p.depths[i]
        trans[ys, xs] = np.where(use, test, t)
    return _finish(rgb, 1.0 - trans, depth)


def _finish(rgb, alpha, zsum, color_space: str = "srgb_rec709_display") -> Image:
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = np.where(alpha > 0, zsum / alpha, np.inf)
    return Image(rgb.astype(np.float32), alpha.astype(np.float32), depth.astype(np.float32), color_space)


def render_gaussians(means: np.ndarray, covariances: np.ndarray, opacities: np.ndarray,
                     sh: np.ndarray, camera: Camera, settings: Settings = Settings(), *,
                     backend: str = "auto", color_space: str = "srgb_rec709_display") -> Image:
    """Render Gaussians (means (N, 3), covariances (N, 3, 3), opacities (N,), SH (N, K, 3), all in
    world space) with ``camera``. ``backend``: ``numba`` (tiles in parallel), ``numpy`` (the
    reference, slow: for tests and small inputs) or ``auto`` (:mod:`gsverse_format.backend`)."""
    if resolve_backend(backend) == "numpy":
        img = composite_reference(project(means, covariances, sh, camera, settings), opacities,
                                  camera, settings)
        img.color_space = color_space
        return img
    p = project_fast(means, covariances, sh, camera, settings)
    w, h = camera.width, camera.height
    tiles_x, tiles_y = -(-w // TILE), -(-h // TILE)
    rects = tile_rects(p.means2d, p.radii, p.valid, w, h)
    rgb = np.zeros((h, w, 3))
    alpha = np.zeros((h, w))
    zsum = np.zeros((h, w))
    cut2 = np.inf if settings.cutoff is None else settings.cutoff ** 2
    with interruptions_immediate():   # compiled code: no Python handler may raise inside
        from .project_compiled import bin_tiles, composite_tiles

        offsets, ids = bin_tiles(_order(p), rects, tiles_x, tiles_x * tiles_y)
        composite_tiles(offsets, ids, p.means2d, p.conics,
                        np.ascontiguousarray(opacities, np.float64), p.colors, p.depths, w, h,
                        TILE, tiles_x, cut2, settings.min_alpha, settings.max_alpha,
                        settings.min_transmittance, rgb, alpha, zsum)
    return _finish(rgb, alpha, zsum, color_space)
