"""Only what the scene requires: --max-distance, --drop-unanchored, summaries, source detection."""
from __future__ import annotations

import json

import numpy as np
import pytest

from gsverse_format.cli.convert import main
from gsverse_format.pipeline import ConvertOptions, convert
from gsverse_format.converters import detect_source
from gsverse_format.examples import example_mesh, example_splats, write_obj
from gsverse_format.io.gltf import read_gltf
from gsverse_format.io.ply import read_splat_ply, write_splat_ply
from gsverse_format.io.registry import FRAMES
from gsverse_format.model import SplatCloud
from gsverse_format.transform import rotate_splats

from helpers import random_splats


@pytest.fixture()
def scene(tmp_path):
    """Splats on a mesh plus a far 'background' shell of splats; no frame change needed."""
    mesh = example_mesh(subdivisions=2)
    near = example_splats(mesh, count=500, seed=3)
    far = random_splats(200, seed=4, sh_degree=1, spread=1.0)
    far.means = (far.means / np.linalg.norm(far.means, axis=1, keepdims=True) * 8.0).astype(np.float32)
    cloud = SplatCloud.concatenate([near, far])
    write_splat_ply(cloud, tmp_path / "scene.ply")
    write_obj(mesh, str(tmp_path / "mesh.obj"))
    return tmp_path, len(near), len(far)


def test_max_distance_keeps_far_splats_static(scene):
    folder, n_near, n_far = scene
    out = folder / "out.glb"
    summary = convert(str(folder / "scene.ply"), str(out),
                      ConvertOptions(mesh=str(folder / "mesh.obj"), max_distance=0.1))
    assert (summary.anchored, summary.static, summary.dropped) == (n_near, n_far, 0)
    asset = read_gltf(out)
    assert [len(p.splats) for p in asset.anchored] == [n_near]
    assert [len(p.splats) for p in asset.static] == [n_far]
    assert summary.max_distance == pytest.approx(0.1 * summary.distance["mesh_diagonal"])


@pytest.mark.parametrize("several", [False, True])
def test_static_splats_take_the_sh_degree_and_order_of_the_input(scene, several):
    """--sh-degree applies to the splats left static too, which keep the input's order, while
    the anchored ones are grouped by face (one mesh, or --mesh given twice)."""
    folder, n_near, n_far = scene
    out = folder / "out.glb"
    mesh = str(folder / "mesh.obj")
    options = (ConvertOptions(meshes=[mesh, mesh], max_distance=0.1, sh_degree=0) if several
               else ConvertOptions(mesh=mesh, max_distance=0.1, sh_degree=0))
    summary = convert(str(folder / "scene.ply"), str(out), options)
    assert summary.static == n_far
    asset = read_gltf(out)
    (static,) = asset.static
    assert static.splats.sh_degree == 0 and all(p.splats.sh_degree == 0 for p in asset.anchored)
    cloud = rotate_splats(read_splat_ply(folder / "scene.ply"), FRAMES["3dgs"].to_gltf)
    np.testing.assert_array_equal(static.splats.means, cloud.means[n_near:])
    np.testing.assert_array_equal(static.splats.sh[:, 0], cloud.sh[n_near:, 0])
    for prim in asset.anchored:
        face = prim.anchoring.anchors.face_index
        assert np.all(np.diff(face.astype(np.int64)) >= 0)


def test_drop_unanchored_and_absolute_distance(scene):
    folder, n_near, n_far = scene
    out = folder / "out.glb"
    summary = convert(str(folder / "scene.ply"), str(out),
                      ConvertOptions(mesh=str(folder / "mesh.obj"), max_distance=1.0,
                                     absolute_distance=True, drop_unanchored=True))
    assert (summary.anchored, summary.static, summary.dropped) == (n_near, 0, n_far)
    assert summary.max_distance == 1.0
    asset = read_gltf(out)
    assert len(asset.primitives) == 1 and asset.primitives[0].anchoring is not None


def test_json_summary_reports_counts(scene, capsys):
    folder, n_near, n_far = scene
    code = main([str(folder / "scene.ply"), str(folder / "o.glb"), "--mesh", str(folder / "mesh.obj"),
                 "--max-distance", "0.1", "--json"])
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["anchored"] == n_near and summary["static"] == n_far
    assert summary["source"] == "3dgs" and summary["profile"] == "local"
    for key in ("p50", "p95", "p99", "max"):
        assert key in summary["distance"]
    assert summary["seconds"] > 0


def test_drop_unanchored_needs_max_distance(scene, capsys):
    folder, *_ = scene
    assert main([str(folder / "scene.ply"), str(folder / "o.glb"), "--mesh", str(folder / "mesh.obj"),
                 "--drop-unanchored"]) == 2
    assert "--max-distance" in capsys.readouterr().err


def test_detect_source(tmp_path, scene):
    folder, *_ = scene
    assert detect_source(str(folder / "scene.ply"), str(folder / "mesh.obj"))[0] == "3dgs"
    assert detect_source(str(folder), None)[0] == "games"
    (folder / "model_params.json").write_text("{}")
    assert detect_source(str(folder / "scene.ply"), None)[0] == "games"
    glb = tmp_path / "x.glb"
    glb.write_bytes(b"")
    assert detect_source(str(glb), None)[0] == "khr"


def test_sources_are_registered_in_one_table():
    from gsverse_format.converters import SOURCES, get_source
    from gsverse_format.errors import UsageError

    assert list(SOURCES) == ["3dgs", "sugar", "trellis", "games", "khr", "splat", "ksplat", "spz",
                             "compressed-ply", "sog"]
    assert all(s.detect is not None for s in SOURCES.values())
    with pytest.raises(UsageError, match="auto, 3dgs, sugar"):
        get_source("colmap")


def test_each_faces_option_has_one_meaning(scene, capsys):
    folder, *_ = scene
    ply, out = str(folder / "scene.ply"), str(folder / "o.glb")
    assert main([ply, out, "--reconstruct-faces", "3"]) == 2
    assert "--reconstruct-faces must be at least 4" in capsys.readouterr().err
    assert main([ply, out, "--mesh", str(folder / "mesh.obj"), "--faces", "3"]) == 2
    assert "--faces must be at least 4" in capsys.readouterr().err


def test_frames_change_once_through_the_format_table(scene, tmp_path):
    from gsverse_format.io.registry import FORMATS, read_asset
    from gsverse_format.transform import PLY_TO_GLTF

    folder, *_ = scene
    assert FORMATS[".ply"].frame == "3dgs" and FORMATS[".glb"].frame == "gltf"
    as_is = read_asset(folder / "scene.ply", frame_change=False).primitives[0].splats
    turned = read_asset(folder / "scene.ply").primitives[0].splats
    assert np.array_equal(turned.means, (as_is.means.astype(np.float64) @ PLY_TO_GLTF.T)
                          .astype(np.float32))
