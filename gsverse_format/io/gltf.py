"""glTF 2.0 (``.gltf``) and GLB (``.glb``) splat assets.

The rest pose of every splat primitive is plain ``KHR_gaussian_splatting``; the anchoring of
anchored primitives is the ``GSVERSE_gaussian_splatting_mesh_anchor`` extension nested in the
``KHR_gaussian_splatting`` extension object (``spec/README.md``).

Layout written (one glTF mesh per splat primitive, then one per anchor mesh):

* splat mesh: one ``POINTS`` primitive with ``POSITION`` (FLOAT VEC3, min/max),
  ``KHR_gaussian_splatting:ROTATION`` (FLOAT VEC4, unit quaternion x, y, z, w),
  ``:SCALE`` (FLOAT VEC3, linear), ``:OPACITY`` (FLOAT SCALAR, linear [0, 1]),
  ``:SH_DEGREE_l_COEF_n`` (FLOAT VEC3, model coefficient ``k = l² + n``) and a ``COLOR_0``
  fallback (UNSIGNED_BYTE normalized VEC4, linear RGB + opacity); instantiated by one node;
* anchor mesh: one ``TRIANGLES`` primitive (FLOAT ``POSITION`` + indices), instantiated by no
  node; several anchored primitives share it when they share the :class:`TriangleMesh` object;
* anchor accessors: referenced only from the extension JSON; their buffer views have no target.

All data live in one buffer: the GLB ``BIN`` chunk, or a base64 ``data:`` URI for ``.gltf``.

Reading accepts any ``KHR_gaussian_splatting`` ``POINTS`` primitive, dequantizes normalized
integer accessors as glTF 2.0 prescribes, honours ``byteStride`` and accessor ``byteOffset``
and bounds-checks every access before it happens. Every problem with the input is a
:class:`~gsverse_format.errors.FormatError` naming the file. Buffers come from the GLB
``BIN`` chunk, base64 ``data:`` URIs, or files inside the asset's folder; nothing is fetched
from the network.
"""
from __future__ import annotations

import base64
import binascii
import json
import math
import os
import re
import struct
import urllib.parse
import warnings
from typing import Any, Iterable

import numpy as np
import pygltflib

from .. import EXTENSION_NAME, __version__
from ..atomic import atomic_write
from ..errors import FormatError, GsverseError, UsageError
from ..model import (Anchoring, GamesAnchors, LocalAnchors, SplatAsset, SplatCloud,
                     SplatPrimitive, TriangleMesh)

__all__ = ["write_gltf", "read_gltf", "asset_to_gltf", "gltf_to_bytes", "KHR", "ANCHOR",
           "DEFAULT_MAX_BYTES"]

KHR = "KHR_gaussian_splatting"
ANCHOR = EXTENSION_NAME
ROTATION = f"{KHR}:ROTATION"
SCALE = f"{KHR}:SCALE"
OPACITY = f"{KHR}:OPACITY"
_SH_RE = re.compile(rf"^{KHR}:SH_DEGREE_(\d+)_COEF_(\d+)$")
SH_C0 = 0.28209479177387814

#: Default cap on the bytes one asset may occupy (file plus external/embedded buffers).
DEFAULT_MAX_BYTES = 2 ** 33

BYTE, UNSIGNED_BYTE, SHORT, UNSIGNED_SHORT, UNSIGNED_INT, FLOAT = 5120, 5121, 5122, 5123, 5125, 5126
_DTYPES = {BYTE: np.dtype("<i1"), UNSIGNED_BYTE: np.dtype("<u1"), SHORT: np.dtype("<i2"),
           UNSIGNED_SHORT: np.dtype("<u2"), UNSIGNED_INT: np.dtype("<u4"), FLOAT: np.dtype("<f4")}
_CTYPE_NAMES = {BYTE: "BYTE", UNSIGNED_BYTE: "UNSIGNED_BYTE", SHORT: "SHORT",
                UNSIGNED_SHORT: "UNSIGNED_SHORT", UNSIGNED_INT: "UNSIGNED_INT", FLOAT: "FLOAT"}
_NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963

_GLB_MAGIC = b"glTF"
_CHUNK_JSON = 0x4E4F534A
_CHUNK_BIN = 0x004E4942

#: Component-type choices for ``quantize=``: property -> {option: (componentType, scale)}.
_QUANTIZE = {
    "barycentrics": {"float": None, "unsigned_short": (UNSIGNED_SHORT, 65535.0),
                     "unsigned_byte": (UNSIGNED_BYTE, 255.0)},
    "localRotation": {"float": None, "short": (SHORT, 32767.0), "byte": (BYTE, 127.0)},
}

#: Required extensions that change how splat data are stored: such files cannot be read.
_UNREADABLE_REQUIRED = ("KHR_draco_mesh_compression", "EXT_meshopt_compression",
                        "KHR_meshopt_compression")

# ----------------------------------------------------------------------------------------
# Writing
# ----------------------------------------------------------------------------------------


def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB decoding of values in [0, 1]."""
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _linear_to_srgb(c: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB encoding of values in [0, 1]."""
    c = np.clip(c, 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1 / 2.4) - 0.055)


def _unit_quaternions(q: np.ndarray) -> np.ndarray:
    """Rows of ``q`` (x, y, z, w) as unit quaternions (float32).

    Rows already unit to float32 precision (|‖q‖ − 1| ≤ 1e-6) are kept bit for bit; others are
    divided by their norm; zero rows become the identity (0, 0, 0, 1).
    """
    q = np.asarray(q, dtype=np.float32)
    norm = np.linalg.norm(q.astype(np.float64), axis=1)
    fix = ~(np.abs(norm - 1.0) <= 1e-6)
    if not fix.any():
        return q
    out = q.copy()
    zero = fix & ~(norm > 0.0)
    scale = np.where(norm[fix] > 0.0, norm[fix], 1.0)
    out[fix] = (q[fix].astype(np.float64) / scale[:, None]).astype(np.float32)
    out[zero] = (0.0, 0.0, 0.0, 1.0)
    return out


def _fallback_color(cloud: SplatCloud) -> np.ndarray:
    """``COLOR_0`` fallback, (N, 4) uint8: linear RGB of the SH DC term and opacity as alpha."""
    rgb = np.clip(0.5 + SH_C0 * cloud.sh[:, 0, :].astype(np.float64), 0.0, 1.0)
    if cloud.color_space == "srgb_rec709_display":
        rgb = _srgb_to_linear(rgb)
    alpha = np.clip(cloud.opacities.astype(np.float64), 0.0, 1.0)[:, None]
    return np.round(np.concatenate([rgb, alpha], axis=1) * 255.0).astype(np.uint8)


class _Builder:
    """Accumulates one binary buffer, one bufferView per accessor, 4-byte aligned."""

    def __init__(self) -> None:
        self.blob = bytearray()
        self.views: list[pygltflib.BufferView] = []
        self.accessors: list[pygltflib.Accessor] = []

    def add(self, array: np.ndarray, ctype: int, gtype: str, *, normalized: bool = False,
            target: int | None = None, minmax: bool = False) -> int:
        data = np.ascontiguousarray(array, dtype=_DTYPES[ctype])
        count = int(data.shape[0])
        self.blob += b"\0" * (-len(self.blob) % 4)
        offset = len(self.blob)
        self.blob += data.tobytes()
        self.views.append(pygltflib.BufferView(buffer=0, byteOffset=offset,
                                               byteLength=int(data.nbytes), target=target))
        flat = data.reshape(count, -1)
        accessor = pygltflib.Accessor(
            bufferView=len(self.views) - 1, byteOffset=0, componentType=ctype, count=count,
            type=gtype, normalized=True if normalized else None,
            min=[float(v) for v in flat.min(axis=0)] if minmax else None,
            max=[float(v) for v in flat.max(axis=0)] if minmax else None)
        self.accessors.append(accessor)
        return len(self.accessors) - 1


def _check_quantize(quantize: dict | None) -> dict[str, tuple[int, float] | None]:
    chosen: dict[str, tuple[int, float] | None] = {}
    for key, value in (quantize or {}).items():
        if key not in _QUANTIZE:
            raise UsageError(f"cannot quantize {key!r}; choose from {', '.join(_QUANTIZE)}")
        if value not in _QUANTIZE[key]:
            raise UsageError(f"quantize[{key!r}] must be one of {', '.join(_QUANTIZE[key])}, "
                             f"got {value!r}")
        chosen[key] = _QUANTIZE[key][value]
    return chosen


def _require_finite(name: str, *arrays: np.ndarray) -> None:
    for a in arrays:
        if not np.all(np.isfinite(a)):
            raise UsageError(f"{name} has non-finite values (NaN or infinity)")


def _check_primitive(i: int, prim: SplatPrimitive) -> None:
    label = f"primitive {i}" + (f" ({prim.name!r})" if prim.name else "")
    c = prim.splats
    if len(c) == 0:
        raise UsageError(f"{label} has no splats (glTF accessors need at least one element)")
    _require_finite(f"{label} splats", c.means, c.rotations, c.scales, c.opacities, c.sh)
    if (c.scales < 0).any():
        raise UsageError(f"{label} has negative scales (KHR_gaussian_splatting scales are "
                         f"linear and non-negative)")
    if ((c.opacities < 0) | (c.opacities > 1)).any():
        raise UsageError(f"{label} has opacities outside [0, 1] (KHR_gaussian_splatting "
                         f"opacities are linear, after the sigmoid)")
    if prim.anchoring is None:
        return
    mesh, anchors = prim.anchoring.mesh, prim.anchoring.anchors
    if len(anchors) != len(c):
        raise UsageError(f"{label} has {len(anchors)} anchors for {len(c)} splats")
    if mesh.face_count == 0:
        raise UsageError(f"{label} is anchored to a mesh with no triangles")
    _require_finite(f"{label} anchor mesh", mesh.vertices)
    if mesh.faces.size and int(mesh.faces.max()) >= len(mesh.vertices):
        raise UsageError(f"{label} anchor mesh has face indices out of range")
    if int(anchors.face_index.max()) >= mesh.face_count:
        raise UsageError(f"{label} has anchor face index {int(anchors.face_index.max())} out "
                         f"of range for a mesh with {mesh.face_count} faces")
    if isinstance(anchors, LocalAnchors):
        _require_finite(f"{label} anchors", anchors.barycentrics, anchors.normal_offset,
                        anchors.local_rotation, anchors.local_scale)
    elif isinstance(anchors, GamesAnchors):
        _require_finite(f"{label} anchors", anchors.barycentrics, anchors.rho)
    else:
        raise UsageError(f"{label} has anchors of unknown type {type(anchors).__name__}")


def _write_anchors(b: _Builder, prim: SplatPrimitive, mesh_index: int, scale_accessor: int,
                   quant: dict[str, tuple[int, float] | None]) -> dict[str, Any]:
    anchors = prim.anchoring.anchors
    faces = prim.anchoring.mesh.face_count
    ftype = UNSIGNED_BYTE if faces <= 256 else UNSIGNED_SHORT if faces <= 65536 else UNSIGNED_INT
    obj: dict[str, Any] = {"mesh": mesh_index, "primitive": 0, "profile": anchors.profile}
    if isinstance(anchors, LocalAnchors):
        obj["deformation"] = anchors.deformation
    obj["faceIndex"] = b.add(anchors.face_index, ftype, "SCALAR")

    bary = anchors.barycentrics
    q = quant.get("barycentrics")
    if q is not None and bool(np.all((bary >= 0.0) & (bary <= 1.0))):
        ctype, top = q
        codes = np.round(bary.astype(np.float64) * top)
        obj["barycentrics"] = b.add(codes, ctype, "VEC2", normalized=True)
    else:
        obj["barycentrics"] = b.add(bary, FLOAT, "VEC2")

    if isinstance(anchors, LocalAnchors):
        obj["normalOffset"] = b.add(anchors.normal_offset, FLOAT, "SCALAR")
        rot = _unit_quaternions(anchors.local_rotation)
        q = quant.get("localRotation")
        if q is not None:
            ctype, top = q
            codes = np.clip(np.round(rot.astype(np.float64) * top), -top, top)
            obj["localRotation"] = b.add(codes, ctype, "VEC4", normalized=True)
        else:
            obj["localRotation"] = b.add(rot, FLOAT, "VEC4")
        if np.array_equal(anchors.local_scale, prim.splats.scales):
            obj["localScale"] = scale_accessor
        else:
            obj["localScale"] = b.add(anchors.local_scale, FLOAT, "VEC3")
    else:
        obj["rho"] = b.add(anchors.rho, FLOAT, "SCALAR")
    return obj


def asset_to_gltf(asset: SplatAsset, *, quantize: dict | None = None) -> pygltflib.GLTF2:
    """The glTF document for ``asset``; its binary buffer is set as the binary blob.

    ``quantize`` optionally stores anchor accessors as normalized integers:
    ``{"barycentrics": "unsigned_short" | "unsigned_byte",
    "localRotation": "short" | "byte"}``. Barycentrics stay FLOAT for a primitive whose
    barycentrics are not all in [0, 1]. Raises :class:`UsageError` for data glTF cannot hold.
    """
    quant = _check_quantize(quantize)
    prims = list(asset.primitives)
    for i, prim in enumerate(prims):
        _check_primitive(i, prim)

    # Anchor meshes are appended after the splat meshes, one per distinct TriangleMesh object.
    anchor_mesh_index: dict[int, int] = {}
    anchor_meshes: list[TriangleMesh] = []
    for prim in prims:
        if prim.anchoring is not None and id(prim.anchoring.mesh) not in anchor_mesh_index:
            anchor_mesh_index[id(prim.anchoring.mesh)] = len(prims) + len(anchor_meshes)
            anchor_meshes.append(prim.anchoring.mesh)

    b = _Builder()
    meshes: list[pygltflib.Mesh | None] = [None] * (len(prims) + len(anchor_meshes))
    nodes: list[pygltflib.Node] = []
    for i, prim in enumerate(prims):
        c = prim.splats
        attrs: dict[str, int] = {"POSITION": b.add(c.means, FLOAT, "VEC3", target=ARRAY_BUFFER,
                                                   minmax=True)}
        attrs[ROTATION] = b.add(_unit_quaternions(c.rotations), FLOAT, "VEC4", target=ARRAY_BUFFER)
        attrs[SCALE] = b.add(c.scales, FLOAT, "VEC3", target=ARRAY_BUFFER)
        attrs[OPACITY] = b.add(c.opacities, FLOAT, "SCALAR", target=ARRAY_BUFFER)
        for k in range(c.sh.shape[1]):
            degree = math.isqrt(k)
            attrs[f"{KHR}:SH_DEGREE_{degree}_COEF_{k - degree * degree}"] = b.add(
                c.sh[:, k, :], FLOAT, "VEC3", target=ARRAY_BUFFER)
        attrs["COLOR_0"] = b.add(_fallback_color(c), UNSIGNED_BYTE, "VEC4", normalized=True,
                                 target=ARRAY_BUFFER)
        khr: dict[str, Any] = {"kernel": "ellipse", "colorSpace": c.color_space,
                               "projection": "perspective", "sortingMethod": "cameraDistance"}
        if prim.anchoring is not None:
            mesh = prim.anchoring.mesh
            m = anchor_mesh_index[id(mesh)]
            if meshes[m] is None:
                pos = b.add(mesh.vertices, FLOAT, "VEC3", target=ARRAY_BUFFER, minmax=True)
                itype = UNSIGNED_SHORT if len(mesh.vertices) < 65535 else UNSIGNED_INT
                idx = b.add(mesh.faces.reshape(-1), itype, "SCALAR", target=ELEMENT_ARRAY_BUFFER)
                meshes[m] = pygltflib.Mesh(primitives=[pygltflib.Primitive(
                    attributes=pygltflib.Attributes(POSITION=pos), indices=idx,
                    mode=pygltflib.TRIANGLES)], weights=None,
                    name=f"{prim.name} anchor mesh" if prim.name else "anchor mesh")
            khr["extensions"] = {ANCHOR: _write_anchors(b, prim, m, attrs[SCALE], quant)}
        primitive = pygltflib.Primitive(attributes=pygltflib.Attributes(**attrs),
                                        mode=pygltflib.POINTS, extensions={KHR: khr})
        meshes[i] = pygltflib.Mesh(primitives=[primitive], name=prim.name, weights=None)
        nodes.append(pygltflib.Node(mesh=i, name=prim.name, children=None))

    used = ([KHR] if prims else []) + ([ANCHOR] if anchor_meshes else [])
    b.blob += b"\0" * (-len(b.blob) % 4)
    gltf = pygltflib.GLTF2(
        asset=pygltflib.Asset(version="2.0", generator=f"gsverse-format {__version__}"),
        extensionsUsed=used, scene=0, scenes=[pygltflib.Scene(nodes=list(range(len(nodes))))],
        nodes=nodes, meshes=meshes, accessors=b.accessors, bufferViews=b.views,
        buffers=[pygltflib.Buffer(byteLength=len(b.blob))] if b.blob else [])
    gltf.set_binary_blob(bytes(b.blob))
    return gltf


def _gltf_json(gltf: pygltflib.GLTF2, *, data_uri: bool) -> bytes:
    doc = json.loads(gltf.to_json())
    if data_uri and doc.get("buffers"):
        payload = base64.b64encode(gltf.binary_blob() or b"").decode("ascii")
        doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + payload
    return json.dumps(doc, separators=(",", ":"), allow_nan=False).encode("utf-8")


def gltf_to_bytes(gltf: pygltflib.GLTF2, *, binary: bool = True) -> bytes:
    """Serialize a document from :func:`asset_to_gltf`: GLB bytes, or ``.gltf`` JSON bytes
    with the buffer embedded as a base64 ``data:`` URI."""
    if not binary:
        return _gltf_json(gltf, data_uri=True)
    text = _gltf_json(gltf, data_uri=False)
    text += b" " * (-len(text) % 4)
    out = struct.pack("<II", len(text), _CHUNK_JSON) + text
    blob = gltf.binary_blob() or b""
    if blob:
        blob = blob + b"\0" * (-len(blob) % 4)
        out += struct.pack("<II", len(blob), _CHUNK_BIN) + blob
    return struct.pack("<4sII", _GLB_MAGIC, 2, 12 + len(out)) + out


def write_gltf(asset: SplatAsset, path: str | os.PathLike, *,
               protect: Iterable[str | os.PathLike] = (), quantize: dict | None = None) -> None:
    """Write ``asset`` to ``path``: ``.glb`` (binary) or ``.gltf`` (JSON, embedded buffer).

    The output is written atomically; ``protect`` lists input files it must not overwrite.
    See :func:`asset_to_gltf` for ``quantize``.
    """
    ext = os.path.splitext(os.fspath(path))[1].lower()
    if ext not in (".glb", ".gltf"):
        raise UsageError(f"glTF output must end in .glb or .gltf, not {ext or '(nothing)'}", path)
    try:
        data = gltf_to_bytes(asset_to_gltf(asset, quantize=quantize), binary=ext == ".glb")
    except GsverseError as err:
        raise err.with_path(path) from None
    with atomic_write(path, "wb", protect=tuple(protect)) as handle:
        handle.write(data)


# ----------------------------------------------------------------------------------------
# Reading
# ----------------------------------------------------------------------------------------


def _is_int(value: Any) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def _int(value: Any, what: str, *, minimum: int = 0, default: int | None = None) -> int:
    if value is None and default is not None:
        return default
    if not _is_int(value) or value < minimum:
        raise FormatError(f"{what} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _index(value: Any, size: int, what: str) -> int:
    if not _is_int(value):
        raise FormatError(f"{what} must be an index, got {value!r}")
    if not 0 <= value < size:
        raise FormatError(f"{what} {value} out of range (there are {size})")
    return int(value)


def _parse_glb(data: memoryview) -> tuple[bytes, memoryview | None]:
    """(JSON chunk, BIN chunk or None) of a GLB container, every length checked."""
    if len(data) < 12:
        raise FormatError(f"truncated GLB: {len(data)} bytes, shorter than the 12-byte header")
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    if magic != _GLB_MAGIC:
        raise FormatError(f"not a GLB file: bad magic {bytes(magic)!r} (expected b'glTF')")
    if version != 2:
        raise FormatError(f"unsupported GLB container version {version} (only 2)")
    if length > len(data):
        raise FormatError(f"truncated GLB: header says {length} bytes, file has {len(data)}")
    if length < len(data):
        raise FormatError(f"GLB length field {length} does not match the file size {len(data)}")
    chunks: list[tuple[int, memoryview]] = []
    pos = 12
    while pos < length:
        if pos + 8 > length:
            raise FormatError(f"truncated GLB: chunk header at byte {pos} runs past the end")
        size, kind = struct.unpack_from("<II", data, pos)
        pos += 8
        if size > length - pos:
            raise FormatError(f"GLB chunk {len(chunks)} is {size} bytes long but only "
                              f"{length - pos} bytes follow it")
        chunks.append((kind, data[pos:pos + size]))
        pos += size
    if not chunks or chunks[0][0] != _CHUNK_JSON:
        raise FormatError("GLB does not start with a JSON chunk")
    binary = chunks[1][1] if len(chunks) > 1 and chunks[1][0] == _CHUNK_BIN else None
    return bytes(chunks[0][1]), binary


_INT_FIELDS = {
    "accessors": ("bufferView", "byteOffset", "componentType", "count"),
    "bufferViews": ("buffer", "byteOffset", "byteLength", "byteStride", "target"),
    "buffers": ("byteLength",),
    "nodes": ("mesh",),
}


def _check_types(doc: dict) -> None:
    """Types of the JSON members the reader relies on (the dataclass decoder coerces silently,
    e.g. 2.5 -> 2, so they are checked on the raw JSON)."""
    def obj_list(value: Any, where: str) -> list:
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise FormatError(f"{where} must be an array of objects")
        return value

    def ints(item: dict, keys: Iterable[str], where: str) -> None:
        for key in keys:
            if key in item and not _is_int(item[key]):
                raise FormatError(f"{where}.{key} must be an integer, got {item[key]!r}")

    for top, keys in _INT_FIELDS.items():
        for i, item in enumerate(obj_list(doc.get(top, []), top)):
            ints(item, keys, f"{top}[{i}]")
    for i, acc in enumerate(doc.get("accessors", [])):
        if "normalized" in acc and not isinstance(acc["normalized"], bool):
            raise FormatError(f"accessors[{i}].normalized must be a boolean")
        if not isinstance(acc.get("type"), str):
            raise FormatError(f"accessors[{i}].type must be a string")
    for i, buf in enumerate(doc.get("buffers", [])):
        if "uri" in buf and not isinstance(buf["uri"], str):
            raise FormatError(f"buffers[{i}].uri must be a string")
    for m, mesh in enumerate(obj_list(doc.get("meshes", []), "meshes")):
        for p, prim in enumerate(obj_list(mesh.get("primitives", []), f"meshes[{m}].primitives")):
            where = f"meshes[{m}].primitives[{p}]"
            ints(prim, ("indices", "mode"), where)
            attrs = prim.get("attributes", {})
            if not isinstance(attrs, dict):
                raise FormatError(f"{where}.attributes must be an object")
            ints(attrs, list(attrs), f"{where}.attributes")
            if not isinstance(prim.get("extensions", {}), dict):
                raise FormatError(f"{where}.extensions must be an object")


def _parse_json(raw: bytes) -> tuple[dict, pygltflib.GLTF2]:
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise FormatError(f"glTF JSON is not valid UTF-8 (byte {err.start})") from None
    text = text.lstrip("\ufeff")
    try:
        doc = json.loads(text)
    except (ValueError, RecursionError) as err:
        raise FormatError(f"glTF JSON is not valid JSON ({err})") from None
    if not isinstance(doc, dict):
        raise FormatError("glTF JSON root is not an object")
    _check_types(doc)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            gltf = pygltflib.GLTF2.from_json(text, infer_missing=True)
    except Exception as err:  # the dataclass decoder raises assorted types on bad JSON
        raise FormatError(f"glTF JSON does not follow the glTF schema "
                          f"({type(err).__name__}: {err})") from None
    return doc, gltf


_SCHEME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9+.\-]*:")


class _Reader:
    """Bounds-checked access to the buffers and accessors of one glTF document."""

    def __init__(self, path: str, gltf: pygltflib.GLTF2, glb_bin: memoryview | None,
                 budget: int) -> None:
        self.path = path
        self.folder = os.path.dirname(os.path.abspath(path))
        self.gltf = gltf
        self.glb_bin = glb_bin
        self.budget = budget
        self.accessors = self._list("accessors")
        self.views = self._list("bufferViews")
        self.buffers_json = self._list("buffers")
        self.meshes = self._list("meshes")
        self._buffers: dict[int, memoryview] = {}
        self._raw: dict[int, tuple[np.ndarray, int, bool]] = {}

    def _list(self, name: str) -> list:
        value = getattr(self.gltf, name, None)
        if value is None:
            return []
        if not isinstance(value, list):
            raise FormatError(f"{name} must be an array")
        return value

    # -- buffers -----------------------------------------------------------------------
    def _spend(self, size: int, what: str) -> None:
        if size > self.budget:
            raise FormatError(f"{what} would take the asset past the size limit")
        self.budget -= size

    def _data_uri(self, uri: str, what: str) -> bytes:
        comma = uri.find(",")
        if comma < 0:
            raise FormatError(f"{what}: malformed data: URI (no comma)")
        if not uri[5:comma].lower().endswith(";base64"):
            raise FormatError(f"{what}: only base64 data: URIs are supported")
        payload = uri[comma + 1:]
        self._spend(len(payload) * 3 // 4, what)
        try:
            return base64.b64decode(payload, validate=True)
        except (binascii.Error, ValueError):
            raise FormatError(f"{what}: data: URI is not valid base64") from None

    def _file_uri(self, uri: str, what: str) -> bytes:
        shown = uri if len(uri) <= 80 else uri[:77] + "..."
        if _SCHEME_RE.match(uri):
            scheme = uri.split(":", 1)[0]
            raise FormatError(f"{what}: URI {shown!r} uses scheme '{scheme}:'; only data: URIs "
                              f"and relative file paths are allowed (nothing is fetched)")
        rel = urllib.parse.unquote(uri)
        if "\0" in rel or not rel:
            raise FormatError(f"{what}: invalid URI {shown!r}")
        if rel.startswith(("/", "\\")) or os.path.isabs(rel) or uri.startswith("//"):
            raise FormatError(f"{what}: absolute path {shown!r} not allowed; buffer files must be "
                              f"relative to the asset's folder")
        if ".." in re.split(r"[\\/]", rel):
            raise FormatError(f"{what}: URI {shown!r} escapes the asset's folder ('..')")
        folder = os.path.realpath(self.folder)
        target = os.path.realpath(os.path.join(folder, rel))
        if os.path.commonpath([folder, target]) != folder:
            raise FormatError(f"{what}: URI {shown!r} resolves outside the asset's folder")
        if not os.path.isfile(target):
            raise FormatError(f"{what}: buffer file {shown!r} not found next to the asset")
        size = os.path.getsize(target)
        self._spend(size, what)
        with open(target, "rb") as handle:
            return handle.read(size)

    def buffer(self, i: int) -> memoryview:
        if i in self._buffers:
            return self._buffers[i]
        buf = self.buffers_json[i]
        what = f"buffers[{i}]"
        length = _int(buf.byteLength, f"{what}.byteLength")
        uri = buf.uri
        if uri is None:
            if i != 0 or self.glb_bin is None:
                raise FormatError(f"{what} has no uri and the file has no GLB BIN chunk "
                                  f"(missing BIN chunk)")
            data = self.glb_bin
        elif not isinstance(uri, str):
            raise FormatError(f"{what}.uri must be a string")
        elif uri[:5].lower() == "data:":
            data = memoryview(self._data_uri(uri, what))
        else:
            data = memoryview(self._file_uri(uri, what))
        if len(data) < length:
            raise FormatError(f"{what} holds {len(data)} bytes but its byteLength is {length}")
        self._buffers[i] = data[:length]
        return self._buffers[i]

    # -- accessors ---------------------------------------------------------------------
    def raw(self, i: Any, what: str, gtypes: tuple[str, ...]) -> tuple[np.ndarray, int, bool]:
        """(elements (count, ncomp) in the stored dtype, componentType, normalized)."""
        i = _index(i, len(self.accessors), f"{what}: accessor")
        acc = self.accessors[i]
        where = f"{what} (accessor {i})"
        gtype = acc.type
        if gtype not in gtypes:
            raise FormatError(f"{where} has type {gtype!r}, expected {' or '.join(gtypes)}")
        if i in self._raw:
            return self._raw[i]
        ctype = acc.componentType
        if not _is_int(ctype) or int(ctype) not in _DTYPES:
            raise FormatError(f"{where} has unknown componentType {ctype!r}")
        ctype = int(ctype)
        normalized = acc.normalized
        if normalized is None:
            normalized = False
        if not isinstance(normalized, bool):
            raise FormatError(f"{where}.normalized must be a boolean")
        if normalized and ctype in (FLOAT, UNSIGNED_INT):
            raise FormatError(f"{where}: {_CTYPE_NAMES[ctype]} accessors cannot be normalized")
        count = _int(acc.count, f"{where}.count")
        if acc.sparse is not None:
            raise FormatError(f"{where}: sparse accessors not supported")
        if acc.bufferView is None:
            raise FormatError(f"{where} has no bufferView (compressed or placeholder data is "
                              f"not supported)")
        v = _index(acc.bufferView, len(self.views), f"{where}.bufferView")
        view = self.views[v]
        dtype = _DTYPES[ctype]
        ncomp = _NCOMP[gtype]
        elem = dtype.itemsize * ncomp
        acc_offset = _int(acc.byteOffset, f"{where}.byteOffset", default=0)
        if acc_offset % dtype.itemsize:
            raise FormatError(f"{where}.byteOffset {acc_offset} is not a multiple of the "
                              f"component size {dtype.itemsize}")
        view_offset = _int(view.byteOffset, f"bufferViews[{v}].byteOffset", default=0)
        view_length = _int(view.byteLength, f"bufferViews[{v}].byteLength", minimum=1)
        stride = elem if view.byteStride is None else _int(view.byteStride,
                                                           f"bufferViews[{v}].byteStride", minimum=1)
        if stride < elem:
            raise FormatError(f"bufferViews[{v}].byteStride {stride} is smaller than the "
                              f"{elem}-byte elements of {where}")
        if stride % dtype.itemsize:
            raise FormatError(f"bufferViews[{v}].byteStride {stride} is not a multiple of the "
                              f"component size of {where}")
        b = _index(view.buffer, len(self.buffers_json), f"bufferViews[{v}].buffer")
        buf = self.buffer(b)
        if view_offset + view_length > len(buf):
            raise FormatError(f"bufferViews[{v}] (bytes {view_offset}..{view_offset + view_length})"
                              f" runs past the end of buffers[{b}] ({len(buf)} bytes)")
        if count:
            need = acc_offset + stride * (count - 1) + elem
            if need > view_length:
                raise FormatError(f"{where} out of bounds: needs {need} bytes of bufferViews[{v}]"
                                  f" which has {view_length}")
            arr = np.ndarray((count, ncomp), dtype=dtype, buffer=buf,
                             offset=view_offset + acc_offset, strides=(stride, dtype.itemsize))
            arr = np.array(arr, copy=True)
        else:
            arr = np.zeros((0, ncomp), dtype)
        self._raw[i] = (arr, ctype, normalized)
        return self._raw[i]

    def floats(self, i: Any, what: str, gtypes: tuple[str, ...],
               allowed: Iterable[tuple[int, bool | None]] | None = None,
               renormalize: bool = False) -> np.ndarray:
        """Accessor ``i`` as float32 (count, ncomp), dequantized per glTF 2.0 §3.11.

        ``allowed`` lists (componentType, normalized) pairs (normalized ``None``: either);
        default: any type but UNSIGNED_INT. ``renormalize`` rescales integer-quantized rows to
        unit length (quaternions).
        """
        arr, ctype, normalized = self.raw(i, what, gtypes)
        if allowed is None:
            ok = ctype != UNSIGNED_INT
        else:
            ok = any(c == ctype and (n is None or n == normalized) for c, n in allowed)
        if not ok:
            kind = _CTYPE_NAMES[ctype] + (" normalized" if normalized else "")
            raise FormatError(f"{what} (accessor {i}) has unsupported component type {kind}")
        if ctype == FLOAT:
            return arr
        values = arr.astype(np.float64)
        if normalized:
            if ctype == UNSIGNED_BYTE:
                values /= 255.0
            elif ctype == UNSIGNED_SHORT:
                values /= 65535.0
            elif ctype == BYTE:
                values = np.maximum(values / 127.0, -1.0)
            elif ctype == SHORT:
                values = np.maximum(values / 32767.0, -1.0)
        if renormalize:
            norm = np.linalg.norm(values, axis=1, keepdims=True)
            values = np.where(norm > 0, values / np.where(norm > 0, norm, 1.0), values)
        return values.astype(np.float32)

    def integers(self, i: Any, what: str) -> np.ndarray:
        """SCALAR unsigned-integer (not normalized) accessor as uint32 (count,)."""
        arr, ctype, normalized = self.raw(i, what, ("SCALAR",))
        if ctype not in (UNSIGNED_BYTE, UNSIGNED_SHORT, UNSIGNED_INT) or normalized:
            kind = _CTYPE_NAMES[ctype] + (" normalized" if normalized else "")
            raise FormatError(f"{what} (accessor {i}) must be UNSIGNED_BYTE, UNSIGNED_SHORT or "
                              f"UNSIGNED_INT (not normalized), got {kind}")
        return arr[:, 0].astype(np.uint32)


def _attributes(prim: Any, where: str) -> dict[str, Any]:
    attrs = prim.attributes
    if attrs is None:
        return {}
    if isinstance(attrs, dict):
        items = attrs
    elif isinstance(attrs, pygltflib.Attributes):
        items = vars(attrs)
    else:
        raise FormatError(f"{where}.attributes must be an object")
    return {k: v for k, v in items.items() if v is not None}


def _sh_degree(attrs: dict[str, Any], where: str) -> int:
    """Highest complete SH degree (−1 if there is no SH at all)."""
    present: set[tuple[int, int]] = set()
    for name in attrs:
        m = _SH_RE.match(name)
        if m:
            degree, coef = int(m.group(1)), int(m.group(2))
            if degree > 3:
                raise FormatError(f"{where}: SH degree {degree} is not supported (0..3)")
            if coef > 2 * degree:
                raise FormatError(f"{where}: attribute {name} does not exist in degree {degree}")
            present.add((degree, coef))
    degree = -1
    for level in range(4):
        have = [(level, n) in present for n in range(2 * level + 1)]
        if all(have):
            if degree != level - 1:
                raise FormatError(f"{where}: SH degree {level} is present but degree "
                                  f"{level - 1} is missing")
            degree = level
        elif any(have):
            missing = [n for n in range(2 * level + 1) if not have[n]]
            raise FormatError(f"{where}: SH degree {level} is partially defined (missing "
                              f"COEF_{', COEF_'.join(map(str, missing))})")
    return degree


class _AssetReader:
    def __init__(self, reader: _Reader) -> None:
        self.r = reader
        self.meshes_cache: dict[tuple[int, int], TriangleMesh] = {}

    def anchor_mesh(self, m: int, p: int) -> TriangleMesh:
        key = (m, p)
        if key in self.meshes_cache:
            return self.meshes_cache[key]
        where = f"anchor mesh meshes[{m}].primitives[{p}]"
        prim = self.r.meshes[m].primitives[p]
        mode = pygltflib.TRIANGLES if prim.mode is None else prim.mode
        if mode != pygltflib.TRIANGLES:
            raise FormatError(f"{where} has mode {mode!r}; anchor primitives must be "
                              f"TRIANGLES (4)")
        attrs = _attributes(prim, where)
        if "POSITION" not in attrs:
            raise FormatError(f"{where} has no POSITION attribute")
        vertices = self.r.floats(attrs["POSITION"], f"{where} POSITION", ("VEC3",),
                                 allowed=[(FLOAT, False)])
        if prim.indices is not None:
            idx = self.r.integers(prim.indices, f"{where} indices")
            if len(idx) % 3:
                raise FormatError(f"{where} has {len(idx)} indices, not a multiple of 3")
            if idx.size and int(idx.max()) >= len(vertices):
                raise FormatError(f"{where}: index {int(idx.max())} out of range for "
                                  f"{len(vertices)} vertices")
            faces = idx.reshape(-1, 3)
        else:
            if len(vertices) % 3:
                raise FormatError(f"{where} is not indexed and has {len(vertices)} vertices, "
                                  f"not a multiple of 3")
            faces = np.arange(len(vertices), dtype=np.uint32).reshape(-1, 3)
        mesh = TriangleMesh(vertices, faces)
        self.meshes_cache[key] = mesh
        return mesh

    def anchoring(self, obj: Any, count: int, scales_accessor: Any, where: str) -> Anchoring:
        where = f"{where} {ANCHOR}"
        if not isinstance(obj, dict):
            raise FormatError(f"{where} must be an object")
        m = _index(obj.get("mesh"), len(self.r.meshes), f"{where}.mesh")
        prims = self.r.meshes[m].primitives or []
        p = _index(obj.get("primitive", 0), len(prims), f"{where}.primitive")
        mesh = self.anchor_mesh(m, p)
        profile = obj.get("profile")
        if profile not in ("local", "games"):
            raise FormatError(f"{where}.profile must be 'local' or 'games', got {profile!r}")
        needed = ["faceIndex", "barycentrics"] + (
            ["normalOffset", "localRotation", "localScale"] if profile == "local" else ["rho"])
        missing = [k for k in needed if k not in obj]
        if missing:
            raise FormatError(f"{where} ({profile} profile) lacks {', '.join(missing)}")
        r = self.r

        def checked(name: str, values: np.ndarray) -> np.ndarray:
            if len(values) != count:
                raise FormatError(f"{where}.{name} has {len(values)} elements but the primitive "
                                  f"has {count} splats (accessor count mismatch)")
            return values

        face = checked("faceIndex", r.integers(obj["faceIndex"], f"{where}.faceIndex"))
        if face.size and int(face.max()) >= mesh.face_count:
            raise FormatError(f"{where}.faceIndex value {int(face.max())} out of range for an "
                              f"anchor mesh with {mesh.face_count} triangles")
        bary = checked("barycentrics", r.floats(
            obj["barycentrics"], f"{where}.barycentrics", ("VEC2",),
            allowed=[(FLOAT, False), (UNSIGNED_BYTE, True), (UNSIGNED_SHORT, True)]))
        if profile == "games":
            if "deformation" in obj:
                raise FormatError(f"{where}: 'deformation' must not be present with the games "
                                  f"profile")
            rho = checked("rho", r.floats(obj["rho"], f"{where}.rho", ("SCALAR",),
                                          allowed=[(FLOAT, False)]))
            anchors = GamesAnchors(face, bary, rho[:, 0])
        else:
            deformation = obj.get("deformation", "affine")
            if deformation not in ("affine", "rigid"):
                raise FormatError(f"{where}.deformation must be 'affine' or 'rigid', got "
                                  f"{deformation!r}")
            offset = checked("normalOffset", r.floats(
                obj["normalOffset"], f"{where}.normalOffset", ("SCALAR",),
                allowed=[(FLOAT, False)]))
            rot_i = obj["localRotation"]
            arr, ctype, _ = r.raw(rot_i, f"{where}.localRotation", ("VEC4",))
            rotation = checked("localRotation", r.floats(
                rot_i, f"{where}.localRotation", ("VEC4",),
                allowed=[(FLOAT, False), (BYTE, True), (SHORT, True)],
                renormalize=ctype != FLOAT))
            scale = checked("localScale", r.floats(
                obj["localScale"], f"{where}.localScale", ("VEC3",),
                allowed=[(FLOAT, False), (UNSIGNED_BYTE, None), (UNSIGNED_SHORT, None)]))
            anchors = LocalAnchors(face, bary, offset[:, 0], rotation, scale, deformation)
        return Anchoring(mesh, anchors)

    def splat_primitive(self, prim: Any, khr: Any, name: str | None, where: str) -> SplatPrimitive:
        r = self.r
        if not isinstance(khr, dict):
            raise FormatError(f"{where}: {KHR} extension must be an object")
        color_space = khr.get("colorSpace")
        if not isinstance(color_space, str):
            raise FormatError(f"{where}: {KHR}.colorSpace is missing or not a string")
        attrs = _attributes(prim, where)
        missing = [a for a in ("POSITION", ROTATION, SCALE, OPACITY) if a not in attrs]
        if missing:
            raise FormatError(f"{where}: required {KHR} attribute(s) missing: "
                              f"{', '.join(missing)}")
        means = r.floats(attrs["POSITION"], f"{where} POSITION", ("VEC3",))
        count = len(means)

        def attr(name: str, gtypes: tuple[str, ...], **kw) -> np.ndarray:
            values = r.floats(attrs[name], f"{where} {name}", gtypes, **kw)
            if len(values) != count:
                raise FormatError(f"{where}: {name} has {len(values)} elements, POSITION has "
                                  f"{count} (accessor count mismatch)")
            return values

        _, rot_type, _ = r.raw(attrs[ROTATION], f"{where} {ROTATION}", ("VEC4",))
        rotations = attr(ROTATION, ("VEC4",), renormalize=rot_type != FLOAT)
        scales = attr(SCALE, ("VEC3",))
        opacities = attr(OPACITY, ("SCALAR",))[:, 0]
        degree = _sh_degree(attrs, where)
        if degree >= 0:
            sh = np.empty((count, (degree + 1) ** 2, 3), np.float32)
            for k in range(sh.shape[1]):
                level = math.isqrt(k)
                sh[:, k] = attr(f"{KHR}:SH_DEGREE_{level}_COEF_{k - level * level}", ("VEC3",))
        elif "COLOR_0" in attrs:
            # No SH at all (not valid KHR_gaussian_splatting): rebuild the DC term from the
            # fallback colour so that the splats keep their colour.
            color = attr("COLOR_0", ("VEC3", "VEC4"), allowed=[
                (FLOAT, False), (UNSIGNED_BYTE, True), (UNSIGNED_SHORT, True)])
            rgb = np.clip(color[:, :3].astype(np.float64), 0.0, 1.0)
            if color_space == "srgb_rec709_display":
                rgb = _linear_to_srgb(rgb)
            sh = ((rgb - 0.5) / SH_C0)[:, None, :]
        else:
            raise FormatError(f"{where}: required {KHR} attribute missing: "
                              f"{KHR}:SH_DEGREE_0_COEF_0")
        cloud = SplatCloud(means, rotations, scales, opacities, sh, color_space)
        anchoring = None
        nested = khr.get("extensions")
        if nested is not None and not isinstance(nested, dict):
            raise FormatError(f"{where}: {KHR}.extensions must be an object")
        if nested and ANCHOR in nested:
            anchoring = self.anchoring(nested[ANCHOR], count, attrs[SCALE], where)
        return SplatPrimitive(cloud, anchoring, name)


def _node_names(gltf: pygltflib.GLTF2) -> dict[int, str]:
    names: dict[int, str] = {}
    for node in gltf.nodes or []:
        mesh = getattr(node, "mesh", None)
        name = getattr(node, "name", None)
        if _is_int(mesh) and isinstance(name, str) and int(mesh) not in names:
            names[int(mesh)] = name
    return names


def _check_header(gltf: pygltflib.GLTF2) -> None:
    version = getattr(gltf.asset, "version", None)
    if not isinstance(version, str) or not version.startswith("2."):
        raise FormatError(f"unsupported glTF asset.version {version!r} (expected '2.0')")
    required = gltf.extensionsRequired or []
    if not isinstance(required, list):
        raise FormatError("extensionsRequired must be an array")
    for name in required:
        if name in _UNREADABLE_REQUIRED or (isinstance(name, str) and name.startswith(KHR + "_")):
            raise FormatError(f"the asset requires extension {name}, which is not supported")


def _load_document(path: str, max_bytes: int) -> tuple[pygltflib.GLTF2, _Reader]:
    """Parse the container (GLB or JSON) and header; return the document and a bounded reader."""
    size = os.path.getsize(path)
    if size > max_bytes:
        raise FormatError(f"file is {size} bytes, larger than the limit of {max_bytes} bytes")
    with open(path, "rb") as handle:
        data = memoryview(handle.read(max_bytes + 1))
    if len(data) > max_bytes:
        raise FormatError(f"file is larger than the limit of {max_bytes} bytes")
    glb_bin = None
    if bytes(data[:4]) == _GLB_MAGIC or os.path.splitext(path)[1].lower() == ".glb":
        raw_json, glb_bin = _parse_glb(data)
    else:
        raw_json = bytes(data)
    _, gltf = _parse_json(raw_json)
    _check_header(gltf)
    return gltf, _Reader(path, gltf, glb_bin, max_bytes - len(data))


def _read(path: str, max_bytes: int) -> SplatAsset:
    gltf, reader = _load_document(path, max_bytes)
    assets = _AssetReader(reader)
    node_names = _node_names(gltf)
    primitives: list[SplatPrimitive] = []
    for m, mesh in enumerate(reader.meshes):
        prims = mesh.primitives or []
        if not isinstance(prims, list):
            raise FormatError(f"meshes[{m}].primitives must be an array")
        name = mesh.name if isinstance(mesh.name, str) else node_names.get(m)
        for p, prim in enumerate(prims):
            extensions = prim.extensions or {}
            if not isinstance(extensions, dict):
                raise FormatError(f"meshes[{m}].primitives[{p}].extensions must be an object")
            if prim.mode != pygltflib.POINTS or KHR not in extensions:
                continue
            where = f"meshes[{m}].primitives[{p}]"
            primitives.append(assets.splat_primitive(prim, extensions[KHR], name, where))
    generator = getattr(gltf.asset, "generator", None)
    return SplatAsset(primitives, generator if isinstance(generator, str) else None)


def read_gltf(path: str | os.PathLike, *, max_bytes: int = DEFAULT_MAX_BYTES) -> SplatAsset:
    """Read every ``KHR_gaussian_splatting`` primitive of a ``.glb``/``.gltf`` file.

    Primitives carrying ``GSVERSE_gaussian_splatting_mesh_anchor`` get their
    :class:`Anchoring`; primitives referencing the same anchor primitive share one
    :class:`TriangleMesh`. ``max_bytes`` caps the file plus all buffers it loads.
    Raises :class:`FormatError` (naming ``path``) for any problem with the input.
    """
    spath = os.fspath(path)
    try:
        return _read(spath, max_bytes)
    except GsverseError as err:
        raise FormatError(err.cause, spath) from None
    except OSError as err:
        raise FormatError(f"cannot read: {err.strerror or err}", spath) from None
    except MemoryError:
        raise FormatError("not enough memory to read the asset", spath) from None
    except Exception as err:  # last line of defence: malformed input never escapes as a crash
        raise FormatError(f"malformed glTF ({type(err).__name__}: {err})", spath) from err


def _node_matrix(node: Any) -> np.ndarray:
    """Local 4x4 matrix of a glTF node (``matrix`` is column-major; else T·R·S)."""
    if node.matrix is not None:
        m = np.asarray(node.matrix, dtype=np.float64)
        if m.shape != (16,):
            raise FormatError("node.matrix must have 16 numbers")
        return m.reshape(4, 4).T
    from .. import quaternion as quat

    out = np.eye(4)
    s = np.asarray(node.scale if node.scale is not None else [1, 1, 1], dtype=np.float64)
    r = np.asarray(node.rotation if node.rotation is not None else [0, 0, 0, 1], dtype=np.float64)
    t = np.asarray(node.translation if node.translation is not None else [0, 0, 0], dtype=np.float64)
    if s.shape != (3,) or r.shape != (4,) or t.shape != (3,):
        raise FormatError("node translation/rotation/scale have the wrong number of values")
    out[:3, :3] = quat.to_matrix(r) * s[None, :]
    out[:3, 3] = t
    return out


def _mesh_instances(gltf: pygltflib.GLTF2) -> list[tuple[int, np.ndarray]]:
    """(mesh index, global matrix) for every node of the default scene that has a mesh.

    Without scenes, every mesh once with the identity. Node cycles are a FormatError.
    """
    nodes = gltf.nodes or []
    scenes = gltf.scenes or []
    if not scenes:
        return [(m, np.eye(4)) for m in range(len(gltf.meshes or []))]
    scene = scenes[gltf.scene if _is_int(gltf.scene) and 0 <= gltf.scene < len(scenes) else 0]
    out: list[tuple[int, np.ndarray]] = []
    stack = [(_index(n, len(nodes), "scene node"), np.eye(4), 0) for n in (scene.nodes or [])]
    while stack:
        i, parent, depth = stack.pop()
        if depth > len(nodes):
            raise FormatError("the node hierarchy has a cycle")
        node = nodes[i]
        world = parent @ _node_matrix(node)
        if node.mesh is not None:
            out.append((_index(node.mesh, len(gltf.meshes or []), f"nodes[{i}].mesh"), world))
        for child in node.children or []:
            stack.append((_index(child, len(nodes), f"nodes[{i}].children"), world, depth + 1))
    return out


def read_gltf_triangles(path: str | os.PathLike, *,
                        max_bytes: int = DEFAULT_MAX_BYTES) -> TriangleMesh:
    """All TRIANGLES primitives of the default scene as one mesh, node transforms applied.

    For reading an anchor mesh supplied as ``.glb``/``.gltf`` (e.g. a TRELLIS export). Face
    order: meshes in scene traversal order, primitives and triangles in file order. Skins and
    morph targets are not applied (the bind pose is used). Same hardening as :func:`read_gltf`.
    """
    spath = os.fspath(path)
    try:
        gltf, reader = _load_document(spath, max_bytes)
        assets = _AssetReader(reader)
        vertices, faces, offset = [], [], 0
        for m, world in _mesh_instances(gltf):
            for p, prim in enumerate(assets.r.meshes[m].primitives or []):
                mode = pygltflib.TRIANGLES if prim.mode is None else prim.mode
                if mode != pygltflib.TRIANGLES:
                    continue
                tri = assets.anchor_mesh(m, p)
                v = tri.vertices.astype(np.float64) @ world[:3, :3].T + world[:3, 3]
                if np.linalg.det(world[:3, :3]) < 0:  # a mirroring node flips the winding
                    f = tri.faces[:, ::-1]
                else:
                    f = tri.faces
                vertices.append(v)
                faces.append(f.astype(np.int64) + offset)
                offset += len(v)
        if not faces:
            raise FormatError("the file has no triangle primitives in its scene")
        return TriangleMesh(np.concatenate(vertices), np.concatenate(faces))
    except GsverseError as err:
        raise FormatError(err.cause, spath) from None
    except OSError as err:
        raise FormatError(f"cannot read: {err.strerror or err}", spath) from None
    except Exception as err:  # malformed input never escapes as a crash
        raise FormatError(f"malformed glTF ({type(err).__name__}: {err})", spath) from err
