"""What every check receives, whatever the file format: the options, the findings collected so
far and a helper that turns per-element problems into a few examples.

The glTF checks use :class:`gsverse_format.validators.container.Context` (this plus the parsed
document); the USD checks use :class:`CheckContext` itself. The format-neutral value checks of
:mod:`.values` accept either.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gsverse_format.io.gltf import DEFAULT_MAX_BYTES

from .issues import Issues

__all__ = ["Options", "CheckContext"]


@dataclass
class Options:
    """What the checks may read: ``max_bytes`` caps the file plus all buffers it loads,
    ``max_data_uri_bytes`` each decoded ``data:`` URI, ``max_splats`` the splats of one
    primitive; ``max_examples`` is how many examples an aggregated finding lists."""

    max_bytes: int = DEFAULT_MAX_BYTES
    max_data_uri_bytes: int | None = None
    max_splats: int | None = None
    max_examples: int = 5


@dataclass
class CheckContext:
    """The file being checked, the options, the findings, and a cache for the checks."""

    path: str
    options: Options
    issues: Issues
    cache: dict = field(default_factory=dict, kw_only=True)

    def examples(self, indices: np.ndarray, **columns: np.ndarray) -> list[dict]:
        """Up to ``max_examples`` dicts {name: value} for the given element indices."""
        out = []
        for j in np.asarray(indices)[:self.options.max_examples]:
            item: dict[str, Any] = {}
            for name, values in columns.items():
                v = values[j]
                if isinstance(v, np.ndarray):
                    item[name] = [_scalar(x) for x in v.tolist()]
                else:
                    item[name] = _scalar(v)
            out.append(item)
        return out


def _scalar(v: Any) -> Any:
    if isinstance(v, (np.integer, int)) and not isinstance(v, bool):
        return int(v)
    if isinstance(v, (np.floating, float)):
        f = float(v)
        return f if np.isfinite(f) else str(f)
    return v
