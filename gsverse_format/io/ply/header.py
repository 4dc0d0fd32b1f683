"""The PLY header: scalar types, element and property declarations, a strict header parser.

Nothing here knows what the elements mean; :mod:`.container` reads the body that the header
describes, and the splat and mesh layers give the data a meaning.

Every problem becomes a :class:`~gsverse_format.errors.FormatError` naming the file with a
one-line cause: a missing ``ply`` magic line or ``end_header``, a non-ASCII header, unknown
keywords, formats or types, a property declared twice, an element count of more than
:data:`MAX_COUNT_DIGITS` digits, or a header longer than :data:`MAX_HEADER_BYTES`.
"""
from __future__ import annotations

import contextlib
import os
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, BinaryIO

import numpy as np

from ...errors import FormatError

__all__ = ["SCALAR_TYPES", "TYPE_NAMES", "STRUCT_CODES", "BYTE_ORDERS", "MAX_HEADER_BYTES",
           "MAX_COUNT_DIGITS", "PlyProperty", "PlyElement", "PlyHeader", "parse_ply_header",
           "read_ply_header", "open_ply"]

#: PLY type names -> numpy type codes (without byte order).
SCALAR_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
#: numpy type codes -> the PLY type names a writer uses.
TYPE_NAMES = {"i1": "char", "u1": "uchar", "i2": "short", "u2": "ushort", "i4": "int",
              "u4": "uint", "f4": "float", "f8": "double"}
#: numpy type codes -> :mod:`struct` format characters.
STRUCT_CODES = {"i1": "b", "u1": "B", "i2": "h", "u2": "H", "i4": "i", "u4": "I", "f4": "f",
                "f8": "d"}
#: PLY formats -> numpy byte order (``None`` for ascii).
BYTE_ORDERS: dict[str, str | None] = {"ascii": None, "binary_little_endian": "<",
                                      "binary_big_endian": ">"}
#: The header must end within this many bytes.
MAX_HEADER_BYTES = 1 << 20
#: Element counts with more digits than this are refused before anything else happens.
MAX_COUNT_DIGITS = 19


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

    @property
    def min_row_bytes(self) -> int:
        """Smallest binary row: scalars plus the length prefix of every (possibly empty) list."""
        return sum(np.dtype(p.count_type if p.count_type else p.type).itemsize
                   for p in self.properties)

    def native_dtype(self, lengths: dict[str, int | None] | None = None) -> np.dtype:
        """The structured dtype (native byte order) of this element's rows: a list property
        with a known common length ``L`` in ``lengths`` is a sub-array field of shape ``(L,)``,
        any other list property an object field."""
        lengths = lengths or {}
        fields: list[tuple[Any, ...]] = []
        for p in self.properties:
            if not p.is_list:
                fields.append((p.name, p.type))
            elif lengths.get(p.name) is None:
                fields.append((p.name, object))
            else:
                fields.append((p.name, p.type, (lengths[p.name],)))
        return np.dtype(fields)

    def assemble(self, columns: dict[str, np.ndarray]) -> np.ndarray:
        """Structured array from per-property columns; uniform lists become sub-array fields."""
        lengths: dict[str, int | None] = {}
        for p in self.properties:
            if p.is_list:
                sizes = {len(v) for v in columns[p.name]}
                lengths[p.name] = sizes.pop() if len(sizes) == 1 else None
        out = np.empty(self.count, self.native_dtype(lengths))
        for p in self.properties:
            if p.is_list and lengths[p.name] is not None:
                out[p.name] = np.stack(list(columns[p.name])) if self.count else 0
            else:
                out[p.name] = columns[p.name]
        return out

    # Defined last: inside the class body this name shadows the builtin ``property``.
    def property(self, name: str) -> PlyProperty | None:
        """The property called ``name``, or ``None``."""
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


def _property(words: list[str], number: int, path: str) -> PlyProperty:
    if len(words) == 5 and words[1] == "list":
        count_type, item_type, name = words[2], words[3], words[4]
        for t in (count_type, item_type):
            if t not in SCALAR_TYPES:
                raise FormatError(f"unsupported property type {t[:30]!r} for list {name!r}", path)
        if SCALAR_TYPES[count_type][0] == "f":
            raise FormatError(f"list {name!r} has a non-integer length type {count_type!r}", path)
        return PlyProperty(name, SCALAR_TYPES[item_type], SCALAR_TYPES[count_type])
    if len(words) == 3 and words[1] != "list":
        if words[1] not in SCALAR_TYPES:
            raise FormatError(f"unsupported property type {words[1][:30]!r} for property "
                              f"{words[2]!r}", path)
        return PlyProperty(words[2], SCALAR_TYPES[words[1]])
    raise FormatError(f"header line {number}: malformed property line", path)


def _element(words: list[str], number: int, elements: list[PlyElement], path: str) -> PlyElement:
    if len(words) != 3:
        raise FormatError(f"header line {number}: expected 'element <name> <count>'", path)
    if not words[2].isdigit():
        raise FormatError(f"header line {number}: element count {words[2][:30]!r} is not "
                          "a non-negative integer", path)
    if len(words[2]) > MAX_COUNT_DIGITS:
        raise FormatError(f"header line {number}: element count {words[2][:30]}… is "
                          "absurdly large", path)
    if any(e.name == words[1] for e in elements):
        raise FormatError(f"header declares element {words[1]!r} twice", path)
    return PlyElement(words[1], int(words[2]))


def _format(words: list[str], number: int, path: str) -> tuple[str, str]:
    if len(words) != 3:
        raise FormatError(f"header line {number}: expected 'format <type> 1.0'", path)
    if words[1] not in BYTE_ORDERS:
        raise FormatError(f"unknown PLY format {words[1][:40]!r}; expected ascii, "
                          "binary_little_endian or binary_big_endian", path)
    if words[2] not in ("1.0", "1"):
        raise FormatError(f"unsupported PLY version {words[2][:20]!r} (only 1.0)", path)
    return words[1], words[2]


def parse_ply_header(raw: bytes, path: str) -> PlyHeader:
    """Parse the header at the start of ``raw`` (the first bytes of the file at ``path``)."""
    if not raw:
        raise FormatError("empty file, not a PLY file", path)
    first = raw.split(b"\n", 1)[0].rstrip(b"\r")
    if first.strip() != b"ply":
        raise FormatError("not a PLY file (the first line is not 'ply')", path)
    fmt: str | None = None
    version = ""
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
            fmt, version = _format(words, number, path)
        elif key == "element":
            elements.append(_element(words, number, elements, path))
        elif key == "property":
            if not elements:
                raise FormatError(f"header line {number}: property before any element", path)
            element = elements[-1]
            prop = _property(words, number, path)
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


@contextlib.contextmanager
def open_ply(path: str) -> Iterator[BinaryIO]:
    """Open ``path`` for reading; a failure inside becomes a one-line ``FormatError``.

    Only the failures a malformed file can cause are translated (I/O errors, and the value,
    index and overflow errors of decoding numbers); anything else is a bug and propagates.
    """
    try:
        with open(path, "rb") as f:
            yield f
    except FormatError:
        raise
    except FileNotFoundError:
        raise FormatError("file not found", path) from None
    except OSError as exc:
        raise FormatError(f"cannot read file: {exc.strerror or exc}", path) from None
    except (ValueError, IndexError, OverflowError, struct.error) as exc:
        raise FormatError(f"malformed PLY data ({type(exc).__name__}: {exc})", path) from None


def read_ply_header(path: str | os.PathLike[str]) -> PlyHeader:
    """Parse the header of a PLY file (the body is not read)."""
    path = os.fspath(path)
    with open_ply(path) as f:
        return parse_ply_header(f.read(MAX_HEADER_BYTES), path)
