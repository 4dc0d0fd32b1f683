"""Animated anchor meshes in the file (spec/README.md §Animated anchor meshes): converting
with a skinned glTF ``--mesh`` keeps its skin, joints, weights and animations; the anchor node
is hidden with ``KHR_node_visibility``; ``gsverse-pose`` without ``--source`` follows the
asset's own animation. The skinning of the written file is recomputed here with plain numpy
(glTF linear blend skinning read with pygltflib), nothing shared with the package."""
from __future__ import annotations

import numpy as np
import pygltflib

import gsverse_format as gv
from gsverse_format.cli.pose import main as pose_main
from gsverse_format.conformance.skin import skinned_tube
from gsverse_format.io.mesh import read_mesh
from gsverse_format.io.registry import FRAMES
from gsverse_format.model import SplatAsset, SplatPrimitive, TriangleMesh
from gsverse_format.validators.validate import Severity

from helpers import anchor_foot_points, numpy_skinning, surface_splats

TIMES = (0.3, 0.7)


def _areas(v: np.ndarray, faces: np.ndarray) -> np.ndarray:
    tri = np.asarray(v, np.float64)[faces.astype(np.intp)]
    return np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)


def _check_asset(out, tmp_path, n_joints: int) -> None:
    """Skin, joints, animations and KHR_node_visibility kept; validators clean; the asset's own
    animation poses every splat within its stated distance of the independently skinned
    mesh."""
    g = pygltflib.GLTF2().load(str(out))
    assert "KHR_node_visibility" in g.extensionsUsed
    assert "KHR_node_visibility" not in (g.extensionsRequired or [])
    users = [i for i, n in enumerate(g.nodes) if n.skin is not None]
    assert len(users) == 1
    anchor_node = g.nodes[users[0]]
    assert anchor_node.extensions["KHR_node_visibility"] == {"visible": False}
    assert len(g.skins) == 1 and len(g.skins[0].joints) == n_joints
    assert g.animations and all(ch.target.node < len(g.nodes) for a in g.animations
                                for ch in a.channels)
    scene_roots = set(g.scenes[0].nodes)
    assert users[0] in scene_roots and 0 in scene_roots   # splat node and anchor node share
    report = gv.validate(out)
    assert report.count(Severity.ERROR) == 0 and report.count(Severity.WARNING) == 0, \
        report.to_json()

    asset = gv.read(out)
    prim = asset.anchored[0]
    rest = prim.anchoring.mesh.vertices.astype(np.float64)
    diag = float(np.linalg.norm(np.ptp(rest, axis=0)))
    stated = np.abs(prim.anchoring.anchors.normal_offset.astype(np.float64)) + 1e-4 * diag
    posed_dir = tmp_path / "posed"
    assert pose_main([str(out), "--times", *map(str, TIMES), "-o", str(posed_dir), "-q"]) == 0
    moved = 0.0
    for i, t in enumerate(TIMES):
        v = numpy_skinning(g, users[0], t)
        posed = gv.read(posed_dir / f"{out.stem}_f{i:04d}.ply").primitives[0].splats.means
        posed = posed[:len(prim.splats)]    # the anchored primitive comes first
        d = np.linalg.norm(posed - anchor_foot_points(prim, v), axis=1)
        # the stated distance: |normal offset| along the scaled normal of the affine law,
        # |m| = sqrt(a_current / a_rest) (spec §Remap: the local profile)
        f = prim.anchoring.anchors.face_index.astype(np.intp)
        ratio = np.sqrt(_areas(v, prim.anchoring.mesh.faces)[f]
                        / _areas(rest, prim.anchoring.mesh.faces)[f])
        assert np.all(d <= stated * ratio * (1 + 1e-5)), (t, d.max(), stated.max())
        moved = max(moved, float(np.abs(posed - prim.splats.means).max()))
    assert moved > 0.01 * diag


def _khr_clean(path) -> None:
    from khr_tools import require_node_tools, validate_gltf

    require_node_tools()
    report = validate_gltf(path)
    assert report["numUnexpectedErrors"] == 0, report["messages"]


def test_fox_keeps_skin_and_animations(shared_data, tmp_path):
    fox = shared_data / "meshes" / "Fox.glb"
    mesh = read_mesh(fox)
    assert mesh.rig is not None and len(mesh.rig.joints) == 24
    cloud = surface_splats(mesh, 600, 3, offset=0.0)
    cloud.scales = np.full_like(cloud.scales, 0.4)
    gv.write(SplatAsset([SplatPrimitive(cloud, None, "fox")]), tmp_path / "splats.glb")
    out = tmp_path / "fox.glb"
    gv.convert(tmp_path / "splats.glb", out, mesh=str(fox))
    g = pygltflib.GLTF2().load(str(out))
    assert [a.name for a in g.animations] == ["Survey", "Walk", "Run"]
    # the anchor mesh keeps the bind vertices in the reader's order
    np.testing.assert_allclose(gv.read(out).anchored[0].anchoring.mesh.vertices,
                               mesh.vertices, atol=1e-4)
    _check_asset(out, tmp_path, 24)
    _khr_clean(out)


def test_hand_built_skin_through_a_frame_change(tmp_path):
    """A 3DGS PLY input: the converter rotates splats and mesh into glTF; the rig follows."""
    glb, rest, faces, _ = skinned_tube()
    src = tmp_path / "tube_mesh.glb"
    src.write_bytes(glb)
    r = FRAMES["3dgs"].to_gltf
    turned = TriangleMesh(rest.astype(np.float64) @ r.T, faces)
    cloud = surface_splats(turned, 300, 5, offset=0.0)
    gv.write(SplatAsset([SplatPrimitive(cloud, None, "tube")]), tmp_path / "splats.ply")
    out = tmp_path / "tube.glb"
    gv.convert(tmp_path / "splats.ply", out, mesh=str(src))
    np.testing.assert_allclose(gv.read(out).anchored[0].anchoring.mesh.vertices,
                               turned.vertices, atol=1e-5)
    _check_asset(out, tmp_path, 3)
    _khr_clean(out)


def test_skin_and_morph_targets_written_from_the_model(tmp_path):
    """An asset built in memory with a rig (two joints, a morph target animated with them)."""
    from validation_assets import rigged_asset

    out = tmp_path / "rigged.glb"
    gv.write(rigged_asset(), out)
    g = pygltflib.GLTF2().load(str(out))
    anchor = g.meshes[g.nodes[[n.skin for n in g.nodes].index(0)].mesh]
    assert anchor.weights == [0.0] and len(anchor.primitives[0].targets) == 1
    _check_asset(out, tmp_path, 2)
    _khr_clean(out)


def test_decimating_the_anchor_mesh_drops_its_rig_with_a_note(tmp_path):
    glb, rest, faces, _ = skinned_tube()
    src = tmp_path / "tube_mesh.glb"
    src.write_bytes(glb)
    cloud = surface_splats(TriangleMesh(rest, faces), 100, 2, offset=0.0)
    gv.write(SplatAsset([SplatPrimitive(cloud, None, "tube")]), tmp_path / "splats.glb")
    summary = gv.convert(tmp_path / "splats.glb", tmp_path / "small.glb", mesh=str(src),
                         faces=len(faces) // 2)
    assert any("skin, morph targets and animations were dropped" in n for n in summary.notes)
    g = pygltflib.GLTF2().load(str(tmp_path / "small.glb"))
    assert not g.skins and not g.animations and all(n.skin is None for n in g.nodes)


def test_simple_skin_whose_mesh_node_parents_the_skeleton(shared_data, tmp_path):
    """Khronos SimpleSkin: the mesh node is the skeleton's parent (kept as a plain node)."""
    src = shared_data / "meshes" / "SimpleSkin.gltf"
    mesh = read_mesh(src)
    assert mesh.rig is not None and len(mesh.rig.nodes) == 3
    cloud = surface_splats(mesh, 200, 4, offset=0.0)
    gv.write(SplatAsset([SplatPrimitive(cloud, None, "skin")]), tmp_path / "splats.glb")
    out = tmp_path / "simple.glb"
    gv.convert(tmp_path / "splats.glb", out, mesh=str(src))
    _check_asset(out, tmp_path, 2)
    _khr_clean(out)
