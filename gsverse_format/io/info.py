"""What a splat file holds, for ``gsverse-info``: format, splat count, SH degree, bounds,
anchoring, meshes and the bytes each part takes.

:func:`describe` reads the file through its registered format (:mod:`.registry`, in the
file's own frame: bounds are in that frame, and the summary names it) and adds what only the
container knows: for glTF the bytes of each accessor group (:mod:`.gltf.document`), for PLY
the bytes of each property (:mod:`.ply.header`), for the web formats the parts their
decoders measure (:mod:`.splatformats`). Reading is the whole check: a file that does not
read is the reader's one-line error.
"""
from __future__ import annotations

import os
import re
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from ..errors import UsageError
from ..model import GamesAnchors, LocalAnchors, SplatAsset, TriangleMesh
from ..vocabulary import ANCHOR_FIELDS, DERIVED_KEYS, EXTENSION, FACE_COUNTS, KHR, SPZ_EXTENSION
from .registry import find_format

__all__ = ["FileInfo", "describe", "format_text"]

_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
_SH_SEMANTIC = re.compile(r"KHR_gaussian_splatting:SH_DEGREE_(\d+)_COEF_\d+\Z")
_F_REST = re.compile(r"f_rest_\d+\Z")
#: The most primitives the text summary lists one by one (``--json`` lists all).
MAX_LISTED = 20
_ANCHOR_KEYS = {f.key for f in ANCHOR_FIELDS} | {FACE_COUNTS.key}


@dataclass
class FileInfo:
    """The summary of one file (``asdict`` of it is the ``--json`` output)."""

    path: str
    format: str
    version: str
    frame: str
    bytes: int
    splats: int
    sh_degree: int | None
    bounds: dict[str, list[float]] | None
    primitives: list[dict[str, Any]] = field(default_factory=list)
    meshes: dict[str, Any] = field(default_factory=dict)
    parts: dict[str, int] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def _anchoring(prim: Any) -> dict[str, Any] | None:
    if prim.anchoring is None:
        return None
    anchors = prim.anchoring.anchors
    out: dict[str, Any] = {"profile": anchors.profile}
    if isinstance(anchors, LocalAnchors):
        out["deformation"] = anchors.deformation
    elif not isinstance(anchors, GamesAnchors):  # pragma: no cover - the model has two
        out["profile"] = type(anchors).__name__
    mesh = prim.anchoring.mesh
    out["mesh_triangles"] = mesh.face_count
    out["mesh_vertices"] = len(mesh.vertices)
    return out


def _meshes(asset: SplatAsset) -> dict[str, Any]:
    anchor: dict[int, TriangleMesh] = {}
    for prim in asset.primitives:
        if prim.anchoring is not None:
            anchor.setdefault(id(prim.anchoring.mesh), prim.anchoring.mesh)
    out: dict[str, Any] = {"anchor_meshes": len(anchor),
                           "anchor_triangles": sum(m.face_count for m in anchor.values())}
    rigged = sum(1 for m in anchor.values() if m.rig is not None)
    if rigged:
        out["animated_anchor_meshes"] = rigged
    if asset.colliders:
        out["colliders"] = len(asset.colliders)
        out["collider_triangles"] = sum(c.mesh.face_count for c in asset.colliders)
    return out


def _accessor_bytes(doc: dict, index: Any) -> int:
    accessors = doc.get("accessors") or []
    if not isinstance(index, int) or not 0 <= index < len(accessors):
        return 0
    acc = accessors[index]
    if not isinstance(acc, dict):
        return 0
    count = acc.get("count")
    components = _COMPONENTS.get(str(acc.get("type")), 0)
    size = _COMPONENT_BYTES.get(acc.get("componentType") or 0, 0)
    return count * components * size if isinstance(count, int) else 0


def _accessor_count(doc: dict, index: Any) -> int:
    accessors = doc.get("accessors") or []
    if not isinstance(index, int) or not 0 <= index < len(accessors) \
            or not isinstance(accessors[index], dict):
        return 0
    count = accessors[index].get("count")
    return count if isinstance(count, int) else 0


def _gltf_parts(path: str, info: FileInfo) -> None:
    """Bytes per accessor group: splat attributes by semantic, anchor fields by key, the
    triangles of meshes; the rest (JSON, images, padding, unused data) as ``other``."""
    from .gltf.document import open_document

    document = open_document(path)
    doc = document.doc
    info.version = f"glTF {doc.get('asset', {}).get('version', '2.0')} " + \
        ("(GLB)" if document.glb else "(JSON)")
    seen: set[int] = set()
    parts: dict[str, int] = {}

    def add(group: str, index: Any) -> None:
        if isinstance(index, int) and index not in seen:
            seen.add(index)
            parts[group] = parts.get(group, 0) + _accessor_bytes(doc, index)

    triangles = primitives = 0
    encodings: list[str] = []
    compressed: list[bool] = []
    for mesh in doc.get("meshes") or []:
        for prim in (mesh or {}).get("primitives") or []:
            if not isinstance(prim, dict):
                continue
            ext = (prim.get("extensions") or {}).get(KHR)
            attrs = prim.get("attributes") or {}
            if isinstance(ext, dict):
                spz = (ext.get("extensions") or {}).get(SPZ_EXTENSION)
                if isinstance(spz, dict):   # placeholders hold nothing: the stream does
                    view = spz.get("bufferView")
                    views = doc.get("bufferViews") or []
                    if isinstance(view, int) and 0 <= view < len(views) and \
                            isinstance(views[view], dict):
                        length = views[view].get("byteLength")
                        parts["splats SPZ stream"] = parts.get("splats SPZ stream", 0) + (
                            length if isinstance(length, int) else 0)
                    compressed.append(True)
                else:
                    compressed.append(False)
                for name, index in attrs.items():
                    sh = _SH_SEMANTIC.match(name)
                    if not isinstance(spz, dict):
                        add(f"splats SH degree {sh.group(1)}" if sh else f"splats {name}", index)
                anchor = (ext.get("extensions") or {}).get(EXTENSION)
                if isinstance(anchor, dict):
                    for key, index in anchor.items():
                        if key in _ANCHOR_KEYS:
                            add(f"anchors {key}", index)
                    compact = FACE_COUNTS.key in anchor or \
                        not any(k in anchor for k in DERIVED_KEYS)
                    encodings.append("compact" if compact else "explicit")
                continue
            if prim.get("mode", 4) == 4:
                primitives += 1
                corners = prim.get("indices", attrs.get("POSITION"))
                triangles += _accessor_count(doc, corners) // 3
            for name, index in attrs.items():
                add(f"mesh {name}", index)
            add("mesh indices", prim.get("indices"))
            for target in prim.get("targets") or []:
                for name, index in (target or {}).items():
                    add(f"morph targets {name}", index)
    for skin in doc.get("skins") or []:
        add("skins", (skin or {}).get("inverseBindMatrices"))
    for anim in doc.get("animations") or []:
        for sampler in (anim or {}).get("samplers") or []:
            add("animations", (sampler or {}).get("input"))
            add("animations", (sampler or {}).get("output"))
    parts["other (JSON, images, padding, unused)"] = max(0, document.size + sum(
        b.get("byteLength", 0) for b in (doc.get("buffers") or [])[int(document.glb):]
        if isinstance(b, dict) and isinstance(b.get("byteLength"), int)) - sum(parts.values()))
    info.parts = parts
    info.meshes["triangle_mesh_primitives"] = primitives
    info.meshes["triangles"] = triangles
    for entry, encoding in zip([p for p in info.primitives if p["anchoring"]], encodings):
        entry["anchoring"]["encoding"] = encoding
    for entry, spz in zip(info.primitives, compressed):
        if spz:
            entry["compression"] = "spz"


def _ply_parts(path: str, info: FileInfo) -> None:
    from .ply.header import read_ply_header

    header = read_ply_header(path)
    info.version = f"PLY {header.format} {header.version}"
    parts = {"header": header.data_offset}
    for element in header.elements:
        for prop in element.properties:
            if prop.is_list:
                parts[f"{element.name} {prop.name} (list)"] = 0
                continue
            name = "f_rest_*" if _F_REST.match(prop.name) else prop.name
            key = f"{element.name} {name}"
            parts[key] = parts.get(key, 0) + element.count * np.dtype(prop.type).itemsize
    if header.format == "ascii":
        info.notes.append("ascii PLY: sizes are those of the binary encoding")
    info.parts = parts


def describe(path: str | os.PathLike[str]) -> FileInfo:
    """The summary of ``path`` (any readable format); the reader's errors propagate."""
    path = os.fspath(path)
    if not os.path.exists(path):
        raise UsageError("file not found", path)
    fmt = find_format(path, "read")
    size = os.path.getsize(path) if os.path.isfile(path) else 0
    decoded = None
    if fmt.name in ("splat", "ksplat", "spz", "compressed-ply", "sog"):
        from .splatformats import decode

        decoded = decode(fmt.name, path)
        asset = decoded.asset()
    else:
        assert fmt.read is not None
        asset = fmt.read(path)
    prims = asset.primitives
    means = [p.splats.means for p in prims if len(p.splats)]
    bounds = None
    if means:
        allm = np.concatenate(means).astype(np.float64)
        bounds = {"min": allm.min(axis=0).tolist(), "max": allm.max(axis=0).tolist()}
    info = FileInfo(path, fmt.name, decoded.version if decoded else fmt.name, fmt.frame, size,
                    asset.splat_count(), max((p.splats.sh_degree for p in prims), default=None),
                    bounds)
    for i, prim in enumerate(prims):
        info.primitives.append({"index": i, "name": prim.name, "splats": len(prim.splats),
                                "sh_degree": prim.splats.sh_degree,
                                "anchoring": _anchoring(prim),
                                "physics": None if prim.physics is None else
                                {"kind": prim.physics.kind, "mass": prim.physics.mass}})
    info.meshes = _meshes(asset)
    if asset.ground is not None:
        info.meshes["ground"] = {"size": list(asset.ground.size),
                                 "translation": list(asset.ground.translation)}
    if decoded is not None:
        info.parts = dict(decoded.parts)
        info.notes.extend(decoded.notes)
    elif fmt.name == "gltf":
        _gltf_parts(path, info)
    elif fmt.name == "ply":
        _ply_parts(path, info)
    else:
        info.version = f"{fmt.name} ({os.path.splitext(path)[1].lower()})"
        info.parts = {"file": size}
    return info


def _vec(values: list[float]) -> str:
    return "(" + ", ".join(f"{v:.6g}" for v in values) + ")"


def format_text(info: FileInfo) -> str:
    """The human-readable summary (what ``gsverse-info`` prints without ``--json``)."""
    lines = [f"{info.path}: {info.format}, {info.version}, {info.bytes} bytes",
             f"  splats      {info.splats} in {len(info.primitives)} primitive(s)"
             + (f", SH degree {info.sh_degree}" if info.sh_degree is not None else "")]
    if info.bounds:
        lines.append(f"  bounds      min {_vec(info.bounds['min'])} max "
                     f"{_vec(info.bounds['max'])} ({info.frame} frame)")
    shown = info.primitives if len(info.primitives) <= MAX_LISTED else \
        info.primitives[:MAX_LISTED]
    for p in shown:
        a = p["anchoring"]
        if a is None:
            what = "not anchored"
        else:
            what = f"anchored: profile {a['profile']}"
            if "deformation" in a:
                what += f", deformation {a['deformation']}"
            if "encoding" in a:
                what += f", {a['encoding']} encoding"
            what += f"; anchor mesh {a['mesh_triangles']} triangles, {a['mesh_vertices']} vertices"
        if p.get("compression"):
            what += f"; rest pose {p['compression'].upper()}-compressed"
        body = p.get("physics")
        if body is not None:
            what += f"; physics {body['kind']}" + (f", {body['mass']:g} kg"
                                                  if body["mass"] is not None else "")
        label = f"primitive {p['index']}" + (f" {p['name']!r}" if p["name"] else "")
        lines.append(f"  {label}: {p['splats']} splats, SH degree {p['sh_degree']}, {what}")
    if len(shown) < len(info.primitives):
        lines.append(f"  ... and {len(info.primitives) - len(shown)} more primitives (--json "
                     "lists all)")
    m = info.meshes
    mesh_line = f"{m.get('anchor_meshes', 0)} anchor mesh(es), {m.get('anchor_triangles', 0)} " \
        "triangles"
    if "triangle_mesh_primitives" in m:
        mesh_line += f"; {m['triangle_mesh_primitives']} triangle mesh primitive(s) in the " \
            f"file, {m['triangles']} triangles"
    if m.get("animated_anchor_meshes"):
        mesh_line += f"; {m['animated_anchor_meshes']} animated"
    if m.get("colliders"):
        mesh_line += f"; {m['colliders']} collider(s), {m['collider_triangles']} triangles"
    lines.append(f"  meshes      {mesh_line}")
    if m.get("ground"):
        g = m["ground"]
        lines.append(f"  ground      static box {_vec(g['size'])}, centre {_vec(g['translation'])}")
    if info.parts:
        lines.append("  size by part")
        width = max(len(k) for k in info.parts)
        for key, value in info.parts.items():
            lines.append(f"    {key:<{width}}  {value:>12}")
    for note in info.notes:
        lines.append(f"  note        {note}")
    return "\n".join(lines)
