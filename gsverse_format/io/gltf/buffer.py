"""The binary buffer a glTF writer fills: one buffer, one aligned buffer view per accessor.

:class:`BufferBuilder` is shared by the writer (:mod:`.writer`), the compressed rest pose
(:mod:`.spz`) and the conformance suite's hand-made assets.
"""
from __future__ import annotations

import io
from typing import Any

import numpy as np

from ...rows import contiguous_rows
from .accessors import COMPONENT_DTYPES

__all__ = ["ARRAY_BUFFER", "ELEMENT_ARRAY_BUFFER", "BufferBuilder"]

#: bufferView targets.
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963


class BufferBuilder:
    """One binary buffer with one 4-byte-aligned bufferView per accessor.

    ``views`` and ``accessors`` are plain glTF JSON objects. The data are not copied when
    added: the builder keeps the arrays (converted to their component type only when the
    buffer is written, a few MiB at a time; a view of some columns of an array, such as one
    SH coefficient of every splat, through :func:`gsverse_format.rows.contiguous_rows`), so
    they must not change until then.
    :meth:`write_to` streams the buffer into a file; :meth:`finish` returns it as bytes.
    ``length`` is the buffer's length so far.
    """

    #: Bytes converted at a time when the buffer is written.
    WRITE_BLOCK = 4 << 20

    def __init__(self) -> None:
        self.length = 0
        self.views: list[dict[str, Any]] = []
        self.accessors: list[dict[str, Any]] = []
        self._parts: list[tuple[int, np.ndarray, np.dtype]] = []

    def add(self, array: Any, ctype: int, gtype: str, *, normalized: bool = False,
            target: int | None = None, minmax: bool = False) -> int:
        """Append ``array`` (first axis: elements) as an accessor of component type
        ``ctype`` and type ``gtype`` in a new buffer view; returns the accessor's index.
        ``minmax`` records the accessor's ``min``/``max`` (required for ``POSITION``)."""
        source = np.asarray(array)
        if source.ndim == 0:
            source = source.reshape(1)
        dtype = COMPONENT_DTYPES[ctype]
        count = int(source.shape[0])
        nbytes = int(source.size) * dtype.itemsize
        self.length += -self.length % 4
        view: dict[str, Any] = {"buffer": 0, "byteOffset": self.length, "byteLength": nbytes}
        if target is not None:
            view["target"] = target
        self._parts.append((self.length, source, dtype))
        self.length += nbytes
        self.views.append(view)
        acc: dict[str, Any] = {"bufferView": len(self.views) - 1, "componentType": ctype,
                               "count": count, "type": gtype}
        if normalized:
            acc["normalized"] = True
        if minmax:
            flat = np.asarray(source, dtype).reshape(count, -1)
            acc["min"] = [float(v) for v in flat.min(axis=0)]
            acc["max"] = [float(v) for v in flat.max(axis=0)]
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def add_bytes(self, data: bytes) -> int:
        """Append ``data`` as a buffer view of its own (no accessor, no target; 4-byte
        aligned); returns the buffer view's index."""
        self.length += -self.length % 4
        self.views.append({"buffer": 0, "byteOffset": self.length, "byteLength": len(data)})
        self._parts.append((self.length, np.frombuffer(data, np.uint8), np.dtype(np.uint8)))
        self.length += len(data)
        return len(self.views) - 1

    def placeholder(self, count: int, ctype: int, gtype: str, *, normalized: bool = False,
                    minmax: np.ndarray | None = None) -> int:
        """Append an accessor without a buffer view (glTF reads it as zeros; an extension
        supplies its values): ``count`` elements of ``ctype``/``gtype``; ``minmax`` the
        elements whose ``min``/``max`` it records. Returns the accessor's index."""
        acc: dict[str, Any] = {"componentType": ctype, "count": int(count), "type": gtype}
        if normalized:
            acc["normalized"] = True
        if minmax is not None:
            flat = np.asarray(minmax).reshape(int(count), -1)
            acc["min"] = [float(v) for v in flat.min(axis=0)]
            acc["max"] = [float(v) for v in flat.max(axis=0)]
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def pad(self) -> int:
        """Pad the buffer to a multiple of 4 bytes; returns its length."""
        self.length += -self.length % 4
        return self.length

    def write_to(self, handle: Any) -> int:
        """Write the buffer, padded to a multiple of 4 bytes, to the binary file ``handle``
        part by part; returns the number of bytes written."""
        written = 0
        for offset, source, dtype in self._parts:
            if offset > written:
                handle.write(b"\0" * (offset - written))
                written = offset
            rows = max(1, self.WRITE_BLOCK // max(1, source[:1].size * dtype.itemsize))
            for start in range(0, len(source), rows):
                block = (contiguous_rows(source, start, min(start + rows, len(source)))
                         if source.dtype == dtype else
                         np.ascontiguousarray(source[start:start + rows], dtype))
                handle.write(block.reshape(-1).view(np.uint8).data)
                written += block.nbytes
        end = self.pad()
        handle.write(b"\0" * (end - written))
        return end

    def finish(self) -> bytes:
        """The buffer, padded to a multiple of 4 bytes."""
        out = io.BytesIO()
        self.write_to(out)
        return out.getvalue()
