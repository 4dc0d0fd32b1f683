"""Writing splat assets as glTF 2.0 (``.gltf``) and GLB (``.glb``).

The rest pose of every splat primitive is plain ``KHR_gaussian_splatting``; the anchoring of
anchored primitives is the ``GSVERSE_gaussian_splatting_mesh_anchor`` extension nested in the
``KHR_gaussian_splatting`` extension object (``spec/README.md``).

Layout written (one glTF mesh per splat primitive, then one per anchor mesh):

* splat mesh: one ``POINTS`` primitive with ``POSITION`` (FLOAT VEC3, min/max),
  ``KHR_gaussian_splatting:ROTATION`` (FLOAT VEC4, unit quaternion x, y, z, w),
  ``:SCALE`` (FLOAT VEC3, linear), ``:OPACITY`` (FLOAT SCALAR, linear [0, 1]),
  ``:SH_DEGREE_l_COEF_n`` (FLOAT VEC3, model coefficient ``k = l² + n``) and a ``COLOR_0``
  fallback (UNSIGNED_BYTE normalized VEC4, linear RGB + opacity); instantiated by one node;
* anchor mesh: one ``TRIANGLES`` primitive (FLOAT ``POSITION`` + indices), instantiated by no
  node; several anchored primitives share it when they share the :class:`TriangleMesh` object;
* anchor accessors: referenced only from the extension JSON; their buffer views have no target;
  with ``anchors="compact"`` (extension 1.2) ``faceCounts`` (one count per triangle, the splats
  grouped by face) and, for ``local``, nothing else (derived from the rest pose by readers).

All data live in one buffer: the GLB ``BIN`` chunk, or a base64 ``data:`` URI for ``.gltf``.
:class:`BufferBuilder` (one buffer, one aligned buffer view per accessor, plain JSON objects)
is also what the conformance suite builds its hand-made assets with.
"""
from __future__ import annotations

import base64
import io
import json
import math
import os
import struct
from dataclasses import dataclass
from typing import Any, Iterable

import numpy as np
import pygltflib

from ...version import __version__
from ...atomic import atomic_write
from ...errors import GsverseError, UsageError
from ...model import (Anchoring, GamesAnchors, LocalAnchors, SplatAsset, SplatCloud,
                      SplatPrimitive, TriangleMesh, check_primitive)
from ...anchors_derive import degenerate_splats
from ...quaternion import unit_quaternions
from ...rig import AnchorRig
from ...vocabulary import ANCHOR_ENCODINGS as VOCAB_ENCODINGS
from ...vocabulary import frame_record
from ...vocabulary import (BYTE, EXTENSION, FLOAT, KHR, NODE_VISIBILITY, SH_C0, SHORT,
                           UNSIGNED_BYTE, UNSIGNED_INT, UNSIGNED_SHORT)
from .accessors import COMPONENT_DTYPES
from .container import CHUNK_BIN, CHUNK_JSON, GLB_MAGIC, glb_bytes
from .physics import write_physics
from .rig import RigOutput, write_rig
from .reader import OPACITY, POINTS, ROTATION, SCALE, TRIANGLES, sh_attribute

__all__ = ["ARRAY_BUFFER", "ELEMENT_ARRAY_BUFFER", "QUANTIZE_OPTIONS", "QUANTIZE_BITS",
           "ANCHOR_ENCODINGS", "quantize_notes", "BufferBuilder",
           "asset_to_gltf", "gltf_to_bytes", "write_glb", "write_gltf"]

#: bufferView targets.
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963

#: Component-type choices for ``quantize=``: property -> {option: (componentType, scale)}.
#: ``ROTATION`` is the rest pose's ``KHR_gaussian_splatting:ROTATION`` (the normalized types
#: that extension allows), quantized only where no stored anchor depends on it: plain
#: primitives and derived ``local`` anchors (compact). Explicit anchors fix the rest pose to
#: their remap (spec §Rest-pose consistency), which a quantized ``ROTATION`` would miss by a
#: quantization step. (``OPACITY``, SCALAR, gains nothing: glTF aligns every vertex attribute
#: element to 4 bytes, the size of a FLOAT.)
QUANTIZE_OPTIONS: dict[str, dict[str, tuple[int, float] | None]] = {
    "barycentrics": {"float": None, "unsigned_short": (UNSIGNED_SHORT, 65535.0),
                     "unsigned_byte": (UNSIGNED_BYTE, 255.0)},
    "localRotation": {"float": None, "short": (SHORT, 32767.0), "byte": (BYTE, 127.0)},
    "ROTATION": {"float": None, "short": (SHORT, 32767.0), "byte": (BYTE, 127.0)},
}
#: ``gsverse-convert --quantize BITS``: the ``quantize=`` choices of each bit depth.
QUANTIZE_BITS: dict[int, dict[str, str]] = {
    16: {"barycentrics": "unsigned_short", "localRotation": "short", "ROTATION": "short"},
    8: {"barycentrics": "unsigned_byte", "localRotation": "byte", "ROTATION": "byte"},
}
#: ``anchors=`` choices: the version 1.1 layout, or ``faceCounts`` + derived ``local`` anchors.
ANCHOR_ENCODINGS = VOCAB_ENCODINGS

def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB decoding of values in [0, 1]."""
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _fallback_color(cloud: SplatCloud) -> np.ndarray:
    """``COLOR_0`` fallback, (N, 4) uint8: linear RGB of the SH DC term and opacity as alpha."""
    rgb = np.clip(0.5 + SH_C0 * cloud.sh[:, 0, :].astype(np.float64), 0.0, 1.0)
    if cloud.color_space == "srgb_rec709_display":
        rgb = _srgb_to_linear(rgb)
    alpha = np.clip(cloud.opacities.astype(np.float64), 0.0, 1.0)[:, None]
    return np.round(np.concatenate([rgb, alpha], axis=1) * 255.0).astype(np.uint8)


class BufferBuilder:
    """One binary buffer with one 4-byte-aligned bufferView per accessor.

    ``views`` and ``accessors`` are plain glTF JSON objects. The data are not copied when
    added: the builder keeps the arrays (converted to their component type only when the
    buffer is written, a few MiB at a time), so they must not change until then.
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
                block = np.ascontiguousarray(source[start:start + rows], dtype)
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


def _check_quantize(quantize: dict | None) -> dict[str, tuple[int, float] | None]:
    chosen: dict[str, tuple[int, float] | None] = {}
    for key, value in (quantize or {}).items():
        if key not in QUANTIZE_OPTIONS:
            raise UsageError(f"cannot quantize {key!r}; choose from {', '.join(QUANTIZE_OPTIONS)}")
        if value not in QUANTIZE_OPTIONS[key]:
            raise UsageError(f"quantize[{key!r}] must be one of "
                             f"{', '.join(QUANTIZE_OPTIONS[key])}, got {value!r}")
        chosen[key] = QUANTIZE_OPTIONS[key][value]
    return chosen


def _check_encoding(anchors: str) -> bool:
    """True for ``compact`` anchors; :class:`UsageError` for an unknown encoding."""
    if anchors not in ANCHOR_ENCODINGS:
        raise UsageError(f"anchors must be one of {', '.join(ANCHOR_ENCODINGS)}, got {anchors!r}")
    return anchors == "compact"


@dataclass
class _EncodedAnchors:
    """Anchor data as the writer stores them: normalized-integer codes for the quantized
    properties (None: stored as FLOAT), and ``anchors`` as a reader dequantizes them.
    ``counts`` (compact): splats per face, the splats grouped by face in face order;
    ``derived`` (compact ``local``): only the faces are stored, the rest is derived from the
    rest pose (spec §Derived `local` anchors)."""

    anchors: LocalAnchors | GamesAnchors
    barycentrics: tuple[np.ndarray, int] | None = None
    local_rotation: tuple[np.ndarray, int] | None = None
    counts: np.ndarray | None = None
    derived: bool = False


def _bary_in_unit_range(bary: np.ndarray) -> bool:
    return bool(np.all((bary >= 0.0) & (bary <= 1.0)))


def _encode_anchors(anchors: LocalAnchors | GamesAnchors,
                    quant: dict[str, tuple[int, float] | None], *, faces: int = 0,
                    compact: bool = False) -> _EncodedAnchors:
    """Quantize the anchors as ``quant`` asks; dequantize the codes as glTF 2.0 §3.11 says
    (``c / 255``, ``max(c / 127, -1)``, ...; quaternions renormalized, as readers do).
    ``compact`` anchors (sorted by face already) store ``faces`` counts, and ``local`` ones
    nothing else: derived anchors have no quantization error."""
    counts = None
    if compact:
        counts = np.bincount(anchors.face_index.astype(np.int64), minlength=faces)
        if isinstance(anchors, LocalAnchors):
            return _EncodedAnchors(anchors, counts=counts, derived=True)
    out = _EncodedAnchors(anchors, counts=counts)
    bary = anchors.barycentrics
    q = quant.get("barycentrics")
    if q is not None and _bary_in_unit_range(bary):
        ctype, top = q
        codes = np.round(bary.astype(np.float64) * top)
        out.barycentrics = (codes, ctype)
        bary = (codes.astype(np.float32) / np.float32(top)).astype(np.float32)
    if isinstance(anchors, LocalAnchors):
        rot = unit_quaternions(anchors.local_rotation)
        q = quant.get("localRotation")
        if q is not None:
            ctype, top = q
            codes = np.clip(np.round(rot.astype(np.float64) * top), -top, top)
            out.local_rotation = (codes, ctype)
            rot = unit_quaternions(np.maximum(codes / top, -1.0).astype(np.float32))
        out.anchors = LocalAnchors(anchors.face_index, bary, anchors.normal_offset, rot,
                                   anchors.local_scale, anchors.deformation)
    else:
        out.anchors = GamesAnchors(anchors.face_index, bary, anchors.rho)
    return out


def _sorted_for_counts(prim: SplatPrimitive, i: int) -> tuple[SplatCloud, Anchoring]:
    """The splats and anchors of ``prim`` grouped by face in face order (stable), as
    ``faceCounts`` stores them; :class:`UsageError` where ``local`` anchors could not be
    derived back (splats on faces degenerate at rest)."""
    anchoring = prim.anchoring
    assert anchoring is not None
    anchors, c = anchoring.anchors, prim.splats
    face = anchors.face_index.astype(np.int64)
    if face.size > 1 and bool(np.any(face[1:] < face[:-1])):
        order = np.argsort(face, kind="stable")
        c = c.subset(order)
        anchors = anchors.subset(order)
    problem = _compact_problem(Anchoring(anchoring.mesh, anchors))
    if problem is not None:
        raise UsageError(f"primitive {i}: {problem}: write explicit anchors")
    return c, Anchoring(anchoring.mesh, anchors)


def _compact_problem(anchoring: Anchoring) -> str | None:
    """Why ``anchoring`` cannot be stored compactly, or None: derived ``local`` anchors need
    every splat on a face regular at rest; ``games`` ones only gain ``faceCounts``."""
    a = anchoring.anchors
    if not isinstance(a, LocalAnchors):
        return None
    bad = degenerate_splats(anchoring.mesh, a.face_index)
    return None if not len(bad) else (
        f"{len(bad)} splat(s) are bound to triangles degenerate at rest (face "
        f"{int(a.face_index[bad[0]])}); compact anchors cannot derive them")


def compact_problem(asset: SplatAsset) -> str | None:
    """Why ``asset`` cannot be written with ``anchors="compact"`` (one line, the first
    primitive that cannot), or None; the rule :func:`asset_to_gltf` refuses by."""
    problems = (f"primitive {i}: {p}" for i, prim in enumerate(asset.primitives)
                if prim.anchoring is not None and (p := _compact_problem(prim.anchoring)))
    return next(problems, None)


def quantize_notes(asset: SplatAsset, quantize: dict | None,
                   anchors: str = "explicit") -> list[str]:
    """What ``quantize`` leaves as FLOAT when ``asset`` is written (one line each): explicit
    barycentrics outside [0, 1], which no normalized unsigned type holds."""
    quant = _check_quantize(quantize)
    if quant.get("barycentrics") is None:
        return []
    compact = _check_encoding(anchors)
    notes = []
    for i, prim in enumerate(asset.primitives):
        a = prim.anchoring
        if a is None or (compact and isinstance(a.anchors, LocalAnchors)):
            continue
        bary = a.anchors.barycentrics
        if not _bary_in_unit_range(bary):
            outside = int(np.count_nonzero(np.any((bary < 0.0) | (bary > 1.0), axis=1)))
            notes.append(f"primitive {i}: barycentrics stay FLOAT: {outside} of {len(bary)} "
                         f"splats have barycentrics outside [0, 1] (--anchors compact stores "
                         f"none for the local profile)")
    return notes


def _rest_pose_of(c: SplatCloud, mesh: TriangleMesh, encoded: _EncodedAnchors) -> SplatCloud:
    """The splats with the rest pose remapped from the anchors as stored (spec §Rest-pose
    consistency), for quantized anchors; otherwise (derived anchors included: they come from
    the rest pose) the splats unchanged."""
    if encoded.barycentrics is None and encoded.local_rotation is None:
        return c
    from ...remapping.reference import remap

    rest = remap(Anchoring(mesh, encoded.anchors))
    return SplatCloud(rest.means.astype(np.float32), rest.rotations.astype(np.float32),
                      rest.scales.astype(np.float32), c.opacities, c.sh, c.color_space,
                      dict(c.extra))


def _index_type(largest: int) -> int:
    """The smallest unsigned component type holding ``largest``."""
    return UNSIGNED_BYTE if largest < 256 else UNSIGNED_SHORT if largest < 65536 else UNSIGNED_INT


def _write_anchors(b: BufferBuilder, faces: int, encoded: _EncodedAnchors,
                   splats: SplatCloud, mesh_index: int, scale_accessor: int) -> dict[str, Any]:
    anchors = encoded.anchors
    obj: dict[str, Any] = {"mesh": mesh_index, "primitive": 0, "profile": anchors.profile}
    if isinstance(anchors, LocalAnchors):
        obj["deformation"] = anchors.deformation
    if encoded.counts is not None:
        largest = int(encoded.counts.max()) if encoded.counts.size else 0
        obj["faceCounts"] = b.add(encoded.counts, _index_type(largest), "SCALAR")
    else:
        obj["faceIndex"] = b.add(anchors.face_index, _index_type(max(faces - 1, 0)), "SCALAR")
    if encoded.derived:
        return obj
    if encoded.barycentrics is not None:
        codes, ctype = encoded.barycentrics
        obj["barycentrics"] = b.add(codes, ctype, "VEC2", normalized=True)
    else:
        obj["barycentrics"] = b.add(anchors.barycentrics, FLOAT, "VEC2")
    if isinstance(anchors, LocalAnchors):
        obj["normalOffset"] = b.add(anchors.normal_offset, FLOAT, "SCALAR")
        if encoded.local_rotation is not None:
            codes, ctype = encoded.local_rotation
            obj["localRotation"] = b.add(codes, ctype, "VEC4", normalized=True)
        else:
            obj["localRotation"] = b.add(anchors.local_rotation, FLOAT, "VEC4")
        if np.array_equal(anchors.local_scale, splats.scales):
            obj["localScale"] = scale_accessor
        else:
            obj["localScale"] = b.add(anchors.local_scale, FLOAT, "VEC3")
    else:
        obj["rho"] = b.add(anchors.rho, FLOAT, "SCALAR")
    return obj


def _rest_rotation(b: BufferBuilder, rotations: np.ndarray, q: tuple[int, float] | None) -> int:
    """The rest ``ROTATION`` (unit quaternions) as FLOAT, or as the normalized signed type
    ``q`` (codes rounded, clipped to ±top; VEC4 of 8 or 4 bytes keeps the 4-byte alignment
    glTF requires of vertex attributes)."""
    if q is None:
        return b.add(rotations, FLOAT, "VEC4", target=ARRAY_BUFFER)
    ctype, top = q
    codes = np.clip(np.round(np.asarray(rotations, np.float64) * top), -top, top)
    return b.add(codes, ctype, "VEC4", normalized=True, target=ARRAY_BUFFER)


def _khr_object(prim: SplatPrimitive, c: SplatCloud) -> dict[str, Any]:
    """The ``KHR_gaussian_splatting`` object of ``prim`` (without the anchor extension): its
    kernel, colour space, projection and sorting method, and the nested extensions it
    carries (copied as they are: :meth:`~gsverse_format.model.KhrProperties.carry_problem`
    is checked first)."""
    props = prim.khr
    khr: dict[str, Any] = {"kernel": props.kernel, "colorSpace": c.color_space,
                           "projection": props.projection, "sortingMethod": props.sorting_method}
    if props.extensions:
        khr["extensions"] = {name: json.loads(json.dumps(obj))
                             for name, obj in props.extensions.items()}
    return khr


def _collider_meshes(b: BufferBuilder, asset: SplatAsset, anchor_mesh_index: dict[int, int],
                     meshes: list[pygltflib.Mesh | None]) -> tuple[list[pygltflib.Mesh],
                                                                    dict[int, int]]:
    """The colliders of the written anchor meshes, appended after them: each a mesh drawn by
    no node, marked ``extras.gsverse = {"collider": kind, "for": <anchor mesh index>}``
    (spec/README.md §Colliders); and ``id(anchor mesh)`` -> the index its (first) collider
    mesh gets."""
    out: list[pygltflib.Mesh] = []
    index: dict[int, int] = {}
    for collider in asset.colliders:
        m = anchor_mesh_index.get(id(collider.anchor))
        if m is None:
            continue
        index.setdefault(id(collider.anchor), len(meshes) + len(out))
        mesh = collider.mesh
        pos = b.add(mesh.vertices, FLOAT, "VEC3", target=ARRAY_BUFFER, minmax=True)
        itype = UNSIGNED_SHORT if len(mesh.vertices) < 65535 else UNSIGNED_INT
        idx = b.add(mesh.faces.reshape(-1), itype, "SCALAR", target=ELEMENT_ARRAY_BUFFER)
        anchor = meshes[m]
        name = f"{anchor.name if anchor is not None else 'anchor mesh'} {collider.kind} collider"
        out.append(pygltflib.Mesh(primitives=[pygltflib.Primitive(
            attributes=pygltflib.Attributes(POSITION=pos), indices=idx, mode=TRIANGLES)],
            weights=None, name=name,
            extras={"gsverse": {"collider": collider.kind, "for": m}}))
    return out, index


def asset_to_gltf(asset: SplatAsset, *, quantize: dict | None = None,
                  anchors: str = "explicit") -> pygltflib.GLTF2:
    """The glTF document for ``asset``; its binary buffer is set as the binary blob.

    ``quantize`` optionally stores anchor accessors as normalized integers:
    ``{"barycentrics": "unsigned_short" | "unsigned_byte",
    "localRotation": "short" | "byte"}``. Barycentrics stay FLOAT for a primitive whose
    barycentrics are not all in [0, 1]. Quantizing moves the anchored splats: the stored rest
    pose is then the remap of the anchors as stored (dequantized), so that the asset stays
    self-consistent (spec §Rest-pose consistency); the move is at most about half a
    quantization step of each property (for 8-bit barycentrics, 1/510 of a triangle edge).
    ``quantize`` also takes the rest pose's ``ROTATION`` (see
    :data:`QUANTIZE_OPTIONS`; :data:`QUANTIZE_BITS` per bit depth).

    ``anchors="compact"`` (extension version 1.2) stores ``faceCounts`` instead of
    ``faceIndex``, the splats of each anchored primitive grouped by face in face order (a
    stable sort when they are not), and for the ``local`` profile no other anchor data: readers
    derive them from the rest pose (spec §Derived `local` anchors). ``"explicit"`` (default)
    is the version 1.1 layout.
    Raises :class:`UsageError` for data glTF cannot hold.
    """
    gltf, buffer = _gltf_document(asset, quantize=quantize, anchors=anchors)
    gltf.set_binary_blob(buffer.finish())
    return gltf


def _gltf_document(asset: SplatAsset, *, quantize: dict | None = None,
                   anchors: str = "explicit") -> tuple[pygltflib.GLTF2, BufferBuilder]:
    """:func:`asset_to_gltf` without the binary blob: the document and the builder holding
    its buffer's data (which :func:`write_gltf` streams into the file)."""
    quant = _check_quantize(quantize)
    compact = _check_encoding(anchors)
    prims = list(asset.primitives)
    for i, prim in enumerate(prims):
        check_primitive(i, prim)
        problem = prim.khr.carry_problem() if EXTENSION not in prim.khr.extensions else \
            f"nested extension {EXTENSION} is written from the anchoring, not copied"
        if problem is not None:
            raise UsageError(f"primitive {i}: {problem}")

    # Anchor meshes are appended after the splat meshes, one per distinct TriangleMesh object.
    anchor_mesh_index: dict[int, int] = {}
    anchor_meshes: list[TriangleMesh] = []
    for prim in prims:
        if prim.anchoring is not None and id(prim.anchoring.mesh) not in anchor_mesh_index:
            anchor_mesh_index[id(prim.anchoring.mesh)] = len(prims) + len(anchor_meshes)
            anchor_meshes.append(prim.anchoring.mesh)

    b = BufferBuilder()
    meshes: list[pygltflib.Mesh | None] = [None] * (len(prims) + len(anchor_meshes))
    nodes: list[pygltflib.Node] = []
    rigs: list[tuple[AnchorRig, pygltflib.Mesh, int]] = []
    for i, prim in enumerate(prims):
        encoded: _EncodedAnchors | None = None
        c = prim.splats
        anchoring = prim.anchoring
        if anchoring is not None:
            if compact:
                c, anchoring = _sorted_for_counts(prim, i)
            encoded = _encode_anchors(anchoring.anchors, quant, faces=anchoring.mesh.face_count,
                                      compact=compact)
            c = _rest_pose_of(c, anchoring.mesh, encoded)
        # the rest ROTATION is quantized only where no stored anchor depends on it
        rest_rotation = quant.get("ROTATION") if encoded is None or encoded.derived else None
        attrs: dict[str, int] = {"POSITION": b.add(c.means, FLOAT, "VEC3", target=ARRAY_BUFFER,
                                                   minmax=True)}
        attrs[ROTATION] = _rest_rotation(b, unit_quaternions(c.rotations), rest_rotation)
        attrs[SCALE] = b.add(c.scales, FLOAT, "VEC3", target=ARRAY_BUFFER)
        attrs[OPACITY] = b.add(c.opacities, FLOAT, "SCALAR", target=ARRAY_BUFFER)
        for k in range(c.sh.shape[1]):
            degree = math.isqrt(k)
            attrs[sh_attribute(degree, k - degree * degree)] = b.add(
                c.sh[:, k, :], FLOAT, "VEC3", target=ARRAY_BUFFER)
        attrs["COLOR_0"] = b.add(_fallback_color(c), UNSIGNED_BYTE, "VEC4", normalized=True,
                                 target=ARRAY_BUFFER)
        khr = _khr_object(prim, c)
        if anchoring is not None and encoded is not None:
            mesh = anchoring.mesh
            m = anchor_mesh_index[id(mesh)]
            if meshes[m] is None:
                pos = b.add(mesh.vertices, FLOAT, "VEC3", target=ARRAY_BUFFER, minmax=True)
                itype = UNSIGNED_SHORT if len(mesh.vertices) < 65535 else UNSIGNED_INT
                idx = b.add(mesh.faces.reshape(-1), itype, "SCALAR", target=ELEMENT_ARRAY_BUFFER)
                anchor_prim = pygltflib.Primitive(attributes=pygltflib.Attributes(POSITION=pos),
                                                  indices=idx, mode=TRIANGLES)
                meshes[m] = pygltflib.Mesh(primitives=[anchor_prim], weights=None,
                    name=f"{prim.name} anchor mesh" if prim.name else "anchor mesh")
                if mesh.rig is not None:
                    rigs.append((mesh.rig, meshes[m], m))
            khr.setdefault("extensions", {})[EXTENSION] = _write_anchors(
                b, mesh.face_count, encoded, c, m, attrs[SCALE])
        primitive = pygltflib.Primitive(attributes=pygltflib.Attributes(**attrs),
                                        mode=POINTS, extensions={KHR: khr})
        meshes[i] = pygltflib.Mesh(primitives=[primitive], name=prim.name, weights=None)
        nodes.append(pygltflib.Node(mesh=i, name=prim.name, children=None))
    collider_meshes, collider_index = _collider_meshes(b, asset, anchor_mesh_index, meshes)
    meshes.extend(collider_meshes)
    rigged = RigOutput()
    for rig, gmesh, m in rigs:
        write_rig(b.add, rig, gmesh, m, len(nodes) + len(rigged.nodes), rigged)
    physics = write_physics(asset, nodes, collider_index, len(nodes) + len(rigged.nodes))

    carried = sorted({name for prim in prims for name in prim.khr.extensions})
    used = ([KHR] if prims else []) + ([EXTENSION] if anchor_meshes else []) + carried + \
        ([NODE_VISIBILITY] if rigs else []) + physics.used
    length = b.pad()
    gltf = pygltflib.GLTF2(
        asset=pygltflib.Asset(version="2.0", generator=f"gsverse-format {__version__}",
                              extras=_frame_extras(asset)),
        extensionsUsed=used, scene=0, extensions=physics.extensions,
        scenes=[pygltflib.Scene(nodes=list(range(len(nodes))) + rigged.roots + physics.roots)],
        nodes=nodes + rigged.nodes + physics.nodes, meshes=meshes, skins=rigged.skins,
        animations=rigged.animations,
        accessors=[pygltflib.Accessor(**{"byteOffset": 0, "normalized": None, "min": None,
                                          "max": None, **acc}) for acc in b.accessors],
        bufferViews=[pygltflib.BufferView(**view) for view in b.views],
        buffers=[pygltflib.Buffer(byteLength=length)] if length else [])
    return gltf, b


def _frame_extras(asset: SplatAsset) -> dict[str, Any] | None:
    """``asset.extras`` recording the frame of an asset not in glTF's (``frame_record``)."""
    record = frame_record(asset.frame)
    return {"gsverse": record} if record is not None else None


def _gltf_json(gltf: pygltflib.GLTF2, *, data_uri: bool) -> bytes:
    doc = json.loads(gltf.to_json())
    if data_uri and doc.get("buffers"):
        payload = base64.b64encode(gltf.binary_blob() or b"").decode("ascii")
        doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + payload
    return json.dumps(doc, separators=(",", ":"), allow_nan=False).encode("utf-8")


def write_glb(handle: Any, json_chunk: bytes, buffer: BufferBuilder) -> int:
    """Write a GLB 2.0 container to the binary file ``handle``: the header, ``json_chunk``
    (padded with spaces) and, when the buffer is not empty, a ``BIN`` chunk streamed from
    ``buffer`` (padded with zeros); byte for byte what :func:`glb_bytes` builds in memory.
    Returns the number of bytes written."""
    text_pad = -len(json_chunk) % 4
    text_length = len(json_chunk) + text_pad
    bin_length = buffer.pad()
    total = 12 + 8 + text_length + (8 + bin_length if bin_length else 0)
    handle.write(struct.pack("<4sII", GLB_MAGIC, 2, total))
    handle.write(struct.pack("<II", text_length, CHUNK_JSON))
    handle.write(json_chunk)
    handle.write(b" " * text_pad)
    if bin_length:
        handle.write(struct.pack("<II", bin_length, CHUNK_BIN))
        buffer.write_to(handle)
    return total


def gltf_to_bytes(gltf: pygltflib.GLTF2, *, binary: bool = True) -> bytes:
    """Serialize a document from :func:`asset_to_gltf`: GLB bytes, or ``.gltf`` JSON bytes
    with the buffer embedded as a base64 ``data:`` URI."""
    if not binary:
        return _gltf_json(gltf, data_uri=True)
    return glb_bytes(_gltf_json(gltf, data_uri=False), gltf.binary_blob() or None)


def write_gltf(asset: SplatAsset, path: str | os.PathLike, *,
               protect: Iterable[str | os.PathLike] = (), quantize: dict | None = None,
               anchors: str = "explicit") -> None:
    """Write ``asset`` to ``path``: ``.glb`` (binary) or ``.gltf`` (JSON, embedded buffer).

    The output is written atomically; ``protect`` lists input files it must not overwrite.
    See :func:`asset_to_gltf` for ``quantize`` and ``anchors``. A GLB is streamed into the
    file (:func:`write_glb`): the buffer is never assembled in memory; the bytes are those
    of ``gltf_to_bytes(asset_to_gltf(asset))``.
    """
    ext = os.path.splitext(os.fspath(path))[1].lower()
    if ext not in (".glb", ".gltf"):
        raise UsageError(f"glTF output must end in .glb or .gltf, not {ext or '(nothing)'}", path)
    binary = ext == ".glb"
    try:
        gltf, buffer = _gltf_document(asset, quantize=quantize, anchors=anchors)
        if not binary:
            gltf.set_binary_blob(buffer.finish())
        text = _gltf_json(gltf, data_uri=not binary)
    except GsverseError as err:
        raise err.with_path(path) from None
    del gltf
    with atomic_write(path, "wb", protect=tuple(protect)) as handle:
        if binary:
            write_glb(handle, text, buffer)
        else:
            handle.write(text)

