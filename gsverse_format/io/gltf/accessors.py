"""glTF accessors: where their elements lie, reading them, and dequantizing them.

:class:`Accessors` adds to the buffer access of :class:`~.container.Buffers` the accessor
layer of glTF 2.0: :meth:`~Accessors.layout` checks an accessor against its buffer view and
buffer (component type, alignment, ``byteStride``, every bound) before anything is read;
:meth:`~Accessors.raw` reads the elements as stored; :meth:`~Accessors.floats` dequantizes
normalized integers as glTF 2.0 §3.11 prescribes (:func:`dequantize`). Problems are
:class:`~.container.GltfFormatError` with their issue code.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Iterable

import numpy as np

from ...codes import Code
from ...limits import MAX_READ_AMPLIFICATION, READ_AMPLIFICATION_SLACK
from ...vocabulary import (BYTE, COMPONENT_TYPE_NAMES, EXTENSION, FLOAT, KHR, SHORT,
                           SPZ_EXTENSION, UNSIGNED_BYTE, UNSIGNED_INT, UNSIGNED_SHORT, Format)
from .container import Buffers, JsonView, as_index, as_int, gltf_error, is_int

__all__ = ["COMPONENT_DTYPES", "TYPE_COMPONENTS", "MATRIX_ROWS", "QUANTIZED_POSITION_FORMATS",
           "AccessorLayout", "Accessors", "dequantize", "describe_format", "format_allowed",
           "check_read_amplification"]

#: numpy dtype of each glTF component type (little endian).
COMPONENT_DTYPES: dict[int, np.dtype] = {
    BYTE: np.dtype("<i1"), UNSIGNED_BYTE: np.dtype("<u1"), SHORT: np.dtype("<i2"),
    UNSIGNED_SHORT: np.dtype("<u2"), UNSIGNED_INT: np.dtype("<u4"), FLOAT: np.dtype("<f4")}
#: Components of each vector accessor type.
TYPE_COMPONENTS: dict[str, int] = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
#: Matrix accessor types (rows = columns); only their bounds are checked, splats never use them.
MATRIX_ROWS: dict[str, int] = {"MAT2": 2, "MAT3": 3, "MAT4": 4}
#: ``POSITION`` formats added by ``KHR_mesh_quantization``.
QUANTIZED_POSITION_FORMATS: tuple[Format, ...] = (
    (BYTE, None), (UNSIGNED_BYTE, None), (SHORT, None), (UNSIGNED_SHORT, None))
#: Largest code of each normalized integer type (glTF 2.0 §3.11).
_NORMALIZED_TOP = {UNSIGNED_BYTE: 255.0, UNSIGNED_SHORT: 65535.0, BYTE: 127.0, SHORT: 32767.0}


@dataclass
class AccessorLayout:
    """Where the elements of one accessor lie, every bound already checked.

    Element ``j`` starts at byte ``start + j * stride`` of ``buffer`` (index ``buffer``);
    it holds ``ncomp`` components of ``dtype``. ``view_offset + accessor_offset == start``.
    """

    accessor: int
    view: int
    buffer: int
    dtype: np.dtype
    ncomp: int
    count: int
    start: int
    stride: int
    component_type: int
    normalized: bool
    gtype: str


def format_allowed(layout: AccessorLayout, accessor_type: str,
                   formats: Iterable[Format]) -> bool:
    """True when ``layout`` is of ``accessor_type`` and one of the (componentType,
    normalized) ``formats`` (normalized ``None``: either)."""
    return layout.gtype == accessor_type and any(
        c == layout.component_type and (n is None or n == layout.normalized) for c, n in formats)


def describe_format(layout: AccessorLayout) -> str:
    """``VEC3 UNSIGNED_SHORT normalized`` and the like."""
    name = COMPONENT_TYPE_NAMES.get(layout.component_type, str(layout.component_type))
    return f"{layout.gtype} {name}" + (" normalized" if layout.normalized else "")


def _kind(ctype: int, normalized: bool) -> str:
    return COMPONENT_TYPE_NAMES[ctype] + (" normalized" if normalized else "")


def dequantize(arr: np.ndarray, ctype: int, normalized: bool) -> np.ndarray:
    """Stored components as float64: normalized integers as glTF 2.0 §3.11 says
    (``c / 255``, ``max(c / 127, -1)``, ...), other integers as they are."""
    values = arr.astype(np.float64)
    if normalized and ctype in _NORMALIZED_TOP:
        values /= _NORMALIZED_TOP[ctype]
        if ctype in (BYTE, SHORT):
            values = np.maximum(values, -1.0)
    return values


class Accessors(Buffers):
    """Bounds-checked access to the accessors (and buffers) of one glTF document."""

    def __init__(self, path: str, gltf: JsonView, glb_bin: memoryview | None,
                 budget: int, max_data_uri: int | None = None) -> None:
        super().__init__(path, gltf, glb_bin, budget, max_data_uri)
        self.accessors = self.array("accessors")
        self._raw: dict[int, tuple[np.ndarray, int, bool]] = {}

    def layout(self, i: int, what: str | None = None) -> AccessorLayout:
        """Check accessor ``i`` against its bufferView and buffer; where its elements lie.

        Raises :class:`GltfFormatError` (with code and pointer) for invalid component types,
        sparse or bufferView-less accessors (not supported), misaligned offsets and strides,
        and every out-of-bounds case. Nothing is read or allocated.
        """
        acc = self.accessors.item(i)
        pointer = f"/accessors/{i}"
        where = f"{what} (accessor {i})" if what else f"accessors[{i}]"
        gtype = acc.get("type")
        if gtype not in TYPE_COMPONENTS and gtype not in MATRIX_ROWS:
            raise gltf_error(Code.ACCESSOR_INVALID, f"{where} has unknown type {gtype!r}",
                             f"{pointer}/type")
        ctype = acc.get("componentType")
        if not is_int(ctype) or int(ctype) not in COMPONENT_DTYPES:
            raise gltf_error(Code.ACCESSOR_INVALID, f"{where} has unknown componentType "
                             f"{ctype!r}", f"{pointer}/componentType")
        ctype = int(ctype)
        normalized = acc.get("normalized")
        if normalized is None:
            normalized = False
        if not isinstance(normalized, bool):
            raise gltf_error(Code.GLTF_SCHEMA_VIOLATION, f"{where}.normalized must be a boolean",
                             f"{pointer}/normalized")
        if normalized and ctype in (FLOAT, UNSIGNED_INT):
            raise gltf_error(Code.ACCESSOR_INVALID, f"{where}: {COMPONENT_TYPE_NAMES[ctype]} "
                             f"accessors cannot be normalized", f"{pointer}/normalized")
        count = as_int(acc.get("count"), f"{where}.count", pointer=f"{pointer}/count",
                       code=Code.ACCESSOR_INVALID)
        if acc.get("sparse") is not None:
            raise gltf_error(Code.ACCESSOR_UNSUPPORTED, f"{where}: sparse accessors not "
                             f"supported", f"{pointer}/sparse")
        if acc.get("bufferView") is None:
            raise gltf_error(Code.ACCESSOR_UNSUPPORTED, f"{where} has no bufferView (compressed "
                             f"or placeholder data is not supported)", pointer)
        v = as_index(acc.get("bufferView"), len(self.views), f"{where}.bufferView",
                     f"{pointer}/bufferView")
        view = self.views.item(v)
        dtype = COMPONENT_DTYPES[ctype]
        if gtype in MATRIX_ROWS:  # every column starts 4-byte aligned (glTF 2.0 §3.6.2.4)
            rows = MATRIX_ROWS[gtype]
            ncomp = rows * rows
            elem = rows * (-(-rows * dtype.itemsize // 4) * 4)
        else:
            ncomp = TYPE_COMPONENTS[gtype]
            elem = dtype.itemsize * ncomp
        acc_offset = as_int(acc.get("byteOffset"), f"{where}.byteOffset", default=0,
                            pointer=f"{pointer}/byteOffset")
        if acc_offset % dtype.itemsize:
            raise gltf_error(Code.ACCESSOR_MISALIGNED, f"{where}.byteOffset {acc_offset} is not "
                             f"a multiple of the component size {dtype.itemsize}",
                             f"{pointer}/byteOffset")
        b, view_offset, view_length = self.view_bounds(v)
        vpointer = f"/bufferViews/{v}/byteStride"
        stride = elem if view.get("byteStride") is None else as_int(
            view.get("byteStride"), f"bufferViews[{v}].byteStride", minimum=1, pointer=vpointer,
            code=Code.BUFFER_VIEW_STRIDE_INVALID)
        if stride < elem:
            raise gltf_error(Code.BUFFER_VIEW_STRIDE_INVALID, f"bufferViews[{v}].byteStride "
                             f"{stride} is smaller than the {elem}-byte elements of {where}",
                             vpointer)
        if stride % dtype.itemsize:
            raise gltf_error(Code.BUFFER_VIEW_STRIDE_INVALID, f"bufferViews[{v}].byteStride "
                             f"{stride} is not a multiple of the component size of {where}",
                             vpointer)
        if count:
            need = acc_offset + stride * (count - 1) + elem
            if need > view_length:
                raise gltf_error(Code.ACCESSOR_OUT_OF_BOUNDS, f"{where} out of bounds: needs "
                                 f"{need} bytes of bufferViews[{v}] which has {view_length}",
                                 pointer)
        return AccessorLayout(i, v, b, dtype, ncomp, count, view_offset + acc_offset, stride,
                              ctype, normalized, gtype)

    def raw(self, i: Any, what: str, gtypes: tuple[str, ...], *, copy: bool = True,
            code: Code = Code.ACCESSOR_INVALID) -> tuple[np.ndarray, int, bool]:
        """(elements (count, ncomp) in the stored dtype, componentType, normalized).

        ``copy=False`` returns a read-only view into the buffer where the data are tightly
        packed (checks that only read the values avoid a copy). An accessor type not in
        ``gtypes`` is reported under ``code``.
        """
        i = as_index(i, len(self.accessors), f"{what}: accessor")
        acc = self.accessors.item(i)
        where = f"{what} (accessor {i})"
        gtype = acc.get("type")
        if gtype not in gtypes:
            raise gltf_error(code, f"{where} has type {gtype!r}, expected {' or '.join(gtypes)}",
                             f"/accessors/{i}/type")
        if i in self._raw:
            return self._raw[i]
        lay = self.layout(i, what)
        if lay.count:
            arr = np.ndarray((lay.count, lay.ncomp), dtype=lay.dtype,
                             buffer=self.buffer(lay.buffer), offset=lay.start,
                             strides=(lay.stride, lay.dtype.itemsize))
            if not copy and arr.flags.c_contiguous and arr.flags.aligned:
                return arr, lay.component_type, lay.normalized
            arr = np.array(arr, copy=True)
        else:
            arr = np.zeros((0, lay.ncomp), lay.dtype)
        self._raw[i] = (arr, lay.component_type, lay.normalized)
        return self._raw[i]

    def floats(self, i: Any, what: str, gtypes: tuple[str, ...],
               allowed: Iterable[Format] | None = None, renormalize: bool = False,
               finite: bool = True, copy: bool = True,
               code: Code = Code.ACCESSOR_INVALID) -> np.ndarray:
        """Accessor ``i`` as float32 (count, ncomp), dequantized per glTF 2.0 §3.11.

        ``allowed`` lists (componentType, normalized) pairs (normalized ``None``: either);
        default: any type but UNSIGNED_INT. ``renormalize`` rescales integer-quantized rows to
        unit length (quaternions). ``finite`` rejects FLOAT data holding NaN or infinity.
        ``copy=False`` may return FLOAT data as a read-only view into the buffer. A type or
        format that is not allowed is reported under ``code``.
        """
        arr, ctype, normalized = self.raw(i, what, gtypes, copy=copy, code=code)
        if allowed is None:
            ok = ctype != UNSIGNED_INT
        else:
            ok = any(c == ctype and (n is None or n == normalized) for c, n in allowed)
        if not ok:
            raise gltf_error(code, f"{what} (accessor {i}) has unsupported component type "
                             f"{_kind(ctype, normalized)}", f"/accessors/{i}/componentType")
        if ctype == FLOAT:
            if finite and not np.isfinite(arr).all():
                bad = int(np.count_nonzero(~np.isfinite(arr).all(axis=1)))
                raise gltf_error(Code.NON_FINITE_VALUE, f"{what} (accessor {i}): {bad} of "
                                 f"{len(arr)} elements hold NaN or infinity", f"/accessors/{i}")
            return arr
        values = dequantize(arr, ctype, normalized)
        if renormalize:
            norm = np.linalg.norm(values, axis=1, keepdims=True)
            values = np.where(norm > 0, values / np.where(norm > 0, norm, 1.0), values)
        return values.astype(np.float32)

    def integers(self, i: Any, what: str, code: Code = Code.ACCESSOR_INVALID) -> np.ndarray:
        """SCALAR unsigned-integer (not normalized) accessor as uint32 (count,)."""
        arr, ctype, normalized = self.raw(i, what, ("SCALAR",), code=code)
        if ctype not in (UNSIGNED_BYTE, UNSIGNED_SHORT, UNSIGNED_INT) or normalized:
            raise gltf_error(code, f"{what} (accessor {i}) must be UNSIGNED_BYTE, UNSIGNED_SHORT "
                             f"or UNSIGNED_INT (not normalized), got {_kind(ctype, normalized)}",
                             f"/accessors/{i}/componentType")
        return arr[:, 0].astype(np.uint32)


def _declared_bytes(accessors: list, ref: Any) -> int:
    """``count`` times the element size an accessor declares (0 when it cannot be told: its
    own checks report that when it is read)."""
    if not is_int(ref) or not 0 <= ref < len(accessors) or not isinstance(accessors[ref], dict):
        return 0
    acc = accessors[ref]
    count, ctype, gtype = acc.get("count"), acc.get("componentType"), acc.get("type")
    if not is_int(count) or count <= 0 or not is_int(ctype) or ctype not in COMPONENT_DTYPES:
        return 0
    ncomp = TYPE_COMPONENTS.get(gtype) or MATRIX_ROWS.get(gtype, 0) ** 2
    return int(count) * ncomp * COMPONENT_DTYPES[int(ctype)].itemsize


def declared_bytes(doc: dict, ref: Any) -> int:
    """The bytes accessor ``ref`` of ``doc`` declares (0 when it cannot be told)."""
    accessors = doc.get("accessors")
    return _declared_bytes(accessors, ref) if isinstance(accessors, list) else 0


def buffer_bytes(doc: dict) -> int:
    """The bytes ``doc``'s buffers declare (valid ``byteLength`` values only)."""
    buffers = doc.get("buffers")
    return sum(int(b["byteLength"]) for b in (buffers if isinstance(buffers, list) else [])
               if isinstance(b, dict) and is_int(b.get("byteLength")) and b["byteLength"] > 0)


def _placeholder(accessors: list, ref: Any) -> bool:
    """True for a valid reference to an accessor without ``bufferView``."""
    return (is_int(ref) and 0 <= ref < len(accessors) and isinstance(accessors[ref], dict)
            and accessors[ref].get("bufferView") is None)


def check_read_amplification(doc: dict) -> None:
    """Raise ``SIZE_LIMIT_EXCEEDED`` when reading every splat primitive would decode far more
    bytes than the buffers hold: primitives sharing accessors (legal glTF) would make a small
    file expand into gigabytes of splats. The accessor bytes all ``KHR_gaussian_splatting``
    primitives and their anchor extensions refer to, an accessor counted once per use, may
    be at most :data:`~gsverse_format.limits.MAX_READ_AMPLIFICATION` times the declared
    buffer bytes plus :data:`~gsverse_format.limits.READ_AMPLIFICATION_SLACK`. Declared
    sizes only, checked on the raw JSON before anything is read (a ``byteLength`` larger
    than the data is refused when the buffer loads)."""
    accessors = doc.get("accessors")
    meshes = doc.get("meshes")
    if not isinstance(accessors, list) or not isinstance(meshes, list):
        return
    held = buffer_bytes(doc)
    allowed = MAX_READ_AMPLIFICATION * held + READ_AMPLIFICATION_SLACK
    total = 0
    for m, mesh in enumerate(meshes):
        prims = mesh.get("primitives") if isinstance(mesh, dict) else None
        for p, prim in enumerate(prims if isinstance(prims, list) else []):
            if not isinstance(prim, dict) or not isinstance(prim.get("extensions"), dict):
                continue
            khr = prim["extensions"].get(KHR)
            if not isinstance(khr, dict):
                continue
            attrs = prim.get("attributes")
            refs = list(attrs.values()) if isinstance(attrs, dict) else []
            nested = khr.get("extensions")
            if isinstance(nested, dict) and SPZ_EXTENSION in nested:
                # placeholders: what the stream decodes to is bounded by its own rule
                # (limits.MAX_SPZ_AMPLIFICATION), checked before it inflates
                refs = [r for r in refs if not _placeholder(accessors, r)]
            anchor = nested.get(EXTENSION) if isinstance(nested, dict) else None
            if isinstance(anchor, dict):
                refs += [v for k, v in anchor.items() if k not in ("mesh", "primitive")]
            total += sum(_declared_bytes(accessors, r) for r in refs)
            if total > allowed:
                raise gltf_error(Code.SIZE_LIMIT_EXCEEDED, f"the splat primitives up to "
                                 f"meshes[{m}].primitives[{p}] would read {total} bytes of "
                                 f"accessors, more than {MAX_READ_AMPLIFICATION} times the "
                                 f"{held} bytes of the buffers (accessors shared by many "
                                 f"primitives)", f"/meshes/{m}/primitives/{p}")
