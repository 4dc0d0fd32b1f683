"""Real spherical harmonics in the 3DGS / KHR_gaussian_splatting convention, and their rotation.

Basis (degree 0..3, with the Condon–Shortley phase, coefficient ``k = l² + (m + l)``) is the one
the original 3DGS renderer evaluates and ``KHR_gaussian_splatting`` Appendix A tabulates. The
colour of a splat seen along unit direction ``d`` (from camera to splat) is
``0.5 + Σ_k Y_k(d) · sh[k]``, clamped at 0.
"""
from __future__ import annotations

import functools

import numpy as np

#: Degree-0 constant; colour = 0.5 + SH_C0 · DC.
SH_C0 = 0.28209479177387814
_C1 = 0.4886025119029199
_C2 = (1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792,
       0.5462742152960396)
_C3 = (-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154,
       -0.4570457994644658, 1.445305721320277, -0.5900435899266435)


def sh_basis(directions: np.ndarray, degree: int) -> np.ndarray:
    """Evaluate the (degree+1)² basis functions at unit ``directions`` (N, 3) -> (N, K) float64."""
    d = np.asarray(directions, dtype=np.float64)
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    out = [np.full_like(x, SH_C0)]
    if degree >= 1:
        out += [-_C1 * y, _C1 * z, -_C1 * x]
    if degree >= 2:
        xx, yy, zz = x * x, y * y, z * z
        out += [_C2[0] * x * y, _C2[1] * y * z, _C2[2] * (2 * zz - xx - yy), _C2[3] * x * z,
                _C2[4] * (xx - yy)]
    if degree >= 3:
        out += [_C3[0] * y * (3 * xx - yy), _C3[1] * x * y * z, _C3[2] * y * (4 * zz - xx - yy),
                _C3[3] * z * (2 * zz - 3 * xx - 3 * yy), _C3[4] * x * (4 * zz - xx - yy),
                _C3[5] * z * (xx - yy), _C3[6] * x * (xx - 3 * yy)]
    return np.stack(out, axis=-1)


@functools.lru_cache(maxsize=1)
def _sample_directions() -> np.ndarray:
    # Fixed, well-spread directions (Fibonacci sphere); 64 >> 16 unknowns per band.
    n = 64
    i = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * i / n)
    theta = np.pi * (1 + 5 ** 0.5) * i
    return np.stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)], -1)


def sh_rotation_matrix(rotation: np.ndarray, degree: int) -> np.ndarray:
    """Block-diagonal (K, K) matrix D with ``sh_rotated = D @ sh`` for a splat rotated by ``rotation``.

    If a splat is rotated by R (directions d become R d), its colour function becomes
    c'(d) = c(Rᵀ d). Each band l is an invariant subspace, so D is block diagonal; each block is
    found by least squares on sample directions (exact up to float64 rounding). Entries within
    1e-12 of -1, 0 or 1 are snapped so that axis-aligned rotations are exact.
    """
    r = np.asarray(rotation, dtype=np.float64)
    dirs = _sample_directions()
    k = (degree + 1) ** 2
    full_a = sh_basis(dirs, degree)
    full_b = sh_basis(dirs @ r, degree)  # rows are (Rᵀ d)ᵀ = dᵀ R
    d = np.zeros((k, k))
    for l in range(degree + 1):
        s = slice(l * l, (l + 1) * (l + 1))
        block, *_ = np.linalg.lstsq(full_a[:, s], full_b[:, s], rcond=None)
        d[s, s] = block
    for target in (-1.0, 0.0, 1.0):
        d[np.abs(d - target) < 1e-12] = target
    return d


#: Rows per block of the generic rotation: bounds its float64 temporaries to a few MiB.
_ROTATE_BLOCK = 1 << 16


def signed_permutation(d: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``(index, sign)`` with ``d @ v == sign * v[index]`` when the square matrix ``d`` has
    exactly one nonzero entry, ±1, in every row and column; ``None`` otherwise."""
    d = np.asarray(d)
    nonzero = d != 0
    if not (np.all(nonzero.sum(axis=1) == 1) and np.all(nonzero.sum(axis=0) == 1)):
        return None
    index = np.argmax(nonzero, axis=1)
    sign = d[np.arange(len(d)), index]
    if not np.all(np.abs(sign) == 1.0):
        return None
    return index, sign


def rotate_sh(sh: np.ndarray, rotation: np.ndarray, *, consume: bool = False) -> np.ndarray:
    """Rotate coefficient-major SH ``sh`` (N, K, 3) by the 3x3 ``rotation``; returns float32.

    When the rotation matrix of the coefficients is a signed permutation (rotations that map
    ``z`` to ``±z`` and ``x``, ``y`` to ``±x``, ``±y``: the 180° turn about Z between the 3DGS
    and glTF frames, 90° turns about Z, identity), the coefficients are reordered and negated
    in float32, which is exact (the product is then a single ±1 term). Any other rotation is
    applied in float64 and rounded once to float32, in blocks of :data:`_ROTATE_BLOCK` splats.

    ``consume``: the caller gives ``sh`` up, so where it is a writeable C-contiguous float32
    array the rotation is written into it (sign changes and general rotations; a reordering of
    coefficients still makes a new array) and ``sh`` is returned. The same values; no second
    array of the size of the SH (at 4M splats of degree 3, 768 MB whose first touch alone
    took 0.3–1.2 s, page faults and the kernel zeroing the pages).
    """
    sh = np.asarray(sh)
    degree = int(round(np.sqrt(sh.shape[1]))) - 1
    d = sh_rotation_matrix(rotation, degree)
    perm = signed_permutation(d)
    reuse = (consume and sh.dtype == np.float32 and sh.flags.c_contiguous
             and sh.flags.writeable)
    if perm is not None:
        index, sign = perm
        sh32 = np.asarray(sh, dtype=np.float32)
        factors = sign.astype(np.float32)[None, :, None]
        if np.array_equal(index, np.arange(len(index))):   # signs only (the 180° turn): one pass
            return np.multiply(sh32, factors, out=sh32 if reuse else None)
        out = np.take(sh32, index, axis=1)   # a new array
        out *= factors
        return out
    out = sh if reuse else np.empty(sh.shape, np.float32)   # each block is copied first
    for start in range(0, sh.shape[0], _ROTATE_BLOCK):
        block = sh[start:start + _ROTATE_BLOCK].astype(np.float64)
        out[start:start + _ROTATE_BLOCK] = np.matmul(d, block)
    return out
