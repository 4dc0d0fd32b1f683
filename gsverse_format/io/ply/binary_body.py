"""The body of a binary PLY file (little or big endian) into one structured array per element.

The file is memory-mapped copy-on-write: an element without list properties in the machine's
byte order is returned as a structured array *over the mapping* (no copy; the pages are read
when used, and writing to the array never changes the file), in the other byte order as one
converted copy. Elements that are not asked for are checked (sizes, list lengths) but never
materialized.

Declared counts are checked against the file size *before* anything is allocated, so a header
claiming 10¹² rows costs nothing; data left over after the last element is an error. An
element whose lists vary in length holds one numpy array per row, about half a kilobyte of
memory for a few bytes of file, and is parsed row by row: more than :data:`MAX_RAGGED_ROWS`
such rows are refused before they are parsed (in an element not asked for as well).
"""
from __future__ import annotations

import mmap
import struct
from collections.abc import Collection
from typing import Any, BinaryIO

import numpy as np

from ...errors import FormatError
from ...limits import MAX_PLY_RAGGED_ROWS
from .header import BYTE_ORDERS, STRUCT_CODES, PlyElement, PlyHeader

__all__ = ["MAX_RAGGED_ROWS", "read_binary_body"]

#: Most rows of an element whose lists vary in length that are read (each becomes a Python
#: object holding a numpy array, about 0.5 KiB: at most about 512 MiB); see
#: :data:`gsverse_format.limits.MAX_PLY_RAGGED_ROWS`.
MAX_RAGGED_ROWS = MAX_PLY_RAGGED_ROWS


def _map(f: BinaryIO, size: int) -> Any:
    """The whole file as a buffer: a copy-on-write memory map, or its bytes where the file
    cannot be mapped (empty files, special files)."""
    if size:
        try:
            mapped = mmap.mmap(f.fileno(), size, access=mmap.ACCESS_COPY)
        except (OSError, ValueError):
            pass
        else:
            advice = getattr(mmap, "MADV_SEQUENTIAL", None)
            if advice is not None and hasattr(mapped, "madvise"):
                mapped.madvise(advice)
            return mapped
    f.seek(0)
    return f.read()


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
    data = _map(f, size)
    if len(data) != size:
        raise FormatError("file changed size while being read", path)
    out: dict[str, np.ndarray] = {}
    for element in header.elements:
        remaining = size - pos
        keep = wanted is None or element.name in wanted
        if not element.has_lists:
            dtype = np.dtype([(p.name, order + p.type) for p in element.properties])
            need = element.count * dtype.itemsize
            if need > remaining:
                raise FormatError(f"file is truncated: element {element.name!r} needs {need} bytes "
                                  f"({element.count} rows × {dtype.itemsize}) but {remaining} "
                                  "remain", path)
            if keep:
                array = np.frombuffer(data, dtype, element.count, pos) if need \
                    else np.empty(0, dtype)
                out[element.name] = array.astype(element.native_dtype(), copy=False)
            pos += need
        else:
            array, used = _list_element(memoryview(data)[pos:], element, order, path, keep)
            if keep:
                out[element.name] = array
            pos += used
    if pos != size:
        raise FormatError(f"{size - pos} bytes of data after the last element: the declared "
                          "counts do not match the file size", path)
    return out


def _list_element(buf: Any, element: PlyElement, order: str, path: str,
                  keep: bool = True) -> tuple[np.ndarray, int]:
    """Parse an element with list properties from the buffer ``buf`` (the file from the
    element's first byte on); returns (array, bytes used). With ``keep`` false the rows are
    only checked and an empty array is returned."""
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
            if not keep:
                return np.empty(0, element.native_dtype(dict(lengths))), count * guess.itemsize
            out = np.empty(count, element.native_dtype(dict(lengths)))
            for i, p in enumerate(props):
                out[p.name] = raw[f"_v{i}"]
            return out, count * guess.itemsize

    # General case: rows of varying length, parsed one by one.
    if count > MAX_RAGGED_ROWS:
        raise FormatError(f"element {element.name!r} has lists of varying length in {count} rows; "
                          f"at most {MAX_RAGGED_ROWS} such rows are read (each is held as a "
                          "separate array)", path)
    columns = {p.name: np.empty(count if keep else 0, object if p.is_list else p.type)
               for p in props}
    off = 0
    for row in range(count):
        for p in props:
            if p.count_type is not None:
                length, size = list_length(p.count_type, off, f"row {row} of {element.name!r}")
                off += size
                nbytes = length * np.dtype(p.type).itemsize
                if off + nbytes > n:
                    raise truncated()
                if keep:
                    columns[p.name][row] = np.frombuffer(buf, order + p.type, length,
                                                         off).astype(p.type)
                off += nbytes
            else:
                size = np.dtype(p.type).itemsize
                if off + size > n:
                    raise truncated()
                if keep:
                    columns[p.name][row] = struct.unpack_from(order + STRUCT_CODES[p.type], buf,
                                                              off)[0]
                off += size
    if not keep:
        return np.empty(0, element.native_dtype()), off
    return element.assemble(columns), off
