"""The glTF container: GLB chunks, the JSON document, buffers, URIs, buffer views and limits.

Nothing here knows about splats. :func:`parse_glb` splits a GLB file into its JSON and BIN
chunks, :func:`parse_json` decodes and type-checks the JSON, :func:`header_problems` checks
``asset.version`` and ``extensionsRequired``, and :class:`Buffers` loads buffers (GLB ``BIN``
chunk, base64 ``data:`` URIs, or files inside the asset's folder; nothing is fetched from the
network) and checks buffer views, within a byte budget. Every problem is a
:class:`GltfFormatError` carrying its issue :class:`~gsverse_format.codes.Code` and where it
is (a JSON pointer or a byte offset).
"""
from __future__ import annotations

import base64
import binascii
import json
import os
import re
import struct
import urllib.parse
import warnings
from typing import Any, Iterable

import numpy as np
import pygltflib

from ...codes import Code
from ...errors import FormatError
from ...vocabulary import KHR

__all__ = ["DEFAULT_MAX_BYTES", "GLB_MAGIC", "CHUNK_JSON", "CHUNK_BIN", "UNREADABLE_REQUIRED",
           "GltfFormatError", "gltf_error", "is_int", "as_int", "as_index", "parse_glb",
           "glb_bytes", "pointer_token", "parse_json", "header_problems", "Buffers"]

#: Default cap on the bytes one asset may occupy (file plus external/embedded buffers).
DEFAULT_MAX_BYTES = 2 ** 33

GLB_MAGIC = b"glTF"
CHUNK_JSON = 0x4E4F534A
CHUNK_BIN = 0x004E4942

#: Required extensions that change how splat data are stored: such files cannot be read.
UNREADABLE_REQUIRED = ("KHR_draco_mesh_compression", "EXT_meshopt_compression",
                       "KHR_meshopt_compression")

_SCHEME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9+.\-]*:")


class GltfFormatError(FormatError):
    """A :class:`FormatError` that also carries the issue ``code`` of ``spec/validation.md``
    and where the problem is: a JSON ``pointer`` (RFC 6901) or a byte ``offset`` into a GLB
    file. ``gsverse-validate`` reports these; the reader only shows the one-line cause."""

    def __init__(self, cause: str, path: str | os.PathLike | None = None, *,
                 code: Code | str | None = None, pointer: str | None = None,
                 offset: int | None = None) -> None:
        super().__init__(cause, path)
        self.code: Code | None = None if code is None else Code(code)
        self.pointer = pointer
        self.offset = offset

    def with_path(self, path: str | os.PathLike) -> "GltfFormatError":
        if self.path is None:
            return GltfFormatError(self.cause, path, code=self.code, pointer=self.pointer,
                                   offset=self.offset)
        return self


def gltf_error(code: Code, cause: str, pointer: str | None = None,
               offset: int | None = None) -> GltfFormatError:
    """A :class:`GltfFormatError` with ``code`` (to raise or to report)."""
    return GltfFormatError(cause, code=code, pointer=pointer, offset=offset)


def is_int(value: Any) -> bool:
    """True for a JSON integer (not a boolean)."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def as_int(value: Any, what: str, *, minimum: int = 0, default: int | None = None,
           pointer: str | None = None, code: Code = Code.GLTF_SCHEMA_VIOLATION) -> int:
    """``value`` as an integer >= ``minimum`` (``default`` when it is None)."""
    if value is None and default is not None:
        return default
    if not is_int(value) or value < minimum:
        raise gltf_error(code, f"{what} must be an integer >= {minimum}, got {value!r}", pointer)
    return int(value)


def as_index(value: Any, size: int, what: str, pointer: str | None = None) -> int:
    """``value`` as an index into an array of ``size`` elements."""
    if not is_int(value):
        raise gltf_error(Code.UNRESOLVED_REFERENCE, f"{what} must be an index, got {value!r}",
                         pointer)
    if not 0 <= value < size:
        raise gltf_error(Code.UNRESOLVED_REFERENCE,
                         f"{what} {value} out of range (there are {size})", pointer)
    return int(value)


# ---------------------------------------------------------------------------- GLB

def parse_glb(data: memoryview | bytes,
              issues: list[tuple[Code, str, int]] | None = None) -> tuple[bytes, memoryview | None]:
    """(JSON chunk, BIN chunk or None) of a GLB container, every length checked.

    Problems that make the container unreadable raise :class:`GltfFormatError`. Problems the
    reader can step over (a chunk length that is not a multiple of 4, an unknown chunk type, a
    JSON or BIN chunk out of place) are appended to ``issues`` as ``(code, message, byte
    offset)`` when a list is given, and ignored otherwise.
    """
    data = memoryview(data)
    if len(data) < 12:
        raise gltf_error(Code.GLB_TRUNCATED, f"truncated GLB: {len(data)} bytes, shorter than "
                         f"the 12-byte header", offset=0)
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    if magic != GLB_MAGIC:
        raise gltf_error(Code.GLB_BAD_MAGIC,
                         f"not a GLB file: bad magic {bytes(magic)!r} (expected b'glTF')", offset=0)
    if version != 2:
        raise gltf_error(Code.GLB_UNSUPPORTED_VERSION,
                         f"unsupported GLB container version {version} (only 2)", offset=4)
    if length > len(data):
        raise gltf_error(Code.GLB_TRUNCATED, f"truncated GLB: header says {length} bytes, file "
                         f"has {len(data)}", offset=8)
    if length < len(data):
        raise gltf_error(Code.GLB_LENGTH_MISMATCH,
                         f"GLB length field {length} does not match the file size {len(data)}",
                         offset=8)
    chunks: list[tuple[int, memoryview]] = []
    pos = 12
    while pos < length:
        if pos + 8 > length:
            raise gltf_error(Code.GLB_TRUNCATED, f"truncated GLB: chunk header at byte {pos} runs "
                             f"past the end", offset=pos)
        size, kind = struct.unpack_from("<II", data, pos)
        if size > length - pos - 8:
            raise gltf_error(Code.GLB_CHUNK_TOO_LONG, f"GLB chunk {len(chunks)} is {size} bytes "
                             f"long but only {length - pos - 8} bytes follow it", offset=pos)
        if issues is not None:
            if size % 4:
                issues.append((Code.GLB_CHUNK_UNALIGNED, f"GLB chunk {len(chunks)} is {size} "
                               f"bytes long, not a multiple of 4 (chunks must be padded)", pos))
            if kind not in (CHUNK_JSON, CHUNK_BIN):
                issues.append((Code.GLB_UNKNOWN_CHUNK, f"GLB chunk {len(chunks)} has unknown type "
                               f"0x{kind:08X}; it is ignored", pos + 4))
            elif len(chunks) > 0 and (kind == CHUNK_JSON or len(chunks) > 1):
                name = "JSON" if kind == CHUNK_JSON else "BIN"
                issues.append((Code.GLB_UNEXPECTED_CHUNK, f"GLB chunk {len(chunks)} is a {name} "
                               f"chunk; only the first chunk may be JSON and only the second "
                               f"BIN; it is ignored", pos + 4))
        pos += 8
        chunks.append((kind, data[pos:pos + size]))
        pos += size
    if not chunks or chunks[0][0] != CHUNK_JSON:
        raise gltf_error(Code.GLB_FIRST_CHUNK_NOT_JSON, "GLB does not start with a JSON chunk",
                         offset=12)
    binary = chunks[1][1] if len(chunks) > 1 and chunks[1][0] == CHUNK_BIN else None
    return bytes(chunks[0][1]), binary


def glb_bytes(json_chunk: bytes, bin_chunk: bytes | None = None) -> bytes:
    """A GLB 2.0 container holding ``json_chunk`` (padded with spaces) and, unless it is
    None, ``bin_chunk`` (padded with zeros)."""
    text = bytes(json_chunk) + b" " * (-len(json_chunk) % 4)
    out = struct.pack("<II", len(text), CHUNK_JSON) + text
    if bin_chunk is not None:
        blob = bytes(bin_chunk) + b"\0" * (-len(bin_chunk) % 4)
        out += struct.pack("<II", len(blob), CHUNK_BIN) + blob
    return struct.pack("<4sII", GLB_MAGIC, 2, 12 + len(out)) + out


# ---------------------------------------------------------------------------- JSON

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
        return gltf_error(Code.GLTF_SCHEMA_VIOLATION, cause, pointer)

    def obj_list(value: Any, where: str, pointer: str) -> list:
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise bad(f"{where} must be an array of objects", pointer)
        return value

    def ints(item: dict, keys: Iterable[str], where: str, pointer: str) -> None:
        for key in keys:
            if key in item and not is_int(item[key]):
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


#: What the dataclass decoder of pygltflib raises for JSON that does not follow its schema.
_DECODER_ERRORS = (AttributeError, TypeError, ValueError, KeyError, IndexError, OverflowError,
                   RecursionError)


def parse_json(raw: bytes) -> tuple[dict, pygltflib.GLTF2]:
    """(raw JSON document, pygltflib document) of glTF JSON bytes; raises
    :class:`GltfFormatError` for bytes that are not UTF-8, not JSON, not an object, or whose
    members have the wrong types."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise gltf_error(Code.JSON_NOT_UTF8,
                         f"glTF JSON is not valid UTF-8 (byte {err.start})") from None
    text = text.lstrip("\ufeff")
    try:
        doc = json.loads(text)
    except (ValueError, RecursionError) as err:
        raise gltf_error(Code.JSON_INVALID, f"glTF JSON is not valid JSON ({err})") from None
    if not isinstance(doc, dict):
        raise gltf_error(Code.JSON_INVALID, "glTF JSON root is not an object", "")
    _check_types(doc)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            gltf = pygltflib.GLTF2.from_json(text, infer_missing=True)
    except _DECODER_ERRORS as err:
        raise gltf_error(Code.GLTF_SCHEMA_VIOLATION, f"glTF JSON does not follow the glTF "
                         f"schema ({type(err).__name__}: {err})") from None
    return doc, gltf


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
        problems.append(gltf_error(Code.ASSET_VERSION_UNSUPPORTED, f"unsupported glTF "
                                   f"asset.version {version!r} (expected '2.0')",
                                   "/asset/version" if isinstance(asset, dict) else "/asset"))
    required = doc.get("extensionsRequired", [])
    if not isinstance(required, list):
        problems.append(gltf_error(Code.GLTF_SCHEMA_VIOLATION,
                                   "extensionsRequired must be an array", "/extensionsRequired"))
        required = []
    for i, name in enumerate(required):
        if name in UNREADABLE_REQUIRED or (isinstance(name, str) and name.startswith(KHR + "_")):
            problems.append(gltf_error(Code.UNSUPPORTED_REQUIRED_EXTENSION, f"the asset requires "
                                       f"extension {name}, which is not supported",
                                       f"/extensionsRequired/{i}"))
    return problems


# ---------------------------------------------------------------------------- buffers

class Buffers:
    """Bounds-checked access to the buffers and buffer views of one glTF document.

    ``budget`` is how many bytes the buffers may still occupy (the file's size already
    spent); ``max_data_uri`` optionally caps the decoded size of each ``data:`` URI.
    """

    def __init__(self, path: str, gltf: pygltflib.GLTF2, glb_bin: memoryview | None,
                 budget: int, max_data_uri: int | None = None) -> None:
        self.path = path
        self.folder = os.path.dirname(os.path.abspath(path))
        self.gltf = gltf
        self.glb_bin = glb_bin
        self.budget = budget
        self.max_data_uri = max_data_uri
        self.views = self.array("bufferViews")
        self.buffers_json = self.array("buffers")
        self._buffers: dict[int, memoryview] = {}

    def array(self, name: str) -> list:
        """The decoded top-level array ``name`` (empty when absent)."""
        value = getattr(self.gltf, name, None)
        if value is None:
            return []
        if not isinstance(value, list):
            raise gltf_error(Code.GLTF_SCHEMA_VIOLATION, f"{name} must be an array", f"/{name}")
        return value

    def _spend(self, size: int, what: str, pointer: str) -> None:
        if size > self.budget:
            raise gltf_error(Code.SIZE_LIMIT_EXCEEDED,
                             f"{what} would take the asset past the size limit", pointer)
        self.budget -= size

    def _data_uri(self, uri: str, what: str, pointer: str) -> bytes:
        comma = uri.find(",")
        if comma < 0:
            raise gltf_error(Code.URI_INVALID, f"{what}: malformed data: URI (no comma)", pointer)
        if not uri[5:comma].lower().endswith(";base64"):
            raise gltf_error(Code.URI_INVALID, f"{what}: only base64 data: URIs are supported",
                             pointer)
        payload = uri[comma + 1:]
        size = len(payload) * 3 // 4
        if self.max_data_uri is not None and size > self.max_data_uri:
            raise gltf_error(Code.DATA_URI_TOO_LARGE, f"{what}: data: URI holds about {size} "
                             f"bytes, more than the limit of {self.max_data_uri} bytes per "
                             f"data: URI", pointer)
        self._spend(size, what, pointer)
        try:
            return base64.b64decode(payload, validate=True)
        except (binascii.Error, ValueError):
            raise gltf_error(Code.URI_INVALID, f"{what}: data: URI is not valid base64",
                             pointer) from None

    def _file_uri(self, uri: str, what: str, pointer: str) -> bytes:
        shown = uri if len(uri) <= 80 else uri[:77] + "..."
        if _SCHEME_RE.match(uri):
            scheme = uri.split(":", 1)[0]
            raise gltf_error(Code.URI_SCHEME_REJECTED, f"{what}: URI {shown!r} uses scheme "
                             f"'{scheme}:'; only data: URIs and relative file paths are allowed "
                             f"(nothing is fetched)", pointer)
        rel = urllib.parse.unquote(uri)
        if "\0" in rel or not rel:
            raise gltf_error(Code.URI_INVALID, f"{what}: invalid URI {shown!r}", pointer)
        if rel.startswith(("/", "\\")) or os.path.isabs(rel) or uri.startswith("//"):
            raise gltf_error(Code.URI_ABSOLUTE_PATH, f"{what}: absolute path {shown!r} not "
                             f"allowed; buffer files must be relative to the asset's folder",
                             pointer)
        if ".." in re.split(r"[\\/]", rel):
            raise gltf_error(Code.URI_OUTSIDE_FOLDER,
                             f"{what}: URI {shown!r} escapes the asset's folder ('..')", pointer)
        folder = os.path.realpath(self.folder)
        target = os.path.realpath(os.path.join(folder, rel))
        if os.path.commonpath([folder, target]) != folder:
            raise gltf_error(Code.URI_OUTSIDE_FOLDER,
                             f"{what}: URI {shown!r} resolves outside the asset's folder", pointer)
        if not os.path.isfile(target):
            raise gltf_error(Code.URI_NOT_FOUND,
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
        length = as_int(buf.byteLength, f"{what}.byteLength", pointer=f"{pointer}/byteLength")
        uri = buf.uri
        if uri is None:
            if i != 0 or self.glb_bin is None:
                raise gltf_error(Code.BUFFER_MISSING_DATA, f"{what} has no uri and the file has "
                                 f"no GLB BIN chunk (missing BIN chunk)", pointer)
            data = self.glb_bin
        elif not isinstance(uri, str):
            raise gltf_error(Code.GLTF_SCHEMA_VIOLATION, f"{what}.uri must be a string",
                             f"{pointer}/uri")
        elif uri[:5].lower() == "data:":
            data = memoryview(self._data_uri(uri, what, f"{pointer}/uri"))
        else:
            data = memoryview(self._file_uri(uri, what, f"{pointer}/uri"))
        if len(data) < length:
            raise gltf_error(Code.BUFFER_TOO_SHORT,
                             f"{what} holds {len(data)} bytes but its byteLength is {length}",
                             pointer)
        self._buffers[i] = data[:length]
        return self._buffers[i]

    def view_bounds(self, v: int) -> tuple[int, int, int]:
        """(buffer index, byteOffset, byteLength) of bufferView ``v``, within its buffer."""
        view = self.views[v]
        pointer = f"/bufferViews/{v}"
        view_offset = as_int(view.byteOffset, f"bufferViews[{v}].byteOffset", default=0,
                             pointer=f"{pointer}/byteOffset")
        view_length = as_int(view.byteLength, f"bufferViews[{v}].byteLength", minimum=1,
                             pointer=f"{pointer}/byteLength")
        b = as_index(view.buffer, len(self.buffers_json), f"bufferViews[{v}].buffer",
                     f"{pointer}/buffer")
        buf = self.buffer(b)
        if view_offset + view_length > len(buf):
            raise gltf_error(Code.BUFFER_VIEW_OUT_OF_BOUNDS,
                             f"bufferViews[{v}] (bytes {view_offset}..{view_offset + view_length})"
                             f" runs past the end of buffers[{b}] ({len(buf)} bytes)", pointer)
        return b, view_offset, view_length
