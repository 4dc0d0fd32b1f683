"""One interface over every deformation source: :func:`open_source` and :class:`Source`.

A source gives anchor-mesh vertices at any time: :meth:`Source.at` (V, 3) float64 in the anchor
mesh's frame and vertex order; :meth:`Source.match` checks it fits an anchor mesh before any
pose is computed; :meth:`Source.duration` is the time of its last key or frame (what
``gsverse-pose --fps`` samples without ``--duration``).
"""
from __future__ import annotations

import os
from typing import Protocol

import numpy as np

from ..errors import FormatError, UsageError
from .caches import VertexCache, check_npz, read_npz, read_sequence
from .gltf_source import open_gltf_source

__all__ = ["Source", "CacheSource", "open_source", "SOURCE_KINDS"]

#: What ``--source`` accepts, for messages and help.
SOURCE_KINDS = ("a skinned/morphed .glb/.gltf", "an .npz vertex cache (T, V, 3)",
                "an .exr vertex-animation texture", "a folder or glob of .obj/.ply frames")


class Source(Protocol):
    """A deformation source (see the module docstring)."""

    path: str

    def match(self, rest: np.ndarray, label: str = "the anchor mesh") -> None: ...

    def at(self, t: float) -> np.ndarray: ...

    def duration(self) -> float: ...


class CacheSource:
    """A :class:`~.caches.VertexCache` as a source; ``match`` checks the vertex count, and an
    offset VAT is resolved against the anchor mesh's rest pose when matched. An ``.npz``
    (``npz_options``) is checked from its headers when opened and loaded when matched (after
    its vertex count is checked on the headers) or first used."""

    def __init__(self, path: str, cache: VertexCache | None, *, vat_options: dict | None = None,
                 npz_options: dict | None = None):
        self.path = path
        self.cache = cache
        self.vat_options = vat_options
        self.npz_options = npz_options

    def match(self, rest: np.ndarray, label: str = "the anchor mesh") -> None:
        rest = np.asarray(rest, dtype=np.float64)
        if self.npz_options is not None and self.cache is None:
            check_npz(self.path, len(rest), label)
            self.cache = read_npz(self.path, **self.npz_options)
        if self.vat_options is not None:
            from .vat import read_vat

            self.cache = read_vat(self.path, rest=rest, vertex_count=len(rest),
                                  **self.vat_options)
        assert self.cache is not None
        if self.cache.vertex_count != len(rest):
            raise FormatError(f"holds {self.cache.vertex_count} vertices per frame but {label} "
                              f"has {len(rest)}", self.path)

    def _cache(self) -> VertexCache:
        if self.cache is None and self.npz_options is not None:
            self.cache = read_npz(self.path, **self.npz_options)
        if self.cache is None:
            raise UsageError("match the source to an anchor mesh first", self.path)
        return self.cache

    def at(self, t: float) -> np.ndarray:
        return self._cache().at(t)

    def duration(self) -> float:
        return self._cache().duration()


def open_source(spec: str | os.PathLike[str], *, animation: int | str | None = 0,
                fps: float = 24.0) -> Source:
    """Open ``spec`` by what it is: ``.glb``/``.gltf`` (skin, morph targets, animation),
    ``.npz`` (vertex cache), ``.exr`` (VAT; read when matched, since offsets need the rest
    pose), a folder or a glob pattern (mesh sequence), or a single ``.obj``/``.ply`` frame.
    ``fps`` spaces frames that carry no times. :class:`UsageError` for anything else."""
    spec = os.fspath(spec)
    ext = os.path.splitext(spec)[1].lower()
    if ext in (".glb", ".gltf") and os.path.isfile(spec):
        return open_gltf_source(spec, animation, prefer_anchor=True)
    if ext == ".npz":
        check_npz(spec)
        return CacheSource(spec, None, npz_options={"fps": fps})
    if ext == ".exr":
        if not os.path.isfile(spec):
            raise FormatError("file not found", spec)
        return CacheSource(spec, None, vat_options={"fps": fps})
    if os.path.isdir(spec) or any(c in spec for c in "*?[") or \
            ext in (".obj", ".ply", ".stl", ".off"):
        return CacheSource(spec, read_sequence(spec, fps))
    if not os.path.exists(spec):
        raise FormatError("file not found", spec)
    raise UsageError(f"unknown deformation source; give {', '.join(SOURCE_KINDS)}", spec)
