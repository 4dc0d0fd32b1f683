"""What the web splat formats' decoders share: the model's splat cloud from decoded arrays, and
the description of a file's parts for ``gsverse-info``."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...errors import FormatError
from ...model import SplatAsset, SplatCloud, SplatPrimitive
from ...vocabulary import SH_C0

__all__ = ["SH_C0", "Decoded", "splat_cloud", "color_to_dc", "sh_rest_index"]


@dataclass
class Decoded:
    """A decoded file: its splats, its format version (or variant), the bytes of each part
    of the file (what ``gsverse-info`` prints as "size by part") and notes on what was not
    kept."""

    splats: SplatCloud
    version: str
    parts: dict[str, int] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def asset(self, name: str | None = None) -> SplatAsset:
        return SplatAsset([SplatPrimitive(self.splats, None, name)])


def color_to_dc(value: np.ndarray) -> np.ndarray:
    """A colour in [0, 1] (the value a renderer shows for SH degree 0) as the 3DGS ``f_dc``
    coefficient: ``(value − 0.5) / SH_C0``."""
    return (np.asarray(value, np.float64) - 0.5) / SH_C0


def sh_rest_index(degree: int) -> tuple[np.ndarray, np.ndarray]:
    """For the channel-major ``f_rest`` layout of 3DGS PLY (``f_rest[c·(K−1) + (j−1)]`` is
    coefficient ``j`` of channel ``c``): the (coefficient, channel) of each ``f_rest`` index."""
    rest = (degree + 1) ** 2 - 1
    index = np.arange(3 * rest)
    return index % rest + 1, index // rest


def splat_cloud(means: np.ndarray, rotations_wxyz: np.ndarray, scales: np.ndarray,
                opacities: np.ndarray, sh: np.ndarray, path: str) -> SplatCloud:
    """The model's splats from decoded float64 arrays: quaternions ``(w, x, y, z)`` are
    normalized and reordered to ``(x, y, z, w)`` (a zero quaternion, which no rotation
    encodes, becomes the identity); anything not finite is refused."""
    q = np.asarray(rotations_wxyz, np.float64)
    if not np.isfinite(q).all():
        row = int(np.argwhere(~np.isfinite(q))[0][0])
        raise FormatError(f"splat {row} has a rotation value that is not finite", path)
    norm = np.linalg.norm(q, axis=1)
    zero = ~(norm > 0)
    q = np.where(zero[:, None], [1.0, 0.0, 0.0, 0.0], q / np.where(zero, 1.0, norm)[:, None])
    arrays = {"positions": means, "scales": scales, "opacities": opacities, "colours": sh}
    for what, array in arrays.items():
        bad = ~np.isfinite(np.asarray(array, np.float64))
        if bad.any():
            row = int(np.argwhere(bad)[0][0])
            raise FormatError(f"splat {row} has a {what[:-1]} value that is not finite", path)
    if (np.asarray(scales) < 0).any():
        row = int(np.argwhere(np.asarray(scales) < 0)[0][0])
        raise FormatError(f"splat {row} has a negative scale", path)
    big = np.abs(np.asarray(means, np.float64)) > np.finfo(np.float32).max
    if big.any():
        raise FormatError(f"splat {int(np.argwhere(big)[0][0])} has a position beyond the "
                          "float32 range", path)
    return SplatCloud(means, q[:, [1, 2, 3, 0]], scales, np.clip(opacities, 0.0, 1.0), sh)
