"""The asset paths of a layer's value clips, which USD opens without listing them as
composition arcs.

``Sdf.Layer.GetCompositionAssetDependencies`` names sublayers, references and payloads, but
not the layers of value clips (``clips`` metadata: ``assetPaths``, ``manifestAssetPath``,
``templateAssetPath``; and the older ``clipAssetPaths``, ``clipManifestAssetPath``,
``clipTemplateAssetPath`` prim metadata), which the stage opens when it composes or reads
values. :func:`clip_asset_paths` lists them so that the folder rule of :mod:`.stage` checks
them like any other arc. A template (``clip.###.usd``) is listed as written: its folder is
what the rule checks.
"""
from __future__ import annotations

from typing import Any

__all__ = ["CLIP_KEYS", "clip_asset_paths"]

#: Prim metadata (``clips`` dictionary entries and older top-level fields) that name files.
CLIP_KEYS = ("assetPaths", "manifestAssetPath", "templateAssetPath",
             "clipAssetPaths", "clipManifestAssetPath", "clipTemplateAssetPath")


def _paths(value: Any) -> list[str]:
    """The asset paths in one metadata value: an ``Sdf.AssetPath``, an array of them, a
    string (templates), or a dictionary holding such values (clip sets)."""
    if value is None:
        return []
    if isinstance(value, str):
        return [value] if value else []
    if hasattr(value, "path") and hasattr(value, "resolvedPath"):  # Sdf.AssetPath
        return [value.path] if value.path else []
    if isinstance(value, dict):
        out: list[str] = []
        for key, item in value.items():
            if isinstance(item, dict):
                out += _paths(item)
            elif key in CLIP_KEYS:
                out += _paths(item)
        return out
    try:
        items = list(value)
    except TypeError:
        return []
    return [p for item in items for p in _paths(item)]


def clip_asset_paths(layer: Any) -> list[str]:
    """Every value-clip asset path authored in ``layer`` (an ``Sdf.Layer``), on any prim
    spec, variants included."""
    found: list[str] = []

    def visit(path: Any) -> None:
        if not (path.IsPrimPath() or path.IsPrimVariantSelectionPath()):
            return
        spec = layer.GetObjectAtPath(path)
        if spec is None:
            return
        if spec.HasInfo("clips"):
            found.extend(_paths(spec.GetInfo("clips")))
        for key in CLIP_KEYS[3:]:
            if spec.HasInfo(key):
                found.extend(_paths(spec.GetInfo(key)))

    layer.Traverse(layer.pseudoRoot.path, visit)
    return found
