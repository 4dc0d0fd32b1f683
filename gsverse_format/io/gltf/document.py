"""Opening a glTF file: the container parsed, the accessors ready to be read within limits."""
from __future__ import annotations

import os
from dataclasses import dataclass

from ...codes import Code
from ...limits import MAX_DATA_URI_BYTES
from .accessors import Accessors, check_read_amplification
from .container import (DEFAULT_MAX_BYTES, GLB_MAGIC, JsonView, check_data_uri_sizes, gltf_error,
                        header_problems, json_text, parse_glb, parse_json,
                        require_json_start)

__all__ = ["Document", "load_document", "open_document"]


@dataclass
class Document:
    """A parsed glTF container: ``doc`` is the raw JSON, ``gltf`` an attribute view of it,
    ``reader`` the bounds-checked buffer and accessor access, ``glb`` whether the container is
    a GLB, ``size`` the file size in bytes."""

    doc: dict
    gltf: JsonView
    reader: Accessors
    glb: bool
    size: int


def load_document(path: str, max_bytes: int = DEFAULT_MAX_BYTES, *,
                  max_data_uri: int | None = None,
                  issues: list[tuple[Code, str, int]] | None = None) -> Document:
    """Read and parse the container (GLB or JSON) of ``path``; no header checks.

    ``max_bytes`` caps the file plus every buffer it loads later; ``max_data_uri`` caps each
    ``data:`` URI (``None``: :data:`~gsverse_format.limits.MAX_DATA_URI_BYTES`); ``issues``
    collects non-fatal GLB problems (see :func:`parse_glb`).
    Raises :class:`GltfFormatError` (or ``OSError`` when the file cannot be read).
    """
    size = os.path.getsize(path)
    if size > max_bytes:
        raise gltf_error(Code.SIZE_LIMIT_EXCEEDED,
                         f"file is {size} bytes, larger than the limit of {max_bytes} bytes")
    with open(path, "rb") as handle:  # read(n) reserves n bytes: never ask for the cap itself
        blob = handle.read(size + 1 if size < max_bytes else max_bytes + 1)
    if len(blob) > max_bytes:
        raise gltf_error(Code.SIZE_LIMIT_EXCEEDED,
                         f"file is larger than the limit of {max_bytes} bytes")
    size = len(blob)
    glb_bin = None
    glb = blob[:4] == GLB_MAGIC or os.path.splitext(path)[1].lower() == ".glb"
    raw_json = blob
    if glb:
        raw_json, glb_bin = parse_glb(blob, issues)  # glb_bin: a view of the file's bytes
    else:
        require_json_start(blob)   # a PLY given as glTF: "not a glTF file", not "not UTF-8"
    check_data_uri_sizes(raw_json, MAX_DATA_URI_BYTES if max_data_uri is None else max_data_uri)
    text = json_text(raw_json)
    del blob, raw_json  # a .gltf file's bytes are not kept while its JSON is parsed
    doc, gltf = parse_json(text)
    del text
    reader = Accessors(path, gltf, glb_bin, max_bytes - size, max_data_uri)
    return Document(doc, gltf, reader, glb, size)


def open_document(path: str, max_bytes: int = DEFAULT_MAX_BYTES) -> Document:
    """:func:`load_document` for reading: the header checked too (a missing ``asset`` or
    ``version`` is taken as 2.0, as the document decoder does), and the bytes the splat
    primitives would read (:func:`~.accessors.check_read_amplification`); raises the first
    problem."""
    document = load_document(path, max_bytes)
    problems = header_problems(document.doc, strict=False)
    if problems:
        raise problems[0]
    check_read_amplification(document.doc)
    return document
