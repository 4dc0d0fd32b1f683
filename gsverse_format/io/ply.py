"""PLY files: a small, strict PLY parser, and the 3D Gaussian splatting (3DGS) PLY layout.

Generic PLY
-----------
:func:`read_ply_header` and :func:`read_ply_elements` read any PLY file (``ascii``,
``binary_little_endian``, ``binary_big_endian``, version 1.0) with every scalar type of the
format (``char/int8``, ``uchar/uint8``, ``short/int16``, ``ushort/uint16``, ``int/int32``,
``uint/uint32``, ``float/float32``, ``double/float64``), properties in any order,
``comment`` and ``obj_info`` lines, and list properties (for example the ``face`` element of
a mesh). Each element becomes a structured numpy array in native byte order; a list property
whose lists all have the same length ``L`` becomes a sub-array field of shape ``(L,)``,
otherwise an object field holding one array per row.

The reader is strict, and every problem becomes a :class:`~gsverse_format.errors.FormatError`
naming the file with a one-line cause: a missing ``ply`` magic line or ``end_header``, a
non-ASCII header, unknown header keywords, formats or types, declared row counts that the data
cannot hold (checked against the file size *before* anything is allocated, so a header
claiming 10¹² rows costs nothing), truncated data, and data left over after the last element
(the declared counts must account for every byte or value of the body).

3DGS splat layout
-----------------
:func:`read_splat_ply` reads the ``vertex`` element written by the reference 3DGS code and its
descendants::

    x y z [nx ny nz] f_dc_0..2 [f_rest_0..M-1] opacity scale_0..2 rot_0..3 [others...]

in any property order. The file stores *pre-activation* values; the model
(:class:`~gsverse_format.model.SplatCloud`) holds activated ones:

* ``opacity`` is a logit: ``opacities = sigmoid(opacity)`` (a stable form, no overflow).
* ``scale_i`` are natural logs: ``scales = exp(scale_i)``.
* ``rot_0..3`` is an unnormalized quaternion ``(w, x, y, z)``: it is normalized and reordered
  to the model's ``(x, y, z, w)``. A zero quaternion is an error.
* ``f_rest`` is **channel-major**: ``f_rest[c·(K−1) + (j−1)]`` is coefficient ``j``
  (1..K−1) of colour channel ``c``; it becomes ``sh[:, j, c]``. ``M = 3·(K−1)`` must be 0, 9,
  24 or 45 (SH degree 0..3). ``f_dc_c`` is ``sh[:, 0, c]``.
* Without ``f_dc_*``, ``red/green/blue`` give ``f_dc = (rgb − 0.5) / 0.28209479177387814``
  with ``rgb`` in [0, 1] (``uchar`` divided by 255, ``ushort`` by 65535, floats taken as is).
* ``nx ny nz`` (normals, unused by 3DGS) are dropped; any other scalar vertex property (for
  example ``filter_3D`` or ``binding_0``) is kept in ``SplatCloud.extra`` as float32.

Activations are computed in float64 and rounded once to float32. Values that are not finite
in a required property, decoded values beyond the float32 range (``exp`` of a log-scale above
88.72) and zero quaternions are rejected. SuperSplat/PlayCanvas compressed PLY files (element
``chunk``, ``packed_*`` properties) and 2D Gaussian splats (only ``scale_0``, ``scale_1``) are
recognised and refused with a clear message.

:func:`write_splat_ply` writes the inverse, all properties ``float``, in the order above
(``nx ny nz`` as zeros when ``normals=True``; extras after ``rot_3``), in any of the three
formats. Rotations are written as stored (``(x, y, z, w)`` → ``rot_0..3 = (w, x, y, z)``).
Two clamps keep every written value finite:

* opacities are clamped to ``[2⁻¹⁵², 1 − 2⁻²⁶]`` before the logit. No float32 value inside
  (0, 1) is affected: only 0 (→ logit −105.36) and 1 (→ logit 18.02) are, and both decode
  back to exactly 0.0 and 1.0 in float32. Values outside [0, 1] are clamped as well.
* scales below ``2⁻¹⁵²`` (zero, or negative) are written as ``log(2⁻¹⁵²) = −105.36``, which
  decodes back to exactly 0.0 in float32; every positive float32 scale is written unchanged.

Round-trip accuracy (PLY → SplatCloud → PLY, each stored float32 value ``v`` → ``v'``)
------------------------------------------------------------------------------------------
``log(exp(v))`` and ``logit(sigmoid(v))`` are not bit-exact once the activated value is
rounded to float32 (relative error ≤ 2⁻²⁴). The bounds below follow from that rounding and
hold on the sample files and on random values (both tested in ``tests/test_ply.py``):

* ``x y z``, ``f_dc_*``, ``f_rest_*`` and extra float properties: bit-exact.
* ``scale_i`` (log-scale ``L``, −87.3 ≤ L ≤ 88.7): ``|L' − L| ≤ 2⁻²⁴ + ulp(L)/2 ≤ 2⁻²³``
  (≈1.2e-7; measured maximum 2⁻²⁴ ≈ 6e-8), and bit-exact for ``|L| > 1``, where that error
  is below half a float32 step of ``L``. Below −87.3 the scale is a float32 subnormal and
  loses relative precision; below −103.9 it decodes to 0 and is re-written as −105.36.
* ``opacity`` (logit ``L``, −87.3 ≤ L ≤ 16.6): ``|L' − L| ≤ 2⁻²⁴·(1 + e^L) + ulp(L)``:
  bit-exact for ``L < −2``, ≤ 1.2e-7 for ``−2 ≤ L ≤ 0``, then growing with ``e^L`` as the
  opacity approaches 1, because float32 resolves opacities near 1 only in steps of 2⁻²⁴
  (measured: 4.8e-6 at L = 5, 7e-4 at L = 10, 0.1 at L = 15). In opacity space the error is
  below one float32 step: ``|sigmoid(L') − sigmoid(L)| ≤ 2⁻²⁴`` for every ``L``. Logits
  above ≈17.3 decode to opacity 1.0 and are re-written as 18.02; logits below −103.9 decode
  to 0.0 and are re-written as −105.36.
* ``rot_0..3``: the quaternion is re-written normalized, ``|q' − q/|q|| ≤ 2⁻²⁴`` per
  component (measured 3e-8), so files with unnormalized quaternions (common) reproduce the
  rotation, not the raw values.
* ``nx ny nz`` are dropped on reading (written as zeros with ``normals=True``); integer extra
  properties come back as floats; colours given only as ``red/green/blue`` come back as
  ``f_dc_*``.
"""
from __future__ import annotations

import contextlib
import os
import re
import struct
import warnings
from dataclasses import dataclass, field
from typing import BinaryIO, Iterable, Iterator

import numpy as np

from ..atomic import atomic_write
from ..errors import FormatError, UsageError
from ..model import SplatCloud, TriangleMesh

__all__ = [
    "PlyProperty",
    "PlyElement",
    "PlyHeader",
    "PlyData",
    "read_ply_header",
    "read_ply_elements",
    "read_ply_mesh",
    "read_splat_ply",
    "describe_ply",
    "write_splat_ply",
    "SH_C0",
    "OPACITY_CLAMP",
    "SCALE_FLOOR",
]

#: Zeroth-order real SH basis constant, 1 / (2·sqrt(pi)).
SH_C0 = 0.28209479177387814
#: Opacities are clamped to this range before the logit is written (see module docstring).
OPACITY_CLAMP = (2.0 ** -152, 1.0 - 2.0 ** -26)
#: Scales below this are written as ``log(SCALE_FLOOR)`` instead of ``log(0) = -inf``.
SCALE_FLOOR = 2.0 ** -152

#: PLY type names -> numpy type codes (without byte order).
SCALAR_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
_STRUCT = {"i1": "b", "u1": "B", "i2": "h", "u2": "H", "i4": "i", "u4": "I", "f4": "f", "f8": "d"}
FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
MAX_HEADER_BYTES = 1 << 20

_LAYOUT_SCALARS = ("x", "y", "z", "opacity", "scale_0", "scale_1", "scale_2",
                   "rot_0", "rot_1", "rot_2", "rot_3")
_DC = ("f_dc_0", "f_dc_1", "f_dc_2")
_RGB = ("red", "green", "blue")
_NORMALS = ("nx", "ny", "nz")
_F_REST = re.compile(r"f_rest_(\d+)\Z")
_SH_REST_COUNTS = {0: 0, 9: 1, 24: 2, 45: 3}
_COMPRESSED = ("compressed PLY (SuperSplat/PlayCanvas) is not supported yet; "
               "decompress it first, e.g. with splat-transform")


# --------------------------------------------------------------------------------------------
# Header


@dataclass(frozen=True)
class PlyProperty:
    """One property: ``type`` is a numpy code (``"f4"``, ``"u1"`` …); lists have ``count_type``."""

    name: str
    type: str
    count_type: str | None = None

    @property
    def is_list(self) -> bool:
        return self.count_type is not None


@dataclass
class PlyElement:
    """An element declaration: ``count`` rows of ``properties``."""

    name: str
    count: int
    properties: list[PlyProperty] = field(default_factory=list)

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.properties]

    @property
    def has_lists(self) -> bool:
        return any(p.is_list for p in self.properties)

    def property(self, name: str) -> PlyProperty | None:
        for p in self.properties:
            if p.name == name:
                return p
        return None


@dataclass
class PlyHeader:
    """A parsed header; ``data_offset`` is the byte offset of the body."""

    format: str
    version: str
    elements: list[PlyElement]
    comments: list[str]
    obj_info: list[str]
    data_offset: int

    def element(self, name: str) -> PlyElement | None:
        for e in self.elements:
            if e.name == name:
                return e
        return None


@dataclass
class PlyData:
    """What :func:`read_ply_elements` returns: the header and one structured array per element."""

    header: PlyHeader
    elements: dict[str, np.ndarray]
    path: str | None = None

    @property
    def format(self) -> str:
        return self.header.format

    @property
    def comments(self) -> list[str]:
        return self.header.comments

    def __getitem__(self, name: str) -> np.ndarray:
        return self.elements[name]

    def __contains__(self, name: object) -> bool:
        return name in self.elements

    def triangles(self) -> np.ndarray:
        """``(F, 3)`` int64 vertex indices of the ``face`` element (``vertex_indices`` or
        ``vertex_index``); a ``FormatError`` if it is missing or holds non-triangles."""
        faces = self.elements.get("face")
        if faces is None:
            raise FormatError("no 'face' element", self.path)
        for name in ("vertex_indices", "vertex_index"):
            if faces.dtype.names and name in faces.dtype.names:
                break
        else:
            raise FormatError("the 'face' element has no vertex_indices list", self.path)
        column = faces[name]
        if len(column) == 0:
            return np.zeros((0, 3), np.int64)
        if column.dtype == object:
            lengths = sorted({len(v) for v in column})
            raise FormatError(f"faces are not all triangles (polygons with {lengths} vertices); "
                              "triangulate the mesh first", self.path)
        if column.ndim != 2 or (len(column) and column.shape[1] != 3):
            raise FormatError(f"faces are not triangles ({column.shape[-1] if column.ndim == 2 else 0}"
                              " vertices each); triangulate the mesh first", self.path)
        return column.reshape(-1, 3).astype(np.int64)


def _parse_header(raw: bytes, path: str) -> PlyHeader:
    if not raw:
        raise FormatError("empty file, not a PLY file", path)
    first = raw.split(b"\n", 1)[0].rstrip(b"\r")
    if first.strip() != b"ply":
        raise FormatError("not a PLY file (the first line is not 'ply')", path)
    fmt = version = None
    elements: list[PlyElement] = []
    comments: list[str] = []
    obj_info: list[str] = []
    pos = raw.index(b"\n") + 1 if b"\n" in raw else len(raw)
    number = 1
    while True:
        end = raw.find(b"\n", pos)
        if end < 0:
            if len(raw) >= MAX_HEADER_BYTES:
                raise FormatError(f"no end_header line in the first {MAX_HEADER_BYTES} bytes", path)
            raise FormatError("header has no end_header line (file truncated or not PLY)", path)
        number += 1
        try:
            line = raw[pos:end].rstrip(b"\r").decode("ascii")
        except UnicodeDecodeError:
            raise FormatError(f"header line {number} contains non-ASCII bytes", path) from None
        pos = end + 1
        words = line.split()
        if not words:
            continue
        key = words[0]
        if key == "end_header":
            if len(words) != 1:
                raise FormatError(f"header line {number}: unexpected text after end_header", path)
            break
        if key == "comment":
            comments.append(line.split(None, 1)[1] if len(words) > 1 else "")
        elif key == "obj_info":
            obj_info.append(line.split(None, 1)[1] if len(words) > 1 else "")
        elif key == "format":
            if fmt is not None:
                raise FormatError(f"header line {number}: second format line", path)
            if len(words) != 3:
                raise FormatError(f"header line {number}: expected 'format <type> 1.0'", path)
            if words[1] not in FORMATS:
                raise FormatError(f"unknown PLY format {words[1][:40]!r}; expected ascii, "
                                  "binary_little_endian or binary_big_endian", path)
            if words[2] not in ("1.0", "1"):
                raise FormatError(f"unsupported PLY version {words[2][:20]!r} (only 1.0)", path)
            fmt, version = words[1], words[2]
        elif key == "element":
            if len(words) != 3:
                raise FormatError(f"header line {number}: expected 'element <name> <count>'", path)
            if not words[2].isdigit():
                raise FormatError(f"header line {number}: element count {words[2][:30]!r} is not "
                                  "a non-negative integer", path)
            if len(words[2]) > 19:
                raise FormatError(f"header line {number}: element count {words[2][:30]}… is "
                                  "absurdly large", path)
            if any(e.name == words[1] for e in elements):
                raise FormatError(f"header declares element {words[1]!r} twice", path)
            elements.append(PlyElement(words[1], int(words[2])))
        elif key == "property":
            if not elements:
                raise FormatError(f"header line {number}: property before any element", path)
            element = elements[-1]
            if len(words) == 5 and words[1] == "list":
                count_type, item_type, name = words[2], words[3], words[4]
                for t in (count_type, item_type):
                    if t not in SCALAR_TYPES:
                        raise FormatError(f"unsupported property type {t[:30]!r} for list "
                                          f"{name!r}", path)
                if SCALAR_TYPES[count_type][0] == "f":
                    raise FormatError(f"list {name!r} has a non-integer length type "
                                      f"{count_type!r}", path)
                prop = PlyProperty(name, SCALAR_TYPES[item_type], SCALAR_TYPES[count_type])
            elif len(words) == 3 and words[1] != "list":
                if words[1] not in SCALAR_TYPES:
                    raise FormatError(f"unsupported property type {words[1][:30]!r} for property "
                                      f"{words[2]!r}", path)
                prop = PlyProperty(words[2], SCALAR_TYPES[words[1]])
            else:
                raise FormatError(f"header line {number}: malformed property line", path)
            if element.property(prop.name) is not None:
                raise FormatError(f"element {element.name!r} declares property {prop.name!r} "
                                  "twice", path)
            element.properties.append(prop)
        else:
            raise FormatError(f"header line {number}: unknown keyword {key[:30]!r}", path)
    if fmt is None:
        raise FormatError("header has no format line", path)
    for e in elements:
        if e.count and not e.properties:
            raise FormatError(f"element {e.name!r} has {e.count} rows but no properties", path)
    return PlyHeader(fmt, version, elements, comments, obj_info, pos)


def read_ply_header(path: str | os.PathLike) -> PlyHeader:
    """Parse the header of a PLY file (the body is not read)."""
    path = os.fspath(path)
    with _reading(path) as f:
        return _parse_header(f.read(MAX_HEADER_BYTES), path)


@contextlib.contextmanager
def _reading(path: str) -> Iterator[BinaryIO]:
    """Open ``path`` for reading; any failure inside becomes a one-line ``FormatError``."""
    try:
        with open(path, "rb") as f:
            yield f
    except FormatError:
        raise
    except FileNotFoundError:
        raise FormatError("file not found", path) from None
    except OSError as exc:
        raise FormatError(f"cannot read file: {exc.strerror or exc}", path) from None
    except (ValueError, TypeError, IndexError, KeyError, OverflowError, struct.error) as exc:
        raise FormatError(f"malformed PLY data ({type(exc).__name__}: {exc})", path) from None


# --------------------------------------------------------------------------------------------
# Body


def _min_row_bytes(element: PlyElement) -> int:
    """Smallest binary row: scalars plus the length prefix of every (possibly empty) list."""
    return sum(np.dtype(p.count_type if p.is_list else p.type).itemsize for p in element.properties)


def _native_dtype(element: PlyElement, lengths: dict[str, int | None]) -> np.dtype:
    fields = []
    for p in element.properties:
        if not p.is_list:
            fields.append((p.name, p.type))
        elif lengths.get(p.name) is None:
            fields.append((p.name, object))
        else:
            fields.append((p.name, p.type, (lengths[p.name],)))
    return np.dtype(fields)


def _read_binary(f, header: PlyHeader, size: int, wanted, path: str) -> dict[str, np.ndarray]:
    order = FORMATS[header.format]
    pos = header.data_offset
    available = size - pos
    minimum = sum(e.count * _min_row_bytes(e) for e in header.elements)
    if minimum > available:
        e = max(header.elements, key=lambda e: e.count * _min_row_bytes(e))
        raise FormatError(f"declared counts do not fit the file: element {e.name!r} declares "
                          f"{e.count} rows of at least {_min_row_bytes(e)} bytes, but only "
                          f"{available} bytes of data follow the header (truncated file?)", path)
    out: dict[str, np.ndarray] = {}
    for element in header.elements:
        remaining = size - pos
        if not element.has_lists:
            dtype = np.dtype([(p.name, order + p.type) for p in element.properties])
            need = element.count * dtype.itemsize
            if need > remaining:
                raise FormatError(f"file is truncated: element {element.name!r} needs {need} bytes "
                                  f"({element.count} rows × {dtype.itemsize}) but {remaining} "
                                  "remain", path)
            if wanted is None or element.name in wanted:
                array = np.empty(element.count, dtype)
                f.seek(pos)
                got = f.readinto(array.view(np.uint8)) if need else 0
                if got != need:
                    raise FormatError(f"file is truncated while reading element {element.name!r}",
                                      path)
                out[element.name] = array.astype(_native_dtype(element, {}), copy=False)
            pos += need
        else:
            f.seek(pos)
            buf = f.read(remaining)
            array, used = _binary_list_element(buf, element, order, path)
            if wanted is None or element.name in wanted:
                out[element.name] = array
            pos += used
    if pos != size:
        raise FormatError(f"{size - pos} bytes of data after the last element: the declared "
                          "counts do not match the file size", path)
    return out


def _binary_list_element(buf: bytes, element: PlyElement, order: str, path: str):
    """Parse an element with list properties; returns (array, bytes used)."""
    count, n = element.count, len(buf)
    props = element.properties
    if count == 0:
        return np.empty(0, _native_dtype(element, {})), 0

    def truncated():
        return FormatError(f"file is truncated inside element {element.name!r}", path)

    # Guess that every row has the list lengths of the first row; verify them all.
    lengths: dict[str, int] = {}
    off = 0
    for p in props:
        if p.is_list:
            size = np.dtype(p.count_type).itemsize
            if off + size > n:
                raise truncated()
            length = struct.unpack_from(order + _STRUCT[p.count_type], buf, off)[0]
            if length < 0:
                raise FormatError(f"negative list length {length} in {element.name!r}.{p.name}", path)
            lengths[p.name] = length
            off += size + length * np.dtype(p.type).itemsize
            if off > n:
                raise truncated()
        else:
            off += np.dtype(p.type).itemsize
    fields = []
    for i, p in enumerate(props):
        if p.is_list:
            fields.append((f"_n{i}", order + p.count_type))
            fields.append((f"_v{i}", order + p.type, (lengths[p.name],)))
        else:
            fields.append((f"_v{i}", order + p.type))
    guess = np.dtype(fields)
    if count * guess.itemsize <= n:
        raw = np.frombuffer(buf, guess, count)
        if all(np.all(raw[f"_n{i}"] == lengths[p.name]) for i, p in enumerate(props) if p.is_list):
            out = np.empty(count, _native_dtype(element, lengths))
            for i, p in enumerate(props):
                out[p.name] = raw[f"_v{i}"]
            return out, count * guess.itemsize

    # General case: rows of varying length, parsed one by one.
    columns = {p.name: np.empty(count, object if p.is_list else p.type) for p in props}
    off = 0
    for row in range(count):
        for p in props:
            if p.is_list:
                size = np.dtype(p.count_type).itemsize
                if off + size > n:
                    raise truncated()
                length = struct.unpack_from(order + _STRUCT[p.count_type], buf, off)[0]
                if length < 0:
                    raise FormatError(f"negative list length {length} in row {row} of "
                                      f"{element.name!r}", path)
                off += size
                nbytes = length * np.dtype(p.type).itemsize
                if off + nbytes > n:
                    raise truncated()
                columns[p.name][row] = np.frombuffer(buf, order + p.type, length, off).astype(p.type)
                off += nbytes
            else:
                size = np.dtype(p.type).itemsize
                if off + size > n:
                    raise truncated()
                columns[p.name][row] = struct.unpack_from(order + _STRUCT[p.type], buf, off)[0]
                off += size
    return _assemble(element, columns), off


def _assemble(element: PlyElement, columns: dict[str, np.ndarray]) -> np.ndarray:
    """Structured array from per-property columns; uniform lists become sub-array fields."""
    lengths: dict[str, int | None] = {}
    for p in element.properties:
        if p.is_list:
            sizes = {len(v) for v in columns[p.name]}
            lengths[p.name] = sizes.pop() if len(sizes) == 1 else None
    out = np.empty(element.count, _native_dtype(element, lengths))
    for p in element.properties:
        if p.is_list and lengths[p.name] is not None:
            out[p.name] = np.stack(list(columns[p.name])) if element.count else 0
        else:
            out[p.name] = columns[p.name]
    return out


def _ascii_values(tokens, ptype: str, what: str, path: str) -> np.ndarray:
    """Parse a sequence of ASCII tokens as PLY type ``ptype`` (numpy code)."""
    text = np.asarray(tokens, dtype=bytes) if not isinstance(tokens, np.ndarray) else tokens
    try:
        if ptype[0] == "f":
            values = text.astype(np.float64)
            with np.errstate(over="ignore", invalid="ignore"):
                return values.astype(ptype)
        values = text.astype(np.int64)
    except (ValueError, OverflowError):
        kind = "number" if ptype[0] == "f" else "integer"
        raise FormatError(f"ascii data: a value of {what} is not a valid {kind}", path) from None
    info = np.iinfo(ptype)
    if values.size and (values.min() < info.min or values.max() > info.max):
        raise FormatError(f"ascii data: a value of {what} is outside the range of {ptype} "
                          f"[{info.min}, {info.max}]", path)
    return values.astype(ptype)


def _ascii_numbers(body: bytes) -> np.ndarray | None:
    """All whitespace-separated numbers of ``body`` as float64, parsed in C; ``None`` when a
    token is not a plain number (the caller then parses token by token to report it)."""
    raw = np.frombuffer(body, np.uint8)
    space = (raw == 32) | ((raw >= 9) & (raw <= 13))
    tokens = int(np.count_nonzero(space[:-1] & ~space[1:])) + int(raw.size > 0 and not space[0])
    if tokens == 0:
        return np.empty(0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            values = np.fromstring(body, dtype=np.float64, sep=" ")
        except (ValueError, DeprecationWarning):
            return None
    return values if len(values) == tokens else None


def _from_float64(values: np.ndarray, ptype: str, what: str, path: str) -> np.ndarray:
    """Cast numbers parsed as float64 to PLY type ``ptype``, checking integers exactly."""
    if ptype[0] == "f":
        with np.errstate(over="ignore", invalid="ignore"):
            return values.astype(ptype)
    if not np.all(np.floor(values) == values):
        raise FormatError(f"ascii data: a value of {what} is not a valid integer", path)
    info = np.iinfo(ptype)
    if values.size and (values.min() < info.min or values.max() > info.max):
        raise FormatError(f"ascii data: a value of {what} is outside the range of {ptype} "
                          f"[{info.min}, {info.max}]", path)
    return values.astype(ptype)


def _ascii_table(values: np.ndarray, header: PlyHeader, needed: int, wanted, path: str):
    """Split the numbers of an ASCII body without list properties into the elements."""
    if len(values) < needed:
        raise FormatError(f"ascii data ends early: the header declares {needed} values, the file "
                          f"holds {len(values)} (truncated file?)", path)
    if len(values) > needed:
        raise FormatError(f"{len(values) - needed} values of ascii data after the last element: "
                          "the declared counts do not match the data", path)
    out: dict[str, np.ndarray] = {}
    pos = 0
    for element in header.elements:
        width, count = len(element.properties), element.count
        if wanted is None or element.name in wanted:
            block = values[pos:pos + count * width].reshape(count, width)
            array = np.empty(count, _native_dtype(element, {}))
            for i, p in enumerate(element.properties):
                array[p.name] = _from_float64(block[:, i], p.type, f"{element.name}.{p.name}", path)
            out[element.name] = array
        pos += count * width
    return out


def _read_ascii(f, header: PlyHeader, size: int, wanted, path: str) -> dict[str, np.ndarray]:
    f.seek(header.data_offset)
    body = f.read()
    # Each value needs at least one character and one separator: refuse impossible counts first.
    tokens_needed = sum(e.count * len(e.properties) for e in header.elements)
    if tokens_needed and 2 * tokens_needed - 1 > len(body):
        e = max(header.elements, key=lambda e: e.count * len(e.properties))
        raise FormatError(f"declared counts do not fit the file: element {e.name!r} declares "
                          f"{e.count} rows of at least {len(e.properties)} values, but only "
                          f"{len(body)} bytes of ascii data follow the header (truncated file?)",
                          path)
    if not any(e.has_lists for e in header.elements):
        values = _ascii_numbers(body)
        if values is not None:
            return _ascii_table(values, header, tokens_needed, wanted, path)
    tokens = body.split()
    total = len(tokens)
    pos = 0
    out: dict[str, np.ndarray] = {}
    for element in header.elements:
        props, count = element.properties, element.count
        keep = wanted is None or element.name in wanted
        if not element.has_lists:
            need = count * len(props)
            if pos + need > total:
                raise FormatError(f"ascii data ends early: element {element.name!r} needs {need} "
                                  f"values, {total - pos} remain (truncated file?)", path)
            if keep:
                block = np.array(tokens[pos:pos + need], dtype=bytes).reshape(count, len(props))
                array = np.empty(count, _native_dtype(element, {}))
                for i, p in enumerate(props):
                    array[p.name] = _ascii_values(block[:, i], p.type,
                                                  f"{element.name}.{p.name}", path)
                out[element.name] = array
            pos += need
            continue
        array, pos = _ascii_list_element(tokens, pos, element, path)
        if keep:
            out[element.name] = array
    if pos != total:
        raise FormatError(f"{total - pos} values of ascii data after the last element: the "
                          "declared counts do not match the data", path)
    return out


def _ascii_list_element(tokens: list, pos: int, element: PlyElement, path: str):
    props, count, total = element.properties, element.count, len(tokens)
    if count == 0:
        return np.empty(0, _native_dtype(element, {})), pos

    def length_at(i: int, p: PlyProperty) -> int:
        if i >= total:
            raise FormatError(f"ascii data ends early inside element {element.name!r}", path)
        try:
            length = int(tokens[i])
        except ValueError:
            raise FormatError(f"ascii data: list length of {element.name}.{p.name} is not an "
                              "integer", path) from None
        if length < 0:
            raise FormatError(f"negative list length {length} in {element.name}.{p.name}", path)
        return length

    # Fast path: all rows shaped like the first one (verified column by column).
    lengths: dict[str, int] = {}
    columns_at: list[tuple[PlyProperty, int]] = []
    width = 0
    for p in props:
        columns_at.append((p, width))
        if p.is_list:
            lengths[p.name] = length_at(pos + width, p)
            width += 1 + lengths[p.name]
        else:
            width += 1
    if pos + count * width <= total:
        block = np.array(tokens[pos:pos + count * width], dtype=bytes).reshape(count, width)
        uniform = True
        for p, col in columns_at:
            if p.is_list:
                counts = _ascii_values(block[:, col], "i8",
                                       f"the list length of {element.name}.{p.name}", path)
                if np.any(counts != lengths[p.name]):
                    uniform = False
                    break
        if uniform:
            out = np.empty(count, _native_dtype(element, lengths))
            for p, col in columns_at:
                what = f"{element.name}.{p.name}"
                if p.is_list:
                    values = block[:, col + 1:col + 1 + lengths[p.name]]
                    out[p.name] = _ascii_values(values, p.type, what, path).reshape(count, -1)
                else:
                    out[p.name] = _ascii_values(block[:, col], p.type, what, path)
            return out, pos + count * width

    # General case: row by row.
    raw: dict[str, list] = {p.name: [] for p in props}
    for _ in range(count):
        for p in props:
            if p.is_list:
                length = length_at(pos, p)
                pos += 1
                if pos + length > total:
                    raise FormatError(f"ascii data ends early inside element {element.name!r}", path)
                raw[p.name].append(tokens[pos:pos + length])
                pos += length
            else:
                if pos >= total:
                    raise FormatError(f"ascii data ends early inside element {element.name!r}", path)
                raw[p.name].append(tokens[pos])
                pos += 1
    columns = {}
    for p in props:
        what = f"{element.name}.{p.name}"
        if p.is_list:
            column = np.empty(count, object)
            for row, values in enumerate(raw[p.name]):
                column[row] = _ascii_values(np.array(values, dtype=bytes), p.type, what, path)
            columns[p.name] = column
        else:
            columns[p.name] = _ascii_values(np.array(raw[p.name], dtype=bytes), p.type, what, path)
    return _assemble(element, columns), pos


def read_ply_elements(path: str | os.PathLike, elements: Iterable[str] | None = None) -> PlyData:
    """Read a PLY file into one structured array per element.

    ``elements`` limits which elements are returned (all others are still parsed, so that the
    whole file is validated). Returns a :class:`PlyData` with ``.elements`` (name → array),
    ``.header``, ``.format`` and ``.comments``.
    """
    path = os.fspath(path)
    wanted = None if elements is None else set(elements)
    with _reading(path) as f:
        header = _parse_header(f.read(MAX_HEADER_BYTES), path)
        size = os.fstat(f.fileno()).st_size
        if header.format == "ascii":
            data = _read_ascii(f, header, size, wanted, path)
        else:
            data = _read_binary(f, header, size, wanted, path)
    return PlyData(header, data, path)


def read_ply_mesh(path: str | os.PathLike) -> TriangleMesh:
    """Read a triangle mesh (``vertex`` x/y/z and ``face`` vertex index triples) from a PLY file."""
    path = os.fspath(path)
    data = read_ply_elements(path)
    vertex = data.elements.get("vertex")
    if vertex is None or not all(n in (vertex.dtype.names or ()) for n in "xyz"):
        raise FormatError("no vertex element with x, y, z", path)
    if any(vertex.dtype[n] == object or vertex.dtype[n].shape for n in "xyz"):
        raise FormatError("vertex x/y/z must be scalar properties", path)
    xyz = np.stack([vertex[n].astype(np.float64) for n in "xyz"], axis=1)
    if not np.all(np.isfinite(xyz)):
        bad = int(np.count_nonzero(~np.isfinite(xyz).all(axis=1)))
        raise FormatError(f"{bad} vertices have NaN or Inf coordinates", path)
    faces = data.triangles()
    if faces.size == 0:
        raise FormatError("mesh has no faces", path)
    try:
        return TriangleMesh(xyz.astype(np.float32), faces)
    except FormatError as exc:
        raise exc.with_path(path) from None


# --------------------------------------------------------------------------------------------
# 3DGS layout


@dataclass
class _Layout:
    element: PlyElement
    f_rest: list[str]
    sh_degree: int
    dc_source: str            # "f_dc" or "rgb"
    has_normals: bool
    extra: list[str]


def _splat_layout(header: PlyHeader, path: str) -> _Layout:
    vertex = header.element("vertex")
    names = set(vertex.names) if vertex is not None else set()
    if header.element("chunk") is not None or any(n.startswith("packed_") for n in names):
        raise FormatError(_COMPRESSED, path)
    if vertex is None:
        raise FormatError("no 'vertex' element: not a 3DGS splat PLY", path)
    lists = [p.name for p in vertex.properties if p.is_list]
    if lists:
        raise FormatError(f"vertex property {lists[0]!r} is a list; 3DGS splat PLY files store "
                          "one scalar per property", path)
    if {"scale_0", "scale_1"} <= names and "scale_2" not in names:
        raise FormatError("2D Gaussian splats (2DGS: only scale_0 and scale_1) are not supported; "
                          "only 3D Gaussian splats with scale_0..2 can be read", path)
    missing = [n for n in _LAYOUT_SCALARS if n not in names]
    dc_source = "f_dc"
    if not all(n in names for n in _DC):
        if any(n in names for n in _DC) or not all(n in names for n in _RGB):
            missing += [n for n in _DC if n not in names]
        else:
            dc_source = "rgb"
    if missing:
        if not names & {"opacity", "scale_0", "rot_0", *_DC}:
            raise FormatError("no 3DGS splat properties (x, opacity, scale_0, rot_0, f_dc_0 …): "
                              "not a Gaussian splat PLY (a mesh or point cloud?)", path)
        raise FormatError(f"missing required vertex properties: {', '.join(missing)}", path)
    rest = [n for n in vertex.names if _F_REST.match(n)]
    expected = [f"f_rest_{i}" for i in range(len(rest))]
    if sorted(rest, key=lambda n: int(_F_REST.match(n).group(1))) != expected:
        absent = sorted(set(expected) - set(rest), key=lambda n: int(n[7:]))
        raise FormatError(f"f_rest properties are not numbered f_rest_0..f_rest_{len(rest) - 1}"
                          + (f" (missing {absent[0]})" if absent else ""), path)
    if len(rest) not in _SH_REST_COUNTS:
        raise FormatError(f"{len(rest)} f_rest properties do not match an SH degree 0..3 "
                          "(expected 0, 9, 24 or 45)", path)
    has_normals = all(n in names for n in _NORMALS)
    used = set(_LAYOUT_SCALARS) | set(rest) | set(_DC if dc_source == "f_dc" else _RGB)
    if has_normals:
        used |= set(_NORMALS)
    extra = [n for n in vertex.names if n not in used]
    return _Layout(vertex, expected, _SH_REST_COUNTS[len(rest)], dc_source, has_normals, extra)


def describe_ply(path: str | os.PathLike) -> dict:
    """Summary of a 3DGS splat PLY from its header alone (the body is not read).

    Keys: ``format``, ``count``, ``sh_degree``, ``has_normals``, ``color`` (``"f_dc"`` or
    ``"rgb"``), ``extra`` (property names kept in ``SplatCloud.extra``), ``elements``
    (name → row count) and ``comments``. Raises ``FormatError`` for non-splat or unsupported
    files, exactly as :func:`read_splat_ply` would for the header.
    """
    path = os.fspath(path)
    header = read_ply_header(path)
    layout = _splat_layout(header, path)
    return {
        "format": header.format,
        "count": layout.element.count,
        "sh_degree": layout.sh_degree,
        "has_normals": layout.has_normals,
        "color": layout.dc_source,
        "extra": list(layout.extra),
        "elements": {e.name: e.count for e in header.elements},
        "comments": list(header.comments),
    }


def _sigmoid(x: np.ndarray) -> np.ndarray:
    """Logistic function in float64 without overflow for any finite input."""
    x = np.asarray(x, dtype=np.float64)
    e = np.exp(-np.abs(x))
    return np.where(x >= 0, 1.0 / (1.0 + e), e / (1.0 + e))


def _logit(p: np.ndarray) -> np.ndarray:
    p = np.clip(np.asarray(p, dtype=np.float64), *OPACITY_CLAMP)
    return np.log(p) - np.log1p(-p)


def _rows(k: int) -> str:
    return f"{k} row{'s' if k != 1 else ''}"


def _column_gatherer(table: np.ndarray):
    """``gather(names) -> (N, len(names))`` array of those scalar fields of ``table``.

    When all fields share one type (the usual all-``float`` file) the rows are viewed as a 2-D
    array and columns are picked without per-field copies.
    """
    dtype = table.dtype
    first = dtype[0]
    if all(dtype[i] == first for i in range(len(dtype.names))) and \
            dtype.itemsize == first.itemsize * len(dtype.names):
        index = {name: i for i, name in enumerate(dtype.names)}
        flat = table.view(first).reshape(len(table), len(dtype.names))
        return lambda names: flat[:, [index[name] for name in names]]
    return lambda names: np.stack([table[name] for name in names], axis=1)


def read_splat_ply(path: str | os.PathLike) -> SplatCloud:
    """Read a 3DGS splat PLY into a :class:`SplatCloud` (activated values, (x, y, z, w)
    quaternions, coefficient-major SH). See the module docstring for the layout."""
    path = os.fspath(path)
    layout = _splat_layout(read_ply_header(path), path)
    vertex = read_ply_elements(path, elements=("vertex",))["vertex"]
    n = len(vertex)
    gather = _column_gatherer(vertex)
    dc_names = list(_DC if layout.dc_source == "f_dc" else ())
    blocks = {"means": ["x", "y", "z"], "dc": dc_names, "rest": layout.f_rest,
              "opacity": ["opacity"], "scales": ["scale_0", "scale_1", "scale_2"],
              "rot": ["rot_1", "rot_2", "rot_3", "rot_0"]}          # (w, x, y, z) → (x, y, z, w)
    block = {key: gather(names) for key, names in blocks.items() if names}
    bad = []
    for key, names in blocks.items():
        if names and block[key].dtype.kind == "f":
            counts = np.count_nonzero(~np.isfinite(block[key]), axis=0)
            bad += [(name, int(c)) for name, c in zip(names, counts) if c]
    if bad:
        listed = ", ".join(f"{name} ({_rows(k)})" for name, k in bad[:6])
        more = f" and {len(bad) - 6} more properties" if len(bad) > 6 else ""
        raise FormatError(f"{sum(k for _, k in bad)} NaN or Inf values in required properties: "
                          f"{listed}{more}", path)

    def f32(values: np.ndarray, what: str) -> np.ndarray:
        with np.errstate(over="ignore"):
            out = values.astype(np.float32, copy=False)
        if not np.all(np.isfinite(out)):
            raise FormatError(f"{int(np.count_nonzero(~np.isfinite(out)))} value(s) of {what} "
                              "exceed the float32 range", path)
        return out

    means = f32(block["means"], "x, y, z")
    k = (layout.sh_degree + 1) ** 2
    sh = np.empty((n, k, 3), np.float32)
    if layout.dc_source == "f_dc":
        sh[:, 0, :] = f32(block["dc"], "f_dc")
    else:
        for c, name in enumerate(_RGB):
            values, ptype = vertex[name].astype(np.float64), layout.element.property(name).type
            if ptype[0] in "iu":
                values /= float(np.iinfo(ptype).max)
            elif not np.all(np.isfinite(values)):
                raise FormatError(f"NaN or Inf values in {name}", path)
            sh[:, 0, c] = f32((values - 0.5) / SH_C0, name)
    if k > 1:  # channel-major (N, 3·(K−1)) → (N, K−1, 3)
        sh[:, 1:, :] = f32(block["rest"], "f_rest").reshape(n, 3, k - 1).transpose(0, 2, 1)

    opacities = _sigmoid(block["opacity"][:, 0]).astype(np.float32)
    with np.errstate(over="ignore"):
        scales64 = np.exp(block["scales"].astype(np.float64))
    scales = f32(scales64, "exp(scale_0..2) (log-scales above 88.72)")

    q = block["rot"].astype(np.float64)
    peak = np.max(np.abs(q), axis=1, keepdims=True)
    zero = peak[:, 0] == 0.0
    if zero.any():
        first = int(np.flatnonzero(zero)[0])
        raise FormatError(f"{_rows(int(zero.sum()))} (first: row {first}) have a zero rotation "
                          "quaternion (rot_0..rot_3 all 0)", path)
    q = q / peak
    q /= np.linalg.norm(q, axis=1, keepdims=True)

    extra = {}
    for name in layout.extra:
        with np.errstate(over="ignore", invalid="ignore"):
            extra[name] = vertex[name].astype(np.float32)
    return SplatCloud(means, q.astype(np.float32), scales, opacities, sh, extra=extra)


# --------------------------------------------------------------------------------------------
# Writing


def _splat_columns(cloud: SplatCloud, normals: bool) -> tuple[list[str], np.ndarray]:
    n, k = len(cloud), cloud.sh.shape[1]
    checks = {"means": cloud.means, "rotations": cloud.rotations, "scales": cloud.scales,
              "opacities": cloud.opacities, "sh": cloud.sh}
    for what, values in checks.items():
        if not np.all(np.isfinite(values)):
            raise UsageError(f"cannot write a splat PLY: {what} contain NaN or Inf values")
    zero = ~np.any(cloud.rotations != 0, axis=1)
    if zero.any():
        raise UsageError(f"cannot write a splat PLY: {int(zero.sum())} splats have a zero "
                         "rotation quaternion")
    rest = [f"f_rest_{i}" for i in range(3 * (k - 1))]
    names = ["x", "y", "z", *(_NORMALS if normals else ()), *_DC, *rest, "opacity",
             "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    taken = set(names) | set(_NORMALS)
    for name in cloud.extra:
        if not name or not (name.isascii() and name.isprintable()) or " " in name:
            raise UsageError(f"extra property name {name!r} cannot be written to PLY "
                             "(must be printable ASCII without spaces)")
        if name in taken or _F_REST.match(name) or name.startswith("packed_"):
            raise UsageError(f"extra property {name!r} clashes with a 3DGS layout property")
    names += list(cloud.extra)
    table = np.empty((n, len(names)), np.float32)
    col = 0

    def put(values) -> None:
        nonlocal col
        values = np.asarray(values).reshape(n, int(np.prod(np.shape(values)[1:])))
        table[:, col:col + values.shape[1]] = values
        col += values.shape[1]

    put(cloud.means)
    if normals:
        put(np.zeros((n, 3), np.float32))
    put(cloud.sh[:, 0, :])
    if k > 1:  # (N, K−1, 3) → channel-major (N, 3, K−1)
        put(cloud.sh[:, 1:, :].transpose(0, 2, 1).reshape(n, 3 * (k - 1)))
    put(_logit(cloud.opacities).astype(np.float32))
    put(np.log(np.maximum(cloud.scales.astype(np.float64), SCALE_FLOOR)).astype(np.float32))
    put(cloud.rotations[:, [3, 0, 1, 2]])
    for values in cloud.extra.values():
        put(values)
    return names, table


def write_splat_ply(cloud: SplatCloud, path: str | os.PathLike, *, binary: bool = True,
                    byte_order: str = "<", normals: bool = False,
                    protect: Iterable[str | os.PathLike] = ()) -> None:
    """Write ``cloud`` as a 3DGS splat PLY (pre-activation values, all ``float``).

    ``binary=False`` writes ASCII (9 significant digits: float32 values are reproduced
    exactly); ``byte_order`` is ``"<"`` (little endian, the usual) or ``">"``. ``normals=True``
    adds zero ``nx ny nz`` as the reference implementation does. Extra properties follow
    ``rot_3``. The file is written atomically; ``protect`` lists inputs it must not replace.
    """
    if byte_order not in ("<", ">"):
        raise UsageError(f"byte_order must be '<' or '>', got {byte_order!r}", path)
    if not isinstance(cloud, SplatCloud):
        raise UsageError(f"expected a SplatCloud, got {type(cloud).__name__}", path)
    try:
        names, table = _splat_columns(cloud, normals)
    except UsageError as exc:
        raise exc.with_path(path) from None
    fmt = "ascii" if not binary else ("binary_little_endian" if byte_order == "<"
                                      else "binary_big_endian")
    lines = ["ply", f"format {fmt} 1.0", f"element vertex {len(cloud)}",
             *(f"property float {name}" for name in names), "end_header"]
    with atomic_write(path, "wb", protect=tuple(protect)) as f:
        f.write(("\n".join(lines) + "\n").encode("ascii"))
        if binary:
            f.write(memoryview(table.astype(byte_order + "f4", copy=False).reshape(-1).view(np.uint8)))
        elif len(table):
            np.savetxt(f, table, fmt="%.9g", delimiter=" ")
