"""SuGaR and GaMeS / GS-Verse sources: exact anchors, frames, rest-pose reproduction, errors."""
from __future__ import annotations

import json
import shutil
import sys
import types
from typing import NamedTuple

import numpy as np
import pytest

from gsverse_format.converters import games, sugar
from gsverse_format.converters.base import SourceOptions
from gsverse_format.pipeline import load_source
from gsverse_format.errors import FormatError
from gsverse_format.io.ply import read_splat_ply, write_splat_ply
from gsverse_format.model import Anchoring
from gsverse_format.remapping.reference import remap
from gsverse_format.transform import PLY_TO_GLTF, rotate_splats

from helpers import max_rel_cov_error
from source_fixtures import (games_scene, sugar_scene, write_gsverse_folder, write_obj,
                             write_ply_mesh, write_sugar)

EPS32 = float(np.finfo(np.float32).eps)


def _diag(v):
    v = np.asarray(v, np.float64)
    return float(np.linalg.norm(v.max(0) - v.min(0)))


def _rest_errors(result, expected):
    """(max |Δμ| / mesh diagonal, max ‖ΔΣ‖/‖Σ‖) of the remap at rest against ``expected``."""
    r = remap(Anchoring(result.mesh, result.anchors))
    mean = np.max(np.linalg.norm(r.means - expected.means.astype(np.float64), axis=1))
    return mean / _diag(result.mesh.vertices), max_rel_cov_error(r.covariances, expected.covariances())


# --------------------------------------------------------------------------------------------
# SuGaR


@pytest.mark.parametrize("k", [1, 3, 4, 6])
def test_sugar_reproduces_splats_at_rest(tmp_path, k):
    scene = sugar_scene(k, seed=k)
    ply, obj = write_sugar(scene, tmp_path, decimals=None)   # exact float32 OBJ
    result = load_source("sugar", ply, obj, SourceOptions())
    expected = rotate_splats(read_splat_ply(ply), PLY_TO_GLTF)
    n, f = len(expected), len(scene.faces)
    assert result.anchors.profile == "local" and result.anchors.deformation == "affine"
    assert np.array_equal(result.anchors.face_index, np.arange(n) // k)
    slots = np.asarray(sugar.SLOT_BARYCENTRICS[k], np.float32)[:, 1:]
    assert np.array_equal(result.anchors.barycentrics, np.tile(slots, (f, 1)))
    assert np.allclose(result.mesh.vertices, scene.vertices @ PLY_TO_GLTF.T, atol=0)
    assert np.array_equal(result.splats.means, expected.means)
    assert np.array_equal(result.splats.sh, expected.sh)
    mean_rel, cov_rel = _rest_errors(result, expected)
    coord = float(np.abs(scene.vertices).max()) / _diag(scene.vertices)
    assert mean_rel <= 4 * EPS32 * coord          # float32 rounding of the PLY means
    assert cov_rel <= 1e-6
    assert np.max(np.abs(result.anchors.normal_offset)) <= 4 * EPS32 * np.abs(scene.vertices).max()
    assert result.check["k"] == k and result.check["max_cov_rel_error"] == pytest.approx(cov_rel)
    assert result.check["max_mean_error_rel"] <= 4 * EPS32 * coord


def test_sugar_obj_with_six_decimals_and_uv_seams(tmp_path):
    # SuGaR writes the refined OBJ with pytorch3d's "%f" and per-corner UVs (OBJ readers may
    # split vertices at the seams; only the face order matters), positions rounded to 1e-6.
    scene = sugar_scene(6, seed=11)
    ply, obj = write_sugar(scene, tmp_path, decimals=6, uv_per_corner=True)
    result = load_source("sugar", ply, obj, SourceOptions())
    assert result.mesh.face_count == len(scene.faces)
    expected = rotate_splats(read_splat_ply(ply), PLY_TO_GLTF)
    r = remap(Anchoring(result.mesh, result.anchors))
    assert np.max(np.linalg.norm(r.means - expected.means, axis=1)) <= 1.5e-6
    assert max_rel_cov_error(r.covariances, expected.covariances()) <= 1e-6
    assert result.check["ply_to_slot_max_error"] <= 1.5e-6


def test_sugar_without_frame_change_keeps_colmap_frame(tmp_path):
    scene = sugar_scene(3, seed=2)
    ply, obj = write_sugar(scene, tmp_path, decimals=None, uv_per_corner=False)
    result = load_source("sugar", ply, obj, SourceOptions(), frame_change=False)
    assert np.array_equal(result.mesh.vertices, scene.vertices)
    mean_rel, cov_rel = _rest_errors(result, read_splat_ply(ply))
    assert mean_rel < 1e-6 and cov_rel < 1e-6


def test_sugar_degenerate_face_is_rebound(tmp_path):
    base = sugar_scene(1, seed=3)
    v0, v1 = base.vertices[base.faces[0, 0]], base.vertices[base.faces[0, 1]]
    extra = np.stack([v0, (v0 + v1) / 2, v1]).astype(np.float32)     # a segment on face 0's edge
    vertices = np.concatenate([base.vertices, extra])
    faces = np.concatenate([base.faces, [[len(base.vertices) + i for i in range(3)]]])
    scene = sugar_scene(4, seed=3, vertices=vertices, faces=faces)
    ply, obj = write_sugar(scene, tmp_path, decimals=None, uv_per_corner=False)
    result = load_source("sugar", ply, obj, SourceOptions())
    last = len(faces) - 1
    assert result.check["splats_rebound_from_degenerate_faces"] == 4
    assert not np.any(result.anchors.face_index == last)
    mean_rel, cov_rel = _rest_errors(result, rotate_splats(read_splat_ply(ply), PLY_TO_GLTF))
    assert mean_rel < 1e-6 and cov_rel < 1e-6


def test_sugar_coarse_mesh_is_refused(tmp_path):
    scene = sugar_scene(6, seed=4)
    ply, _ = write_sugar(scene, tmp_path)
    rng = np.random.default_rng(0)
    coarse = scene.vertices + rng.normal(0, 2e-3, scene.vertices.shape).astype(np.float32)
    path = str(tmp_path / "sugarmesh_scene_level03_decim1000.ply")
    write_ply_mesh(path, coarse, scene.faces)
    with pytest.raises(FormatError) as info:
        load_source("sugar", ply, path, SourceOptions())
    message = str(info.value)
    assert message.startswith(path + ":") and "\n" not in message
    assert "coarse mesh" in message and "sugarfine_*.obj" in message and "--pt" in message


@pytest.mark.parametrize("named", [True, False])
def test_sugar_postprocessed_mesh_is_refused(tmp_path, named):
    scene = sugar_scene(6, seed=5)
    ply, _ = write_sugar(scene, tmp_path, ply_name=None if named else "refined.ply")
    obj = str(tmp_path / "sugarfine_scene_postprocessed.obj")
    write_obj(obj, scene.vertices, scene.faces[:-7])
    with pytest.raises(FormatError) as info:
        load_source("sugar", ply, obj, SourceOptions())
    message = str(info.value)
    f, n = len(scene.faces), len(scene.cloud)
    assert message.startswith(obj + ":")
    assert f"{f - 7} faces" in message and f"{n} splats" in message and f"6×{f}" in message
    assert "--postprocess_mesh" in message and "without post-processing" in message


def test_sugar_wrong_k_is_refused(tmp_path):
    scene = sugar_scene(4, seed=6)
    ply, obj = write_sugar(scene, tmp_path, ply_name="refined.ply", decimals=None)
    doubled = str(tmp_path / "doubled.obj")          # 2F faces: 4F splats = 2 per face
    write_obj(doubled, scene.vertices, np.concatenate([scene.faces, scene.faces]))
    with pytest.raises(FormatError, match=r"2 per face, but SuGaR places 1, 3, 4 or 6"):
        load_source("sugar", ply, doubled, SourceOptions())
    with pytest.raises(FormatError, match=r"k = 5 .*from --k.* 1, 3, 4 or 6"):
        load_source("sugar", ply, obj, SourceOptions(k=5))
    assert len(scene.cloud) % 6 and len(scene.cloud) % 3        # 4 × 320 splats
    with pytest.raises(FormatError, match=r"not a multiple of k = 6 \(from --k\)"):
        load_source("sugar", ply, obj, SourceOptions(k=6))
    named = str(tmp_path / "sugarfine_x_gaussperface3.ply")     # k from the file name
    shutil.copy(ply, named)
    with pytest.raises(FormatError, match=r"not a multiple of k = 3 \(from the file name\)"):
        load_source("sugar", named, obj, SourceOptions())
    three = sugar_scene(3, seed=6)
    ply3, obj3 = write_sugar(three, tmp_path / "k3", decimals=None)
    with pytest.raises(FormatError, match=r"320 faces but the PLY has 960 splats = 6×160 faces: "
                                          r"this mesh belongs to another run"):
        load_source("sugar", ply3, obj3, SourceOptions(k=6))


def test_sugar_layout_detection(tmp_path):
    from gsverse_format.io.ply import describe_ply

    scene = sugar_scene(3, seed=9)
    ply, obj = write_sugar(scene, tmp_path / "named", decimals=None)
    assert sugar.matches_layout(ply, obj, describe_ply(ply))            # by the file names
    plain_ply, plain_obj = str(tmp_path / "splats.ply"), str(tmp_path / "mesh.obj")
    shutil.copy(ply, plain_ply)
    shutil.copy(obj, plain_obj)
    assert sugar.matches_layout(plain_ply, plain_obj, describe_ply(plain_ply))  # by the geometry
    write_obj(plain_obj, scene.vertices + np.float32(0.01), scene.faces)
    assert not sugar.matches_layout(plain_ply, plain_obj, describe_ply(plain_ply))


def test_sugar_needs_a_mesh(tmp_path):
    ply, _ = write_sugar(sugar_scene(1), tmp_path)
    with pytest.raises(FormatError, match=r"--mesh .*--pt"):
        load_source("sugar", ply, None, SourceOptions())


def test_sugar_pt_needs_torch(tmp_path, monkeypatch):
    ply, _ = write_sugar(sugar_scene(1), tmp_path)
    pt = tmp_path / "15000.pt"
    pt.write_bytes(b"not used")
    monkeypatch.setitem(sys.modules, "torch", None)
    with pytest.raises(FormatError, match=r"reading \.pt needs PyTorch: pip install torch"):
        load_source("sugar", ply, None, SourceOptions(pt_path=str(pt)))


def test_sugar_refined_checkpoint(tmp_path):
    torch = pytest.importorskip("torch")
    scene = sugar_scene(3, seed=8)
    ply, _ = write_sugar(scene, tmp_path)
    pt = str(tmp_path / "15000.pt")
    torch.save({"iteration": 15000, "train_losses": [0.5, 0.25],
                "state_dict": {"_points": torch.nn.Parameter(torch.from_numpy(scene.vertices)),
                               "_surface_mesh_faces": torch.from_numpy(scene.faces),
                               "surface_mesh_thickness": torch.tensor(1e-6)}}, pt)
    result = load_source("sugar", ply, None, SourceOptions(pt_path=pt))
    mean_rel, cov_rel = _rest_errors(result, rotate_splats(read_splat_ply(ply), PLY_TO_GLTF))
    assert mean_rel < 1e-7 and cov_rel < 1e-6


# --------------------------------------------------------------------------------------------
# GaMeS / GS-Verse

#: Covariance bound of the games rest pose against GaMeS's own PLY, relative (measured ~1e-6:
#: float32 arithmetic and GaMeS's ε-regularized normalization, on edges of ~0.2 units).
GAMES_COV_BOUND = 1e-5


@pytest.mark.parametrize("frame", ["blender", "colmap"])
def test_gsverse_folder_reproduces_ply(tmp_path, frame):
    scene = games_scene(frame, k=5, seed=1 if frame == "blender" else 2)
    folder = write_gsverse_folder(scene, tmp_path / "export")
    result = load_source("games", str(folder), None, SourceOptions())
    to_gltf = games.Z_UP_TO_GLTF if frame == "blender" else PLY_TO_GLTF
    expected = rotate_splats(read_splat_ply(folder / "point_cloud.ply"), to_gltf)
    assert result.check["frame"] == frame and result.check["k"] == 5
    if frame == "blender":   # GaMeS's transform then Z-up -> glTF gives back the OBJ as written
        assert np.array_equal(result.mesh.vertices, scene.obj_vertices)
    else:
        assert np.allclose(result.mesh.vertices, scene.obj_vertices @ PLY_TO_GLTF.T, atol=0)
    a = result.anchors
    assert a.profile == "games"
    assert np.array_equal(a.face_index, np.arange(len(expected)) // 5)
    assert np.array_equal(a.rho, scene.rho)
    alpha = np.maximum(scene.alpha_raw.astype(np.float64), 0) + 1e-8
    alpha = (alpha / alpha.sum(-1, keepdims=True)).reshape(-1, 3)
    assert np.allclose(a.barycentrics, alpha[:, 1:], atol=EPS32)
    # rest pose = remap at the rest mesh; opacity and SH from the PLY (SH rotated to glTF)
    r = remap(Anchoring(result.mesh, a))
    assert np.allclose(result.splats.means, r.means, atol=1e-6)
    assert np.array_equal(result.splats.opacities, expected.opacities)
    assert np.allclose(result.splats.sh, expected.sh, atol=1e-6)
    mean_err = np.max(np.linalg.norm(r.means - expected.means, axis=1))
    cov_err = max_rel_cov_error(r.covariances, expected.covariances())
    assert mean_err / _diag(result.mesh.vertices) < 1e-6
    assert cov_err < GAMES_COV_BOUND
    assert result.check["max_cov_rel_error"] == pytest.approx(cov_err, rel=1e-3)
    assert result.check["max_mean_error"] == pytest.approx(mean_err, rel=1e-3, abs=1e-12)
    other = "colmap" if frame == "blender" else "blender"
    assert result.check["frame_mean_errors"][other] > 1e-2


def test_games_output_layout_highest_iteration(tmp_path):
    scene = games_scene("blender", k=3, seed=4)
    root = tmp_path / "output"
    early = root / "point_cloud" / "iteration_7000"
    late = root / "point_cloud" / "iteration_30000"
    early.mkdir(parents=True)
    write_splat_ply(scene.cloud.subset(np.arange(10)), early / "point_cloud.ply")
    write_gsverse_folder(scene, late, mesh=False)
    mesh = tmp_path / "dataset" / "mesh.obj"
    mesh.parent.mkdir()
    write_obj(mesh, scene.obj_vertices, scene.faces)
    result = load_source("games", str(root), str(mesh), SourceOptions())
    assert len(result.splats) == len(scene.cloud)
    assert any("iteration_30000" in note for note in result.notes)
    # the point_cloud.ply path itself, model_params.json beside it
    again = load_source("games", str(late / "point_cloud.ply"), str(mesh), SourceOptions())
    assert np.array_equal(again.splats.means, result.splats.means)


def test_games_json_variants(tmp_path):
    scene = games_scene("colmap", k=4, seed=3)
    folder = write_gsverse_folder(scene, tmp_path)
    reference = load_source("games", str(folder), None, SourceOptions())
    params = folder / "model_params.json"
    # one-element list around the arrays (a multi-mesh run with one mesh)
    params.write_text(json.dumps({"_alpha": [scene.alpha_raw.tolist()],
                                  "_scale": [scene.rho[:, None].tolist()]}))
    wrapped = load_source("games", str(folder), None, SourceOptions())
    assert np.array_equal(wrapped.splats.means, reference.splats.means)
    # flattened α (N, 3): k from the face count, or --k
    params.write_text(json.dumps({"_alpha": scene.alpha_raw.reshape(-1, 3).tolist(),
                                  "_scale": scene.rho[:, None].tolist()}))
    flat = load_source("games", str(folder), None, SourceOptions(k=4))
    assert np.array_equal(flat.anchors.face_index, reference.anchors.face_index)
    write_gsverse_folder(scene, folder, mesh=False)      # back to (F, k, 3)
    with pytest.raises(FormatError, match=r"4 splats per face, not --k 2"):
        load_source("games", str(folder), None, SourceOptions(k=2))
    params.write_text(json.dumps({"alpha": []}))
    with pytest.raises(FormatError, match=r"needs the keys _alpha and _scale"):
        load_source("games", str(folder), None, SourceOptions())


def test_games_without_frame_change_stays_in_training_frame(tmp_path):
    scene = games_scene("blender", k=2, seed=5)
    folder = write_gsverse_folder(scene, tmp_path)
    result = load_source("games", str(folder), None, SourceOptions(), frame_change=False)
    assert np.array_equal(result.mesh.vertices, scene.train_vertices)
    assert np.max(np.abs(result.splats.means - scene.cloud.means)) < 1e-6


def test_games_missing_model_params(tmp_path):
    scene = games_scene("colmap", k=2)
    folder = write_gsverse_folder(scene, tmp_path, params=False)
    with pytest.raises(FormatError) as info:
        load_source("games", str(folder), None, SourceOptions())
    message = str(info.value)
    assert message.startswith(str(folder / "point_cloud.ply") + ":")
    assert "model_params.json" in message and "import_params.py" in message and "--pt" in message


def test_games_missing_mesh(tmp_path):
    folder = write_gsverse_folder(games_scene("colmap", k=2), tmp_path, mesh=False)
    with pytest.raises(FormatError, match=r"no mesh\.obj .*--mesh"):
        load_source("games", str(folder), None, SourceOptions())


def test_games_missing_point_cloud(tmp_path):
    with pytest.raises(FormatError, match=r"point_cloud/iteration_\*"):
        load_source("games", str(tmp_path), None, SourceOptions())


def test_games_wrong_mesh(tmp_path):
    scene = games_scene("colmap", k=2, seed=6)
    folder = write_gsverse_folder(scene, tmp_path)
    moved = scene.obj_vertices + np.float32(0.01)
    write_obj(folder / "mesh.obj", moved, scene.faces)
    with pytest.raises(FormatError, match=r"both frames .*--vertices_lr"):
        load_source("games", str(folder), None, SourceOptions())
    write_obj(folder / "mesh.obj", scene.obj_vertices, scene.faces[:-1])
    with pytest.raises(FormatError, match=r"describe \d+ faces but the mesh has"):
        load_source("games", str(folder), None, SourceOptions())


def test_games_params_of_another_run(tmp_path):
    scene = games_scene("colmap", k=2, seed=7)
    folder = write_gsverse_folder(scene, tmp_path)
    write_splat_ply(scene.cloud.subset(np.arange(len(scene.cloud) - 2)), folder / "point_cloud.ply")
    with pytest.raises(FormatError, match=r"different runs or iterations"):
        load_source("games", str(folder), None, SourceOptions())


def test_games_pt_needs_torch(tmp_path, monkeypatch):
    scene = games_scene("colmap", k=2)
    folder = write_gsverse_folder(scene, tmp_path, params=False)
    (folder / "model_params.pt").write_bytes(b"not used")
    monkeypatch.setitem(sys.modules, "torch", None)
    with pytest.raises(FormatError, match=r"reading \.pt needs PyTorch: pip install torch"):
        load_source("games", str(folder), None, SourceOptions())


def _fake_training_module():
    """A stand-in for the training code: a module the loader cannot import."""
    module = types.ModuleType("games_training_stub")

    def transform_vertices_function(v):
        return v

    fake = NamedTuple("MeshPointCloud", [("alpha", object), ("transform_vertices_function", object)])
    fake.__module__ = module.__name__
    transform_vertices_function.__module__ = module.__name__
    transform_vertices_function.__qualname__ = "transform_vertices_function"
    module.MeshPointCloud = fake
    module.transform_vertices_function = transform_vertices_function
    return module


def test_games_checkpoint_single_mesh(tmp_path, monkeypatch):
    torch = pytest.importorskip("torch")
    scene = games_scene("blender", k=3, seed=8)
    folder = write_gsverse_folder(scene, tmp_path, params=False, mesh=False)
    module = _fake_training_module()
    monkeypatch.setitem(sys.modules, module.__name__, module)
    vertices = torch.nn.Parameter(torch.from_numpy(scene.train_vertices))
    faces = torch.from_numpy(scene.faces)
    torch.save({"_alpha": torch.nn.Parameter(torch.from_numpy(scene.alpha_raw)),
                "_scale": torch.nn.Parameter(torch.from_numpy(scene.rho[:, None])),
                "point_cloud": module.MeshPointCloud(torch.zeros(1), module.transform_vertices_function),
                "triangles": vertices.detach()[faces], "vertices": vertices, "faces": faces},
               folder / "model_params.pt")
    monkeypatch.delitem(sys.modules, module.__name__)   # the loader must not need it
    result = load_source("games", str(folder), None, SourceOptions())
    assert result.check["frame"] == "blender"
    assert np.array_equal(result.mesh.vertices, scene.obj_vertices)
    expected = rotate_splats(read_splat_ply(folder / "point_cloud.ply"), games.Z_UP_TO_GLTF)
    assert result.check["max_cov_rel_error"] < GAMES_COV_BOUND
    assert np.max(np.linalg.norm(result.splats.means - expected.means, axis=1)) < 1e-6


def test_games_checkpoint_multi_mesh(tmp_path):
    torch = pytest.importorskip("torch")
    scene = games_scene("colmap", k=2, seed=9)
    folder = write_gsverse_folder(scene, tmp_path, params=False, mesh=False)
    split = len(scene.faces) // 3
    v = torch.from_numpy(scene.train_vertices)
    parts = [slice(0, split), slice(split, None)]
    rho = scene.rho.reshape(-1, 2, 1)                     # (faces, k, 1) -> per-mesh (N_m, 1)
    torch.save({"_alpha": [torch.nn.Parameter(torch.from_numpy(scene.alpha_raw[p])) for p in parts],
                "_scale": [torch.nn.Parameter(torch.from_numpy(rho[p].reshape(-1, 1))) for p in parts],
                "point_cloud": [None, None], "vertices": [torch.nn.Parameter(v.clone()) for _ in parts],
                "faces": [torch.from_numpy(scene.faces[p]) for p in parts]},
               folder / "model_params.pt")
    result = load_source("games", str(folder), None, SourceOptions())
    assert result.check["frame"] == "colmap" and result.mesh.face_count == len(scene.faces)
    assert len(result.mesh.vertices) == 2 * len(scene.obj_vertices)
    expected = rotate_splats(read_splat_ply(folder / "point_cloud.ply"), PLY_TO_GLTF)
    assert result.check["max_cov_rel_error"] < GAMES_COV_BOUND
    assert np.max(np.linalg.norm(result.splats.means - expected.means, axis=1)) < 1e-6
