"""The body of a binary PLY file (little or big endian) into one structured array per element.

Declared counts are checked against the file size *before* anything is allocated, so a header
claiming 10¹² rows costs nothing; data left over after the last element is an error.
"""
from __future__ import annotations

import struct
from collections.abc import Collection
from typing import Any, BinaryIO

import numpy as np

from ...errors import FormatError
from .header import BYTE_ORDERS, STRUCT_CODES, PlyElement, PlyHeader

__all__ = ["read_binary_body"]


def read_binary_body(f: BinaryIO, header: PlyHeader, size: int, wanted: Collection[str] | None,
                     path: str) -> dict[str, np.ndarray]:
    """Read every element of the binary body of ``f`` (``size`` bytes in all); return those
    named in ``wanted`` (all when ``None``) as native-order structured arrays."""
    order = BYTE_ORDERS[header.format] or "<"
    pos = header.data_offset
    available = size - pos
    minimum = sum(e.count * e.min_row_bytes for e in header.elements)
    if minimum > available:
        e = max(header.elements, key=lambda e: e.count * e.min_row_bytes)
        raise FormatError(f"declared counts do not fit the file: element {e.name!r} declares "
                          f"{e.count} rows of at least {e.min_row_bytes} bytes, but only "
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
                got = f.readinto(array.view(np.uint8)) if need else 0   # type: ignore[attr-defined]
                if got != need:
                    raise FormatError(f"file is truncated while reading element {element.name!r}",
                                      path)
                out[element.name] = array.astype(element.native_dtype(), copy=False)
            pos += need
        else:
            f.seek(pos)
            buf = f.read(remaining)
            array, used = _list_element(buf, element, order, path)
            if wanted is None or element.name in wanted:
                out[element.name] = array
            pos += used
    if pos != size:
        raise FormatError(f"{size - pos} bytes of data after the last element: the declared "
                          "counts do not match the file size", path)
    return out


def _list_element(buf: bytes, element: PlyElement, order: str,
                  path: str) -> tuple[np.ndarray, int]:
    """Parse an element with list properties; returns (array, bytes used)."""
    count, n = element.count, len(buf)
    props = element.properties
    if count == 0:
        return np.empty(0, element.native_dtype()), 0

    def truncated() -> FormatError:
        return FormatError(f"file is truncated inside element {element.name!r}", path)

    def list_length(count_type: str, at: int, where: str) -> tuple[int, int]:
        """The length of the list whose count (of type ``count_type``) starts at byte ``at``,
        and the size of that count in bytes."""
        size = np.dtype(count_type).itemsize
        if at + size > n:
            raise truncated()
        length = struct.unpack_from(order + STRUCT_CODES[count_type], buf, at)[0]
        if length < 0:
            raise FormatError(f"negative list length {length} in {where}", path)
        return length, size

    # Guess that every row has the list lengths of the first row; verify them all.
    lengths: dict[str, int] = {}
    off = 0
    for p in props:
        if p.count_type is not None:
            length, size = list_length(p.count_type, off, f"{element.name!r}.{p.name}")
            lengths[p.name] = length
            off += size + length * np.dtype(p.type).itemsize
            if off > n:
                raise truncated()
        else:
            off += np.dtype(p.type).itemsize
    fields: list[tuple[Any, ...]] = []
    for i, p in enumerate(props):
        if p.count_type is not None:
            fields.append((f"_n{i}", order + p.count_type))
            fields.append((f"_v{i}", order + p.type, (lengths[p.name],)))
        else:
            fields.append((f"_v{i}", order + p.type))
    guess = np.dtype(fields)
    if count * guess.itemsize <= n:
        raw = np.frombuffer(buf, guess, count)
        if all(np.all(raw[f"_n{i}"] == lengths[p.name]) for i, p in enumerate(props) if p.is_list):
            out = np.empty(count, element.native_dtype(dict(lengths)))
            for i, p in enumerate(props):
                out[p.name] = raw[f"_v{i}"]
            return out, count * guess.itemsize

    # General case: rows of varying length, parsed one by one.
    columns = {p.name: np.empty(count, object if p.is_list else p.type) for p in props}
    off = 0
    for row in range(count):
        for p in props:
            if p.count_type is not None:
                length, size = list_length(p.count_type, off, f"row {row} of {element.name!r}")
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
                columns[p.name][row] = struct.unpack_from(order + STRUCT_CODES[p.type], buf, off)[0]
                off += size
    return element.assemble(columns), off
