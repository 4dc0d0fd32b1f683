"""Small inputs and arguments that would amplify into gigabytes or minutes, and refusals that
must give their true cause: one line, exit 1 (2 for usage), bounded time and memory of the
child, nothing written.

Every input is built here: a pose source whose node chain is thousands of levels deep or
whose key times run past an hour, a few hundred bytes of ``.npz`` declaring 10¹¹ elements,
50,000 morph targets sharing one accessor, a truncated binary STL, output folders that are a
file, a broken symbolic link or a link loop. The limits are those of ``limits.py`` (README
§Limits)."""
from __future__ import annotations

import io
import os
import struct
import zipfile
from pathlib import Path

import numpy as np
import pytest

import gsverse_format as gv
from gsverse_format.limits import MAX_NODE_DEPTH, MAX_POSES, MAX_VAT_WIDTH
from gsverse_format.model import SplatAsset, SplatPrimitive, TriangleMesh

from helpers import random_splats, surface_splats
from hostile_tools import assert_one_line, glb_bytes, run_measured

POSE = "gsverse_format.cli.pose"
CONVERT = "gsverse_format.cli.convert"
RENDER = "gsverse_format.cli.render"

QUAD = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float32)
QUAD_FACES = np.array([[0, 1, 2], [1, 3, 2]], np.uint16)


def pose_source(path: Path, *, depth: int = 1, key_times=(0.0, 1.0)) -> Path:
    """A GLB drawing QUAD at the end of a chain of ``depth`` nodes, with one morph target
    whose weight an animation moves over ``key_times``."""
    times = np.asarray(key_times, np.float32)
    weights = np.linspace(0, 1, len(times), dtype=np.float32)
    delta = np.full((4, 3), 0.1, np.float32)
    parts = [QUAD.tobytes(), QUAD_FACES.tobytes(), delta.tobytes(), times.tobytes(),
             weights.tobytes()]
    views, offset = [], 0
    for part in parts:
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(part)})
        offset += len(part)
    acc = [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
            "min": [0, 0, 0], "max": [1, 1, 0]},
           {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"},
           {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC3"},
           {"bufferView": 3, "componentType": 5126, "count": len(times), "type": "SCALAR"},
           {"bufferView": 4, "componentType": 5126, "count": len(times), "type": "SCALAR"}]
    nodes = [{"children": [i + 1]} for i in range(depth - 1)] + [{"mesh": 0}]
    doc = {"scene": 0, "scenes": [{"nodes": [0]}], "nodes": nodes, "bufferViews": views,
           "accessors": acc,
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1,
                                       "targets": [{"POSITION": 2}]}], "weights": [0]}],
           "animations": [{"samplers": [{"input": 3, "output": 4}],
                           "channels": [{"sampler": 0,
                                         "target": {"node": depth - 1, "path": "weights"}}]}]}
    path.write_bytes(glb_bytes(doc, b"".join(parts)))
    return path


def morph_bomb(path: Path, side: int = 40, targets: int = 50_000) -> Path:
    """A grid mesh of side² vertices with ``targets`` morph targets sharing one accessor."""
    u, v = np.meshgrid(np.linspace(0, 1, side), np.linspace(0, 1, side))
    verts = np.stack([u.ravel(), v.ravel(), np.zeros(side * side)], 1).astype(np.float32)
    k = np.arange(side * side).reshape(side, side)[:-1, :-1].ravel()
    faces = np.concatenate([np.stack([k, k + 1, k + side], 1),
                            np.stack([k + 1, k + side + 1, k + side], 1)]).astype(np.uint32)
    delta = np.full_like(verts, 0.01)
    blob = verts.tobytes() + faces.tobytes() + delta.tobytes()
    n, f = len(verts), faces.size
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": 12 * n},
             {"buffer": 0, "byteOffset": 12 * n, "byteLength": 4 * f},
             {"buffer": 0, "byteOffset": 12 * n + 4 * f, "byteLength": 12 * n}]
    acc = [{"bufferView": 0, "componentType": 5126, "count": n, "type": "VEC3",
            "min": [0, 0, 0], "max": [1, 1, 0]},
           {"bufferView": 1, "componentType": 5125, "count": f, "type": "SCALAR"},
           {"bufferView": 2, "componentType": 5126, "count": n, "type": "VEC3"}]
    doc = {"scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "bufferViews": views, "accessors": acc,
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1,
                                       "targets": [{"POSITION": 2}] * targets}],
                       "weights": [0] * targets}]}
    path.write_bytes(glb_bytes(doc, blob))
    return path


def npz_declaring(path: Path, shape: tuple[int, ...], payload: bytes = b"") -> Path:
    """An ``.npz`` whose ``vertices.npy`` header declares ``shape`` float32, followed by
    ``payload`` only (a few hundred bytes however large the shape)."""
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f4", "fortran_order": False,
                                                  "shape": shape})
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("vertices.npy", header.getvalue() + payload)
    return path


@pytest.fixture(scope="module")
def work(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("amplify")
    mesh = TriangleMesh(QUAD, QUAD_FACES.astype(np.int64))
    cloud = surface_splats(mesh, 50, 0, offset=0.0)
    gv.write(SplatAsset([SplatPrimitive(cloud, gv.bind(cloud, mesh), "quad")]),
             root / "asset.glb")
    gv.write(SplatAsset([SplatPrimitive(random_splats(200, 1, sh_degree=0), None, "s")]),
             root / "splats.glb")
    return {"asset": root / "asset.glb", "splats": root / "splats.glb", "root": root}


def _nothing_new(folder: Path, before: set[str]) -> None:
    assert {p.name for p in folder.iterdir()} == before


# ---------------------------------------------------------------------------- item 6

def test_vat_width_beyond_the_limit_is_a_usage_error(work, tmp_path):
    out = tmp_path / "v.exr"
    code, err, cpu, peak = run_measured(POSE, work["asset"], "--deform", "twist=30",
                                        "--vat", out, "--vat-width", str(10 ** 9))
    assert_one_line(code, err, cpu, peak, "--vat-width", str(MAX_VAT_WIDTH), status=2)
    assert not out.exists()


@pytest.mark.parametrize("size", ["16384x16384", "5000x5000"])
def test_render_size_beyond_the_pixel_limit_is_a_usage_error(work, tmp_path, size):
    out = tmp_path / "r.png"
    code, err, cpu, peak = run_measured(RENDER, work["asset"], out, "--size", size)
    assert_one_line(code, err, cpu, peak, "--size", "pixels", status=2)
    assert not out.exists()


def test_key_times_of_an_hour_at_24_fps_exceed_the_pose_limit(work, tmp_path):
    source = pose_source(tmp_path / "long.glb", key_times=(0.0, 4166.0))
    out = tmp_path / "poses"
    code, err, cpu, peak = run_measured(POSE, work["asset"], "--source", source, "--fps", "24",
                                        "--output-dir", out)
    assert_one_line(code, err, cpu, peak, "99985 poses", str(MAX_POSES), "--fps", "--duration",
                    "--times", status=2)
    assert not out.exists()


def test_an_npz_declaring_1e11_elements_is_refused_from_its_header(work, tmp_path):
    cache = npz_declaring(tmp_path / "bomb.npz", (1, 33_333_333_334, 3))
    assert cache.stat().st_size < 1024
    out = tmp_path / "poses"
    code, err, cpu, peak = run_measured(POSE, work["asset"], "--source", cache, "--fps", "24",
                                        "--output-dir", out)
    assert_one_line(code, err, cpu, peak, str(cache), "declares 100000000002 elements")
    assert not out.exists()


def test_an_npz_of_the_wrong_vertex_count_is_refused_before_it_is_loaded(work, tmp_path):
    # 48 MB declared (within the ratio to its size): refused by the header's vertex count
    frames = np.zeros((2000, 1000, 3), np.float64)
    cache = tmp_path / "wrong.npz"
    np.savez_compressed(cache, vertices=frames)
    out = tmp_path / "poses"
    code, err, cpu, peak = run_measured(POSE, work["asset"], "--source", cache, "--fps", "24",
                                        "--output-dir", out)
    assert_one_line(code, err, cpu, peak, str(cache), "holds 1000 vertices per frame",
                    "has 4")
    assert not out.exists()


def test_morph_targets_sharing_one_accessor_are_bounded(work, tmp_path):
    mesh = morph_bomb(tmp_path / "morphs.glb")
    assert mesh.stat().st_size < 2 * 2 ** 20
    out = tmp_path / "out.glb"
    code, err, cpu, peak = run_measured(CONVERT, work["splats"], out, "--mesh", mesh)
    assert_one_line(code, err, cpu, peak, mesh.name, "50000 morph targets")
    assert not out.exists()


def test_a_few_morph_targets_still_convert(work, tmp_path):
    mesh = morph_bomb(tmp_path / "morphs.glb", side=8, targets=3)
    out = tmp_path / "out.glb"
    code, err, _, _ = run_measured(CONVERT, work["splats"], out, "--mesh", mesh)
    assert code == 0, err
    from gsverse_format.io.mesh import read_mesh

    assert len(read_mesh(mesh).rig.targets) == 3


def test_a_deep_node_chain_is_refused_as_pose_source_and_as_mesh(work, tmp_path):
    deep = pose_source(tmp_path / "deep.glb", depth=MAX_NODE_DEPTH + 1)
    out = tmp_path / "poses"
    code, err, cpu, peak = run_measured(POSE, work["asset"], "--source", deep, "--times", "0.5",
                                        "--output-dir", out)
    assert_one_line(code, err, cpu, peak, deep.name, "levels deep", str(MAX_NODE_DEPTH))
    assert not out.exists()
    glb = tmp_path / "out.glb"
    code, err, cpu, peak = run_measured(CONVERT, work["splats"], glb, "--mesh", deep)
    assert_one_line(code, err, cpu, peak, deep.name, "levels deep")
    assert not glb.exists()


def test_a_chain_at_the_depth_limit_poses(work, tmp_path):
    chain = pose_source(tmp_path / "chain.glb", depth=MAX_NODE_DEPTH)
    out = tmp_path / "poses"
    code, err, cpu, _ = run_measured(POSE, work["asset"], "--source", chain, "--fps", "4",
                                     "--output-dir", out)
    assert code == 0, err
    assert len(list(out.iterdir())) == 5


# ---------------------------------------------------------------------------- item 9

def test_a_truncated_binary_stl_says_so(work, tmp_path):
    stl = tmp_path / "cut.stl"
    tri = struct.pack("<12fH", *([0.0] * 3 + [0, 0, 0, 1, 0, 0, 0, 1, 0]), 0)
    stl.write_bytes(b"\0" * 80 + struct.pack("<I", 1000) + tri * 10)
    out = tmp_path / "out.glb"
    code, err, cpu, peak = run_measured(CONVERT, work["splats"], out, "--mesh", stl)
    assert_one_line(code, err, cpu, peak, stl.name, "truncated binary STL", "1000 triangles")
    assert not out.exists()


def test_nan_key_times_are_refused_naming_the_source(work, tmp_path):
    source = pose_source(tmp_path / "nan.glb", key_times=(0.0, float("nan")))
    out = tmp_path / "poses"
    code, err, cpu, peak = run_measured(POSE, work["asset"], "--source", source, "--fps", "24",
                                        "--output-dir", out)
    assert_one_line(code, err, cpu, peak, source.name, "key time is not a finite number")
    assert not out.exists()


def _bad_folder(root: Path, kind: str) -> Path:
    path = root / kind
    if kind == "file":
        path.write_bytes(b"x")
    elif kind == "dangling":
        os.symlink(root / "nowhere", path)
    else:
        os.symlink(path, path)
    return path


CAUSES = {"file": "is a file, not a folder", "dangling": "is a broken symbolic link",
          "loop": "is a symbolic link loop"}


@pytest.mark.parametrize("kind", sorted(CAUSES))
@pytest.mark.parametrize("how", ["convert -o DIR/", "convert --output-dir", "pose --output-dir"])
def test_an_output_folder_that_cannot_be_one_says_why(work, tmp_path, kind, how):
    folder = _bad_folder(tmp_path, kind)
    before = {p.name for p in tmp_path.iterdir()}
    if how == "convert -o DIR/":
        args = (CONVERT, work["splats"], "-o", f"{folder}/")
    elif how == "convert --output-dir":
        args = (CONVERT, work["splats"], "--output-dir", folder)
    else:
        args = (POSE, work["asset"], "--deform", "twist=30", "--output-dir", folder)
    code, err, cpu, peak = run_measured(*args)
    assert_one_line(code, err, cpu, peak, str(folder), CAUSES[kind])
    assert "File exists" not in err
    _nothing_new(tmp_path, before)
