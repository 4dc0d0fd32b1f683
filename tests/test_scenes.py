"""Scenes of several objects: gsverse-convert scene.ply out.glb --mesh fox.obj --mesh chair.glb."""
from __future__ import annotations

import json
import pathlib

import numpy as np
import pytest
from gsverse_format.validators import validate_file
from helpers import random_splats

from gsverse_format import read
from gsverse_format.cli.convert import main
from gsverse_format.examples import example_mesh, example_splats, write_obj
from gsverse_format.io.gltf import read_gltf
from gsverse_format.io.ply import write_splat_ply
from gsverse_format.model import SplatCloud, TriangleMesh
from gsverse_format.nearest import closest_points_on_triangles
from gsverse_format.pipeline import ConvertOptions, convert
from gsverse_format.scene import bind_scene

ROOT = pathlib.Path(__file__).resolve().parents[1]
N_FOX, N_CHAIR, N_BACKGROUND = 400, 300, 150


def _chair() -> TriangleMesh:
    m = example_mesh(subdivisions=2, seed=1)
    return TriangleMesh(m.vertices * np.float32(0.6) + np.float32([2.0, 0.0, 0.0]), m.faces)


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """Splats on two objects (a 'fox' OBJ, a 'chair' GLB) and a far background shell."""
    import trimesh

    folder = tmp_path_factory.mktemp("scene")
    fox, chair = example_mesh(subdivisions=2), _chair()
    background = random_splats(N_BACKGROUND, seed=4, sh_degree=1, spread=1.0)
    background.means = (background.means / np.linalg.norm(background.means, axis=1,
                                                          keepdims=True) * 9.0).astype(np.float32)
    cloud = SplatCloud.concatenate([example_splats(fox, N_FOX, seed=3),
                                    example_splats(chair, N_CHAIR, seed=5), background])
    write_splat_ply(cloud, folder / "scene.ply")
    write_obj(fox, str(folder / "fox.obj"))
    trimesh.Trimesh(chair.vertices, chair.faces, process=False).export(folder / "chair.glb")
    return folder


def _args(folder: pathlib.Path, out: pathlib.Path, *extra: str) -> list[str]:
    return [str(folder / "scene.ply"), str(out), "--mesh", str(folder / "fox.obj"),
            "--mesh", str(folder / "chair.glb"), "--max-distance", "0.05", "-w", *extra]


def test_two_object_scene_gltf(scene, capsys):
    out = scene / "scene.glb"
    assert main(_args(scene, out, "--json")) == 0
    summary = json.loads(capsys.readouterr().out)
    assert (summary["anchored"], summary["static"]) == (N_FOX + N_CHAIR, N_BACKGROUND)
    objects = {o["name"]: o for o in summary["objects"]}
    assert list(objects) == ["fox", "chair"]
    assert objects["fox"]["splats"] == N_FOX and objects["chair"]["splats"] == N_CHAIR
    assert objects["fox"]["faces"] == 320 and objects["chair"]["faces"] == 320
    for o in objects.values():
        assert o["distance"]["p95"] < 0.02 and o["distance"]["max"] <= o["max_distance"]
    assert [m["name"] for m in summary["anchor_meshes"]] == ["fox", "chair"]
    assert all(m["closed_manifold"] for m in summary["anchor_meshes"])

    asset = read_gltf(out)
    assert [p.name for p in asset.primitives] == ["fox", "chair", "scene static"]
    assert [len(p.splats) for p in asset.primitives] == [N_FOX, N_CHAIR, N_BACKGROUND]
    assert asset.primitives[2].anchoring is None
    fox_mesh, chair_mesh = (p.anchoring.mesh for p in asset.anchored)
    assert abs(abs(chair_mesh.vertices.mean(axis=0)[0]) - 2.0) < 0.1   # the chair's mesh
    doc = json.loads(out.read_bytes()[20:20 + int.from_bytes(out.read_bytes()[12:16], "little")])
    assert [n["name"] for n in doc["nodes"]] == ["fox", "chair", "scene static"]
    assert [m["name"] for m in doc["meshes"]][3:] == ["fox anchor mesh", "chair anchor mesh"]
    report = validate_file(out)
    assert report.findings == [], [(f.code, f.message) for f in report.findings]


def test_two_object_scene_text_summary(scene, capsys):
    assert main(_args(scene, scene / "text.glb")) == 0
    text = capsys.readouterr().out
    assert "object     fox: 400 splats, 320 faces, distance p50" in text
    assert "object     chair: 300 splats" in text
    assert "manifold   fox anchor mesh: a closed 2-manifold" in text


def test_two_object_scene_usd(scene, capsys):
    pytest.importorskip("pxr")
    out = scene / "scene.usda"
    assert main(_args(scene, out, "-q", "--collider", "hull")) == 0
    report = validate_file(out)
    assert report.findings == [], [(f.code, f.message) for f in report.findings]
    asset = read(out)
    assert sorted((p.name, len(p.splats), p.anchoring is not None) for p in asset.primitives) \
        == [("chair", N_CHAIR, True), ("fox", N_FOX, True), ("scene static", N_BACKGROUND, False)]
    text = out.read_text()
    assert 'def Mesh "fox_anchor_mesh"' in text and 'def Mesh "chair_anchor_mesh"' in text
    assert 'def Mesh "fox_anchor_mesh_hull_collider"' in text
    assert text.count("PhysicsCollisionAPI") == 2


def test_scene_binds_to_the_nearest_mesh_over_all(scene):
    fox, chair = example_mesh(subdivisions=2), _chair()
    splats = random_splats(300, seed=9, sh_degree=0, spread=3.0)
    owner, bound = bind_scene(splats, [fox, chair])
    best = []
    for mesh in (fox, chair):   # brute force: every splat against every triangle
        tri = mesh.triangles()
        means = np.repeat(splats.means.astype(np.float64), mesh.face_count, axis=0)
        _, _, d = closest_points_on_triangles(means, *(np.tile(tri[:, k], (len(splats), 1))
                                                       for k in range(3)))
        best.append(d.reshape(len(splats), mesh.face_count).min(axis=1))
    assert np.array_equal(owner, np.argmin(np.stack(best), axis=0))
    for j, b in enumerate(bound):
        assert np.allclose(b.distance, best[j], atol=1e-9)
    same, _ = bind_scene(splats, [fox, fox])   # ties go to the mesh given first
    assert not same.any()


def test_scene_max_distance_is_per_object_and_drop(scene):
    out = scene / "dropped.glb"
    summary = convert(scene / "scene.ply", out, ConvertOptions(
        meshes=[str(scene / "fox.obj"), str(scene / "chair.glb")], max_distance=0.005,
        absolute_distance=True, drop_unanchored=True))
    assert summary.static == 0 and summary.dropped > N_BACKGROUND
    assert all(o["max_distance"] == 0.005 for o in summary.objects)
    assert summary.anchored == sum(o["splats"] for o in summary.objects)
    assert [p.name for p in read_gltf(out).primitives] == ["fox", "chair"]


def test_single_mesh_output_is_unchanged(tmp_path, example_asset):
    """One --mesh writes exactly what it always did: the example asset, byte for byte."""
    capsule = ROOT / "examples" / "capsule"
    out = tmp_path / "anchored.glb"
    assert main([str(capsule / "splats.ply"), str(out), "--mesh", str(capsule / "mesh.obj"),
                 "-q"]) == 0
    assert out.read_bytes() == example_asset.read_bytes()
    listed = tmp_path / "listed.glb"
    convert(capsule / "splats.ply", listed, ConvertOptions(meshes=[str(capsule / "mesh.obj")]))
    assert listed.read_bytes() == out.read_bytes()
