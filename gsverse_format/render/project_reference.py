"""The per-Gaussian projection of 3D Gaussian splatting, in plain float64 numpy (the reference).

For each Gaussian (mean μ, covariance Σ, opacity, SH coefficients) and a :class:`Camera`:

* camera-space mean t = R (μ − eye) (x right, y down, z forward); Gaussians with
  t_z ∉ (near, far) are culled;
* the EWA local affine approximation of the perspective map at t (Zwicker et al. 2002, as in
  the 3DGS rasterizer): J = [[f_x/t_z, 0, −f_x t'_x/t_z²], [0, f_y/t_z, −f_y t'_y/t_z²]] where
  t'_x, t'_y are t_x, t_y clamped to 1.3× the half field of view (3DGS's guard against huge
  Jacobians off screen); the 2D covariance Σ' = J R Σ Rᵀ Jᵀ + ``dilation`` · I (the standard
  0.3 px² low-pass filter), its inverse the *conic* (a, b, c) = Σ'⁻¹ as [[a, b], [b, c]];
* the pixel-space mean (f_x t_x/t_z + c_x, f_y t_y/t_z + c_y) (pixel centres at half-integers);
* the screen radius ⌈k √λ_max(Σ')⌉ with k = ``extent_sigma`` (3: the 3DGS tile footprint);
* the view-dependent colour 0.5 + Σ_k Y_k(d) sh_k (d the unit direction from the eye to μ,
  basis and conventions of :mod:`gsverse_format.sh`), clamped at 0.

:mod:`gsverse_format.render.project_compiled` is the numba twin; the tests hold them together.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..sh import sh_basis
from .camera import Camera

__all__ = ["Settings", "Projected", "project", "tile_rects", "TILE"]

#: Tile edge in pixels.
TILE = 16


@dataclass(frozen=True)
class Settings:
    """Rasterization constants (the defaults are those of the original 3DGS renderer).

    ``cutoff``: when set, a Gaussian is evaluated only where its Mahalanobis distance is below
    ``cutoff`` (PlayCanvas draws each splat on a quad reaching √8 ≈ 2.83 σ; the 3DGS rasterizer
    has no such cut and evaluates every pixel of the tiles its 3σ radius touches).
    ``min_extent``: Gaussians whose larger 2D standard deviation (dilation included) is below
    this many pixels are not drawn (3DGS: 0; PlayCanvas drops splats whose quad, 2√(2λ) across,
    is under 2 pixels: ``min_extent`` = √½). ``max_alpha``: 0.99 in 3DGS, 1 in PlayCanvas."""

    dilation: float = 0.3
    extent_sigma: float = 3.0
    cutoff: float | None = None
    min_alpha: float = 1.0 / 255.0
    max_alpha: float = 0.99
    min_transmittance: float = 1e-4
    min_extent: float = 0.0


@dataclass
class Projected:
    """Per-Gaussian screen-space quantities (float64; ``valid`` False for culled Gaussians)."""

    means2d: np.ndarray   # (N, 2) pixels
    conics: np.ndarray    # (N, 3) a, b, c of the inverse 2D covariance
    depths: np.ndarray    # (N,) camera z
    radii: np.ndarray     # (N,) int32 pixels (0 when culled)
    colors: np.ndarray    # (N, 3) view-dependent colour, clamped at 0
    valid: np.ndarray     # (N,) bool


def project(means: np.ndarray, covariances: np.ndarray, sh: np.ndarray, camera: Camera,
            settings: Settings = Settings()) -> Projected:
    """Project Gaussians (means (N, 3), covariances (N, 3, 3), SH (N, K, 3)) for ``camera``."""
    mu = np.asarray(means, np.float64)
    cov = np.asarray(covariances, np.float64)
    rot = camera.rotation()
    eye = np.asarray(camera.eye, np.float64)
    t = (mu - eye) @ rot.T
    z = t[:, 2]
    valid = (z > camera.near) & (z < camera.far)
    zs = np.where(valid, z, 1.0)
    fx, fy = camera.focal
    cx, cy = camera.center
    limx, limy = camera.tan_half_fov
    txc = np.clip(t[:, 0] / zs, -1.3 * limx, 1.3 * limx) * zs
    tyc = np.clip(t[:, 1] / zs, -1.3 * limy, 1.3 * limy) * zs
    jac = np.zeros((len(mu), 2, 3))
    jac[:, 0, 0] = fx / zs
    jac[:, 0, 2] = -fx * txc / zs ** 2
    jac[:, 1, 1] = fy / zs
    jac[:, 1, 2] = -fy * tyc / zs ** 2
    m = jac @ rot
    c2 = m @ cov @ np.swapaxes(m, 1, 2)
    a = c2[:, 0, 0] + settings.dilation
    b = c2[:, 0, 1]
    c = c2[:, 1, 1] + settings.dilation
    det = a * c - b * b
    valid &= det > 0
    dets = np.where(valid, det, 1.0)
    conics = np.stack([c / dets, -b / dets, a / dets], axis=1)
    mid = 0.5 * (a + c)
    lam1 = mid + np.sqrt(np.maximum(0.1, mid * mid - det))
    radii = np.ceil(settings.extent_sigma * np.sqrt(np.maximum(lam1, 0.0)))
    if settings.min_extent > 0:
        valid &= np.sqrt(np.maximum(lam1, 0.0)) >= settings.min_extent
    means2d = np.stack([fx * t[:, 0] / zs + cx, fy * t[:, 1] / zs + cy], axis=1)
    d = mu - eye
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-30)
    shc = np.asarray(sh, np.float64)
    degree = int(round(np.sqrt(shc.shape[1]))) - 1
    colors = np.maximum(0.5 + np.einsum("nk,nkc->nc", sh_basis(d, degree), shc), 0.0)
    radii = np.where(valid, radii, 0).astype(np.int32)
    return Projected(means2d, conics, z, radii, colors, valid & (radii > 0))


def tile_rects(means2d: np.ndarray, radii: np.ndarray, valid: np.ndarray, width: int,
               height: int) -> np.ndarray:
    """(N, 4) int32 tile ranges [x0, y0, x1, y1) each Gaussian's square of half-side ``radius``
    about its mean touches (empty, x0 == x1, for culled or off-screen Gaussians)."""
    tx, ty = -(-width // TILE), -(-height // TILE)
    r = radii.astype(np.float64)
    x0 = np.clip(np.floor((means2d[:, 0] - r) / TILE), 0, tx).astype(np.int64)
    x1 = np.clip(np.floor((means2d[:, 0] + r) / TILE) + 1, 0, tx).astype(np.int64)
    y0 = np.clip(np.floor((means2d[:, 1] - r) / TILE), 0, ty).astype(np.int64)
    y1 = np.clip(np.floor((means2d[:, 1] + r) / TILE) + 1, 0, ty).astype(np.int64)
    bad = ~valid | (x1 <= x0) | (y1 <= y0)
    x1 = np.where(bad, x0, x1)
    y1 = np.where(bad, y0, y1)
    return np.stack([x0, y0, x1, y1], axis=1).astype(np.int32)
