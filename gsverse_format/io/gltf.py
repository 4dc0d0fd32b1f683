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
from dataclasses import dataclass
from typing import Any, Iterable

import numpy as np
import pygltflib

from .. import EXTENSION_NAME, __version__
from ..atomic import atomic_write
from ..errors import FormatError, GsverseError, UsageError
from ..quaternion import unit_quaternions
from ..model import (Anchoring, check_primitive, GamesAnchors, LocalAnchors, SplatAsset, SplatCloud,
                     SplatPrimitive, TriangleMesh)

__all__ = ["write_gltf", "read_gltf", "asset_to_gltf", "gltf_to_bytes", "KHR", "ANCHOR",
           "DEFAULT_MAX_BYTES", "GltfFormatError", "AccessorLayout", "Document", "parse_glb",
           "parse_json", "load_document", "header_problems", "pointer_token"]

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
#: Matrix accessor types (rows = columns); only their bounds are checked, splats never use them.
_MAT_ROWS = {"MAT2": 2, "MAT3": 3, "MAT4": 4}
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963

_GLB_MAGIC = b"glTF"
_CHUNK_JSON = 0x4E4F534A
_CHUNK_BIN = 0x004E4942

#: Accessor formats of ``KHR_gaussian_splatting`` attributes: semantic -> (accessor types,
#: allowed (componentType, normalized) pairs; normalized ``None`` = either). ``SH`` stands for
#: every ``SH_DEGREE_l_COEF_n``. ``POSITION`` is FLOAT unless ``KHR_mesh_quantization`` is used.
KHR_ATTRIBUTE_FORMATS: dict[str, tuple[tuple[str, ...], tuple[tuple[int, bool | None], ...]]] = {
    "POSITION": (("VEC3",), ((FLOAT, False),)),
    f"{KHR}:ROTATION": (("VEC4",), ((FLOAT, False), (BYTE, True), (SHORT, True))),
    f"{KHR}:SCALE": (("VEC3",), ((FLOAT, False), (UNSIGNED_BYTE, None), (UNSIGNED_SHORT, None))),
    f"{KHR}:OPACITY": (("SCALAR",), ((FLOAT, False), (UNSIGNED_BYTE, True),
                                     (UNSIGNED_SHORT, True))),
    "SH": (("VEC3",), ((FLOAT, False),)),
}
#: ``POSITION`` formats added by ``KHR_mesh_quantization``.
QUANTIZED_POSITION_FORMATS = ((BYTE, None), (UNSIGNED_BYTE, None), (SHORT, None),
                              (UNSIGNED_SHORT, None))

#: Accessor formats of the anchor extension's properties (spec §Accessor component types).
ANCHOR_ACCESSOR_FORMATS: dict[str, tuple[tuple[str, ...], tuple[tuple[int, bool | None], ...]]] = {
    "faceIndex": (("SCALAR",), ((UNSIGNED_BYTE, False), (UNSIGNED_SHORT, False),
                                (UNSIGNED_INT, False))),
    "barycentrics": (("VEC2",), ((FLOAT, False), (UNSIGNED_BYTE, True), (UNSIGNED_SHORT, True))),
    "normalOffset": (("SCALAR",), ((FLOAT, False),)),
    "localRotation": (("VEC4",), ((FLOAT, False), (BYTE, True), (SHORT, True))),
    "localScale": (("VEC3",), ((FLOAT, False), (UNSIGNED_BYTE, None), (UNSIGNED_SHORT, None))),
    "rho": (("SCALAR",), ((FLOAT, False),)),
}

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


@dataclass
class _EncodedAnchors:
    """Anchor data as the writer stores them: normalized-integer codes for the quantized
    properties (None: stored as FLOAT), and ``anchors`` as a reader dequantizes them."""

    anchors: LocalAnchors | GamesAnchors
    barycentrics: tuple[np.ndarray, int] | None = None
    local_rotation: tuple[np.ndarray, int] | None = None


def _encode_anchors(anchors: LocalAnchors | GamesAnchors,
                    quant: dict[str, tuple[int, float] | None]) -> _EncodedAnchors:
    """Quantize the anchors as ``quant`` asks; dequantize the codes as glTF 2.0 §3.11 says
    (``c / 255``, ``max(c / 127, -1)``, ...; quaternions renormalized, as readers do)."""
    out = _EncodedAnchors(anchors)
    bary = anchors.barycentrics
    q = quant.get("barycentrics")
    if q is not None and bool(np.all((bary >= 0.0) & (bary <= 1.0))):
        ctype, top = q
        codes = np.round(bary.astype(np.float64) * top)
        out.barycentrics = (codes, ctype)
        bary = (codes.astype(np.float32) / np.float32(top)).astype(np.float32)
    if isinstance(anchors, LocalAnchors):
        rot = unit_quaternions(anchors.local_rotation)
        q = quant.get("localRotation")
        if q is not None:
            ctype, top = q
            codes = np.clip(np.round(rot.astype(np.float64) * top), -top, top)
            out.local_rotation = (codes, ctype)
            rot = unit_quaternions(np.maximum(codes / top, -1.0).astype(np.float32))
        out.anchors = LocalAnchors(anchors.face_index, bary, anchors.normal_offset, rot,
                                   anchors.local_scale, anchors.deformation)
    else:
        out.anchors = GamesAnchors(anchors.face_index, bary, anchors.rho)
    return out


def _rest_pose_of(prim: SplatPrimitive, encoded: _EncodedAnchors) -> SplatCloud:
    """The splats with the rest pose remapped from the anchors as stored (spec §Rest-pose
    consistency), for quantized anchors; otherwise the splats unchanged."""
    if encoded.barycentrics is None and encoded.local_rotation is None:
        return prim.splats
    from ..remap import remap

    rest = remap(Anchoring(prim.anchoring.mesh, encoded.anchors))
    c = prim.splats
    return SplatCloud(rest.means.astype(np.float32), rest.rotations.astype(np.float32),
                      rest.scales.astype(np.float32), c.opacities, c.sh, c.color_space,
                      dict(c.extra))


def _write_anchors(b: _Builder, prim: SplatPrimitive, encoded: _EncodedAnchors,
                   splats: SplatCloud, mesh_index: int, scale_accessor: int) -> dict[str, Any]:
    anchors = encoded.anchors
    faces = prim.anchoring.mesh.face_count
    ftype = UNSIGNED_BYTE if faces <= 256 else UNSIGNED_SHORT if faces <= 65536 else UNSIGNED_INT
    obj: dict[str, Any] = {"mesh": mesh_index, "primitive": 0, "profile": anchors.profile}
    if isinstance(anchors, LocalAnchors):
        obj["deformation"] = anchors.deformation
    obj["faceIndex"] = b.add(anchors.face_index, ftype, "SCALAR")
    if encoded.barycentrics is not None:
        codes, ctype = encoded.barycentrics
        obj["barycentrics"] = b.add(codes, ctype, "VEC2", normalized=True)
    else:
        obj["barycentrics"] = b.add(anchors.barycentrics, FLOAT, "VEC2")
    if isinstance(anchors, LocalAnchors):
        obj["normalOffset"] = b.add(anchors.normal_offset, FLOAT, "SCALAR")
        if encoded.local_rotation is not None:
            codes, ctype = encoded.local_rotation
            obj["localRotation"] = b.add(codes, ctype, "VEC4", normalized=True)
        else:
            obj["localRotation"] = b.add(anchors.local_rotation, FLOAT, "VEC4")
        if np.array_equal(anchors.local_scale, splats.scales):
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
    barycentrics are not all in [0, 1]. Quantizing moves the anchored splats: the stored rest
    pose is then the remap of the anchors as stored (dequantized), so that the asset stays
    self-consistent (spec §Rest-pose consistency); the move is at most about half a
    quantization step of each property (for 8-bit barycentrics, 1/510 of a triangle edge).
    Raises :class:`UsageError` for data glTF cannot hold.
    """
    quant = _check_quantize(quantize)
    prims = list(asset.primitives)
    for i, prim in enumerate(prims):
        check_primitive(i, prim)

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
        encoded = None
        c = prim.splats
        if prim.anchoring is not None:
            encoded = _encode_anchors(prim.anchoring.anchors, quant)
            c = _rest_pose_of(prim, encoded)
        attrs: dict[str, int] = {"POSITION": b.add(c.means, FLOAT, "VEC3", target=ARRAY_BUFFER,
                                                   minmax=True)}
        attrs[ROTATION] = b.add(unit_quaternions(c.rotations), FLOAT, "VEC4", target=ARRAY_BUFFER)
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
            khr["extensions"] = {ANCHOR: _write_anchors(b, prim, encoded, c, m, attrs[SCALE])}
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


class GltfFormatError(FormatError):
    """A :class:`FormatError` of the container and bounds checks that also carries the stable
    issue ``code`` of ``spec/validation.md`` and where the problem is: a JSON ``pointer``
    (RFC 6901) or a byte ``offset`` into a GLB file. ``gsverse-validate`` reports these; the
    reader only shows the one-line cause."""

    def __init__(self, cause: str, path: str | os.PathLike | None = None, *,
                 code: str | None = None, pointer: str | None = None,
                 offset: int | None = None) -> None:
        super().__init__(cause, path)
        self.code = code
        self.pointer = pointer
        self.offset = offset

    def with_path(self, path: str | os.PathLike) -> "GltfFormatError":
        if self.path is None:
            return GltfFormatError(self.cause, path, code=self.code, pointer=self.pointer,
                                   offset=self.offset)
        return self


def _fail(code: str, cause: str, pointer: str | None = None,
          offset: int | None = None) -> GltfFormatError:
    return GltfFormatError(cause, code=code, pointer=pointer, offset=offset)


def _is_int(value: Any) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def _int(value: Any, what: str, *, minimum: int = 0, default: int | None = None,
         pointer: str | None = None, code: str = "GLTF_SCHEMA_VIOLATION") -> int:
    if value is None and default is not None:
        return default
    if not _is_int(value) or value < minimum:
        raise _fail(code, f"{what} must be an integer >= {minimum}, got {value!r}", pointer)
    return int(value)


def _index(value: Any, size: int, what: str, pointer: str | None = None) -> int:
    if not _is_int(value):
        raise _fail("UNRESOLVED_REFERENCE", f"{what} must be an index, got {value!r}", pointer)
    if not 0 <= value < size:
        raise _fail("UNRESOLVED_REFERENCE", f"{what} {value} out of range (there are {size})",
                    pointer)
    return int(value)


def parse_glb(data: memoryview | bytes,
              issues: list[tuple[str, str, int]] | None = None) -> tuple[bytes, memoryview | None]:
    """(JSON chunk, BIN chunk or None) of a GLB container, every length checked.

    Problems that make the container unreadable raise :class:`GltfFormatError`. Problems the
    reader can step over (a chunk length that is not a multiple of 4, an unknown chunk type, a
    JSON or BIN chunk out of place) are appended to ``issues`` as ``(code, message, byte
    offset)`` when a list is given, and ignored otherwise.
    """
    data = memoryview(data)
    if len(data) < 12:
        raise _fail("GLB_TRUNCATED",
                    f"truncated GLB: {len(data)} bytes, shorter than the 12-byte header", offset=0)
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    if magic != _GLB_MAGIC:
        raise _fail("GLB_BAD_MAGIC",
                    f"not a GLB file: bad magic {bytes(magic)!r} (expected b'glTF')", offset=0)
    if version != 2:
        raise _fail("GLB_UNSUPPORTED_VERSION",
                    f"unsupported GLB container version {version} (only 2)", offset=4)
    if length > len(data):
        raise _fail("GLB_TRUNCATED",
                    f"truncated GLB: header says {length} bytes, file has {len(data)}", offset=8)
    if length < len(data):
        raise _fail("GLB_LENGTH_MISMATCH",
                    f"GLB length field {length} does not match the file size {len(data)}",
                    offset=8)
    chunks: list[tuple[int, memoryview]] = []
    pos = 12
    while pos < length:
        if pos + 8 > length:
            raise _fail("GLB_TRUNCATED",
                        f"truncated GLB: chunk header at byte {pos} runs past the end", offset=pos)
        size, kind = struct.unpack_from("<II", data, pos)
        if size > length - pos - 8:
            raise _fail("GLB_CHUNK_TOO_LONG", f"GLB chunk {len(chunks)} is {size} bytes long but "
                        f"only {length - pos - 8} bytes follow it", offset=pos)
        if issues is not None:
            if size % 4:
                issues.append(("GLB_CHUNK_UNALIGNED", f"GLB chunk {len(chunks)} is {size} bytes "
                               f"long, not a multiple of 4 (chunks must be padded)", pos))
            if kind not in (_CHUNK_JSON, _CHUNK_BIN):
                issues.append(("GLB_UNKNOWN_CHUNK", f"GLB chunk {len(chunks)} has unknown type "
                               f"0x{kind:08X}; it is ignored", pos + 4))
            elif len(chunks) > 0 and (kind == _CHUNK_JSON or len(chunks) > 1):
                name = "JSON" if kind == _CHUNK_JSON else "BIN"
                issues.append(("GLB_UNEXPECTED_CHUNK", f"GLB chunk {len(chunks)} is a {name} "
                               f"chunk; only the first chunk may be JSON and only the second "
                               f"BIN; it is ignored", pos + 4))
        pos += 8
        chunks.append((kind, data[pos:pos + size]))
        pos += size
    if not chunks or chunks[0][0] != _CHUNK_JSON:
        raise _fail("GLB_FIRST_CHUNK_NOT_JSON", "GLB does not start with a JSON chunk", offset=12)
    binary = chunks[1][1] if len(chunks) > 1 and chunks[1][0] == _CHUNK_BIN else None
    return bytes(chunks[0][1]), binary


_INT_FIELDS = {
    "accessors": ("bufferView", "byteOffset", "componentType", "count"),
    "bufferViews": ("buffer", "byteOffset", "byteLength", "byteStride", "target"),
    "buffers": ("byteLength",),
    "nodes": ("mesh",),
}


def pointer_token(key: Any) -> str:
    """One RFC 6901 reference token (``~`` -> ``~0``, ``/`` -> ``~1``)."""
    return str(key).replace("~", "~0").replace("/", "~1")


def _check_types(doc: dict) -> None:
    """Types of the JSON members the reader relies on (the dataclass decoder coerces silently,
    e.g. 2.5 -> 2, so they are checked on the raw JSON)."""
    def bad(cause: str, pointer: str) -> GltfFormatError:
        return _fail("GLTF_SCHEMA_VIOLATION", cause, pointer)

    def obj_list(value: Any, where: str, pointer: str) -> list:
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise bad(f"{where} must be an array of objects", pointer)
        return value

    def ints(item: dict, keys: Iterable[str], where: str, pointer: str) -> None:
        for key in keys:
            if key in item and not _is_int(item[key]):
                raise bad(f"{where}.{key} must be an integer, got {item[key]!r}",
                          f"{pointer}/{pointer_token(key)}")

    for top, keys in _INT_FIELDS.items():
        for i, item in enumerate(obj_list(doc.get(top, []), top, f"/{top}")):
            ints(item, keys, f"{top}[{i}]", f"/{top}/{i}")
    for i, acc in enumerate(doc.get("accessors", [])):
        if "normalized" in acc and not isinstance(acc["normalized"], bool):
            raise bad(f"accessors[{i}].normalized must be a boolean", f"/accessors/{i}/normalized")
        if not isinstance(acc.get("type"), str):
            raise bad(f"accessors[{i}].type must be a string", f"/accessors/{i}/type")
    for i, buf in enumerate(doc.get("buffers", [])):
        if "uri" in buf and not isinstance(buf["uri"], str):
            raise bad(f"buffers[{i}].uri must be a string", f"/buffers/{i}/uri")
    for m, mesh in enumerate(obj_list(doc.get("meshes", []), "meshes", "/meshes")):
        for p, prim in enumerate(obj_list(mesh.get("primitives", []), f"meshes[{m}].primitives",
                                          f"/meshes/{m}/primitives")):
            where = f"meshes[{m}].primitives[{p}]"
            pointer = f"/meshes/{m}/primitives/{p}"
            ints(prim, ("indices", "mode"), where, pointer)
            attrs = prim.get("attributes", {})
            if not isinstance(attrs, dict):
                raise bad(f"{where}.attributes must be an object", f"{pointer}/attributes")
            ints(attrs, list(attrs), f"{where}.attributes", f"{pointer}/attributes")
            if not isinstance(prim.get("extensions", {}), dict):
                raise bad(f"{where}.extensions must be an object", f"{pointer}/extensions")


def parse_json(raw: bytes) -> tuple[dict, pygltflib.GLTF2]:
    """(raw JSON document, pygltflib document) of glTF JSON bytes; raises
    :class:`GltfFormatError` for bytes that are not UTF-8, not JSON, not an object, or whose
    members have the wrong types."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise _fail("JSON_NOT_UTF8", f"glTF JSON is not valid UTF-8 (byte {err.start})") from None
    text = text.lstrip("\ufeff")
    try:
        doc = json.loads(text)
    except (ValueError, RecursionError) as err:
        raise _fail("JSON_INVALID", f"glTF JSON is not valid JSON ({err})") from None
    if not isinstance(doc, dict):
        raise _fail("JSON_INVALID", "glTF JSON root is not an object", "")
    _check_types(doc)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            gltf = pygltflib.GLTF2.from_json(text, infer_missing=True)
    except Exception as err:  # the dataclass decoder raises assorted types on bad JSON
        raise _fail("GLTF_SCHEMA_VIOLATION", f"glTF JSON does not follow the glTF schema "
                    f"({type(err).__name__}: {err})") from None
    return doc, gltf


_SCHEME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9+.\-]*:")


@dataclass
class AccessorLayout:
    """Where the elements of one accessor lie, every bound already checked.

    Element ``j`` starts at byte ``start + j * stride`` of ``buffer`` (index ``buffer``);
    it holds ``ncomp`` components of ``dtype``. ``view_offset + accessor_offset == start``.
    """

    accessor: int
    view: int
    buffer: int
    dtype: np.dtype
    ncomp: int
    count: int
    start: int
    stride: int
    component_type: int
    normalized: bool
    gtype: str


class _Reader:
    """Bounds-checked access to the buffers and accessors of one glTF document.

    ``max_data_uri`` optionally caps the decoded size of each ``data:`` URI (the overall
    ``budget`` always applies).
    """

    def __init__(self, path: str, gltf: pygltflib.GLTF2, glb_bin: memoryview | None,
                 budget: int, max_data_uri: int | None = None) -> None:
        self.path = path
        self.folder = os.path.dirname(os.path.abspath(path))
        self.gltf = gltf
        self.glb_bin = glb_bin
        self.budget = budget
        self.max_data_uri = max_data_uri
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
            raise _fail("GLTF_SCHEMA_VIOLATION", f"{name} must be an array", f"/{name}")
        return value

    # -- buffers -----------------------------------------------------------------------
    def _spend(self, size: int, what: str, pointer: str) -> None:
        if size > self.budget:
            raise _fail("SIZE_LIMIT_EXCEEDED", f"{what} would take the asset past the size limit",
                        pointer)
        self.budget -= size

    def _data_uri(self, uri: str, what: str, pointer: str) -> bytes:
        comma = uri.find(",")
        if comma < 0:
            raise _fail("URI_INVALID", f"{what}: malformed data: URI (no comma)", pointer)
        if not uri[5:comma].lower().endswith(";base64"):
            raise _fail("URI_INVALID", f"{what}: only base64 data: URIs are supported", pointer)
        payload = uri[comma + 1:]
        size = len(payload) * 3 // 4
        if self.max_data_uri is not None and size > self.max_data_uri:
            raise _fail("DATA_URI_TOO_LARGE", f"{what}: data: URI holds about {size} bytes, more "
                        f"than the limit of {self.max_data_uri} bytes per data: URI", pointer)
        self._spend(size, what, pointer)
        try:
            return base64.b64decode(payload, validate=True)
        except (binascii.Error, ValueError):
            raise _fail("URI_INVALID", f"{what}: data: URI is not valid base64", pointer) from None

    def _file_uri(self, uri: str, what: str, pointer: str) -> bytes:
        shown = uri if len(uri) <= 80 else uri[:77] + "..."
        if _SCHEME_RE.match(uri):
            scheme = uri.split(":", 1)[0]
            raise _fail("URI_SCHEME_REJECTED", f"{what}: URI {shown!r} uses scheme '{scheme}:'; "
                        f"only data: URIs and relative file paths are allowed (nothing is "
                        f"fetched)", pointer)
        rel = urllib.parse.unquote(uri)
        if "\0" in rel or not rel:
            raise _fail("URI_INVALID", f"{what}: invalid URI {shown!r}", pointer)
        if rel.startswith(("/", "\\")) or os.path.isabs(rel) or uri.startswith("//"):
            raise _fail("URI_ABSOLUTE_PATH", f"{what}: absolute path {shown!r} not allowed; buffer "
                        f"files must be relative to the asset's folder", pointer)
        if ".." in re.split(r"[\\/]", rel):
            raise _fail("URI_OUTSIDE_FOLDER",
                        f"{what}: URI {shown!r} escapes the asset's folder ('..')", pointer)
        folder = os.path.realpath(self.folder)
        target = os.path.realpath(os.path.join(folder, rel))
        if os.path.commonpath([folder, target]) != folder:
            raise _fail("URI_OUTSIDE_FOLDER",
                        f"{what}: URI {shown!r} resolves outside the asset's folder", pointer)
        if not os.path.isfile(target):
            raise _fail("URI_NOT_FOUND",
                        f"{what}: buffer file {shown!r} not found next to the asset", pointer)
        size = os.path.getsize(target)
        self._spend(size, what, pointer)
        with open(target, "rb") as handle:
            return handle.read(size)

    def buffer(self, i: int) -> memoryview:
        """The bytes of buffer ``i`` (exactly ``byteLength`` of them)."""
        if i in self._buffers:
            return self._buffers[i]
        buf = self.buffers_json[i]
        what = f"buffers[{i}]"
        pointer = f"/buffers/{i}"
        length = _int(buf.byteLength, f"{what}.byteLength", pointer=f"{pointer}/byteLength")
        uri = buf.uri
        if uri is None:
            if i != 0 or self.glb_bin is None:
                raise _fail("BUFFER_MISSING_DATA", f"{what} has no uri and the file has no GLB "
                            f"BIN chunk (missing BIN chunk)", pointer)
            data = self.glb_bin
        elif not isinstance(uri, str):
            raise _fail("GLTF_SCHEMA_VIOLATION", f"{what}.uri must be a string", f"{pointer}/uri")
        elif uri[:5].lower() == "data:":
            data = memoryview(self._data_uri(uri, what, f"{pointer}/uri"))
        else:
            data = memoryview(self._file_uri(uri, what, f"{pointer}/uri"))
        if len(data) < length:
            raise _fail("BUFFER_TOO_SHORT",
                        f"{what} holds {len(data)} bytes but its byteLength is {length}", pointer)
        self._buffers[i] = data[:length]
        return self._buffers[i]

    def view_bounds(self, v: int) -> tuple[int, int, int]:
        """(buffer index, byteOffset, byteLength) of bufferView ``v``, within its buffer."""
        view = self.views[v]
        pointer = f"/bufferViews/{v}"
        view_offset = _int(view.byteOffset, f"bufferViews[{v}].byteOffset", default=0,
                           pointer=f"{pointer}/byteOffset")
        view_length = _int(view.byteLength, f"bufferViews[{v}].byteLength", minimum=1,
                           pointer=f"{pointer}/byteLength")
        b = _index(view.buffer, len(self.buffers_json), f"bufferViews[{v}].buffer",
                   f"{pointer}/buffer")
        buf = self.buffer(b)
        if view_offset + view_length > len(buf):
            raise _fail("BUFFER_VIEW_OUT_OF_BOUNDS",
                        f"bufferViews[{v}] (bytes {view_offset}..{view_offset + view_length})"
                        f" runs past the end of buffers[{b}] ({len(buf)} bytes)", pointer)
        return b, view_offset, view_length

    # -- accessors ---------------------------------------------------------------------
    def layout(self, i: int, what: str | None = None) -> AccessorLayout:
        """Check accessor ``i`` against its bufferView and buffer; where its elements lie.

        Raises :class:`GltfFormatError` (with code and pointer) for invalid component types,
        sparse or bufferView-less accessors (not supported), misaligned offsets and strides,
        and every out-of-bounds case. Nothing is read or allocated.
        """
        acc = self.accessors[i]
        pointer = f"/accessors/{i}"
        where = f"{what} (accessor {i})" if what else f"accessors[{i}]"
        gtype = acc.type
        if gtype not in _NCOMP and gtype not in _MAT_ROWS:
            raise _fail("ACCESSOR_INVALID", f"{where} has unknown type {gtype!r}",
                        f"{pointer}/type")
        ctype = acc.componentType
        if not _is_int(ctype) or int(ctype) not in _DTYPES:
            raise _fail("ACCESSOR_INVALID", f"{where} has unknown componentType {ctype!r}",
                        f"{pointer}/componentType")
        ctype = int(ctype)
        normalized = acc.normalized
        if normalized is None:
            normalized = False
        if not isinstance(normalized, bool):
            raise _fail("GLTF_SCHEMA_VIOLATION", f"{where}.normalized must be a boolean",
                        f"{pointer}/normalized")
        if normalized and ctype in (FLOAT, UNSIGNED_INT):
            raise _fail("ACCESSOR_INVALID",
                        f"{where}: {_CTYPE_NAMES[ctype]} accessors cannot be normalized",
                        f"{pointer}/normalized")
        count = _int(acc.count, f"{where}.count", pointer=f"{pointer}/count",
                     code="ACCESSOR_INVALID")
        if acc.sparse is not None:
            raise _fail("ACCESSOR_UNSUPPORTED", f"{where}: sparse accessors not supported",
                        f"{pointer}/sparse")
        if acc.bufferView is None:
            raise _fail("ACCESSOR_UNSUPPORTED", f"{where} has no bufferView (compressed or "
                        f"placeholder data is not supported)", pointer)
        v = _index(acc.bufferView, len(self.views), f"{where}.bufferView", f"{pointer}/bufferView")
        view = self.views[v]
        dtype = _DTYPES[ctype]
        if gtype in _MAT_ROWS:  # every column starts 4-byte aligned (glTF 2.0 §3.6.2.4)
            rows = _MAT_ROWS[gtype]
            ncomp = rows * rows
            elem = rows * (-(-rows * dtype.itemsize // 4) * 4)
        else:
            ncomp = _NCOMP[gtype]
            elem = dtype.itemsize * ncomp
        acc_offset = _int(acc.byteOffset, f"{where}.byteOffset", default=0,
                          pointer=f"{pointer}/byteOffset")
        if acc_offset % dtype.itemsize:
            raise _fail("ACCESSOR_MISALIGNED", f"{where}.byteOffset {acc_offset} is not a multiple "
                        f"of the component size {dtype.itemsize}", f"{pointer}/byteOffset")
        b, view_offset, view_length = self.view_bounds(v)
        vpointer = f"/bufferViews/{v}/byteStride"
        stride = elem if view.byteStride is None else _int(
            view.byteStride, f"bufferViews[{v}].byteStride", minimum=1, pointer=vpointer,
            code="BUFFER_VIEW_STRIDE_INVALID")
        if stride < elem:
            raise _fail("BUFFER_VIEW_STRIDE_INVALID", f"bufferViews[{v}].byteStride {stride} is "
                        f"smaller than the {elem}-byte elements of {where}", vpointer)
        if stride % dtype.itemsize:
            raise _fail("BUFFER_VIEW_STRIDE_INVALID", f"bufferViews[{v}].byteStride {stride} is "
                        f"not a multiple of the component size of {where}", vpointer)
        if count:
            need = acc_offset + stride * (count - 1) + elem
            if need > view_length:
                raise _fail("ACCESSOR_OUT_OF_BOUNDS", f"{where} out of bounds: needs {need} bytes "
                            f"of bufferViews[{v}] which has {view_length}", pointer)
        return AccessorLayout(i, v, b, dtype, ncomp, count, view_offset + acc_offset, stride,
                              ctype, normalized, gtype)

    def raw(self, i: Any, what: str, gtypes: tuple[str, ...], *,
            copy: bool = True) -> tuple[np.ndarray, int, bool]:
        """(elements (count, ncomp) in the stored dtype, componentType, normalized).

        ``copy=False`` returns a read-only view into the buffer where the data are tightly
        packed (checks that only read the values avoid a copy).
        """
        i = _index(i, len(self.accessors), f"{what}: accessor")
        acc = self.accessors[i]
        where = f"{what} (accessor {i})"
        gtype = acc.type
        if gtype not in gtypes:
            raise FormatError(f"{where} has type {gtype!r}, expected {' or '.join(gtypes)}")
        if i in self._raw:
            return self._raw[i]
        lay = self.layout(i, what)
        if lay.count:
            arr = np.ndarray((lay.count, lay.ncomp), dtype=lay.dtype, buffer=self.buffer(lay.buffer),
                             offset=lay.start, strides=(lay.stride, lay.dtype.itemsize))
            if not copy and arr.flags.c_contiguous and arr.flags.aligned:
                return arr, lay.component_type, lay.normalized
            arr = np.array(arr, copy=True)
        else:
            arr = np.zeros((0, lay.ncomp), lay.dtype)
        self._raw[i] = (arr, lay.component_type, lay.normalized)
        return self._raw[i]

    def floats(self, i: Any, what: str, gtypes: tuple[str, ...],
               allowed: Iterable[tuple[int, bool | None]] | None = None,
               renormalize: bool = False, finite: bool = True, copy: bool = True) -> np.ndarray:
        """Accessor ``i`` as float32 (count, ncomp), dequantized per glTF 2.0 §3.11.

        ``allowed`` lists (componentType, normalized) pairs (normalized ``None``: either);
        default: any type but UNSIGNED_INT. ``renormalize`` rescales integer-quantized rows to
        unit length (quaternions). ``finite`` rejects FLOAT data holding NaN or infinity.
        ``copy=False`` may return FLOAT data as a read-only view into the buffer.
        """
        arr, ctype, normalized = self.raw(i, what, gtypes, copy=copy)
        if allowed is None:
            ok = ctype != UNSIGNED_INT
        else:
            ok = any(c == ctype and (n is None or n == normalized) for c, n in allowed)
        if not ok:
            kind = _CTYPE_NAMES[ctype] + (" normalized" if normalized else "")
            raise FormatError(f"{what} (accessor {i}) has unsupported component type {kind}")
        if ctype == FLOAT:
            if finite and not np.isfinite(arr).all():
                bad = int(np.count_nonzero(~np.isfinite(arr).all(axis=1)))
                raise _fail("NON_FINITE_VALUE", f"{what} (accessor {i}): {bad} of {len(arr)} "
                            f"elements hold NaN or infinity", f"/accessors/{i}")
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
        instances = [n for n, node in enumerate(self.r.gltf.nodes or []) if node.mesh == m]
        if len(instances) > 1:
            raise FormatError(f"{where}: the anchor mesh {m} is instantiated by {len(instances)} "
                              f"nodes ({', '.join(map(str, instances))}); at most one may "
                              f"instantiate it (which instance deforms the splats is ambiguous)")
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
            obj["barycentrics"], f"{where}.barycentrics", *ANCHOR_ACCESSOR_FORMATS["barycentrics"]))
        if profile == "games":
            if "deformation" in obj:
                raise FormatError(f"{where}: 'deformation' must not be present with the games "
                                  f"profile")
            rho = checked("rho", r.floats(obj["rho"], f"{where}.rho",
                                          *ANCHOR_ACCESSOR_FORMATS["rho"]))
            anchors = GamesAnchors(face, bary, rho[:, 0])
        else:
            deformation = obj.get("deformation", "affine")
            if deformation not in ("affine", "rigid"):
                raise FormatError(f"{where}.deformation must be 'affine' or 'rigid', got "
                                  f"{deformation!r}")
            offset = checked("normalOffset", r.floats(
                obj["normalOffset"], f"{where}.normalOffset",
                *ANCHOR_ACCESSOR_FORMATS["normalOffset"]))
            rot_i = obj["localRotation"]
            arr, ctype, _ = r.raw(rot_i, f"{where}.localRotation", ("VEC4",))
            rotation = checked("localRotation", r.floats(
                rot_i, f"{where}.localRotation", *ANCHOR_ACCESSOR_FORMATS["localRotation"],
                renormalize=ctype != FLOAT))
            scale = checked("localScale", r.floats(
                obj["localScale"], f"{where}.localScale", *ANCHOR_ACCESSOR_FORMATS["localScale"]))
            zero = np.flatnonzero(~np.any(rotation != 0, axis=1))
            if zero.size:
                raise FormatError(f"{where}.localRotation: {zero.size} zero quaternion(s) (splat "
                                  f"{int(zero[0])}); a rotation must have non-zero length")
            negative = np.flatnonzero(np.any(scale < 0, axis=1))
            if negative.size:
                raise FormatError(f"{where}.localScale: {negative.size} splat(s) with a negative "
                                  f"scale (splat {int(negative[0])}); scales are linear, >= 0")
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


def header_problems(doc: dict, *, strict: bool = True) -> list[GltfFormatError]:
    """Problems with ``asset.version`` and ``extensionsRequired`` of a raw glTF document.

    ``strict=False`` (the reader) accepts a missing ``asset``/``version`` as 2.0, as the
    document decoder does; ``strict=True`` (the validator) reports it.
    """
    problems: list[GltfFormatError] = []
    asset = doc.get("asset")
    version = asset.get("version") if isinstance(asset, dict) else None
    if not (version is None and not strict) and (
            not isinstance(version, str) or not version.startswith("2.")):
        problems.append(_fail("ASSET_VERSION_UNSUPPORTED", f"unsupported glTF asset.version "
                              f"{version!r} (expected '2.0')", "/asset/version"
                              if isinstance(asset, dict) else "/asset"))
    required = doc.get("extensionsRequired", [])
    if not isinstance(required, list):
        problems.append(_fail("GLTF_SCHEMA_VIOLATION", "extensionsRequired must be an array",
                              "/extensionsRequired"))
        required = []
    for i, name in enumerate(required):
        if name in _UNREADABLE_REQUIRED or (isinstance(name, str) and name.startswith(KHR + "_")):
            problems.append(_fail("UNSUPPORTED_REQUIRED_EXTENSION", f"the asset requires "
                                  f"extension {name}, which is not supported",
                                  f"/extensionsRequired/{i}"))
    return problems


@dataclass
class Document:
    """A parsed glTF container: ``doc`` is the raw JSON, ``gltf`` the decoded document,
    ``reader`` the bounds-checked buffer and accessor access, ``glb`` whether the container is
    a GLB, ``size`` the file size in bytes."""

    doc: dict
    gltf: pygltflib.GLTF2
    reader: "_Reader"
    glb: bool
    size: int


def load_document(path: str, max_bytes: int = DEFAULT_MAX_BYTES, *,
                  max_data_uri: int | None = None,
                  issues: list[tuple[str, str, int]] | None = None) -> Document:
    """Read and parse the container (GLB or JSON) of ``path``; no header checks.

    ``max_bytes`` caps the file plus every buffer it loads later; ``max_data_uri`` caps each
    ``data:`` URI; ``issues`` collects non-fatal GLB problems (see :func:`parse_glb`).
    Raises :class:`GltfFormatError` (or ``OSError`` when the file cannot be read).
    """
    size = os.path.getsize(path)
    if size > max_bytes:
        raise _fail("SIZE_LIMIT_EXCEEDED",
                    f"file is {size} bytes, larger than the limit of {max_bytes} bytes")
    with open(path, "rb") as handle:  # read(n) reserves n bytes: never ask for the cap itself
        data = memoryview(handle.read(size + 1 if size < max_bytes else max_bytes + 1))
    if len(data) > max_bytes:
        raise _fail("SIZE_LIMIT_EXCEEDED", f"file is larger than the limit of {max_bytes} bytes")
    glb_bin = None
    glb = bytes(data[:4]) == _GLB_MAGIC or os.path.splitext(path)[1].lower() == ".glb"
    if glb:
        raw_json, glb_bin = parse_glb(data, issues)
    else:
        raw_json = bytes(data)
    doc, gltf = parse_json(raw_json)
    reader = _Reader(path, gltf, glb_bin, max_bytes - len(data), max_data_uri)
    return Document(doc, gltf, reader, glb, len(data))


def _load_document(path: str, max_bytes: int) -> tuple[pygltflib.GLTF2, _Reader]:
    """Parse the container (GLB or JSON) and header; return the document and a bounded reader."""
    document = load_document(path, max_bytes)
    problems = header_problems(document.doc, strict=False)
    if problems:
        raise problems[0]
    return document.gltf, document.reader


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
            if KHR not in extensions:
                continue
            if prim.mode != pygltflib.POINTS:
                khr = extensions[KHR]
                nested = khr.get("extensions") if isinstance(khr, dict) else None
                if isinstance(nested, dict) and ANCHOR in nested:
                    raise FormatError(f"meshes[{m}].primitives[{p}]: an anchored splat primitive "
                                      f"must have mode POINTS (0), not {prim.mode!r}")
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
