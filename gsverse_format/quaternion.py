"""Quaternion helpers, vectorized over leading axes.

Convention everywhere in this package: **(x, y, z, w)** with ``w`` the scalar
part, as in glTF and ``KHR_gaussian_splatting``. Rotation matrices act on column
vectors (``v' = R @ v``). The Hamilton product is used, so
``to_matrix(multiply(a, b)) == to_matrix(a) @ to_matrix(b)``.
"""
from __future__ import annotations

import numpy as np

__all__ = [
    "unit_quaternions",
    "normalize",
    "multiply",
    "conjugate",
    "to_matrix",
    "from_matrix",
    "canonical_sign",
]


def normalize(q: np.ndarray) -> np.ndarray:
    """Return unit quaternions (float64). A zero quaternion becomes identity (0, 0, 0, 1)."""
    q = np.asarray(q, dtype=np.float64)
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    regular = norm > 0.0          # False for a zero (and a NaN) norm
    # one output array, divided in place where the norm is regular (no full-size temporaries
    # besides it: this runs on every splat of a conversion)
    out = np.divide(q, norm, out=np.empty_like(q), where=regular)
    out[~regular[..., 0]] = (0.0, 0.0, 0.0, 1.0)
    return out


def multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a ⊗ b`` (apply ``b`` first, then ``a``)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=-1,
    )


def conjugate(q: np.ndarray) -> np.ndarray:
    """Conjugate (the inverse of a unit quaternion)."""
    q = np.array(q, dtype=np.float64, copy=True)
    q[..., :3] *= -1.0
    return q


def to_matrix(q: np.ndarray) -> np.ndarray:
    """3x3 rotation matrices of (normalized) quaternions, shape ``(..., 3, 3)``."""
    x, y, z, w = np.moveaxis(normalize(q), -1, 0)
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    m = np.empty(x.shape + (3, 3), dtype=np.float64)
    m[..., 0, 0] = 1.0 - 2.0 * (yy + zz)
    m[..., 0, 1] = 2.0 * (xy - wz)
    m[..., 0, 2] = 2.0 * (xz + wy)
    m[..., 1, 0] = 2.0 * (xy + wz)
    m[..., 1, 1] = 1.0 - 2.0 * (xx + zz)
    m[..., 1, 2] = 2.0 * (yz - wx)
    m[..., 2, 0] = 2.0 * (xz - wy)
    m[..., 2, 1] = 2.0 * (yz + wx)
    m[..., 2, 2] = 1.0 - 2.0 * (xx + yy)
    return m


def from_matrix(m: np.ndarray) -> np.ndarray:
    """Unit quaternions (x, y, z, w) of rotation matrices ``(..., 3, 3)``.

    Shepperd's method: the largest of the four candidate diagonal combinations is
    used as the pivot, so the result is accurate for every rotation. The result
    is normalized and has ``w >= 0`` (see :func:`canonical_sign`).
    """
    m = np.asarray(m, dtype=np.float64)
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    trace = m00 + m11 + m22
    # Candidates: 4w^2, 4x^2, 4y^2, 4z^2 (each times 4, minus 1 handled below).
    cand = np.stack([1.0 + 2.0 * m00 - trace, 1.0 + 2.0 * m11 - trace,
                     1.0 + 2.0 * m22 - trace, 1.0 + trace], axis=-1)
    pivot = np.argmax(cand, axis=-1)
    q = np.empty(m.shape[:-2] + (4,), dtype=np.float64)

    def fill(sel, i):
        s = np.sqrt(np.maximum(cand[sel][..., i], 1e-300)) * 2.0  # s = 4 * component
        mm = m[sel]
        if i == 3:
            q[sel] = np.stack([(mm[..., 2, 1] - mm[..., 1, 2]) / s,
                               (mm[..., 0, 2] - mm[..., 2, 0]) / s,
                               (mm[..., 1, 0] - mm[..., 0, 1]) / s, 0.25 * s], axis=-1)
        elif i == 0:
            q[sel] = np.stack([0.25 * s, (mm[..., 0, 1] + mm[..., 1, 0]) / s,
                               (mm[..., 0, 2] + mm[..., 2, 0]) / s,
                               (mm[..., 2, 1] - mm[..., 1, 2]) / s], axis=-1)
        elif i == 1:
            q[sel] = np.stack([(mm[..., 0, 1] + mm[..., 1, 0]) / s, 0.25 * s,
                               (mm[..., 1, 2] + mm[..., 2, 1]) / s,
                               (mm[..., 0, 2] - mm[..., 2, 0]) / s], axis=-1)
        else:
            q[sel] = np.stack([(mm[..., 0, 2] + mm[..., 2, 0]) / s,
                               (mm[..., 1, 2] + mm[..., 2, 1]) / s, 0.25 * s,
                               (mm[..., 1, 0] - mm[..., 0, 1]) / s], axis=-1)

    for i in range(4):
        sel = pivot == i
        if np.any(sel):
            fill(sel, i)
    return canonical_sign(normalize(q))


def canonical_sign(q: np.ndarray) -> np.ndarray:
    """Flip quaternions so that ``w >= 0`` (q and -q are the same rotation)."""
    q = np.asarray(q, dtype=np.float64)
    return np.where(q[..., 3:4] < 0.0, -q, q)


def unit_quaternions(q: np.ndarray) -> np.ndarray:
    """Rows of ``q`` (x, y, z, w) as unit quaternions (float32).

    Rows already unit to float32 precision (|‖q‖ − 1| ≤ 1e-6) are kept bit for bit; others are
    divided by their norm; zero rows become the identity (0, 0, 0, 1).
    """
    q = np.asarray(q, dtype=np.float32)
    norm = np.linalg.norm(q.astype(np.float64), axis=1)
    fix = ~(np.abs(norm - 1.0) <= 1e-6)
    if not fix.any():
        return q
    out = q.copy()
    zero = fix & ~(norm > 0.0)
    scale = np.where(norm[fix] > 0.0, norm[fix], 1.0)
    out[fix] = (q[fix].astype(np.float64) / scale[:, None]).astype(np.float32)
    out[zero] = (0.0, 0.0, 0.0, 1.0)
    return out
