"""The splat/mesh fit check (gsverse_format.fit): generated splats around a generated mesh, and
the real files of ../shared/data (skipped when absent) that calibrate its thresholds."""
from __future__ import annotations

import numpy as np
import pytest

from gsverse_format.fit import (AROUND_FRACTION, MIN_AROUND_NEAR_SHARE, MIN_EXTENT_RATIO,
                                MIN_NEAR_SHARE, MIN_SPAN_RATIO, NEAR_FRACTION, assess_fit)
from gsverse_format.nearest import nearest_triangles


def _box_mesh(size=(1.0, 1.6, 0.8)):
    """A closed box (12 triangles) centred on the origin, elongated along y."""
    sx, sy, sz = (s / 2 for s in size)
    v = np.array([[x, y, z] for x in (-sx, sx) for y in (-sy, sy) for z in (-sz, sz)], float)
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return v, f


def _splats_on(v, f, n=2000, noise=0.01, seed=0):
    rng = np.random.default_rng(seed)
    tri = v[f[rng.integers(0, len(f), n)]]
    w = rng.dirichlet((1, 1, 1), n)
    return np.einsum("nk,nkj->nj", w, tri) + rng.normal(0, noise, (n, 3))


def _fit(means, v, f):
    return assess_fit(means, v, nearest_triangles(means, v, f, method="numpy").distance)


def test_matching_mesh_passes_with_numbers():
    v, f = _box_mesh()
    r = _fit(_splats_on(v, f), v, f)
    assert r.ok and r.message() == ""
    assert r.near_share > 0.99
    assert r.mesh_diagonal == pytest.approx(np.linalg.norm([1, 1.6, 0.8]))


def test_moved_mesh_is_far_and_names_the_offset():
    v, f = _box_mesh()
    means = _splats_on(v, f)
    moved = v + [40 * np.linalg.norm(v.max(0) - v.min(0)), 0, 0]
    r = _fit(means, moved, f)
    assert not r.ok
    assert r.near_share < 0.01 and r.median_distance > 30
    assert "0% of the splats" in r.problem and "offset by (-82," in r.hint


def test_mesh_in_other_units_names_the_factor():
    v, f = _box_mesh()
    means = _splats_on(v, f)
    r = _fit(means, v * 100, f)     # the mesh in centimetres, the splats in metres
    assert not r.ok and r.splat_diagonal / r.mesh_diagonal < MIN_EXTENT_RATIO
    assert "larger than the splats" in r.problem and "by 100" in r.hint


def test_mesh_in_another_frame_names_the_turn():
    v, f = _box_mesh()
    means = _splats_on(v, f)
    z_up = v @ np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], float).T   # y-up -> z-up
    r = _fit(means, z_up, f)
    assert not r.ok
    assert "turned (x, y, z) -> (x, -z, y)" in r.hint or "turned (x, y, z) -> (x, z, -y)" in r.hint


def test_scene_around_a_small_object_is_not_a_mismatch():
    """A capture of a room around an anchored object: most splats are far, which is fine."""
    v, f = _box_mesh()
    rng = np.random.default_rng(3)
    room = rng.uniform(-20, 20, (20000, 3))
    means = np.concatenate([_splats_on(v, f, 1000), room])
    r = _fit(means, v, f)
    assert r.ok, r.message()
    assert NEAR_FRACTION * r.mesh_diagonal > 0 and 0.01 < r.near_share < 0.5


def test_floaters_do_not_make_a_scale_mismatch():
    v, f = _box_mesh()
    means = _splats_on(v, f)
    means[:5] = 1e4            # five floaters far away
    assert _fit(means, v, f).ok


def _sphere_splats(radius, n=3000, seed=1):
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    return radius * d / np.linalg.norm(d, axis=1, keepdims=True)


def _quad(lo, hi):
    """A square in the plane z = 0 from (lo, lo) to (hi, hi): two triangles."""
    v = np.array([[lo, lo, 0], [hi, lo, 0], [hi, hi, 0], [lo, hi, 0]], float)
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def test_splats_on_a_small_part_of_a_larger_mesh_warn():
    """Splats on a 2 x 2 patch of a 10 x 10 floor (another object's mesh, a whole scene's):
    they lie on it, but cover a small part of it."""
    rng = np.random.default_rng(2)
    means = np.column_stack([rng.uniform(0, 2, (2000, 2)), rng.normal(0, 0.005, 2000)])
    v, f = _quad(-4, 6)
    r = _fit(means, v, f)
    assert not r.ok and r.near_share > 0.99
    assert MIN_EXTENT_RATIO < r.splat_diagonal / r.mesh_diagonal < MIN_SPAN_RATIO
    assert "5.1x larger than the splats" in r.problem and "small part" in r.problem
    assert "belongs to these splats" in r.hint
    v, f = _quad(-1, 3)      # twice as large as the patch: a mesh reaching beyond it passes
    assert _fit(means, v, f).ok


def test_another_object_in_the_same_place_warns():
    """Splats of a ball inside a box mesh of about its size: they fill the box, but few lie
    on its faces (as an unrelated bunny under a donut)."""
    v, f = _box_mesh()
    means = _sphere_splats(0.35)
    r = _fit(means, v, f)
    assert not r.ok and MIN_NEAR_SHARE < r.near_share < MIN_AROUND_NEAR_SHARE
    assert r.around_near_share == pytest.approx(r.near_share)   # every splat is around it
    assert "splats around the anchor mesh" in r.problem and "surface" in r.hint
    assert r.as_dict()["around_near_share"] == r.around_near_share


def test_the_share_around_the_mesh_ignores_far_splats():
    """The same ball in a room: the room's splats are not around the mesh, the verdict stays."""
    v, f = _box_mesh()
    rng = np.random.default_rng(3)
    room = rng.uniform(-20, 20, (20000, 3))
    room = room[np.any(np.abs(room) > 1 + 2 * AROUND_FRACTION * 2.1, axis=1)]
    r = _fit(np.concatenate([_sphere_splats(0.35), room]), v, f)
    assert not r.ok and "splats around the anchor mesh" in r.problem
    assert r.near_share < 0.05 < r.around_near_share < MIN_AROUND_NEAR_SHARE


# ---------------------------------------------------------------------------- real files

def _real_fit(src, out, **options):
    import warnings

    import gsverse_format as gv
    from gsverse_format.fit import MeshFitWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MeshFitWarning)
        summary = gv.convert(src, out, **options)
    (entry,) = summary.fit
    return entry


def _unrelated_pairs(data):
    splats = sorted((data / "3dgs").glob("*.ply"))
    meshes = sorted([*(data / "meshes").glob("*.ply"), *(data / "meshes").glob("*.glb"),
                     *(data / "meshes").glob("*.gltf"), *(data / "trellis").glob("*.glb")])
    return [(s, m) for s in splats for m in meshes]


def test_every_unrelated_real_pair_warns(shared_data, tmp_path):
    """Every 3DGS capture of ../shared/data against every mesh there (none is the capture's):
    the calibration data of fit.py's thresholds."""
    pairs = _unrelated_pairs(shared_data)
    assert len(pairs) >= 9
    passed = []
    for i, (splats, mesh) in enumerate(pairs):
        entry = _real_fit(splats, tmp_path / f"{i}.glb", mesh=str(mesh))
        if entry["ok"]:
            passed.append((splats.name, mesh.name, entry["near_share"]))
    assert not passed, passed


def test_the_bunny_under_the_donut_warns_in_the_validator_too(shared_data, tmp_path):
    from gsverse_format.codes import Code
    from gsverse_format.validators.validate import validate_file

    entry = _real_fit(shared_data / "3dgs" / "donut_mipsplatting_sh0_fused.ply", tmp_path / "o.glb",
                      mesh=str(shared_data / "meshes" / "trimesh_bunny_stanford_res2.ply"))
    assert not entry["ok"] and 0.05 < entry["near_share"] < 0.2       # about 89% not near
    assert entry["around_near_share"] < MIN_AROUND_NEAR_SHARE
    found = [f for f in validate_file(tmp_path / "o.glb").findings
             if f.code == Code.ANCHOR_MESH_MISFIT]
    assert len(found) == 1 and "around the anchor mesh" in found[0].message


@pytest.mark.parametrize("name", ["donut_mipsplatting_sh0_fused.ply",
                                  "404gen_tmp_model_dreamgaussian_sh0.ply"])
def test_meshes_reconstructed_from_real_captures_fit(shared_data, tmp_path, name):
    entry = _real_fit(shared_data / "3dgs" / name, tmp_path / "o.glb", reconstruct_faces=300,
                      strict=True)
    assert entry["ok"] and entry["around_near_share"] > 0.95
    assert entry["splat_diagonal"] / entry["mesh_diagonal"] > MIN_SPAN_RATIO


def test_the_offset_hint_applied_in_the_output_frame_makes_the_mesh_fit(tmp_path):
    """The hint's offset is in the output's glTF frame; gsverse-convert applies it there with
    --mesh-translate and --edit-frame output, and the warning is gone."""
    import json
    import re
    import subprocess
    import sys
    from pathlib import Path

    import trimesh

    capsule = Path(__file__).resolve().parents[1] / "examples" / "capsule"
    mesh = trimesh.load(capsule / "mesh.obj", process=False)
    mesh.apply_translation([4.0, -2.0, 1.0])  # in the PLY's own frame
    moved = tmp_path / "moved.obj"
    mesh.export(moved)

    def convert(*extra: str) -> dict:
        proc = subprocess.run([sys.executable, "-m", "gsverse_format.cli.convert",
                               str(capsule / "splats.ply"), str(tmp_path / "out.glb"), "-w",
                               "--mesh", str(moved), "--json", *extra],
                              capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr
        return json.loads(proc.stdout)

    hint = convert()["fit"][0]["hint"]
    assert "--edit-frame output" in hint, hint
    offset = re.search(r"offset by \(([^)]*)\)", hint).group(1)
    fixed = convert(f"--mesh-translate={offset.replace(' ', '')}", "--edit-frame", "output")
    assert fixed["fit"][0]["problem"] is None, fixed["fit"]
