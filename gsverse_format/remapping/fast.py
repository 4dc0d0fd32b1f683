"""Fast per-frame remap: :class:`FastRemapper` for engines that remap every frame.

Same mathematics as the float64 reference :mod:`gsverse_format.remapping.reference`
(``spec/README.md`` §Remap), reorganized for speed and stored in float32. This module chooses
the backend and drives it; the compiled kernels are in :mod:`gsverse_format.remapping.compiled`
and the float32 error bounds in :mod:`gsverse_format.remapping.bounds`.

**Once per asset** (:class:`FastRemapper` construction): rest-face data (C_r⁻¹, √a_r of the
rest doubled area, regular flag; computed in float64 from the stored float32 rest vertices by
:func:`gsverse_format.remapping.reference.prepare_rest`, as spec §Precision requires, and kept
in float64) and per-splat constants. For the ``local`` profile the splat-side constant is the
3×3 matrix ``L = R_l S_l`` (rotation matrix of the local quaternion times its scales), so that no
quaternion or ``exp`` work is left per frame. **Per frame** (:meth:`FastRemapper.remap`): for
splats grouped by face (as files store them), one parallel region over chunks of consecutive
splats handed out dynamically; each chunk computes the faces of its runs, then streams its
splats (:mod:`gsverse_format.remapping.compiled_runs`; faces without splats are never computed).
Otherwise a pass over all faces, then a streaming pass over the splats
(:mod:`gsverse_format.remapping.compiled`). Both give the same bits for every splat.

Outputs (:class:`RemapOutput`) are float32: means (N, 3) and the 6 unique covariance entries
(N, 6) in the order ``xx, xy, xz, yy, yz, zz`` (:data:`COV6_ORDER`). Covariance is the normative
output; rotation/scale pairs are produced on request for ``local``/``rigid`` (``q_c ⊗ q_l`` and
``k s_l``, k = 1 on faces degenerate at rest) and ``games`` (the face frame's quaternion and the
GaMeS scales). The ``affine`` law has no cheap rotation/scale pair (the reference takes an SVD
per splat); use the reference remap when one is needed.

Splats are processed in the order given. Files store them sorted by face (spec §Ordering), which
keeps the per-face data in cache; random order costs several times more at 100k faces.

Threads: numba's thread count (``numba.set_num_threads``) at each call. The work is handed out
in chunks from a shared counter: when another process keeps a thread off its core, the other
threads take the remaining chunks and the frame waits only for the chunk that thread holds
(once it runs again), not for its share of the work; the one-pass path also has one parallel
region (one join) per frame instead of two. Measured on 1 thread (CPU time, 100k-face grid of
``benchmarks/remap.py``): 100k splats 3.1 ms against 4.1 ms for the two passes (37% of the
faces carry no splat); 1M splats 14.6 ms against 13.7 ms (every face used; the alternation of
face and splat work per chunk costs about 7%). Per splat the remap is bound by scalar FMA
throughput (≈ 54 multiply-adds, ≈ 11 ns a splat on a 2.2 GHz EPYC), not by memory.

Selection: :func:`remap_auto` and ``FastRemapper(backend="auto")`` follow
:mod:`gsverse_format.backend`: numba when it can be imported, otherwise the numpy reference
(whose float64 result is then stored in the same float32 output buffers);
``GSVERSE_BACKEND=numpy`` or ``set_backend("numpy")`` forces the reference. A one-shot
:func:`remap_auto` of fewer than :data:`~gsverse_format.backend.REMAP_NUMPY_BELOW` splats runs
the reference under ``"auto"``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import quaternion as quat
from ..atomic import interruptions_immediate
from ..backend import REMAP_NUMPY_BELOW, numba_available, resolve_backend
from ..model import Anchoring, GamesAnchors
from ..vocabulary import COV6_INDEX, COV6_ORDER
from .reference import RestData, prepare_rest, remap as reference_remap

__all__ = ["COV6_ORDER", "RemapOutput", "FastRemapper", "remap_auto", "numba_available",
           "cov6_to_matrix", "matrix_to_cov6"]

_EMPTY4 = np.zeros((0, 4), np.float32)
_EMPTY3 = np.zeros((0, 3), np.float32)


def _threads() -> int:
    """numba's current thread count (``numba.set_num_threads``), the workers a kernel starts."""
    import numba

    return int(numba.get_num_threads())


def cov6_to_matrix(cov6: np.ndarray) -> np.ndarray:
    """(N, 6) unique entries → (N, 3, 3) float64 symmetric matrices."""
    c = np.asarray(cov6, dtype=np.float64)
    m = np.empty(c.shape[:-1] + (3, 3))
    for j, (r, s) in enumerate(COV6_INDEX):
        m[..., r, s] = c[..., j]
        m[..., s, r] = c[..., j]
    return m


def matrix_to_cov6(cov: np.ndarray) -> np.ndarray:
    """(N, 3, 3) → (N, 6) unique entries (upper triangle, :data:`COV6_ORDER`)."""
    cov = np.asarray(cov)
    return np.stack([cov[..., r, s] for r, s in COV6_INDEX], axis=-1)


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


class FastRemapper:
    """Remaps one anchored primitive, frame after frame, into preallocated float32 buffers.

    Build it once per asset (this precomputes the rest data and the per-splat constants), then
    call :meth:`remap` with the current anchor vertices (V, 3) every frame. The returned
    :class:`RemapOutput` is the remapper's own buffer set, overwritten by the next call (pass
    ``out=`` or ``.copy()`` it to keep a frame).

    ``rotations=True`` also produces rotation/scale pairs for the ``rigid`` law and the ``games``
    profile (ignored for ``affine``, whose covariance is the output). ``backend`` is ``"numba"``,
    ``"numpy"`` or ``"auto"``: the process-wide choice of :mod:`gsverse_format.backend` (numba
    when importable, unless ``GSVERSE_BACKEND`` or ``set_backend`` says otherwise). ``"numba"``
    without numba raises :class:`~gsverse_format.backend.BackendUnavailableError`.
    ``one_pass=False`` keeps the compiled path on its two passes even for splats grouped by
    face (same results; for comparing the two, see :attr:`one_pass`).
    """

    def __init__(self, anchoring: Anchoring, *, rotations: bool = False,
                 backend: str = "auto", one_pass: bool = True) -> None:
        self.anchoring = anchoring
        self.backend = resolve_backend(backend)
        anchors = anchoring.anchors
        self.profile = anchors.profile
        self.law = None if isinstance(anchors, GamesAnchors) else anchors.deformation
        self.rotations = bool(rotations) and self.law != "affine"
        mesh = anchoring.mesh
        self.n_splats = len(anchors)
        self.n_faces = mesh.face_count
        self.n_vertices = len(mesh.vertices)
        self._rest: RestData | None = None
        self._out = self.allocate()
        if self.backend == "numpy":
            if self.profile == "local":
                self._rest = prepare_rest(mesh.triangles())
            return
        self._faces = np.ascontiguousarray(mesh.faces, dtype=np.int32)
        self._face = np.ascontiguousarray(anchors.face_index, dtype=np.int32)
        with interruptions_immediate():   # compiled code: no Python handler may raise inside
            from . import compiled, compiled_runs

            # One pass over runs of splats sharing a face when the splats are grouped by face
            # (files sort them so); otherwise a face pass into a table, then a splat pass.
            self._plan = (compiled_runs.plan_runs(self._face, self.n_faces) if one_pass
                          else None)
        self._kernels = compiled
        self._runs_kernels = compiled_runs
        rows = self.n_faces if self._plan is None else self._plan.runs
        # The one pass of the affine law keeps its faces in a per-thread workspace: no table.
        table_rows = 0 if self._plan is not None and self.law == "affine" else rows
        self._table = np.zeros((table_rows, compiled.TABLE_WIDTH), np.float32)
        self._qlocal, self._slocal, self._qface = _EMPTY4, _EMPTY3, _EMPTY4
        if isinstance(anchors, GamesAnchors):
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
        self._qface = np.zeros((rows if self.rotations else 0, 4), np.float32)
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
    def one_pass(self) -> bool:
        """True when the compiled path remaps in one pass over runs of splats sharing a face
        (:mod:`gsverse_format.remapping.compiled_runs`; splats grouped by face, as files store
        them), False for the face pass + splat pass of :mod:`gsverse_format.remapping.compiled`."""
        return self.backend == "numba" and self._plan is not None

    @property
    def bytes_per_splat(self) -> int:
        """Bytes the compiled remap must stream per splat: the face (two passes) or run (one
        pass) index and the per-splat constants read, the outputs written. Per-face data stay
        in cache and are not counted."""
        if self.profile == "games":
            read, write = 4 + 12, 12 + 24
            if self.rotations:
                write += 16 + 12
        else:
            read, write = 4 + 48, 12 + 24
            if self.rotations:
                read += 16 + 12              # q_l, s_l
                write += 16 + 12
        return read + write

    # -- per frame

    def remap(self, vertices: np.ndarray | None = None,
              out: RemapOutput | None = None) -> RemapOutput:
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
        with interruptions_immediate():   # compiled code: no Python handler may raise inside
            return self._remap_compiled(v, out)

    def _remap_compiled(self, v: np.ndarray, out: RemapOutput) -> RemapOutput:
        workers = _threads()
        rotations, scales = ((out.rotations, out.scales) if self.rotations
                             else (_EMPTY4, _EMPTY3))
        plan = self._plan
        if plan is not None:
            r = self._runs_kernels
            if self.profile == "games":
                r.games_runs(v, self._faces, plan.face, plan.run_of, plan.start, plan.chunk,
                             self._consts, self._table, out.means, out.cov6, rotations, scales,
                             plan.size, workers)
            else:
                r.local_runs(v, self._faces, self._rest_table, self.law == "rigid", plan.face,
                             plan.run_of, plan.start, plan.chunk, self._consts, self._table,
                             self._qface, out.means, out.cov6, self._qlocal, self._slocal,
                             rotations, scales, plan.size, workers)
            return out
        self._face_pass(v)
        k = self._kernels
        if self.profile == "games":
            k.games_splats(self._face, self._consts, self._table, out.means, out.cov6,
                           rotations, scales, workers)
        else:
            k.local_splats(self._face, self._consts, self._table, out.means, out.cov6,
                           self._qlocal, self._slocal, self._qface, rotations, scales, workers)
        return out

    def face_pass(self, vertices: np.ndarray) -> None:
        """Only the per-face pass of the two-pass path (for timing its share; the one-pass
        path has no separate face pass)."""
        if self.backend == "numpy" or self._plan is not None:
            raise RuntimeError("only the two-pass compiled path has a separate face pass")
        with interruptions_immediate():   # compiled code: no Python handler may raise inside
            self._face_pass(vertices)

    def _face_pass(self, vertices: np.ndarray) -> None:
        if self.profile == "games":
            self._kernels.games_faces(vertices, self._faces, self._table, _threads())
        else:
            self._kernels.local_faces(vertices, self._faces, self._rest_table,
                                      self.law == "rigid", self._table, self._qface, _threads())

    def _remap_numpy(self, v: np.ndarray, out: RemapOutput) -> RemapOutput:
        r = reference_remap(self.anchoring, v, rest=self._rest)
        out.means[...] = r.means
        out.cov6[...] = matrix_to_cov6(r.covariances)
        if out.rotations is not None and out.scales is not None:
            out.rotations[...] = r.rotations
            out.scales[...] = r.scales
        return out

    def warm_up(self) -> "FastRemapper":
        """Compile (or load from the cache) the kernels on a tiny problem; returns self."""
        if self.backend == "numba":
            self.remap()
        return self


def remap_auto(anchoring: Anchoring, vertices: np.ndarray | None = None, *,
               rotations: bool = False, backend: str = "auto") -> RemapOutput:
    """One-shot remap with backend selection (``backend`` as in :class:`FastRemapper`).

    For per-frame use build a :class:`FastRemapper` once instead: construction precomputes
    the per-splat constants, which costs more than one remap. Under ``"auto"``, fewer than
    :data:`~gsverse_format.backend.REMAP_NUMPY_BELOW` splats run the numpy reference (no
    kernel compilation for a one-shot job that the reference finishes sooner).
    """
    chosen = resolve_backend(backend, size=len(anchoring.anchors), numpy_below=REMAP_NUMPY_BELOW)
    return FastRemapper(anchoring, rotations=rotations, backend=chosen).remap(vertices).copy()
