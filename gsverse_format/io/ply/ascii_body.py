"""The body of an ASCII PLY file into one structured array per element.

Numbers are checked against their declared type (integers exactly, within range); declared
counts that the body cannot hold are refused before anything is allocated, and values left
over after the last element are an error. The body is parsed in C into one float64 array (8
bytes per value, list lengths included) and split into the elements from there; only a body
holding a token that is not a plain number is split into Python tokens, to name the culprit.
As in binary files, more than :data:`~.binary_body.MAX_RAGGED_ROWS` rows of lists of varying
length are refused before they are parsed.
"""
from __future__ import annotations

import warnings
from collections.abc import Collection
from typing import Any, BinaryIO

import numpy as np

from ...errors import FormatError
from .binary_body import MAX_RAGGED_ROWS
from .header import PlyElement, PlyHeader, PlyProperty

__all__ = ["read_ascii_body"]


def read_ascii_body(f: BinaryIO, header: PlyHeader, wanted: Collection[str] | None,
                    path: str) -> dict[str, np.ndarray]:
    """Read every element of the ASCII body of ``f``; return those named in ``wanted`` (all
    when ``None``) as structured arrays."""
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
    values = _numbers(body)
    if values is not None:
        if not any(e.has_lists for e in header.elements):
            return _table(values, header, tokens_needed, wanted, path)
        return _number_elements(values, header, wanted, path)
    # A token that is not a plain number: parse token by token to name it.
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
                array = np.empty(count, element.native_dtype())
                for i, p in enumerate(props):
                    array[p.name] = _values(block[:, i], p.type, f"{element.name}.{p.name}", path)
                out[element.name] = array
            pos += need
            continue
        array, pos = _list_element(tokens, pos, element, path)
        if keep:
            out[element.name] = array
    if pos != total:
        raise FormatError(f"{total - pos} values of ascii data after the last element: the "
                          "declared counts do not match the data", path)
    return out


def _values(tokens: np.ndarray, ptype: str, what: str, path: str) -> np.ndarray:
    """Parse an array of ASCII tokens (``bytes``) as PLY type ``ptype`` (numpy code)."""
    try:
        if ptype[0] == "f":
            floats = tokens.astype(np.float64)
            with np.errstate(over="ignore", invalid="ignore"):
                return floats.astype(ptype)
        values = tokens.astype(np.int64)
    except (ValueError, OverflowError):
        kind = "number" if ptype[0] == "f" else "integer"
        raise FormatError(f"ascii data: a value of {what} is not a valid {kind}", path) from None
    info = np.iinfo(ptype)
    if values.size and (values.min() < info.min or values.max() > info.max):
        raise FormatError(f"ascii data: a value of {what} is outside the range of {ptype} "
                          f"[{info.min}, {info.max}]", path)
    return values.astype(ptype)


def _numbers(body: bytes) -> np.ndarray | None:
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


def _table(values: np.ndarray, header: PlyHeader, needed: int, wanted: Collection[str] | None,
           path: str) -> dict[str, np.ndarray]:
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
            array = np.empty(count, element.native_dtype())
            for i, p in enumerate(element.properties):
                array[p.name] = _from_float64(block[:, i], p.type, f"{element.name}.{p.name}", path)
            out[element.name] = array
        pos += count * width
    return out


def _ragged_limit(element: PlyElement, path: str) -> None:
    if element.count > MAX_RAGGED_ROWS:
        raise FormatError(f"element {element.name!r} has lists of varying length in "
                          f"{element.count} rows; at most {MAX_RAGGED_ROWS} such rows are read "
                          "(each is held as a separate array)", path)


def _number_elements(values: np.ndarray, header: PlyHeader, wanted: Collection[str] | None,
                     path: str) -> dict[str, np.ndarray]:
    """Split the numbers of an ASCII body with list properties into the elements."""
    total = len(values)
    pos = 0
    out: dict[str, np.ndarray] = {}

    def ends_early() -> FormatError:
        return FormatError(f"ascii data ends early inside element {element.name!r}", path)

    def length_at(i: int, p: PlyProperty) -> int:
        if i >= total:
            raise ends_early()
        length = values[i]
        if not float(length).is_integer():
            raise FormatError(f"ascii data: list length of {element.name}.{p.name} is not an "
                              "integer", path)
        if length < 0:
            raise FormatError(f"negative list length {int(length)} in {element.name}.{p.name}",
                              path)
        return int(length)

    for element in header.elements:
        props, count = element.properties, element.count
        keep = wanted is None or element.name in wanted
        if count == 0:
            if keep:
                out[element.name] = np.empty(0, element.native_dtype())
            continue
        # Every row shaped like the first one? (verified on the length columns at once)
        lengths: dict[str, int | None] = {}
        columns_at: list[tuple[PlyProperty, int]] = []
        width = 0
        for p in props:
            columns_at.append((p, width))
            if p.is_list:
                lengths[p.name] = length_at(pos + width, p)
                width += 1 + (lengths[p.name] or 0)
            else:
                width += 1
        block = values[pos:pos + count * width].reshape(-1, width) \
            if pos + count * width <= total else None
        if block is not None and all(np.all(block[:, col] == lengths[p.name])
                                     for p, col in columns_at if p.is_list):
            if keep:
                array = np.empty(count, element.native_dtype(lengths))
                for p, col in columns_at:
                    what = f"{element.name}.{p.name}"
                    if p.is_list:
                        stop = col + 1 + (lengths[p.name] or 0)
                        array[p.name] = _from_float64(block[:, col + 1:stop], p.type, what, path)
                    else:
                        array[p.name] = _from_float64(block[:, col], p.type, what, path)
                out[element.name] = array
            pos += count * width
            continue
        _ragged_limit(element, path)
        columns = {p.name: np.empty(count if keep else 0, object if p.is_list else np.float64)
                   for p in props}
        for row in range(count):
            for p in props:
                if p.is_list:
                    length = length_at(pos, p)
                    if pos + 1 + length > total:
                        raise ends_early()
                    if keep:
                        columns[p.name][row] = values[pos + 1:pos + 1 + length]
                    pos += 1 + length
                else:
                    if pos >= total:
                        raise ends_early()
                    if keep:
                        columns[p.name][row] = values[pos]
                    pos += 1
        if keep:
            for p in props:
                what = f"{element.name}.{p.name}"
                if p.is_list:
                    for row in range(count):
                        columns[p.name][row] = _from_float64(columns[p.name][row], p.type, what,
                                                             path)
                else:
                    columns[p.name] = _from_float64(columns[p.name], p.type, what, path)
            out[element.name] = element.assemble(columns)
    if pos != total:
        raise FormatError(f"{total - pos} values of ascii data after the last element: the "
                          "declared counts do not match the data", path)
    return out


def _list_element(tokens: list[bytes], pos: int, element: PlyElement,
                  path: str) -> tuple[np.ndarray, int]:
    props, count, total = element.properties, element.count, len(tokens)
    if count == 0:
        return np.empty(0, element.native_dtype()), pos

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
    lengths: dict[str, int | None] = {}
    columns_at: list[tuple[PlyProperty, int]] = []
    width = 0
    for p in props:
        columns_at.append((p, width))
        if p.is_list:
            length = length_at(pos + width, p)
            lengths[p.name] = length
            width += 1 + length
        else:
            width += 1
    if pos + count * width <= total:
        block = np.array(tokens[pos:pos + count * width], dtype=bytes).reshape(count, width)
        uniform = True
        for p, col in columns_at:
            if p.is_list:
                counts = _values(block[:, col], "i8",
                                 f"the list length of {element.name}.{p.name}", path)
                if np.any(counts != lengths[p.name]):
                    uniform = False
                    break
        if uniform:
            out = np.empty(count, element.native_dtype(lengths))
            for p, col in columns_at:
                what = f"{element.name}.{p.name}"
                if p.is_list:
                    stop = col + 1 + (lengths[p.name] or 0)
                    out[p.name] = _values(block[:, col + 1:stop], p.type, what, path).reshape(count, -1)
                else:
                    out[p.name] = _values(block[:, col], p.type, what, path)
            return out, pos + count * width

    # General case: row by row.
    _ragged_limit(element, path)
    raw: dict[str, list[Any]] = {p.name: [] for p in props}
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
                column[row] = _values(np.array(values, dtype=bytes), p.type, what, path)
            columns[p.name] = column
        else:
            columns[p.name] = _values(np.array(raw[p.name], dtype=bytes), p.type, what, path)
    return element.assemble(columns), pos
