"""Opening a glTF file: the container parsed, the accessors ready to be read within limits."""
from __future__ import annotations

import os
from dataclasses import dataclass

import pygltflib

from ...codes import Code
from .accessors import Accessors
from .container import (DEFAULT_MAX_BYTES, GLB_MAGIC, gltf_error, header_problems, parse_glb,
                        parse_json)

__all__ = ["Document", "load_document", "open_document"]


@dataclass
class Document:
    """A parsed glTF container: ``doc`` is the raw JSON, ``gltf`` the decoded document,
    ``reader`` the bounds-checked buffer and accessor access, ``glb`` whether the container is
    a GLB, ``size`` the file size in bytes."""

    doc: dict
    gltf: pygltflib.GLTF2
    reader: Accessors
    glb: bool
    size: int


def load_document(path: str, max_bytes: int = DEFAULT_MAX_BYTES, *,
                  max_data_uri: int | None = None,
                  issues: list[tuple[Code, str, int]] | None = None) -> Document:
    """Read and parse the container (GLB or JSON) of ``path``; no header checks.

    ``max_bytes`` caps the file plus every buffer it loads later; ``max_data_uri`` caps each
    ``data:`` URI; ``issues`` collects non-fatal GLB problems (see :func:`parse_glb`).
    Raises :class:`GltfFormatError` (or ``OSError`` when the file cannot be read).
    """
    size = os.path.getsize(path)
    if size > max_bytes:
        raise gltf_error(Code.SIZE_LIMIT_EXCEEDED,
                         f"file is {size} bytes, larger than the limit of {max_bytes} bytes")
    with open(path, "rb") as handle:  # read(n) reserves n bytes: never ask for the cap itself
        data = memoryview(handle.read(size + 1 if size < max_bytes else max_bytes + 1))
    if len(data) > max_bytes:
        raise gltf_error(Code.SIZE_LIMIT_EXCEEDED,
                         f"file is larger than the limit of {max_bytes} bytes")
    glb_bin = None
    glb = bytes(data[:4]) == GLB_MAGIC or os.path.splitext(path)[1].lower() == ".glb"
    if glb:
        raw_json, glb_bin = parse_glb(data, issues)
    else:
        raw_json = bytes(data)
    doc, gltf = parse_json(raw_json)
    reader = Accessors(path, gltf, glb_bin, max_bytes - len(data), max_data_uri)
    return Document(doc, gltf, reader, glb, len(data))


def open_document(path: str, max_bytes: int = DEFAULT_MAX_BYTES) -> Document:
    """:func:`load_document` for reading: the header checked too (a missing ``asset`` or
    ``version`` is taken as 2.0, as the document decoder does); raises the first problem."""
    document = load_document(path, max_bytes)
    problems = header_problems(document.doc, strict=False)
    if problems:
        raise problems[0]
    return document
