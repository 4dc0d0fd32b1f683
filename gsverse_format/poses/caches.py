"""Vertex caches: a sequence of poses of one mesh, stored frame by frame.

:class:`VertexCache` holds times (s) and vertices (T, V, 3) and samples them at any time
(linear interpolation between the two neighbouring frames; times outside clamp to the first or
last frame). Readers:

* :func:`read_npz`: an ``.npz`` with ``vertices`` (T, V, 3) and optionally ``times`` (T,) in
  seconds (strictly increasing) or a scalar ``fps``; without either, frames are ``1 / fps``
  apart (``fps`` argument, default 24) starting at 0. (The ``--bake-poses`` files of
  ``gsverse-convert``, whose ``times`` are USD time codes, carry ``time_codes_per_second``;
  their times are divided by it.)
* :func:`read_sequence`: one mesh file per frame (``.obj`` or ``.ply``, anything
  :func:`gsverse_format.io.mesh.read_mesh` reads), given as a folder (every mesh file in it) or
  a glob pattern, sorted by name with digit runs compared as numbers (``f2`` before ``f10``),
  frames ``1 / fps`` apart from 0.

Vertices are taken as they are: in the asset's frame (glTF, +Y up) and in the anchor mesh's
vertex order.
"""
from __future__ import annotations

import glob
import os
import re
from dataclasses import dataclass

import numpy as np

from ..errors import FormatError, GsverseError, UsageError

__all__ = ["VertexCache", "read_npz", "read_sequence", "sequence_files", "natural_key"]

SEQUENCE_SUFFIXES = (".obj", ".ply", ".stl", ".off")


@dataclass
class VertexCache:
    """Poses of a mesh: ``times`` (T,) float64 seconds, strictly increasing; ``vertices``
    (T, V, 3) float64; ``label`` names where they come from."""

    times: np.ndarray
    vertices: np.ndarray
    label: str = "vertex cache"

    def __post_init__(self) -> None:
        self.times = np.asarray(self.times, dtype=np.float64).reshape(-1)
        self.vertices = np.asarray(self.vertices, dtype=np.float64)
        v = self.vertices
        if v.ndim != 3 or v.shape[2] != 3:
            raise FormatError(f"vertices must have shape (T, V, 3), got {v.shape}")
        if v.shape[0] == 0 or v.shape[1] == 0:
            raise FormatError("the cache holds no frames or no vertices")
        if len(self.times) != v.shape[0]:
            raise FormatError(f"{v.shape[0]} frames but {len(self.times)} times")
        if not np.all(np.isfinite(self.times)) or np.any(np.diff(self.times) <= 0):
            raise FormatError("times must be finite and strictly increasing")
        if not np.all(np.isfinite(v)):
            raise FormatError("vertices contain NaN or infinite values")

    @property
    def vertex_count(self) -> int:
        return int(self.vertices.shape[1])

    def duration(self) -> float:
        """The time of the last frame (s)."""
        return float(self.times[-1])

    def at(self, t: float) -> np.ndarray:
        """Vertices (V, 3) at time ``t``: linear between neighbouring frames, clamped."""
        times = self.times
        if t <= times[0]:
            return self.vertices[0].copy()
        if t >= times[-1]:
            return self.vertices[-1].copy()
        k = int(np.searchsorted(times, t, side="right") - 1)
        s = (t - times[k]) / (times[k + 1] - times[k])
        return (1.0 - s) * self.vertices[k] + s * self.vertices[k + 1]


def _frame_times(count: int, fps: float) -> np.ndarray:
    if not (np.isfinite(fps) and fps > 0):
        raise UsageError(f"frame rate must be > 0, got {fps}")
    return np.arange(count, dtype=np.float64) / float(fps)


def read_npz(path: str | os.PathLike, fps: float = 24.0) -> VertexCache:
    """A vertex cache from an ``.npz`` (see the module docstring); :class:`FormatError` naming
    ``path`` for what it holds."""
    spath = os.fspath(path)
    try:
        with np.load(spath, allow_pickle=False) as data:
            if "vertices" not in data.files:
                raise FormatError(f"the .npz has no array 'vertices' (T, V, 3); it has "
                                  f"{', '.join(data.files) or 'nothing'}")
            vertices = np.asarray(data["vertices"], dtype=np.float64)
            if vertices.ndim == 2 and vertices.shape[1] == 3:
                vertices = vertices[None]
            if "times" in data.files:
                times = np.asarray(data["times"], dtype=np.float64).reshape(-1)
                if "time_codes_per_second" in data.files:
                    times = times / float(data["time_codes_per_second"])
            else:
                rate = float(data["fps"]) if "fps" in data.files else fps
                times = _frame_times(len(vertices), rate)
        return VertexCache(times, vertices, spath)
    except GsverseError as err:
        raise type(err)(err.cause, spath) from None
    except (OSError, ValueError, TypeError, EOFError) as err:
        raise FormatError(f"cannot read vertex cache: {' '.join(str(err).split())}",
                          spath) from None


def natural_key(path: str) -> list:
    """Sort key comparing digit runs as numbers: ``f2`` < ``f10``."""
    return [int(p) if p.isdigit() else p.lower() for p in re.split(r"(\d+)", path)]


def sequence_files(spec: str) -> list[str]:
    """The mesh files of a sequence given as a folder or a glob pattern, naturally sorted;
    :class:`UsageError` when there are none."""
    if os.path.isdir(spec):
        files = [os.path.join(spec, f) for f in os.listdir(spec)
                 if os.path.splitext(f)[1].lower() in SEQUENCE_SUFFIXES]
    else:
        files = [f for f in glob.glob(spec) if os.path.isfile(f)]
    if not files:
        raise UsageError("no mesh files (.obj, .ply, .stl, .off) found for the sequence", spec)
    return sorted(files, key=natural_key)


def read_sequence(spec: str | os.PathLike[str], fps: float = 24.0) -> VertexCache:
    """A vertex cache from one mesh file per frame (see the module docstring)."""
    from ..io.mesh import read_mesh

    spec = os.fspath(spec)
    files = sequence_files(spec)
    frames: list[np.ndarray] = []
    for f in files:
        v = read_mesh(f).vertices
        if frames and len(v) != len(frames[0]):
            raise FormatError(f"has {len(v)} vertices but the sequence's first frame "
                              f"{os.path.basename(files[0])} has {len(frames[0])}", f)
        frames.append(v.astype(np.float64))
    return VertexCache(_frame_times(len(frames), fps), np.stack(frames), spec)
