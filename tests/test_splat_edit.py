"""Editing splats while converting (gsverse_format.edit, gsverse-convert's editing flags):
the math against independent references (scipy's rotations, covariances s² R Σ Rᵀ, the SH
colour function at rotated directions), then each flag on generated PLYs, with and without
--mesh, in batches and in the --json summary."""
from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from gsverse_format import read
from gsverse_format.cli.convert import main
from gsverse_format.edit import (Similarity, SplatEdit, euler_matrix, nonfinite_rows,
                                 transform_mesh, transform_splats)
from gsverse_format.errors import UsageError
from gsverse_format.io.ply import write_splat_ply
from gsverse_format.model import TriangleMesh
from gsverse_format.pipeline import ConvertOptions, load_source
from gsverse_format.sh import sh_basis
from gsverse_format.transform import PLY_TO_GLTF

from gsverse_format.converters.base import SourceOptions
from gsverse_format.validators.validate import validate_file

from helpers import bumpy_sphere, random_splats, surface_splats
from source_fixtures import games_scene, sugar_scene, write_gsverse_folder, write_sugar
from splat_writers import write_spz_v2

#: float32 storage of values computed in float64: a few float32 steps of the largest
#: magnitude involved (means within ~10 units here).
F32 = 1e-5


def _covariances(q_xyzw: np.ndarray, scales: np.ndarray) -> np.ndarray:
    r = Rotation.from_quat(np.asarray(q_xyzw, np.float64)).as_matrix()
    rs = r * np.asarray(scales, np.float64)[:, None, :]
    return rs @ np.swapaxes(rs, 1, 2)


# --- the math ------------------------------------------------------------------------------

@pytest.mark.parametrize("angles", [(10, 20, 30), (90, 0, 0), (-45, 170, 5), (0, 0, 90)])
def test_euler_matrix_is_playcanvas_and_extrinsic_xyz(angles):
    expected = Rotation.from_euler("xyz", angles, degrees=True).as_matrix()  # fixed axes
    assert np.allclose(euler_matrix(angles), expected, atol=1e-15)
    # PlayCanvas Quat.setFromEulerAngles, written out
    hx, hy, hz = (np.radians(a) / 2 for a in angles)
    sx, cx, sy, cy, sz, cz = np.sin(hx), np.cos(hx), np.sin(hy), np.cos(hy), np.sin(hz), np.cos(hz)
    q = [sx * cy * cz - cx * sy * sz, cx * sy * cz + sx * cy * sz,
         cx * cy * sz - sx * sy * cz, cx * cy * cz + sx * sy * sz]
    assert np.allclose(euler_matrix(angles), Rotation.from_quat(q).as_matrix(), atol=1e-15)


def test_quarter_turns_are_exact():
    assert np.array_equal(euler_matrix((90, 0, 0)), [[1, 0, 0], [0, 0, -1], [0, 1, 0]])


def test_transform_splats_matches_the_similarity_of_each_gaussian():
    cloud = random_splats(300, seed=4, sh_degree=3)
    edit = Similarity(translate=(1.5, -2.0, 0.25), rotate=(33.0, -71.0, 12.0), scale=2.5)
    out = transform_splats(cloud, edit)
    r = Rotation.from_euler("xyz", edit.rotate, degrees=True).as_matrix()
    means = 2.5 * cloud.means.astype(np.float64) @ r.T + edit.translate
    assert np.allclose(out.means, means, rtol=0, atol=F32)
    expected = 2.5 ** 2 * r @ _covariances(cloud.rotations, cloud.scales) @ r.T
    got = _covariances(out.rotations, out.scales)
    # float32 quaternions and scales: a few float32 steps (6e-8) relative to the largest entry
    assert np.max(np.abs(got - expected) / np.abs(expected).max(axis=(1, 2))[:, None, None]) \
        < 1e-5
    assert np.array_equal(out.opacities, cloud.opacities)
    # colour seen along d after the edit = colour seen along Rᵀ d before it
    dirs = Rotation.random(50, random_state=1).apply([0.0, 0.0, 1.0])
    before = np.einsum("dk,nkc->ndc", sh_basis(dirs @ r, 3), cloud.sh.astype(np.float64))
    after = np.einsum("dk,nkc->ndc", sh_basis(dirs, 3), out.sh.astype(np.float64))
    assert np.allclose(after, before, atol=1e-5)   # float32 coefficients (|sh| < 2), 16 terms


def test_transform_mesh_and_identity():
    mesh = bumpy_sphere(1)
    edit = Similarity((0.0, 3.0, 0.0), (0.0, 90.0, 0.0), 100.0)
    out = transform_mesh(mesh, edit)
    r = Rotation.from_euler("y", 90, degrees=True).as_matrix()
    assert np.allclose(out.vertices, 100 * mesh.vertices.astype(np.float64) @ r.T + [0, 3, 0],
                       atol=1e-3)
    assert np.array_equal(out.faces, mesh.faces)
    cloud = random_splats(5)
    assert transform_splats(cloud, Similarity()) is cloud
    assert transform_mesh(mesh, Similarity()) is mesh


@pytest.mark.parametrize("field, value, needle", [
    ("translate", "1,2", "--translate takes 3"),
    ("rotate", "1,x,3", "--rotate: 'x' is not a number"),
    ("rotate", "nan,0,0", "--rotate: 'nan' is not a finite number"),
    ("scale", "0", "--scale must be > 0"),
    ("scale", "-2", "--scale must be > 0"),
    ("mesh_scale", "inf", "--mesh-scale: 'inf' is not a finite"),
    ("crop_box", "0,0,0,1,-1,1", "--crop-box is XMIN"),
    ("crop_box", "0,0,0,1,1", "--crop-box takes 6"),
    ("crop_sphere", "0,0,0,-1", "--crop-sphere radius must be >= 0"),
    ("min_opacity", "1.5", "--min-opacity must be in [0, 1]"),
])
def test_bad_edit_values_name_the_flag(field, value, needle):
    with pytest.raises(UsageError, match=needle.replace("[", r"\[").replace("]", r"\]")):
        SplatEdit.from_options(ConvertOptions(**{field: value}))


# --- the command line ----------------------------------------------------------------------

def _run(capsys, *args: str) -> tuple[int, str, str]:
    try:
        code = main([str(a) for a in args])
    except SystemExit as exc:   # the parser's own usage errors
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def _poison(path, rows, prop: str, value: float) -> None:
    """Overwrite property ``prop`` of ``rows`` in a binary little-endian float PLY."""
    data = bytearray(path.read_bytes())
    end = data.index(b"end_header\n") + len(b"end_header\n")
    props = [line.split()[-1] for line in data[:end].decode().splitlines()
             if line.startswith("property")]
    for row in rows:
        at = end + 4 * (row * len(props) + props.index(prop))
        data[at:at + 4] = np.array([value], "<f4").tobytes()
    path.write_bytes(bytes(data))


@pytest.fixture()
def ply(tmp_path):
    cloud = random_splats(400, seed=7, sh_degree=1, spread=2.0)
    path = tmp_path / "splats.ply"
    write_splat_ply(cloud, path)
    return path, cloud


def _to_gltf(points: np.ndarray) -> np.ndarray:
    return np.asarray(points, np.float64) @ PLY_TO_GLTF.T


def test_plain_move_happens_in_the_input_frame(ply, tmp_path, capsys):
    path, cloud = ply
    out = tmp_path / "moved.glb"
    code, text, _ = _run(capsys, path, out, "--plain", "--scale", "2", "--rotate", "0,0,90",
                         "--translate=-1,0,5")
    assert code == 0 and "edits      dropped 0 non-finite" in text
    (prim,) = read(out).primitives
    r = Rotation.from_euler("z", 90, degrees=True).as_matrix()
    expected = _to_gltf(2 * cloud.means.astype(np.float64) @ r.T + [-1, 0, 5])
    assert np.allclose(prim.splats.means, expected, atol=F32)
    assert np.allclose(prim.splats.scales, 2 * cloud.scales, rtol=1e-6)


def test_drop_nonfinite_counts_and_refusal_names_the_flag(ply, tmp_path, capsys):
    path, cloud = ply
    _poison(path, [3, 5], "y", np.nan)
    _poison(path, [5, 8], "f_rest_2", np.inf)
    _poison(path, [11], "opacity", -np.inf)   # a finite opacity of 0: kept
    for prop in ("rot_0", "rot_1", "rot_2", "rot_3"):
        _poison(path, [20], prop, 0.0)
    code, _, err = _run(capsys, path, tmp_path / "refused.glb", "--plain")
    assert code == 1 and "--drop-nonfinite" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "refused.glb").exists()
    out = tmp_path / "clean.glb"
    code, text, _ = _run(capsys, path, out, "--plain", "--drop-nonfinite", "--json")
    summary = json.loads(text)
    assert code == 0 and summary["edits"] == {"nonfinite": 4, "cropped": 0, "below_opacity": 0}
    assert summary["splats"] == len(cloud) - 4
    kept = np.setdiff1d(np.arange(len(cloud)), [3, 5, 8, 20])
    (prim,) = read(out).primitives
    assert np.allclose(prim.splats.means, _to_gltf(cloud.means[kept]), atol=0)


def test_drop_nonfinite_with_a_mesh(tmp_path, capsys):
    mesh = bumpy_sphere(2)
    cloud = surface_splats(mesh, 300, seed=3)
    path, mesh_path = tmp_path / "s.ply", tmp_path / "m.obj"
    write_splat_ply(cloud, path)
    trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).export(mesh_path)
    _poison(path, [0, 299], "scale_1", np.nan)
    code, _, err = _run(capsys, path, tmp_path / "x.glb", "--mesh", mesh_path)
    assert code == 1 and "--drop-nonfinite" in err
    code, text, _ = _run(capsys, path, tmp_path / "a.glb", "--mesh", mesh_path,
                         "--drop-nonfinite", "--json")
    summary = json.loads(text)
    assert code == 0 and summary["edits"]["nonfinite"] == 2 and summary["anchored"] == 298


def test_crop_and_opacity_counts(ply, tmp_path, capsys):
    path, cloud = ply
    m = cloud.means.astype(np.float64) + [0.5, 0, 0]    # after --translate, in the PLY frame
    in_box = np.all((m >= [-1, -1, -1]) & (m <= [1.5, 1, 1]), axis=1)
    in_sphere = np.linalg.norm(m - [0.2, 0, 0], axis=1) <= 1.4
    inside = in_box & in_sphere
    low = inside & (cloud.opacities < 0.4)
    out = tmp_path / "crop.glb"
    code, text, _ = _run(capsys, path, out, "--plain", "--translate", "0.5,0,0", "--json",
                         "--crop-box=-1,-1,-1,1.5,1,1", "--crop-sphere", "0.2,0,0,1.4",
                         "--min-opacity", "0.4")
    summary = json.loads(text)
    assert code == 0
    assert summary["edits"] == {"nonfinite": 0, "cropped": int((~inside).sum()),
                                "below_opacity": int(low.sum())}
    (prim,) = read(out).primitives
    assert len(prim.splats) == int((inside & ~low).sum()) and prim.splats.opacities.min() >= 0.4
    assert np.allclose(prim.splats.means, _to_gltf(m[inside & ~low]), atol=F32)


def test_empty_result_is_an_error_and_writes_nothing(ply, tmp_path, capsys):
    path, _ = ply
    out = tmp_path / "none.glb"
    code, _, err = _run(capsys, path, out, "--plain", "--crop-sphere", "50,50,50,1")
    assert code == 1 and "no splats left after the edits" in err and "400 outside" in err
    assert not out.exists()


@pytest.fixture()
def small_mesh(tmp_path):
    """Splats on a mesh, the mesh written 100 times larger (centimetres beside metres)."""
    mesh = bumpy_sphere(2)
    cloud = surface_splats(mesh, 500, seed=5, offset=0.005)
    path, mesh_path = tmp_path / "s.ply", tmp_path / "cm.obj"
    write_splat_ply(cloud, path)
    trimesh.Trimesh(mesh.vertices * 100, mesh.faces, process=False).export(mesh_path)
    return path, mesh_path, mesh, cloud


def test_mesh_scale_removes_the_fit_warning(small_mesh, tmp_path, capsys):
    path, mesh_path, mesh, _ = small_mesh
    code, text, err = _run(capsys, path, tmp_path / "bad.glb", "--mesh", mesh_path, "--json")
    assert code == 0 and "warning:" in err and "by 100" in err
    assert [f["ok"] for f in json.loads(text)["fit"]] == [False]
    out = tmp_path / "good.glb"
    code, text, err = _run(capsys, path, out, "--mesh", mesh_path, "--mesh-scale", "0.01",
                           "--json")
    assert code == 0 and "warning" not in err
    assert [f["ok"] for f in json.loads(text)["fit"]] == [True]
    (prim,) = read(out).anchored
    assert np.allclose(prim.anchoring.mesh.vertices, _to_gltf(mesh.vertices), atol=F32)


@pytest.mark.parametrize("frame", ["input", "output"])
def test_moving_splats_and_mesh_together_with_keep_order(small_mesh, tmp_path, capsys, frame):
    path, mesh_path, mesh, cloud = small_mesh
    out = tmp_path / "both.glb"
    move = ("--rotate", "20,-30,40", "--translate", "1,2,3")
    code, text, err = _run(capsys, path, out, "--mesh", mesh_path, "--mesh-scale", "0.01",
                           "--keep-order", "-q", "--edit-frame", frame, *move,
                           *(f"--mesh-{a[2:]}" if a.startswith("--") else a for a in move))
    assert code == 0 and err == ""
    r = Rotation.from_euler("xyz", (20, -30, 40), degrees=True).as_matrix()

    def moved(points):
        points = np.asarray(points, np.float64)
        return _to_gltf(points @ r.T + [1, 2, 3]) if frame == "input" \
            else _to_gltf(points) @ r.T + [1, 2, 3]

    (prim,) = read(out).anchored
    assert np.allclose(prim.anchoring.mesh.vertices, moved(mesh.vertices), atol=F32)
    # the stored rest pose is remapped from float32 anchors: 1e-4 of a mesh of diagonal ~4
    assert np.allclose(prim.splats.means, moved(cloud.means), atol=1e-4)


@pytest.mark.parametrize("frame", ["input", "output"])
def test_mesh_edits_move_every_mesh_of_a_scene(tmp_path, capsys, frame):
    a, b = bumpy_sphere(1), bumpy_sphere(1, seed=2)
    b = TriangleMesh(b.vertices + np.float32([4, 0, 0]), b.faces)
    paths = []
    for name, m in (("a", a), ("b", b)):
        paths.append(tmp_path / f"{name}.obj")
        trimesh.Trimesh(m.vertices / 10, m.faces, process=False).export(paths[-1])
    cloud = random_splats(200, seed=1, spread=3.0)
    write_splat_ply(cloud, tmp_path / "s.ply")
    out = tmp_path / "scene.glb"
    code, _, _ = _run(capsys, tmp_path / "s.ply", out, "--mesh", paths[0], "--mesh", paths[1],
                      "--mesh-scale", "10", "--mesh-translate", "0.5,1,0", "--edit-frame", frame,
                      "-q")
    assert code == 0
    meshes = [p.anchoring.mesh for p in read(out).anchored]
    for got, want in zip(meshes, (a, b)):
        moved = _to_gltf(want.vertices.astype(np.float64) + [0.5, 1, 0]) if frame == "input" \
            else _to_gltf(want.vertices) + [0.5, 1, 0]
        assert np.allclose(got.vertices, moved, atol=F32)


@pytest.mark.parametrize("args, needle", [
    (("--translate", "1,2"), "--translate"),
    (("--rotate", "a,b,c"), "--rotate"),
    (("--scale", "0"), "--scale must be > 0"),
    (("--mesh-scale", "-1", "--mesh", "missing.obj"), "--mesh-scale must be > 0"),
    (("--crop-box", "1,1,1,0,0,0"), "--crop-box"),
    (("--crop-sphere", "0,0,0,-2"), "--crop-sphere radius"),
    (("--crop-sphere", "0,0,nan,2"), "--crop-sphere"),
    (("--min-opacity", "2"), "--min-opacity"),
    (("--mesh-translate", "1,2,3"), "give one"),
])
def test_usage_errors_exit_2_before_reading(tmp_path, capsys, args, needle):
    # the input does not exist: a usage error is found before any file is looked at
    code, out, err = _run(capsys, tmp_path / "missing.ply", tmp_path / "o.glb", *args)
    assert code == 2 and needle in err and len(err.strip().splitlines()) == 1
    assert "Traceback" not in err and not (tmp_path / "o.glb").exists()


def test_anchored_input_is_not_moved_without_plain(tmp_path, capsys):
    mesh = bumpy_sphere(1)
    write_splat_ply(surface_splats(mesh, 100, seed=2), tmp_path / "s.ply")
    trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).export(tmp_path / "m.obj")
    anchored = tmp_path / "anchored.glb"
    assert _run(capsys, tmp_path / "s.ply", anchored, "--mesh", tmp_path / "m.obj", "-q")[0] == 0
    code, _, err = _run(capsys, anchored, tmp_path / "moved.glb", "--translate", "1,0,0")
    assert code == 2 and "--plain" in err
    code, text, _ = _run(capsys, anchored, tmp_path / "moved.glb", "--translate", "1,0,0",
                         "--plain", "--json")
    assert code == 0 and json.loads(text)["anchored"] == 0
    # filters keep the anchoring, the anchors following the splats kept
    code, text, _ = _run(capsys, anchored, tmp_path / "some.glb", "--min-opacity", "0.5",
                         "--json")
    summary = json.loads(text)
    kept = read(tmp_path / "some.glb").anchored[0]
    assert code == 0 and summary["anchored"] == len(kept.splats) < 100
    assert summary["edits"]["below_opacity"] == 100 - len(kept.splats)
    assert kept.splats.opacities.min() >= 0.5


def test_batch_manifest_keys(ply, tmp_path, capsys):
    path, cloud = ply
    manifest = tmp_path / "assets.json"
    manifest.write_text(json.dumps([
        {"input": path.name, "output": "a.glb", "plain": True, "translate": [1, 0, 0],
         "crop-sphere": "1,0,0,1", "min_opacity": 0.25},
        {"input": path.name, "output": "b.glb", "plain": True, "scale": 3, "rotate": "0,90,0"},
    ]))
    code, text, _ = _run(capsys, manifest, "--output-dir", tmp_path / "out", "--json")
    report = json.loads(text)
    assert code == 0 and report["ok"] == 2, report
    inside = np.linalg.norm(cloud.means.astype(np.float64), axis=1) <= 1
    a, b = (asset["summary"] for asset in report["assets"])
    assert a["edits"] == {"nonfinite": 0, "cropped": int((~inside).sum()),
                          "below_opacity": int((inside & (cloud.opacities < 0.25)).sum())}
    assert b["splats"] == len(cloud) and b["edits"]["cropped"] == 0
    (prim,) = read(tmp_path / "out" / "b.glb").primitives
    assert np.allclose(prim.splats.scales, 3 * cloud.scales, rtol=1e-6)


def test_batch_manifest_bad_edit_is_a_usage_error(ply, tmp_path, capsys):
    path, _ = ply
    manifest = tmp_path / "assets.csv"
    manifest.write_text(f'input,scale\n{path.name},"-1"\n')
    code, _, err = _run(capsys, manifest, "--output-dir", tmp_path / "out")
    assert code == 2 and "assets.csv:2" in err and "--scale must be > 0" in err


def test_summary_without_edits_has_none(ply, tmp_path, capsys):
    path, _ = ply
    code, text, _ = _run(capsys, path, tmp_path / "p.glb", "--plain", "--json")
    assert code == 0 and json.loads(text)["edits"] == {}
    code, text, _ = _run(capsys, path, tmp_path / "q.glb", "--plain")
    assert "\n  edits " not in text


# --- every source ---------------------------------------------------------------------------

def test_sugar_filters_keep_the_exact_binding_and_moves_replace_it(tmp_path, capsys):
    scene = sugar_scene(3, seed=2)
    ply, obj = write_sugar(scene, tmp_path, decimals=None)
    low = int((scene.cloud.opacities < 0.5).sum())
    code, text, _ = _run(capsys, ply, tmp_path / "f.glb", "--mesh", obj, "--min-opacity", "0.5",
                         "--json")
    summary = json.loads(text)
    assert code == 0 and summary["source"] == "sugar" and 0 < low < len(scene.cloud)
    assert summary["edits"]["below_opacity"] == low == len(scene.cloud) - summary["anchored"]
    assert not any("replaced" in n for n in summary["notes"])
    assert validate_file(tmp_path / "f.glb").findings == []
    code, text, _ = _run(capsys, ply, tmp_path / "m.glb", "--mesh", obj, "--scale", "2",
                         "--mesh-scale", "2", "--json", "--strict")
    summary = json.loads(text)
    assert code == 0 and summary["anchored"] == len(scene.cloud)
    assert any("exact binding was replaced" in n for n in summary["notes"])


def test_games_crop_keeps_its_anchors(tmp_path, capsys):
    scene = games_scene("colmap", k=3, seed=1)
    folder = write_gsverse_folder(scene, tmp_path / "games")
    reference = load_source("games", str(folder), None, SourceOptions(), frame_change=False)
    m = reference.splats.means.astype(np.float64)
    centre = np.median(m, axis=0)
    radius = float(np.median(np.linalg.norm(m - centre, axis=1)))
    inside = np.linalg.norm(m - centre, axis=1) <= radius
    sphere = ",".join(f"{v:.9g}" for v in (*centre, radius))
    out = tmp_path / "g.glb"
    code, text, _ = _run(capsys, folder, out, f"--crop-sphere={sphere}", "--json")
    summary = json.loads(text)
    assert code == 0 and summary["profile"] == "games"
    assert summary["anchored"] == int(inside.sum()) == len(m) - summary["edits"]["cropped"]
    assert validate_file(out).findings == []


def test_khr_glb_and_web_format_inputs(ply, tmp_path, capsys):
    path, cloud = ply
    glb = tmp_path / "plain.glb"
    assert _run(capsys, path, glb, "--plain", "-q")[0] == 0   # in the glTF frame
    mesh = bumpy_sphere(1)
    trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).export(tmp_path / "m.obj")
    out = tmp_path / "khr.glb"
    code, text, _ = _run(capsys, glb, out, "--mesh", tmp_path / "m.obj", "--translate", "0,1,0",
                         "--keep-order", "--json")
    assert code == 0 and json.loads(text)["source"] == "khr"
    (prim,) = read(out).anchored
    assert np.allclose(prim.splats.means, _to_gltf(cloud.means) + [0, 1, 0], atol=1e-4)
    spz = tmp_path / "s.spz"
    write_spz_v2(cloud, spz)
    code, text, _ = _run(capsys, spz, tmp_path / "spz.glb", "--plain", "--crop-sphere",
                         "0,0,0,1", "--json")
    summary = json.loads(text)
    assert code == 0 and summary["splats"] + summary["edits"]["cropped"] == len(cloud)
    assert np.all(np.linalg.norm(read(tmp_path / "spz.glb").primitives[0].splats.means, axis=1)
                  <= 1 + 1e-6)


def test_nonfinite_rows_flags_zero_quaternions_and_each_array():
    cloud = random_splats(8, sh_degree=1)
    cloud.rotations[1] = 0
    cloud.means[2, 0] = np.inf
    cloud.sh[4, 3, 2] = np.nan
    cloud.opacities[6] = np.nan
    assert np.flatnonzero(nonfinite_rows(cloud)).tolist() == [1, 2, 4, 6]


def test_mesh_edits_move_a_rigged_mesh_with_its_skin(tmp_path, capsys):
    """A skinned --mesh moved by --mesh-*: the posed anchor mesh is the original pose moved
    by the same similarity (its skin, inverse bind matrices and animation follow)."""
    import gsverse_format as gv
    from gsverse_format.cli.pose import main as pose_main
    from gsverse_format.model import SplatAsset, SplatPrimitive

    from test_skin_weights import _character, _skinned

    char = tmp_path / "character.glb"
    rest, faces, weights = _character(char)
    r = Rotation.from_euler("y", 90, degrees=True).as_matrix()

    def move(v):
        return 2.0 * np.asarray(v, np.float64) @ r.T + [1.0, 0.5, -0.25]

    cloud = surface_splats(TriangleMesh(move(rest), faces), 300, 7, offset=0.0)
    splats = tmp_path / "splats.glb"   # glTF frame: the edits act there
    gv.write(SplatAsset([SplatPrimitive(cloud, None, "body")]), splats)
    out = tmp_path / "anchored.glb"
    code, _, _ = _run(capsys, splats, out, "--mesh", char, "--mesh-scale", "2",
                      "--mesh-rotate", "0,90,0", "--mesh-translate=1,0.5,-0.25", "-q")
    assert code == 0
    anchoring = gv.read(out).anchored[0].anchoring
    np.testing.assert_allclose(anchoring.mesh.vertices, move(rest), atol=1e-5)
    posed = tmp_path / "posed.glb"
    assert pose_main([str(out), str(posed), "--times", "1", "-q"]) == 0
    got = gv.read(posed).primitives[0].splats.means.astype(np.float64)
    want = gv.remap(anchoring, move(_skinned(rest, weights, 1.0))).means
    np.testing.assert_allclose(got, want, atol=1e-4)
    # the unmoved pose would differ: the comparison tells them apart
    assert np.abs(gv.remap(anchoring, move(rest)).means - want).max() > 0.1


def test_trellis_drops_nonfinite_splats(tmp_path):
    from gsverse_format.errors import NonFiniteError
    from gsverse_format.pipeline import convert

    from test_converters_trellis_reconstruct import _write_trellis_run

    ply, glb, _ = _write_trellis_run(tmp_path, n=1500)
    _poison(ply, [0, 700, 1499], "scale_2", np.nan)
    with pytest.raises(NonFiniteError, match="3 NaN or Inf.*--drop-nonfinite"):
        convert(ply, tmp_path / "x.glb", ConvertOptions(mesh=str(glb)))
    summary = convert(ply, tmp_path / "out.glb", ConvertOptions(mesh=str(glb),
                                                               drop_nonfinite=True))
    assert summary.source == "trellis" and summary.anchored == 1497
    assert summary.edits == {"nonfinite": 3, "cropped": 0, "below_opacity": 0}


def test_output_frame_matches_splat_transform(tmp_path, capsys):
    """splat-transform (the reference; skipped without it) acts in the frame it reads a PLY
    into, turned 180° about Z: --edit-frame output gives its numbers; in the PLY's own frame
    the same edit is written with x and y negated."""
    from gsverse_format.io.ply import read_splat_ply
    from gsverse_format.quaternion import to_matrix

    from test_splat_formats import splat_transform

    cloud = random_splats(300, seed=3, sh_degree=3)
    write_splat_ply(cloud, tmp_path / "in.ply")
    splat_transform(tmp_path / "in.ply", "-s", "2", "-r", "10,20,30", "-t", "1,2,3",
                    "-B", "-2,-1,-3,3,4,5", tmp_path / "theirs.ply")
    theirs = read_splat_ply(tmp_path / "theirs.ply")
    assert 0 < len(theirs) < len(cloud)
    runs = {"output": ("--edit-frame", "output", "--rotate", "10,20,30", "--translate", "1,2,3",
                       "--crop-box=-2,-1,-3,3,4,5"),
            "input": ("--rotate=-10,-20,30", "--translate=-1,-2,3", "--crop-box=-3,-4,-3,2,1,5")}
    for frame, args in runs.items():
        out = tmp_path / f"{frame}.ply"
        assert _run(capsys, tmp_path / "in.ply", out, "--scale", "2", "-q", *args)[0] == 0
        ours = read_splat_ply(out)
        assert len(ours) == len(theirs), frame
        assert np.allclose(ours.means, theirs.means, atol=F32), frame
        assert np.allclose(ours.scales, theirs.scales, rtol=1e-6), frame
        assert np.allclose(to_matrix(ours.rotations), to_matrix(theirs.rotations), atol=1e-6)
        assert np.allclose(ours.sh, theirs.sh, atol=1e-5), frame


def test_batch_mesh_edits_need_each_asset_mesh(small_mesh, tmp_path, capsys):
    path, mesh_path, _, _ = small_mesh
    manifest = tmp_path / "m.csv"
    manifest.write_text(f"input,mesh,output\n{path.name},{mesh_path.name},a.glb\n"
                        f"{path.name},,b.glb\n")
    code, _, err = _run(capsys, manifest, "-o", tmp_path / "out", "--mesh-scale", "0.01")
    assert code == 2 and "m.csv:3" in err and "give one" in err
    assert not (tmp_path / "out" / "a.glb").exists()
    manifest.write_text(f"input,mesh,output\n{path.name},{mesh_path.name},a.glb\n")
    code, text, err = _run(capsys, manifest, "-o", tmp_path / "out", "--mesh-scale", "0.01",
                           "--json")
    assert code == 0 and json.loads(text)["ok"] == 1 and "warning" not in err
