"""Fast per-frame remap: a compiled (numba) path for engines that remap every frame.

Same mathematics as the float64 reference :mod:`gsverse_format.remap` (``spec/README.md``
§Remap), reorganized for speed and stored in float32:

1. **Once per asset** (:class:`FastRemapper` construction): rest-face data (C_r⁻¹, √a_r of the
   rest doubled area, regular flag; computed in float64 from the stored float32 rest vertices by
   :func:`gsverse_format.remap.prepare_rest`, as spec §Precision requires, and kept in float64)
   and per-splat constants. For the ``local`` profile the splat-side constant is the 3×3 matrix
   ``L = R_l S_l`` (rotation matrix of the local quaternion times its scales), so that no
   quaternion or ``exp`` work is left per frame.
2. **Per frame, per face** (one pass over F faces, computed in float64, stored as float32): the
   size factor ``k = √(a_c/a_r)`` (a_c the true current doubled area), the scaled normal
   ``m = (e1 × e2)/(√a_c √a_r)`` (``m = 0`` when ``a_c = 0``; ``m = k n_c`` for regular current
   triangles, continuous as a_c → 0) and the matrix ``A`` that maps the splat's rest-frame
   factor to world space:

   * ``local``/``affine``: ``A = [E_c C_r⁻¹ | m]``, i.e. columns 0, 1 are ``E_c C_r⁻¹`` with
     ``E_c = [e1 e2]`` (3×2) and column 2 is m (equal to ``R_c blockdiag(C_c C_r⁻¹, k)`` for
     regular current triangles; no current frame is involved);
   * ``local``/``rigid``:  ``A = k R_c`` (R_c = [t b n] the current frame);
   * faces degenerate at rest (both laws): ``k = 1``, ``m = n_c``, ``A = R_c``;
   * ``games``: the GaMeS frame ``[n, b1, b2]`` (built from g = (e1 + e2)/3, u = e1 − g,
     w = e2 − g, relative to v0) and the base scales.

3. **Per frame, per splat** (a streaming pass, parallel over splats): the mean
   ``v0 + b1 e1 + b2 e2 + d m`` and the covariance ``Σ = (A L)(A L)ᵀ`` (``local``), or the mean
   ``v0 + α1 e1 + α2 e2`` and ``Σ = R diag(max(ρ s, 0) + ε)² Rᵀ`` (``games``), in float32.

Outputs (:class:`RemapOutput`) are float32: means (N, 3) and the 6 unique covariance entries
(N, 6) in the order ``xx, xy, xz, yy, yz, zz`` (:data:`COV6_ORDER`). Covariance is the normative
output; rotation/scale pairs are produced on request for ``local``/``rigid`` (``q_c ⊗ q_l`` and
``k s_l``, k = 1 on faces degenerate at rest) and ``games`` (the face frame's quaternion and the
GaMeS scales). The ``affine`` law has no cheap rotation/scale pair (the reference takes an SVD
per splat); use the reference remap when one is needed.

Precision (float32 result against the float64 reference, u = 2⁻²⁴ the float32 unit roundoff;
checked by ``tests/test_remap_fast.py`` and ``tests/test_stability.py``):

* means: ``|Δμ| <= 16 u (|v0| + |b1| |e1| + |b2| |e2| + |d| k) + |d| ν`` where, on faces
  regular at rest, ``ν = min(8 u P / √(a_c a_r), 6 √(u P / a_r))`` (P = |e1| |e2| of the current
  triangle) bounds the float32 error of the normal term d·m, and ν = 0 on faces degenerate at
  rest (k = 1 there);
* ``local`` covariances: ``‖ΔΣ‖_F <= 64 u ‖A‖_F² ‖L‖_F²`` (``‖L‖_F² = Σ s_l²``, the trace of
  the rest covariance). Relative to ‖Σ‖_F this is at most ``576 u κ(A)²`` (κ the condition
  number of A; ‖A‖_F² ≤ 3‖A‖₂², ‖L‖_F² ≤ 3‖L‖₂², ‖Σ‖_F ≥ σ_min(A)² ‖L‖₂²); the tests also
  check ``‖ΔΣ‖_F / ‖Σ‖_F <= 1e-5`` for stretches and compressions up to 10×.
* ``games`` covariances: ``‖ΔΣ‖_F <= 64 u Σ_j scale_j²``.

Splats are processed in the order given. Files store them sorted by face (spec §Ordering), which
keeps the per-face table in cache; random order costs several times more at 100k faces. (A
variant fusing steps 2 and 3 into one pass over runs of splats sharing a face was measured and
was no faster.)

Determinism: every per-splat result depends only on that splat's anchors and its face, not on
the order of the splats or the number of threads; the ``local`` splat pass spells out its fused
multiply-adds so that the compiler cannot round differently in different builds of the loop.

Selection: :func:`remap_auto` and ``FastRemapper(backend="auto")`` use numba when it can be
imported and otherwise the numpy reference (whose float64 result is then stored in the same
float32 output buffers). The environment variable ``GSVERSE_REMAP_BACKEND=numpy`` forces the
reference.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from . import quaternion as quat
from .frames import EPS_DEGENERATE, GAMES_EPS
from .model import Anchoring, GamesAnchors
from .remap import prepare_rest, remap as reference_remap

__all__ = ["COV6_ORDER", "RemapOutput", "FastRemapper", "remap_auto", "numba_available",
           "cov6_to_matrix", "matrix_to_cov6", "float32_error_bounds", "F32_UNIT_ROUNDOFF",
           "MEAN_BOUND_FACTOR", "COV_BOUND_FACTOR"]

#: Order of the six unique covariance entries in :attr:`RemapOutput.cov6`.
COV6_ORDER = ("xx", "xy", "xz", "yy", "yz", "zz")
#: u = 2⁻²⁴, float32 unit roundoff (half the machine epsilon 2⁻²³).
F32_UNIT_ROUNDOFF = 2.0 ** -24
#: Multiples of u in the stated float32-vs-float64 bounds (see :func:`float32_error_bounds`).
MEAN_BOUND_FACTOR = 16.0
COV_BOUND_FACTOR = 64.0

_COV6_INDEX = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
_TABLE_WIDTH = 24  # float32 per face (96 bytes)

try:  # pragma: no cover - exercised whichever way the environment is set up
    import numba
    from numba import njit, prange
    _NUMBA_ERROR: str | None = None
except Exception as exc:  # ImportError, or a broken llvmlite
    numba = None
    _NUMBA_ERROR = f"{type(exc).__name__}: {exc}"


def numba_available() -> bool:
    """True when the compiled backend can be used (numba imports)."""
    return numba is not None


def cov6_to_matrix(cov6: np.ndarray) -> np.ndarray:
    """(N, 6) unique entries → (N, 3, 3) float64 symmetric matrices."""
    c = np.asarray(cov6, dtype=np.float64)
    m = np.empty(c.shape[:-1] + (3, 3))
    for j, (r, s) in enumerate(_COV6_INDEX):
        m[..., r, s] = c[..., j]
        m[..., s, r] = c[..., j]
    return m


def matrix_to_cov6(cov: np.ndarray) -> np.ndarray:
    """(N, 3, 3) → (N, 6) unique entries (upper triangle, :data:`COV6_ORDER`)."""
    cov = np.asarray(cov)
    return np.stack([cov[..., r, s] for r, s in _COV6_INDEX], axis=-1)


@dataclass
class RemapOutput:
    """float32 remap results (the buffers a :class:`FastRemapper` reuses every frame).

    * ``means`` (N, 3); ``cov6`` (N, 6), entries in :data:`COV6_ORDER`;
    * ``rotations`` (N, 4) unit xyzw with w >= 0, and ``scales`` (N, 3) linear, or None when
      not requested (always None for the ``affine`` law on the compiled backend).
    """

    means: np.ndarray
    cov6: np.ndarray
    rotations: np.ndarray | None = None
    scales: np.ndarray | None = None

    def covariances(self) -> np.ndarray:
        """(N, 3, 3) float64 covariance matrices."""
        return cov6_to_matrix(self.cov6)

    def copy(self) -> "RemapOutput":
        return RemapOutput(self.means.copy(), self.cov6.copy(),
                           None if self.rotations is None else self.rotations.copy(),
                           None if self.scales is None else self.scales.copy())


# --------------------------------------------------------------------------- compiled kernels

if numba is not None:
    _EPS_DEG = EPS_DEGENERATE
    _GEPS = GAMES_EPS
    _GEPS32 = np.float32(GAMES_EPS)
    # The games splat pass may fuse multiply-adds (one rounding instead of two); nothing else
    # of fast-math (no reassociation, NaN/Inf assumptions) is allowed anywhere.
    _CONTRACT = {"contract"}

    from numba.extending import intrinsic as _intrinsic

    @_intrinsic
    def _fma(typingctx, a, b, c):  # pragma: no cover - compiled
        """a·b + c with one rounding (LLVM ``llvm.fma``; a hardware FMA on current CPUs).

        The ``local`` splat pass spells out every fused multiply-add instead of letting the
        compiler contract expressions (which it may do differently in differently vectorized
        copies of a loop): the rounding is fixed by the source.
        """
        sig = a(a, b, c)

        def codegen(context, builder, signature, args):
            from llvmlite import ir

            ty = args[0].type
            fn = builder.module.declare_intrinsic("llvm.fma", [ty], ir.FunctionType(ty, [ty, ty, ty]))
            return builder.call(fn, args)

        return sig, codegen

    @njit(cache=True, inline="always")
    def _local_splat(c, x0, y0, z0, e1x, e1y, e1z, e2x, e2y, e2z, nx, ny, nz,
                     a00, a01, a02, a10, a11, a12, a20, a21, a22):  # pragma: no cover - compiled
        """Mean and the six covariance entries of one ``local`` splat (float32, explicit FMAs).

        ``c``: b1, b2, d, L row-major; the rest: the face's v0, e1, e2, the scaled normal m and A."""
        b1, b2, d = c[0], c[1], c[2]
        mx = _fma(d, nx, _fma(b2, e2x, _fma(b1, e1x, x0)))
        my = _fma(d, ny, _fma(b2, e2y, _fma(b1, e1y, y0)))
        mz = _fma(d, nz, _fma(b2, e2z, _fma(b1, e1z, z0)))
        l00, l01, l02 = c[3], c[4], c[5]
        l10, l11, l12 = c[6], c[7], c[8]
        l20, l21, l22 = c[9], c[10], c[11]
        m00 = _fma(a02, l20, _fma(a01, l10, a00 * l00))
        m01 = _fma(a02, l21, _fma(a01, l11, a00 * l01))
        m02 = _fma(a02, l22, _fma(a01, l12, a00 * l02))
        m10 = _fma(a12, l20, _fma(a11, l10, a10 * l00))
        m11 = _fma(a12, l21, _fma(a11, l11, a10 * l01))
        m12 = _fma(a12, l22, _fma(a11, l12, a10 * l02))
        m20 = _fma(a22, l20, _fma(a21, l10, a20 * l00))
        m21 = _fma(a22, l21, _fma(a21, l11, a20 * l01))
        m22 = _fma(a22, l22, _fma(a21, l12, a20 * l02))
        s00 = _fma(m02, m02, _fma(m01, m01, m00 * m00))
        s01 = _fma(m02, m12, _fma(m01, m11, m00 * m10))
        s02 = _fma(m02, m22, _fma(m01, m21, m00 * m20))
        s11 = _fma(m12, m12, _fma(m11, m11, m10 * m10))
        s12 = _fma(m12, m22, _fma(m11, m21, m10 * m20))
        s22 = _fma(m22, m22, _fma(m21, m21, m20 * m20))
        return mx, my, mz, s00, s01, s02, s11, s12, s22

    @njit(cache=True, inline="always")
    def _perp(tx, ty, tz):  # pragma: no cover - compiled
        """normalize(t × axis), axis = coordinate axis of smallest |t_k| (lowest k on ties)."""
        ax, ay, az = abs(tx), abs(ty), abs(tz)
        if ax <= ay and ax <= az:
            ux, uy, uz = 1.0, 0.0, 0.0
        elif ay <= az:
            ux, uy, uz = 0.0, 1.0, 0.0
        else:
            ux, uy, uz = 0.0, 0.0, 1.0
        px = ty * uz - tz * uy
        py = tz * ux - tx * uz
        pz = tx * uy - ty * ux
        s = np.sqrt(px * px + py * py + pz * pz)
        return px / s, py / s, pz / s

    @njit(cache=True, inline="always")
    def _quat_of_columns(c0x, c0y, c0z, c1x, c1y, c1z, c2x, c2y, c2z):  # pragma: no cover
        """Unit quaternion (x, y, z, w), w >= 0, of the rotation with columns c0, c1, c2.

        Shepperd's method exactly as :func:`gsverse_format.quaternion.from_matrix`.
        """
        m00, m01, m02 = c0x, c1x, c2x
        m10, m11, m12 = c0y, c1y, c2y
        m20, m21, m22 = c0z, c1z, c2z
        tr = m00 + m11 + m22
        k0 = 1.0 + 2.0 * m00 - tr
        k1 = 1.0 + 2.0 * m11 - tr
        k2 = 1.0 + 2.0 * m22 - tr
        k3 = 1.0 + tr
        piv = 0
        best = k0
        if k1 > best:
            piv, best = 1, k1
        if k2 > best:
            piv, best = 2, k2
        if k3 > best:
            piv, best = 3, k3
        s = np.sqrt(max(best, 1e-300)) * 2.0
        if piv == 3:
            x, y, z, w = (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, 0.25 * s
        elif piv == 0:
            x, y, z, w = 0.25 * s, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s
        elif piv == 1:
            x, y, z, w = (m01 + m10) / s, 0.25 * s, (m12 + m21) / s, (m02 - m20) / s
        else:
            x, y, z, w = (m02 + m20) / s, (m12 + m21) / s, 0.25 * s, (m10 - m01) / s
        nrm = np.sqrt(x * x + y * y + z * z + w * w)
        if w < 0.0:
            nrm = -nrm
        return x / nrm, y / nrm, z / nrm, w / nrm

    @njit(cache=True, inline="always")
    def _local_face(vertices, faces, rest, rigid, f):  # pragma: no cover - compiled
        """Current frame and remap quantities of face ``f`` (``local`` profile, float64).

        ``rest`` (F, 5) float64: C_r⁻¹ entries (i00, i01, i11), √a_r and the regular flag (all
        computed in float64 from the stored rest vertices). Returns v0 (3), e1 (3), e2 (3), k,
        the current frame t, b, n (3 × 3), the scaled normal m (3) and A row-major (9).

        Faces regular at rest: k = √(a_c/a_r), m = (e1 × e2)/(√a_c √a_r) (0 when a_c = 0),
        A = [E_c C_r⁻¹ | m] (affine) or k R_c (rigid). Faces degenerate at rest: k = 1,
        m = n_c, A = R_c (both laws).
        """
        i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
        x0 = np.float64(vertices[i0, 0])
        y0 = np.float64(vertices[i0, 1])
        z0 = np.float64(vertices[i0, 2])
        e1x = np.float64(vertices[i1, 0]) - x0
        e1y = np.float64(vertices[i1, 1]) - y0
        e1z = np.float64(vertices[i1, 2]) - z0
        e2x = np.float64(vertices[i2, 0]) - x0
        e2y = np.float64(vertices[i2, 1]) - y0
        e2z = np.float64(vertices[i2, 2]) - z0
        e3x, e3y, e3z = e2x - e1x, e2y - e1y, e2z - e1z
        cx = e1y * e2z - e1z * e2y
        cy = e1z * e2x - e1x * e2z
        cz = e1x * e2y - e1y * e2x
        a = np.sqrt(cx * cx + cy * cy + cz * cz)       # the true a_c, also when degenerate
        q1 = e1x * e1x + e1y * e1y + e1z * e1z
        q2 = e2x * e2x + e2y * e2y + e2z * e2z
        q3 = e3x * e3x + e3y * e3y + e3z * e3z
        lmax2 = max(q1, max(q2, q3))
        # The current frame R_c = [t b n] (spec §Triangle frames): used by the rigid law, by
        # faces degenerate at rest and for the rotation of rigid pairs.
        if a > _EPS_DEG * lmax2:
            r1 = 1.0 / np.sqrt(q1)
            ra = 1.0 / a
            tx, ty, tz = e1x * r1, e1y * r1, e1z * r1
            nx, ny, nz = cx * ra, cy * ra, cz * ra
        elif lmax2 > 0.0:
            # the longest edge by squared length, the first of (e1, e2, e3) on exact ties
            if q1 == lmax2:
                dx, dy, dz = e1x, e1y, e1z
            elif q2 == lmax2:
                dx, dy, dz = e2x, e2y, e2z
            else:
                dx, dy, dz = e3x, e3y, e3z
            rd = 1.0 / np.sqrt(lmax2)
            tx, ty, tz = dx * rd, dy * rd, dz * rd
            nx, ny, nz = _perp(tx, ty, tz)
        else:
            tx, ty, tz = 1.0, 0.0, 0.0
            nx, ny, nz = 0.0, 0.0, 1.0
        bx = ny * tz - nz * ty
        by = nz * tx - nx * tz
        bz = nx * ty - ny * tx
        if rest[f, 4] != 0.0:
            root_r = rest[f, 3]
            root_c = np.sqrt(a)
            k = root_c / root_r
            if root_c > 0.0:
                s = root_c * root_r
                mx, my, mz = cx / s, cy / s, cz / s
            else:
                mx, my, mz = 0.0, 0.0, 0.0
            if rigid:
                a00, a01, a02 = k * tx, k * bx, k * nx
                a10, a11, a12 = k * ty, k * by, k * ny
                a20, a21, a22 = k * tz, k * bz, k * nz
            else:
                # columns 0, 1: E_c C_r⁻¹ with C_r⁻¹ = [[i00, i01], [0, i11]]; column 2: m
                i00, i01, i11 = rest[f, 0], rest[f, 1], rest[f, 2]
                a00, a01, a02 = e1x * i00, e1x * i01 + e2x * i11, mx
                a10, a11, a12 = e1y * i00, e1y * i01 + e2y * i11, my
                a20, a21, a22 = e1z * i00, e1z * i01 + e2z * i11, mz
        else:
            k = 1.0
            mx, my, mz = nx, ny, nz
            a00, a01, a02 = tx, bx, nx
            a10, a11, a12 = ty, by, ny
            a20, a21, a22 = tz, bz, nz
        return (x0, y0, z0, e1x, e1y, e1z, e2x, e2y, e2z, k,
                tx, ty, tz, bx, by, bz, nx, ny, nz, mx, my, mz,
                a00, a01, a02, a10, a11, a12, a20, a21, a22)

    @njit(parallel=True, cache=True)
    def _local_faces(vertices, faces, rest, rigid, table, qface):  # pragma: no cover
        """Per-face pass of the ``local`` profile (float64 arithmetic, float32 table).

        Table row: v0 (0:3), e1 (3:6), e2 (6:9), m (9:12), A row-major (12:21), k (21).
        ``qface`` (F, 4) or (0, 4): quaternion of the current frame R_c when it has rows.
        """
        nf = faces.shape[0]
        want_q = qface.shape[0] == nf and nf > 0
        for f in prange(nf):
            (x0, y0, z0, e1x, e1y, e1z, e2x, e2y, e2z, k, tx, ty, tz, bx, by, bz, nx, ny, nz,
             mx, my, mz, a00, a01, a02, a10, a11, a12, a20, a21, a22) = _local_face(
                vertices, faces, rest, rigid, f)
            row = table[f]
            row[0] = x0
            row[1] = y0
            row[2] = z0
            row[3] = e1x
            row[4] = e1y
            row[5] = e1z
            row[6] = e2x
            row[7] = e2y
            row[8] = e2z
            row[9] = mx
            row[10] = my
            row[11] = mz
            row[12] = a00
            row[13] = a01
            row[14] = a02
            row[15] = a10
            row[16] = a11
            row[17] = a12
            row[18] = a20
            row[19] = a21
            row[20] = a22
            row[21] = k
            if want_q:
                qx, qy, qz, qw = _quat_of_columns(tx, ty, tz, bx, by, bz, nx, ny, nz)
                qface[f, 0] = qx
                qface[f, 1] = qy
                qface[f, 2] = qz
                qface[f, 3] = qw

    @njit(parallel=True, cache=True)
    def _local_splats(face, consts, table, means, cov6):  # pragma: no cover
        """Per-splat pass of the ``local`` profile (float32).

        ``consts`` (N, 12): b1, b2, d, then L = R_l S_l row-major.
        """
        n = face.shape[0]
        for i in prange(n):
            t = table[face[i]]
            mx, my, mz, s00, s01, s02, s11, s12, s22 = _local_splat(
                consts[i], t[0], t[1], t[2], t[3], t[4], t[5], t[6], t[7], t[8], t[9], t[10], t[11],
                t[12], t[13], t[14], t[15], t[16], t[17], t[18], t[19], t[20])
            means[i, 0] = mx
            means[i, 1] = my
            means[i, 2] = mz
            cov6[i, 0] = s00
            cov6[i, 1] = s01
            cov6[i, 2] = s02
            cov6[i, 3] = s11
            cov6[i, 4] = s12
            cov6[i, 5] = s22

    @njit(parallel=True, cache=True)
    def _rigid_pairs(face, qlocal, slocal, table, qface, rotations, scales):  # pragma: no cover
        """Rotation ``q_c ⊗ q_l`` (w >= 0) and scales ``k s_l`` of the ``rigid`` law."""
        n = face.shape[0]
        for i in prange(n):
            f = face[i]
            ax, ay, az, aw = qface[f, 0], qface[f, 1], qface[f, 2], qface[f, 3]
            bx, by, bz, bw = qlocal[i, 0], qlocal[i, 1], qlocal[i, 2], qlocal[i, 3]
            x = aw * bx + ax * bw + ay * bz - az * by
            y = aw * by - ax * bz + ay * bw + az * bx
            z = aw * bz + ax * by - ay * bx + az * bw
            w = aw * bw - ax * bx - ay * by - az * bz
            if w < 0:
                x, y, z, w = -x, -y, -z, -w
            rotations[i, 0] = x
            rotations[i, 1] = y
            rotations[i, 2] = z
            rotations[i, 3] = w
            k = table[f, 21]
            scales[i, 0] = k * slocal[i, 0]
            scales[i, 1] = k * slocal[i, 1]
            scales[i, 2] = k * slocal[i, 2]

    @njit(parallel=True, cache=True)
    def _games_faces(vertices, faces, table):  # pragma: no cover
        """Per-face pass of the ``games`` profile (float64 arithmetic, float32 table).

        Row: v0 (0:3), e1 (3:6), e2 (6:9), n (9:12), b1 (12:15), b2 (15:18), base scales
        s1, s2 (18, 19), quaternion of [n, b1, b2] (20:24).
        """
        nf = faces.shape[0]
        for f in prange(nf):
            i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
            x0 = np.float64(vertices[i0, 0])
            y0 = np.float64(vertices[i0, 1])
            z0 = np.float64(vertices[i0, 2])
            x1 = np.float64(vertices[i1, 0])
            y1 = np.float64(vertices[i1, 1])
            z1 = np.float64(vertices[i1, 2])
            x2 = np.float64(vertices[i2, 0])
            y2 = np.float64(vertices[i2, 1])
            z2 = np.float64(vertices[i2, 2])
            e1x, e1y, e1z = x1 - x0, y1 - y0, z1 - z0
            e2x, e2y, e2z = x2 - x0, y2 - y0, z2 - z0
            e3x, e3y, e3z = x2 - x1, y2 - y1, z2 - z1
            cx = e1y * e2z - e1z * e2y
            cy = e1z * e2x - e1x * e2z
            cz = e1x * e2y - e1y * e2x
            a = np.sqrt(cx * cx + cy * cy + cz * cz)
            q1 = e1x * e1x + e1y * e1y + e1z * e1z
            q2 = e2x * e2x + e2y * e2y + e2z * e2z
            q3 = e3x * e3x + e3y * e3y + e3z * e3z
            lmax2 = max(q1, max(q2, q3))
            tol = _EPS_DEG * np.sqrt(lmax2)          # ε_deg ℓ
            # Relative to v0: g = c − v0 = (e1 + e2)/3, u = v1 − c, w = v2 − c.
            gx, gy, gz = (e1x + e2x) / 3.0, (e1y + e2y) / 3.0, (e1z + e2z) / 3.0
            ux, uy, uz = e1x - gx, e1y - gy, e1z - gz
            wx, wy, wz = e2x - gx, e2y - gy, e2z - gz
            lu = np.sqrt(ux * ux + uy * uy + uz * uz)
            if a > _EPS_DEG * lmax2:
                # regular (then |u| > ε_deg ℓ / 2 > 0): n = cross/a, b1 = u/|u|, b2 = n × b1
                ra = 1.0 / a
                nx, ny, nz = cx * ra, cy * ra, cz * ra
                p1x, p1y, p1z = ux / lu, uy / lu, uz / lu
                p2x = ny * p1z - nz * p1y
                p2y = nz * p1x - nx * p1z
                p2z = nx * p1y - ny * p1x
            elif lu > tol:
                # degenerate: b1 = u/|u|, b2 = unit(w − (w·b1) b1) or perp(b1), n = b1 × b2
                p1x, p1y, p1z = ux / lu, uy / lu, uz / lu
                wb = wx * p1x + wy * p1y + wz * p1z
                rx, ry, rz = wx - wb * p1x, wy - wb * p1y, wz - wb * p1z
                lr = np.sqrt(rx * rx + ry * ry + rz * rz)
                if lr > tol:
                    p2x, p2y, p2z = rx / lr, ry / lr, rz / lr
                else:
                    p2x, p2y, p2z = _perp(p1x, p1y, p1z)
                nx = p1y * p2z - p1z * p2y
                ny = p1z * p2x - p1x * p2z
                nz = p1x * p2y - p1y * p2x
            elif lmax2 > 0.0:
                # degenerate with v1 at the centroid: b2 = w/|w|, b1 = perp(b2), n = b1 × b2
                lw = np.sqrt(wx * wx + wy * wy + wz * wz)
                p2x, p2y, p2z = wx / lw, wy / lw, wz / lw
                p1x, p1y, p1z = _perp(p2x, p2y, p2z)
                nx = p1y * p2z - p1z * p2y
                ny = p1z * p2x - p1x * p2z
                nz = p1x * p2y - p1y * p2x
            else:
                nx, ny, nz = 0.0, 0.0, 1.0
                p1x, p1y, p1z = 1.0, 0.0, 0.0
                p2x, p2y, p2z = 0.0, 1.0, 0.0
            s1 = (lu + _GEPS) / 2.0
            s2 = (wx * p2x + wy * p2y + wz * p2z) / 2.0
            row = table[f]
            row[0] = x0
            row[1] = y0
            row[2] = z0
            row[3] = e1x
            row[4] = e1y
            row[5] = e1z
            row[6] = e2x
            row[7] = e2y
            row[8] = e2z
            row[9] = nx
            row[10] = ny
            row[11] = nz
            row[12] = p1x
            row[13] = p1y
            row[14] = p1z
            row[15] = p2x
            row[16] = p2y
            row[17] = p2z
            row[18] = s1
            row[19] = s2
            qx, qy, qz, qw = _quat_of_columns(nx, ny, nz, p1x, p1y, p1z, p2x, p2y, p2z)
            row[20] = qx
            row[21] = qy
            row[22] = qz
            row[23] = qw

    @njit(parallel=True, cache=True, fastmath=_CONTRACT)
    def _games_splats(face, consts, table, means, cov6, rotations, scales):  # pragma: no cover
        """Per-splat pass of the ``games`` profile (float32). ``consts`` (N, 3): α1, α2, ρ.

        ``rotations``/``scales`` are written when they have N rows.
        """
        n = face.shape[0]
        want = rotations.shape[0] == n and n > 0
        zero = np.float32(0.0)
        for i in prange(n):
            f = face[i]
            t = table[f]
            a1, a2, rho = consts[i, 0], consts[i, 1], consts[i, 2]
            means[i, 0] = t[0] + a1 * t[3] + a2 * t[6]
            means[i, 1] = t[1] + a1 * t[4] + a2 * t[7]
            means[i, 2] = t[2] + a1 * t[5] + a2 * t[8]
            s0 = max(rho * _GEPS32, zero) + _GEPS32
            s1 = max(rho * t[18], zero) + _GEPS32
            s2 = max(rho * t[19], zero) + _GEPS32
            q0, q1, q2 = s0 * s0, s1 * s1, s2 * s2
            nx, ny, nz = t[9], t[10], t[11]
            ux, uy, uz = t[12], t[13], t[14]
            vx, vy, vz = t[15], t[16], t[17]
            cov6[i, 0] = q0 * nx * nx + q1 * ux * ux + q2 * vx * vx
            cov6[i, 1] = q0 * nx * ny + q1 * ux * uy + q2 * vx * vy
            cov6[i, 2] = q0 * nx * nz + q1 * ux * uz + q2 * vx * vz
            cov6[i, 3] = q0 * ny * ny + q1 * uy * uy + q2 * vy * vy
            cov6[i, 4] = q0 * ny * nz + q1 * uy * uz + q2 * vy * vz
            cov6[i, 5] = q0 * nz * nz + q1 * uz * uz + q2 * vz * vz
            if want:
                rotations[i, 0] = t[20]
                rotations[i, 1] = t[21]
                rotations[i, 2] = t[22]
                rotations[i, 3] = t[23]
                scales[i, 0] = s0
                scales[i, 1] = s1
                scales[i, 2] = s2


# --------------------------------------------------------------------------- the remapper

def _choose_backend(backend: str) -> str:
    if backend not in ("auto", "numba", "numpy"):
        raise ValueError(f"backend must be 'auto', 'numba' or 'numpy', got {backend!r}")
    if backend == "auto":
        forced = os.environ.get("GSVERSE_REMAP_BACKEND", "").strip().lower()
        if forced in ("numba", "numpy"):
            backend = forced
        else:
            return "numba" if numba is not None else "numpy"
    if backend == "numba" and numba is None:
        raise RuntimeError(f"the numba backend is not available ({_NUMBA_ERROR})")
    return backend


class FastRemapper:
    """Remaps one anchored primitive, frame after frame, into preallocated float32 buffers.

    Build it once per asset (this precomputes the rest data and the per-splat constants), then
    call :meth:`remap` with the current anchor vertices (V, 3) every frame. The returned
    :class:`RemapOutput` is the remapper's own buffer set, overwritten by the next call (pass
    ``out=`` or ``.copy()`` it to keep a frame).

    ``rotations=True`` also produces rotation/scale pairs for the ``rigid`` law and the ``games``
    profile (ignored for ``affine``, whose covariance is the output). ``backend`` is ``"auto"``
    (numba when importable, else the numpy reference), ``"numba"`` or ``"numpy"``.
    """

    def __init__(self, anchoring: Anchoring, *, rotations: bool = False, backend: str = "auto"):
        self.anchoring = anchoring
        self.backend = _choose_backend(backend)
        anchors = anchoring.anchors
        self.profile = anchors.profile
        self.law = None if isinstance(anchors, GamesAnchors) else anchors.deformation
        self.rotations = bool(rotations) and self.law != "affine"
        mesh = anchoring.mesh
        self.n_splats = len(anchors)
        self.n_faces = mesh.face_count
        self.n_vertices = len(mesh.vertices)
        self._rest = None
        self._out = self.allocate()
        if self.backend == "numpy":
            if self.profile == "local":
                self._rest = prepare_rest(mesh.triangles())
            return
        self._faces = np.ascontiguousarray(mesh.faces, dtype=np.int32)
        self._face = np.ascontiguousarray(anchors.face_index, dtype=np.int32)
        self._table = np.zeros((self.n_faces, _TABLE_WIDTH), np.float32)
        if self.profile == "games":
            self._consts = np.ascontiguousarray(np.concatenate(
                [anchors.barycentrics, anchors.rho[:, None]], axis=1), dtype=np.float32)
            return
        # Rest quantities in float64 from the stored float32 rest vertices (spec §Precision):
        # C_r⁻¹ (i00, i01, i11), √a_r (1 on faces degenerate at rest) and the regular flag.
        rest = prepare_rest(mesh.triangles())
        self._rest_table = np.ascontiguousarray(np.concatenate(
            [rest.inverse_shape[:, 0, 0:1], rest.inverse_shape[:, 0, 1:2],
             rest.inverse_shape[:, 1, 1:2],
             np.sqrt(np.where(rest.regular, rest.area2, 1.0))[:, None],
             rest.regular[:, None].astype(np.float64)], axis=1), dtype=np.float64)
        q_l = quat.normalize(anchors.local_rotation)
        s_l = anchors.local_scale.astype(np.float64)
        lmat = quat.to_matrix(q_l) * s_l[:, None, :]            # L = R_l S_l
        self._consts = np.ascontiguousarray(np.concatenate(
            [anchors.barycentrics, anchors.normal_offset[:, None], lmat.reshape(-1, 9)],
            axis=1), dtype=np.float32)
        self._qface = np.zeros((self.n_faces if self.rotations else 0, 4), np.float32)
        if self.rotations:
            self._qlocal = np.ascontiguousarray(q_l, dtype=np.float32)
            self._slocal = np.ascontiguousarray(anchors.local_scale, dtype=np.float32)

    # -- sizes

    def allocate(self) -> RemapOutput:
        """A fresh set of output buffers for this remapper."""
        n = self.n_splats
        rot = np.zeros((n, 4), np.float32) if self.rotations else None
        sca = np.zeros((n, 3), np.float32) if self.rotations else None
        return RemapOutput(np.zeros((n, 3), np.float32), np.zeros((n, 6), np.float32), rot, sca)

    @property
    def bytes_per_splat(self) -> int:
        """Bytes the per-splat pass must read and write per splat (streamed data only)."""
        if self.profile == "games":
            read, write = 4 + 12, 12 + 24
            if self.rotations:
                write += 16 + 12
        else:
            read, write = 4 + 48, 12 + 24
            if self.rotations:
                read += 4 + 16 + 12          # face index again, q_l, s_l
                write += 16 + 12
        return read + write

    # -- per frame

    def remap(self, vertices: np.ndarray | None = None, out: RemapOutput | None = None) -> RemapOutput:
        """Remap onto current ``vertices`` (V, 3) float32 or float64 (default: the rest pose)."""
        mesh = self.anchoring.mesh
        v = mesh.vertices if vertices is None else np.asarray(vertices)
        if v.shape != (self.n_vertices, 3):
            raise ValueError(f"expected vertices of shape {(self.n_vertices, 3)}, got {v.shape}")
        if v.dtype not in (np.float32, np.float64) or not v.flags.c_contiguous:
            v = np.ascontiguousarray(v, dtype=np.float64 if v.dtype == np.float64 else np.float32)
        out = self._out if out is None else out
        if self.backend == "numpy":
            return self._remap_numpy(v, out)
        if self.profile == "games":
            _games_faces(v, self._faces, self._table)
            if self.rotations:
                _games_splats(self._face, self._consts, self._table, out.means, out.cov6,
                              out.rotations, out.scales)
            else:
                _games_splats(self._face, self._consts, self._table, out.means, out.cov6,
                              _EMPTY4, _EMPTY3)
            return out
        _local_faces(v, self._faces, self._rest_table, self.law == "rigid", self._table, self._qface)
        _local_splats(self._face, self._consts, self._table, out.means, out.cov6)
        if self.rotations:
            _rigid_pairs(self._face, self._qlocal, self._slocal, self._table, self._qface,
                         out.rotations, out.scales)
        return out

    def face_pass(self, vertices: np.ndarray) -> None:
        """Only the per-face pass (for timing its share)."""
        if self.backend == "numpy":
            raise RuntimeError("the numpy backend has no separate face pass")
        if self.profile == "games":
            _games_faces(vertices, self._faces, self._table)
        else:
            _local_faces(vertices, self._faces, self._rest_table, self.law == "rigid",
                         self._table, self._qface)

    def _remap_numpy(self, v: np.ndarray, out: RemapOutput) -> RemapOutput:
        r = reference_remap(self.anchoring, v, rest=self._rest)
        out.means[...] = r.means
        out.cov6[...] = matrix_to_cov6(r.covariances)
        if out.rotations is not None:
            out.rotations[...] = r.rotations
            out.scales[...] = r.scales
        return out

    def warm_up(self) -> "FastRemapper":
        """Compile (or load from the cache) the kernels on a tiny problem; returns self."""
        if self.backend == "numba":
            self.remap()
        return self


def float32_error_bounds(anchoring: Anchoring, vertices: np.ndarray | None = None):
    """Per-splat bounds on |μ_fast − μ_ref| and ‖Σ_fast − Σ_ref‖_F (float32 fast path against
    the float64 reference), as (N,) float64 arrays ``(mean_bound, cov_bound)``.

    * mean: ``16 u (|v0| + |b1| |e1| + |b2| |e2| + |d| k)``, plus, on faces regular at rest,
      the float32 error of the normal term d·m: ``|d| min(8 u P / √(a_c a_r), 6 √(u P / a_r))``
      with P = |e1| |e2| of the current triangle (k = 1 and no such term on faces degenerate
      at rest, where m = n_c);
    * ``local`` covariance: ``64 u ‖A‖_F² Σ s_l²`` with A = [E_c C_r⁻¹ | m] (affine), k R_c
      (rigid) or R_c (faces degenerate at rest);
    * ``games`` covariance: ``64 u Σ_j scale_j²``.

    u = 2⁻²⁴. Both implementations evaluate the branch tests of the current frames in float64;
    a triangle within rounding of a branch point may take different branches. Only frames with
    a jump there are affected: the current frame R_c at ``a = ε_deg ℓ²`` (the rigid law, and
    faces degenerate at rest) and the games frame at ``|u| = ε_deg ℓ`` or ``|r| = ε_deg ℓ``;
    these bounds do not cover such triangles. The affine law and every mean on faces regular
    at rest have no branch on the current triangle.
    """
    from .frames import games_frames, local_frames
    from .remap import face_matrices

    mesh = anchoring.mesh
    v = mesh.vertices if vertices is None else np.asarray(vertices)
    tri = mesh.triangles(v)
    anchors = anchoring.anchors
    face = anchors.face_index.astype(np.intp)
    b = np.abs(anchors.barycentrics.astype(np.float64))
    len1 = np.linalg.norm(tri[:, 1] - tri[:, 0], axis=1)
    len2 = np.linalg.norm(tri[:, 2] - tri[:, 0], axis=1)
    v0 = np.linalg.norm(tri[face, 0], axis=1)
    base_mean = v0 + b[:, 0] * len1[face] + b[:, 1] * len2[face]
    u = F32_UNIT_ROUNDOFF
    if isinstance(anchors, GamesAnchors):
        _, base, _ = games_frames(tri)
        scales = np.maximum(anchors.rho.astype(np.float64)[:, None] * base[face], 0.0) + GAMES_EPS
        return MEAN_BOUND_FACTOR * u * base_mean, COV_BOUND_FACTOR * u * np.sum(scales * scales, axis=1)
    rest = prepare_rest(mesh.triangles())
    cur = local_frames(tri)
    k, _, a = face_matrices(rest, cur, tri, anchors.deformation)
    a2 = np.sum(a * a, axis=(1, 2))
    # float32 error of d·m on faces regular at rest, per unit |d|
    p = len1 * len2
    a_r = np.where(rest.regular, rest.area2, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        normal = np.fmin(8.0 * u * p / np.sqrt(cur.area2 * a_r), 6.0 * np.sqrt(u * p / a_r))
    normal = np.where(rest.regular, normal, 0.0)
    d = np.abs(anchors.normal_offset.astype(np.float64))
    mean_bound = MEAN_BOUND_FACTOR * u * (base_mean + d * k[face]) + d * normal[face]
    s2 = np.sum(anchors.local_scale.astype(np.float64) ** 2, axis=1)
    return mean_bound, COV_BOUND_FACTOR * u * a2[face] * s2


_EMPTY4 = np.zeros((0, 4), np.float32)
_EMPTY3 = np.zeros((0, 3), np.float32)


def remap_auto(anchoring: Anchoring, vertices: np.ndarray | None = None, *,
               rotations: bool = False, backend: str = "auto") -> RemapOutput:
    """One-shot remap with automatic backend selection (numba if importable, else numpy).

    For per-frame use build a :class:`FastRemapper` once instead: construction precomputes
    the per-splat constants, which costs more than one remap.
    """
    return FastRemapper(anchoring, rotations=rotations, backend=backend).remap(vertices).copy()
