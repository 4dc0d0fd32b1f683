"""Opening a USD file as a stage, safely: the file must be a USD file, and no composition arc
(sublayer, reference, payload, value clip) may lead outside its folder."""
from __future__ import annotations

import os
import re
import types
from contextlib import contextmanager
from typing import Any, Iterator

import numpy as np

from ...errors import FormatError, GsverseError
from ...limits import MAX_USD_TEXT_BYTES, MAX_USD_TEXT_NESTING, MAX_USD_TEXT_PRIMS
from .clips import clip_asset_paths
from .schema import USD_SUFFIXES, pxr_errors, pxr_message

__all__ = ["MAX_LAYERS", "OutsideFolder", "check_path", "check_text_layer", "open_stage"]


def check_path(path: str) -> None:
    """Raise :class:`FormatError` unless ``path`` is an existing file with a USD suffix (and,
    for a text layer, within the limits of :func:`check_text_layer`)."""
    if os.path.isdir(path):
        raise FormatError("is a folder, not a USD file", path)
    if not os.path.isfile(path):
        raise FormatError("file not found", path)
    ext = os.path.splitext(path)[1].lower()
    if ext not in USD_SUFFIXES:
        raise FormatError(f"not a USD file name (use one of {', '.join(USD_SUFFIXES)})", path)
    check_text_layer(path)


#: The words that open a prim statement. Counted as substrings (``default`` counts too),
#: an upper bound of the prims a text layer declares.
_PRIM_WORDS = (b"def", b"over", b"class")
_SCAN_BLOCK = 2 ** 22


def check_text_layer(path: str) -> None:
    """Refuse a USD text layer (``#usda``) larger than :data:`~gsverse_format.limits.
    MAX_USD_TEXT_BYTES`, declaring more prims than :data:`~gsverse_format.limits.
    MAX_USD_TEXT_PRIMS`, or nesting brackets deeper than :data:`~gsverse_format.limits.
    MAX_USD_TEXT_NESTING`, before the USD library parses it: its text parser takes tens to
    hundreds of times a layer's size in memory, and deep nesting overflows its stack. The
    text is scanned in blocks; binary (``usdc``) and packaged (``usdz``) files pass."""
    with open(path, "rb") as handle:
        if handle.read(5) != b"#usda":
            return
        size = os.fstat(handle.fileno()).st_size
        if size > MAX_USD_TEXT_BYTES:
            raise FormatError(f"USD text layer is {size} bytes, larger than the limit of "
                              f"{MAX_USD_TEXT_BYTES} bytes (store large data as .usdc)", path)
        handle.seek(0)
        prims = depth = deepest = 0
        while True:
            block = handle.read(_SCAN_BLOCK)
            if not block:
                break
            prims += sum(block.count(word) for word in _PRIM_WORDS)
            codes = np.frombuffer(block, np.uint8)
            running = depth + np.cumsum(_BRACKET_STEP[codes], dtype=np.int64)
            deepest = max(deepest, int(running.max(initial=depth)))
            depth = int(running[-1])
            if prims > MAX_USD_TEXT_PRIMS or deepest > MAX_USD_TEXT_NESTING:
                break
    if prims > MAX_USD_TEXT_PRIMS:
        raise FormatError(f"USD text layer declares more than {MAX_USD_TEXT_PRIMS} prims "
                          f"(def/over/class; the limit of one text layer)", path)
    if deepest > MAX_USD_TEXT_NESTING:
        raise FormatError(f"USD text layer nests brackets more than {MAX_USD_TEXT_NESTING} "
                          f"deep (the limit of one text layer)", path)


#: +1 for an opening bracket, -1 for a closing one, by byte value.
_BRACKET_STEP = np.zeros(256, np.int8)
_BRACKET_STEP[np.frombuffer(b"{[(", np.uint8)] = 1
_BRACKET_STEP[np.frombuffer(b"}])", np.uint8)] = -1


#: At most this many layers are followed when checking a file's composition arcs.
MAX_LAYERS = 4096


class OutsideFolder(FormatError):
    """A composition arc of the file leads outside the file's folder."""


def _inside(resolved: str, folder: str) -> bool:
    outer = resolved.split("[", 1)[0]  # "pkg.usdz[inner.usdc]": the package is what counts
    real = os.path.realpath(outer)
    return real == folder or real.startswith(folder.rstrip(os.sep) + os.sep)


def _check_composition(px: types.SimpleNamespace, path: str) -> None:
    """Refuse files whose sublayers, references, payloads or value clips leave the file's
    folder.

    Like the glTF reader's URI rules: an asset path with a scheme (``http:``, ...), an
    absolute path, or a relative path that resolves (symbolic links followed) outside the
    folder of ``path`` is refused before USD composes anything, so that opening a file never
    reads files elsewhere. Layers inside a ``.usdz`` package are inside by definition.
    Dependencies are followed recursively (``MAX_LAYERS`` at most); a dependency that does
    not exist or does not open is left to USD (which reports it as a warning).
    """
    folder = os.path.realpath(os.path.dirname(os.path.abspath(path)))
    root = px.Sdf.Layer.FindOrOpen(path)
    if root is None:
        return  # not a layer at all: Usd.Stage.Open says why
    todo, seen = [root], {root.identifier}
    while todo:
        layer = todo.pop()
        for dep in list(layer.GetCompositionAssetDependencies()) + clip_asset_paths(layer):
            scheme = re.match(r"^([A-Za-z][A-Za-z0-9+.-]*):", dep)
            if scheme and len(scheme.group(1)) > 1:
                raise OutsideFolder(f"composition arc to {dep!r} in {layer.GetDisplayName()}: "
                                    f"URI schemes are not followed", path)
            if os.path.isabs(dep) or dep.startswith(("\\", "//")) or scheme:
                raise OutsideFolder(f"composition arc to the absolute path {dep!r} in "
                                    f"{layer.GetDisplayName()}: only paths inside the "
                                    f"asset's folder are followed", path)
            resolved = layer.ComputeAbsolutePath(dep)
            if not _inside(resolved, folder):
                raise OutsideFolder(f"composition arc to {dep!r} in {layer.GetDisplayName()} "
                                    f"leaves the asset's folder", path)
            if resolved in seen:
                continue
            seen.add(resolved)
            if len(seen) > MAX_LAYERS:
                raise FormatError(f"more than {MAX_LAYERS} layers in the composition", path)
            outer = resolved.split("[", 1)[0]
            if os.path.isfile(outer):  # a text sublayer within the limits before USD parses it
                try:
                    check_text_layer(outer)
                except FormatError as err:
                    raise FormatError(f"layer {os.path.basename(outer)}: {err.cause}",
                                      path) from None
            try:
                child = px.Sdf.Layer.FindOrOpen(resolved)
            except pxr_errors():
                child = None
            if child is not None:
                todo.append(child)


def open_stage(px: types.SimpleNamespace, path: str) -> Any:
    """Open ``path`` as a USD stage; every failure is a one-line FormatError."""
    check_path(path)
    try:
        existing = px.Sdf.Layer.Find(path)
        if existing is not None and not existing.dirty:
            existing.Reload(True)  # the file may have been replaced since it was opened
        _check_composition(px, path)
        stage = px.Usd.Stage.Open(path, px.Usd.Stage.LoadAll)
    except pxr_errors() as err:
        raise FormatError(f"not a readable USD file: {pxr_message(err)}", path) from None
    if stage is None:
        raise FormatError("not a readable USD file", path)
    return stage


@contextmanager
def input_errors(spath: str) -> Iterator[None]:
    """What reading ``spath`` raises for bad input, as one :class:`FormatError` naming it:
    our own errors get the path, USD's own errors and running out of memory become
    "malformed USD" / "not enough memory". Anything else is a bug and propagates."""
    try:
        yield
    except GsverseError as err:
        raise err.with_path(spath) from None
    except MemoryError:
        raise FormatError("not enough memory to read the asset", spath) from None
    except pxr_errors() as err:
        raise FormatError(f"malformed USD ({type(err).__name__}: {pxr_message(err)})",
                          spath) from None
