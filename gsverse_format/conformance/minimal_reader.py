"""The importer logic an engine plugin needs, written without any glTF library.

This is what a plugin's importer does for ``GSVERSE_gaussian_splatting_mesh_anchor``, in
the order it does it, so that it can be ported line by line to C#, C++ or GDScript:

1. parse the GLB container and its JSON;
2. find the ``KHR_gaussian_splatting`` POINTS primitive that carries the anchor extension;
3. read the rest pose (POSITION, ROTATION, SCALE, OPACITY, SH) and the anchor accessors as raw
   typed arrays, checking every accessor against its buffer view;
4. check the rules a plugin must enforce before it can remap (splat primitive mode POINTS,
   anchor mesh mode and types, at most one node instantiating the anchor mesh, profile,
   required accessors, allowed component types, counts, face index range, finite anchor data
   and rest pose, no zero ``localRotation``, no negative ``localScale``) and refuse the asset
   otherwise (:class:`Refused`);
5. dequantize (:func:`dequantize`) and renormalize quantized quaternions.

Everything is returned raw (stored dtype, component type, normalized flag), so that an
implementation under test can do its own dequantization. Only GLB files with their data in the
binary chunk are supported (which is what the conformance suite contains).
"""
from __future__ import annotations

import json
import struct
from dataclasses import dataclass, field

import numpy as np

from .glb import (BYTE, COMPONENT_DTYPES, FLOAT, SHORT, TYPE_COMPONENTS, UNSIGNED_BYTE,
                  UNSIGNED_INT, UNSIGNED_SHORT)

__all__ = ["Refused", "Raw", "RawAsset", "read_anchored_glb", "dequantize", "ANCHOR_ACCESSORS",
           "accessor_allowed"]

KHR = "KHR_gaussian_splatting"
ANCHOR = "GSVERSE_gaussian_splatting_mesh_anchor"

#: property -> (accessor type, allowed (componentType, normalized) pairs), spec §Accessor
#: component types and dequantization.
ANCHOR_ACCESSORS: dict[str, tuple[str, frozenset]] = {
    "faceIndex": ("SCALAR", frozenset({(UNSIGNED_BYTE, False), (UNSIGNED_SHORT, False),
                                       (UNSIGNED_INT, False)})),
    "barycentrics": ("VEC2", frozenset({(FLOAT, False), (UNSIGNED_BYTE, True),
                                        (UNSIGNED_SHORT, True)})),
    "normalOffset": ("SCALAR", frozenset({(FLOAT, False)})),
    "localRotation": ("VEC4", frozenset({(FLOAT, False), (BYTE, True), (SHORT, True)})),
    "localScale": ("VEC3", frozenset({(FLOAT, False), (UNSIGNED_BYTE, False),
                                      (UNSIGNED_BYTE, True), (UNSIGNED_SHORT, False),
                                      (UNSIGNED_SHORT, True)})),
    "rho": ("SCALAR", frozenset({(FLOAT, False)})),
}
_REQUIRED = {"local": ("faceIndex", "barycentrics", "normalOffset", "localRotation", "localScale"),
             "games": ("faceIndex", "barycentrics", "rho")}


class Refused(Exception):
    """The asset breaks a rule the plugin must enforce; the message says which."""


def accessor_allowed(prop: str, gtype: str, component_type: int, normalized: bool) -> bool:
    """True when the spec allows this accessor type and component type for ``prop``."""
    want, allowed = ANCHOR_ACCESSORS[prop]
    return gtype == want and (component_type, bool(normalized)) in allowed


@dataclass
class Raw:
    """An accessor's elements as stored: ``values`` (count, ncomp) in the stored dtype."""

    values: np.ndarray
    component_type: int
    normalized: bool


@dataclass
class RawAsset:
    """One anchored splat primitive, as raw arrays."""

    positions: Raw
    rotations: Raw
    scales: Raw
    opacities: Raw
    sh: list[Raw]
    anchor_vertices: np.ndarray          # (V, 3) float32
    anchor_faces: np.ndarray             # (F, 3) uint32
    profile: str
    deformation: str | None
    anchors: dict[str, Raw] = field(default_factory=dict)

    @property
    def count(self) -> int:
        return int(self.positions.values.shape[0])


def dequantize(raw: Raw) -> np.ndarray:
    """float64 values of an accessor per glTF 2.0 §3.11: FLOAT as is; normalized unsigned
    c / (2^n − 1); normalized signed max(c / (2^(n−1) − 1), −1); other integers as is."""
    v = raw.values.astype(np.float64)
    if not raw.normalized:
        return v
    top = {UNSIGNED_BYTE: 255.0, UNSIGNED_SHORT: 65535.0, BYTE: 127.0, SHORT: 32767.0}
    v = v / top[raw.component_type]
    return np.maximum(v, -1.0) if raw.component_type in (BYTE, SHORT) else v


class _Doc:
    def __init__(self, doc: dict, blob: bytes) -> None:
        self.doc, self.blob = doc, blob

    def get(self, key: str, index, what: str) -> dict:
        items = self.doc.get(key, [])
        if not isinstance(index, int) or isinstance(index, bool) or not 0 <= index < len(items):
            raise Refused(f"{what}: {key} index {index!r} out of range")
        return items[index]

    def accessor(self, index, what: str, gtypes: tuple[str, ...]) -> Raw:
        acc = self.get("accessors", index, what)
        if "sparse" in acc:
            raise Refused(f"{what}: sparse accessors are not allowed here")
        gtype, ctype = acc.get("type"), acc.get("componentType")
        if gtype not in gtypes:
            raise Refused(f"{what}: accessor type {gtype} (expected {' or '.join(gtypes)})")
        if ctype not in COMPONENT_DTYPES:
            raise Refused(f"{what}: unknown componentType {ctype}")
        normalized = bool(acc.get("normalized", False))
        if normalized and ctype in (FLOAT, UNSIGNED_INT):
            raise Refused(f"{what}: FLOAT and UNSIGNED_INT accessors cannot be normalized")
        if "bufferView" not in acc:
            raise Refused(f"{what}: accessor without bufferView")
        view = self.get("bufferViews", acc["bufferView"], what)
        if view.get("buffer", 0) != 0 or self.doc.get("buffers", [{}])[0].get("uri") is not None:
            raise Refused(f"{what}: only data in the GLB binary chunk is supported")
        dtype = COMPONENT_DTYPES[ctype]
        ncomp = TYPE_COMPONENTS[gtype]
        elem = dtype.itemsize * ncomp
        stride = view.get("byteStride", elem)
        count = acc.get("count", 0)
        offset = acc.get("byteOffset", 0)
        v_off, v_len = view.get("byteOffset", 0), view.get("byteLength", 0)
        if v_off + v_len > len(self.blob):
            raise Refused(f"{what}: bufferView runs past the end of the buffer")
        if stride < elem or offset % dtype.itemsize or stride % dtype.itemsize:
            raise Refused(f"{what}: misaligned accessor or stride")
        if count and offset + stride * (count - 1) + elem > v_len:
            raise Refused(f"{what}: accessor runs past the end of its bufferView")
        arr = np.ndarray((count, ncomp), dtype=dtype, buffer=self.blob, offset=v_off + offset,
                         strides=(stride, dtype.itemsize))
        return Raw(np.array(arr, copy=True), ctype, normalized)


def _parse_glb(data: bytes) -> tuple[dict, bytes]:
    if len(data) < 20 or data[:4] != b"glTF":
        raise Refused("not a GLB file")
    _, version, length = struct.unpack_from("<4sII", data, 0)
    if version != 2 or length != len(data):
        raise Refused("unsupported GLB version or wrong length")
    size, kind = struct.unpack_from("<II", data, 12)
    if kind != 0x4E4F534A or 20 + size > length:
        raise Refused("GLB does not start with a complete JSON chunk")
    try:
        doc = json.loads(data[20:20 + size].decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as err:
        raise Refused(f"invalid JSON chunk: {err}") from None
    blob = b""
    pos = 20 + size
    if pos + 8 <= length:
        bsize, bkind = struct.unpack_from("<II", data, pos)
        if bkind == 0x004E4942:
            if pos + 8 + bsize > length:
                raise Refused("BIN chunk runs past the end of the file")
            blob = data[pos + 8:pos + 8 + bsize]
    return doc, blob


def _anchored_primitive(doc: dict) -> tuple[dict, dict, dict]:
    found = []
    for m, mesh in enumerate(doc.get("meshes", [])):
        for prim in mesh.get("primitives", []):
            khr = (prim.get("extensions") or {}).get(KHR)
            if isinstance(khr, dict) and ANCHOR in (khr.get("extensions") or {}):
                if prim.get("mode", 4) != 0:
                    raise Refused(f"the anchored splat primitive of mesh {m} has mode "
                                  f"{prim.get('mode', 4)!r}, not POINTS (0)")
                found.append((prim, khr, khr["extensions"][ANCHOR]))
    if len(found) != 1:
        raise Refused(f"expected one anchored splat primitive, found {len(found)}")
    return found[0]


def read_anchored_glb(path) -> RawAsset:
    """Read and check the single anchored splat primitive of a GLB file (see module doc)."""
    with open(path, "rb") as handle:
        doc, blob = _parse_glb(handle.read())
    d = _Doc(doc, blob)
    prim, khr, ext = _anchored_primitive(doc)
    attrs = prim.get("attributes", {})
    for name in ("POSITION", f"{KHR}:ROTATION", f"{KHR}:SCALE", f"{KHR}:OPACITY",
                 f"{KHR}:SH_DEGREE_0_COEF_0"):
        if name not in attrs:
            raise Refused(f"splat primitive lacks {name}")
    positions = d.accessor(attrs["POSITION"], "POSITION", ("VEC3",))
    if positions.component_type != FLOAT:
        raise Refused("POSITION must be FLOAT")
    n = positions.values.shape[0]
    rotations = d.accessor(attrs[f"{KHR}:ROTATION"], "ROTATION", ("VEC4",))
    scales = d.accessor(attrs[f"{KHR}:SCALE"], "SCALE", ("VEC3",))
    opacities = d.accessor(attrs[f"{KHR}:OPACITY"], "OPACITY", ("SCALAR",))
    sh = []
    for level in range(4):
        names = [f"{KHR}:SH_DEGREE_{level}_COEF_{c}" for c in range(2 * level + 1)]
        if not all(nm in attrs for nm in names):
            break
        sh += [d.accessor(attrs[nm], nm, ("VEC3",)) for nm in names]
    for raw, what in [(rotations, "ROTATION"), (scales, "SCALE"), (opacities, "OPACITY")] + \
            [(s, "SH") for s in sh]:
        if raw.values.shape[0] != n:
            raise Refused(f"{what} count differs from POSITION count")
    for raw, what in ((positions, "POSITION"), (rotations, "ROTATION"), (scales, "SCALE")):
        if raw.component_type == FLOAT and not np.all(np.isfinite(raw.values)):
            raise Refused(f"rest pose {what} holds NaN or infinity")

    # the anchor mesh
    if not isinstance(ext, dict):
        raise Refused("anchor extension must be an object")
    mesh = d.get("meshes", ext.get("mesh"), "anchor mesh")
    users = [i for i, node in enumerate(doc.get("nodes", []))
             if isinstance(node, dict) and node.get("mesh") == ext["mesh"]]
    if len(users) > 1:
        raise Refused(f"the anchor mesh is instantiated by {len(users)} nodes; at most one is "
                      f"allowed")
    aprim_list = mesh.get("primitives", [])
    p = ext.get("primitive", 0)
    if not isinstance(p, int) or not 0 <= p < len(aprim_list):
        raise Refused(f"anchor primitive index {p!r} out of range")
    aprim = aprim_list[p]
    if aprim.get("mode", 4) != 4:
        raise Refused(f"anchor primitive has mode {aprim.get('mode')}, not TRIANGLES (4)")
    if "POSITION" not in aprim.get("attributes", {}):
        raise Refused("anchor primitive has no POSITION")
    apos = d.accessor(aprim["attributes"]["POSITION"], "anchor POSITION", ("VEC3",))
    if apos.component_type != FLOAT or apos.normalized:
        raise Refused("anchor POSITION must be FLOAT")
    nv = apos.values.shape[0]
    if "indices" in aprim:
        idx = d.accessor(aprim["indices"], "anchor indices", ("SCALAR",))
        if idx.component_type not in (UNSIGNED_BYTE, UNSIGNED_SHORT, UNSIGNED_INT) \
                or idx.normalized:
            raise Refused("anchor indices must be unsigned integers, not normalized")
        flat = idx.values[:, 0].astype(np.int64)
    else:
        flat = np.arange(nv, dtype=np.int64)
    if len(flat) % 3:
        raise Refused(f"anchor primitive has {len(flat)} indices, not a multiple of 3")
    if flat.size and int(flat.max()) >= nv:
        raise Refused(f"anchor index {int(flat.max())} out of range for {nv} vertices")
    faces = flat.reshape(-1, 3).astype(np.uint32)

    # the anchors
    profile = ext.get("profile")
    if profile not in _REQUIRED:
        raise Refused(f"unknown profile {profile!r}")
    deformation = None
    if profile == "games":
        if "deformation" in ext:
            raise Refused("deformation must not be present with the games profile")
    else:
        deformation = ext.get("deformation", "affine")
        if deformation not in ("affine", "rigid"):
            raise Refused(f"unknown deformation {deformation!r}")
    anchors: dict[str, Raw] = {}
    for prop in _REQUIRED[profile]:
        if prop not in ext:
            raise Refused(f"{profile} profile requires {prop}")
        gtype, _ = ANCHOR_ACCESSORS[prop]
        raw = d.accessor(ext[prop], prop, tuple(TYPE_COMPONENTS))
        acc = doc["accessors"][ext[prop]]
        if not accessor_allowed(prop, acc["type"], raw.component_type, raw.normalized):
            raise Refused(f"{prop}: {acc['type']} componentType {raw.component_type}"
                          f"{' normalized' if raw.normalized else ''} is not allowed")
        if raw.values.shape[0] != n:
            raise Refused(f"{prop} has {raw.values.shape[0]} elements, POSITION has {n}")
        anchors[prop] = raw
    face = anchors["faceIndex"].values[:, 0]
    if face.size and int(face.max()) >= len(faces):
        raise Refused(f"faceIndex {int(face.max())} out of range for {len(faces)} triangles")
    for name, raw in [("anchor POSITION", apos)] + list(anchors.items()):
        if raw.component_type == FLOAT and not np.all(np.isfinite(raw.values)):
            raise Refused(f"{name} holds NaN or infinity")
    if profile == "local":
        zero = np.flatnonzero(~np.any(anchors["localRotation"].values != 0, axis=1))
        if zero.size:
            raise Refused(f"localRotation of splat {int(zero[0])} has length zero")
        negative = np.flatnonzero(np.any(dequantize(anchors["localScale"]) < 0, axis=1))
        if negative.size:
            raise Refused(f"localScale of splat {int(negative[0])} is negative")
    return RawAsset(positions, rotations, scales, opacities, sh,
                    apos.values.astype(np.float32), faces, profile, deformation, anchors)
