"""Converters from other tools' outputs to anchored assets (installed as ``gsverse_format.converters``).

One module per source, each with ``load(input_path, mesh_path, options) -> SourceResult``
(:mod:`gsverse_format.converters.base`):

============  =====================================================================
``3dgs``      any 3DGS PLY, with ``--mesh`` (nearest-triangle binding) or without (a mesh is
              reconstructed from the splats)
``sugar``     SuGaR refined PLY + refined mesh: exact binding (splat i on face i // k)
``trellis``   TRELLIS PLY + GLB of the same run: frame change, welded mesh, nearest binding
``games``     GaMeS / GS-Verse output folder: ``games`` profile, lossless
``khr``       a ``KHR_gaussian_splatting`` .glb/.gltf as splat input, with ``--mesh``
============  =====================================================================
"""
from __future__ import annotations

import importlib
import os

from ..errors import UsageError

SOURCES = ("3dgs", "sugar", "trellis", "games", "khr")
_MODULES = {"3dgs": "threedgs", "sugar": "sugar", "trellis": "trellis", "games": "games",
            "khr": "khr"}


def loader(source: str):
    """The ``load`` function of ``source``."""
    if source not in _MODULES:
        raise UsageError(f"unknown source {source!r}; use one of auto, {', '.join(SOURCES)}")
    return importlib.import_module(f"{__name__}.{_MODULES[source]}").load


def detect_source(input_path: str, mesh_path: str | None) -> tuple[str, str]:
    """Guess the source from the inputs; returns (source, reason). Only unambiguous layouts
    are detected: everything else is plain ``3dgs`` (``--from`` overrides)."""
    ext = os.path.splitext(input_path)[1].lower()
    folder = input_path if os.path.isdir(input_path) else os.path.dirname(os.path.abspath(input_path))
    if os.path.isdir(input_path):
        return "games", "input is a folder (GaMeS / GS-Verse output)"
    if ext == ".ply" and any(os.path.isfile(os.path.join(folder, n))
                             for n in ("model_params.json", "model_params.pt")):
        return "games", "model_params.json/.pt beside the PLY (GaMeS / GS-Verse)"
    if ext in (".glb", ".gltf"):
        return "khr", "input is a glTF file (KHR_gaussian_splatting)"
    if ext == ".ply" and mesh_path is not None:
        from ..io.ply import describe_ply

        info = describe_ply(input_path)
        mesh_ext = os.path.splitext(mesh_path)[1].lower()
        if _looks_like_sugar(input_path, mesh_path, info):
            return "sugar", "splat count is k x face count with SuGaR's slot positions"
        if mesh_ext == ".glb" and info.get("sh_degree") == 0 and info.get("has_normals") \
                and not info.get("extra"):
            return "trellis", "SH0 PLY with normals and a GLB mesh (TRELLIS layout)"
    return "3dgs", "plain 3DGS PLY"


def _looks_like_sugar(ply_path: str, mesh_path: str, info: dict) -> bool:
    try:
        sugar = importlib.import_module(f"{__name__}.sugar")
    except ImportError:  # pragma: no cover
        return False
    probe = getattr(sugar, "matches_layout", None)
    return bool(probe and probe(ply_path, mesh_path, info))
