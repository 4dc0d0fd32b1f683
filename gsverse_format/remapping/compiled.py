"""Compiled (numba) kernels of the per-frame float32 remap.

The mathematics of the float64 reference :mod:`gsverse_format.remapping.reference`
(``spec/README.md`` §Remap), reorganized for speed;
:class:`gsverse_format.remapping.fast.FastRemapper` prepares the inputs once per asset and calls
these kernels every frame. The per-face and per-splat steps are inline functions (``*_row``, and
``*_span`` for a chunk's splats) shared with the one-pass kernels of
:mod:`gsverse_format.remapping.compiled_runs` (used for splats grouped by face); this module's
kernels are the two-pass path for other orders, each pass handing out :data:`CHUNK` items at a
time from a shared counter (:func:`gsverse_format.compiled_chunks.next_chunk`). Two passes per
frame:

1. **Per face** (:func:`local_faces`, :func:`games_faces`; one pass over F faces, computed in
   float64, stored in a float32 table of :data:`TABLE_WIDTH` columns): the size factor
   ``k = √(a_c/a_r)`` (a_c the true current doubled area), the scaled normal
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

2. **Per splat** (:func:`local_splats` with the rigid pairs, :func:`games_splats`; a streaming
   pass, parallel over splats): the mean ``v0 + b1 e1 + b2 e2 + d m`` and the covariance
   ``Σ = (A L)(A L)ᵀ`` with ``L = R_l S_l`` (``local``), or the mean ``v0 + α1 e1 + α2 e2`` and
   ``Σ = R diag(max(ρ s, 0) + ε)² Rᵀ`` (``games``), in float32, covariances as the six entries
   of :data:`gsverse_format.vocabulary.COV6_ORDER`.

Determinism: every per-splat result depends only on that splat's anchors and its face, not on
the order of the splats, the path (one or two passes) or the number of threads; the splat
steps spell out their fused multiply-adds (no fast-math) so that the compiler cannot round
differently in different builds of the loop.
The float32 error against the reference is bounded in :mod:`gsverse_format.remapping.bounds`.

Importing this module imports numba; :mod:`gsverse_format.remapping.fast` imports it only when
the numba backend is chosen. Compiled code is cached on disk (``cache=True``, in
``remapping/__pycache__`` or under ``NUMBA_CACHE_DIR``); the cold compile of the ``local``
kernels took 9.5 s of CPU (see :mod:`gsverse_format.backend`, "Small inputs"). numba checks only
a function's own file for changes: after editing :mod:`gsverse_format.compiled_chunks`, whose
helpers the kernels inline, delete the cached entries of this module and of
:mod:`gsverse_format.remapping.compiled_runs`.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange
from numba.extending import intrinsic

from ..backend import configure_numba
from ..compiled_chunks import chunk_count, next_chunk
from ..frames import EPS_DEGENERATE, GAMES_EPS

configure_numba()

__all__ = ["TABLE_WIDTH", "CHUNK", "local_faces", "local_splats", "games_faces", "games_splats"]

#: float32 columns of the per-face table (96 bytes a face).
TABLE_WIDTH = 24
#: Items (faces or splats) a thread takes from the shared counter at a time.
CHUNK = 4096

_EPS_DEG = EPS_DEGENERATE
_GEPS = GAMES_EPS
_GEPS32 = np.float32(GAMES_EPS)
# No fast-math anywhere (no contraction, reassociation, NaN/Inf assumptions): the splat
# passes spell out their fused multiply-adds with _fma.


@intrinsic
def _fma(typingctx, a, b, c):
    """a·b + c with one rounding (LLVM ``llvm.fma``; a hardware FMA on current CPUs).

    The splat passes spell out every fused multiply-add instead of letting the
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
def local_splat(splat, face):
    """Mean and the six covariance entries of one ``local`` splat (float32, explicit FMAs).

    ``splat``: the splat's constants b1, b2, d and L = R_l S_l row-major (a 12-tuple);
    ``face``: its face's v0, e1, e2, the scaled normal m and A row-major (a 21-tuple, the first
    21 columns of a table row). Tuples, because a call with more than 30 arguments compiles
    to a ``*args`` call, which numba cannot inline."""
    b1, b2, d, l00, l01, l02, l10, l11, l12, l20, l21, l22 = splat
    (x0, y0, z0, e1x, e1y, e1z, e2x, e2y, e2z, nx, ny, nz,
     a00, a01, a02, a10, a11, a12, a20, a21, a22) = face
    mx = _fma(d, nx, _fma(b2, e2x, _fma(b1, e1x, x0)))
    my = _fma(d, ny, _fma(b2, e2y, _fma(b1, e1y, y0)))
    mz = _fma(d, nz, _fma(b2, e2z, _fma(b1, e1z, z0)))
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
def _perp(tx, ty, tz):
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
def _quat_of_columns(c0x, c0y, c0z, c1x, c1y, c1z, c2x, c2y, c2z):
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
def _local_face(vertices, faces, rest, rigid, f, want_frame):
    """Current frame and remap quantities of face ``f`` (``local`` profile, float64).

    ``rest`` (F, 5) float64: C_r⁻¹ entries (i00, i01, i11), √a_r and the regular flag (all
    computed in float64 from the stored rest vertices). Returns v0 (3), e1 (3), e2 (3), k,
    the current frame t, b, n (3 × 3), the scaled normal m (3) and A row-major (9). The
    frame is computed only when something uses it (the rigid law, a face degenerate at rest,
    or ``want_frame`` for the rotations of rigid pairs); otherwise t, b, n are returned as 0.

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
    regular_rest = rest[f, 4] != 0.0
    # The current frame R_c = [t b n] (spec §Triangle frames): used by the rigid law, by
    # faces degenerate at rest and for the rotation of rigid pairs.
    if regular_rest and not rigid and not want_frame:
        tx, ty, tz, nx, ny, nz = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    elif a > _EPS_DEG * lmax2:
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
    if regular_rest:
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

@njit(cache=True, inline="always")
def _games_face(vertices, faces, f):
    """The :data:`TABLE_WIDTH` values of face ``f`` of the ``games`` profile (float64): v0,
    e1, e2, n, b1, b2, base scales s1, s2, quaternion of [n, b1, b2]."""
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
    qx, qy, qz, qw = _quat_of_columns(nx, ny, nz, p1x, p1y, p1z, p2x, p2y, p2z)
    return (x0, y0, z0, e1x, e1y, e1z, e2x, e2y, e2z, nx, ny, nz, p1x, p1y, p1z,
            p2x, p2y, p2z, s1, s2, qx, qy, qz, qw)


@njit(cache=True, inline="always")
def games_splat(a1, a2, rho, x0, y0, z0, e1x, e1y, e1z, e2x, e2y, e2z, nx, ny, nz,
                ux, uy, uz, vx, vy, vz, t1, t2):
    """Mean, the six covariance entries and the three scales of one ``games`` splat (float32,
    explicit FMAs: the rounding is fixed by the source, as in :func:`local_splat`)."""
    zero = np.float32(0.0)
    mx = _fma(a2, e2x, _fma(a1, e1x, x0))
    my = _fma(a2, e2y, _fma(a1, e1y, y0))
    mz = _fma(a2, e2z, _fma(a1, e1z, z0))
    s0 = max(rho * _GEPS32, zero) + _GEPS32
    s1 = max(rho * t1, zero) + _GEPS32
    s2 = max(rho * t2, zero) + _GEPS32
    q0, q1, q2 = s0 * s0, s1 * s1, s2 * s2
    c00 = _fma(q2 * vx, vx, _fma(q1 * ux, ux, q0 * nx * nx))
    c01 = _fma(q2 * vx, vy, _fma(q1 * ux, uy, q0 * nx * ny))
    c02 = _fma(q2 * vx, vz, _fma(q1 * ux, uz, q0 * nx * nz))
    c11 = _fma(q2 * vy, vy, _fma(q1 * uy, uy, q0 * ny * ny))
    c12 = _fma(q2 * vy, vz, _fma(q1 * uy, uz, q0 * ny * nz))
    c22 = _fma(q2 * vz, vz, _fma(q1 * uz, uz, q0 * nz * nz))
    return mx, my, mz, c00, c01, c02, c11, c12, c22, s0, s1, s2


@njit(cache=True, inline="always")
def _rigid_pair(ax, ay, az, aw, bx, by, bz, bw):
    """``q_a ⊗ q_b`` (float32), sign chosen so that w >= 0."""
    x = aw * bx + ax * bw + ay * bz - az * by
    y = aw * by - ax * bz + ay * bw + az * bx
    z = aw * bz + ax * by - ay * bx + az * bw
    w = aw * bw - ax * bx - ay * by - az * bz
    if w < 0:
        x, y, z, w = -x, -y, -z, -w
    return x, y, z, w


# --------------------------------------------------------------------------- rows
# The per-face and per-splat steps shared by the two-pass kernels below and the one-pass
# kernels of compiled_runs (numba inlines them; both produce the same bits).

@njit(cache=True, inline="always")
def local_face_row(vertices, faces, rest, rigid, f, row, qtab, qi, want_q):
    """Table row of face ``f`` (``local``): v0 (0:3), e1 (3:6), e2 (6:9), m (9:12), A
    row-major (12:21), k (21); with ``want_q`` also the quaternion of R_c into ``qtab[qi]``."""
    (x0, y0, z0, e1x, e1y, e1z, e2x, e2y, e2z, k, tx, ty, tz, bx, by, bz,
     nx, ny, nz, mx, my, mz, a00, a01, a02, a10, a11, a12, a20, a21, a22) = (
        _local_face(vertices, faces, rest, rigid, f, want_q))
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
        qtab[qi, 0] = qx
        qtab[qi, 1] = qy
        qtab[qi, 2] = qz
        qtab[qi, 3] = qw


@njit(cache=True, inline="always")
def local_splat_row(consts, t, means, cov6, i):
    """Mean and covariance of ``local`` splat ``i`` from its face's table row ``t``."""
    local_splat_on(consts, row_face(t), means, cov6, i)


@njit(cache=True, inline="always")
def row_face(t):
    """The first 21 values of the ``local`` table row ``t``, as the tuple :func:`local_splat`
    takes."""
    return (t[0], t[1], t[2], t[3], t[4], t[5], t[6], t[7], t[8], t[9], t[10], t[11], t[12],
            t[13], t[14], t[15], t[16], t[17], t[18], t[19], t[20])


@njit(cache=True, inline="always")
def local_splat_on(consts, face, means, cov6, i):
    """Mean and covariance of ``local`` splat ``i`` on ``face``, the first 21 values of its
    face's table row (a tuple, as :func:`local_splat` takes it)."""
    c = consts[i]
    mx, my, mz, s00, s01, s02, s11, s12, s22 = local_splat(
        (c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8], c[9], c[10], c[11]), face)
    means[i, 0] = mx
    means[i, 1] = my
    means[i, 2] = mz
    cov6[i, 0] = s00
    cov6[i, 1] = s01
    cov6[i, 2] = s02
    cov6[i, 3] = s11
    cov6[i, 4] = s12
    cov6[i, 5] = s22


@njit(cache=True, inline="always")
def rigid_pair_row(qtab, qi, k, qlocal, slocal, rotations, scales, i):
    """Rigid pair of splat ``i``: rotation ``q_c ⊗ q_l`` (w >= 0, q_c = ``qtab[qi]``) and
    scales ``k s_l`` (float32)."""
    x, y, z, w = _rigid_pair(qtab[qi, 0], qtab[qi, 1], qtab[qi, 2], qtab[qi, 3],
                             qlocal[i, 0], qlocal[i, 1], qlocal[i, 2], qlocal[i, 3])
    rotations[i, 0] = x
    rotations[i, 1] = y
    rotations[i, 2] = z
    rotations[i, 3] = w
    scales[i, 0] = k * slocal[i, 0]
    scales[i, 1] = k * slocal[i, 1]
    scales[i, 2] = k * slocal[i, 2]


@njit(cache=True, inline="always")
def games_face_row(vertices, faces, f, row):
    """Table row of face ``f`` (``games``, see :func:`games_faces`)."""
    vals = _games_face(vertices, faces, f)
    for j in range(TABLE_WIDTH):
        row[j] = vals[j]


@njit(cache=True, inline="always")
def games_splat_row(consts, t, means, cov6, rotations, scales, i, want):
    """Mean and covariance (and with ``want`` rotation and scales) of ``games`` splat ``i``."""
    mx, my, mz, c00, c01, c02, c11, c12, c22, s0, s1, s2 = games_splat(
        consts[i, 0], consts[i, 1], consts[i, 2], t[0], t[1], t[2], t[3], t[4], t[5], t[6],
        t[7], t[8], t[9], t[10], t[11], t[12], t[13], t[14], t[15], t[16], t[17], t[18], t[19])
    means[i, 0] = mx
    means[i, 1] = my
    means[i, 2] = mz
    cov6[i, 0] = c00
    cov6[i, 1] = c01
    cov6[i, 2] = c02
    cov6[i, 3] = c11
    cov6[i, 4] = c12
    cov6[i, 5] = c22
    if want:
        rotations[i, 0] = t[20]
        rotations[i, 1] = t[21]
        rotations[i, 2] = t[22]
        rotations[i, 3] = t[23]
        scales[i, 0] = s0
        scales[i, 1] = s1
        scales[i, 2] = s2


# --------------------------------------------------------------------------- spans
# A chunk's splats, each reading the table row ``row_of[i]``: its face in the two passes below,
# its run in compiled_runs. ``want``: the rigid pairs (local) or rotations and scales
# (games) are written too; tested once per chunk, outside the splat loop.

@njit(cache=True, inline="always")
def local_splat_span(row_of, consts, table, qtab, qlocal, slocal, means, cov6, rotations,
                     scales, start, stop, want):
    """``local`` splats ``start .. stop - 1`` (:func:`local_splat_row`, and with ``want`` the
    rigid pairs of :func:`rigid_pair_row`, q_c from ``qtab[row_of[i]]``)."""
    if want:
        for i in range(start, stop):
            r = row_of[i]
            local_splat_row(consts, table[r], means, cov6, i)
            rigid_pair_row(qtab, r, table[r, 21], qlocal, slocal, rotations, scales, i)
    else:
        for i in range(start, stop):
            local_splat_row(consts, table[row_of[i]], means, cov6, i)


@njit(cache=True, inline="always")
def games_splat_span(row_of, consts, table, means, cov6, rotations, scales, start, stop, want):
    """``games`` splats ``start .. stop - 1`` (:func:`games_splat_row`)."""
    for i in range(start, stop):
        games_splat_row(consts, table[row_of[i]], means, cov6, rotations, scales, i, want)


# --------------------------------------------------------------------------- two passes
# Used when the splats are not grouped by face (the one pass of compiled_runs needs
# runs). Each pass hands out CHUNK items at a time from a shared counter (dynamic scheduling,
# :func:`gsverse_format.compiled_chunks.next_chunk`).

@njit(parallel=True, cache=True)
def local_faces(vertices: np.ndarray, faces: np.ndarray, rest: np.ndarray, rigid: bool,
                table: np.ndarray, qface: np.ndarray, workers: int) -> None:
    """Per-face pass of the ``local`` profile (float64 arithmetic, float32 table; rows as in
    :func:`local_face_row`). ``qface`` (F, 4) or (0, 4): quaternion of the current frame R_c
    when it has rows."""
    nf = faces.shape[0]
    want_q = qface.shape[0] == nf and nf > 0
    n_chunks = chunk_count(nf, CHUNK)
    counter = np.zeros(1, np.int64)
    for _ in prange(workers):
        while True:
            c, start, stop = next_chunk(counter, CHUNK, nf)
            if c >= n_chunks:
                break
            for f in range(start, stop):
                local_face_row(vertices, faces, rest, rigid, f, table[f], qface, f, want_q)


@njit(parallel=True, cache=True)
def local_splats(face: np.ndarray, consts: np.ndarray, table: np.ndarray, means: np.ndarray,
                 cov6: np.ndarray, qlocal: np.ndarray, slocal: np.ndarray, qface: np.ndarray,
                 rotations: np.ndarray, scales: np.ndarray, workers: int) -> None:
    """Per-splat pass of the ``local`` profile (float32).

    ``consts`` (N, 12): b1, b2, d, then L = R_l S_l row-major. When ``rotations`` has N rows,
    also the rigid pairs: rotation ``q_c ⊗ q_l`` (w >= 0) and scales ``k s_l``.
    """
    n = face.shape[0]
    want = rotations.shape[0] == n and n > 0
    n_chunks = chunk_count(n, CHUNK)
    counter = np.zeros(1, np.int64)
    for _ in prange(workers):
        while True:
            c, start, stop = next_chunk(counter, CHUNK, n)
            if c >= n_chunks:
                break
            local_splat_span(face, consts, table, qface, qlocal, slocal, means, cov6, rotations,
                             scales, start, stop, want)


@njit(parallel=True, cache=True)
def games_faces(vertices: np.ndarray, faces: np.ndarray, table: np.ndarray, workers: int) -> None:
    """Per-face pass of the ``games`` profile (float64 arithmetic, float32 table).

    Row: v0 (0:3), e1 (3:6), e2 (6:9), n (9:12), b1 (12:15), b2 (15:18), base scales
    s1, s2 (18, 19), quaternion of [n, b1, b2] (20:24).
    """
    nf = faces.shape[0]
    n_chunks = chunk_count(nf, CHUNK)
    counter = np.zeros(1, np.int64)
    for _ in prange(workers):
        while True:
            c, start, stop = next_chunk(counter, CHUNK, nf)
            if c >= n_chunks:
                break
            for f in range(start, stop):
                games_face_row(vertices, faces, f, table[f])


@njit(parallel=True, cache=True)
def games_splats(face: np.ndarray, consts: np.ndarray, table: np.ndarray, means: np.ndarray,
                 cov6: np.ndarray, rotations: np.ndarray, scales: np.ndarray,
                 workers: int) -> None:
    """Per-splat pass of the ``games`` profile (float32). ``consts`` (N, 3): α1, α2, ρ.

    ``rotations``/``scales`` are written when they have N rows.
    """
    n = face.shape[0]
    want = rotations.shape[0] == n and n > 0
    n_chunks = chunk_count(n, CHUNK)
    counter = np.zeros(1, np.int64)
    for _ in prange(workers):
        while True:
            c, start, stop = next_chunk(counter, CHUNK, n)
            if c >= n_chunks:
                break
            games_splat_span(face, consts, table, means, cov6, rotations, scales, start, stop,
                             want)
