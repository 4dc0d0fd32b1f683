"""A small GLB toolkit: pack and unpack containers, build buffers, patch accessor data.

The conformance suite writes some assets by hand (the skinned test asset) and derives the
invalid assets from valid ones by editing their JSON and binary chunk. These helpers work on
the plain JSON document (a ``dict``) and the ``BIN`` chunk (``bytes``), without any glTF
library, so that what they do is exactly what the bytes say.
"""
from __future__ import annotations

import json
import struct

import numpy as np

from ..io.gltf import BufferBuilder  # the writer's buffer builder, shared with the suite

__all__ = ["pack_glb", "unpack_glb", "BufferBuilder", "accessor_bytes", "patch_accessor",
           "anchored_primitive", "anchor_extension", "anchor_primitive", "append_accessor",
           "COMPONENT_DTYPES", "TYPE_COMPONENTS", "BYTE", "UNSIGNED_BYTE", "SHORT",
           "UNSIGNED_SHORT", "UNSIGNED_INT", "FLOAT"]

BYTE, UNSIGNED_BYTE, SHORT, UNSIGNED_SHORT, UNSIGNED_INT, FLOAT = 5120, 5121, 5122, 5123, 5125, 5126
COMPONENT_DTYPES: dict[int, np.dtype] = {BYTE: np.dtype("<i1"), UNSIGNED_BYTE: np.dtype("<u1"),
                    SHORT: np.dtype("<i2"), UNSIGNED_SHORT: np.dtype("<u2"),
                    UNSIGNED_INT: np.dtype("<u4"), FLOAT: np.dtype("<f4")}
TYPE_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}

_MAGIC = b"glTF"
_JSON = 0x4E4F534A
_BIN = 0x004E4942


def pack_glb(doc: dict, blob: bytes) -> bytes:
    """GLB 2.0 container bytes for JSON ``doc`` and binary chunk ``blob`` (both padded)."""
    text = json.dumps(doc, separators=(",", ":"), allow_nan=False).encode("utf-8")
    text += b" " * (-len(text) % 4)
    out = struct.pack("<II", len(text), _JSON) + text
    if blob:
        blob = bytes(blob) + b"\0" * (-len(blob) % 4)
        out += struct.pack("<II", len(blob), _BIN) + blob
    return struct.pack("<4sII", _MAGIC, 2, 12 + len(out)) + out


def unpack_glb(data: bytes) -> tuple[dict, bytes]:
    """(JSON document, BIN chunk or b"") of a well-formed GLB; ``ValueError`` otherwise."""
    if len(data) < 12 or data[:4] != _MAGIC:
        raise ValueError("not a GLB container")
    _, version, length = struct.unpack_from("<4sII", data, 0)
    if version != 2 or length != len(data):
        raise ValueError("unsupported GLB version or wrong length")
    pos, chunks = 12, []
    while pos + 8 <= length:
        size, kind = struct.unpack_from("<II", data, pos)
        chunks.append((kind, data[pos + 8:pos + 8 + size]))
        pos += 8 + size
    if not chunks or chunks[0][0] != _JSON:
        raise ValueError("GLB does not start with a JSON chunk")
    blob = chunks[1][1] if len(chunks) > 1 and chunks[1][0] == _BIN else b""
    return json.loads(chunks[0][1].decode("utf-8")), bytes(blob)


def _layout(doc: dict, index: int) -> tuple[int, int, np.dtype, int, int]:
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    dtype = COMPONENT_DTYPES[acc["componentType"]]
    ncomp = TYPE_COMPONENTS[acc["type"]]
    stride = view.get("byteStride", dtype.itemsize * ncomp)
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    return start, stride, dtype, ncomp, acc["count"]


def accessor_bytes(doc: dict, blob: bytes, index: int) -> np.ndarray:
    """Accessor ``index`` as a (count, ncomp) array in its stored dtype (copy)."""
    start, stride, dtype, ncomp, count = _layout(doc, index)
    arr = np.ndarray((count, ncomp), dtype=dtype, buffer=blob, offset=start,
                     strides=(stride, dtype.itemsize))
    return np.array(arr, copy=True)


def patch_accessor(doc: dict, blob: bytes, index: int, values: np.ndarray) -> bytes:
    """A copy of ``blob`` with accessor ``index`` overwritten by ``values`` (same shape);
    ``min``/``max`` of the accessor are updated when present."""
    start, stride, dtype, ncomp, count = _layout(doc, index)
    values = np.asarray(values, dtype=dtype).reshape(count, ncomp)
    out = bytearray(blob)
    view = np.ndarray((count, ncomp), dtype=dtype, buffer=out, offset=start,
                      strides=(stride, dtype.itemsize))
    view[...] = values
    acc = doc["accessors"][index]
    if "min" in acc:
        acc["min"] = [float(v) for v in values.astype(np.float64).min(axis=0)]
        acc["max"] = [float(v) for v in values.astype(np.float64).max(axis=0)]
    return bytes(out)


# --------------------------------------------------------------------------- editing anchored assets

_ANCHOR = "GSVERSE_gaussian_splatting_mesh_anchor"


def anchored_primitive(doc: dict) -> dict:
    """The (single) anchored splat primitive of ``doc``."""
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            khr = prim.get("extensions", {}).get("KHR_gaussian_splatting", {})
            if _ANCHOR in khr.get("extensions", {}):
                return prim
    raise KeyError("no anchored primitive")


def anchor_extension(doc: dict) -> dict:
    """The anchor extension object of the (single) anchored splat primitive of ``doc``."""
    return anchored_primitive(doc)["extensions"]["KHR_gaussian_splatting"]["extensions"][_ANCHOR]


def anchor_primitive(doc: dict) -> dict:
    """The anchor triangle primitive the anchored splat primitive of ``doc`` refers to."""
    e = anchor_extension(doc)
    return doc["meshes"][e["mesh"]]["primitives"][e.get("primitive", 0)]


def append_accessor(doc: dict, blob: bytes, values: np.ndarray, ctype: int, gtype: str,
                    normalized: bool = False) -> tuple[int, bytes]:
    """Append ``values`` as a new accessor in its own buffer view at the end of ``blob``;
    returns (accessor index, new blob)."""
    data = np.ascontiguousarray(values, dtype=COMPONENT_DTYPES[ctype]).tobytes()
    blob = blob + b"\0" * (-len(blob) % 4)
    doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)})
    blob += data
    blob += b"\0" * (-len(blob) % 4)
    doc["buffers"][0]["byteLength"] = len(blob)
    acc = {"bufferView": len(doc["bufferViews"]) - 1, "componentType": ctype,
           "count": int(len(values)), "type": gtype}
    if normalized:
        acc["normalized"] = True
    doc["accessors"].append(acc)
    return len(doc["accessors"]) - 1, blob
