"""Container checks: file, GLB chunks, JSON, header, buffers and URIs, buffer views, accessors.

The parsing and every bounds check are those of the project's hardened glTF reader
(:mod:`gsverse_format.io.gltf`): its errors carry the issue code and JSON pointer reported
here, so the validator and the reader cannot disagree about what is readable. This module
adds the checks a lenient reader need not make (GLB chunk padding and order, byteStride
limits, total-offset alignment, ``count ≥ 1``) and, unlike the reader, keeps going after a
problem that affects only one buffer, view or accessor.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gsverse_format.codes import Code
from gsverse_format.io.gltf import (AccessorLayout, Accessors, Document, GltfFormatError,
                                    header_problems, load_document)

from .context import CheckContext, Options
from .issues import Issues

__all__ = ["Options", "Context", "load_container", "file_problem", "GLB_MIME", "GLTF_MIME"]

GLB_MIME = "model/gltf-binary"
GLTF_MIME = "model/gltf+json"


@dataclass
class Context(CheckContext):
    """A loaded document and what the container checks found out about its parts."""

    document: Document
    layouts: dict[int, AccessorLayout] = field(default_factory=dict)
    unsupported: dict[int, GltfFormatError] = field(default_factory=dict)
    reported: set[int] = field(default_factory=set)

    @property
    def doc(self) -> dict:
        return self.document.doc

    @property
    def reader(self) -> Accessors:
        return self.document.reader

    def add_error(self, err: GltfFormatError, fallback: Code = Code.INTERNAL_ERROR,
                  pointer: str | None = None) -> None:
        """Report a reader error under its own code and location."""
        self.issues.add(err.code or fallback, err.cause, pointer=err.pointer or pointer,
                        offset=err.offset)

    def array(self, name: str) -> list:
        value = self.doc.get(name, [])
        return value if isinstance(value, list) else []

    def accessor(self, ref: Any, pointer: str) -> AccessorLayout | None:
        """Resolve the accessor index ``ref`` found at ``pointer``.

        Returns its layout, or ``None`` after reporting why its data cannot be used (a bad
        reference here; a bad accessor once, at the accessor).
        """
        accessors = self.array("accessors")
        if not isinstance(ref, int) or isinstance(ref, bool) or not 0 <= ref < len(accessors):
            self.issues.add(Code.UNRESOLVED_REFERENCE, f"accessor index {ref!r} does not exist "
                            f"(there are {len(accessors)} accessors)", pointer=pointer)
            return None
        if ref in self.unsupported and ref not in self.reported:
            self.reported.add(ref)
            self.add_error(self.unsupported[ref])
        return self.layouts.get(ref)

    def read(self, layout: AccessorLayout, what: str) -> np.ndarray | None:
        """The elements of a checked accessor, (count, ncomp) in the stored dtype (read-only:
        possibly a view into the file's buffer)."""
        try:
            arr, _, _ = self.reader.raw(layout.accessor, what, (layout.gtype,), copy=False)
        except GltfFormatError as err:
            self.add_error(err, pointer=f"/accessors/{layout.accessor}")
            return None
        return arr

    def floats(self, layout: AccessorLayout, what: str) -> np.ndarray | None:
        """A checked accessor dequantized as glTF 2.0 prescribes: float32 (count, ncomp)
        (not renormalized; read-only, possibly a view into the file's buffer)."""
        try:
            return self.reader.floats(layout.accessor, what, (layout.gtype,),
                                      allowed=[(layout.component_type, layout.normalized)],
                                      finite=False, copy=False)
        except GltfFormatError as err:
            self.add_error(err, pointer=f"/accessors/{layout.accessor}")
            return None


def file_problem(path: str, issues: Issues, accepted: tuple[str, ...] = (".glb", ".gltf")) -> bool:
    """Report a file that cannot be validated at all; True when there is one.

    A file is accepted by its suffix (``accepted``), or when it starts with the GLB magic."""
    if not os.path.exists(path):
        issues.add(Code.IO_ERROR, "file not found")
        return True
    if os.path.isdir(path):
        issues.add(Code.IO_ERROR, "is a folder, not a file")
        return True
    ext = os.path.splitext(path)[1].lower()
    if ext not in accepted:
        try:
            with open(path, "rb") as handle:
                magic = handle.read(4)
        except OSError as err:
            issues.add(Code.IO_ERROR, f"cannot read: {err.strerror or err}")
            return True
        if magic != b"glTF":
            issues.add(Code.FILE_TYPE_UNSUPPORTED, f"unsupported file type "
                       f"{ext or '(no extension)'}: expected a .glb, .gltf, .usda, .usdc, .usd "
                       f"or .usdz file")
            return True
    return False


def load_container(path: str, options: Options, issues: Issues) -> Context | None:
    """Parse ``path`` and check everything below the meshes; ``None`` when the file could not
    be parsed (the reason is reported)."""
    if file_problem(path, issues):
        return None
    glb_issues: list[tuple[Code, str, int]] = []
    try:
        document = load_document(path, options.max_bytes,
                                   max_data_uri=options.max_data_uri_bytes, issues=glb_issues)
    except GltfFormatError as err:
        for code, message, offset in glb_issues:
            issues.add(code, message, offset=offset)
        issues.add(err.code or Code.JSON_INVALID, err.cause, pointer=err.pointer, offset=err.offset)
        return None
    except OSError as err:
        issues.add(Code.IO_ERROR, f"cannot read: {err.strerror or err}")
        return None
    except MemoryError:
        issues.add(Code.SIZE_LIMIT_EXCEEDED, "not enough memory to read the file; lower "
                   "--max-bytes to fail fast")
        return None
    for code, message, offset in glb_issues:
        issues.add(code, message, offset=offset)
    ctx = Context(path, options, issues, document)
    for problem in header_problems(document.doc, strict=True):
        ctx.add_error(problem)
    _check_buffers(ctx)
    return ctx


def _check_buffers(ctx: Context) -> None:
    reader = ctx.reader
    bad_buffers: set[int] = set()
    for i in range(len(reader.buffers_json)):
        try:
            reader.buffer(i)
        except GltfFormatError as err:
            ctx.add_error(err, pointer=f"/buffers/{i}")
            bad_buffers.add(i)
    bad_views: set[int] = set()
    raw_views = ctx.array("bufferViews")
    for v in range(len(reader.views)):
        raw = raw_views[v] if v < len(raw_views) else {}
        if raw.get("buffer") in bad_buffers:
            bad_views.add(v)
            continue
        try:
            reader.view_bounds(v)
        except GltfFormatError as err:
            ctx.add_error(err, pointer=f"/bufferViews/{v}")
            bad_views.add(v)
            continue
        stride = raw.get("byteStride")
        if stride is not None and not (4 <= stride <= 252 and stride % 4 == 0):
            ctx.issues.add(Code.BUFFER_VIEW_STRIDE_INVALID, f"bufferViews[{v}].byteStride {stride} "
                           f"must be a multiple of 4 in 4..252",
                           pointer=f"/bufferViews/{v}/byteStride")
            bad_views.add(v)
    raw_accessors = ctx.array("accessors")
    for i in range(len(reader.accessors)):
        raw = raw_accessors[i] if i < len(raw_accessors) else {}
        if raw.get("bufferView") in bad_views:
            continue
        try:
            lay = reader.layout(i)
        except GltfFormatError as err:
            if err.code == Code.ACCESSOR_UNSUPPORTED:
                ctx.unsupported[i] = err  # reported only if splat or anchor data use it
            elif err.code == Code.BUFFER_VIEW_STRIDE_INVALID:
                ctx.issues.add(err.code, f"{err.cause}", pointer=err.pointer)
            else:
                ctx.add_error(err, pointer=f"/accessors/{i}")
            continue
        pointer = f"/accessors/{i}"
        if lay.count < 1:
            ctx.issues.add(Code.ACCESSOR_INVALID, f"accessors[{i}].count must be at least 1",
                           pointer=f"{pointer}/count")
            continue
        if lay.start % lay.dtype.itemsize:
            ctx.issues.add(Code.ACCESSOR_MISALIGNED, f"accessors[{i}] starts at byte {lay.start} "
                           f"of buffers[{lay.buffer}] (bufferView.byteOffset + byteOffset), not a "
                           f"multiple of its {lay.dtype.itemsize}-byte components",
                           pointer=pointer)
            continue
        ctx.layouts[i] = lay
