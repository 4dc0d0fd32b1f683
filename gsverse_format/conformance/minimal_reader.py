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
5. dequantize (:func:`dequantize`) and renormalize quantized quaternions;
6. (version 1.2) take the face of each splat from ``faceCounts`` when the asset stores counts
   instead of ``faceIndex`` (:func:`face_index`), and derive the ``local`` anchors from the
   rest pose when the asset stores none (:func:`derive_local`), refusing splats on faces
   degenerate at rest.

(Version 1.2) A rest pose stored as an SPZ stream (``KHR_gaussian_splatting_compression_spz_2``,
spec §SPZ-compressed rest pose) is inflated with the standard library's zlib, never past the
bytes the placeholders' splat count needs, decoded per the spec's table in binary64, turned
from SPZ's frame to glTF's and rounded once to float32 (:func:`decode_spz`); it is then
returned as FLOAT accessors, and derived anchors come from those float32 values. (The work is
bounded by the placeholders' count N: 16 + 65 N bytes at most. A plugin reading untrusted files
also bounds N against the stream's size before allocating, as the package's reader does:
``MAX_SPZ_AMPLIFICATION`` of README §Limits.)

Everything is returned raw (stored dtype, component type, normalized flag), so that an
implementation under test can do its own dequantization. Only GLB files with their data in the
binary chunk are supported (which is what the conformance suite contains).
"""
from __future__ import annotations

import json
import math
import struct
import zlib
from dataclasses import dataclass, field

import numpy as np

from .glb import (BYTE, COMPONENT_DTYPES, FLOAT, SHORT, TYPE_COMPONENTS, UNSIGNED_BYTE,
                  UNSIGNED_INT, UNSIGNED_SHORT)

__all__ = ["Refused", "Raw", "RawAsset", "read_anchored_glb", "dequantize", "ANCHOR_ACCESSORS",
           "accessor_allowed", "face_index", "derive_local", "decode_spz", "SPZ"]

KHR = "KHR_gaussian_splatting"
ANCHOR = "GSVERSE_gaussian_splatting_mesh_anchor"
SPZ = "KHR_gaussian_splatting_compression_spz_2"

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
    # version 1.2: one count per triangle instead of faceIndex
    "faceCounts": ("SCALAR", frozenset({(UNSIGNED_BYTE, False), (UNSIGNED_SHORT, False),
                                        (UNSIGNED_INT, False)})),
}
_REQUIRED = {"local": ("barycentrics", "normalOffset", "localRotation", "localScale"),
             "games": ("barycentrics", "rho")}
#: version 1.2: a local primitive without barycentrics stores none of these (derived)
_DERIVED = ("barycentrics", "normalOffset", "localRotation", "localScale")
_EPS_DEG = 1e-6


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
    #: version 1.2: ``faceCounts`` (then ``anchors`` has no ``faceIndex``)
    face_counts: Raw | None = None
    #: version 1.2: a ``local`` primitive without stored anchors (see :func:`derive_local`)
    derived: bool = False
    #: version 1.2: the rest pose was decoded from an SPZ stream (see :func:`decode_spz`)
    compressed: bool = False

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
    compressed = SPZ in (khr.get("extensions") or {})
    if compressed:
        positions, rotations, scales, opacities, sh = _read_spz(d, khr, attrs)
    else:
        positions, rotations, scales, opacities, sh = _read_rest_pose(d, attrs)
    n = positions.values.shape[0]
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
    if ("faceIndex" in ext) == ("faceCounts" in ext):
        raise Refused("exactly one of faceIndex and faceCounts must be present")
    derived = profile == "local" and "barycentrics" not in ext
    if derived and any(k in ext for k in _DERIVED):
        raise Refused("without barycentrics, normalOffset, localRotation and localScale must "
                      "be absent")
    anchors: dict[str, Raw] = {}
    counts = None
    face_prop = "faceIndex" if "faceIndex" in ext else "faceCounts"
    for prop in (face_prop,) + (() if derived else _REQUIRED[profile]):
        if prop not in ext:
            raise Refused(f"{profile} profile requires {prop}")
        raw = d.accessor(ext[prop], prop, tuple(TYPE_COMPONENTS))
        acc = doc["accessors"][ext[prop]]
        if not accessor_allowed(prop, acc["type"], raw.component_type, raw.normalized):
            raise Refused(f"{prop}: {acc['type']} componentType {raw.component_type}"
                          f"{' normalized' if raw.normalized else ''} is not allowed")
        if prop == "faceCounts":
            if raw.values.shape[0] != len(faces):
                raise Refused(f"faceCounts has {raw.values.shape[0]} elements, the anchor mesh "
                              f"has {len(faces)} triangles")
            if int(raw.values[:, 0].astype(np.int64).sum()) != n:
                raise Refused(f"faceCounts does not sum to the {n} splats")
            counts = raw
            continue
        if raw.values.shape[0] != n:
            raise Refused(f"{prop} has {raw.values.shape[0]} elements, POSITION has {n}")
        anchors[prop] = raw
    face = anchors["faceIndex"].values[:, 0] if counts is None else \
        np.repeat(np.arange(len(faces)), counts.values[:, 0].astype(np.int64))
    if face.size and int(face.max()) >= len(faces):
        raise Refused(f"faceIndex {int(face.max())} out of range for {len(faces)} triangles")
    for name, raw in [("anchor POSITION", apos)] + list(anchors.items()):
        if raw.component_type == FLOAT and not np.all(np.isfinite(raw.values)):
            raise Refused(f"{name} holds NaN or infinity")
    if derived:
        tri = apos.values.astype(np.float64)[faces[face].astype(np.int64)]
        bad = np.flatnonzero(~_regular(tri))
        if bad.size:
            raise Refused(f"splat {int(bad[0])} has derived anchors on face {int(face[bad[0]])}, "
                          f"which is degenerate at rest")
        # derived anchors are used as stored ones: q_l from a zero ROTATION has length zero,
        # and s_l = SCALE must be >= 0
        zero = np.flatnonzero(~np.any(dequantize(rotations) != 0, axis=1))
        if zero.size:
            raise Refused(f"rest ROTATION of splat {int(zero[0])} (derived localRotation) has "
                          f"length zero")
        negative = np.flatnonzero(np.any(dequantize(scales) < 0, axis=1))
        if negative.size:
            raise Refused(f"rest SCALE of splat {int(negative[0])} (derived localScale) is "
                          f"negative")
    elif profile == "local":
        zero = np.flatnonzero(~np.any(anchors["localRotation"].values != 0, axis=1))
        if zero.size:
            raise Refused(f"localRotation of splat {int(zero[0])} has length zero")
        negative = np.flatnonzero(np.any(dequantize(anchors["localScale"]) < 0, axis=1))
        if negative.size:
            raise Refused(f"localScale of splat {int(negative[0])} is negative")
    return RawAsset(positions, rotations, scales, opacities, sh,
                    apos.values.astype(np.float32), faces, profile, deformation, anchors,
                    counts, derived, compressed)


def _read_rest_pose(d: _Doc, attrs: dict) -> tuple:
    positions = d.accessor(attrs["POSITION"], "POSITION", ("VEC3",))
    if positions.component_type != FLOAT:
        raise Refused("POSITION must be FLOAT")
    rotations = d.accessor(attrs[f"{KHR}:ROTATION"], "ROTATION", ("VEC4",))
    scales = d.accessor(attrs[f"{KHR}:SCALE"], "SCALE", ("VEC3",))
    opacities = d.accessor(attrs[f"{KHR}:OPACITY"], "OPACITY", ("SCALAR",))
    sh = []
    for level in range(4):
        names = [f"{KHR}:SH_DEGREE_{level}_COEF_{c}" for c in range(2 * level + 1)]
        if not all(nm in attrs for nm in names):
            break
        sh += [d.accessor(attrs[nm], nm, ("VEC3",)) for nm in names]
    return positions, rotations, scales, opacities, sh


#: SPZ -> glTF (180 degrees about Y): signs of x, y, z of positions and quaternions, and of SH
#: coefficient k = 0 .. 15 (spec §SPZ-compressed rest pose, s_k).
_SPZ_AXIS = np.array([-1.0, 1.0, -1.0])
_SPZ_SH_SIGN = np.array([1, 1, -1, -1, -1, -1, 1, 1, 1, 1, 1, 1, -1, -1, -1, -1], np.float64)


def _spz_stream_bytes(version: int, count: int, degree: int) -> int:
    """Header and attributes of ``count`` splats: 9 + 1 + 3 + 3 + (3 or 4) + 3 ((d+1)^2 - 1)."""
    return 16 + count * (16 + (4 if version >= 3 else 3) + 3 * ((degree + 1) ** 2 - 1))


def _read_spz(d: _Doc, khr: dict, attrs: dict) -> tuple:
    """The rest pose of a compressed primitive as FLOAT Raw accessors (glTF frame, float32)."""
    shapes = {"POSITION": "VEC3", f"{KHR}:ROTATION": "VEC4", f"{KHR}:SCALE": "VEC3",
              f"{KHR}:OPACITY": "SCALAR"}
    degree = -1
    while degree < 3 and f"{KHR}:SH_DEGREE_{degree + 1}_COEF_0" in attrs:
        degree += 1
        shapes.update({f"{KHR}:SH_DEGREE_{degree}_COEF_{c}": "VEC3"
                       for c in range(2 * degree + 1)})
    if any(a.startswith(f"{KHR}:SH_DEGREE_") and a not in shapes for a in attrs):
        raise Refused("the SH attributes of the compressed primitive are not exactly degrees "
                      f"0 to {degree}")
    count = -1
    for name, gtype in shapes.items():
        acc = d.get("accessors", attrs[name] if name in attrs else None, f"placeholder {name}")
        if acc.get("type") != gtype or acc.get("componentType") != FLOAT:
            raise Refused(f"placeholder {name} must be FLOAT {gtype}")
        c = acc.get("count")
        if not isinstance(c, int) or isinstance(c, bool) or c < 0 or count not in (-1, c):
            raise Refused(f"placeholder {name} has count {c!r}, POSITION has {count!r}")
        count = c
    if "COLOR_0" in attrs:      # the fallback colour: any type glTF allows, the same count
        c = d.get("accessors", attrs["COLOR_0"], "placeholder COLOR_0").get("count")
        if c != count:
            raise Refused(f"placeholder COLOR_0 has count {c!r}, POSITION has {count!r}")
    obj = khr["extensions"][SPZ]
    view = d.get("bufferViews", obj.get("bufferView") if isinstance(obj, dict) else None,
                 SPZ)
    if view.get("buffer", 0) != 0 or _external_buffer(d):
        raise Refused(f"{SPZ}: only data in the GLB binary chunk is supported")
    start, length = view.get("byteOffset", 0), view.get("byteLength", 0)
    if not (isinstance(start, int) and isinstance(length, int) and start >= 0 and length >= 0
            and start + length <= len(d.blob)):
        raise Refused(f"{SPZ}: bufferView runs past the end of the buffer")
    data = _inflate(d.blob[start:start + length], _spz_stream_bytes(3, count, 3))
    values = decode_spz(data, count, degree)
    return tuple(Raw(v, FLOAT, False) for v in values[:4]) + (
        [Raw(values[4][:, k], FLOAT, False) for k in range(values[4].shape[1])],)


def _external_buffer(d: _Doc) -> bool:
    return d.doc.get("buffers", [{}])[0].get("uri") is not None


def _inflate(raw: bytes, limit: int) -> bytes:
    """The content of the one gzip member ``raw``; refused past ``limit`` bytes (inflation
    stops there), when broken or truncated, or when non-zero bytes follow the member."""
    inflater = zlib.decompressobj(wbits=16 + zlib.MAX_WBITS)
    try:
        out = inflater.decompress(bytes(raw), limit + 1)
    except zlib.error as err:
        raise Refused(f"{SPZ}: broken gzip stream ({err})") from None
    if len(out) > limit:
        raise Refused(f"{SPZ}: the stream inflates past the {limit} bytes its splats can need")
    if not inflater.eof:
        raise Refused(f"{SPZ}: truncated gzip stream")
    if inflater.unused_data.strip(b"\0"):
        raise Refused(f"{SPZ}: data follows the gzip member")
    return out


def decode_spz(data: bytes, count: int, degree: int) -> tuple[np.ndarray, ...]:
    """An inflated SPZ stream of ``count`` splats of SH degree ``degree`` (what the placeholders
    say; refused otherwise) as float32 positions (N, 3), rotations (N, 4) xyzw, scales (N, 3),
    opacities (N, 1) and SH (N, K, 3), in glTF's frame: the spec's table in binary64, the frame
    change, quaternions normalized, one rounding to float32."""
    if len(data) < 16:
        raise Refused(f"{SPZ}: the stream is shorter than its header")
    magic, version, n, deg, frac, flags, _ = struct.unpack_from("<IIIBBBB", data, 0)
    if magic != 0x5053474E:
        raise Refused(f"{SPZ}: no NGSP magic")
    if version not in (2, 3):
        raise Refused(f"{SPZ}: SPZ version {version} (2 and 3 are allowed)")
    if flags & 2:
        raise Refused(f"{SPZ}: the stream carries extension records (flag bit 1)")
    if n != count:
        raise Refused(f"{SPZ}: the stream holds {n} splats, the placeholders {count}")
    if deg != degree:
        raise Refused(f"{SPZ}: the stream has SH degree {deg}, the attributes {degree}")
    if frac > 24:
        raise Refused(f"{SPZ}: {frac} fractional bits")
    if len(data) != _spz_stream_bytes(version, n, deg):
        raise Refused(f"{SPZ}: the stream holds {len(data)} bytes, its splats need "
                      f"{_spz_stream_bytes(version, n, deg)}")
    rest = (deg + 1) ** 2 - 1
    rot_bytes = 4 if version >= 3 else 3
    buf = np.frombuffer(data, np.uint8, offset=16)
    parts, at = [], 0
    for size in (9, 1, 3, 3, rot_bytes, 3 * rest):
        parts.append(buf[at:at + size * n])
        at += size * n
    pos_b, alpha_b, colour_b, scale_b, rot_b, sh_b = parts
    b = pos_b.reshape(n, 3, 3).astype(np.int64)
    fixed = b[..., 0] | (b[..., 1] << 8) | (b[..., 2] << 16)
    fixed = np.where(fixed >= 1 << 23, fixed - (1 << 24), fixed)
    positions = fixed / float(1 << frac) * _SPZ_AXIS
    if version >= 3:
        q = _smallest_three(rot_b.view("<u4").astype(np.int64))
    else:
        xyz = rot_b.reshape(n, 3) / 127.5 - 1.0
        q = np.concatenate([xyz, np.sqrt(np.maximum(0.0, 1.0 - (xyz * xyz).sum(1)))[:, None]],
                           axis=1)
    q[:, :3] *= _SPZ_AXIS
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    scales = np.exp(scale_b.reshape(n, 3) / 16.0 - 10.0)
    opacities = (alpha_b / 255.0).reshape(n, 1)
    sh = np.empty((n, rest + 1, 3))
    sh[:, 0] = (colour_b.reshape(n, 3) / 255.0 - 0.5) / 0.15
    sh[:, 1:] = (sh_b.reshape(n, rest, 3) - 128.0) / 128.0 * _SPZ_SH_SIGN[1:rest + 1, None]
    return tuple(a.astype(np.float32) for a in (positions, q, scales, opacities, sh))


def _smallest_three(words: np.ndarray) -> np.ndarray:
    """Version-3 rotations: bits 30-31 the index of the largest component (rebuilt from the
    others), then the other three in index order, the last in the lowest 10 bits, each a sign
    (bit 9) and a magnitude m (bits 0-8) meaning m / 511 * sqrt(1/2)."""
    largest = words >> 30
    q = np.zeros((len(words), 4))
    rest = words.copy()
    for i in (3, 2, 1, 0):
        here = largest != i
        value = (rest & 511) / 511.0 * math.sqrt(0.5)
        value = np.where((rest >> 9) & 1, -value, value)
        q[:, i] = np.where(here, value, 0.0)
        rest = np.where(here, rest >> 10, rest)
    rows = np.arange(len(words))
    q[rows, largest] = np.sqrt(np.maximum(0.0, 1.0 - (q * q).sum(axis=1)))
    return q


def _regular(tri: np.ndarray) -> np.ndarray:
    """(F,) whether triangles (F, 3, 3) are regular: a > eps_deg l^2 (spec Triangle frames)."""
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    e3 = e2 - e1
    a = np.linalg.norm(np.cross(e1, e2), axis=1)
    longest2 = np.max(np.stack([(e * e).sum(axis=1) for e in (e1, e2, e3)]), axis=0)
    return a > _EPS_DEG * longest2


def face_index(asset: RawAsset) -> np.ndarray:
    """(N,) uint32 face of each splat: ``faceIndex``, or from ``faceCounts`` (splat i is on
    face f with S_f <= i < S_{f+1}, S_f the sum of the counts before f)."""
    if asset.face_counts is None:
        return asset.anchors["faceIndex"].values[:, 0].astype(np.uint32)
    counts = asset.face_counts.values[:, 0].astype(np.int64)
    return np.repeat(np.arange(len(counts), dtype=np.uint32), counts)


def _quat_from_matrix(m: np.ndarray) -> np.ndarray:
    """Shepperd's method, (F, 3, 3) -> (F, 4) xyzw."""
    out = np.empty((len(m), 4))
    tr = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    cand = np.stack([1 + 2 * m[:, 0, 0] - tr, 1 + 2 * m[:, 1, 1] - tr, 1 + 2 * m[:, 2, 2] - tr,
                     1 + tr], axis=1)
    k = np.argmax(cand, axis=1)
    s = 2 * np.sqrt(np.maximum(cand[np.arange(len(m)), k], 0.0))
    for i in range(len(m)):
        r, si = m[i], s[i]
        if k[i] == 3:
            q = [(r[2, 1] - r[1, 2]) / si, (r[0, 2] - r[2, 0]) / si, (r[1, 0] - r[0, 1]) / si, si / 4]
        elif k[i] == 0:
            q = [si / 4, (r[0, 1] + r[1, 0]) / si, (r[0, 2] + r[2, 0]) / si, (r[2, 1] - r[1, 2]) / si]
        elif k[i] == 1:
            q = [(r[0, 1] + r[1, 0]) / si, si / 4, (r[1, 2] + r[2, 1]) / si, (r[0, 2] - r[2, 0]) / si]
        else:
            q = [(r[0, 2] + r[2, 0]) / si, (r[1, 2] + r[2, 1]) / si, si / 4, (r[1, 0] - r[0, 1]) / si]
        out[i] = q
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def derive_local(asset: RawAsset) -> dict[str, np.ndarray]:
    """The ``local`` anchors of a compact asset (version 1.2), float64: ``barycentrics``
    (N, 2), ``normalOffset`` (N,), ``localRotation`` (N, 4) and ``localScale`` (N, 3), from
    the rest pose (POSITION, ROTATION dequantized and normalized, SCALE dequantized) and the
    rest triangle of each splat (regular: :func:`read_anchored_glb` refused the others):
    (x, y, z) = R_r^T (mu - v0), b2 = y / C_r[1,1], b1 = (x - C_r[0,1] b2) / C_r[0,0], d = z,
    q_l = conj(q_r) (x) q."""
    face = face_index(asset).astype(np.int64)
    v = asset.anchor_vertices.astype(np.float64)[asset.anchor_faces.astype(np.int64)[face]]
    e1, e2 = v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]
    cross = np.cross(e1, e2)
    a = np.linalg.norm(cross, axis=1)
    l1 = np.linalg.norm(e1, axis=1)
    t = e1 / l1[:, None]
    n = cross / a[:, None]
    b = np.cross(n, t)
    rel = dequantize(asset.positions) - v[:, 0]
    x, y, z = ((rel * axis).sum(axis=1) for axis in (t, b, n))
    c01 = (e2 * t).sum(axis=1)
    b2 = y / (a / l1)
    b1 = (x - c01 * b2) / l1
    q = dequantize(asset.rotations)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    qr = _quat_from_matrix(np.stack([t, b, n], axis=-1))
    ax, ay, az, aw = -qr[:, 0], -qr[:, 1], -qr[:, 2], qr[:, 3]      # conj(q_r)
    bx, by, bz, bw = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    ql = np.stack([aw * bx + ax * bw + ay * bz - az * by,
                   aw * by - ax * bz + ay * bw + az * bx,
                   aw * bz + ax * by - ay * bx + az * bw,
                   aw * bw - ax * bx - ay * by - az * bz], axis=1)
    return {"barycentrics": np.stack([b1, b2], axis=1), "normalOffset": z,
            "localRotation": ql, "localScale": dequantize(asset.scales)}
