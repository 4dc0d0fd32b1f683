"""One registry for splat-asset formats, keyed by file extension (like meshio).

Every reader returns a :class:`SplatAsset` in the glTF coordinate frame (+Y up); every writer
takes one. PLY files are in the 3DGS frame: by default the PLY reader/writer here rotate 180°
about Z on the way in and out (see :mod:`gsverse_format.transform`); pass
``frame_change=False`` to keep coordinates as they are. USD files (``spec/usd.md``) need the
optional usd-core package.
"""
from __future__ import annotations

import os
from typing import Iterable

from dataclasses import dataclass
from typing import Any, Callable

from ..errors import UsageError
from ..model import SplatAsset, SplatCloud, SplatPrimitive
from ..transform import PLY_TO_GLTF, rotate_splats
from .usd import USD_SUFFIXES  # pxr itself is imported only when a USD file is used

SPLAT_INPUTS = (".ply", ".glb", ".gltf") + USD_SUFFIXES
SPLAT_OUTPUTS = (".glb", ".gltf", ".ply") + USD_SUFFIXES


@dataclass(frozen=True)
class FileFormat:
    """A registered splat-asset format: ``read(path) -> SplatAsset`` in the file's own
    coordinate frame, ``write(asset, path, *, protect=(), **options)``; ``frame`` is that
    frame: ``"gltf"`` (+Y up) or ``"3dgs"`` (the 3DGS capture frame, +Y down)."""

    name: str
    suffixes: tuple[str, ...]
    read: Callable[..., SplatAsset] | None = None
    write: Callable[..., Any] | None = None
    frame: str = "gltf"


#: suffix (lower case, with the dot) -> format; filled by :func:`register_format`.
FORMATS: dict[str, FileFormat] = {}


def register_format(name: str, suffixes: tuple[str, ...], *,
                    read: Callable[..., SplatAsset] | None = None,
                    write: Callable[..., Any] | None = None, frame: str = "gltf") -> None:
    """Register a format under its file suffixes (each format package calls this once)."""
    fmt = FileFormat(name, tuple(s.lower() for s in suffixes), read, write, frame)
    for suffix in fmt.suffixes:
        FORMATS[suffix] = fmt


def _ext(path: str | os.PathLike) -> str:
    return os.path.splitext(os.fspath(path))[1].lower()


def read_asset(path: str | os.PathLike, *, frame_change: bool = True) -> SplatAsset:
    """Read splats from a 3DGS PLY, a KHR_gaussian_splatting glTF/GLB or a USD file."""
    ext = _ext(path)
    if ext == ".ply":
        from .ply import read_splat_ply

        cloud = read_splat_ply(path)
        if frame_change:
            cloud = rotate_splats(cloud, PLY_TO_GLTF)
        name = os.path.splitext(os.path.basename(os.fspath(path)))[0]
        return SplatAsset([SplatPrimitive(cloud, None, name)])
    if ext in (".glb", ".gltf"):
        from .gltf import read_gltf

        return read_gltf(path)
    if ext in USD_SUFFIXES:
        from .usd import read_usd

        return read_usd(path)
    raise UsageError(f"unsupported splat input format {ext or '(no extension)'}; "
                     f"use one of {', '.join(SPLAT_INPUTS)}", path)


def write_asset(asset: SplatAsset, path: str | os.PathLike, *, frame_change: bool = True,
                protect: Iterable[str | os.PathLike] = (), bake_poses=None) -> None:
    """Write ``asset``; PLY output holds all splats of all primitives (no anchoring).

    ``bake_poses`` (a :class:`gsverse_format.io.usd.BakedPoses`) is for USD output only.
    """
    ext = _ext(path)
    protect = tuple(protect)
    if bake_poses is not None and ext not in USD_SUFFIXES:
        raise UsageError(f"baked poses need a USD output ({', '.join(USD_SUFFIXES)})", path)
    if ext in USD_SUFFIXES:
        from .usd import write_usd

        write_usd(asset, path, protect=protect, bake_poses=bake_poses)
        return
    if ext in (".glb", ".gltf"):
        from .gltf import write_gltf

        write_gltf(asset, path, protect=protect)
        return
    if ext == ".ply":
        from .ply import write_splat_ply

        if not asset.primitives:
            raise UsageError("nothing to write: the asset has no splats", path)
        cloud = SplatCloud.concatenate([p.splats for p in asset.primitives])
        if frame_change:
            cloud = rotate_splats(cloud, PLY_TO_GLTF)
        write_splat_ply(cloud, path, protect=protect)
        return
    raise UsageError(f"unsupported output format {ext or '(no extension)'}; "
                     f"use one of {', '.join(SPLAT_OUTPUTS)}", path)
