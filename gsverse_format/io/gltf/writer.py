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
import json
import math
import os
import struct
from typing import Any, Iterable

import numpy as np
import pygltflib

from ...version import __version__
from ...atomic import atomic_write
from ...errors import GsverseError, UsageError
from ...model import SplatAsset, SplatCloud, SplatPrimitive, TriangleMesh, check_primitive
from ...quaternion import unit_quaternions
from ...rig import AnchorRig
from ...vocabulary import frame_record
from ...vocabulary import (EXTENSION, FLOAT, KHR, NODE_VISIBILITY, SH_C0, SPZ_EXTENSION,
                           UNSIGNED_BYTE, UNSIGNED_INT, UNSIGNED_SHORT)
from .anchors_write import (ANCHOR_ENCODINGS, QUANTIZE_BITS, QUANTIZE_OPTIONS, EncodedAnchors,
                            check_encoding, check_quantize, compact_problem, encode_anchors,
                            quantize_notes, rest_pose_of, sorted_for_counts, write_anchors)
from .attributes import OPACITY, POINTS, ROTATION, SCALE, TRIANGLES, sh_attribute
from .buffer import ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER, BufferBuilder
from .container import CHUNK_BIN, CHUNK_JSON, GLB_MAGIC, glb_bytes
from .physics import write_physics
from .rig import RigOutput, write_rig
from . import spz

__all__ = ["ARRAY_BUFFER", "ELEMENT_ARRAY_BUFFER", "QUANTIZE_OPTIONS", "QUANTIZE_BITS",
           "ANCHOR_ENCODINGS", "COMPRESSIONS", "quantize_notes", "compact_problem",
           "compress_problem", "BufferBuilder", "asset_to_gltf", "gltf_to_bytes", "write_glb",
           "write_gltf"]

#: ``compress=`` choices: none, or the rest pose through ``KHR_gaussian_splatting_compression_
#: spz_2`` (spec §SPZ-compressed rest pose).
COMPRESSIONS = (None, "spz")


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


def _rest_rotation(b: BufferBuilder, rotations: np.ndarray, q: tuple[int, float] | None) -> int:
    """The rest ``ROTATION`` (unit quaternions) as FLOAT, or as the normalized signed type
    ``q`` (codes rounded, clipped to ±top; VEC4 of 8 or 4 bytes keeps the 4-byte alignment
    glTF requires of vertex attributes)."""
    if q is None:
        return b.add(rotations, FLOAT, "VEC4", target=ARRAY_BUFFER)
    ctype, top = q
    codes = np.clip(np.round(np.asarray(rotations, np.float64) * top), -top, top)
    return b.add(codes, ctype, "VEC4", normalized=True, target=ARRAY_BUFFER)


def _rest_attributes(b: BufferBuilder, c: SplatCloud,
                     rest_rotation: tuple[int, float] | None) -> dict[str, int]:
    """The rest pose's accessors; ``rest_rotation`` the quantization of ``ROTATION``, only
    where no stored anchor depends on it."""
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
    return attrs


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


def compress_problem(asset: SplatAsset, anchors: str = "explicit") -> str | None:
    """Why ``asset`` cannot be written with ``compress="spz"`` and ``anchors``, or None: stored
    anchors (explicit ``local``, or ``games``) fix the rest pose to their remap within
    10⁻⁵ D, which SPZ's quantization exceeds (spec §SPZ-compressed rest pose)."""
    for i, prim in enumerate(asset.primitives):
        a = prim.anchoring
        if a is None:
            continue
        if a.anchors.profile == "games":
            return (f"primitive {i}: games anchors are stored, and SPZ quantization would move "
                    f"the rest pose off their remap; only derived (compact) local anchors can "
                    f"be compressed")
        if anchors != "compact":
            return (f"primitive {i}: explicit anchors fix the rest pose, and SPZ quantization "
                    f"would move it off their remap; compress with compact anchors")
        problem = compact_problem(SplatAsset([prim]))
        if problem is not None:
            return problem.replace("primitive 0", f"primitive {i}", 1)
    return None


def compress_notes(asset: SplatAsset) -> list[str]:
    """What SPZ compression clamps (one line per primitive that has any): scales outside
    [e⁻¹⁰, e^5.94] and DC colours outside what a byte holds."""
    from ..spz_stream import SpzArrays, clamped_counts

    notes = []
    for i, prim in enumerate(asset.primitives):
        c = prim.splats
        counts = clamped_counts(SpzArrays(c.means, c.rotations, c.scales, c.opacities, c.sh))
        parts = [f"{n} splat(s) with a {what} outside what SPZ stores, clamped"
                 for what, n in counts.items() if n]
        if parts:
            notes.append(f"primitive {i}: " + "; ".join(parts))
    return notes


def asset_to_gltf(asset: SplatAsset, *, quantize: dict | None = None,
                  anchors: str = "explicit", compress: str | None = None) -> pygltflib.GLTF2:
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

    ``compress="spz"`` stores each splat primitive's rest pose as one SPZ stream through
    ``KHR_gaussian_splatting_compression_spz_2`` (spec §SPZ-compressed rest pose): the splats
    are encoded, decoded back, and written and derived from the decoded values; anchored
    primitives need ``anchors="compact"`` and the ``local`` profile (:func:`compress_problem`).
    Raises :class:`UsageError` for data glTF cannot hold.
    """
    gltf, buffer = _gltf_document(asset, quantize=quantize, anchors=anchors, compress=compress)
    gltf.set_binary_blob(buffer.finish())
    return gltf


def _gltf_document(asset: SplatAsset, *, quantize: dict | None = None,
                   anchors: str = "explicit", compress: str | None = None
                   ) -> tuple[pygltflib.GLTF2, BufferBuilder]:
    """:func:`asset_to_gltf` without the binary blob: the document and the builder holding
    its buffer's data (which :func:`write_gltf` streams into the file)."""
    quant = check_quantize(quantize)
    compact = check_encoding(anchors)
    if compress not in COMPRESSIONS:
        raise UsageError(f"compress must be one of none, spz, got {compress!r}")
    if compress is not None and (problem := compress_problem(asset, anchors)) is not None:
        raise UsageError(f"cannot compress: {problem}")
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
        encoded: EncodedAnchors | None = None
        c = prim.splats
        anchoring = prim.anchoring
        if anchoring is not None:
            if compact:
                c, anchoring = sorted_for_counts(prim, i)
            encoded = encode_anchors(anchoring.anchors, quant, faces=anchoring.mesh.face_count,
                                     compact=compact)
            c = rest_pose_of(c, anchoring.mesh, encoded)
        payload: bytes | None = None
        if compress == "spz":
            # everything below is written from what readers decode (spec: decode, then derive)
            payload, c = spz.compress(c)
            attrs = spz.write_placeholders(b, c)
        else:
            attrs = _rest_attributes(b, c, quant.get("ROTATION") if encoded is None
                                     or encoded.derived else None)
        khr = _khr_object(prim, c)
        if payload is not None:
            khr.setdefault("extensions", {})[SPZ_EXTENSION] = {"bufferView": b.add_bytes(payload)}
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
            khr.setdefault("extensions", {})[EXTENSION] = write_anchors(
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
    compressed = [SPZ_EXTENSION] if compress == "spz" and prims else []
    used = ([KHR] if prims else []) + ([EXTENSION] if anchor_meshes else []) + carried + \
        compressed + ([NODE_VISIBILITY] if rigs else []) + physics.used
    length = b.pad()
    gltf = pygltflib.GLTF2(
        asset=pygltflib.Asset(version="2.0", generator=f"gsverse-format {__version__}",
                              extras=_frame_extras(asset)),
        extensionsUsed=used, extensionsRequired=compressed or None, scene=0,
        extensions=physics.extensions,
        scenes=[pygltflib.Scene(nodes=list(range(len(nodes))) + rigged.roots + physics.roots)],
        nodes=nodes + rigged.nodes + physics.nodes, meshes=meshes, skins=rigged.skins,
        animations=rigged.animations,
        accessors=[pygltflib.Accessor(**{"byteOffset": 0 if "bufferView" in acc else None,
                                          "normalized": None, "min": None, "max": None, **acc})
                   for acc in b.accessors],
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
               anchors: str = "explicit", compress: str | None = None) -> None:
    """Write ``asset`` to ``path``: ``.glb`` (binary) or ``.gltf`` (JSON, embedded buffer).

    The output is written atomically; ``protect`` lists input files it must not overwrite.
    See :func:`asset_to_gltf` for ``quantize``, ``anchors`` and ``compress``. A GLB is streamed into the
    file (:func:`write_glb`): the buffer is never assembled in memory; the bytes are those
    of ``gltf_to_bytes(asset_to_gltf(asset))``.
    """
    ext = os.path.splitext(os.fspath(path))[1].lower()
    if ext not in (".glb", ".gltf"):
        raise UsageError(f"glTF output must end in .glb or .gltf, not {ext or '(nothing)'}", path)
    binary = ext == ".glb"
    try:
        gltf, buffer = _gltf_document(asset, quantize=quantize, anchors=anchors,
                                      compress=compress)
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

