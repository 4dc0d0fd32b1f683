"""Remap cases that store the same kind of asset in other valid glTF encodings.

The remap cases of :mod:`.cases` are written by the package's writer, which always uses one
layout: tightly packed FLOAT accessors (bar the quantized anchor cases), an indexed anchor
mesh, and a splat node without a transform. A plugin's importer must read every encoding the
spec and glTF 2.0 allow. Each case here edits the written, rest-consistent asset
(:attr:`RemapCase.edit`); the expected outputs come from the edited file as read back:

* ``local-*-local-scale-*``: ``localScale`` as UNSIGNED_BYTE / UNSIGNED_SHORT, normalized and
  not (dequantized as ``KHR_gaussian_splatting:SCALE``), shared with ``SCALE`` or not;
* ``*-rest-quantized``: the rest pose quantized as ``KHR_gaussian_splatting`` allows
  (ROTATION normalized SHORT / BYTE, SCALE normalized and unnormalized UNSIGNED_SHORT, OPACITY
  normalized UNSIGNED_BYTE / UNSIGNED_SHORT), with the anchors adjusted so that the asset
  stays rest-consistent;
* ``*-byte-stride``: interleaved buffer views (``byteStride``) for the anchor accessors, the
  splat attributes and the anchor mesh ``POSITION``;
* ``*-non-indexed``: an anchor primitive without ``indices`` (triangle f = vertices 3f..3f+2);
* ``*-node-transforms``: transforms on the node of the splat mesh and on a node that
  instantiates the anchor mesh; the remap is in the splat primitive's local space and the
  anchor node's transform is ignored, so the expected outputs do not change.
"""
from __future__ import annotations

from typing import Any, cast

import numpy as np

from .. import quaternion as quat
from ..model import TriangleMesh
from .case_tools import (LAWS, Pose, RemapCase, bend, case_rng, faces_from_counts, law_id,
                         law_tags, make_anchors, make_case, random_barycentrics, stretch,
                         tube_mesh, twist)
from .glb import (BYTE, COMPONENT_DTYPES, FLOAT, SHORT, TYPE_COMPONENTS, UNSIGNED_BYTE,
                  UNSIGNED_SHORT, accessor_bytes, anchor_extension, anchor_primitive,
                  anchored_primitive, append_accessor, patch_accessor)

__all__ = ["encoding_cases"]


def _dtype(component_type: int) -> np.dtype[Any]:
    """The numpy dtype of a glTF component type."""
    return cast("np.dtype[Any]", COMPONENT_DTYPES[component_type])


_KHR = "KHR_gaussian_splatting"
_ROTATION, _SCALE, _OPACITY = f"{_KHR}:ROTATION", f"{_KHR}:SCALE", f"{_KHR}:OPACITY"
_ARRAY_BUFFER = 34962
_TOP = {UNSIGNED_BYTE: 255, UNSIGNED_SHORT: 65535, BYTE: 127, SHORT: 32767}
_NAMES = {UNSIGNED_BYTE: "unsigned_byte", UNSIGNED_SHORT: "unsigned_short", BYTE: "byte",
          SHORT: "short"}


def _describe(profile: str, law: str | None) -> str:
    return f"{profile} profile{f', {law} law' if law else ''}"


# --------------------------------------------------------------------------- GLB editing

def _bounds(doc: dict, index: int):
    acc = doc["accessors"][index]
    return (acc["min"], acc["max"]) if "min" in acc else None


def _interleave(doc: dict, blob: bytes, fields: list, *, target: int | None = None,
                stride: int | None = None) -> tuple[list[int], bytes]:
    """Append one buffer view holding ``fields`` interleaved and one accessor per field.

    ``fields``: (values (n, k), componentType, accessor type, normalized, (min, max) or None).
    Every field starts at a multiple of 4 bytes within the element (as glTF requires of vertex
    attributes); ``byteStride`` is the element size rounded up to 4 (or ``stride``).
    """
    n = len(fields[0][0])
    offsets, pos = [], 0
    for _, ctype, gtype, _, _ in fields:
        pos += -pos % 4
        offsets.append(pos)
        pos += _dtype(ctype).itemsize * TYPE_COMPONENTS[gtype]
    stride = max(pos + (-pos % 4), stride or 0)
    data = bytearray(n * stride)
    for (values, ctype, gtype, _, _), off in zip(fields, offsets):
        dtype = _dtype(ctype)
        k = TYPE_COMPONENTS[gtype]
        view = np.ndarray((n, k), dtype=dtype, buffer=data, offset=off,
                          strides=(stride, dtype.itemsize))
        view[...] = np.asarray(values).reshape(n, k)
    blob = blob + b"\0" * (-len(blob) % 4)
    bv = {"buffer": 0, "byteOffset": len(blob), "byteLength": len(data), "byteStride": stride}
    if target is not None:
        bv["target"] = target
    doc["bufferViews"].append(bv)
    blob += bytes(data)
    doc["buffers"][0]["byteLength"] = len(blob)
    out = []
    for (_, ctype, gtype, normalized, bounds), off in zip(fields, offsets):
        acc = {"bufferView": len(doc["bufferViews"]) - 1, "byteOffset": off,
               "componentType": ctype, "count": n, "type": gtype}
        if normalized:
            acc["normalized"] = True
        if bounds is not None:
            acc["min"], acc["max"] = bounds
        doc["accessors"].append(acc)
        out.append(len(doc["accessors"]) - 1)
    return out, blob


def _codes(values: np.ndarray, ctype: int, normalized: bool) -> tuple[np.ndarray, np.ndarray]:
    """(integer codes, their dequantized float64 values) for ``values``; unsigned codes are at
    least 1 (no splat scale or opacity collapses to exactly 0 by the re-encoding)."""
    top = _TOP[ctype]
    low = -top if ctype in (BYTE, SHORT) else 1
    codes = np.clip(np.rint(values * top if normalized else values), low, top)
    deq = np.maximum(codes / top, -1.0) if normalized else codes
    return codes, deq


def _unbind_target(doc: dict, index: int) -> None:
    """Drop ``target`` from the buffer view of accessor ``index`` (it holds anchor data)."""
    doc["bufferViews"][doc["accessors"][index]["bufferView"]].pop("target", None)


def _local_scale_edit(ctype: int, normalized: bool, shared: bool):
    def edit(doc, blob):
        """Store localScale as integers (shared with SCALE, or SCALE kept FLOAT with the
        dequantized values): the rest pose keeps the scales the remap uses."""
        attrs = anchored_primitive(doc)["attributes"]
        ext = anchor_extension(doc)
        codes, deq = _codes(accessor_bytes(doc, blob, ext["localScale"]).astype(np.float64),
                            ctype, normalized)
        if shared:   # a vertex attribute: 4-byte aligned elements, so a padded stride
            (ext["localScale"],), blob = _interleave(doc, blob,
                                                     [(codes, ctype, "VEC3", normalized, None)],
                                                     target=_ARRAY_BUFFER)
            attrs[_SCALE] = ext["localScale"]
        else:        # anchor data only: tightly packed
            blob = patch_accessor(doc, blob, attrs[_SCALE], deq.astype(np.float32))
            ext["localScale"], blob = append_accessor(doc, blob, codes, ctype, "VEC3",
                                                      normalized)
        return doc, blob
    return edit


def _rest_quantized_edit(rotation: int | None, scale: tuple[int, bool] | None,
                         opacity: int | None):
    def edit(doc, blob):
        """Quantize the rest pose; for ``local``, adjust localRotation (and give localScale
        its own FLOAT accessor) so that the remap at rest still returns the stored pose."""
        attrs = anchored_primitive(doc)["attributes"]
        ext = anchor_extension(doc)
        local = ext["profile"] == "local"
        if rotation is not None:
            q = accessor_bytes(doc, blob, attrs[_ROTATION]).astype(np.float64)
            codes, deq = _codes(q, rotation, True)
            deq = deq / np.linalg.norm(deq, axis=1, keepdims=True)
            if local:   # R_r R_l' = R(deq) with R_r = R(q) R_lᵀ
                q_l = accessor_bytes(doc, blob, ext["localRotation"]).astype(np.float64)
                new = quat.normalize(quat.multiply(q_l, quat.multiply(quat.conjugate(q), deq)))
                blob = patch_accessor(doc, blob, ext["localRotation"], new.astype(np.float32))
            (attrs[_ROTATION],), blob = _interleave(doc, blob,
                                                    [(codes, rotation, "VEC4", True, None)],
                                                    target=_ARRAY_BUFFER)
        if scale is not None:
            ctype, normalized = scale
            s = accessor_bytes(doc, blob, attrs[_SCALE]).astype(np.float64)
            codes, deq = _codes(s, ctype, normalized)
            if local and ext["localScale"] == attrs[_SCALE]:
                blob = patch_accessor(doc, blob, ext["localScale"], deq.astype(np.float32))
                _unbind_target(doc, ext["localScale"])
            (attrs[_SCALE],), blob = _interleave(doc, blob,
                                                 [(codes, ctype, "VEC3", normalized, None)],
                                                 target=_ARRAY_BUFFER)
        if opacity is not None:
            o = accessor_bytes(doc, blob, attrs[_OPACITY]).astype(np.float64)
            codes, _ = _codes(o, opacity, True)
            (attrs[_OPACITY],), blob = _interleave(doc, blob,
                                                   [(codes, opacity, "SCALAR", True, None)],
                                                   target=_ARRAY_BUFFER)
        return doc, blob
    return edit


def _field(doc: dict, blob: bytes, index: int, with_bounds: bool = False):
    acc = doc["accessors"][index]
    return (accessor_bytes(doc, blob, index), acc["componentType"], acc["type"],
            bool(acc.get("normalized", False)), _bounds(doc, index) if with_bounds else None)


def _stride_edit(doc, blob):
    """Interleave the splat attributes POSITION/ROTATION/SCALE, the anchor accessors, and the
    anchor mesh POSITION with a TEXCOORD_0, each group in one buffer view with byteStride."""
    attrs = anchored_primitive(doc)["attributes"]
    ext = anchor_extension(doc)
    shared = ext.get("localScale") == attrs[_SCALE]
    names = ["POSITION", _ROTATION, _SCALE]
    new, blob = _interleave(doc, blob, [_field(doc, blob, attrs[n], n == "POSITION")
                                        for n in names], target=_ARRAY_BUFFER)
    attrs.update(zip(names, new))
    if shared:
        ext["localScale"] = attrs[_SCALE]
    # the anchor accessors: faceIndex last, so that every field of the element is read at an
    # offset other than 0 except the first
    props = [p for p in ("barycentrics", "normalOffset", "rho", "localRotation", "faceIndex")
             if p in ext]
    new, blob = _interleave(doc, blob, [_field(doc, blob, ext[p]) for p in props])
    ext.update(zip(props, new))
    aprim = anchor_primitive(doc)
    pos = aprim["attributes"]["POSITION"]
    v = accessor_bytes(doc, blob, pos).astype(np.float64)
    uv = np.stack([np.arctan2(v[:, 2], v[:, 0]) / (2 * np.pi) + 0.5, v[:, 1]], axis=1)
    (aprim["attributes"]["POSITION"], aprim["attributes"]["TEXCOORD_0"]), blob = _interleave(
        doc, blob, [_field(doc, blob, pos, True), (uv, FLOAT, "VEC2", False, None)],
        target=_ARRAY_BUFFER)
    return doc, blob


def _non_indexed_edit(doc, blob):
    """Drop the anchor primitive's indices (the mesh is a soup: indices were 0, 1, 2, ...)."""
    aprim = anchor_primitive(doc)
    idx = accessor_bytes(doc, blob, aprim["indices"])[:, 0]
    assert np.array_equal(idx, np.arange(len(idx))), "the mesh of a non-indexed case is a soup"
    del aprim["indices"]
    return doc, blob


def _axis_angle(axis, degrees: float) -> list[float]:
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    half = np.radians(degrees) / 2.0
    return [float(x) for x in np.sin(half) * axis] + [float(np.cos(half))]


def _matrix(translation, rotation, scale) -> list[float]:
    """Column-major 4x4 T·R·S, as glTF stores node.matrix."""
    m = np.eye(4)
    m[:3, :3] = quat.to_matrix(np.asarray(rotation)) * np.asarray(scale, dtype=np.float64)
    m[:3, 3] = translation
    return [float(x) for x in m.T.ravel()]


def _node_edit(variant: str):
    def edit(doc, blob):
        """Transforms on the splat node and a node instantiating the anchor mesh."""
        splat_mesh = next(i for i, mesh in enumerate(doc["meshes"])
                          if any(p is anchored_primitive(doc) for p in mesh["primitives"]))
        node = next(n for n in doc["nodes"] if n.get("mesh") == splat_mesh)
        anchor = {"mesh": anchor_extension(doc)["mesh"], "name": "anchor mesh (deformation source)"}
        if variant == "trs":
            node.update(translation=[0.5, -1.25, 2.0], rotation=_axis_angle((1, 2, -0.5), 70),
                        scale=[2.0, 0.5, 1.25])
            anchor.update(translation=[-3.0, 0.25, 1.0], rotation=_axis_angle((0, 1, 1), -40),
                          scale=[0.75, 1.5, 3.0])
        elif variant == "matrix":
            node["matrix"] = _matrix([1.0, 2.0, -0.5], _axis_angle((0.3, -1, 0.2), 125),
                                     [2.5, 2.5, 2.5])
            anchor["matrix"] = _matrix([0.0, -4.0, 0.0], _axis_angle((1, 0, 0), 90),
                                       [0.4, 0.4, 0.4])
        else:   # the anchor node is a child of a transformed parent
            node.update(translation=[0.0, 3.0, 0.0], scale=[1.0, 1.0, -1.0])
            anchor.update(translation=[0.25, 0.0, -0.75], rotation=_axis_angle((1, 1, 1), 33),
                          scale=[2.0, 2.0, 2.0])
        doc["nodes"].append(anchor)
        if variant == "child":
            parent = {"name": "parent", "children": [len(doc["nodes"]) - 1],
                      "translation": [5.0, 0.0, 0.0], "scale": [0.5, 3.0, 0.5]}
            doc["nodes"].append(parent)
        doc["scenes"][doc.get("scene", 0)]["nodes"].append(len(doc["nodes"]) - 1)
        return doc, blob
    return edit


# --------------------------------------------------------------------------- cases

def _tube_poses(mesh: TriangleMesh, height: float) -> list[Pose]:
    v = mesh.vertices.astype(np.float64)
    c = (0.0, 0.0, 0.0)
    return [Pose("rest", mesh.vertices, {"kind": "rest"}),
            Pose("twist 75", twist(v, 75, c, 0.0, height), {"kind": "analytic", "name": "twist"}),
            Pose("bend 90 + stretch", stretch(bend(v, 90, c, 0.0, height), (1.3, 0.8, 1.1), c),
                 {"kind": "analytic", "name": "bend+stretch"})]


def _small(profile: str, law: str | None, cid: str, *, size: float = 1.0,
           soup: bool = False, **kw):
    """A small tube (scaled by ``size``; a triangle soup when ``soup``), about 32 splats."""
    rng = case_rng(cid)
    mesh = tube_mesh(radius=0.25 * size, height=size)
    if soup:
        mesh = TriangleMesh(mesh.vertices[mesh.faces.reshape(-1)],
                            np.arange(3 * mesh.face_count).reshape(-1, 3))
    face = faces_from_counts(rng.integers(0, 2, mesh.face_count))
    anchors = make_anchors(profile, law, mesh, face, random_barycentrics(rng, len(face)), rng, **kw)
    return rng, mesh, anchors, _tube_poses(mesh, size)


def _local_scale_cases() -> list[RemapCase]:
    # (law, componentType, normalized, shared with SCALE, mesh size, splat scale / face size)
    specs = [("affine", UNSIGNED_BYTE, True, True, 1.0, 1.0),
             ("rigid", UNSIGNED_SHORT, True, True, 1.0, 0.5),
             ("rigid", UNSIGNED_BYTE, False, True, 200.0, 1.0),
             ("affine", UNSIGNED_SHORT, False, False, 2000.0, 1.0)]
    out = []
    for law, ctype, normalized, shared, size, scale in specs:
        kind = ("u8" if ctype == UNSIGNED_BYTE else "u16") + ("-normalized" if normalized else "")
        cid = f"local-{law}-local-scale-{kind}"
        rng, mesh, anchors, poses = _small("local", law, cid, size=size, scale=scale)
        value = "c/255" if ctype == UNSIGNED_BYTE else "c/65535"
        how = (f"normalized {_NAMES[ctype].upper()} (scale = {value})" if normalized
               else f"{_NAMES[ctype].upper()}, not normalized (scale = the integer c; a tube "
               f"of height {size:g} so that the scales are integers of the scene's size)")
        where = ("shared with KHR_gaussian_splatting:SCALE (the rest pose reads the same "
                 "dequantized values)" if shared else "in its own accessor; SCALE stays FLOAT "
                 "with the dequantized values")
        tag = f"{_NAMES[ctype]}{'_normalized' if normalized else ''}"
        out.append(make_case(cid, f"local profile, {law} law: localScale stored as {how}, {where}. "
                             f"The remap uses the dequantized localScale.",
                             law_tags("local", law) + [f"encoding:localScale={tag}"]
                             + (["encoding:localScale-normalized"] if normalized else []),
                             mesh, anchors, poses, rng, 1, edit=_local_scale_edit(ctype, normalized,
                                                                                  shared)))
    return out


def _rest_quantized_cases() -> list[RemapCase]:
    # (profile, law, ROTATION, SCALE (type, normalized), OPACITY, mesh size)
    specs = [("local", "affine", SHORT, (UNSIGNED_SHORT, True), UNSIGNED_BYTE, 1.0),
             ("local", "rigid", BYTE, (UNSIGNED_SHORT, False), UNSIGNED_BYTE, 100.0),
             ("games", None, None, None, UNSIGNED_SHORT, 1.0)]
    out = []
    for profile, law, rotation, scale, opacity, size in specs:
        cid = f"{law_id(profile, law)}-rest-quantized"
        rng, mesh, anchors, poses = _small(profile, law, cid, size=size)
        parts = []
        if rotation is not None:
            parts.append(f"ROTATION as normalized {_NAMES[rotation].upper()}")
        if scale is not None:
            parts.append(f"SCALE as normalized {_NAMES[scale[0]].upper()}" if scale[1]
                         else f"SCALE as {_NAMES[scale[0]].upper()} (not normalized)")
        parts.append(f"OPACITY as normalized {_NAMES[opacity].upper()}")
        if profile == "local":
            note = ("localRotation is adjusted (and localScale kept FLOAT with the dequantized "
                    "scales) so that the remap at rest still returns the quantized rest pose; "
                    "readers dequantize per glTF and renormalize ROTATION")
        else:
            note = ("ROTATION and SCALE stay FLOAT: a games rest pose is fixed by the triangles, "
                    "so quantizing it would break rest-pose consistency")
        out.append(make_case(cid, f"{_describe(profile, law)}: the rest pose quantized as "
                             f"KHR_gaussian_splatting allows ({', '.join(parts)}, 4-byte aligned "
                             f"with byteStride where the element is shorter); {note}. The rest "
                             f"dumps are the dequantized values.",
                             law_tags(profile, law) + ["encoding:rest-quantized"], mesh, anchors,
                             poses, rng, 2, edit=_rest_quantized_edit(rotation, scale, opacity)))
    return out


def _stride_cases() -> list[RemapCase]:
    quantize = {"affine": {"barycentrics": "unsigned_short"}, "rigid": {"localRotation": "byte"},
                None: None}
    tags = {"affine": ["quantized:barycentrics=unsigned_short"],
            "rigid": ["quantized:localRotation=byte"], None: []}
    out = []
    for profile, law in LAWS:
        cid = f"{law_id(profile, law)}-byte-stride"
        rng, mesh, anchors, poses = _small(profile, law, cid)
        q = quantize[law]
        extra = (f" ({', '.join(f'{k} as normalized {v.upper()}' for k, v in q.items())})"
                 if q else "")
        out.append(make_case(cid, f"{_describe(profile, law)}: interleaved buffer views. The "
                             f"anchor accessors{extra} share one buffer view with byteStride, at "
                             f"byte offsets inside the element; POSITION, ROTATION and SCALE of "
                             f"the splats{' (SCALE also as localScale)' if law else ''} share "
                             f"another; the anchor mesh POSITION is interleaved with a TEXCOORD_0. "
                             f"Read every accessor with its bufferView's byteStride and its "
                             f"byteOffset.",
                             law_tags(profile, law) + ["encoding:byte-stride"] + tags[law], mesh,
                             anchors, poses, rng, 0, quantize=q, edit=_stride_edit))
    return out


def _non_indexed_cases() -> list[RemapCase]:
    out = []
    for profile, law in LAWS:
        cid = f"{law_id(profile, law)}-non-indexed"
        rng, mesh, anchors, poses = _small(profile, law, cid, soup=True)
        out.append(make_case(cid, f"{_describe(profile, law)}: the anchor primitive has no indices "
                             f"(a tube stored as a triangle soup of {mesh.face_count} triangles): "
                             f"triangle f has corners = vertices 3f, 3f + 1, 3f + 2, and F is the "
                             f"vertex count divided by 3.",
                             law_tags(profile, law) + ["encoding:non-indexed"], mesh, anchors,
                             poses, rng, 1, edit=_non_indexed_edit))
    return out


def _node_cases() -> list[RemapCase]:
    text = {"trs": "translation, rotation and non-uniform scale on both nodes",
            "matrix": "a matrix with uniform scale on the splat node, another matrix on the "
            "anchor node",
            "child": "a translation and a mirroring scale on the splat node; the anchor node "
            "(translation, rotation, uniform scale) is the child of a parent node "
            "with non-uniform scale"}
    variants = {"affine": "trs", "rigid": "matrix", None: "child"}
    out = []
    for profile, law in LAWS:
        cid = f"{law_id(profile, law)}-node-transforms"
        variant = variants[law]
        rng, mesh, anchors, poses = _small(profile, law, cid)
        out.append(make_case(cid, f"{_describe(profile, law)}: node transforms ({text[variant]}). "
                             f"The remap is in the splat primitive's local space and the transform "
                             f"of the node that instantiates the anchor mesh is ignored for "
                             f"anchoring (spec section 'The anchor mesh'), so the expected outputs "
                             f"are those of the same asset without any transform: dump them in the "
                             f"splat primitive's local space, before the splat node's transform.",
                             law_tags(profile, law) + ["encoding:node-transforms"], mesh, anchors,
                             poses, rng, 2, edit=_node_edit(variant),
                             validator_codes=["ANCHOR_MESH_INSTANTIATED"],
                             note="gsverse-validate warns that a node instantiates the anchor mesh "
                             "(the spec says SHOULD NOT); one node is allowed, and its "
                             "transform is ignored for anchoring."))
    return out


def encoding_cases() -> list[RemapCase]:
    """The cases of this module, in suite order."""
    return (_local_scale_cases() + _rest_quantized_cases() + _stride_cases()
            + _non_indexed_cases() + _node_cases())
