"""Programmatic test assets for ``gsverse-validate``: valid bases and one trigger per issue code.

:func:`clean_assets` writes assets that must validate without any finding. :data:`TRIGGERS`
maps every code of the catalogue to a builder ``build(folder) -> Trigger`` that writes a file
(from a valid base, changed in one place) on which the validator reports that code. Nothing
binary is stored in the repository: every asset is built here from the data model.
"""
from __future__ import annotations

import base64
import gzip
import copy
import json
import pathlib
import struct
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.spatial.transform import Rotation

from gsverse_format import EXTENSION_NAME
from gsverse_format.binding import bind_local
from gsverse_format.examples import example_mesh, example_splats
from gsverse_format.io.gltf import asset_to_gltf
from gsverse_format.vocabulary import SPZ_EXTENSION
from gsverse_format.model import (Anchoring, Collider, GamesAnchors, Ground, Physics,
                                  SplatAsset, SplatCloud, SplatPrimitive, TriangleMesh)
from gsverse_format.physics import PHYSICS, SHAPES
from gsverse_format.remapping.reference import remap
from gsverse_format.rig import AnchorRig, RigAnimation, RigChannel, RigNode

KHR = "KHR_gaussian_splatting"
ANCHOR = EXTENSION_NAME
ROTATION, SCALE, OPACITY = f"{KHR}:ROTATION", f"{KHR}:SCALE", f"{KHR}:OPACITY"
_DTYPES = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
JSON_CHUNK, BIN_CHUNK = 0x4E4F534A, 0x004E4942


# ---------------------------------------------------------------------------- model assets

def local_asset(n: int = 60, *, deformation: str = "affine", seed: int = 1,
                floater: bool = False, shuffle: bool = False, lift: float = 0.0,
                away: float = 0.0) -> SplatAsset:
    """Splats on a small capsule mesh, bound with the reference binder (rest pose consistent),
    plus a plain static primitive. ``floater`` adds a splat far from the mesh; ``shuffle``
    stores the anchored splats out of face order; ``lift`` moves the splats outwards (on the
    convex mesh, splats near edges then have their foot point outside their triangle);
    ``away`` binds the splats to the mesh moved this far along +x (a mesh that does not fit
    its splats)."""
    mesh = example_mesh(subdivisions=1)
    cloud = example_splats(mesh, n, seed=seed)
    if away:
        mesh = TriangleMesh(mesh.vertices + np.array([away, 0.0, 0.0], np.float32), mesh.faces)
    if lift:
        radial = cloud.means / np.linalg.norm(cloud.means, axis=1, keepdims=True)
        cloud.means = (cloud.means + lift * radial).astype(np.float32)
    if floater:
        cloud = SplatCloud.concatenate([cloud, cloud.subset([0])])
        cloud.means[-1] = (2.5, 2.5, 2.5)
    anchors = bind_local(cloud, mesh, deformation=deformation).anchors
    order = np.argsort(anchors.face_index, kind="stable")
    if shuffle:
        order = order[::-1]
    cloud, anchors = cloud.subset(order), anchors.subset(order)
    static = example_splats(mesh, 5, seed=seed + 7)
    return SplatAsset([SplatPrimitive(cloud, Anchoring(mesh, anchors), "body"),
                       SplatPrimitive(static, None, "static")])


def games_asset(n: int = 48, *, seed: int = 2, negative_rho: bool = False) -> SplatAsset:
    """GaMeS splats (k per face) whose rest pose is the games remap at rest."""
    mesh = example_mesh(subdivisions=1)
    rng = np.random.default_rng(seed)
    face = np.sort(rng.integers(0, mesh.face_count, n))
    alpha = rng.dirichlet([2, 2, 2], n)[:, 1:]
    rho = rng.uniform(0.2, 1.5, n)
    if negative_rho:
        rho[3] = -0.5
    anchors = GamesAnchors(face, alpha, rho)
    rest = remap(Anchoring(mesh, anchors))
    sh = rng.normal(0, 0.3, (n, 4, 3))
    cloud = SplatCloud(rest.means, rest.rotations, rest.scales, rng.uniform(0.2, 1.0, n), sh)
    return SplatAsset([SplatPrimitive(cloud, Anchoring(mesh, anchors), "games")])


# ---------------------------------------------------------------------------- documents

@dataclass
class Doc:
    """A glTF document being edited: JSON ``doc`` and the binary buffer ``blob``."""

    doc: dict
    blob: bytearray

    @classmethod
    def of(cls, asset: SplatAsset, **kw) -> "Doc":
        gltf = asset_to_gltf(asset, **kw)
        return cls(json.loads(gltf.to_json()), bytearray(gltf.binary_blob() or b""))

    def copy(self) -> "Doc":
        return Doc(copy.deepcopy(self.doc), bytearray(self.blob))

    # -- navigation -------------------------------------------------------------------
    def prim(self, m: int = 0, p: int = 0) -> dict:
        return self.doc["meshes"][m]["primitives"][p]

    def khr(self, m: int = 0) -> dict:
        return self.prim(m)["extensions"][KHR]

    def ext(self, m: int = 0) -> dict:
        return self.khr(m)["extensions"][ANCHOR]

    def anchor_prim(self, m: int = 0) -> dict:
        e = self.ext(m)
        return self.prim(e["mesh"], e.get("primitive", 0))

    def attr(self, name: str, m: int = 0) -> int:
        return self.prim(m)["attributes"][name]

    # -- data -------------------------------------------------------------------------
    def values(self, index: int) -> np.ndarray:
        """A writable (count, ncomp) view of a tightly packed accessor's data in the blob."""
        acc = self.doc["accessors"][index]
        view = self.doc["bufferViews"][acc["bufferView"]]
        dtype = np.dtype(_DTYPES[acc["componentType"]])
        start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
        shape = (acc["count"], _NCOMP[acc["type"]])
        return np.ndarray(shape, dtype, buffer=self.blob, offset=start)

    def add_accessor(self, array, ctype: int, gtype: str, *, normalized: bool = False,
                     target: int | None = None, minmax: bool = False) -> int:
        """Append a bufferView and an accessor holding ``array``; returns the accessor index."""
        data = np.ascontiguousarray(np.asarray(array).reshape(len(array), -1),
                                    dtype=np.dtype(_DTYPES[ctype]))
        self.blob += b"\0" * (-len(self.blob) % 4)
        view = {"buffer": 0, "byteOffset": len(self.blob), "byteLength": data.nbytes}
        if target is not None:
            view["target"] = target
        self.blob += data.tobytes()
        self.blob += b"\0" * (-len(self.blob) % 4)
        self.doc["buffers"][0]["byteLength"] = len(self.blob)
        self.doc["bufferViews"].append(view)
        acc = {"bufferView": len(self.doc["bufferViews"]) - 1, "componentType": ctype,
               "count": len(data), "type": gtype}
        if normalized:
            acc["normalized"] = True
        if minmax:
            acc["min"] = data.min(axis=0).tolist()
            acc["max"] = data.max(axis=0).tolist()
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def extend_anchor_mesh(self, vertices=(), faces=()) -> int:
        """Append vertices and faces (indices into the extended vertex list) to the anchor
        primitive of mesh 0; returns the new face count."""
        prim = self.anchor_prim()
        v = np.concatenate([self.values(prim["attributes"]["POSITION"]),
                            np.asarray(vertices, np.float32).reshape(-1, 3)])
        f = np.concatenate([self.values(prim["indices"]).reshape(-1),
                            np.asarray(faces, np.uint32).reshape(-1)])
        prim["attributes"]["POSITION"] = self.add_accessor(v, 5126, "VEC3", target=34962,
                                                           minmax=True)
        prim["indices"] = self.add_accessor(f, 5125, "SCALAR", target=34963)
        return len(f) // 3

    # -- output -----------------------------------------------------------------------
    def json_bytes(self) -> bytes:
        return json.dumps(self.doc).encode("utf-8")

    def glb(self, *, bin_chunk: bool = True, pad: bool = True) -> bytes:
        text = self.json_bytes()
        if pad:
            text += b" " * (-len(text) % 4)
        out = struct.pack("<II", len(text), JSON_CHUNK) + text
        if bin_chunk and self.blob:
            blob = bytes(self.blob) + b"\0" * (-len(self.blob) % 4)
            out += struct.pack("<II", len(blob), BIN_CHUNK) + blob
        return struct.pack("<4sII", b"glTF", 2, 12 + len(out)) + out

    def gltf(self, uri: str | None = None) -> bytes:
        doc = copy.deepcopy(self.doc)
        doc["buffers"][0]["uri"] = uri if uri is not None else (
            "data:application/octet-stream;base64," + base64.b64encode(bytes(self.blob)).decode())
        return json.dumps(doc).encode("utf-8")

    def write(self, folder: pathlib.Path, name: str) -> pathlib.Path:
        path = pathlib.Path(folder) / name
        path.write_bytes(self.glb() if name.endswith(".glb") else self.gltf())
        return path


def _local() -> Doc:
    return Doc.of(local_asset())


def rigged_asset() -> SplatAsset:
    """:func:`local_asset` whose anchor mesh is animated (spec §Animated anchor meshes): a
    two-joint skin, one morph target and an animation of both."""
    asset = local_asset()
    mesh = asset.primitives[0].anchoring.mesh
    v = mesh.vertices.astype(np.float64)
    up = np.clip((v[:, 1] - v[:, 1].min()) / np.ptp(v[:, 1]), 0, 1)
    joints = np.zeros((len(v), 4), np.uint16)
    joints[:, 1] = 1
    weights = np.zeros((len(v), 4), np.float32)
    weights[:, 0], weights[:, 1] = 1 - up, up
    tip = RigNode("tip", translation=np.array([0.0, 0.5, 0.0]))
    ibm = np.stack([np.eye(4), np.eye(4)])
    ibm[1, 1, 3] = -0.5
    turn = Rotation.from_euler("z", [[0], [30]], degrees=True).as_quat()
    mesh.rig = AnchorRig(
        nodes=[RigNode("root", children=[1]), tip], roots=[0], joints=[0, 1], inverse_bind=ibm,
        joints_0=joints, weights_0=weights, targets=[0.1 * v.astype(np.float32)], weights=[0.0],
        animations=[RigAnimation("bend", [
            RigChannel(1, "rotation", np.array([0.0, 1.0]), turn),
            RigChannel(None, "weights", np.array([0.0, 1.0]), np.array([[0.0], [1.0]]))])])
    return asset


def _rigged() -> Doc:
    return Doc.of(rigged_asset())


def _games() -> Doc:
    return Doc.of(games_asset())


def physics_asset(kind: str = "soft") -> SplatAsset:
    """:func:`local_asset` whose anchored object is a body of ``kind`` (its anchor mesh as its
    collider) over a ground box (spec §Physics)."""
    asset = local_asset()
    body = asset.primitives[0]
    body.physics = Physics(kind, 2.0 if kind != "static" else None)
    asset.colliders.append(Collider(body.anchoring.mesh, body.anchoring.mesh))
    asset.ground = Ground((3.0, 0.02, 3.0), (0.0, -0.9, 0.0))
    return asset


def _physics() -> Doc:
    return Doc.of(physics_asset())


def _body(d: Doc) -> dict:
    return d.doc["nodes"][0]["extensions"][PHYSICS]


def clean_assets(folder: pathlib.Path) -> list[pathlib.Path]:
    """Valid assets of every kind the writer produces; they must validate without findings."""
    folder = pathlib.Path(folder)
    out = []
    for name, asset, kw in (
            ("local_affine.glb", local_asset(), {}),
            ("local_rigid.gltf", local_asset(deformation="rigid"), {}),
            ("games.glb", games_asset(), {}),
            ("quantized.glb", local_asset(), {"quantize": {"barycentrics": "unsigned_short",
                                                           "localRotation": "short"}}),
            ("quantized16.gltf", games_asset(), {"quantize": {"barycentrics": "unsigned_short"}}),
            ("quantized8.glb", local_asset(), {"quantize": {"barycentrics": "unsigned_byte",
                                                            "localRotation": "byte"}}),
            ("quantized8_rigid.gltf", local_asset(deformation="rigid", lift=0.05),
             {"quantize": {"barycentrics": "unsigned_byte", "localRotation": "byte"}}),
            ("quantized8_games.glb", games_asset(), {"quantize": {"barycentrics": "unsigned_byte"}}),
            ("rigged.glb", rigged_asset(), {}),
            ("compact_local.glb", local_asset(lift=0.05), {"anchors": "compact"}),
            ("compact_rigid_q8.gltf", local_asset(deformation="rigid"),
             {"anchors": "compact", "quantize": {"ROTATION": "byte"}}),
            ("compact_games.glb", games_asset(), {"anchors": "compact",
                                                  "quantize": {"barycentrics": "unsigned_short"}}),
            ("plain.glb", SplatAsset([SplatPrimitive(example_splats(example_mesh(1), 20), None,
                                                     "plain")]), {}),
            ("physics_soft.glb", physics_asset(), {"anchors": "compact"}),
            ("physics_kinematic.gltf", physics_asset("kinematic"), {}),
            ("physics_static.glb", physics_asset("static"), {}),
            ("compact_spz.glb", local_asset(), {"anchors": "compact", "compress": "spz"}),
            ("plain_spz.gltf", SplatAsset([SplatPrimitive(example_splats(example_mesh(1), 20),
                                                          None, "plain")]), {"compress": "spz"})):
        out.append(Doc.of(asset, **kw).write(folder, name))
    return out


# ---------------------------------------------------------------------------- triggers

@dataclass
class Trigger:
    """A file that triggers one code; ``options`` are :class:`Options` fields to validate it
    with, ``fault`` asks the test to inject a failure into a check (``INTERNAL_ERROR``)."""

    path: pathlib.Path
    options: dict = field(default_factory=dict)
    fault: bool = False


TRIGGERS: dict[str, Callable[[pathlib.Path], Trigger]] = {}


def trigger(code: str):
    def register(fn):
        assert code not in TRIGGERS, code
        TRIGGERS[code] = fn
        return fn
    return register


def _edited(folder, name, edit: Callable[[Doc], None], base: Callable[[], Doc] = _local,
            **options) -> Trigger:
    d = base()
    edit(d)
    return Trigger(d.write(folder, name), options)


def _raw(folder, name, data: bytes, **options) -> Trigger:
    path = pathlib.Path(folder) / name
    path.write_bytes(data)
    return Trigger(path, options)


# -- file ---------------------------------------------------------------------------------
@trigger("IO_ERROR")
def _(folder):
    return Trigger(pathlib.Path(folder) / "does-not-exist.glb")


@trigger("FILE_TYPE_UNSUPPORTED")
def _(folder):
    return _raw(folder, "splats.ply", b"ply\nformat ascii 1.0\nend_header\n")


@trigger("SIZE_LIMIT_EXCEEDED")
def _(folder):
    return Trigger(_local().write(folder, "big.glb"), {"max_bytes": 1000})


@trigger("SPLAT_COUNT_LIMIT")
def _(folder):
    return Trigger(_local().write(folder, "many.glb"), {"max_splats": 10})


# -- GLB ----------------------------------------------------------------------------------
@trigger("GLB_TRUNCATED")
def _(folder):
    data = _local().glb()
    return _raw(folder, "cut.glb", data[:len(data) // 2])


@trigger("GLB_BAD_MAGIC")
def _(folder):
    return _raw(folder, "magic.glb", b"gLTF" + _local().glb()[4:])


@trigger("GLB_UNSUPPORTED_VERSION")
def _(folder):
    data = bytearray(_local().glb())
    struct.pack_into("<I", data, 4, 1)
    return _raw(folder, "v1.glb", bytes(data))


@trigger("GLB_LENGTH_MISMATCH")
def _(folder):
    return _raw(folder, "trailing.glb", _local().glb() + b"\0\0\0\0")


@trigger("GLB_CHUNK_TOO_LONG")
def _(folder):
    data = bytearray(_local().glb())
    json_len = struct.unpack_from("<I", data, 12)[0]
    struct.pack_into("<I", data, 20 + json_len, 10 ** 7)
    return _raw(folder, "chunk.glb", bytes(data))


@trigger("GLB_FIRST_CHUNK_NOT_JSON")
def _(folder):
    data = bytearray(_local().glb())
    struct.pack_into("<I", data, 16, BIN_CHUNK)
    return _raw(folder, "order.glb", bytes(data))


@trigger("GLB_CHUNK_UNALIGNED")
def _(folder):
    d = _local()
    while len(d.json_bytes()) % 4 != 1:
        d.doc["asset"]["generator"] += "+"
    return _raw(folder, "unaligned.glb", d.glb(pad=False))


def _append_chunk(data: bytes, kind: int, payload: bytes) -> bytes:
    out = bytearray(data) + struct.pack("<II", len(payload), kind) + payload
    struct.pack_into("<I", out, 8, len(out))
    return bytes(out)


@trigger("GLB_UNKNOWN_CHUNK")
def _(folder):
    return _raw(folder, "extra.glb", _append_chunk(_local().glb(), 0x12345678, b"abcd"))


@trigger("GLB_UNEXPECTED_CHUNK")
def _(folder):
    return _raw(folder, "twobin.glb", _append_chunk(_local().glb(), BIN_CHUNK, b"\0" * 8))


# -- JSON ---------------------------------------------------------------------------------
@trigger("JSON_NOT_UTF8")
def _(folder):
    return _raw(folder, "latin1.gltf", _local().gltf().replace(b'"body"', b'"b\xf6dy"'))


@trigger("JSON_INVALID")
def _(folder):
    return _raw(folder, "broken.gltf", _local().gltf()[:-10])


@trigger("GLTF_SCHEMA_VIOLATION")
def _(folder):
    return _edited(folder, "types.glb", lambda d: d.doc["bufferViews"][0].update(
        byteOffset="zero"))


@trigger("ASSET_VERSION_UNSUPPORTED")
def _(folder):
    return _edited(folder, "v1.gltf", lambda d: d.doc["asset"].update(version="1.0"))


@trigger("UNSUPPORTED_REQUIRED_EXTENSION")
def _(folder):
    def edit(d):
        d.doc["extensionsUsed"].append("KHR_draco_mesh_compression")
        d.doc["extensionsRequired"] = ["KHR_draco_mesh_compression"]
    return _edited(folder, "draco.glb", edit)


@trigger("UNRESOLVED_REFERENCE")
def _(folder):
    return _edited(folder, "ref.glb", lambda d: d.ext().update(mesh=99))


@trigger("EXTENSION_NOT_DECLARED")
def _(folder):
    return _edited(folder, "undeclared.glb", lambda d: d.doc["extensionsUsed"].remove(ANCHOR))


@trigger("ANCHOR_EXTENSION_REQUIRED")
def _(folder):
    return _edited(folder, "required.glb", lambda d: d.doc.update(extensionsRequired=[ANCHOR]))


# -- buffers ------------------------------------------------------------------------------
def _uri(folder, name, uri, **options) -> Trigger:
    return _raw(folder, name, _local().gltf(uri), **options)


@trigger("URI_SCHEME_REJECTED")
def _(folder):
    return _uri(folder, "http.gltf", "https://example.com/splats.bin")


@trigger("URI_ABSOLUTE_PATH")
def _(folder):
    return _uri(folder, "abs.gltf", "/etc/passwd")


@trigger("URI_OUTSIDE_FOLDER")
def _(folder):
    (pathlib.Path(folder).parent / "outside.bin").write_bytes(bytes(_local().blob))
    return _uri(folder, "escape.gltf", "../outside.bin")


@trigger("URI_NOT_FOUND")
def _(folder):
    return _uri(folder, "missing.gltf", "missing.bin")


@trigger("URI_INVALID")
def _(folder):
    return _uri(folder, "b64.gltf", "data:application/octet-stream;base64,@@@@")


@trigger("DATA_URI_TOO_LARGE")
def _(folder):
    return Trigger(_local().write(folder, "embedded.gltf"), {"max_data_uri_bytes": 1024})


@trigger("BUFFER_MISSING_DATA")
def _(folder):
    return _raw(folder, "nobin.glb", _local().glb(bin_chunk=False))


@trigger("BUFFER_TOO_SHORT")
def _(folder):
    return _edited(folder, "short.glb", lambda d: d.doc["buffers"][0].update(
        byteLength=d.doc["buffers"][0]["byteLength"] + 64))


@trigger("BUFFER_VIEW_OUT_OF_BOUNDS")
def _(folder):
    def edit(d):
        view = d.doc["bufferViews"][d.doc["accessors"][d.attr(OPACITY)]["bufferView"]]
        view["byteOffset"] = len(d.blob) - 4
    return _edited(folder, "view.glb", edit)


@trigger("BUFFER_VIEW_STRIDE_INVALID")
def _(folder):
    def edit(d):
        d.doc["bufferViews"][d.doc["accessors"][d.attr(OPACITY)]["bufferView"]]["byteStride"] = 2
    return _edited(folder, "stride.glb", edit)


# -- accessors ----------------------------------------------------------------------------
@trigger("ACCESSOR_INVALID")
def _(folder):
    return _edited(folder, "ctype.glb", lambda d: d.doc["accessors"][d.attr(OPACITY)].update(
        componentType=5130))


@trigger("ACCESSOR_UNSUPPORTED")
def _(folder):
    return _edited(folder, "sparse.glb", lambda d: d.doc["accessors"][d.attr(OPACITY)].update(
        sparse={"count": 1, "indices": {"bufferView": 0, "componentType": 5125},
                "values": {"bufferView": 0}}))


@trigger("ACCESSOR_OUT_OF_BOUNDS")
def _(folder):
    return _edited(folder, "oob.glb", lambda d: d.doc["accessors"][d.attr(OPACITY)].update(
        count=d.doc["accessors"][d.attr(OPACITY)]["count"] * 50))


@trigger("ACCESSOR_MISALIGNED")
def _(folder):
    return _edited(folder, "align.glb", lambda d: d.doc["accessors"][d.attr(OPACITY)].update(
        byteOffset=2))


@trigger("NON_FINITE_VALUE")
def _(folder):
    return _edited(folder, "nan.glb", lambda d: d.values(d.attr("POSITION")).__setitem__(
        (3, 1), np.nan))


# -- KHR_gaussian_splatting ---------------------------------------------------------------------
@trigger("KHR_NO_SPLATS")
def _(folder):
    def edit(d):
        for mesh in d.doc["meshes"]:
            for prim in mesh["primitives"]:
                prim.pop("extensions", None)
        d.doc["extensionsUsed"] = []
    return _edited(folder, "points.glb", edit)


@trigger("KHR_PRIMITIVE_NOT_POINTS")
def _(folder):
    return _edited(folder, "mode.glb", lambda d: d.prim(1).update(mode=4))


@trigger("KHR_PROPERTY_MISSING")
def _(folder):
    return _edited(folder, "kernel.glb", lambda d: d.khr().pop("kernel"))


@trigger("KHR_PROPERTY_INVALID")
def _(folder):
    return _edited(folder, "colorspace.glb", lambda d: d.khr().update(colorSpace=5))


@trigger("KHR_PROPERTY_UNKNOWN_VALUE")
def _(folder):
    return _edited(folder, "kernel3d.glb", lambda d: d.khr().update(kernel="gaussian3d"))


@trigger("KHR_ATTRIBUTE_MISSING")
def _(folder):
    return _edited(folder, "noopacity.glb", lambda d: d.prim().get("attributes").pop(OPACITY))


@trigger("KHR_ATTRIBUTE_FORMAT")
def _(folder):
    def edit(d):
        sh = d.values(d.attr(f"{KHR}:SH_DEGREE_0_COEF_0"))
        codes = np.clip(np.round((sh + 2) * 60), 0, 255)
        d.prim()["attributes"][f"{KHR}:SH_DEGREE_0_COEF_0"] = d.add_accessor(
            codes, 5121, "VEC3", normalized=True, target=34962)
    return _edited(folder, "sh8.glb", edit)


@trigger("KHR_UNKNOWN_SEMANTIC")
def _(folder):
    return _edited(folder, "sh4.glb", lambda d: d.prim()["attributes"].update(
        {f"{KHR}:SH_DEGREE_4_COEF_0": d.attr(f"{KHR}:SH_DEGREE_0_COEF_0")}))


@trigger("KHR_SH_INCOMPLETE")
def _(folder):
    return _edited(folder, "sh1.glb", lambda d: d.prim()["attributes"].pop(
        f"{KHR}:SH_DEGREE_1_COEF_2"))


@trigger("ATTRIBUTE_COUNT_MISMATCH")
def _(folder):
    def edit(d):
        values = d.values(d.attr(OPACITY))
        d.prim()["attributes"][OPACITY] = d.add_accessor(values[:-1], 5126, "SCALAR",
                                                         target=34962)
    return _edited(folder, "count.glb", edit)


@trigger("ROTATION_NOT_UNIT")
def _(folder):
    return _edited(folder, "rot.glb", lambda d: d.values(d.attr(ROTATION)).__imul__(
        np.float32(1.01)))


@trigger("SCALE_NEGATIVE")
def _(folder):
    return _edited(folder, "neg.glb", lambda d: d.values(d.attr(SCALE, m=1)).__setitem__(
        (2, 0), -0.01))


@trigger("OPACITY_OUT_OF_RANGE")
def _(folder):
    return _edited(folder, "alpha.glb", lambda d: d.values(d.attr(OPACITY)).__setitem__(
        (0, 0), 1.5))


# -- anchor extension ---------------------------------------------------------------------
@trigger("ANCHOR_SCHEMA_VIOLATION")
def _(folder):
    return _edited(folder, "games_deformation.glb", lambda d: d.ext().update(
        deformation="affine"), base=_games)


@trigger("ANCHOR_EXTENSION_MISPLACED")
def _(folder):
    return _edited(folder, "misplaced.glb", lambda d: d.prim()["extensions"].update(
        {ANCHOR: copy.deepcopy(d.ext())}))


@trigger("ANCHOR_MESH_SAME_AS_SPLAT")
def _(folder):
    def edit(d):
        anchor = copy.deepcopy(d.anchor_prim())
        d.doc["meshes"][0]["primitives"].append(anchor)
        d.ext().update(mesh=0, primitive=1)
    return _edited(folder, "same.glb", edit)


@trigger("ANCHOR_MESH_NOT_TRIANGLES")
def _(folder):
    return _edited(folder, "lines.glb", lambda d: d.anchor_prim().update(mode=1))


@trigger("ANCHOR_MESH_POSITION_INVALID")
def _(folder):
    return _edited(folder, "nopos.glb", lambda d: d.anchor_prim()["attributes"].pop("POSITION"))


@trigger("ANCHOR_MESH_INDICES_INVALID")
def _(folder):
    return _edited(folder, "indices.glb", lambda d: d.doc["accessors"][
        d.anchor_prim()["indices"]].update(count=d.doc["accessors"][
            d.anchor_prim()["indices"]]["count"] - 1))


@trigger("ANCHOR_MESH_INSTANTIATED")
def _(folder):
    def edit(d):
        d.doc["nodes"].append({"mesh": d.ext()["mesh"], "name": "anchor"})
        d.doc["scenes"][0]["nodes"].append(len(d.doc["nodes"]) - 1)
    return _edited(folder, "drawn.glb", edit)


# -- physics ------------------------------------------------------------------------------
@trigger("PHYSICS_GEOMETRY_INVALID")
def _(folder):
    return _edited(folder, "collider_node.glb",
                   lambda d: _body(d)["collider"]["geometry"].update(node=99), _physics)


@trigger("PHYSICS_SHAPE_INVALID")
def _(folder):
    return _edited(folder, "flat_ground.glb", lambda d: d.doc["extensions"][SHAPES]["shapes"][0]
                   ["box"].update(size=[3.0, 0.0, 3.0]), _physics)


@trigger("PHYSICS_MOTION_INVALID")
def _(folder):
    return _edited(folder, "negative_mass.glb",
                   lambda d: _body(d)["motion"].update(mass=-1.0), _physics)


@trigger("PHYSICS_KIND_UNKNOWN")
def _(folder):
    return _edited(folder, "jelly.glb",
                   lambda d: d.doc["nodes"][0]["extras"]["gsverse"].update(physics="jelly"),
                   _physics)


@trigger("PHYSICS_KIND_MISMATCH")
def _(folder):
    return _edited(folder, "kinematic_moving.glb",
                   lambda d: d.doc["nodes"][0]["extras"]["gsverse"].update(physics="kinematic"),
                   _physics)


@trigger("PHYSICS_SOFT_NOT_ANCHORED")
def _(folder):
    def edit(d):
        d.doc["nodes"].append({"name": "cloth", "extras": {"gsverse": {"physics": "soft"}},
                               "extensions": {PHYSICS: copy.deepcopy(_body(d))}})
        d.doc["scenes"][0]["nodes"].append(len(d.doc["nodes"]) - 1)
    return _edited(folder, "soft_without_anchors.glb", edit, _physics)


@trigger("ANCHOR_SKIN_INVALID")
def _(folder):
    return _edited(folder, "skin-ibm.glb", lambda d: d.doc["skins"][0]["joints"].append(
        d.doc["skins"][0]["joints"][0]), _rigged)


@trigger("ANCHOR_SKIN_ATTRIBUTES_INVALID")
def _(folder):
    return _edited(folder, "skin-attrs.glb", lambda d: d.anchor_prim()["attributes"].pop(
        "JOINTS_0"), _rigged)


@trigger("ANCHOR_SKIN_WEIGHTS_NOT_NORMALIZED")
def _(folder):
    def edit(d):
        w = d.values(d.anchor_prim()["attributes"]["WEIGHTS_0"])
        w[:] *= 0.5
    return _edited(folder, "skin-weights.glb", edit, _rigged)


@trigger("ANCHOR_MORPH_TARGETS_INVALID")
def _(folder):
    return _edited(folder, "morph-weights.glb", lambda d: d.doc["meshes"][d.ext()["mesh"]][
        "weights"].append(0.0), _rigged)


@trigger("ANCHOR_ANIMATION_TARGET_INVALID")
def _(folder):
    return _edited(folder, "anim-target.glb", lambda d: d.doc["animations"][0]["channels"][0][
        "target"].update(node=999), _rigged)


@trigger("ANCHOR_ANIMATION_SAMPLER_INVALID")
def _(folder):
    def edit(d):   # key times 0, 1 become 0, -1: they decrease
        d.values(d.doc["animations"][0]["samplers"][0]["input"])[-1] = -1.0
    return _edited(folder, "anim-times.glb", edit, _rigged)


@trigger("ANCHOR_MESH_MULTIPLE_INSTANCES")
def _(folder):
    def edit(d):
        for name in ("anchor 1", "anchor 2"):
            d.doc["nodes"].append({"mesh": d.ext()["mesh"], "name": name})
            d.doc["scenes"][0]["nodes"].append(len(d.doc["nodes"]) - 1)
    return _edited(folder, "drawn-twice.glb", edit)


@trigger("ANCHOR_MESH_NOT_MANIFOLD")
def _(folder):
    # A lone triangle beside the closed anchor mesh: its three edges are boundary edges.
    def edit(d):
        v = d.doc["accessors"][d.anchor_prim()["attributes"]["POSITION"]]["count"]
        d.extend_anchor_mesh(vertices=[[3, 0, 0], [4, 0, 0], [3, 1, 0]], faces=[v, v + 1, v + 2])
    return _edited(folder, "open.glb", edit)


@trigger("MESH_DEGENERATE_TRIANGLES")
def _(folder):
    return _edited(folder, "degenerate.glb", lambda d: d.extend_anchor_mesh(faces=[0, 1, 1]))


@trigger("MESH_SLIVER_TRIANGLES")
def _(folder):
    # A triangle 1 long and 1e-4 high: regular (1e-4 > 1e-6) but a sliver (1e-4 <= 1e-3).
    def edit(d):
        v = d.doc["accessors"][d.anchor_prim()["attributes"]["POSITION"]]["count"]
        d.extend_anchor_mesh(vertices=[[-0.5, 0, 0], [0.5, 0, 0], [0, 1e-4, 0]],
                             faces=[v, v + 1, v + 2])
    return _edited(folder, "sliver.glb", edit)


@trigger("MESH_DUPLICATE_TRIANGLES")
def _(folder):
    def edit(d):
        first = d.values(d.anchor_prim()["indices"]).reshape(-1)[:3].tolist()
        d.extend_anchor_mesh(faces=first[1:] + first[:1])
    return _edited(folder, "duplicate.glb", edit)


@trigger("ANCHOR_ACCESSOR_FORMAT")
def _(folder):
    def edit(d):
        face = d.values(d.ext()["faceIndex"]).astype(np.float32)
        d.ext()["faceIndex"] = d.add_accessor(face, 5126, "SCALAR")
    return _edited(folder, "face_float.glb", edit)


@trigger("ANCHOR_ACCESSOR_COUNT")
def _(folder):
    def edit(d):
        bary = d.values(d.ext()["barycentrics"])
        d.ext()["barycentrics"] = d.add_accessor(bary[:-1], 5126, "VEC2")
    return _edited(folder, "bary_count.glb", edit)


@trigger("ANCHOR_ACCESSOR_TARGET")
def _(folder):
    def edit(d):
        acc = d.doc["accessors"][d.ext()["faceIndex"]]
        d.doc["bufferViews"][acc["bufferView"]]["target"] = 34962
    return _edited(folder, "target.glb", edit)


@trigger("ANCHOR_FACE_OUT_OF_RANGE")
def _(folder):
    return _edited(folder, "face_range.glb", lambda d: d.values(d.ext()["faceIndex"]).__setitem__(
        (-1, 0), 200))


@trigger("ANCHOR_BOUND_TO_DEGENERATE")
def _(folder):
    def edit(d):
        f = d.extend_anchor_mesh(faces=[0, 1, 1])
        d.values(d.ext()["faceIndex"])[-1, 0] = f - 1
    return _edited(folder, "bound_degenerate.glb", edit)


@trigger("GAMES_BARYCENTRICS_OUTSIDE_SIMPLEX")
def _(folder):
    return _edited(folder, "games_bary.glb", lambda d: d.values(d.ext()["barycentrics"])
                   .__setitem__(0, (0.9, 0.5)), base=_games)


@trigger("LOCAL_BARYCENTRICS_FAR")
def _(folder):
    return Trigger(Doc.of(local_asset(floater=True)).write(folder, "floater.glb"))


@trigger("ANCHOR_MESH_MISFIT")
def _(folder):
    return Trigger(Doc.of(local_asset(away=50.0)).write(folder, "misfit.glb"))


@trigger("LOCAL_SCALE_NOT_SHARED")
def _(folder):
    def edit(d):
        d.ext()["localScale"] = d.add_accessor(d.values(d.attr(SCALE)).copy(), 5126, "VEC3")
    return _edited(folder, "scale_copy.glb", edit)


@trigger("GAMES_RHO_NEGATIVE")
def _(folder):
    return Trigger(Doc.of(games_asset(negative_rho=True)).write(folder, "rho.glb"))


@trigger("ANCHOR_NOT_SORTED")
def _(folder):
    return Trigger(Doc.of(local_asset(shuffle=True)).write(folder, "unsorted.glb"))


def _compact() -> Doc:
    return Doc.of(local_asset(), anchors="compact")


@trigger("ANCHOR_FACE_COUNTS_COUNT")
def _(folder):
    def edit(d):
        counts = d.values(d.ext()["faceCounts"])[:, 0]
        d.ext()["faceCounts"] = d.add_accessor(np.append(counts, 0), 5125, "SCALAR")
    return _edited(folder, "counts_length.glb", edit, _compact)


@trigger("ANCHOR_FACE_COUNTS_SUM")
def _(folder):
    def edit(d):
        counts = d.values(d.ext()["faceCounts"])
        counts[int(np.argmax(counts[:, 0])), 0] -= 1
    return _edited(folder, "counts_sum.glb", edit, _compact)


@trigger("ANCHOR_DERIVED_ON_DEGENERATE")
def _(folder):
    def edit(d):
        prim = d.anchor_prim()
        counts = d.values(d.ext()["faceCounts"])[:, 0]
        f = int(np.flatnonzero(counts)[0])
        corners = d.values(prim["indices"]).reshape(-1)[3 * f:3 * f + 3]
        pos = d.values(prim["attributes"]["POSITION"])
        pos[corners[2]] = pos[corners[0]]
    return _edited(folder, "derived_degenerate.glb", edit, _compact)


# -- SPZ compression ----------------------------------------------------------------------
def _spz() -> Doc:
    return Doc.of(local_asset(), anchors="compact", compress="spz")


def _spz_ext(d: Doc) -> dict:
    return d.khr()["extensions"][SPZ_EXTENSION]


def _restream(d: Doc, edit: Callable[[bytearray], bytes]) -> None:
    """Replace the stream of the first primitive by ``edit`` of its inflated content, in a
    buffer view of its own."""
    view = d.doc["bufferViews"][_spz_ext(d)["bufferView"]]
    start = view.get("byteOffset", 0)
    data = bytearray(gzip.decompress(bytes(d.blob[start:start + view["byteLength"]])))
    stream = gzip.compress(bytes(edit(data)), mtime=0)
    d.blob += b"\0" * (-len(d.blob) % 4)
    d.doc["bufferViews"].append({"buffer": 0, "byteOffset": len(d.blob),
                                 "byteLength": len(stream)})
    d.blob += stream + b"\0" * (-len(stream) % 4)
    d.doc["buffers"][0]["byteLength"] = len(d.blob)
    _spz_ext(d)["bufferView"] = len(d.doc["bufferViews"]) - 1


@trigger("SPZ_STREAM_INVALID")
def _(folder):
    return _edited(folder, "spz_truncated.glb", lambda d: _restream(d, lambda b: b[:-9]), _spz)


@trigger("SPZ_COUNT_MISMATCH")
def _(folder):
    def edit(d):
        _restream(d, lambda b: b[:8] + struct.pack("<I", struct.unpack_from("<I", b, 8)[0] - 1)
                  + b[12:])
    return _edited(folder, "spz_count.glb", edit, _spz)


@trigger("SPZ_SH_MISMATCH")
def _(folder):
    return _edited(folder, "spz_degree.glb",
                   lambda d: _restream(d, lambda b: b[:12] + b"\x00" + b[13:]), _spz)


@trigger("SPZ_BUFFER_VIEW_INVALID")
def _(folder):
    return _edited(folder, "spz_view.glb", lambda d: _spz_ext(d).update(bufferView=999), _spz)


@trigger("SPZ_EXPLICIT_ANCHORS")
def _(folder):
    def edit(d):
        explicit = Doc.of(local_asset(), anchors="explicit")
        ext = explicit.ext()
        for key in ("barycentrics", "normalOffset", "localRotation", "localScale"):
            d.ext()[key] = d.add_accessor(explicit.values(ext[key]), explicit.doc["accessors"][
                ext[key]]["componentType"], explicit.doc["accessors"][ext[key]]["type"])
    return _edited(folder, "spz_explicit.glb", edit, _spz)


# -- rest pose ----------------------------------------------------------------------------
@trigger("REST_POSE_MEAN_MISMATCH")
def _(folder):
    return _edited(folder, "moved.glb", lambda d: d.values(d.attr("POSITION")).__setitem__(
        (5, 0), d.values(d.attr("POSITION"))[5, 0] + 0.05))


@trigger("REST_POSE_COVARIANCE_MISMATCH")
def _(folder):
    def edit(d):
        q = Rotation.from_quat(d.values(d.attr(ROTATION))[7]) * Rotation.from_euler("x", 30,
                                                                                    degrees=True)
        d.values(d.attr(ROTATION))[7] = q.as_quat()
    return _edited(folder, "turned.glb", edit)


# -- validator ----------------------------------------------------------------------------
@trigger("INTERNAL_ERROR")
def _(folder):
    trig = Trigger(_local().write(folder, "fault.glb"))
    trig.fault = True
    return trig


import validation_assets_input  # noqa: E402,F401  (registers the issues_input triggers)
