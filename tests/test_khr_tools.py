"""Checks of KHR_gaussian_splatting files with two third-party tools.

The Khronos glTF-Validator and the PlayCanvas engine's glTF parser run under
Node.js through :mod:`khr_tools`; these tests skip when ``tests/js`` has not
been installed (``npm ci`` there).  Expected values are decoded here
independently with pygltflib and numpy.  With GSVERSE_REQUIRE_NODE_TOOLS=1
a missing installation fails them instead.
"""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import numpy as np
import pygltflib
import pytest

import khr_tools


@pytest.fixture(autouse=True)
def _node_tools() -> None:
    khr_tools.require_node_tools()


KHR = "KHR_gaussian_splatting"
ANCHOR_EXT = "GSVERSE_gaussian_splatting_mesh_anchor"
SH_C0 = 0.28209479177387814

_DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


# ---------------------------------------------------------------- decoding


def read_accessor(gltf: pygltflib.GLTF2, blob: bytes, index: int) -> np.ndarray:
    """Accessor -> float32 (count, ncomp), dequantizing normalized integers per glTF 2.0."""
    acc = gltf.accessors[index]
    view = gltf.bufferViews[acc.bufferView]
    dtype = np.dtype(_DTYPES[acc.componentType])
    ncomp = _NCOMP[acc.type]
    item = dtype.itemsize * ncomp
    stride = view.byteStride or item
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    rows = b"".join(blob[start + i * stride : start + i * stride + item] for i in range(acc.count))
    raw = np.frombuffer(rows, dtype=dtype).reshape(acc.count, ncomp).astype(np.float64)
    if acc.normalized:
        scale = float(np.iinfo(dtype).max)
        raw = np.maximum(raw / scale, -1.0)
    return raw.astype(np.float32)


def decode_khr_primitive(gltf: pygltflib.GLTF2, blob: bytes, mesh: int) -> dict:
    """Independent decode of the first primitive of ``mesh`` (KHR conventions)."""
    attrs = _attributes(gltf.meshes[mesh].primitives[0])
    get = lambda name: read_accessor(gltf, blob, attrs[name])  # noqa: E731
    degree = 0
    while degree < 3 and all(
        f"{KHR}:SH_DEGREE_{degree + 1}_COEF_{n}" in attrs for n in range(2 * degree + 3)
    ):
        degree += 1
    sh = [get(f"{KHR}:SH_DEGREE_{l}_COEF_{n}") for l in range(degree + 1) for n in range(2 * l + 1)]
    return {
        "position": get("POSITION"),
        "rotation": get(f"{KHR}:ROTATION"),
        "scale": get(f"{KHR}:SCALE"),
        "opacity": get(f"{KHR}:OPACITY")[:, 0],
        "sh": np.stack(sh, axis=1),
        "sh_degree": degree,
    }


def _attributes(primitive: pygltflib.Primitive) -> dict[str, int]:
    return {k: v for k, v in json.loads(primitive.attributes.to_json()).items() if v is not None}


def assert_splats_equal(got: dict, want: dict) -> None:
    """Values must agree to float32 precision."""
    for key in ("position", "rotation", "scale", "opacity", "sh"):
        assert got[key].shape == want[key].shape, key
        np.testing.assert_allclose(got[key], want[key], rtol=2e-7, atol=0, err_msg=key)
    assert got["sh_degree"] == want["sh_degree"]


# ---------------------------------------------------------------- tiny file


def _pad4(b: bytes) -> bytes:
    return b + b"\0" * (-len(b) % 4)


def build_tiny_khr_glb(path: Path) -> dict:
    """Write a 3-splat SH-degree-1 KHR GLB with an unused anchor mesh and a nested extension.

    Returns the splat values written (KHR conventions, file order).
    """
    rng = np.random.default_rng(7)
    # Positions in reverse Morton order, so the engine's reordering shows.
    position = np.array([[1.0, 1.0, 1.0], [0.25, 0.5, 0.75], [0.0, 0.0, 0.0]], np.float32)
    q = rng.normal(size=(3, 4))
    rotation = (q / np.linalg.norm(q, axis=1, keepdims=True)).astype(np.float32)
    scale = np.array([[0.01, 0.02, 0.03], [0.5, 0.25, 0.125], [1.5, 0.001, 0.2]], np.float32)
    opacity = np.array([0.05, 0.5, 0.99], np.float32)
    sh = rng.normal(scale=0.3, size=(3, 4, 3)).astype(np.float32)
    rgb = np.clip(0.5 + SH_C0 * sh[:, 0], 0, 1)
    color = np.round(np.concatenate([rgb, opacity[:, None]], axis=1) * 255).astype(np.uint8)

    tri_pos = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    tri_idx = np.array([0, 1, 2, 0, 2, 3], np.uint16)
    face = np.array([0, 1, 1], np.uint8)
    bary = np.array([[0.2, 0.3], [0.5, 0.5], [0.1, 0.1]], np.float32)
    normal_offset = np.array([0.0, 0.01, -0.02], np.float32)

    blob = bytearray()
    views: list[pygltflib.BufferView] = []
    accessors: list[pygltflib.Accessor] = []

    def add(
        arr: np.ndarray, ctype: int, atype: str, target: int | None, normalized: bool = False, bounds: bool = False
    ) -> int:
        view = pygltflib.BufferView(buffer=0, byteOffset=len(blob), byteLength=arr.nbytes, target=target)
        views.append(view)
        blob.extend(_pad4(arr.tobytes()))
        flat = arr.reshape(len(arr), -1)
        accessors.append(
            pygltflib.Accessor(
                bufferView=len(views) - 1,
                componentType=ctype,
                count=len(arr),
                type=atype,
                normalized=normalized or None,
                min=flat.min(axis=0).tolist() if bounds else None,
                max=flat.max(axis=0).tolist() if bounds else None,
            )
        )
        return len(accessors) - 1

    F, U8, U16, VTX, IDX = 5126, 5121, 5123, 34962, 34963
    attrs = {
        "POSITION": add(position, F, "VEC3", VTX, bounds=True),
        f"{KHR}:ROTATION": add(rotation, F, "VEC4", VTX),
        f"{KHR}:SCALE": add(scale, F, "VEC3", VTX),
        f"{KHR}:OPACITY": add(opacity, F, "SCALAR", VTX),
        "COLOR_0": add(color, U8, "VEC4", VTX, normalized=True),
    }
    for l in range(2):
        for n in range(2 * l + 1):
            coef = np.ascontiguousarray(sh[:, l * l + n])
            attrs[f"{KHR}:SH_DEGREE_{l}_COEF_{n}"] = add(coef, F, "VEC3", VTX)
    anchor = {
        "mesh": 1,
        "primitive": 0,
        "profile": "local",
        "deformation": "affine",
        "faceIndex": add(face, U8, "SCALAR", None),
        "barycentrics": add(bary, F, "VEC2", None),
        "normalOffset": add(normal_offset, F, "SCALAR", None),
        "localRotation": add(rotation, F, "VEC4", None),
        "localScale": attrs[f"{KHR}:SCALE"],
    }
    tri_attrs = {"POSITION": add(tri_pos, F, "VEC3", VTX, bounds=True)}
    tri_indices = add(tri_idx, U16, "SCALAR", IDX)

    tri_prim = pygltflib.Primitive(attributes=pygltflib.Attributes(**tri_attrs), indices=tri_indices, mode=4)
    splat_prim = pygltflib.Primitive(
        attributes=pygltflib.Attributes(**{"POSITION": attrs["POSITION"], "COLOR_0": attrs["COLOR_0"]}),
        mode=0,
        extensions={
            KHR: {
                "kernel": "ellipse",
                "colorSpace": "srgb_rec709_display",
                "projection": "perspective",
                "sortingMethod": "cameraDistance",
                "extensions": {ANCHOR_EXT: anchor},
            }
        },
    )
    # pygltflib's Attributes only declares core semantics; add the KHR ones.
    for name, idx in attrs.items():
        setattr(splat_prim.attributes, name, idx)
    gltf = pygltflib.GLTF2(
        asset=pygltflib.Asset(version="2.0", generator="gsverse-format tests"),
        extensionsUsed=[KHR, ANCHOR_EXT],
        scene=0,
        scenes=[pygltflib.Scene(nodes=[0])],
        nodes=[pygltflib.Node(mesh=0, name="splats")],
        meshes=[
            pygltflib.Mesh(name="splats", primitives=[splat_prim]),
            pygltflib.Mesh(name="anchor", primitives=[tri_prim]),
        ],
        accessors=accessors,
        bufferViews=views,
        buffers=[pygltflib.Buffer(byteLength=len(blob))],
    )
    gltf.set_binary_blob(bytes(blob))
    gltf.save_binary(str(path))
    return {
        "position": position,
        "rotation": rotation,
        "scale": scale,
        "opacity": opacity,
        "sh": sh,
        "sh_degree": 1,
    }


@pytest.fixture
def tiny_glb(tmp_path: Path) -> tuple[Path, dict]:
    path = tmp_path / "tiny.glb"
    return path, build_tiny_khr_glb(path)


def _load(path: Path) -> tuple[pygltflib.GLTF2, bytes]:
    gltf = pygltflib.GLTF2().load(str(path))
    return gltf, gltf.binary_blob()


def _rewrite_json(src: Path, dst: Path, edit) -> None:
    gltf, blob = _load(src)
    doc = json.loads(gltf.to_json())
    edit(doc)
    out = pygltflib.GLTF2.from_json(json.dumps(doc))
    out.set_binary_blob(blob)
    out.save_binary(str(dst))


def _unexpected_errors(report: dict) -> list[dict]:
    return [m for m in report["messages"] if m["severity"] == "Error" and not m["expectedKhrAttribute"]]


def _by_severity(report: dict, severity: str) -> Counter:
    return Counter(m["code"] for m in report["messages"] if m["severity"] == severity)


# ---------------------------------------------------------------- validator


def test_validator_on_bevy_conformance_matrix(shared_data: Path) -> None:
    path = shared_data / "khr_gaussian" / "bevy_khr_conformance_matrix.glb"
    gltf, _ = _load(path)
    report = khr_tools.validate_gltf(path)
    assert report["validatorVersion"] == "2.0.0-dev.3.10"
    assert not report["truncated"]

    # Every KHR attribute of every primitive gets the "unknown attribute" error.
    khr_pointers = set()
    unaligned = set()
    unbounded = set()
    for m, mesh in enumerate(gltf.meshes):
        attrs = _attributes(mesh.primitives[0])
        for name, idx in attrs.items():
            pointer = f"/meshes/{m}/primitives/0/attributes/{name}"
            if name.startswith(KHR + ":"):
                khr_pointers.add(pointer)
            acc = gltf.accessors[idx]
            size = np.dtype(_DTYPES[acc.componentType]).itemsize * _NCOMP[acc.type]
            offset = (gltf.bufferViews[acc.bufferView].byteOffset or 0) + (acc.byteOffset or 0)
            if size % 4 or offset % 4:
                unaligned.add(pointer)
            if name == "POSITION" and not (acc.min and acc.max):
                unbounded.add(pointer)
    expected = {m["pointer"] for m in report["messages"] if m["expectedKhrAttribute"]}
    assert expected == khr_pointers and len(khr_pointers) == 86
    assert all(
        m["code"] == "MESH_PRIMITIVE_INVALID_ATTRIBUTE" and m["severity"] == "Error"
        for m in report["messages"]
        if m["expectedKhrAttribute"]
    )

    # The rest is real: 8/16-bit quantized attributes without 4-byte padding,
    # and POSITION accessors without min/max.
    unexpected = _unexpected_errors(report)
    pointers = lambda code: {m["pointer"] for m in unexpected if m["code"] == code}  # noqa: E731
    assert pointers("MESH_PRIMITIVE_ACCESSOR_UNALIGNED") == unaligned
    assert pointers("MESH_PRIMITIVE_POSITION_ACCESSOR_WITHOUT_BOUNDS") == unbounded
    assert Counter(m["code"] for m in unexpected) == {
        "MESH_PRIMITIVE_POSITION_ACCESSOR_WITHOUT_BOUNDS": 15,
        "MESH_PRIMITIVE_ACCESSOR_UNALIGNED": 6,
    }
    assert report["numErrors"] == 107
    assert report["numUnexpectedErrors"] == 21
    assert report["numExpectedKhrAttributeErrors"] == 86
    assert report["numWarnings"] == 0
    assert _by_severity(report, "Information") == {"UNSUPPORTED_EXTENSION": 1}
    # Hints: no bufferView.target on any of the 101 vertex attributes.
    assert _by_severity(report, "Hint") == {"BUFFER_VIEW_TARGET_MISSING": 101}


def test_validator_on_tiny_file(tiny_glb: tuple[Path, dict]) -> None:
    path, _ = tiny_glb
    report = khr_tools.validate_gltf(path)
    assert report["numUnexpectedErrors"] == 0, [m for m in report["messages"] if m["severity"] == "Error"]
    # 4 rest attributes: ROTATION, SCALE, OPACITY and 4 SH coefficients.
    assert report["numErrors"] == report["numExpectedKhrAttributeErrors"] == 7
    assert report["numWarnings"] == 0
    unsupported = {
        m["message"].split("'")[1] for m in report["messages"] if m["code"] == "UNSUPPORTED_EXTENSION"
    }
    assert unsupported == {KHR, ANCHOR_EXT}
    # The accessors only the (unknown) anchor extension refers to, and the
    # anchor mesh that no node instantiates, are reported as possibly unused.
    unused = sorted(m["pointer"] for m in report["messages"] if m["code"] == "UNUSED_OBJECT")
    assert unused == ["/accessors/10", "/accessors/11", "/accessors/12", "/accessors/9", "/meshes/1"]
    assert _by_severity(report, "Information") == {"UNSUPPORTED_EXTENSION": 2, "UNUSED_OBJECT": 5}
    assert report["numHints"] == 0


def test_validator_counts_invalid_khr_names(tiny_glb: tuple[Path, dict], tmp_path: Path) -> None:
    src, _ = tiny_glb
    dst = tmp_path / "bad_names.glb"

    def rename(doc: dict) -> None:
        attrs = doc["meshes"][0]["primitives"][0]["attributes"]
        attrs[f"{KHR}:SH_DEGREE_1_COEF_3"] = attrs.pop(f"{KHR}:SH_DEGREE_1_COEF_2")
        attrs[f"{KHR}:SH_DEGREE_4_COEF_0"] = attrs.pop(f"{KHR}:SH_DEGREE_1_COEF_1")
        attrs[f"{KHR}:ROTATIONS"] = attrs.pop(f"{KHR}:ROTATION")

    _rewrite_json(src, dst, rename)
    report = khr_tools.validate_gltf(dst)
    bad = {m["pointer"].rsplit("/", 1)[1] for m in _unexpected_errors(report)}
    assert bad == {f"{KHR}:SH_DEGREE_1_COEF_3", f"{KHR}:SH_DEGREE_4_COEF_0", f"{KHR}:ROTATIONS"}
    assert report["numUnexpectedErrors"] == 3


def test_validator_refuses_external_resources(tmp_path: Path) -> None:
    (tmp_path / "data.bin").write_bytes(np.zeros(3, np.float32).tobytes())
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [{"uri": "data.bin", "byteLength": 12}],
        "bufferViews": [{"buffer": 0, "byteLength": 12}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 1, "type": "VEC3", "min": [0] * 3, "max": [0] * 3}
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": 0}]}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}],
        "scene": 0,
    }
    path = tmp_path / "external.gltf"
    path.write_text(json.dumps(doc))
    report = khr_tools.validate_gltf(path)
    errors = [(m["code"], m["pointer"]) for m in report["messages"] if m["severity"] == "Error"]
    assert errors == [("IO_ERROR", "/buffers/0/uri")]
    assert report["numUnexpectedErrors"] == 1
    with pytest.raises(khr_tools.NodeToolError, match="external buffer URI refused"):
        khr_tools.read_with_playcanvas(path)


def test_tools_raise_clear_errors(tmp_path: Path) -> None:
    missing = tmp_path / "missing.glb"
    with pytest.raises(khr_tools.NodeToolError, match="cannot read"):
        khr_tools.validate_gltf(missing)
    with pytest.raises(khr_tools.NodeToolError, match="cannot read"):
        khr_tools.read_with_playcanvas(missing)
    junk = tmp_path / "junk.glb"
    junk.write_bytes(b"glTF" + b"\0" * 8)
    with pytest.raises(khr_tools.NodeToolError, match="PlayCanvas could not parse"):
        khr_tools.read_with_playcanvas(junk)


# ---------------------------------------------------------------- PlayCanvas


def test_playcanvas_reads_bevy_conformance_matrix(shared_data: Path) -> None:
    path = shared_data / "khr_gaussian" / "bevy_khr_conformance_matrix.glb"
    gltf, blob = _load(path)
    splats = khr_tools.read_with_playcanvas(path)
    # One single-splat primitive per mesh; every quantization variant decodes.
    got = [(s["mesh"], s["primitive"], s["count"]) for s in splats]
    assert got == [(m, 0, 1) for m in range(len(gltf.meshes))]
    for s in splats:
        want = decode_khr_primitive(gltf, blob, s["mesh"])
        assert_splats_equal(s, want)
        pc = s["playcanvas"]
        assert pc["activated"] is True  # linear scale, opacity in [0, 1]
        assert pc["shBands"] == want["sh_degree"]
        assert pc["properties"][:14] == [
            "x", "y", "z", "rot_0", "rot_1", "rot_2", "rot_3",
            "scale_0", "scale_1", "scale_2", "opacity", "f_dc_0", "f_dc_1", "f_dc_2",
        ]  # fmt: skip
        assert len(pc["properties"]) == 14 + 3 * ((want["sh_degree"] + 1) ** 2 - 1)
    assert [s["sh_degree"] for s in splats[11:]] == [0, 1, 2, 3]


def test_playcanvas_reads_tiny_file(tiny_glb: tuple[Path, dict]) -> None:
    path, want = tiny_glb
    report = khr_tools.playcanvas_report(path)
    assert report["engine_version"] == "2.23.3"
    splats = report["splats"]
    # Only the splat primitive becomes splats; the nested extension is ignored
    # and the anchor mesh is built as an ordinary indexed triangle mesh.
    assert len(splats) == 1
    assert [(m["splatPrimitives"], m["renderPrimitives"]) for m in report["meshes"]] == [
        (1, []),
        (0, [{"mode": 4, "indexed": True, "count": 6, "vertexCount": 4}]),
    ]
    s = splats[0]
    assert (s["mesh"], s["primitive"], s["mesh_name"], s["count"]) == (0, 0, "splats", 3)
    assert_splats_equal(s, want)
    # The engine stores rows sorted by Morton code, not in file order.
    assert sorted(s["file_index"].tolist()) == [0, 1, 2]
    assert s["file_index"].tolist() == [2, 1, 0]
    assert s["playcanvas"]["activated"] is True and s["playcanvas"]["shBands"] == 1
    # Decoded independently from the same bytes, too.
    gltf, blob = _load(path)
    assert_splats_equal(s, decode_khr_primitive(gltf, blob, 0))


def test_playcanvas_skips_primitive_without_sh0(shared_data: Path) -> None:
    # KHR primitive with COLOR_0 but no SH_DEGREE_0_COEF_0: the engine yields no splats.
    path = shared_data / "khr_gaussian" / "bevy_khr_extensible_fallback.gltf"
    assert khr_tools.read_with_playcanvas(path) == []
    report = khr_tools.validate_gltf(path)
    assert [m["code"] for m in _unexpected_errors(report)] == ["MESH_PRIMITIVE_POSITION_ACCESSOR_WITHOUT_BOUNDS"]
