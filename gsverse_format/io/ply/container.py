"""PLY as a container: any PLY file to structured arrays and back, free of any meaning.

:func:`read_ply_elements` reads any PLY file (``ascii``, ``binary_little_endian``,
``binary_big_endian``, version 1.0) with every scalar type of the format (``char/int8``,
``uchar/uint8``, ``short/int16``, ``ushort/uint16``, ``int/int32``, ``uint/uint32``,
``float/float32``, ``double/float64``), properties in any order, ``comment`` and ``obj_info``
lines, and list properties (for example the ``face`` element of a mesh). Each element becomes
a structured numpy array in native byte order (from a binary body, a view of a copy-on-write
memory map of the file where the byte order allows: see :mod:`.binary_body`); a list property whose lists all have the same
length ``L`` becomes a sub-array field of shape ``(L,)``, otherwise an object field holding one
array per row.

The reader is strict (see :mod:`.header`, :mod:`.binary_body` and :mod:`.ascii_body`): every
problem is a one-line :class:`~gsverse_format.errors.FormatError` naming the file, declared
counts are checked against the file size before anything is allocated, and the declared counts
must account for every byte or value of the body.

:func:`write_ply` writes structured arrays the same way in any of the three formats, atomically.
"""
from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import IO, Any

import numpy as np

from ...atomic import atomic_write
from ...errors import UsageError
from .ascii_body import read_ascii_body
from .binary_body import read_binary_body
from .header import (BYTE_ORDERS, MAX_HEADER_BYTES, TYPE_NAMES, PlyHeader, PlyProperty,
                     open_ply, parse_ply_header)

__all__ = ["PlyData", "read_ply_elements", "write_ply"]


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


def read_ply_elements(path: str | os.PathLike[str],
                      elements: Iterable[str] | None = None) -> PlyData:
    """Read a PLY file into one structured array per element.

    ``elements`` limits which elements are returned (all others are still parsed, so that the
    whole file is validated). Returns a :class:`PlyData` with ``.elements`` (name → array),
    ``.header``, ``.format`` and ``.comments``.
    """
    path = os.fspath(path)
    wanted = None if elements is None else set(elements)
    with open_ply(path) as f:
        header = parse_ply_header(f.read(MAX_HEADER_BYTES), path)
        size = os.fstat(f.fileno()).st_size
        if header.format == "ascii":
            data = read_ascii_body(f, header, wanted, path)
        else:
            data = read_binary_body(f, header, size, wanted, path)
    return PlyData(header, data, path)


# --------------------------------------------------------------------------------------------
# Writing


def _plain_name(name: object) -> bool:
    return isinstance(name, str) and bool(name) and name.isascii() and name.isprintable() \
        and " " not in name


def _type_code(dtype: np.dtype, what: str) -> str:
    code = f"{dtype.kind}{dtype.itemsize}"
    if code not in TYPE_NAMES:
        raise UsageError(f"{what} has type {dtype}, which PLY cannot store")
    return code


def _properties(name: str, array: np.ndarray) -> list[PlyProperty]:
    """The PLY properties that hold the fields of ``array`` (element ``name``)."""
    if not _plain_name(name):
        raise UsageError(f"element name {name!r} cannot be written to PLY "
                         "(must be printable ASCII without spaces)")
    if not isinstance(array, np.ndarray) or array.ndim != 1 or array.dtype.names is None:
        raise UsageError(f"element {name!r} must be a 1-D structured array")
    props = []
    for field in array.dtype.names:
        what = f"property {name}.{field}"
        if not _plain_name(field):
            raise UsageError(f"property name {field!r} of element {name!r} cannot be written to "
                             "PLY (must be printable ASCII without spaces)")
        dtype = array.dtype[field]
        if dtype == object:
            rows = [np.asarray(v) for v in array[field]]
            if any(v.ndim != 1 for v in rows):
                raise UsageError(f"{what}: each row of a list property must be a 1-D array")
            types = [v.dtype for v in rows if len(v)]
            item = np.result_type(*types) if types else np.dtype("i4")
            props.append(PlyProperty(field, _type_code(item, what), "u4"))
        elif dtype.shape:
            if len(dtype.shape) != 1:
                raise UsageError(f"{what} has shape {dtype.shape}; a list is one-dimensional")
            count = "u1" if dtype.shape[0] < 256 else "u4"
            props.append(PlyProperty(field, _type_code(dtype.base, what), count))
        else:
            props.append(PlyProperty(field, _type_code(dtype, what)))
    return props


def _declaration(p: PlyProperty) -> str:
    if p.count_type is None:
        return f"property {TYPE_NAMES[p.type]} {p.name}"
    return f"property list {TYPE_NAMES[p.count_type]} {TYPE_NAMES[p.type]} {p.name}"


def _ascii_format(code: str) -> str:
    return {"f4": "%.9g", "f8": "%.17g"}.get(code, "%d")


def _write_ascii(f: IO[bytes], array: np.ndarray, props: list[PlyProperty]) -> None:
    if not len(array) or not props:
        return
    first = array.dtype[0]
    if not any(p.is_list for p in props) and all(array.dtype[i] == first for i in range(len(props))) \
            and array.dtype.itemsize == first.itemsize * len(props):
        table = array.view(first).reshape(len(array), len(props))
        np.savetxt(f, table, fmt=_ascii_format(props[0].type), delimiter=" ")
        return
    lines = []
    for row in array:
        words: list[str] = []
        for p in props:
            form = _ascii_format(p.type)
            if p.is_list:
                items = np.asarray(row[p.name]).astype(p.type)
                words += [str(len(items))] + [form % v for v in items.tolist()]
            else:
                words.append(form % row[p.name])
        lines.append(" ".join(words) + "\n")
    f.write("".join(lines).encode("ascii"))


def _write_binary(f: IO[bytes], array: np.ndarray, props: list[PlyProperty], order: str) -> None:
    if not len(array):
        return
    if not any(p.is_list for p in props):
        out = array.astype(np.dtype([(p.name, order + p.type) for p in props]), copy=False)
        f.write(np.ascontiguousarray(out).view(np.uint8).data)
        return
    if all(array.dtype[p.name] != object for p in props):  # one length per list: vectorized
        fields: list[tuple[Any, ...]] = []
        for i, p in enumerate(props):
            if p.count_type is not None:
                fields.append((f"_n{i}", order + p.count_type))
                fields.append((f"_v{i}", order + p.type, array.dtype[p.name].shape))
            else:
                fields.append((f"_v{i}", order + p.type))
        rows = np.empty(len(array), fields)
        for i, p in enumerate(props):
            if p.is_list:
                rows[f"_n{i}"] = array.dtype[p.name].shape[0]
            rows[f"_v{i}"] = array[p.name]
        f.write(rows.view(np.uint8).data)
        return
    for row in array:  # lists of varying length: row by row
        parts = []
        for p in props:
            if p.count_type is not None:
                items = np.asarray(row[p.name])
                parts.append(np.asarray(len(items), order + p.count_type).tobytes())
                parts.append(items.astype(order + p.type).tobytes())
            else:
                parts.append(np.asarray(row[p.name], order + p.type).tobytes())
        f.write(b"".join(parts))


def write_ply(path: str | os.PathLike[str], elements: Mapping[str, np.ndarray], *,
              format: str = "binary_little_endian", comments: Iterable[str] = (),
              obj_info: Iterable[str] = (), protect: Iterable[str | os.PathLike[str]] = ()) -> None:
    """Write ``elements`` (name → 1-D structured array, in order) as a PLY file.

    Scalar fields of the eight PLY types become properties; a sub-array field of shape
    ``(L,)`` becomes a list property (``uchar`` lengths below 256), an object field of 1-D
    arrays a list property with ``uint`` lengths. ``format`` is ``ascii`` (floats with 9 or
    17 significant digits: values are reproduced exactly), ``binary_little_endian`` or
    ``binary_big_endian``. The file is written atomically; ``protect`` lists inputs it must not
    replace. Anything PLY cannot hold is a :class:`UsageError` raised before writing.
    """
    try:
        if format not in BYTE_ORDERS:
            raise UsageError(f"unknown PLY format {format!r}; use one of {', '.join(BYTE_ORDERS)}")
        lines = ["ply", f"format {format} 1.0"]
        for kind, texts in (("comment", comments), ("obj_info", obj_info)):
            for text in texts:
                if "\n" in text or "\r" in text or not text.isascii():
                    raise UsageError(f"{kind} {text[:40]!r} must be one line of ASCII")
                lines.append(f"{kind} {text}".rstrip())
        properties = {}
        for name, array in elements.items():
            properties[name] = _properties(name, array)
            lines.append(f"element {name} {len(array)}")
            lines += [_declaration(p) for p in properties[name]]
        lines.append("end_header")
    except UsageError as exc:
        raise exc.with_path(path) from None
    order = BYTE_ORDERS[format]
    with atomic_write(path, "wb", protect=tuple(protect)) as f:
        f.write(("\n".join(lines) + "\n").encode("ascii"))
        for name, array in elements.items():
            if order is None:
                _write_ascii(f, array, properties[name])
            else:
                _write_binary(f, array, properties[name], order)
