"""``gsverse-convert`` conventions: bad input exits 1 naming the input, inputs without splats are
refused, and ``KHR_gaussian_splatting`` properties of the input are kept or refused, never
rewritten."""
from __future__ import annotations

import json
import os
import struct
import subprocess
import sys

import numpy as np
import pygltflib
import pytest

from gsverse_format.cli.convert import main
from gsverse_format.errors import UsageError
from gsverse_format.io.gltf import asset_to_gltf, read_gltf, write_gltf
from gsverse_format.io.ply import write_splat_ply
from gsverse_format.model import KhrProperties, SplatAsset, SplatCloud, SplatPrimitive

from helpers import bumpy_sphere, random_splats, surface_splats
from source_fixtures import games_scene, write_gsverse_folder, write_obj

KHR = "KHR_gaussian_splatting"
PREFIX = "gsverse-convert: error: "


# ---------------------------------------------------------------------------- helpers

def _glb(doc: dict, blob: bytes) -> bytes:
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    out = struct.pack("<II", len(text), 0x4E4F534A) + text
    if blob:
        blob = bytes(blob) + b"\0" * (-len(blob) % 4)
        out += struct.pack("<II", len(blob), 0x004E4942) + blob
    return struct.pack("<4sII", b"glTF", 2, 12 + len(out)) + out


def _splat_doc(cloud: SplatCloud) -> tuple[dict, bytearray]:
    """The glTF JSON and buffer of one plain splat primitive holding ``cloud``."""
    gltf = asset_to_gltf(SplatAsset([SplatPrimitive(cloud, None, "splats")]))
    return json.loads(gltf.to_json()), bytearray(gltf.binary_blob())


def _set_accessor(doc: dict, blob: bytearray, index: int, values: np.ndarray) -> None:
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    data = np.asarray(values, "<f4").tobytes()
    blob[start:start + len(data)] = data


def _khr(doc: dict) -> dict:
    return doc["meshes"][0]["primitives"][0]["extensions"][KHR]


def _mesh_obj(tmp_path, cloud_mesh=None):
    mesh = cloud_mesh or bumpy_sphere(1, 0)
    path = tmp_path / "mesh.obj"
    write_obj(path, mesh.vertices, mesh.faces)
    return path


def _convert(capsys, *args) -> tuple[int, list[str]]:
    """Run the command in this process: (exit code, stderr lines)."""
    code = main([str(a) for a in args] + ["--quiet"])
    return code, capsys.readouterr().err.strip().splitlines()


def _assert_refused(code, lines, input_path, output_path, *words):
    """Exit 1, one line naming the input (not the output), no output written."""
    assert code == 1, lines
    assert len(lines) == 1, lines
    line = lines[0]
    assert line.startswith(PREFIX + str(input_path) + ": "), line
    assert "Traceback" not in line
    assert os.path.basename(str(output_path)) not in line, line
    for word in words:
        assert word in line, line
    assert not os.path.exists(output_path)
    leftovers = [n for n in os.listdir(os.path.dirname(str(output_path)))
                 if n.startswith(os.path.basename(str(output_path)))]
    assert not leftovers, leftovers


@pytest.fixture
def legacy_glb(tmp_path):
    """A KHR GLB whose SCALE holds log-space values (negative), as older exporters wrote."""
    cloud = random_splats(30, 4, sh_degree=1)
    doc, blob = _splat_doc(cloud)
    index = doc["meshes"][0]["primitives"][0]["attributes"][f"{KHR}:SCALE"]
    _set_accessor(doc, blob, index, np.log(cloud.scales))
    path = tmp_path / "legacy.glb"
    path.write_bytes(_glb(doc, blob))
    return path


# ---------------------------------------------------------------------------- bad input: exit 1

def test_legacy_log_scales_exit_1_naming_the_input(legacy_glb, tmp_path):
    """Through the command's module in a child process: exit 1, the input named."""
    out = tmp_path / "out.glb"
    proc = subprocess.run([sys.executable, "-m", "gsverse_format.cli.convert", str(legacy_glb),
                           str(out)], capture_output=True, text=True, timeout=300)
    _assert_refused(proc.returncode, proc.stderr.strip().splitlines(), legacy_glb, out,
                    "negative scales", "log-space")


@pytest.mark.parametrize("output, extra", [("out.glb", []), ("out.ply", []),
                                           ("out.usda", []), ("out.glb", ["--plain"]),
                                           ("out.glb", ["--mesh"])])
def test_legacy_log_scales_every_route(legacy_glb, tmp_path, capsys, output, extra):
    if extra == ["--mesh"]:
        extra = ["--mesh", _mesh_obj(tmp_path)]
    out = tmp_path / output
    code, lines = _convert(capsys, legacy_glb, out, *extra)
    _assert_refused(code, lines, legacy_glb, out, "negative scales")


def test_opacity_out_of_range_names_the_input(tmp_path, capsys):
    cloud = random_splats(12, 5, sh_degree=0)
    doc, blob = _splat_doc(cloud)
    index = doc["meshes"][0]["primitives"][0]["attributes"][f"{KHR}:OPACITY"]
    _set_accessor(doc, blob, index, np.full(12, -2.0))   # logits, not opacities
    path = tmp_path / "logits.glb"
    path.write_bytes(_glb(doc, blob))
    out = tmp_path / "out.glb"
    code, lines = _convert(capsys, path, out)
    _assert_refused(code, lines, path, out, "opacities outside [0, 1]")


@pytest.mark.parametrize("output", ["out.glb", "out.ply"])
def test_zero_rotation_names_the_input(tmp_path, capsys, output):
    """A zero quaternion is no rotation: refused for a KHR input as for a PLY input, naming the
    input whatever the output."""
    cloud = random_splats(10, 8, sh_degree=0)
    doc, blob = _splat_doc(cloud)
    index = doc["meshes"][0]["primitives"][0]["attributes"][f"{KHR}:ROTATION"]
    rotations = cloud.rotations.copy()
    rotations[3] = 0.0
    _set_accessor(doc, blob, index, rotations)
    path = tmp_path / "zero.glb"
    path.write_bytes(_glb(doc, blob))
    out = tmp_path / output
    code, lines = _convert(capsys, path, out)
    _assert_refused(code, lines, path, out, "zero rotation")


def test_infinite_scale_in_ply_names_the_input(tmp_path, capsys):
    """A 3DGS PLY whose log-scale overflows exp(): the input's fault, not the output's."""
    cloud = random_splats(8, 6, sh_degree=0)
    path = tmp_path / "huge.ply"
    write_splat_ply(cloud, path)
    data = bytearray(path.read_bytes())
    header = data[:data.index(b"end_header\n")].decode().splitlines()
    props = [line.split()[-1] for line in header if line.startswith("property")]
    body = data.index(b"end_header\n") + len(b"end_header\n")
    column = props.index("scale_0")
    data[body + 4 * column: body + 4 * column + 4] = np.array([1000.0], "<f4").tobytes()
    path.write_bytes(bytes(data))
    for output in ("out.glb", "out.ply"):
        out = tmp_path / output
        code, lines = _convert(capsys, path, out, "--plain")
        _assert_refused(code, lines, path, out)


# ---------------------------------------------------------------------------- no splats

@pytest.fixture
def mesh_only_glb(tmp_path):
    import trimesh

    mesh = bumpy_sphere(1, 0)
    path = tmp_path / "meshonly.glb"
    trimesh.Trimesh(mesh.vertices, mesh.faces).export(path)
    return path


@pytest.mark.parametrize("output, extra", [("out.glb", []), ("out.gltf", []), ("out.ply", []),
                                           ("out.usda", []), ("out.glb", ["--plain"]),
                                           ("out.glb", ["--mesh"]), ("out.glb", ["--from", "khr"])])
def test_mesh_only_glb_is_refused(mesh_only_glb, tmp_path, capsys, output, extra):
    if extra == ["--mesh"]:
        extra = ["--mesh", _mesh_obj(tmp_path)]
    out = tmp_path / output
    code, lines = _convert(capsys, mesh_only_glb, out, *extra)
    _assert_refused(code, lines, mesh_only_glb, out, KHR)


@pytest.fixture
def empty_ply(tmp_path):
    path = tmp_path / "empty.ply"
    write_splat_ply(random_splats(3, 0, sh_degree=0).subset(np.arange(0)), path)
    return path


@pytest.mark.parametrize("output, extra", [("out.glb", []), ("out.ply", []), ("out.usda", []),
                                           ("out.glb", ["--plain"]), ("out.glb", ["--mesh"])])
def test_zero_vertex_ply_is_refused(empty_ply, tmp_path, capsys, output, extra):
    if extra == ["--mesh"]:
        extra = ["--mesh", _mesh_obj(tmp_path)]
    out = tmp_path / output
    code, lines = _convert(capsys, empty_ply, out, *extra)
    _assert_refused(code, lines, empty_ply, out, "no splats")


def test_empty_trellis_ply_is_refused(tmp_path, capsys):
    """An SH0 PLY with normals and a GLB mesh (TRELLIS's layout) without any splat."""
    import trimesh

    path = tmp_path / "run.ply"
    cloud = random_splats(2, 1, sh_degree=0).subset(np.arange(0))
    cloud.extra = {}
    write_splat_ply(cloud, path)
    text = path.read_bytes()
    head = text[:text.index(b"end_header\n")]
    head = head.replace(b"property float z\n", b"property float z\nproperty float nx\n"
                        b"property float ny\nproperty float nz\n")
    path.write_bytes(head + b"end_header\n")
    mesh = bumpy_sphere(1, 0)
    glb = tmp_path / "run.glb"
    trimesh.Trimesh(mesh.vertices * 0.4, mesh.faces).export(glb)
    for source in ([], ["--from", "trellis"]):
        out = tmp_path / "out.glb"
        code, lines = _convert(capsys, path, out, "--mesh", glb, *source)
        _assert_refused(code, lines, path, out, "no splats")


def test_empty_usd_stage_is_refused(tmp_path, capsys):
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    path = tmp_path / "meshonly.usda"
    stage = Usd.Stage.CreateNew(str(path))
    mesh = UsdGeom.Mesh.Define(stage, "/World/mesh")
    mesh.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (0, 1, 0)])
    mesh.CreateFaceVertexCountsAttr([3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2])
    stage.GetRootLayer().Save()
    for output in ("out.glb", "out.ply", "out.usda"):
        out = tmp_path / output
        code, lines = _convert(capsys, path, out)
        _assert_refused(code, lines, path, out, "no splats")


def test_empty_usd_particle_field_is_refused(tmp_path, capsys):
    """A USD written by the library with one splat, then emptied of its points."""
    pytest.importorskip("pxr")
    from pxr import Usd, UsdVol

    from gsverse_format.io.usd import write_usd

    path = tmp_path / "emptied.usda"
    write_usd(SplatAsset([SplatPrimitive(random_splats(3, 2, sh_degree=0), None, "s")]), path)
    stage = Usd.Stage.Open(str(path))
    for prim in stage.Traverse():
        if prim.IsA(UsdVol.ParticleField3DGaussianSplat):
            for name in ("positions", "orientations", "scales", "opacities",
                         "radiance:sphericalHarmonicsCoefficients"):
                attr = prim.GetAttribute(name)
                if attr:
                    attr.Set([])
    stage.GetRootLayer().Save()
    out = tmp_path / "out.glb"
    code, lines = _convert(capsys, path, out)
    _assert_refused(code, lines, path, out, "no splats")


def test_empty_games_folder_is_refused(tmp_path, capsys):
    """A GS-Verse export folder whose point_cloud.ply holds no splat (mesh and parameters
    present): refused as having no splats, naming the PLY of the input folder."""
    scene = games_scene("colmap", k=2, seed=1)
    folder = tmp_path / "games"
    write_gsverse_folder(scene, folder)
    ply = folder / "point_cloud.ply"
    write_splat_ply(scene.cloud.subset(np.arange(0)), ply)
    for args in ([folder], [ply], [folder, "--from", "games"]):
        out = tmp_path / "out.glb"
        code, lines = _convert(capsys, args[0], out, *args[1:])
        _assert_refused(code, lines, ply, out, "no splats")


def test_drop_unanchored_leaving_nothing_is_refused(tmp_path, capsys):
    mesh = bumpy_sphere(1, 0)
    cloud = random_splats(20, 3, sh_degree=0, center=(50, 50, 50), spread=1.0)
    ply = tmp_path / "far.ply"
    write_splat_ply(cloud, ply)
    obj = _mesh_obj(tmp_path, mesh)
    out = tmp_path / "out.glb"
    code, lines = _convert(capsys, ply, out, "--mesh", obj, "--max-distance", "0.01",
                           "--drop-unanchored")
    _assert_refused(code, lines, ply, out, "--drop-unanchored", "nothing to write")


# ---------------------------------------------------------------------------- KHR properties

def _custom_glb(tmp_path, *, nested: dict | None = None, name="custom.glb", **props) -> str:
    doc, blob = _splat_doc(random_splats(25, 7, sh_degree=1))
    khr = _khr(doc)
    khr.update(props)
    if nested:
        khr["extensions"] = nested
        doc["extensionsUsed"] = doc["extensionsUsed"] + sorted(nested)
    path = tmp_path / name
    path.write_bytes(_glb(doc, blob))
    return path


CUSTOM = {"EXT_gaussian_splatting_kernel_customShape": {"gain": 1.25, "shape": "star"}}


def _written_khr(path) -> tuple[dict, list]:
    gltf = pygltflib.GLTF2().load(str(path))
    doc = json.loads(gltf.to_json())
    return _khr(doc), doc["extensionsUsed"]


def test_reader_keeps_unknown_values_and_nested_extensions(tmp_path):
    path = _custom_glb(tmp_path, nested=CUSTOM, kernel="customShape", projection="orthographic",
                       sortingMethod="zDepth", colorSpace="custom_space_display")
    prim = read_gltf(path).primitives[0]
    assert prim.khr == KhrProperties("customShape", "orthographic", "zDepth", CUSTOM)
    assert prim.splats.color_space == "custom_space_display"
    out = tmp_path / "again.glb"
    write_gltf(read_gltf(path), out)
    khr, used = _written_khr(out)
    assert khr["kernel"] == "customShape" and khr["projection"] == "orthographic"
    assert khr["sortingMethod"] == "zDepth" and khr["colorSpace"] == "custom_space_display"
    assert khr["extensions"] == CUSTOM
    assert "EXT_gaussian_splatting_kernel_customShape" in used


@pytest.mark.parametrize("extra", [[], ["--plain"], ["--sh-degree", "0"], ["--mesh"]])
def test_custom_kernel_and_nested_extension_are_kept(tmp_path, capsys, extra):
    path = _custom_glb(tmp_path, nested=CUSTOM, kernel="customShape")
    if extra == ["--mesh"]:
        mesh = bumpy_sphere(1, 0)
        extra = ["--mesh", _mesh_obj(tmp_path, mesh)]
    out = tmp_path / "out.glb"
    code, lines = _convert(capsys, path, out, *extra)
    assert code == 0, lines
    for prim in read_gltf(out).primitives:
        assert prim.khr.kernel == "customShape"
        assert prim.khr.extensions == CUSTOM
    khr, used = _written_khr(out)
    name = "EXT_gaussian_splatting_kernel_customShape"
    assert khr["kernel"] == "customShape" and khr["extensions"][name] == CUSTOM[name]
    assert name in used


def test_anchor_and_foreign_nested_extensions_live_side_by_side(tmp_path, capsys):
    mesh = bumpy_sphere(1, 0)
    cloud = surface_splats(mesh, 60, 2)
    doc, blob = _splat_doc(cloud)
    _khr(doc)["extensions"] = {"VENDOR_marker": {}}
    doc["extensionsUsed"].append("VENDOR_marker")
    path = tmp_path / "marked.glb"
    path.write_bytes(_glb(doc, blob))
    anchored = tmp_path / "anchored.glb"
    code, lines = _convert(capsys, path, anchored, "--mesh", _mesh_obj(tmp_path, mesh))
    assert code == 0, lines
    again = tmp_path / "again.glb"
    code, lines = _convert(capsys, anchored, again)
    assert code == 0, lines
    prim = read_gltf(again).primitives[0]
    assert prim.anchoring is not None and prim.khr.extensions == {"VENDOR_marker": {}}
    khr, _ = _written_khr(again)
    assert set(khr["extensions"]) == {"VENDOR_marker", "GSVERSE_gaussian_splatting_mesh_anchor"}


@pytest.mark.parametrize("output", ["out.ply", "out.usda"])
def test_custom_kernel_to_a_format_without_kernels_is_refused(tmp_path, capsys, output):
    path = _custom_glb(tmp_path, kernel="customShape")
    out = tmp_path / output
    code, lines = _convert(capsys, path, out)
    _assert_refused(code, lines, path, out, "customShape")


def test_nested_extension_with_references_is_refused(tmp_path, capsys):
    """Integers may be accessor indices the rewritten file renumbers: never copied blindly."""
    nested = {"MPEG_gaussian_splatting_transport": {"stitching": {"faceIndex": 3,
                                                                  "weights": 4}}}
    path = _custom_glb(tmp_path, nested=nested)
    for extra in ([], ["--plain"], ["--mesh", _mesh_obj(tmp_path)]):
        out = tmp_path / "out.glb"
        code, lines = _convert(capsys, path, out, *extra)
        _assert_refused(code, lines, path, out, "MPEG_gaussian_splatting_transport",
                        "integer")
    asset = read_gltf(path)   # the library reads it, and refuses to write it
    with pytest.raises(UsageError, match="MPEG_gaussian_splatting_transport"):
        write_gltf(asset, tmp_path / "api.glb")
    assert not (tmp_path / "api.glb").exists()


def test_required_foreign_nested_extension_is_refused(tmp_path, capsys):
    """Listed in extensionsRequired, it has no fallback: the splats cannot be read without it."""
    doc, blob = _splat_doc(random_splats(6, 9, sh_degree=0))
    _khr(doc).update(kernel="customShape", extensions=CUSTOM)
    doc["extensionsUsed"] += sorted(CUSTOM)
    doc["extensionsRequired"] = sorted(CUSTOM)
    path = tmp_path / "required.glb"
    path.write_bytes(_glb(doc, blob))
    out = tmp_path / "out.glb"
    code, lines = _convert(capsys, path, out)
    _assert_refused(code, lines, path, out, "extensionsRequired",
                    "EXT_gaussian_splatting_kernel_customShape")


def test_nested_extension_with_its_own_attributes_is_refused(tmp_path, capsys):
    """The base extension's own example: a custom kernel whose extension adds a per-splat
    attribute. The attribute is not carried, so neither can the extension be."""
    doc, blob = _splat_doc(random_splats(6, 10, sh_degree=0))
    prim = doc["meshes"][0]["primitives"][0]
    name = "EXT_gaussian_splatting_kernel_customShape"
    prim["attributes"][f"{name}:CUSTOM_ATTRIBUTE"] = prim["attributes"][f"{KHR}:OPACITY"]
    _khr(doc).update(kernel="customShape", extensions={name: {}})
    doc["extensionsUsed"].append(name)
    path = tmp_path / "attribute.glb"
    path.write_bytes(_glb(doc, blob))
    assert read_gltf(path).primitives[0].khr.attributes == (f"{name}:CUSTOM_ATTRIBUTE",)
    for extra in ([], ["--mesh", _mesh_obj(tmp_path)]):
        out = tmp_path / "out.glb"
        code, lines = _convert(capsys, path, out, *extra)
        _assert_refused(code, lines, path, out, f"{name}:CUSTOM_ATTRIBUTE")


def test_non_string_kernel_is_refused(tmp_path, capsys):
    path = _custom_glb(tmp_path, kernel=7)
    out = tmp_path / "out.glb"
    code, lines = _convert(capsys, path, out)
    _assert_refused(code, lines, path, out, "kernel")


def test_joined_primitives_with_different_kernels_are_refused(tmp_path, capsys):
    a = SplatPrimitive(random_splats(10, 1, sh_degree=0), None, "a")
    b = SplatPrimitive(random_splats(10, 2, sh_degree=0), None, "b",
                       KhrProperties(kernel="customShape"))
    path = tmp_path / "two.glb"
    write_gltf(SplatAsset([a, b]), path)
    out = tmp_path / "out.glb"
    code, lines = _convert(capsys, path, out, "--mesh", _mesh_obj(tmp_path))
    _assert_refused(code, lines, path, out, "kernel")
    code, lines = _convert(capsys, path, out)      # kept per primitive when not joined
    assert code == 0, lines
    assert [p.khr.kernel for p in read_gltf(out).primitives] == ["ellipse", "customShape"]


def test_real_extensible_fallback_fixture_keeps_its_kernel(shared_data, tmp_path, capsys):
    path = shared_data / "khr_gaussian" / "bevy_khr_extensible_fallback.gltf"
    if not path.is_file():
        pytest.skip("fallback fixture not present")
    out = tmp_path / "out.glb"
    code, lines = _convert(capsys, path, out)
    assert code == 0, lines
    prim = read_gltf(out).primitives[0]
    assert prim.khr.kernel == "customShape"
    assert prim.khr.extensions == {"EXT_gaussian_splatting_kernel_customShape": {"gain": 1.25}}
    assert prim.splats.color_space == "custom_space_display"


def test_real_log_scale_fixture_is_refused(shared_data, tmp_path, capsys):
    path = shared_data / "khr_gaussian" / "bevy_khr_conformance_matrix.glb"
    if not path.is_file():
        pytest.skip("conformance matrix not present")
    out = tmp_path / "out.glb"
    code, lines = _convert(capsys, path, out)
    _assert_refused(code, lines, path, out, "negative scales")


# ---------------------------------------------------------------------------- --mesh mistakes

def test_a_splat_ply_given_as_mesh_is_a_point_cloud(tmp_path, capsys):
    """The splats of another capture given as --mesh (vertices, no faces): one line naming
    that file, saying it is a point cloud of splats and not a triangle mesh, exit 1."""
    splats = tmp_path / "splats.ply"
    other = tmp_path / "other_splats.ply"
    write_splat_ply(random_splats(40, 1, sh_degree=0), splats)
    write_splat_ply(random_splats(25, 2, sh_degree=1), other)
    out = tmp_path / "out.glb"
    code, lines = _convert(capsys, splats, out, "--mesh", other)
    assert code == 1 and len(lines) == 1 and "Traceback" not in lines[0], lines
    assert lines[0].startswith(f"{PREFIX}{other}: is a point cloud of 25 Gaussian splats")
    assert "not a triangle mesh" in lines[0]
    assert not out.exists()
    # a plain point cloud (x, y, z only) is named as such
    cloud = tmp_path / "cloud.ply"
    cloud.write_text("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
                     "property float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n")
    code, lines = _convert(capsys, splats, out, "--mesh", cloud)
    assert code == 1 and lines == [f"{PREFIX}{cloud}: is a point cloud of 2 vertices (no 'face' "
                                   "element), not a triangle mesh"]
