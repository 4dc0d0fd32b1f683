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

A face whose splats straddle a chunk boundary is computed once per chunk. The results do not
depend on the chunking, the thread count or the path: every splat's result depends only on its
anchors and its face's float32 quantities, bit-identical to the two-pass kernels. Splats not
grouped by face (more runs than faces plus chunks) keep the two passes.

The kernels take the chunk size as an argument (from the :class:`RunPlan`), so a kernel loaded
from the on-disk cache (``cache=True``) can never disagree with the plan. numba checks only this
file for changes: after editing the inlined ``*_row`` and ``*_span`` functions of
:mod:`gsverse_format.remapping.compiled` or :func:`gsverse_format.compiled_chunks.next_chunk`,
delete the cached ``compiled_runs.*`` entries (``remapping/__pycache__``, or under
``NUMBA_CACHE_DIR``).
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..backend import configure_numba
from ..compiled_chunks import next_chunk
from .compiled import CHUNK, games_face_row, games_splat_span, local_face_row, local_splat_span

configure_numba()

__all__ = ["CHUNK", "RunPlan", "plan_runs", "local_runs", "games_runs"]



class RunPlan:
    """Runs of equal face index: ``face`` (R,) int32 the face of each run, ``run_of`` (N,) int32
    the run of each splat and ``chunk`` (C + 1,) int64 the first run of each chunk of ``size``
    splats (every multiple of ``size`` starts a run, so a run lies in one chunk). The kernels
    take ``size`` as an argument: a cached kernel never disagrees with the plan."""

    def __init__(self, face: np.ndarray, run_of: np.ndarray, chunk: np.ndarray,
                 size: int) -> None:
        self.face, self.run_of, self.chunk, self.size = face, run_of, chunk, int(size)

    @property
    def runs(self) -> int:
        return int(self.face.shape[0])


def plan_runs(face_index: np.ndarray, n_faces: int, chunk: int = CHUNK) -> RunPlan | None:
    """The :class:`RunPlan` of ``face_index`` (N,), or None when the splats are not grouped by
    face (more runs than ``n_faces`` plus the number of chunks): the two-pass kernels are
    faster there, since the one-pass kernel would compute a face once per run."""
    face = np.asarray(face_index)
    n = int(face.shape[0])
    if n == 0:
        return RunPlan(np.zeros(0, np.int32), np.zeros(0, np.int32), np.zeros(1, np.int64), chunk)
    boundary = np.zeros(n, bool)
    boundary[1:] = face[1:] != face[:-1]
    n_chunks = (n + chunk - 1) // chunk
    if np.count_nonzero(boundary) + 1 > n_faces + n_chunks:
        return None
    boundary[::chunk] = True                        # every chunk starts a run
    start = np.flatnonzero(boundary)
    run_of = (np.cumsum(boundary, dtype=np.int64) - 1).astype(np.int32)
    return RunPlan(np.ascontiguousarray(face[start], dtype=np.int32), run_of,
                   np.append(run_of[::chunk], start.shape[0]).astype(np.int64), chunk)


@njit(parallel=True, cache=True)
def local_runs(vertices: np.ndarray, faces: np.ndarray, rest: np.ndarray, rigid: bool,
               run_face: np.ndarray, run_of: np.ndarray, chunk_run: np.ndarray,
               consts: np.ndarray, table: np.ndarray, qrun: np.ndarray, means: np.ndarray,
               cov6: np.ndarray, qlocal: np.ndarray, slocal: np.ndarray, rotations: np.ndarray,
               scales: np.ndarray, chunk: int, workers: int) -> None:
    """One-pass remap of the ``local`` profile: per chunk, the faces of its runs into rows
    ``chunk_run[c] .. chunk_run[c + 1]`` of ``table`` (R, :data:`TABLE_WIDTH`) (and ``qrun``
    (R, 4) when the rigid pairs are wanted, i.e. ``rotations`` has N rows), then its splats."""
    n = consts.shape[0]
    want = rotations.shape[0] == n and n > 0
    n_chunks = chunk_run.shape[0] - 1
    counter = np.zeros(1, np.int64)
    for _ in prange(workers):
        while True:
            c, start, stop = next_chunk(counter, chunk, n)
            if c >= n_chunks:
                break
            for r in range(chunk_run[c], chunk_run[c + 1]):
                local_face_row(vertices, faces, rest, rigid, run_face[r], table[r], qrun, r,
                               want)
            local_splat_span(run_of, consts, table, qrun, qlocal, slocal, means, cov6,
                             rotations, scales, start, stop, want)


@njit(parallel=True, cache=True)
def games_runs(vertices: np.ndarray, faces: np.ndarray, run_face: np.ndarray,
               run_of: np.ndarray, chunk_run: np.ndarray, consts: np.ndarray,
               table: np.ndarray, means: np.ndarray, cov6: np.ndarray, rotations: np.ndarray,
               scales: np.ndarray, chunk: int, workers: int) -> None:
    """One-pass remap of the ``games`` profile (``rotations``/``scales`` written when they have
    N rows); ``table`` as in :func:`local_runs`."""
    n = consts.shape[0]
    want = rotations.shape[0] == n and n > 0
    n_chunks = chunk_run.shape[0] - 1
    counter = np.zeros(1, np.int64)
    for _ in prange(workers):
        while True:
            c, start, stop = next_chunk(counter, chunk, n)
            if c >= n_chunks:
                break
            for r in range(chunk_run[c], chunk_run[c + 1]):
                games_face_row(vertices, faces, run_face[r], table[r])
            games_splat_span(run_of, consts, table, means, cov6, rotations, scales, start, stop,
                             want)
