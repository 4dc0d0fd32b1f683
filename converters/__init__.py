"""Converters from other tools' outputs to anchored assets (installed as ``gsverse_format.converters``).

One module per source; each registers itself in :mod:`gsverse_format.converters.registry`
with ``load(input_path, mesh_path, options) -> SourceResult``
(:mod:`gsverse_format.converters.base`) and a detector for ``--from auto``:

============  =====================================================================
``3dgs``      any 3DGS PLY, with ``--mesh`` (nearest-triangle binding) or without (the
              pipeline reconstructs a mesh from the splats, :mod:`.reconstruct`)
``sugar``     SuGaR refined PLY + refined mesh: exact binding (splat i on face i // k)
``trellis``   TRELLIS PLY + GLB of the same run: frame change, welded mesh, nearest binding
``games``     GaMeS / GS-Verse output folder: ``games`` profile, lossless
``khr``       a ``KHR_gaussian_splatting`` .glb/.gltf as splat input, with ``--mesh``
``spz`` etc.  ``splat``, ``ksplat``, ``spz``, ``compressed-ply``, ``sog`` (:mod:`.splatformats`)
============  =====================================================================

Importing this package registers all of them (in this order, which ``--help`` shows).
"""
from __future__ import annotations

# Each import registers one source; this order is the order of ``--from``'s choices.
from gsverse_format.converters import threedgs  # noqa: F401  isort: skip
from gsverse_format.converters import sugar  # noqa: F401  isort: skip
from gsverse_format.converters import trellis  # noqa: F401  isort: skip
from gsverse_format.converters import games  # noqa: F401  isort: skip
from gsverse_format.converters import khr  # noqa: F401  isort: skip
from gsverse_format.converters import splatformats  # noqa: F401  isort: skip
from gsverse_format.converters.registry import SOURCES, detect_source, get_source

__all__ = ["SOURCES", "detect_source", "get_source"]
