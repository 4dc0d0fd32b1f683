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
import zipfile
from dataclasses import dataclass

import numpy as np

from ..errors import FormatError, GsverseError, UsageError
from ..limits import MAX_NPZ_RATIO, NPZ_SLACK

__all__ = ["VertexCache", "read_npz", "check_npz", "read_sequence", "sequence_files",
           "natural_key"]

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


def _npy_headers(zf: zipfile.ZipFile) -> dict[str, tuple[tuple[int, ...], np.dtype]]:
    """Shape and dtype of every ``.npy`` member, from its header alone (nothing loaded)."""
    out = {}
    for info in zf.infolist():
        if not info.filename.endswith(".npy"):
            continue
        with zf.open(info) as f:
            version = np.lib.format.read_magic(f)
            if version == (1, 0):
                shape, _, dtype = np.lib.format.read_array_header_1_0(f)
            elif version == (2, 0):
                shape, _, dtype = np.lib.format.read_array_header_2_0(f)
            else:
                raise FormatError(f"array {info.filename[:-4]!r} is .npy version "
                                  f"{version[0]}.{version[1]}; 1.0 and 2.0 are read")
        out[info.filename[:-4]] = (tuple(int(n) for n in shape), np.dtype(dtype))
    return out


def check_npz(path: str | os.PathLike, vertex_count: int | None = None,
              label: str = "the anchor mesh") -> None:
    """Check an ``.npz`` vertex cache from the ``.npy`` headers inside the zip, before any array
    is loaded: ``vertices`` of shape (T, V, 3) or (V, 3) and a numeric dtype, V equal to
    ``vertex_count`` when given, and the arrays' bytes at most
    :data:`~gsverse_format.limits.MAX_NPZ_RATIO` times the file's size plus
    :data:`~gsverse_format.limits.NPZ_SLACK`. :class:`FormatError` naming ``path``."""
    spath = os.fspath(path)
    try:
        size = os.path.getsize(spath)
        with zipfile.ZipFile(spath) as zf:
            headers = _npy_headers(zf)
    except GsverseError as err:
        raise type(err)(err.cause, spath) from None
    except (OSError, ValueError, TypeError, EOFError, zipfile.BadZipFile) as err:
        raise FormatError(f"cannot read vertex cache: {' '.join(str(err).split())}",
                          spath) from None
    if "vertices" not in headers:
        raise FormatError(f"the .npz has no array 'vertices' (T, V, 3); it has "
                          f"{', '.join(sorted(headers)) or 'nothing'}", spath)
    allowed = MAX_NPZ_RATIO * size + NPZ_SLACK
    declared = 0
    for name, (shape, dtype) in sorted(headers.items()):
        if dtype.kind not in "biuf":
            raise FormatError(f"array {name!r} holds {dtype}, not numbers", spath)
        count = 1
        for n in shape:
            count *= n
        declared += count * max(dtype.itemsize, 8)     # read as float64
        if declared > allowed:
            raise FormatError(f"array {name!r} declares {count} elements of {dtype} "
                              f"(shape {shape}): more than {MAX_NPZ_RATIO} times the "
                              f"file's {size} bytes plus {NPZ_SLACK >> 20} MiB", spath)
    shape = headers["vertices"][0]
    if not (len(shape) == 3 and shape[2] == 3) and not (len(shape) == 2 and shape[1] == 3):
        raise FormatError(f"vertices must have shape (T, V, 3), got {shape}", spath)
    if vertex_count is not None and shape[-2] != vertex_count:
        raise FormatError(f"holds {shape[-2]} vertices per frame but {label} has "
                          f"{vertex_count}", spath)


def read_npz(path: str | os.PathLike, fps: float = 24.0) -> VertexCache:
    """A vertex cache from an ``.npz`` (see the module docstring), checked first by
    :func:`check_npz`; :class:`FormatError` naming ``path`` for what it holds."""
    spath = os.fspath(path)
    check_npz(spath)
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
