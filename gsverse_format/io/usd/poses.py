"""Anchor-mesh poses to bake into a USD file (``--bake-poses``): :class:`BakedPoses` and the
pose files :func:`load_poses` reads (``.npz`` or ``.json``)."""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass

import numpy as np

from ...errors import FormatError, GsverseError, UsageError

__all__ = ["BakedPoses", "load_poses"]


@dataclass
class BakedPoses:
    """Anchor-mesh poses to bake (``--bake-poses``).

    * ``times``    (P,) float64 USD time codes, finite and strictly increasing;
    * ``vertices`` (P, V, 3) float32 anchor-mesh vertex positions at each time code, in the
      frame and vertex order of the anchor mesh as written (glTF/USD frame: metres, +Y up);
    * ``time_codes_per_second`` the stage's ``timeCodesPerSecond`` (playback rate), > 0.
    """

    times: np.ndarray
    vertices: np.ndarray
    time_codes_per_second: float = 24.0

    def __post_init__(self) -> None:
        self.times = np.asarray(self.times, dtype=np.float64).reshape(-1)
        v = np.asarray(self.vertices, dtype=np.float32)
        if v.ndim != 3 or v.shape[2] != 3:
            raise UsageError(f"poses: vertices must have shape (P, V, 3), got {v.shape}")
        if v.shape[0] != self.times.shape[0]:
            raise UsageError(f"poses: {v.shape[0]} vertex sets but {self.times.shape[0]} times")
        if v.shape[0] == 0:
            raise UsageError("poses: no poses given")
        if not np.all(np.isfinite(self.times)) or np.any(np.diff(self.times) <= 0):
            raise UsageError("poses: times must be finite and strictly increasing")
        if not np.all(np.isfinite(v)):
            raise UsageError("poses: vertices contain NaN or infinite values")
        fps = float(self.time_codes_per_second)
        if not (math.isfinite(fps) and fps > 0):
            raise UsageError(f"poses: time_codes_per_second must be > 0, got {fps}")
        self.time_codes_per_second = fps
        self.vertices = np.ascontiguousarray(v)



def load_poses(path: str | os.PathLike) -> BakedPoses:
    """Read a ``--bake-poses`` file.

    * ``.npz``: arrays ``vertices`` (P, V, 3), ``times`` (P,) and optionally
      ``time_codes_per_second`` (a scalar, default 24);
    * ``.json``: a list of poses ``[{"time": t, "vertices": [[x, y, z], ...]}, ...]``, or an
      object ``{"timeCodesPerSecond": 24, "poses": [...]}`` with such a list.

    Times are USD time codes; vertices are in the frame and vertex order of the anchor mesh as
    written (see :class:`BakedPoses`). Raises :class:`FormatError` naming ``path`` for what the
    file holds (unreadable, missing arrays, poses :class:`BakedPoses` refuses), and
    :class:`UsageError` for a suffix other than ``.npz``/``.json``.
    """
    spath = os.fspath(path)
    ext = os.path.splitext(spath)[1].lower()
    try:
        if ext == ".npz":
            with np.load(spath, allow_pickle=False) as data:
                missing = [k for k in ("vertices", "times") if k not in data.files]
                if missing:
                    raise FormatError(f"poses .npz lacks array(s) {', '.join(missing)} "
                                     f"(needs vertices (P, V, 3) and times (P,))")
                fps = float(data["time_codes_per_second"]) if "time_codes_per_second" in \
                    data.files else 24.0
                return BakedPoses(data["times"], data["vertices"], fps)
        if ext == ".json":
            with open(spath, "rb") as handle:
                doc = json.loads(handle.read().decode("utf-8"))
            fps = 24.0
            if isinstance(doc, dict):
                fps = doc.get("timeCodesPerSecond", 24.0)
                if not isinstance(fps, (int, float)) or isinstance(fps, bool):
                    raise FormatError("poses JSON: timeCodesPerSecond must be a number")
                doc = doc.get("poses")
            if not isinstance(doc, list) or not all(
                    isinstance(p, dict) and "time" in p and "vertices" in p for p in doc):
                raise FormatError('poses JSON must be a list of {"time": t, "vertices": '
                                 '[[x, y, z], ...]} objects')
            try:
                times = np.array([p["time"] for p in doc], dtype=np.float64)
                vertices = np.array([p["vertices"] for p in doc], dtype=np.float32)
            except (TypeError, ValueError):
                raise FormatError("poses JSON: every time must be a number and every pose the "
                                 "same number of [x, y, z] vertices") from None
            return BakedPoses(times, vertices, fps)
    except UsageError as err:   # BakedPoses refuses what the file holds
        raise FormatError(err.cause, spath) from None
    except GsverseError as err:
        raise err.with_path(spath) from None
    except (OSError, ValueError, UnicodeDecodeError) as err:
        raise FormatError(f"cannot read poses: {' '.join(str(err).split())}", spath) from None
    raise UsageError(f"poses must be a .npz or .json file, not {ext or '(no extension)'}", spath)
