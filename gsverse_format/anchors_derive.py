"""The derivation rule of ``local`` anchors, written once (spec §Derived `local` anchors and
§Writing anchors (informative), steps 2 and 3).

Given a splat's rest pose (mean μ, rotation q) and the rest triangle f it follows, with rest
frame R_r = [t | b | n], edge matrix C_r and first corner v0 (spec §Triangle frames), in
binary64:

    (x, y, z) = R_rᵀ (μ − v0);  b2 = y / C_r[1,1];  b1 = (x − C_r[0,1] b2) / C_r[0,0];  d = z;
    q_l = conj(q_r) ⊗ q   (Hamilton, xyzw; q_r the quaternion of R_r);   s_l = s.

The binder (:mod:`gsverse_format.binding`) uses it to store explicit anchors; readers of
compact assets (``barycentrics`` absent) use it to rebuild the anchors from the stored rest
pose. The rule needs a face regular at rest (C_r invertible): callers exclude or refuse the
others (:func:`degenerate_splats`).
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from numpy.typing import DTypeLike

from . import quaternion as quat
from .frames import LocalFrames, local_frames, regular_mask
from .model import TriangleMesh

__all__ = ["DerivedAnchors", "DERIVE_CHUNK", "derive_local", "degenerate_splats"]

#: Splats :func:`derive_local` derives at a time: its float64 temporaries (gathered frames,
#: offsets, quaternions: about 0.5 KiB a splat) stay near 8 MiB a thread however many splats
#: there are. Small enough for the allocator to hand the same memory to the next chunk: 1M
#: splats on two threads fault in 3.5k pages and take 0.073 s, against 11k pages and 0.080 s
#: in chunks of 65,536 (a fresh process).
DERIVE_CHUNK = 16_384


@dataclass
class DerivedAnchors:
    """``local`` anchors of splats (float64 unless asked otherwise): ``barycentrics`` (N, 2),
    ``normal_offset`` (N,), ``local_rotation`` (N, 4) unit xyzw with w ≥ 0 (the local scale is
    the rest scale)."""

    barycentrics: np.ndarray
    normal_offset: np.ndarray
    local_rotation: np.ndarray


def degenerate_splats(mesh: TriangleMesh, face: np.ndarray,
                      frames: LocalFrames | None = None) -> np.ndarray:
    """Indices of the splats whose face (``face``, in range) is degenerate at rest."""
    regular = regular_mask(mesh.triangles()) if frames is None else frames.regular
    return np.flatnonzero(~regular[np.asarray(face, dtype=np.intp)])


def derive_local(mesh: TriangleMesh, face: np.ndarray, means: np.ndarray,
                 rotations: np.ndarray, *, frames: LocalFrames | None = None,
                 dtype: DTypeLike = np.float64, chunk: int = DERIVE_CHUNK,
                 threads: int = 1, order: np.ndarray | None = None) -> DerivedAnchors:
    """``local`` anchors of splats with rest ``means`` (N, 3) and ``rotations`` (N, 4, xyzw,
    normalized here) on faces ``face`` (N,) of the rest ``mesh``, in binary64.

    ``frames`` are the rest frames of ``mesh`` when the caller has them. Every face in
    ``face`` must be regular at rest (:func:`degenerate_splats` is empty); on a degenerate one
    C_r is singular and the result is not finite.

    The splats are derived ``chunk`` at a time (the float64 temporaries stay bounded, about
    0.5 KiB a splat) and each binary64 result is stored as ``dtype``: float64 by default, or
    float32 for anchors about to be stored (rounded once, exactly as converting the float64
    result would). Neither changes a value: every step is row by row. With ``threads`` > 1
    the chunks are derived on that many threads (numpy releases the GIL in its loops; each
    chunk writes its own rows, so the values are the same); the temporaries then grow with
    the threads.

    ``order`` (N splat indices, a permutation as a rule) derives them in that order: row ``i``
    of the result is splat ``order[i]`` on face ``face[order[i]]``, the values of
    ``derive_local(...)`` taken in that order, without reordering the inputs first (each chunk
    gathers its rows).
    """
    if chunk < 1:
        raise ValueError("chunk must be positive")
    frames = local_frames(mesh.triangles()) if frames is None else frames
    f = np.asarray(face, dtype=np.intp)
    n = f.shape[0]
    means = np.asarray(means)
    rotations = np.asarray(rotations)
    if means.shape != (n, 3) or rotations.shape != (n, 4):
        raise ValueError(f"means (N, 3) and rotations (N, 4) must match face (N,) with N={n}, "
                         f"got {means.shape} and {rotations.shape}")
    # once per face, not per splat: conj(q_r) of the frame's rotation
    q_conj = quat.conjugate(quat.from_matrix(frames.rotation))
    out = DerivedAnchors(np.empty((n, 2), dtype), np.empty(n, dtype), np.empty((n, 4), dtype))

    if order is not None:
        order = np.asarray(order)
        if order.shape != (n,) or order.dtype.kind not in "iu":
            raise ValueError(f"order must hold {n} integer splat indices")

    def derive(lo: int) -> None:
        hi = min(lo + chunk, n)
        if order is None:
            fc, mu, q = f[lo:hi], means[lo:hi], rotations[lo:hi]
        else:
            rows = order[lo:hi]
            fc, mu, q = f[rows], np.take(means, rows, axis=0), np.take(rotations, rows, axis=0)
        rot = np.take(frames.rotation, fc, axis=0)                     # columns t, b, n
        rel = np.asarray(mu, dtype=np.float64) - np.take(frames.origin, fc, axis=0)
        local = np.einsum("nji,nj->ni", rot, rel)                      # (x, y, z) = R_rᵀ (μ − v0)
        c = np.take(frames.shape, fc, axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            b2 = local[:, 1] / c[:, 1, 1]
            b1 = (local[:, 0] - c[:, 0, 1] * b2) / c[:, 0, 0]
        out.barycentrics[lo:hi, 0] = b1
        out.barycentrics[lo:hi, 1] = b2
        out.normal_offset[lo:hi] = local[:, 2]
        out.local_rotation[lo:hi] = quat.canonical_sign(quat.multiply(
            np.take(q_conj, fc, axis=0), quat.normalize(q)))

    starts = range(0, n, chunk)
    workers = min(threads, len(starts))
    if workers > 1:
        # numpy releases the GIL in its loops over a chunk; each chunk writes its own rows.
        # On an error or an interrupt the chunks not started are cancelled, not waited for.
        pool = ThreadPoolExecutor(max_workers=workers)
        try:
            for _ in pool.map(derive, starts):
                pass
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
    else:
        for lo in starts:
            derive(lo)
    return out
