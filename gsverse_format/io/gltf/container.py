"""The glTF container: GLB chunks, the JSON document, buffers, URIs, buffer views and limits.

Nothing here knows about splats. :func:`parse_glb` splits a GLB file into its JSON and BIN
chunks, :func:`parse_json` decodes and type-checks the JSON (array lengths capped by
:data:`~gsverse_format.limits.MAX_GLTF_ARRAY_ITEMS` before anything else; members are read
through :class:`JsonView`, no object is built per accessor), :func:`header_problems` checks
``asset.version`` and ``extensionsRequired``, and :class:`Buffers` loads buffers (GLB ``BIN``
chunk, base64 ``data:`` URIs, or files inside the asset's folder; nothing is fetched from the
network; a ``data:`` URI is capped by :data:`~gsverse_format.limits.MAX_DATA_URI_BYTES` and
decoded in slices, without a copy of the whole text) and checks buffer views, within a byte
budget. Every problem is a
:class:`GltfFormatError` carrying its issue :class:`~gsverse_format.codes.Code` and where it
is (a JSON pointer or a byte offset).
"""
from __future__ import annotations

import binascii
import json
import os
import re
import struct
import urllib.parse
from typing import Any, Iterable

import numpy as np

from ...codes import Code
from ...errors import FormatError
from ...limits import MAX_ASSET_BYTES, MAX_DATA_URI_BYTES, MAX_GLTF_ARRAY_ITEMS
from ...vocabulary import KHR, SPZ_EXTENSION

__all__ = ["DEFAULT_MAX_BYTES", "GLB_MAGIC", "CHUNK_JSON", "CHUNK_BIN", "UNREADABLE_REQUIRED",
           "GltfFormatError", "gltf_error", "is_int", "as_int", "as_index", "parse_glb",
           "glb_bytes", "pointer_token", "JsonView", "check_data_uri_sizes", "json_text",
           "require_json_start",
           "parse_json", "header_problems", "Buffers"]

#: Default cap on the bytes one asset may occupy (file plus external/embedded buffers).
DEFAULT_MAX_BYTES = MAX_ASSET_BYTES

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


class JsonView:
    """Attribute access to a JSON object: ``view.byteOffset`` is ``obj.get("byteOffset")``
    (``None`` when absent), nested objects and arrays are views too. Nothing is copied or
    decoded ahead of use, so a document with many accessors costs only its JSON parse."""

    __slots__ = ("_obj",)

    def __init__(self, obj: dict) -> None:
        self._obj = obj

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        return _view(self._obj.get(name))


class _ListView:
    """A JSON array whose object elements are seen as :class:`JsonView` (built on access)."""

    __slots__ = ("_items",)

    def __init__(self, items: list) -> None:
        self._items = items

    def __len__(self) -> int:
        return len(self._items)

    def __getitem__(self, i: int) -> Any:
        return _view(self._items[i])

    def __iter__(self) -> Iterable[Any]:
        return (_view(item) for item in self._items)

    def item(self, i: int) -> Any:
        """Element ``i`` as it is in the JSON (a ``dict`` for an object)."""
        return self._items[i]


def _view(value: Any) -> Any:
    if isinstance(value, dict):
        return JsonView(value)
    if isinstance(value, list):
        return _ListView(value)
    return value


def _check_counts(doc: dict) -> None:
    """Array lengths against :data:`MAX_GLTF_ARRAY_ITEMS`, before any member is looked at."""
    for key, value in doc.items():
        if isinstance(value, list) and len(value) > MAX_GLTF_ARRAY_ITEMS:
            raise gltf_error(Code.SIZE_LIMIT_EXCEEDED, f"the document has {len(value)} {key}, "
                             f"more than the limit of {MAX_GLTF_ARRAY_ITEMS}",
                             f"/{pointer_token(key)}")
    meshes = doc.get("meshes")
    for m, mesh in enumerate(meshes if isinstance(meshes, list) else []):
        prims = mesh.get("primitives") if isinstance(mesh, dict) else None
        if isinstance(prims, list) and len(prims) > MAX_GLTF_ARRAY_ITEMS:
            raise gltf_error(Code.SIZE_LIMIT_EXCEEDED, f"meshes[{m}] has {len(prims)} "
                             f"primitives, more than the limit of {MAX_GLTF_ARRAY_ITEMS}",
                             f"/meshes/{m}/primitives")


def check_data_uri_sizes(raw: bytes, limit: int) -> None:
    """Refuse, before the JSON is parsed, a ``data:`` URI string whose base64 text would
    decode to more than ``limit`` bytes (``DATA_URI_TOO_LARGE``): a huge URI would otherwise
    cost several copies of itself in memory before its size could be looked at. Each
    ``"data:`` is measured up to the next quote (base64 text holds no quote or escape)."""
    encoded_limit = (limit // 3 + 1) * 4 + 1024
    pos = raw.find(b'"data:')
    while pos >= 0:
        end = raw.find(b'"', pos + 1)
        if end < 0:
            return  # unterminated string: the JSON parser says so
        if end - pos - 1 > encoded_limit:
            raise gltf_error(Code.DATA_URI_TOO_LARGE, f"a data: URI at byte {pos + 1} of the "
                             f"JSON holds about {(end - pos) * 3 // 4} bytes, more than the "
                             f"limit of {limit} bytes per data: URI", offset=None)
        pos = raw.find(b'"data:', end + 1)


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON value")


#: First bytes of files that are often given in place of a glTF file, by what they are.
_OTHER_MAGIC = ((b"ply", "a PLY file"), (b"NGSP", "an SPZ file"), (b"\x1f\x8b", "a gzip file "
                "(.spz?)"), (b"PK\x03\x04", "a ZIP archive (.sog, .usdz?)"),
                (b"PXR-USDC", "a binary USD file"), (b"#usda", "a USD text file"))


def require_json_start(blob: bytes | memoryview) -> None:
    """Raise JSON_INVALID saying "not a glTF file" when ``blob`` (a whole file that is not
    a GLB) cannot be glTF JSON: its first byte after whitespace and a byte order mark is
    not ``{``. (Without this, a PLY given as glTF is reported as "not valid UTF-8".)"""
    head = bytes(blob[:64])
    text = head[3:] if head.startswith(b"\xef\xbb\xbf") else head
    text = text.lstrip(b" \t\r\n")
    if not text or text.startswith(b"{"):
        return
    what = next((name for magic, name in _OTHER_MAGIC if head.startswith(magic)), None)
    raise gltf_error(Code.JSON_INVALID, f"not a glTF file: it starts with {head[:8]!r}"
                     + (f" ({what})" if what else "") + ", not with b'glTF' (GLB) or '{' "
                     "(glTF JSON)", offset=0)


def json_text(raw: bytes | memoryview) -> str:
    """glTF JSON bytes as text (a leading byte order mark dropped); raises
    :class:`GltfFormatError` for bytes that are not UTF-8."""
    try:
        text = str(raw, "utf-8")
    except UnicodeDecodeError as err:
        raise gltf_error(Code.JSON_NOT_UTF8,
                         f"glTF JSON is not valid UTF-8 (byte {err.start})") from None
    return text.lstrip("\ufeff") if text.startswith("\ufeff") else text


def parse_json(raw: bytes | memoryview | str) -> tuple[dict, JsonView]:
    """(raw JSON document, attribute view of it) of glTF JSON bytes or text; raises
    :class:`GltfFormatError` for bytes that are not UTF-8, not JSON (``NaN`` and
    ``Infinity`` included), not an object, with arrays longer than the limit, or whose
    members have the wrong types."""
    text = raw if isinstance(raw, str) else json_text(raw)
    try:
        doc = json.loads(text, parse_constant=_no_constant)
    except (ValueError, RecursionError) as err:
        raise gltf_error(Code.JSON_INVALID, f"glTF JSON is not valid JSON ({err})") from None
    del text
    if not isinstance(doc, dict):
        raise gltf_error(Code.JSON_INVALID, "glTF JSON root is not an object", "")
    _check_counts(doc)
    _check_types(doc)
    return doc, JsonView(doc)


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
        if name in UNREADABLE_REQUIRED or (isinstance(name, str) and name.startswith(KHR + "_")
                                           and name != SPZ_EXTENSION):
            problems.append(gltf_error(Code.UNSUPPORTED_REQUIRED_EXTENSION, f"the asset requires "
                                       f"extension {name}, which is not supported",
                                       f"/extensionsRequired/{i}"))
    return problems


# ---------------------------------------------------------------------------- buffers

class Buffers:
    """Bounds-checked access to the buffers and buffer views of one glTF document.

    ``budget`` is how many bytes the buffers may still occupy (the file's size already
    spent); ``max_data_uri`` caps the decoded size of each ``data:`` URI (``None``:
    :data:`~gsverse_format.limits.MAX_DATA_URI_BYTES`).
    """

    def __init__(self, path: str, gltf: JsonView, glb_bin: memoryview | None,
                 budget: int, max_data_uri: int | None = None) -> None:
        self.path = path
        self.folder = os.path.dirname(os.path.abspath(path))
        self.gltf = gltf
        self.glb_bin = glb_bin
        self.budget = budget
        self.max_data_uri = MAX_DATA_URI_BYTES if max_data_uri is None else max_data_uri
        self.views = self.array("bufferViews")
        self.buffers_json = self.array("buffers")
        self._buffers: dict[int, memoryview] = {}
        self._view_bounds: dict[int, tuple[int, int, int]] = {}

    def array(self, name: str) -> Any:
        """The top-level array ``name`` (empty when absent), its objects seen as
        :class:`JsonView`."""
        value = getattr(self.gltf, name, None)
        if value is None:
            return _ListView([])
        if not isinstance(value, _ListView):
            raise gltf_error(Code.GLTF_SCHEMA_VIOLATION, f"{name} must be an array", f"/{name}")
        return value

    def _spend(self, size: int, what: str, pointer: str) -> None:
        if size > self.budget:
            raise gltf_error(Code.SIZE_LIMIT_EXCEEDED,
                             f"{what} would take the asset past the size limit", pointer)
        self.budget -= size

    def _data_uri(self, uri: str, what: str, pointer: str) -> bytearray:
        comma = uri.find(",", 0, 1024)
        if comma < 0:
            raise gltf_error(Code.URI_INVALID, f"{what}: malformed data: URI (no comma)", pointer)
        if not uri[5:comma].lower().endswith(";base64"):
            raise gltf_error(Code.URI_INVALID, f"{what}: only base64 data: URIs are supported",
                             pointer)
        encoded = len(uri) - comma - 1
        size = encoded * 3 // 4
        if size > self.max_data_uri:
            raise gltf_error(Code.DATA_URI_TOO_LARGE, f"{what}: data: URI holds about {size} "
                             f"bytes, more than the limit of {self.max_data_uri} bytes per "
                             f"data: URI", pointer)
        if encoded % 4:
            raise gltf_error(Code.URI_INVALID, f"{what}: data: URI is not valid base64",
                             pointer)
        size -= uri.count("=", max(comma + 1, len(uri) - 2))
        self._spend(size, what, pointer)
        # Decoded slice by slice into one buffer: never a second copy of the whole text.
        out = bytearray(size)
        step = 4 * 2 ** 20
        pos = 0
        try:
            for start in range(comma + 1, len(uri), step):
                chunk = binascii.a2b_base64(uri[start:start + step], strict_mode=True)
                out[pos:pos + len(chunk)] = chunk
                pos += len(chunk)
        except (binascii.Error, ValueError):
            raise gltf_error(Code.URI_INVALID, f"{what}: data: URI is not valid base64",
                             pointer) from None
        if pos != size:
            raise gltf_error(Code.URI_INVALID, f"{what}: data: URI is not valid base64",
                             pointer)
        return out

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
        buf = self.buffers_json.item(i)
        what = f"buffers[{i}]"
        pointer = f"/buffers/{i}"
        length = as_int(buf.get("byteLength"), f"{what}.byteLength",
                        pointer=f"{pointer}/byteLength")
        uri = buf.get("uri")
        if uri is None:
            if i != 0 or self.glb_bin is None:
                raise gltf_error(Code.BUFFER_MISSING_DATA, f"{what} has no uri and the file has "
                                 f"no GLB BIN chunk (missing BIN chunk)", pointer)
            data = self.glb_bin
        elif not isinstance(uri, str):
            raise gltf_error(Code.GLTF_SCHEMA_VIOLATION, f"{what}.uri must be a string",
                             f"{pointer}/uri")
        elif uri[:5].lower() == "data:":
            data = memoryview(self._data_uri(uri, what, f"{pointer}/uri")).toreadonly()
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
        if v in self._view_bounds:
            return self._view_bounds[v]
        view = self.views.item(v)
        pointer = f"/bufferViews/{v}"
        view_offset = as_int(view.get("byteOffset"), f"bufferViews[{v}].byteOffset", default=0,
                             pointer=f"{pointer}/byteOffset")
        view_length = as_int(view.get("byteLength"), f"bufferViews[{v}].byteLength", minimum=1,
                             pointer=f"{pointer}/byteLength")
        b = as_index(view.get("buffer"), len(self.buffers_json), f"bufferViews[{v}].buffer",
                     f"{pointer}/buffer")
        buf = self.buffer(b)
        if view_offset + view_length > len(buf):
            raise gltf_error(Code.BUFFER_VIEW_OUT_OF_BOUNDS,
                             f"bufferViews[{v}] (bytes {view_offset}..{view_offset + view_length})"
                             f" runs past the end of buffers[{b}] ({len(buf)} bytes)", pointer)
        self._view_bounds[v] = (b, view_offset, view_length)
        return b, view_offset, view_length
