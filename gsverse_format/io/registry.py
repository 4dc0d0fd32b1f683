"""The table of splat-asset formats, keyed by file suffix (like meshio), and the frames they use.

Each format package registers itself once, at the end of its ``__init__``, with
:func:`register_format`: ``read(path) -> SplatAsset`` returns the file's content in the file's
own coordinate frame, ``write(asset, path, *, protect=(), **options)`` writes an asset given in
that frame, and ``frame`` names it (a key of :data:`FRAMES`). Formats never import each other
or this module's callers; :mod:`gsverse_format.io` imports every format package, so importing
anything from ``gsverse_format.io`` fills the table.

:func:`read_asset` and :func:`write_asset` are the callers' side: they dispatch on the suffix
and, with ``frame_change`` (the default), rotate between the file's frame and the glTF frame
(+Y up) in which every :class:`SplatAsset` of this package lives. glTF and USD files are in
the glTF frame already; 3DGS PLY files are in the 3DGS capture frame (+Y down), 180° about Z
away (:data:`gsverse_format.transform.PLY_TO_GLTF`); the web formats of :mod:`.splatformats`
use the 3DGS frame too, except spz (``spz-rub``). The conversion pipeline
(:mod:`gsverse_format.pipeline`) uses the same :data:`FRAMES` for the sources it reads.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any, Callable, Iterable

import numpy as np

from ..errors import UsageError
from ..model import (Anchoring, KhrProperties, SplatAsset, SplatPrimitive, TriangleMesh,
                     prim_label)
from ..transform import PLY_TO_GLTF, rotate_mesh, rotate_splats

__all__ = ["Frame", "FRAMES", "Z_UP_TO_GLTF", "FileFormat", "FORMATS", "VARIANTS",
           "register_format",
           "find_format", "suffixes", "rotate_asset", "read_asset", "write_asset", "khr_loss"]

#: Z-up scene (Blender world) -> glTF +Y up: (x, y, z) -> (x, z, −y).
Z_UP_TO_GLTF = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


@dataclass(frozen=True)
class Frame:
    """A coordinate frame a file or a source may use: the proper rotation ``to_gltf`` that
    takes it to the glTF frame, and the note the pipeline prints when it applies it."""

    name: str
    to_gltf: np.ndarray
    note: str


#: Every coordinate frame by name.
FRAMES: dict[str, Frame] = {f.name: f for f in (
    Frame("gltf", np.eye(3), ""),
    Frame("3dgs", PLY_TO_GLTF,
          "3DGS frame (+Y down) rotated 180 degrees about Z into glTF (+Y up)"),
    Frame("z-up", Z_UP_TO_GLTF, "Z-up scene rotated into glTF (+Y up) by (x, y, z) -> (x, z, -y)"),
    # spz's RUB (+Y up, +Z back) is the 3DGS frame with y and z flipped: 180 degrees about Y
    # puts an spz file where the PLY it was made from goes (the 3dgs frame's rotation)
    Frame("spz-rub", np.diag([-1.0, 1.0, -1.0]),
          "spz RUB frame (+Y up, +Z back) rotated 180 degrees about Y into glTF, where the "
          "3DGS PLY of the same splats goes"),
)}


@dataclass(frozen=True)
class FileFormat:
    """A registered splat-asset format: ``read(path) -> SplatAsset`` in the file's own
    coordinate frame, ``write(asset, path, *, protect=(), **options)``; ``frame`` is that
    frame, a key of :data:`FRAMES`: ``"gltf"`` (+Y up), ``"3dgs"`` (the 3DGS capture frame,
    +Y down) or ``"spz-rub"``.
    ``keeps_khr`` says whether the format stores every :class:`~gsverse_format.model.
    KhrProperties` (kernel, projection, sorting method, nested extensions); a format that
    does not is only given primitives with the defaults (:func:`write_asset` refuses others)."""

    name: str
    suffixes: tuple[str, ...]
    read: Callable[..., SplatAsset] | None = None
    write: Callable[..., Any] | None = None
    frame: str = "gltf"
    keeps_khr: bool = False
    #: for a format that shares its suffix with another (compressed PLY is a ``.ply``): whether
    #: a file is this format, from its content (never raises)
    sniff: Callable[[str], bool] | None = None


#: suffix (lower case, with the dot) -> format; filled by :func:`register_format`.
FORMATS: dict[str, FileFormat] = {}
#: suffix -> the formats registered with ``sniff`` for it: :func:`find_format` asks them
#: first when reading, and takes :data:`FORMATS`' entry when none claims the file.
VARIANTS: dict[str, list[FileFormat]] = {}


def register_format(name: str, suffixes: tuple[str, ...], *,
                    read: Callable[..., SplatAsset] | None = None,
                    write: Callable[..., Any] | None = None, frame: str = "gltf",
                    keeps_khr: bool = False,
                    sniff: Callable[[str], bool] | None = None) -> None:
    """Register a format under its file suffixes (each format package calls this once; a
    read-only format gives no ``write``). With ``sniff`` the format is a variant of its
    suffixes, chosen by content (:data:`VARIANTS`) and never their default."""
    if frame not in FRAMES:
        raise ValueError(f"unknown frame {frame!r}; use one of {', '.join(FRAMES)}")
    fmt = FileFormat(name, tuple(s.lower() for s in suffixes), read, write, frame, keeps_khr,
                     sniff)
    for suffix in fmt.suffixes:
        if sniff is not None:
            VARIANTS.setdefault(suffix, []).append(fmt)
        else:
            FORMATS[suffix] = fmt


def suffixes(kind: str = "read", name: str | None = None) -> tuple[str, ...]:
    """The registered suffixes that can be read (``kind="read"``) or written (``"write"``),
    of the format ``name`` only when given."""
    return tuple(s for s, f in FORMATS.items()
                 if getattr(f, kind) is not None and (name is None or f.name == name))


def _ext(path: str | os.PathLike[str]) -> str:
    return os.path.splitext(os.fspath(path))[1].lower()


def find_format(path: str | os.PathLike[str], kind: str = "read") -> FileFormat:
    """The format that reads (``kind="read"``) or writes (``"write"``) ``path``, by its suffix;
    :class:`UsageError` naming the supported suffixes when there is none."""
    ext = _ext(path)
    if kind == "read":
        for variant in VARIANTS.get(ext, ()):
            if variant.read is not None and variant.sniff is not None \
                    and variant.sniff(os.fspath(path)):
                return variant
    fmt = FORMATS.get(ext)
    if fmt is None or getattr(fmt, kind) is None:
        what = "splat input" if kind == "read" else "output"
        raise UsageError(f"unsupported {what} format {ext or '(no extension)'}; "
                         f"use one of {', '.join(suffixes(kind))}", path)
    return fmt


def rotate_asset(asset: SplatAsset, rotation: np.ndarray, *,
                 consume: bool = False) -> SplatAsset:
    """``asset`` rotated by the proper rotation ``rotation``: splats and anchor meshes (an
    anchor mesh shared by several primitives stays shared); anchors are relative to their
    triangles and do not change. ``consume``: the caller gives ``asset`` up (its SH may be
    rotated in place, see :func:`gsverse_format.transform.rotate_splats`)."""
    meshes: dict[int, TriangleMesh] = {}

    def mesh(m: TriangleMesh) -> TriangleMesh:
        if id(m) not in meshes:
            meshes[id(m)] = rotate_mesh(m, rotation)
        return meshes[id(m)]

    return SplatAsset([SplatPrimitive(rotate_splats(p.splats, rotation, consume=consume),
                                      Anchoring(mesh(p.anchoring.mesh), p.anchoring.anchors)
                                      if p.anchoring is not None else None, p.name, p.khr)
                       for p in asset.primitives], asset.generator)


def read_asset(path: str | os.PathLike[str], *, frame_change: bool = True) -> SplatAsset:
    """Read splats from any registered format (3DGS PLY, KHR_gaussian_splatting glTF/GLB, USD)
    into the glTF frame (in the file's own frame with ``frame_change=False``, which the
    asset's :attr:`~gsverse_format.model.SplatAsset.frame` then names)."""
    fmt = find_format(path, "read")
    assert fmt.read is not None
    asset = fmt.read(path)
    if frame_change and fmt.frame != "gltf":
        asset = rotate_asset(asset, FRAMES[fmt.frame].to_gltf, consume=True)  # read here
    elif fmt.frame != "gltf":
        asset.frame = fmt.frame   # kept in the file's frame: a glTF or USD output records it
    return asset


def khr_loss(props: KhrProperties, fmt: FileFormat, label: str = "the splats") -> str | None:
    """What ``fmt`` cannot store of the ``KHR_gaussian_splatting`` properties ``props`` of a
    primitive (one line starting with ``label``), or None."""
    if fmt.keeps_khr or props.is_default:
        return None
    return (f"{label} {'has' if label != 'the splats' else 'have'} "
            f"{', '.join(props.differences())}, which {fmt.name} output cannot store (it holds "
            f"ellipse-kernel splats with the default projection and sorting, and no glTF "
            f"extensions): write glTF instead")


def write_asset(asset: SplatAsset, path: str | os.PathLike[str], *, frame_change: bool = True,
                protect: Iterable[str | os.PathLike[str]] = (), **options: Any) -> None:
    """Write ``asset`` (in the glTF frame, or the one its ``frame`` names; taken as is with
    ``frame_change=False``) in the format of ``path``'s suffix. glTF and USD files hold the
    asset's frame as it is and record one that is not glTF's. ``options`` go to the format's writer: ``bake_poses`` (a
    :class:`gsverse_format.io.usd.BakedPoses`) is for USD output only. PLY output holds all
    splats of all primitives (no anchoring)."""
    fmt = find_format(path, "write")
    assert fmt.write is not None
    options = {k: v for k, v in options.items() if v is not None}
    if "bake_poses" in options and fmt.name != "usd":
        raise UsageError(f"baked poses need a USD output ({', '.join(suffixes('write', 'usd'))})",
                         path)
    for i, prim in enumerate(asset.primitives):
        problem = khr_loss(prim.khr, fmt, prim_label(i, prim))
        if problem is not None:
            raise UsageError(problem, path)
    if frame_change and fmt.frame != "gltf" and fmt.frame != asset.frame:
        # from the asset's frame (glTF's unless it was kept, see SplatAsset.frame) to the file's
        asset = rotate_asset(asset, FRAMES[fmt.frame].to_gltf.T @ FRAMES[asset.frame].to_gltf)
    fmt.write(asset, path, protect=tuple(protect), **options)
