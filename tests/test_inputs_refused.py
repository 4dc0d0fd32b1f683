"""Hostile and careless inputs, generated here: what must be refused with one line naming the
input (and nothing written), and what the validator must report about what it read."""
from __future__ import annotations

import json
import os
import pathlib
import shutil
import subprocess
import sys

import numpy as np
import pytest

from gsverse_format.binding import bind_local
from gsverse_format.codes import Code
from gsverse_format.converters import detect_source
from gsverse_format.converters.base import SourceOptions
from gsverse_format.errors import FormatError
from gsverse_format.examples import example_mesh, example_splats
from gsverse_format.io.gltf import asset_to_gltf, glb_bytes, gltf_to_bytes
from gsverse_format.io.ply import write_splat_ply
from gsverse_format.model import Anchoring, SplatAsset, SplatCloud, SplatPrimitive
from gsverse_format.pipeline import load_source
from gsverse_format.validators.validate import validate_file

from source_fixtures import games_scene, write_gsverse_folder

ROOT = pathlib.Path(__file__).resolve().parents[1]
CONVERT = [sys.executable, "-m", "gsverse_format.cli.convert"]


def _convert(cwd, *args):
    return subprocess.run(CONVERT + [str(a) for a in args], capture_output=True, text=True,
                          cwd=cwd, timeout=300, env={**os.environ, "PYTHONPATH": str(ROOT)})


# ---------------------------------------------------------------------------- USD value clips

CLIP_LAYER = """#usda 1.0
(
    defaultPrim = "Root"
    metersPerUnit = 1
    upAxis = "Y"
)
def Xform "Root" (
    clips = {{
        dictionary default = {{
            {entry}
            string primPath = "/Root"
            double2[] active = [(0, 0)]
            double2[] times = [(0, 0)]
        }}
    }}
)
{{
}}
"""
CLIP_IN_VARIANT = """#usda 1.0
def Xform "Root" (
    variantSets = "v"
    variants = { string v = "x" }
)
{
    variantSet "v" = {
        "x" (
            clips = { dictionary d = { asset manifestAssetPath = @../outside.usda@ } }
        ) {}
    }
}
"""


@pytest.mark.parametrize("entry", [
    "asset[] assetPaths = [@../outside.usda@]",
    "asset[] assetPaths = [@./inside.usda@, @../outside.usda@]",
    "asset manifestAssetPath = @../outside.usda@",
    'string templateAssetPath = "../outside.#.usda"\n            double templateStartTime = 0\n'
    "            double templateEndTime = 1\n            double templateStride = 1",
    "asset[] assetPaths = [@/etc/hostname@]",
])
def test_usd_value_clips_outside_the_folder_are_refused(tmp_path, entry):
    pytest.importorskip("pxr")
    from gsverse_format.io.usd import read_usd

    inner = tmp_path / "asset"
    inner.mkdir()
    # Unparseable on purpose: had it been opened, the error would be a USD parse error.
    (tmp_path / "outside.usda").write_text("#usda 1.0\nnot usd at all {\n")
    (tmp_path / "outside.0.usda").write_text("#usda 1.0\nnot usd at all {\n")
    (inner / "inside.usda").write_text('#usda 1.0\ndef Xform "Root" {}\n')
    path = inner / "clips.usda"
    path.write_text(CLIP_LAYER.format(entry=entry))
    with pytest.raises(FormatError, match="leaves the asset's folder|absolute path"):
        read_usd(path)
    report = validate_file(path)
    assert Code.USD_LAYER_OUTSIDE_FOLDER in report.codes(), report.codes()
    assert report.exit_status == 1
    proc = _convert(tmp_path, path, tmp_path / "out.glb")
    assert proc.returncode == 1 and len(proc.stderr.splitlines()) == 1, proc.stderr
    assert "folder" in proc.stderr and not (tmp_path / "out.glb").exists()


def test_usd_value_clip_manifest_in_a_variant_is_refused(tmp_path):
    pytest.importorskip("pxr")
    inner = tmp_path / "asset"
    inner.mkdir()
    (tmp_path / "outside.usda").write_text("#usda 1.0\nnot usd at all {\n")
    (inner / "variant.usda").write_text(CLIP_IN_VARIANT)
    assert Code.USD_LAYER_OUTSIDE_FOLDER in validate_file(inner / "variant.usda").codes()


def test_usd_value_clips_inside_the_folder_are_followed(tmp_path):
    pytest.importorskip("pxr")
    from gsverse_format.io.usd import read_usd
    from gsverse_format.io.usd.clips import clip_asset_paths
    from pxr import Sdf

    (tmp_path / "inside.usda").write_text('#usda 1.0\ndef Xform "Root" {}\n')
    path = tmp_path / "clips.usda"
    path.write_text(CLIP_LAYER.format(entry="asset[] assetPaths = [@./inside.usda@]"))
    assert clip_asset_paths(Sdf.Layer.FindOrOpen(str(path))) == ["./inside.usda"]
    assert len(read_usd(path).primitives) == 0  # read (no splats), not refused
    assert Code.USD_LAYER_OUTSIDE_FOLDER not in validate_file(path).codes()


def test_usd_payload_and_reference_outside_the_folder_are_refused(tmp_path):
    pytest.importorskip("pxr")
    inner = tmp_path / "asset"
    inner.mkdir()
    (tmp_path / "outside.usda").write_text('#usda 1.0\ndef Xform "Root" {}\n')
    for arc in ("payload", "references"):
        path = inner / f"{arc}.usda"
        path.write_text(f'#usda 1.0\ndef Xform "Root" ({arc} = @../outside.usda@</Root>) {{}}\n')
        assert Code.USD_LAYER_OUTSIDE_FOLDER in validate_file(path).codes(), arc


# ---------------------------------------------------------------------------- GaMeS symlinks

@pytest.mark.parametrize("name", ["model_params.json", "mesh.obj", "point_cloud.ply"])
def test_games_run_folder_refuses_links_to_outside_files(tmp_path, name):
    if not hasattr(os, "symlink"):
        pytest.skip("no symbolic links")
    scene = games_scene("colmap", k=2)
    elsewhere = write_gsverse_folder(scene, tmp_path / "elsewhere")
    run = write_gsverse_folder(scene, tmp_path / "run")
    os.remove(run / name)
    os.symlink(elsewhere / name, run / name)
    with pytest.raises(FormatError) as info:
        load_source("games", str(run), None, SourceOptions())
    assert info.value.path == str(run / name)
    assert "outside the run folder" in info.value.cause
    proc = _convert(tmp_path, run, tmp_path / "out.glb", "--from", "games")
    assert proc.returncode == 1 and len(proc.stderr.splitlines()) == 1, proc.stderr
    assert "outside the run folder" in proc.stderr and not (tmp_path / "out.glb").exists()


def test_games_run_folder_follows_links_inside_it(tmp_path):
    if not hasattr(os, "symlink"):
        pytest.skip("no symbolic links")
    scene = games_scene("colmap", k=2)
    run = write_gsverse_folder(scene, tmp_path / "run")
    (run / "data").mkdir()
    shutil.move(run / "mesh.obj", run / "data" / "mesh.obj")
    os.symlink(os.path.join("data", "mesh.obj"), run / "mesh.obj")
    result = load_source("games", str(run), None, SourceOptions())
    assert len(result.splats) == len(scene.cloud)


# ---------------------------------------------------------------------------- no splats

def _empty_ply(path: pathlib.Path) -> None:
    props = "".join(f"property float {n}\n" for n in (
        "x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
        "rot_0", "rot_1", "rot_2", "rot_3"))
    path.write_bytes(f"ply\nformat binary_little_endian 1.0\nelement vertex 0\n{props}"
                     "end_header\n".encode())


@pytest.mark.parametrize("args", [[], ["--plain"], ["--from", "3dgs"]])
@pytest.mark.parametrize("suffix", [".glb", ".ply", ".usda"])
def test_empty_ply_is_refused(tmp_path, args, suffix):
    _empty_ply(tmp_path / "empty.ply")
    out = tmp_path / ("out" + suffix)
    proc = _convert(tmp_path, "empty.ply", out, *args)
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr.startswith("gsverse-convert: error: empty.ply: no splats"), proc.stderr
    assert not out.exists()


def test_asset_without_splats_is_a_validator_error(tmp_path):
    path = tmp_path / "empty.glb"
    path.write_bytes(gltf_to_bytes(asset_to_gltf(SplatAsset([])), binary=True))
    report = validate_file(path)
    found = [f for f in report.findings if f.code == Code.NO_SPLATS]
    assert found and report.exit_status == 1
    assert "no KHR_gaussian_splatting primitive" in found[0].message
    assert "not checked" in found[0].message


def test_usd_stage_without_splats_is_a_validator_error(tmp_path):
    pytest.importorskip("pxr")
    path = tmp_path / "empty.usda"
    path.write_text('#usda 1.0\n(\n    defaultPrim = "Asset"\n    metersPerUnit = 1\n'
                    '    upAxis = "Y"\n)\ndef Xform "Asset" {}\n')
    report = validate_file(path)
    assert Code.NO_SPLATS in report.codes() and report.exit_status == 1


# ---------------------------------------------------------------------------- bad input values

def _patched_glb(path: pathlib.Path, anchored: bool, field: str, edit) -> None:
    """A GLB of 40 splats whose ``field`` values (as float32 in the binary chunk) are edited."""
    mesh = example_mesh(1)
    cloud = example_splats(mesh, 40, seed=3)
    anchoring = Anchoring(mesh, bind_local(cloud, mesh).anchors) if anchored else None
    data = gltf_to_bytes(asset_to_gltf(SplatAsset([SplatPrimitive(cloud, anchoring, "body")])))
    raw = getattr(cloud, field).astype("<f4").tobytes()
    at = data.find(raw)
    assert at > 0
    values = edit(np.frombuffer(raw, "<f4").copy().reshape(getattr(cloud, field).shape))
    path.write_bytes(data[:at] + values.astype("<f4").tobytes() + data[at + len(raw):])


@pytest.mark.parametrize("field, edit, cause", [
    ("scales", lambda a: np.where(np.arange(len(a))[:, None] % 5 == 0, -a, a), "negative scale"),
    ("opacities", lambda a: np.where(np.arange(len(a)) % 4 == 0, 1.5, a), "opacities outside"),
    ("rotations", lambda a: np.where(np.arange(len(a))[:, None] < 2, 0.0, a), "zero rotation"),
])
@pytest.mark.parametrize("anchored", [False, True])
@pytest.mark.parametrize("args", [[], ["--plain"]])
def test_bad_values_in_an_input_glb_name_the_input(tmp_path, field, edit, cause, anchored, args):
    _patched_glb(tmp_path / "bad.glb", anchored, field, edit)
    existing = tmp_path / "out.glb"
    existing.write_bytes(b"previous output")
    proc = _convert(tmp_path, "bad.glb", "out.glb", "-w", *args)
    assert proc.returncode == 1, proc.stderr
    assert len(proc.stderr.splitlines()) == 1
    assert proc.stderr.startswith("gsverse-convert: error: bad.glb: "), proc.stderr
    assert cause in proc.stderr
    assert existing.read_bytes() == b"previous output"


# ---------------------------------------------------------------------------- mesh-only glTF

def _mesh_gltf(path: pathlib.Path, nodes: list, indices: list[int], scenes=None) -> None:
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float32).tobytes()
    index = np.array(indices, np.uint32).tobytes()
    doc = {"asset": {"version": "2.0"}, "scene": 0,
           "scenes": scenes if scenes is not None else [{"nodes": [0]}], "nodes": nodes,
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                          "min": [0, 0, 0], "max": [1, 1, 0]},
                         {"bufferView": 1, "componentType": 5125, "count": len(indices),
                          "type": "SCALAR"}],
           "bufferViews": [{"buffer": 0, "byteLength": 48},
                           {"buffer": 0, "byteOffset": 48, "byteLength": len(index)}],
           "buffers": [{"byteLength": 48 + len(index)}]}
    path.write_bytes(glb_bytes(json.dumps(doc).encode(), vertices + index))


def test_mesh_only_gltf_reports_what_it_read(tmp_path):
    good = tmp_path / "good.glb"
    _mesh_gltf(good, [{"mesh": 0}], [0, 1, 2, 1, 3, 2])
    report = validate_file(good)
    assert report.codes() >= {Code.NO_SPLATS}
    assert not report.codes() & {Code.MESH_INDEX_OUT_OF_RANGE, Code.NODE_GRAPH_INVALID}
    message = next(f.message for f in report.findings if f.code == Code.NO_SPLATS)
    assert "1 node(s) and the indices of 1 other mesh primitive(s)" in message

    bad = tmp_path / "indices.glb"
    _mesh_gltf(bad, [{"mesh": 0}], [0, 1, 2, 1, 3, 4000])
    found = [f for f in validate_file(bad).findings if f.code == Code.MESH_INDEX_OUT_OF_RANGE]
    assert found and found[0].pointer == "/meshes/0/primitives/0/indices"
    assert "1 of 6 indices" in found[0].message and "4000" in found[0].message


@pytest.mark.parametrize("nodes, scenes, code, pointer", [
    ([{"mesh": 0, "children": [1]}, {"children": [0]}], None, Code.GLTF_SCHEMA_VIOLATION,
     "/nodes/1/children"),
    ([{"mesh": 0}, {"children": [2]}, {"children": [1]}], None, Code.GLTF_SCHEMA_VIOLATION,
     "/nodes/2/children"),  # a cycle the scene does not reach
    ([{"children": [1, 1]}, {"mesh": 0}], None, Code.NODE_GRAPH_INVALID, "/nodes/0/children/1"),
    ([{"children": [2]}, {"children": [2]}, {"mesh": 0}], [{"nodes": [0, 1]}],
     Code.NODE_GRAPH_INVALID, "/nodes/1/children/0"),
    ([{"children": [1]}, {"mesh": 0}], [{"nodes": [0, 1]}], Code.NODE_GRAPH_INVALID,
     "/scenes/0/nodes/1"),
    ([{"children": [5]}], None, Code.UNRESOLVED_REFERENCE, "/nodes/0/children/0"),
])
def test_node_graph_errors(tmp_path, nodes, scenes, code, pointer):
    path = tmp_path / "graph.glb"
    _mesh_gltf(path, nodes, [0, 1, 2], scenes)
    report = validate_file(path)
    assert report.exit_status == 1
    found = [f for f in report.findings if f.code == code]
    assert found, sorted(report.codes())
    assert any(f.pointer == pointer for f in found), [f.pointer for f in found]
    assert Code.INTERNAL_ERROR not in report.codes()


def test_node_bomb_is_refused_by_the_validator_without_expanding(tmp_path):
    """Each node lists the next one 8 times: 8^40 paths, 41 nodes."""
    depth = 40
    nodes = [{"children": [i + 1] * 8} for i in range(depth)] + [{"mesh": 0}]
    path = tmp_path / "bomb.glb"
    _mesh_gltf(path, nodes, [0, 1, 2])
    report = validate_file(path)
    assert Code.NODE_GRAPH_INVALID in report.codes() and report.exit_status == 1
    assert report.seconds < 30


# ---------------------------------------------------------------------------- detection

def _sh0_ply(path: pathlib.Path, means: np.ndarray, scales: np.ndarray) -> None:
    n = len(means)
    rng = np.random.default_rng(0)
    q = rng.normal(size=(n, 4))
    cloud = SplatCloud(means, q / np.linalg.norm(q, axis=1, keepdims=True), scales,
                       rng.uniform(0.2, 1, n), rng.normal(0, 0.3, (n, 1, 3)))
    write_splat_ply(cloud, path, normals=True)


def _glb_mesh(path: pathlib.Path) -> None:
    import trimesh

    trimesh.creation.icosphere(2).export(str(path))


def test_detection_needs_trellis_values_not_only_its_layout(tmp_path):
    rng = np.random.default_rng(1)
    _glb_mesh(tmp_path / "mesh.glb")
    trellis_like = tmp_path / "trellis.ply"
    _sh0_ply(trellis_like, rng.uniform(-0.45, 0.45, (300, 3)),
             rng.uniform(2e-3, 2e-2, (300, 3)))
    source, reason = detect_source(str(trellis_like), str(tmp_path / "mesh.glb"))
    assert source == "trellis" and "unit cube" in reason and "--from 3dgs" in reason
    # The same layout from a plain 3DGS scene: beyond the cube, or scales below the kernel.
    for name, means, scales in (
            ("scene.ply", rng.uniform(-4, 4, (300, 3)), rng.uniform(2e-3, 2e-2, (300, 3))),
            ("small.ply", rng.uniform(-0.45, 0.45, (300, 3)), rng.uniform(1e-5, 2e-2, (300, 3)))):
        _sh0_ply(tmp_path / name, means, scales)
        source, reason = detect_source(str(tmp_path / name), str(tmp_path / "mesh.glb"))
        assert source == "3dgs", (name, reason)
        assert "--from" in reason


def test_plain_3dgs_ply_with_normals_and_a_glb_mesh_converts(tmp_path):
    mesh = example_mesh(1)
    cloud = example_splats(mesh, 200, seed=2)
    big = SplatCloud(cloud.means * 5.0, cloud.rotations, cloud.scales * 5.0, cloud.opacities,
                     cloud.sh[:, :1])
    write_splat_ply(big, tmp_path / "scene.ply", normals=True)
    import trimesh

    trimesh.Trimesh(mesh.vertices * 5.0, mesh.faces).export(str(tmp_path / "mesh.glb"))
    proc = _convert(tmp_path, "scene.ply", "out.glb", "--mesh", "mesh.glb")
    assert proc.returncode == 0, proc.stderr
    assert "detected source 3dgs" in proc.stdout, proc.stdout
    assert validate_file(tmp_path / "out.glb").exit_status == 0
