"""Sources for the splat formats of web viewers and capture apps: ``splat`` (antimatter15),
``ksplat`` (GaussianSplats3D), ``spz`` (Niantic), ``compressed-ply`` (SuperSplat / PlayCanvas)
and ``sog`` (PlayCanvas).

Each reads the file through its format (:mod:`gsverse_format.io.splatformats`, found in
:mod:`gsverse_format.io.registry` by suffix or, for compressed PLY and an unbundled SOG
``meta.json``, by content) and returns the splats in the file's frame — the 3DGS frame, or
``spz-rub`` for spz — with ``--mesh`` read as is and taken to be in that frame, like a plain
3DGS PLY's mesh. Without a mesh the pipeline reconstructs one from the splats. ``--from auto``
detects each by its file (before the plain 3DGS PLY, which answers last).
"""
from __future__ import annotations

from typing import Callable

from gsverse_format.converters.base import SourceOptions, SourceResult
from gsverse_format.converters.registry import register_source
from gsverse_format.io.mesh import read_mesh
from gsverse_format.io.registry import find_format
from gsverse_format.io.splatformats import FRAME_OF, decode
from gsverse_format.errors import GsverseError
from gsverse_format.model import SplatCloud

__all__ = ["NAMES"]

#: source name -> what ``--from auto`` says when it recognises the input
NAMES = {"splat": "antimatter15 .splat file", "ksplat": "GaussianSplats3D .ksplat file",
         "spz": "Niantic .spz file", "compressed-ply": "compressed PLY (SuperSplat/PlayCanvas)",
         "sog": "PlayCanvas SOG scene"}


def _format_of(input_path: str) -> str | None:
    try:
        return find_format(input_path, "read").name
    except GsverseError:
        return None


def _loader(name: str) -> Callable[[str, str | None, SourceOptions], SourceResult]:
    def load(input_path: str, mesh_path: str | None, options: SourceOptions) -> SourceResult:
        decoded = decode(name, input_path)
        splats: SplatCloud = decoded.splats
        mesh = read_mesh(mesh_path) if mesh_path is not None else None
        return SourceResult(splats, mesh, None, [f"read {decoded.version}", *decoded.notes],
                            frame=FRAME_OF[name])
    load.__doc__ = f"The splats of a {NAMES[name]} and the mesh (if any), in the file's frame."
    return load


def _detector(name: str) -> Callable[[str, str | None], str | None]:
    def detect(input_path: str, mesh_path: str | None) -> str | None:
        return f"input is a {NAMES[name]}" if _format_of(input_path) == name else None
    return detect


for _name in NAMES:
    register_source(_name, _loader(_name), detect=_detector(_name), priority=30)
