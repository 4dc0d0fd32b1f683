"""The splat formats of web viewers and capture apps, read-only: ``.splat`` (antimatter15),
``.ksplat`` (GaussianSplats3D), ``.spz`` (Niantic, v2/v3), compressed PLY (SuperSplat /
PlayCanvas) and SOG (PlayCanvas; ``.sog`` archives or ``meta.json``).

One package with a module per format, because the formats share almost nothing but their
byte layer (:mod:`.container`: whole files, gzip, zip bundles, WebP through Pillow) and the
step from decoded arrays to the model (:mod:`.common`); each module is the splat layer of one
format and documents its encoding. Compressed PLY is a PLY container: its module reads it
with the PLY container layer (:mod:`gsverse_format.io.ply.container`), not with the 3DGS PLY
splat layer.

Each format registers itself read-only in :data:`gsverse_format.io.registry.FORMATS` with the
frame its files use (``3dgs``: the 3DGS capture frame, +Y down; ``spz-rub`` for spz);
compressed PLY and an unbundled SOG ``meta.json`` are variants of ``.ply`` and ``.json``
recognised by content (:data:`gsverse_format.io.registry.VARIANTS`). ``gsverse-convert``
reads them through the sources of :mod:`gsverse_format.converters.splatformats`. The formats
and their frames are described in ``spec/inputs.md``.
"""
from __future__ import annotations

import os
from typing import Callable

import numpy as np

from ...model import SplatAsset
from ..registry import register_format
from .antimatter import read_antimatter_splat
from .common import Decoded
from .compressed_ply import is_compressed_ply, read_compressed_ply
from .ksplat import read_ksplat
from .sog import is_sog_meta, read_sog
from .spz import read_spz

__all__ = ["DECODERS", "FRAME_OF", "Decoded", "decode", "read_antimatter_splat", "read_ksplat",
           "read_spz",
           "read_compressed_ply", "read_sog", "is_compressed_ply", "is_sog_meta"]

#: format name -> decoder (path -> :class:`Decoded`, in the file's own frame)
DECODERS: dict[str, Callable[[str], Decoded]] = {
    "splat": read_antimatter_splat, "ksplat": read_ksplat, "spz": read_spz,
    "compressed-ply": read_compressed_ply, "sog": read_sog}


#: format name -> the frame its files use (a key of :data:`gsverse_format.io.registry.FRAMES`)
FRAME_OF = {"splat": "3dgs", "ksplat": "3dgs", "spz": "spz-rub", "compressed-ply": "3dgs",
            "sog": "3dgs"}


def decode(name: str, path: str | os.PathLike[str]) -> Decoded:
    """Decode ``path`` as the format ``name`` (a key of :data:`DECODERS`). Overflow while
    dequantizing is not a warning: every decoded value is checked to be finite, and a file
    whose values are not is refused (:func:`.common.splat_cloud`)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return DECODERS[name](os.fspath(path))


def _reader(name: str) -> Callable[..., SplatAsset]:
    def read(path: str | os.PathLike[str]) -> SplatAsset:
        return decode(name, path).asset(os.path.basename(os.fspath(path)))
    read.__doc__ = f"Read a {name} file as a splat asset in the file's frame."
    return read


register_format("splat", (".splat",), read=_reader("splat"), frame=FRAME_OF["splat"])
register_format("ksplat", (".ksplat",), read=_reader("ksplat"), frame=FRAME_OF["ksplat"])
register_format("spz", (".spz",), read=_reader("spz"), frame=FRAME_OF["spz"])
register_format("sog", (".sog",), read=_reader("sog"), frame=FRAME_OF["sog"])
register_format("sog", (".json",), read=_reader("sog"), frame=FRAME_OF["sog"], sniff=is_sog_meta)
register_format("compressed-ply", (".ply",), read=_reader("compressed-ply"),
                frame=FRAME_OF["compressed-ply"], sniff=is_compressed_ply)
