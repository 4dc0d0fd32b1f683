"""Compiled (numba) one-pass remap over runs of splats that share a face.

Files store splats sorted by face (spec §Ordering), so the splats of a face are consecutive:
a *run*. :class:`gsverse_format.remapping.fast.FastRemapper` plans the runs once per asset
(:func:`plan_runs`) and then remaps every frame in **one parallel region**: each thread takes a
chunk of ``CHUNK`` consecutive splats at a time from a shared counter (dynamic scheduling);
for a chunk it first computes the faces of its runs into the chunk's rows of a per-run table
(float64, stored in float32: the values the two-pass table of
:mod:`gsverse_format.remapping.compiled` holds), then streams the chunk's splats, each reading its
run's row (still in cache). Every multiple of ``CHUNK`` starts a run, so each run, and its
table row, belongs to exactly one chunk: no two threads write the same row.

Compared with the two passes (a face pass over all faces into a per-face table, then a splat
pass):

* faces that no splat uses are never computed (at 100k splats on 100k faces about 37% of the
  faces carry no splat);
* one parallel region per frame instead of two, and dynamic instead of static scheduling:
  when another process keeps a thread off its core, the other threads take the remaining
  chunks; the frame still ends with one join, where it waits for that thread to finish the
  chunk it holds (at most ``CHUNK`` splats), instead of for half of every pass.

Vectorised face step (``local`` profile, affine law, no rigid pairs: the default). A chunk's
runs are taken :data:`FACE_BLOCK` at a time: their faces are computed in a per-worker float64
workspace laid out as a structure of arrays (one row of :data:`FACE_BLOCK` values per
quantity, at offsets that are compile-time constants, so that LLVM sees no aliasing and needs
no run-time checks), then the splats of those runs are remapped, each run reading its face's
21 values from the workspace once (rounded to float32 as a table row would store them). A
scalar loop gathers the three corners and the rest quantities of each face, a branch-free loop
computes the 22 table values of :func:`gsverse_format.remapping.compiled.local_face_row`
four faces per AVX2 instruction (``vsqrtpd``, ``vdivpd``: the same correctly rounded
operations in the same order, so the same bits); faces degenerate at rest are then recomputed
by the scalar row (a current frame is needed there) and copied into the workspace. There is
no per-run table, so no float64 → float32 transposition into rows (9.4 ns a face, measured
with blocks of 32 and a table) and no table streamed through memory. Measured side by side
on the benchmark's 100k-face mesh, 1M splats, the faces alone: one thread 1.27 → 0.85 ms, two
threads 1.03 → 0.48 ms. The rigid law and the rigid pairs keep the scalar rows of a table.

Vectorised splat loop (both profiles, without rotations and scales). The splats of a run of at
least :data:`SHORT_RUN` splats are remapped in a loop over that run alone, its face's row read
once before it (:func:`_local_run_splats`, :func:`_games_run_splats`), which LLVM vectorises
eight splats per AVX2 instruction; shorter runs take the scalar rows. 1M splats on 100k
faces (about 10 a run), one thread: ``local`` 12.1 → 10.4 ms, ``games`` 16.7 → 14.4 ms. Runs
of about 10 splats would leave about 3.5 splats each to the loop's scalar remainder (a scalar
splat costs about two vector lanes), so from :data:`PAD_FROM` splats on a run is remapped in
whole vectors, running over into the following runs of its chunk, which then overwrite those
splats (:func:`_padded_count`). Together with the face blocks, 1M splats on 100k faces,
measured side by side: ``local``/affine 3.62 → 3.06 ms on two threads, 6.86 → 5.71 ms on one.
With rotations and scales the spans of :mod:`gsverse_format.remapping.compiled` stay scalar
(more output streams than LLVM checks for overlap).

A face whose splats straddle a chunk boundary is computed once per chunk. The results do not
depend on the chunking, the thread count or the path: every splat's result depends only on its
anchors and its face's float32 quantities, bit-identical to the two-pass kernels. Splats not
grouped by face (more runs than faces plus chunks) keep the two passes.

The kernels take the chunk size as an argument (from the :class:`RunPlan`), so a kernel loaded
from the on-disk cache (``cache=True``) can never disagree with the plan. numba checks only this
file for changes: after editing the inlined ``*_row`` and ``*_span`` functions of
:mod:`gsverse_format.remapping.compiled` (``local_splat`` and ``games_splat`` too) or
:func:`gsverse_format.compiled_chunks.next_chunk`,
delete the cached ``compiled_runs.*`` entries (``remapping/__pycache__``, or under
``NUMBA_CACHE_DIR``).
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..backend import configure_numba
from ..compiled_chunks import next_chunk
from .compiled import (CHUNK, TABLE_WIDTH, games_face_row, games_splat, games_splat_row,
                       games_splat_span, local_face_row, local_splat, local_splat_on,
                       local_splat_span, row_face)

configure_numba()

__all__ = ["CHUNK", "FACE_BLOCK", "RunPlan", "plan_runs", "local_runs", "games_runs"]

#: Faces the vectorised face step computes together before their splats are remapped (two
#: AVX2 vectors of float64; its workspace, 35 float64 rows of this many values, is 2.2 KiB).
#: Measured side by side (two runs), 1M splats on 100k faces, one thread: 8 faces 5.6–5.8 ms,
#: 16 5.9 ms, 32 6.8 ms, 128 8.5 ms; two threads: 3.2–3.3, 3.4, 3.9, 4.7 ms. Between two
#: blocks the splat loop streams about ten splats a face, so a small block keeps the faces'
#: gathers, whose vertices miss the caches, close to the streaming they overlap with.
FACE_BLOCK = 8
_IN = 13            # gathered per face: v0, v1, v2 (9), then C_r⁻¹ (i00, i01, i11) and √a_r
_OUT = 22           # computed per face: the 22 columns of a ``local`` table row
#: float64 values of one worker's workspace.
WORKSPACE = (_IN + _OUT) * FACE_BLOCK
#: Runs shorter than this many splats (the vector width of AVX2 in float32) take the scalar
#: splat loop: they would never enter the vectorised one, and its scalar remainder on flat
#: arrays measured slower than the scalar loop (100k splats on 100k faces, about 1.6 splats a
#: run: 2.97 ms with every run through the vectorised loop, 2.48 ms with this threshold; 1M
#: splats, about 10 a run: 10.4 ms both ways, against 12.1 ms without the vectorised loop).
SHORT_RUN = 8
#: Runs of at least this many splats are remapped in whole vectors (:func:`_padded_count`).
#: Measured side by side: from 4 on, 100k splats on 100k faces 0.75 ms on two threads;
#: from 2 on, 0.96 ms; from 6 on, 0.79 ms (1M splats: 3.01, 3.04, 3.06 ms).
PAD_FROM = 4


class RunPlan:
    """Runs of equal face index: ``face`` (R,) int32 the face of each run, ``run_of`` (N,) int32
    the run of each splat, ``start`` (R + 1,) uint32 the first splat of each run and then N,
    and ``chunk`` (C + 1,) int64 the first run of each chunk of ``size`` splats (every multiple
    of ``size`` starts a run, so a run lies in one chunk). The kernels take ``size`` as an
    argument: a cached kernel never disagrees with the plan."""

    def __init__(self, face: np.ndarray, run_of: np.ndarray, start: np.ndarray,
                 chunk: np.ndarray, size: int) -> None:
        self.face, self.run_of, self.start = face, run_of, start
        self.chunk, self.size = chunk, int(size)

    @property
    def runs(self) -> int:
        return int(self.face.shape[0])


def plan_runs(face_index: np.ndarray, n_faces: int, chunk: int = CHUNK) -> RunPlan | None:
    """The :class:`RunPlan` of ``face_index`` (N,), or None when the splats are not grouped by
    face (more runs than ``n_faces`` plus the number of chunks): the two-pass kernels are
    faster there, since the one-pass kernel would compute a face once per run. Also None from
    2³² splats on (the run starts are uint32, see :func:`_local_run_splats`)."""
    face = np.asarray(face_index)
    n = int(face.shape[0])
    if n >= 2**32:
        return None
    if n == 0:
        return RunPlan(np.zeros(0, np.int32), np.zeros(0, np.int32), np.zeros(1, np.uint32),
                       np.zeros(1, np.int64), chunk)
    boundary = np.zeros(n, bool)
    boundary[1:] = face[1:] != face[:-1]
    n_chunks = (n + chunk - 1) // chunk
    if np.count_nonzero(boundary) + 1 > n_faces + n_chunks:
        return None
    boundary[::chunk] = True                        # every chunk starts a run
    start = np.flatnonzero(boundary)
    run_of = (np.cumsum(boundary, dtype=np.int64) - 1).astype(np.int32)
    return RunPlan(np.ascontiguousarray(face[start], dtype=np.int32), run_of,
                   np.append(start, n).astype(np.uint32),
                   np.append(run_of[::chunk], start.shape[0]).astype(np.int64), chunk)


@njit(cache=True, inline="always")
def _affine_block(vertices, faces, rest, run_face, b0, m, ws, scratch, qrun):
    """The faces ``run_face[b0 .. b0 + m - 1]`` (``m`` ≤ :data:`FACE_BLOCK`; ``local`` profile,
    affine law, no frame) in the workspace ``ws`` (:data:`WORKSPACE` float64): column ``j`` of
    rows ``_IN .. _IN + _OUT - 1`` holds the table row of face ``run_face[b0 + j]``, whose
    float32 roundings (:func:`_ws_face`) are the values and bits of :func:`local_face_row`.
    Faces degenerate at rest are recomputed by that scalar row (into ``scratch``, float32)
    and copied back."""
    B = FACE_BLOCK
    for j in range(m):                                   # gather
        f = run_face[b0 + j]
        i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
        ws[0 * B + j] = vertices[i0, 0]
        ws[1 * B + j] = vertices[i0, 1]
        ws[2 * B + j] = vertices[i0, 2]
        ws[3 * B + j] = vertices[i1, 0]
        ws[4 * B + j] = vertices[i1, 1]
        ws[5 * B + j] = vertices[i1, 2]
        ws[6 * B + j] = vertices[i2, 0]
        ws[7 * B + j] = vertices[i2, 1]
        ws[8 * B + j] = vertices[i2, 2]
        ws[9 * B + j] = rest[f, 0]
        ws[10 * B + j] = rest[f, 1]
        ws[11 * B + j] = rest[f, 2]
        ws[12 * B + j] = rest[f, 3]
    for j in range(m):                                   # vectorised: no branch, no call
        x0 = ws[0 * B + j]
        y0 = ws[1 * B + j]
        z0 = ws[2 * B + j]
        e1x = ws[3 * B + j] - x0
        e1y = ws[4 * B + j] - y0
        e1z = ws[5 * B + j] - z0
        e2x = ws[6 * B + j] - x0
        e2y = ws[7 * B + j] - y0
        e2z = ws[8 * B + j] - z0
        i00 = ws[9 * B + j]
        i01 = ws[10 * B + j]
        i11 = ws[11 * B + j]
        root_r = ws[12 * B + j]
        cx = e1y * e2z - e1z * e2y
        cy = e1z * e2x - e1x * e2z
        cz = e1x * e2y - e1y * e2x
        root_c = np.sqrt(np.sqrt(cx * cx + cy * cy + cz * cz))
        k = root_c / root_r
        s = root_c * root_r
        positive = root_c > 0.0
        mx = cx / s if positive else 0.0
        my = cy / s if positive else 0.0
        mz = cz / s if positive else 0.0
        o = _IN * B + j
        ws[o + 0 * B] = x0
        ws[o + 1 * B] = y0
        ws[o + 2 * B] = z0
        ws[o + 3 * B] = e1x
        ws[o + 4 * B] = e1y
        ws[o + 5 * B] = e1z
        ws[o + 6 * B] = e2x
        ws[o + 7 * B] = e2y
        ws[o + 8 * B] = e2z
        ws[o + 9 * B] = mx
        ws[o + 10 * B] = my
        ws[o + 11 * B] = mz
        ws[o + 12 * B] = e1x * i00
        ws[o + 13 * B] = e1x * i01 + e2x * i11
        ws[o + 14 * B] = mx
        ws[o + 15 * B] = e1y * i00
        ws[o + 16 * B] = e1y * i01 + e2y * i11
        ws[o + 17 * B] = my
        ws[o + 18 * B] = e1z * i00
        ws[o + 19 * B] = e1z * i01 + e2z * i11
        ws[o + 20 * B] = mz
        ws[o + 21 * B] = k
    for j in range(m):                                   # faces degenerate at rest
        f = run_face[b0 + j]
        if rest[f, 4] == 0.0:
            local_face_row(vertices, faces, rest, False, f, scratch, qrun, b0 + j, False)
            for c in range(_OUT):
                ws[(_IN + c) * B + j] = scratch[c]


@njit(cache=True, inline="always")
def _ws_face(ws, j):
    """The first 21 values of the table row in column ``j`` of the workspace, in float32."""
    B = FACE_BLOCK
    o = _IN * B + j
    return (np.float32(ws[o]), np.float32(ws[o + B]), np.float32(ws[o + 2 * B]),
            np.float32(ws[o + 3 * B]), np.float32(ws[o + 4 * B]), np.float32(ws[o + 5 * B]),
            np.float32(ws[o + 6 * B]), np.float32(ws[o + 7 * B]), np.float32(ws[o + 8 * B]),
            np.float32(ws[o + 9 * B]), np.float32(ws[o + 10 * B]),
            np.float32(ws[o + 11 * B]), np.float32(ws[o + 12 * B]),
            np.float32(ws[o + 13 * B]), np.float32(ws[o + 14 * B]),
            np.float32(ws[o + 15 * B]), np.float32(ws[o + 16 * B]),
            np.float32(ws[o + 17 * B]), np.float32(ws[o + 18 * B]),
            np.float32(ws[o + 19 * B]), np.float32(ws[o + 20 * B]))


@njit(cache=True, inline="always")
def _padded_count(first, count, stop):
    """Splats to remap from ``first`` for a run of ``count`` splats of a chunk that ends at
    ``stop``: from :data:`PAD_FROM` splats on, ``count`` rounded up to a multiple of
    :data:`SHORT_RUN` (the vector width), or to ``stop`` where that comes first.

    The splats past the run belong to the runs that follow it in the same chunk. The vectorised
    loop computes them with this run's face, and the following runs, remapped after this one
    by the same thread, overwrite them with their own results. So the loop runs whole vectors
    and no splat is left to its scalar remainder (about 3.5 splats a run, each costing about
    two vector lanes), and the extra splats are already in the cache. Nothing outside the
    chunk is read or written. The end is computed as a uint32, as ``run_start`` holds it, so
    that LLVM can bound the addresses and still vectorise (from an int64 end it found "too
    many SCEV assumptions"). Measured side by side, 1M splats on 100k faces, two threads:
    3.33 → 3.06 ms."""
    if count < PAD_FROM:
        return count
    end = np.uint32(min(np.int64(first) + (count + SHORT_RUN - 1) // SHORT_RUN * SHORT_RUN,
                        np.int64(stop)))
    return np.int64(end) - np.int64(first)


@njit(cache=True, inline="always")
def _store(means, cov6, i, mx, my, mz, s00, s01, s02, s11, s12, s22):
    """Splat ``i``'s mean and six covariance entries into the flat ``means`` (N·3) and
    ``cov6`` (N·6) of the vectorised run loops."""
    m = i * 3
    means[m] = mx
    means[m + 1] = my
    means[m + 2] = mz
    v = i * 6
    cov6[v] = s00
    cov6[v + 1] = s01
    cov6[v + 2] = s02
    cov6[v + 3] = s11
    cov6[v + 4] = s12
    cov6[v + 5] = s22


@njit(cache=True, inline="always")
def _local_run_splats(consts, face, means, cov6, first, count):
    """``local`` splats ``first .. first + count - 1`` of one run (no rigid pairs) on ``face``,
    the first 21 values of its face's table row; ``consts``, ``means`` and ``cov6`` flattened
    (N·12, N·3, N·6). LLVM vectorises the loop over the run's splats, eight per AVX2
    instruction, with the explicit FMAs of :func:`local_splat` in every lane (so the bits of
    :func:`~gsverse_format.remapping.compiled.local_splat_row`). It does so only because the
    arrays are flat (a 2-D C array's row length is a run-time value: LLVM assumed it could
    be 1 and found dependences between a splat's outputs and the next splat's) and the index
    ``first + j`` is provably non-negative (``first`` uint32, ``j`` counted from 0): with a
    signed start numba's negative-index wrap-around makes the addresses non-affine."""
    for j in range(count):
        i = first + j
        c = i * 12
        mx, my, mz, s00, s01, s02, s11, s12, s22 = local_splat(
            (consts[c], consts[c + 1], consts[c + 2], consts[c + 3], consts[c + 4],
             consts[c + 5], consts[c + 6], consts[c + 7], consts[c + 8], consts[c + 9],
             consts[c + 10], consts[c + 11]), face)
        _store(means, cov6, i, mx, my, mz, s00, s01, s02, s11, s12, s22)


@njit(cache=True, inline="always")
def _local_splats(consts, face, means, cov6, flat_consts, flat_means, flat_cov6, first, count):
    """``local`` splats ``first .. first + count - 1`` of one run on ``face`` (no rigid pairs):
    the vectorised loop from :data:`SHORT_RUN` splats on, else the scalar rows."""
    if count >= SHORT_RUN:
        _local_run_splats(flat_consts, face, flat_means, flat_cov6, first, count)
    else:
        for j in range(count):
            local_splat_on(consts, face, means, cov6, first + j)


@njit(parallel=True, cache=True)
def local_runs(vertices: np.ndarray, faces: np.ndarray, rest: np.ndarray, rigid: bool,
               run_face: np.ndarray, run_of: np.ndarray, run_start: np.ndarray,
               chunk_run: np.ndarray, consts: np.ndarray, table: np.ndarray, qrun: np.ndarray,
               means: np.ndarray, cov6: np.ndarray, qlocal: np.ndarray, slocal: np.ndarray,
               rotations: np.ndarray, scales: np.ndarray, chunk: int, workers: int) -> None:
    """One-pass remap of the ``local`` profile: per chunk, the faces of its runs into rows
    ``chunk_run[c] .. chunk_run[c + 1]`` of ``table`` (R, :data:`TABLE_WIDTH`) (and ``qrun``
    (R, 4) when the rigid pairs are wanted, i.e. ``rotations`` has N rows), then its splats.
    The affine law without rigid pairs uses no table (it may have no rows): it takes the
    runs :data:`FACE_BLOCK` at a time, their faces computed by :func:`_affine_block`, then
    their splats."""
    n = consts.shape[0]
    want = rotations.shape[0] == n and n > 0
    blocked = not rigid and not want
    n_chunks = chunk_run.shape[0] - 1
    counter = np.zeros(1, np.int64)
    workspace = np.empty((workers, WORKSPACE), np.float64)
    scratch = np.empty((workers, TABLE_WIDTH), np.float32)
    flat_consts, flat_means, flat_cov6 = consts.reshape(-1), means.reshape(-1), cov6.reshape(-1)
    for w in prange(workers):
        ws = workspace[w]
        row = scratch[w]
        while True:
            c, start, stop = next_chunk(counter, chunk, n)
            if c >= n_chunks:
                break
            if blocked:
                last = chunk_run[c + 1]
                for b0 in range(chunk_run[c], last, FACE_BLOCK):
                    m = min(b0 + FACE_BLOCK, last) - b0
                    _affine_block(vertices, faces, rest, run_face, b0, m, ws, row, qrun)
                    for j in range(m):
                        first = run_start[b0 + j]
                        count = _padded_count(
                            first, np.int64(run_start[b0 + j + 1]) - np.int64(first), stop)
                        _local_splats(consts, _ws_face(ws, j), means, cov6, flat_consts,
                                      flat_means, flat_cov6, first, count)
                continue
            for r in range(chunk_run[c], chunk_run[c + 1]):
                local_face_row(vertices, faces, rest, rigid, run_face[r], table[r], qrun, r,
                               want)
            if want:
                local_splat_span(run_of, consts, table, qrun, qlocal, slocal, means, cov6,
                                 rotations, scales, start, stop, want)
            else:
                for r in range(chunk_run[c], chunk_run[c + 1]):
                    first = run_start[r]
                    count = _padded_count(first, np.int64(run_start[r + 1]) - np.int64(first),
                                          stop)
                    _local_splats(consts, row_face(table[r]), means, cov6, flat_consts,
                                  flat_means, flat_cov6, first, count)


@njit(cache=True, inline="always")
def _games_run_splats(consts, t, means, cov6, first, count):
    """``games`` splats ``first .. first + count - 1`` of one run (no rotations or scales):
    the vectorised loop of :func:`_local_run_splats` for :func:`games_splat` (flat ``consts``
    N·3, ``means`` N·3, ``cov6`` N·6; the bits of
    :func:`~gsverse_format.remapping.compiled.games_splat_row`)."""
    x0, y0, z0, e1x, e1y, e1z = t[0], t[1], t[2], t[3], t[4], t[5]
    e2x, e2y, e2z, nx, ny, nz = t[6], t[7], t[8], t[9], t[10], t[11]
    ux, uy, uz, vx, vy, vz = t[12], t[13], t[14], t[15], t[16], t[17]
    t1, t2 = t[18], t[19]
    for j in range(count):
        i = first + j
        k = i * 3
        mx, my, mz, c00, c01, c02, c11, c12, c22, _, _, _ = games_splat(
            consts[k], consts[k + 1], consts[k + 2], x0, y0, z0, e1x, e1y, e1z, e2x, e2y, e2z,
            nx, ny, nz, ux, uy, uz, vx, vy, vz, t1, t2)
        _store(means, cov6, i, mx, my, mz, c00, c01, c02, c11, c12, c22)


@njit(parallel=True, cache=True)
def games_runs(vertices: np.ndarray, faces: np.ndarray, run_face: np.ndarray,
               run_of: np.ndarray, run_start: np.ndarray, chunk_run: np.ndarray,
               consts: np.ndarray, table: np.ndarray, means: np.ndarray, cov6: np.ndarray,
               rotations: np.ndarray, scales: np.ndarray, chunk: int, workers: int) -> None:
    """One-pass remap of the ``games`` profile (``rotations``/``scales`` written when they have
    N rows); ``table`` as in :func:`local_runs`. Without rotations and scales, runs of at least
    :data:`SHORT_RUN` splats take the vectorised :func:`_games_run_splats`."""
    n = consts.shape[0]
    want = rotations.shape[0] == n and n > 0
    n_chunks = chunk_run.shape[0] - 1
    counter = np.zeros(1, np.int64)
    flat_consts, flat_means, flat_cov6 = consts.reshape(-1), means.reshape(-1), cov6.reshape(-1)
    for _ in prange(workers):
        while True:
            c, start, stop = next_chunk(counter, chunk, n)
            if c >= n_chunks:
                break
            for r in range(chunk_run[c], chunk_run[c + 1]):
                games_face_row(vertices, faces, run_face[r], table[r])
            if want:
                games_splat_span(run_of, consts, table, means, cov6, rotations, scales, start,
                                 stop, want)
                continue
            for r in range(chunk_run[c], chunk_run[c + 1]):
                first = run_start[r]
                count = _padded_count(first, np.int64(run_start[r + 1]) - np.int64(first),
                                      stop)
                if count >= SHORT_RUN:
                    _games_run_splats(flat_consts, table[r], flat_means, flat_cov6, first,
                                      count)
                else:
                    for j in range(count):
                        games_splat_row(consts, table[r], means, cov6, rotations, scales,
                                        first + j, False)
