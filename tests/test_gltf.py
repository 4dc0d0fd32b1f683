"""glTF / GLB reading and writing: round trips, layout, JSON Schema, real files, hardening."""
from __future__ import annotations

import base64
import json
import pathlib
import struct

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gsverse_format import EXTENSION_NAME, __version__
from gsverse_format.errors import FormatError, UsageError
from gsverse_format.io.gltf import asset_to_gltf, gltf_to_bytes, read_gltf, write_gltf
from gsverse_format.model import (Anchoring, GamesAnchors, LocalAnchors, SplatAsset, SplatCloud,
                                  SplatPrimitive, TriangleMesh)

from helpers import (bumpy_sphere, extension_schema_validator, max_rel_cov_error, random_splats,
                     surface_splats)

KHR = "KHR_gaussian_splatting"
ROOT = pathlib.Path(__file__).resolve().parents[1]
SCHEMA_NAME = "primitive.KHR_gaussian_splatting.GSVERSE_gaussian_splatting_mesh_anchor.schema.json"


# ---------------------------------------------------------------------------- fixtures

def _local_anchors(mesh: TriangleMesh, cloud: SplatCloud, seed: int, *, deformation="affine",
                   inside=True) -> LocalAnchors:
    rng = np.random.default_rng(seed)
    n = len(cloud)
    bary = rng.uniform(0, 0.5, (n, 2)) if inside else rng.uniform(-0.2, 1.1, (n, 2))
    return LocalAnchors(np.sort(rng.integers(0, mesh.face_count, n)), bary,
                        rng.normal(0, 0.01, n), Rotation.random(n, random_state=seed).as_quat(),
                        cloud.scales, deformation)


def _games_anchors(mesh: TriangleMesh, n: int, seed: int) -> GamesAnchors:
    rng = np.random.default_rng(seed)
    return GamesAnchors(rng.integers(0, mesh.face_count, n), rng.dirichlet([1, 1, 1], n)[:, 1:],
                        rng.uniform(0.1, 2.0, n))


def _anchored_asset(profile="local", sh_degree=1, n=40, seed=0, deformation="affine"):
    mesh = bumpy_sphere(1, seed)
    cloud = surface_splats(mesh, n, seed, sh_degree=sh_degree)
    anchors = (_local_anchors(mesh, cloud, seed, deformation=deformation) if profile == "local"
               else _games_anchors(mesh, n, seed))
    return SplatAsset([SplatPrimitive(cloud, Anchoring(mesh, anchors), "body"),
                       SplatPrimitive(random_splats(7, seed + 1, sh_degree=sh_degree), None, "bg")])


def _tiny_asset(profile="local"):
    """Tetrahedron anchor mesh + 5 splats, for hand-corrupted files."""
    mesh = TriangleMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
                        [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
    cloud = random_splats(5, 3, sh_degree=1)
    anchors = (_local_anchors(mesh, cloud, 3) if profile == "local" else _games_anchors(mesh, 5, 3))
    return SplatAsset([SplatPrimitive(cloud, Anchoring(mesh, anchors), "tiny")])


def _doc(asset, **kw):
    gltf = asset_to_gltf(asset, **kw)
    return json.loads(gltf.to_json()), bytearray(gltf.binary_blob())


def _glb_bytes(doc, blob, *, bin_chunk=True) -> bytes:
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    out = struct.pack("<II", len(text), 0x4E4F534A) + text
    if bin_chunk and blob:
        blob = bytes(blob) + b"\0" * (-len(blob) % 4)
        out += struct.pack("<II", len(blob), 0x004E4942) + blob
    return struct.pack("<4sII", b"glTF", 2, 12 + len(out)) + out


def _save_glb(tmp_path, doc, blob, name="bad.glb", **kw) -> pathlib.Path:
    path = tmp_path / name
    path.write_bytes(_glb_bytes(doc, blob, **kw))
    return path


def _save_gltf(tmp_path, doc, blob=None, name="bad.gltf") -> pathlib.Path:
    doc = json.loads(json.dumps(doc))
    if blob is not None:
        doc["buffers"][0]["uri"] = ("data:application/octet-stream;base64,"
                                    + base64.b64encode(bytes(blob)).decode())
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    return path


def _ext(doc, mesh=0):
    return doc["meshes"][mesh]["primitives"][0]["extensions"][KHR]["extensions"][EXTENSION_NAME]


def _acc_rows(doc, blob, index) -> tuple[int, int, np.dtype]:
    """(byte offset of accessor ``index`` in the blob, element size, dtype)."""
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    dtype = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
    dt = np.dtype(dtype[acc["componentType"]])
    ncomp = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[acc["type"]]
    return view.get("byteOffset", 0) + acc.get("byteOffset", 0), dt.itemsize * ncomp, dt


def _poke(doc, blob, index, row, values):
    offset, elem, dt = _acc_rows(doc, blob, index)
    blob[offset + row * elem: offset + (row + 1) * elem] = np.asarray(values, dt).tobytes()


def _assert_cloud_equal(a: SplatCloud, b: SplatCloud):
    for name in ("means", "rotations", "scales", "opacities", "sh"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype == np.float32, name
        assert np.array_equal(x, y), name
    assert a.color_space == b.color_space


def _expect_error(path, *match, **kw):
    with pytest.raises(FormatError) as info:
        read_gltf(path, **kw)
    message = str(info.value)
    assert path.name in message
    assert "\n" not in message
    for m in match:
        assert m in message, message
    return message


# ---------------------------------------------------------------------------- round trips

@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
@pytest.mark.parametrize("degree", [0, 1, 2, 3])
def test_round_trip_plain(tmp_path, suffix, degree):
    clouds = [random_splats(30, degree, sh_degree=degree), random_splats(4, 9, sh_degree=degree)]
    clouds[1].color_space = "lin_rec709_display"
    asset = SplatAsset([SplatPrimitive(clouds[0], None, "a"), SplatPrimitive(clouds[1])])
    path = tmp_path / f"plain{suffix}"
    write_gltf(asset, path)
    back = read_gltf(path)
    assert back.generator == f"gsverse-format {__version__}"
    assert [p.name for p in back.primitives] == ["a", None]
    for p, c in zip(back.primitives, clouds):
        assert p.anchoring is None
        assert p.splats.sh_degree == degree
        _assert_cloud_equal(p.splats, c)


def _assert_anchoring_equal(got: Anchoring, want: Anchoring):
    assert np.array_equal(got.mesh.vertices, want.mesh.vertices)
    assert got.mesh.vertices.dtype == np.float32 and got.mesh.faces.dtype == np.uint32
    assert np.array_equal(got.mesh.faces, want.mesh.faces)
    a, b = got.anchors, want.anchors
    assert type(a) is type(b)
    assert np.array_equal(a.face_index, b.face_index) and a.face_index.dtype == np.uint32
    assert np.array_equal(a.barycentrics, b.barycentrics)
    if isinstance(b, LocalAnchors):
        assert a.deformation == b.deformation
        for name in ("normal_offset", "local_rotation", "local_scale"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
    else:
        assert np.array_equal(a.rho, b.rho)


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
@pytest.mark.parametrize("profile,deformation", [("local", "affine"), ("local", "rigid"),
                                                 ("games", None)])
def test_round_trip_anchored(tmp_path, suffix, profile, deformation):
    asset = _anchored_asset(profile, sh_degree=2, deformation=deformation or "affine")
    path = tmp_path / f"anchored{suffix}"
    write_gltf(asset, path)
    back = read_gltf(path)
    assert [p.name for p in back.primitives] == ["body", "bg"]
    for got, want in zip(back.primitives, asset.primitives):
        _assert_cloud_equal(got.splats, want.splats)
    assert back.primitives[1].anchoring is None
    _assert_anchoring_equal(back.primitives[0].anchoring, asset.primitives[0].anchoring)


def test_round_trip_large_mesh_index_types(tmp_path):
    """> 256 faces -> UNSIGNED_SHORT faceIndex; > 65535 vertices -> UNSIGNED_INT indices."""
    rng = np.random.default_rng(0)
    v = rng.normal(size=(70000, 3))
    f = rng.integers(0, 70000, size=(300, 3))
    mesh = TriangleMesh(v, f)
    cloud = random_splats(20, 1)
    anchors = LocalAnchors(rng.integers(0, 300, 20), rng.uniform(0, 1, (20, 2)), np.zeros(20),
                           cloud.rotations, cloud.scales)
    asset = SplatAsset([SplatPrimitive(cloud, Anchoring(mesh, anchors))])
    doc, _ = _doc(asset)
    assert doc["accessors"][_ext(doc)["faceIndex"]]["componentType"] == 5123
    anchor_prim = doc["meshes"][1]["primitives"][0]
    assert doc["accessors"][anchor_prim["indices"]]["componentType"] == 5125
    write_gltf(asset, tmp_path / "big.glb")
    _assert_anchoring_equal(read_gltf(tmp_path / "big.glb").primitives[0].anchoring,
                            asset.primitives[0].anchoring)


def test_shared_anchor_mesh(tmp_path):
    mesh, other = bumpy_sphere(1, 0), bumpy_sphere(1, 5)
    prims = []
    for i, m in enumerate((mesh, mesh, other)):
        cloud = surface_splats(m, 10 + i, i)
        prims.append(SplatPrimitive(cloud, Anchoring(m, _local_anchors(m, cloud, i)), f"p{i}"))
    asset = SplatAsset(prims)
    doc, _ = _doc(asset)
    assert len(doc["meshes"]) == 5  # three splat meshes + two anchor meshes
    assert _ext(doc, 0)["mesh"] == _ext(doc, 1)["mesh"] == 3
    assert _ext(doc, 2)["mesh"] == 4
    write_gltf(asset, tmp_path / "shared.glb")
    back = read_gltf(tmp_path / "shared.glb")
    a, b, c = (p.anchoring.mesh for p in back.primitives)
    assert a is b and a is not c
    for got, want in zip(back.primitives, prims):
        _assert_anchoring_equal(got.anchoring, want.anchoring)


def test_local_scale_shares_scale_accessor():
    asset = _anchored_asset("local")
    doc, _ = _doc(asset)
    attrs = doc["meshes"][0]["primitives"][0]["attributes"]
    assert _ext(doc)["localScale"] == attrs[f"{KHR}:SCALE"]
    asset.primitives[0].anchoring.anchors.local_scale = asset.primitives[0].splats.scales * 2
    doc, _ = _doc(asset)
    assert _ext(doc)["localScale"] != attrs[f"{KHR}:SCALE"]


@pytest.mark.parametrize("bary,rot", [("unsigned_short", "short"), ("unsigned_byte", "byte"),
                                      ("unsigned_short", "byte"), ("unsigned_byte", "short")])
def test_quantized_anchors(tmp_path, bary, rot):
    asset = _anchored_asset("local", n=200)
    want = asset.primitives[0].anchoring.anchors
    quantize = {"barycentrics": bary, "localRotation": rot}
    doc, _ = _doc(asset, quantize=quantize)
    ext = _ext(doc)
    acc_b, acc_r = doc["accessors"][ext["barycentrics"]], doc["accessors"][ext["localRotation"]]
    assert acc_b["componentType"] == {"unsigned_short": 5123, "unsigned_byte": 5121}[bary]
    assert acc_r["componentType"] == {"short": 5122, "byte": 5120}[rot]
    assert acc_b["normalized"] is True and acc_r["normalized"] is True
    path = tmp_path / "q.glb"
    write_gltf(asset, path, quantize=quantize)
    got = read_gltf(path).primitives[0].anchoring.anchors
    step_b = 1 / 65535 if bary == "unsigned_short" else 1 / 255
    step_r = 1 / 32767 if rot == "short" else 1 / 127
    assert np.max(np.abs(got.barycentrics - want.barycentrics)) <= 0.5 * step_b + 1e-7
    assert np.allclose(np.linalg.norm(got.local_rotation, axis=1), 1, atol=1e-6)
    dots = np.abs(np.sum(got.local_rotation * want.local_rotation, axis=1))
    assert np.max(np.abs(got.local_rotation - want.local_rotation)) <= 2 * step_r
    assert np.min(dots) > 1 - 4 * step_r ** 2 - 1e-6
    assert np.array_equal(got.face_index, want.face_index)
    assert np.array_equal(got.normal_offset, want.normal_offset)


def test_quantized_barycentrics_games_and_out_of_range(tmp_path):
    asset = _anchored_asset("games")
    doc, _ = _doc(asset, quantize={"barycentrics": "unsigned_byte"})
    assert doc["accessors"][_ext(doc)["barycentrics"]]["componentType"] == 5121
    write_gltf(asset, tmp_path / "g.gltf", quantize={"barycentrics": "unsigned_byte"})
    got = read_gltf(tmp_path / "g.gltf").primitives[0].anchoring.anchors
    want = asset.primitives[0].anchoring.anchors
    assert np.max(np.abs(got.barycentrics - want.barycentrics)) <= 0.5 / 255 + 1e-7
    # Barycentrics outside [0, 1] cannot be unsigned-normalized: they stay FLOAT (and exact).
    mesh = bumpy_sphere(1)
    cloud = surface_splats(mesh, 30)
    outside = _local_anchors(mesh, cloud, 1, inside=False)
    asset = SplatAsset([SplatPrimitive(cloud, Anchoring(mesh, outside))])
    doc, _ = _doc(asset, quantize={"barycentrics": "unsigned_short"})
    assert doc["accessors"][_ext(doc)["barycentrics"]]["componentType"] == 5126
    write_gltf(asset, tmp_path / "o.glb", quantize={"barycentrics": "unsigned_short"})
    got = read_gltf(tmp_path / "o.glb").primitives[0].anchoring.anchors
    assert np.array_equal(got.barycentrics, outside.barycentrics)


@pytest.mark.parametrize("quantize", [{"rho": "short"}, {"barycentrics": "half"},
                                      {"localRotation": "unsigned_byte"}])
def test_quantize_bad_options(tmp_path, quantize):
    with pytest.raises(UsageError):
        write_gltf(_anchored_asset(), tmp_path / "x.glb", quantize=quantize)
    assert not (tmp_path / "x.glb").exists()


def test_writer_rejects_unwritable_data(tmp_path):
    cloud = random_splats(5)
    cloud.opacities[0] = 1.5
    with pytest.raises(UsageError, match="opacities"):
        write_gltf(SplatAsset([SplatPrimitive(cloud)]), tmp_path / "x.glb")
    cloud = random_splats(5)
    cloud.means[2, 1] = np.nan
    with pytest.raises(UsageError, match="x.glb.*non-finite"):
        write_gltf(SplatAsset([SplatPrimitive(cloud)]), tmp_path / "x.glb")
    with pytest.raises(UsageError):
        write_gltf(SplatAsset([SplatPrimitive(random_splats(5))]), tmp_path / "x.ply")
    assert not list(tmp_path.iterdir())


def test_rotations_normalized_on_write(tmp_path):
    cloud = random_splats(20, 4)
    unit = cloud.rotations.copy()
    cloud.rotations = cloud.rotations * np.linspace(0.5, 3, 20)[:, None]
    write_gltf(SplatAsset([SplatPrimitive(cloud)]), tmp_path / "r.glb")
    got = read_gltf(tmp_path / "r.glb").primitives[0].splats.rotations
    assert np.allclose(np.linalg.norm(got, axis=1), 1, atol=1e-6)
    assert np.allclose(got, unit, atol=1e-6)


def test_protect_input(tmp_path):
    path = tmp_path / "in.glb"
    write_gltf(_anchored_asset(), path)
    before = path.read_bytes()
    with pytest.raises(UsageError):
        write_gltf(_anchored_asset(), path, protect=(path,))
    assert path.read_bytes() == before


# ---------------------------------------------------------------------------- layout

def test_json_layout_anchored():
    asset = _anchored_asset("local", sh_degree=1)
    doc, blob = _doc(asset)
    assert doc["asset"] == {"version": "2.0", "generator": f"gsverse-format {__version__}"}
    assert doc["extensionsUsed"] == [KHR, EXTENSION_NAME]
    assert "extensionsRequired" not in doc
    assert len(doc["buffers"]) == 1 and doc["buffers"][0]["byteLength"] == len(blob)
    assert len(blob) % 4 == 0

    splat = doc["meshes"][0]["primitives"][0]
    assert splat["mode"] == 0
    khr = splat["extensions"][KHR]
    assert {k: khr[k] for k in ("kernel", "colorSpace", "projection", "sortingMethod")} == {
        "kernel": "ellipse", "colorSpace": "srgb_rec709_display", "projection": "perspective",
        "sortingMethod": "cameraDistance"}
    assert list(khr["extensions"]) == [EXTENSION_NAME]
    assert EXTENSION_NAME not in splat["extensions"]  # nested, not beside KHR
    ext = _ext(doc)
    assert ext["profile"] == "local" and ext["deformation"] == "affine" and ext["primitive"] == 0

    acc = doc["accessors"]
    attrs = splat["attributes"]
    expected = {"POSITION": ("VEC3", 5126), f"{KHR}:ROTATION": ("VEC4", 5126),
                f"{KHR}:SCALE": ("VEC3", 5126), f"{KHR}:OPACITY": ("SCALAR", 5126),
                "COLOR_0": ("VEC4", 5121)}
    expected.update({f"{KHR}:SH_DEGREE_{l}_COEF_{n}": ("VEC3", 5126)
                     for l in (0, 1) for n in range(2 * l + 1)})
    assert set(attrs) == set(expected)
    for name, (gtype, ctype) in expected.items():
        assert (acc[attrs[name]]["type"], acc[attrs[name]]["componentType"]) == (gtype, ctype)
        assert acc[attrs[name]]["count"] == 40
    assert acc[attrs["COLOR_0"]]["normalized"] is True
    assert len(acc[attrs["POSITION"]]["min"]) == 3 and len(acc[attrs["POSITION"]]["max"]) == 3
    means = asset.primitives[0].splats.means
    assert acc[attrs["POSITION"]]["min"] == [float(x) for x in means.min(axis=0)]

    anchor_mesh = doc["meshes"][ext["mesh"]]
    assert ext["mesh"] == 2 and len(anchor_mesh["primitives"]) == 1
    tri = anchor_mesh["primitives"][0]
    assert tri["mode"] == 4 and set(tri["attributes"]) == {"POSITION"}
    assert "extensions" not in tri
    assert acc[tri["attributes"]["POSITION"]]["componentType"] == 5126
    assert "min" in acc[tri["attributes"]["POSITION"]]
    assert acc[tri["indices"]]["componentType"] == 5123
    assert doc["bufferViews"][acc[tri["indices"]]["bufferView"]]["target"] == 34963
    # The anchor mesh is not instantiated by any node; each splat mesh has its node.
    assert sorted(n["mesh"] for n in doc["nodes"]) == [0, 1]
    assert doc["scenes"][0]["nodes"] == [0, 1] and doc["scene"] == 0
    assert [n.get("name") for n in doc["nodes"]] == ["body", "bg"]
    assert [m.get("name") for m in doc["meshes"][:2]] == ["body", "bg"]

    types = {"faceIndex": ("SCALAR", 5121), "barycentrics": ("VEC2", 5126),
             "normalOffset": ("SCALAR", 5126), "localRotation": ("VEC4", 5126),
             "localScale": ("VEC3", 5126)}
    for key, (gtype, ctype) in types.items():
        a = acc[ext[key]]
        assert (a["type"], a["componentType"], a["count"]) == (gtype, ctype, 40)
        if key != "localScale":  # the shared SCALE accessor is a vertex attribute
            assert "target" not in doc["bufferViews"][a["bufferView"]]
            used_as_attr = any(ext[key] in p["attributes"].values()
                               for m in doc["meshes"] for p in m["primitives"])
            assert not used_as_attr
    assert len({a["bufferView"] for a in acc}) == len(acc)  # one view per accessor
    for view in doc["bufferViews"]:
        assert view["byteOffset"] % 4 == 0 and view["buffer"] == 0
        assert view["byteOffset"] + view["byteLength"] <= len(blob)


def test_json_layout_games_has_no_deformation():
    doc, _ = _doc(_anchored_asset("games"))
    ext = _ext(doc)
    assert ext["profile"] == "games" and "deformation" not in ext
    assert set(ext) == {"mesh", "primitive", "profile", "faceIndex", "barycentrics", "rho"}


def test_plain_asset_is_plain_khr():
    doc, _ = _doc(SplatAsset([SplatPrimitive(random_splats(10), None, "x")]))
    assert "GSVERSE" not in json.dumps(doc)
    assert doc["extensionsUsed"] == [KHR]
    assert "extensionsRequired" not in doc
    assert "extensions" not in doc["meshes"][0]["primitives"][0]["extensions"][KHR]


def test_color_fallback_values():
    cloud = random_splats(50, 2)
    cloud.sh[:, 0] = np.linspace(-3, 3, 150).reshape(50, 3)
    for space in ("srgb_rec709_display", "lin_rec709_display"):
        cloud.color_space = space
        doc, blob = _doc(SplatAsset([SplatPrimitive(cloud)]))
        index = doc["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"]
        offset, _, _ = _acc_rows(doc, blob, index)
        rgba = np.frombuffer(bytes(blob[offset:offset + 200]), np.uint8).reshape(50, 4) / 255
        c = np.clip(0.5 + 0.28209479177387814 * cloud.sh[:, 0].astype(np.float64), 0, 1)
        if space == "srgb_rec709_display":
            c = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
        assert np.max(np.abs(rgba[:, :3] - c)) <= 0.5 / 255 + 1e-9
        assert np.max(np.abs(rgba[:, 3] - cloud.opacities)) <= 0.5 / 255 + 1e-7


def test_gltf_to_bytes_glb_container():
    data = gltf_to_bytes(asset_to_gltf(_tiny_asset()))
    magic, version, length = struct.unpack_from("<4sII", data)
    assert (magic, version, length) == (b"glTF", 2, len(data))
    json_len, json_type = struct.unpack_from("<II", data, 12)
    assert json_type == 0x4E4F534A and json_len % 4 == 0
    bin_len, bin_type = struct.unpack_from("<II", data, 20 + json_len)
    assert bin_type == 0x004E4942 and 28 + json_len + bin_len == len(data)


# ---------------------------------------------------------------------------- JSON Schema

def _schema_validator():
    return extension_schema_validator()


def test_schema_copies_identical():
    spec = (ROOT / "spec" / "schema" / SCHEMA_NAME).read_bytes()
    package = (ROOT / "gsverse_format" / "schema" / SCHEMA_NAME).read_bytes()
    assert spec == package


def test_schema_every_property_described():
    schema = json.loads((ROOT / "spec" / "schema" / SCHEMA_NAME).read_text())
    assert schema["$id"] == SCHEMA_NAME
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    for name, prop in schema["properties"].items():
        assert prop.get("description"), name
    assert schema["properties"]["deformation"]["default"] == "affine"
    assert schema["properties"]["primitive"]["default"] == 0


def test_schema_accepts_written_objects():
    validator = _schema_validator()
    for profile, deformation in (("local", "affine"), ("local", "rigid"), ("games", "affine")):
        doc, _ = _doc(_anchored_asset(profile, deformation=deformation))
        validator.validate(_ext(doc))
    extended = dict(_ext(doc), extras={"note": 1}, extensions={"VENDOR_x": {}}, futureKey=3)
    validator.validate(extended)
    validator.validate({"mesh": 0, "profile": "local", "faceIndex": 1, "barycentrics": 2,
                        "normalOffset": 3, "localRotation": 4, "localScale": 5})


LOCAL = {"mesh": 1, "primitive": 0, "profile": "local", "deformation": "affine", "faceIndex": 6,
         "barycentrics": 7, "normalOffset": 8, "localRotation": 9, "localScale": 2}
GAMES = {"mesh": 1, "profile": "games", "faceIndex": 6, "barycentrics": 7, "rho": 8}


@pytest.mark.parametrize("bad", [
    {k: v for k, v in LOCAL.items() if k != "mesh"},
    {k: v for k, v in LOCAL.items() if k != "localScale"},
    {k: v for k, v in LOCAL.items() if k != "faceIndex"},
    {k: v for k, v in GAMES.items() if k != "rho"},
    dict(LOCAL, profile="skinned"),
    dict(LOCAL, deformation="elastic"),
    dict(GAMES, deformation="affine"),
    dict(LOCAL, faceIndex=-1),
    dict(LOCAL, mesh="1"),
    dict(LOCAL, barycentrics=1.5),
    dict(LOCAL, primitive=-2),
    dict(LOCAL, extensions=[]),
    [LOCAL],
])
def test_schema_rejects_invalid_objects(bad):
    import jsonschema

    with pytest.raises(jsonschema.ValidationError):
        _schema_validator().validate(bad)


# ---------------------------------------------------------------------------- real files

def test_read_khr_conformance_matrix(shared_data):
    path = shared_data / "khr_gaussian" / "bevy_khr_conformance_matrix.glb"
    if not path.is_file():
        pytest.skip("conformance matrix not present")
    asset = read_gltf(path)
    prims = {p.name: p for p in asset.primitives}
    assert len(asset.primitives) == 15 and len(prims) == 15
    assert all(p.anchoring is None and len(p.splats) == 1 for p in asset.primitives)
    for degree in range(4):
        assert prims[f"sh_degree{degree}"].splats.sh_degree == degree
    ref = prims["rotation_f32"].splats
    for name in ("rotation_i8_norm", "rotation_i16_norm"):
        q = prims[name].splats.rotations
        assert np.isclose(np.linalg.norm(q), 1, atol=1e-6)
        assert abs(float(np.dot(q[0], ref.rotations[0]))) > 1 - 1e-4
    assert np.isclose(prims["opacity_u8_norm"].splats.opacities[0], 64 / 255)
    assert abs(prims["opacity_u16_norm"].splats.opacities[0] - 0.25) <= 1 / 65535
    assert np.isclose(prims["opacity_f32"].splats.opacities[0], 0.75)
    # Normalized integer scales dequantize into [-1, 1]; plain integers are taken as they are.
    assert np.all(np.abs(prims["scale_i8_norm"].splats.scales) <= 1)
    assert np.all(prims["scale_i16"].splats.scales == np.round(prims["scale_i16"].splats.scales))
    assert prims["scale_f32"].splats.color_space == "srgb_rec709_display"
    assert ref.color_space == "lin_rec709_display"
    for p in asset.primitives:
        assert np.array_equal(p.splats.means, ref.means)


def test_read_khr_extensible_fallback(shared_data):
    path = shared_data / "khr_gaussian" / "bevy_khr_extensible_fallback.gltf"
    if not path.is_file():
        pytest.skip("fallback fixture not present")
    asset = read_gltf(path)
    assert len(asset.primitives) == 1
    prim = asset.primitives[0]
    assert prim.anchoring is None and prim.name == "extensible_unknown"
    assert prim.splats.color_space == "custom_space_display"
    # The file has no SH attributes: the DC term is rebuilt from COLOR_0.
    assert prim.splats.sh_degree == 0
    assert np.allclose(0.5 + 0.28209479177387814 * prim.splats.sh[0, 0],
                       [0.28209479, 0.56418958, 0.84628438], atol=1e-6)


# ---------------------------------------------------------------------------- other valid input

def test_interleaved_strided_quantized_attributes(tmp_path):
    """byteStride, accessor byteOffset and the quantized KHR component types."""
    n = 6
    rng = np.random.default_rng(0)
    pos = rng.normal(size=(n, 3)).astype(np.float32)
    q = Rotation.random(n, random_state=1).as_quat()
    q_i16 = np.round(q * 32767).astype(np.int16)
    scale_u8 = rng.integers(0, 255, (n, 3)).astype(np.uint8)
    opac_u16 = rng.integers(0, 65535, n).astype(np.uint16)
    dc = rng.normal(size=(n, 3)).astype(np.float32)
    # One interleaved view: POSITION f32x3 @0, ROTATION i16x4 @12, SCALE u8x3 @20, pad to 24,
    # OPACITY u16 @24 -> stride 28.
    stride = 28
    inter = bytearray(stride * n)
    for i in range(n):
        row = i * stride
        inter[row:row + 12] = pos[i].tobytes()
        inter[row + 12:row + 20] = q_i16[i].tobytes()
        inter[row + 20:row + 23] = scale_u8[i].tobytes()
        inter[row + 24:row + 26] = opac_u16[i].tobytes()
    blob = bytes(8) + bytes(inter) + dc.tobytes()  # 8 leading bytes: non-zero view offsets
    doc = {
        "asset": {"version": "2.0"}, "extensionsUsed": [KHR],
        "meshes": [{"name": "mixed", "primitives": [{"mode": 0, "attributes": {
            "POSITION": 0, f"{KHR}:ROTATION": 1, f"{KHR}:SCALE": 2, f"{KHR}:OPACITY": 3,
            f"{KHR}:SH_DEGREE_0_COEF_0": 4},
            "extensions": {KHR: {"kernel": "ellipse", "colorSpace": "lin_rec709_display"}}}]}],
        "buffers": [{"byteLength": len(blob)}],
        "bufferViews": [{"buffer": 0, "byteOffset": 8, "byteLength": len(inter),
                         "byteStride": stride},
                        {"buffer": 0, "byteOffset": 8 + len(inter), "byteLength": dc.nbytes}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": n, "type": "VEC3",
             "min": pos.min(0).tolist(), "max": pos.max(0).tolist()},
            {"bufferView": 0, "byteOffset": 12, "componentType": 5122, "normalized": True,
             "count": n, "type": "VEC4"},
            {"bufferView": 0, "byteOffset": 20, "componentType": 5121, "count": n,
             "type": "VEC3"},
            {"bufferView": 0, "byteOffset": 24, "componentType": 5123, "normalized": True,
             "count": n, "type": "SCALAR"},
            {"bufferView": 1, "componentType": 5126, "count": n, "type": "VEC3"}]}
    path = _save_glb(tmp_path, doc, blob, name="mixed.glb")
    cloud = read_gltf(path).primitives[0].splats
    assert np.array_equal(cloud.means, pos)
    assert np.allclose(cloud.rotations, q, atol=2 / 32767)
    assert np.allclose(np.linalg.norm(cloud.rotations, axis=1), 1, atol=1e-6)
    assert np.array_equal(cloud.scales, scale_u8.astype(np.float32))
    assert np.allclose(cloud.opacities, opac_u16 / 65535, atol=1e-7)
    assert np.array_equal(cloud.sh[:, 0], dc)
    assert cloud.color_space == "lin_rec709_display"


def test_non_indexed_anchor_mesh(tmp_path):
    asset = _tiny_asset()
    doc, blob = _doc(asset)
    mesh = asset.primitives[0].anchoring.mesh
    soup = mesh.vertices[mesh.faces].reshape(-1, 3)
    blob += soup.tobytes()
    doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob) - soup.nbytes,
                               "byteLength": soup.nbytes})
    doc["accessors"].append({"bufferView": len(doc["bufferViews"]) - 1, "componentType": 5126,
                             "count": len(soup), "type": "VEC3"})
    doc["buffers"][0]["byteLength"] = len(blob)
    tri = doc["meshes"][_ext(doc)["mesh"]]["primitives"][0]
    tri["attributes"]["POSITION"] = len(doc["accessors"]) - 1
    del tri["indices"]
    got = read_gltf(_save_glb(tmp_path, doc, blob, name="soup.glb")).primitives[0].anchoring.mesh
    assert np.array_equal(got.vertices, soup)
    assert np.array_equal(got.faces, np.arange(len(soup)).reshape(-1, 3))


def test_external_buffer_inside_folder(tmp_path):
    doc, blob = _doc(_tiny_asset())
    for uri, rel in (("data.bin", "data.bin"), ("sub/da%20ta.bin", "sub/da ta.bin")):
        (tmp_path / rel).parent.mkdir(exist_ok=True)
        (tmp_path / rel).write_bytes(bytes(blob))
        doc["buffers"][0]["uri"] = uri
        path = _save_gltf(tmp_path, doc, name="ext.gltf")
        _assert_anchoring_equal(read_gltf(path).primitives[0].anchoring,
                                _tiny_asset().primitives[0].anchoring)


def test_unknown_nested_extension_and_nodes_ignored(tmp_path):
    doc, blob = _doc(_tiny_asset())
    doc["meshes"][0]["primitives"][0]["extensions"][KHR]["extensions"]["VENDOR_other"] = {"a": 1}
    doc["nodes"][0]["translation"] = [1, 2, 3]
    doc["extensionsUsed"].append("VENDOR_other")
    prim = read_gltf(_save_glb(tmp_path, doc, blob)).primitives[0]
    assert prim.anchoring is not None
    _assert_cloud_equal(prim.splats, _tiny_asset().primitives[0].splats)


def test_empty_asset_round_trip(tmp_path):
    write_gltf(SplatAsset([]), tmp_path / "empty.glb")
    assert read_gltf(tmp_path / "empty.glb").primitives == []


# ---------------------------------------------------------------------------- hardening

@pytest.fixture
def good(tmp_path):
    doc, blob = _doc(_tiny_asset())
    return doc, blob


def test_truncated_glb(tmp_path, good):
    data = _glb_bytes(*good)
    for cut in (0, 5, 11, 16, 40, len(data) // 2, len(data) - 4):
        path = tmp_path / f"cut{cut}.glb"
        path.write_bytes(data[:cut])
        _expect_error(path)
    path = tmp_path / "cut.glb"
    path.write_bytes(data[:len(data) // 2])
    _expect_error(path, "truncated")


def test_every_truncation_and_byte_flip_is_a_format_error(tmp_path, good):
    data = _glb_bytes(*good)
    path = tmp_path / "fuzz.glb"
    for cut in range(0, len(data), 5):
        path.write_bytes(data[:cut])
        with pytest.raises(FormatError):
            read_gltf(path)
    rng = np.random.default_rng(0)
    for _ in range(300):
        mutated = bytearray(data)
        for pos in rng.integers(0, len(data), rng.integers(1, 4)):
            mutated[pos] = rng.integers(0, 256)
        path.write_bytes(bytes(mutated))
        try:
            read_gltf(path)
        except FormatError as err:
            assert "fuzz.glb" in str(err)


def test_bad_magic_version_length(tmp_path, good):
    data = bytearray(_glb_bytes(*good))
    path = tmp_path / "magic.glb"
    path.write_bytes(b"gLTF" + bytes(data[4:]))
    _expect_error(path, "magic")
    path = tmp_path / "version.glb"
    path.write_bytes(bytes(data[:4]) + struct.pack("<I", 1) + bytes(data[8:]))
    _expect_error(path, "version")
    path = tmp_path / "length.glb"
    path.write_bytes(bytes(data) + b"\0\0\0\0")
    _expect_error(path, "length")
    path = tmp_path / "ply.glb"
    path.write_bytes(b"ply\nformat binary_little_endian 1.0\n")
    _expect_error(path, "magic")


def test_chunk_length_past_end(tmp_path, good):
    data = bytearray(_glb_bytes(*good))
    json_len = struct.unpack_from("<I", data, 12)[0]
    struct.pack_into("<I", data, 20 + json_len, 10 ** 6)  # BIN chunk length
    path = tmp_path / "chunk.glb"
    path.write_bytes(bytes(data))
    _expect_error(path, "chunk")
    data = bytearray(_glb_bytes(*good))
    struct.pack_into("<I", data, 12, len(data))  # JSON chunk length
    path.write_bytes(bytes(data))
    _expect_error(path, "chunk")


def test_json_not_utf8_or_not_json(tmp_path, good):
    doc, blob = good
    text = json.dumps(doc).encode()
    bad = text.replace(b'"tiny"', b'"ti\xff\xfey"')
    assert bad != text
    for name, payload in (("latin.glb", bad), ("garbage.glb", b"{not json at all"),
                          ("array.glb", b"[1, 2, 3]")):
        payload += b" " * (-len(payload) % 4)
        body = struct.pack("<II", len(payload), 0x4E4F534A) + payload
        path = tmp_path / name
        path.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body)
        message = _expect_error(path)
        assert {"latin.glb": "UTF-8", "garbage.glb": "JSON", "array.glb": "object"}[name] in message
    path = tmp_path / "latin.gltf"
    path.write_bytes(bad)
    _expect_error(path, "UTF-8")


def test_missing_bin_chunk(tmp_path, good):
    _expect_error(_save_glb(tmp_path, *good, bin_chunk=False), "BIN")


def test_accessor_out_of_bounds(tmp_path, good):
    doc, blob = good
    doc = json.loads(json.dumps(doc))
    pos = doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
    doc["accessors"][pos]["count"] += 1
    _expect_error(_save_glb(tmp_path, doc, blob, name="count.glb"), "out of bounds")
    doc, _ = good
    doc = json.loads(json.dumps(doc))
    doc["accessors"][pos]["byteOffset"] = 4
    _expect_error(_save_glb(tmp_path, doc, blob, name="offset.glb"), "out of bounds")
    doc = json.loads(json.dumps(good[0]))
    doc["bufferViews"][0]["byteStride"] = 4096
    _expect_error(_save_glb(tmp_path, doc, blob, name="stride.glb"), "out of bounds")
    doc = json.loads(json.dumps(good[0]))
    doc["bufferViews"][-1]["byteLength"] += 64
    _expect_error(_save_glb(tmp_path, doc, blob, name="view.glb"), "bufferViews")
    doc = json.loads(json.dumps(good[0]))
    doc["buffers"][0]["byteLength"] += 64
    _expect_error(_save_glb(tmp_path, doc, blob, name="buffer.glb"), "byteLength")
    doc = json.loads(json.dumps(good[0]))
    doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 999
    _expect_error(_save_glb(tmp_path, doc, blob, name="index.glb"), "out of range")
    doc = json.loads(json.dumps(good[0]))
    doc["accessors"][pos]["count"] = -3
    _expect_error(_save_glb(tmp_path, doc, blob, name="negative.glb"), "count")
    doc = json.loads(json.dumps(good[0]))
    doc["accessors"][pos]["componentType"] = 5130
    _expect_error(_save_glb(tmp_path, doc, blob, name="ctype.glb"), "componentType")


def test_accessor_count_mismatch(tmp_path, good):
    doc = json.loads(json.dumps(good[0]))
    attrs = doc["meshes"][0]["primitives"][0]["attributes"]
    doc["accessors"][attrs[f"{KHR}:SCALE"]]["count"] -= 1
    doc["meshes"][0]["primitives"][0]["extensions"][KHR]["extensions"][EXTENSION_NAME][
        "localScale"] = 0  # keep the mismatch in the splat attributes only (POSITION is VEC3)
    _expect_error(_save_glb(tmp_path, doc, good[1], name="mismatch.glb"), "count mismatch")
    doc = json.loads(json.dumps(good[0]))
    doc["accessors"][_ext(doc)["normalOffset"]]["count"] -= 1
    _expect_error(_save_glb(tmp_path, doc, good[1], name="anchor.glb"), "count mismatch")


def test_index_and_face_out_of_range(tmp_path, good):
    doc, blob = good
    tri = doc["meshes"][_ext(doc)["mesh"]]["primitives"][0]
    bad = bytearray(blob)
    _poke(doc, bad, tri["indices"], 5, 4)  # 4 vertices: index 4 is out of range
    _expect_error(_save_glb(tmp_path, doc, bad, name="indices.glb"), "index 4 out of range")
    bad = bytearray(blob)
    _poke(doc, bad, _ext(doc)["faceIndex"], 2, 4)  # 4 faces
    _expect_error(_save_glb(tmp_path, doc, bad, name="face.glb"), "faceIndex", "out of range")


def test_bad_anchor_mesh_and_extension(tmp_path, good):
    cases = {
        "mode.glb": lambda d: d["meshes"][1]["primitives"][0].__setitem__("mode", 0),
        "mesh.glb": lambda d: _ext(d).__setitem__("mesh", 7),
        "prim.glb": lambda d: _ext(d).__setitem__("primitive", 1),
        "profile.glb": lambda d: _ext(d).__setitem__("profile", "skinned"),
        "deform.glb": lambda d: _ext(d).__setitem__("deformation", "elastic"),
        "required.glb": lambda d: _ext(d).pop("localRotation"),
        "type.glb": lambda d: _ext(d).__setitem__("faceIndex", _ext(d)["normalOffset"]),
        "object.glb": lambda d: d["meshes"][0]["primitives"][0]["extensions"][KHR][
            "extensions"].__setitem__(EXTENSION_NAME, [1]),
    }
    for name, change in cases.items():
        doc = json.loads(json.dumps(good[0]))
        change(doc)
        _expect_error(_save_glb(tmp_path, doc, good[1], name=name))
    doc, blob = _doc(_tiny_asset("games"))
    _ext(doc)["deformation"] = "affine"
    _expect_error(_save_glb(tmp_path, doc, blob, name="games.glb"), "deformation")


def test_sh_and_required_attributes(tmp_path, good):
    def attrs(d):
        return d["meshes"][0]["primitives"][0]["attributes"]

    doc = json.loads(json.dumps(good[0]))
    del attrs(doc)[f"{KHR}:SH_DEGREE_1_COEF_2"]
    _expect_error(_save_glb(tmp_path, doc, good[1], name="partial.glb"), "partially defined")
    doc = json.loads(json.dumps(good[0]))
    attrs(doc)[f"{KHR}:SH_DEGREE_2_COEF_0"] = attrs(doc)[f"{KHR}:SH_DEGREE_1_COEF_0"]
    _expect_error(_save_glb(tmp_path, doc, good[1], name="partial2.glb"), "degree 2")
    doc = json.loads(json.dumps(good[0]))
    for n in range(3):
        attrs(doc)[f"{KHR}:SH_DEGREE_2_COEF_{n}"] = attrs(doc).pop(f"{KHR}:SH_DEGREE_1_COEF_{n}")
    attrs(doc).update({f"{KHR}:SH_DEGREE_2_COEF_{n}": attrs(doc)[f"{KHR}:SH_DEGREE_2_COEF_0"]
                       for n in (3, 4)})
    _expect_error(_save_glb(tmp_path, doc, good[1], name="gap.glb"), "degree 1 is missing")
    doc = json.loads(json.dumps(good[0]))
    del attrs(doc)[f"{KHR}:ROTATION"]
    _expect_error(_save_glb(tmp_path, doc, good[1], name="norot.glb"), "ROTATION")
    doc = json.loads(json.dumps(good[0]))
    for key in [k for k in attrs(doc) if "SH_DEGREE" in k or k == "COLOR_0"]:
        del attrs(doc)[key]
    _expect_error(_save_glb(tmp_path, doc, good[1], name="nosh.glb"), "SH_DEGREE_0_COEF_0")
    doc = json.loads(json.dumps(good[0]))
    del doc["meshes"][0]["primitives"][0]["extensions"][KHR]["colorSpace"]
    _expect_error(_save_glb(tmp_path, doc, good[1], name="nocolor.glb"), "colorSpace")
    doc = json.loads(json.dumps(good[0]))
    doc["accessors"][attrs(doc)[f"{KHR}:SCALE"]]["type"] = "VEC4"
    _expect_error(_save_glb(tmp_path, doc, good[1], name="vec4.glb"), "type")


def test_sparse_and_unsupported_required(tmp_path, good):
    doc = json.loads(json.dumps(good[0]))
    doc["accessors"][0]["sparse"] = {"count": 1, "indices": {"bufferView": 0, "componentType": 5121},
                                     "values": {"bufferView": 0}}
    _expect_error(_save_glb(tmp_path, doc, good[1], name="sparse.glb"), "sparse")
    doc = json.loads(json.dumps(good[0]))
    doc["extensionsRequired"] = ["KHR_gaussian_splatting_compression_lgsc"]
    _expect_error(_save_glb(tmp_path, doc, good[1], name="spz.glb"), "not supported")
    doc = json.loads(json.dumps(good[0]))
    doc["asset"]["version"] = "1.0"
    _expect_error(_save_glb(tmp_path, doc, good[1], name="v1.glb"), "version")


def test_max_bytes(tmp_path, good):
    path = _save_glb(tmp_path, *good, name="big.glb")
    _expect_error(path, "limit", max_bytes=path.stat().st_size - 1)
    assert read_gltf(path, max_bytes=path.stat().st_size).primitives
    path = _save_gltf(tmp_path, *good, name="big.gltf")
    _expect_error(path, "limit", max_bytes=path.stat().st_size + 10)
    assert read_gltf(path, max_bytes=2 * path.stat().st_size).primitives
    doc = json.loads(json.dumps(good[0]))
    doc["buffers"][0]["uri"] = "ext.bin"
    (tmp_path / "ext.bin").write_bytes(bytes(good[1]))
    path = _save_gltf(tmp_path, doc, name="ext.gltf")
    total = path.stat().st_size + len(good[1])
    _expect_error(path, "limit", max_bytes=total - 1)
    assert read_gltf(path, max_bytes=total).primitives


@pytest.mark.parametrize("uri,cause", [
    ("/etc/passwd", "absolute"),
    ("%2Fetc%2Fpasswd", "absolute"),
    ("../x.bin", "escapes"),
    ("sub/../../x.bin", "escapes"),
    ("%2e%2e/x.bin", "escapes"),
    ("http://example.com/x.bin", "scheme"),
    ("https://example.com/x.bin", "scheme"),
    ("file:///etc/passwd", "scheme"),
    ("ftp://example.com/x.bin", "scheme"),
    ("C:/Windows/x.bin", "scheme"),
    ("//example.com/x.bin", "absolute"),
    ("missing.bin", "not found"),
    ("data:application/octet-stream,AAAA", "base64"),
    ("data:application/octet-stream;base64,@@@@", "base64"),
])
def test_hostile_uris(tmp_path, good, uri, cause):
    (tmp_path.parent / "x.bin").write_bytes(bytes(good[1]))
    doc = json.loads(json.dumps(good[0]))
    doc["buffers"][0]["uri"] = uri
    _expect_error(_save_gltf(tmp_path, doc, name="hostile.gltf"), cause)
    # The same in a GLB (buffer 0 with a uri instead of the BIN chunk).
    _expect_error(_save_glb(tmp_path, doc, good[1], name="hostile.glb"), cause)


def test_symlink_escape(tmp_path, good):
    outside = tmp_path / "outside"
    inside = tmp_path / "asset"
    outside.mkdir()
    inside.mkdir()
    (outside / "x.bin").write_bytes(bytes(good[1]))
    try:
        (inside / "link.bin").symlink_to(outside / "x.bin")
    except OSError:
        pytest.skip("no symlinks here")
    doc = json.loads(json.dumps(good[0]))
    doc["buffers"][0]["uri"] = "link.bin"
    _expect_error(_save_gltf(inside, doc, name="link.gltf"), "outside")


def test_missing_file_and_bad_types(tmp_path, good):
    _expect_error(tmp_path / "nope.glb", "cannot read")
    doc = json.loads(json.dumps(good[0]))
    doc["accessors"] = 5
    _expect_error(_save_glb(tmp_path, doc, good[1], name="types.glb"))
    doc = json.loads(json.dumps(good[0]))
    doc["meshes"][0]["primitives"][0]["attributes"] = [1, 2]
    _expect_error(_save_glb(tmp_path, doc, good[1], name="attrs.glb"))
    doc = json.loads(json.dumps(good[0]))
    doc["bufferViews"][0]["byteOffset"] = "zero"
    _expect_error(_save_glb(tmp_path, doc, good[1], name="str.glb"))
    doc = json.loads(json.dumps(good[0]))
    doc["bufferViews"][0]["byteOffset"] = 2.5
    _expect_error(_save_glb(tmp_path, doc, good[1], name="float.glb"))


# ---------------------------------------------------------------------------- independent tools

@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_output_passes_validator_and_playcanvas(tmp_path, suffix):
    """Khronos glTF-Validator: no errors besides the KHR attribute names it does not know, no
    warnings. PlayCanvas' KHR_gaussian_splatting parser reads the rest pose exactly."""
    import khr_tools

    khr_tools.require_node_tools()
    asset = _anchored_asset("local", sh_degree=3)
    path = tmp_path / f"out{suffix}"
    write_gltf(asset, path, quantize={"barycentrics": "unsigned_byte", "localRotation": "byte"})
    report = khr_tools.validate_gltf(path)
    assert report["numUnexpectedErrors"] == 0 and report["numWarnings"] == 0, report["messages"]
    codes = {m["code"] for m in report["messages"] if not m["expectedKhrAttribute"]}
    assert codes <= {"UNSUPPORTED_EXTENSION", "UNUSED_OBJECT"}, codes
    read = khr_tools.read_with_playcanvas(path)
    assert [r["mesh_name"] for r in read] == ["body", "bg"]
    stored = read_gltf(path)  # quantized anchors store their own rest pose (not asset's)
    np.testing.assert_array_equal(stored.primitives[1].splats.means, asset.primitives[1].splats.means)
    for got, want in zip(read, stored.primitives):
        s = want.splats
        assert np.array_equal(np.asarray(got["position"], np.float32), s.means)
        assert np.array_equal(np.asarray(got["rotation"], np.float32), s.rotations)
        assert np.array_equal(np.asarray(got["scale"], np.float32), s.scales)
        assert np.array_equal(np.asarray(got["opacity"], np.float32), s.opacities)
        assert np.array_equal(np.asarray(got["sh"], np.float32), s.sh)


@pytest.mark.parametrize("quantize", [{"barycentrics": "unsigned_byte", "localRotation": "byte"},
                                      {"barycentrics": "unsigned_short", "localRotation": "short"}])
@pytest.mark.parametrize("profile", ["local", "games"])
def test_quantized_anchors_store_their_own_rest_pose(tmp_path, quantize, profile):
    """Quantizing moves the splats by about half a step, and the stored rest pose is the remap
    of the anchors as stored (the asset stays self-consistent)."""
    import validation_assets as va
    from gsverse_format.remapping.reference import remap

    asset = va.local_asset(80) if profile == "local" else va.games_asset(80)
    path = tmp_path / "q.glb"
    write_gltf(asset, path, quantize=quantize if profile == "local" else
               {"barycentrics": quantize["barycentrics"]})
    got = read_gltf(path).primitives[0]
    rest = remap(got.anchoring)
    assert np.abs(rest.means - got.splats.means).max() < 1e-6
    assert max_rel_cov_error(got.splats.covariances(), rest.covariances) < 1e-5
    want = asset.primitives[0]
    step = 1 / 255 if quantize["barycentrics"] == "unsigned_byte" else 1 / 65535
    edge = np.linalg.norm(np.diff(want.anchoring.mesh.triangles(), axis=1), axis=2).max()
    moved = np.linalg.norm(got.splats.means - want.splats.means, axis=1).max()
    assert 0 < moved <= step * edge * 1.01
    np.testing.assert_array_equal(got.splats.opacities, want.splats.opacities)
