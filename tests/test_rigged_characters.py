"""Rigged characters of several parts as ``--mesh`` (spec/README.md §Animated anchor meshes):
every triangle primitive becomes part of the one anchor mesh with its skin(s), weights and
animations; the rest pose is what glTF draws (a skinned mesh's node transform is ignored, the
skeleton places it); posing follows glTF skinning. The characters are built here from numpy
arrays; the reference skinning is the tests' own (helpers.numpy_skinning, pygltflib)."""
from __future__ import annotations

import itertools
import warnings

import numpy as np
import pygltflib
import pytest

import gsverse_format as gv
from gsverse_format.cli.convert import main as convert_main
from gsverse_format.cli.pose import main as pose_main
from gsverse_format.conformance.glb import (FLOAT, UNSIGNED_BYTE, UNSIGNED_SHORT, BufferBuilder,
                                            pack_glb)
from gsverse_format.conformance.skin import tube
from gsverse_format.errors import FormatError
from gsverse_format.fit import MeshFitWarning
from gsverse_format.io.mesh import read_mesh
from gsverse_format.model import SplatAsset, SplatPrimitive, TriangleMesh
from gsverse_format.validators.validate import Severity

from helpers import anchor_foot_points, numpy_skinning, surface_splats

H = 1.2
STEP = H / 3
TIMES = (0.3, 0.7)


def _quat(axis, degrees: float) -> list[float]:
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    half = np.radians(degrees) / 2
    return [*(np.sin(half) * axis), float(np.cos(half))]


def _matrix(t=(0, 0, 0), q=(0, 0, 0, 1), s=(1, 1, 1)) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    m = np.eye(4)
    m[:3, :3] = Rotation.from_quat(q).as_matrix() @ np.diag(s)
    m[:3, 3] = t
    return m


ARMATURE = {"translation": [0.0, 0.5, 0.2], "rotation": _quat((1, 0, 0), 30)}
#: the transform of the skinned body's node: glTF ignores it
BODY_NODE = {"translation": [3.0, 0.0, 0.0], "rotation": _quat((0, 1, 0), 90),
             "scale": [2.0, 2.0, 2.0]}


def _tube_weights(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    joint_y = np.array([0.0, STEP, 2 * STEP])
    y = v[:, 1]
    seg = np.clip(np.searchsorted(joint_y, y, side="right") - 1, 0, 1)
    frac = np.clip((y - joint_y[seg]) / STEP, 0.0, 1.0)
    joints = np.zeros((len(v), 4), np.uint8)
    weights = np.zeros((len(v), 4), np.float32)
    joints[:, 0], joints[:, 1] = seg, seg + 1
    weights[:, 0] = 1.0 - frac
    weights[:, 1] = 1.0 - weights[:, 0]
    joints[weights == 0] = 0
    return joints, weights


def _animation(b: BufferBuilder, root: int, middle: int, tip: int) -> dict:
    t = b.add(np.array([0.0, 0.5, 1.0], np.float32), FLOAT, "SCALAR", minmax=True)
    outs = [
        (root, "translation", [[0, 0, 0], [0.1, 0.0, -0.05], [0.0, 0.08, 0.1]], "VEC3"),
        (root, "rotation", [_quat((0, 1, 0), a) for a in (0, 25, -15)], "VEC4"),
        (middle, "rotation", [_quat((0, 0, 1), a) for a in (0, 40, 70)], "VEC4"),
        (tip, "rotation", [_quat((1, 0, 0), a) for a in (0, -45, 30)], "VEC4"),
    ]
    samplers, channels = [], []
    for k, (node, path, values, gtype) in enumerate(outs):
        samplers.append({"input": t, "output": b.add(np.array(values, np.float32), FLOAT, gtype),
                         "interpolation": "LINEAR"})
        channels.append({"sampler": k, "target": {"node": node, "path": path}})
    return {"name": "bend", "samplers": samplers, "channels": channels}


def _primitive(b: BufferBuilder, v: np.ndarray, f: np.ndarray, joints=None, weights=None,
               extra: dict | None = None) -> dict:
    attrs = {"POSITION": b.add(v.astype(np.float32), FLOAT, "VEC3", target=34962, minmax=True)}
    if joints is not None:
        attrs["JOINTS_0"] = b.add(joints, UNSIGNED_BYTE, "VEC4", target=34962)
        attrs["WEIGHTS_0"] = b.add(weights, FLOAT, "VEC4", target=34962)
    for name, (arr, ctype) in (extra or {}).items():
        attrs[name] = b.add(arr, ctype, "VEC4", target=34962)
    return {"attributes": attrs, "indices": b.add(f.reshape(-1).astype(np.uint16),
                                                  UNSIGNED_SHORT, "SCALAR", target=34963),
            "mode": 4}


def _ibm(b: BufferBuilder, mats: list[np.ndarray]) -> int:
    return b.add(np.stack([m.T for m in mats]).reshape(-1, 16).astype(np.float32), FLOAT, "MAT4")


def _skeleton_nodes() -> list[dict]:
    """Nodes 1..4: armature (placed by ARMATURE) → root → middle → tip."""
    return [{"name": "armature", "children": [2], **ARMATURE},
            {"name": "root", "children": [3]},
            {"name": "middle", "translation": [0.0, STEP, 0.0], "children": [4]},
            {"name": "tip", "translation": [0.0, STEP, 0.0]}]


def _finish(path, b: BufferBuilder, doc: dict) -> None:
    blob = b.finish()
    doc.update({"asset": {"version": "2.0"}, "scene": 0, "accessors": b.accessors,
                "bufferViews": b.views, "buffers": [{"byteLength": len(blob)}]})
    path.write_bytes(pack_glb(doc, blob))


def robot(path, *, joints_1: str | None = None, bent: bool = False) -> None:
    """One skinned node (with a transform glTF ignores) drawing a tube in two primitives
    that share one skin; the skeleton hangs under a rotated, moved armature node, so what
    glTF draws at rest is ARMATURE · POSITION (the inverse bind matrices leave it out)."""
    v, f = tube(7, 8, 0.2, H)
    j, w = _tube_weights(v)
    b = BufferBuilder()
    extra = None
    if joints_1 is not None:
        w1 = np.zeros((len(v), 4), np.float32)
        if joints_1 == "used":
            w1[:, 0] = 0.1
            w = (w * 0.9).astype(np.float32)
        extra = {"JOINTS_1": (np.zeros((len(v), 4), np.uint8), UNSIGNED_BYTE),
                 "WEIGHTS_1": (w1, FLOAT)}
    # rings 0..3 and rings 3..6: two primitives (ring 3 in both)
    lower = _primitive(b, v[:32], f[:48], j[:32], w[:32], extra and {
        k: (a[:32], c) for k, (a, c) in extra.items()})
    upper = _primitive(b, v[24:], f[48:] - 24, j[24:], w[24:], extra and {
        k: (a[24:], c) for k, (a, c) in extra.items()})
    ibm = _ibm(b, [_matrix((0, -y, 0)) for y in (0.0, STEP, 2 * STEP)])
    skeleton = _skeleton_nodes()
    if bent:   # the skeleton's rest (node values) is not the pose it was bound in
        skeleton[2]["rotation"] = _quat((0, 0, 1), 35)
    doc = {"scenes": [{"nodes": [0, 1]}],
           "nodes": [{"name": "robot", "mesh": 0, "skin": 0, **BODY_NODE}, *skeleton],
           "meshes": [{"name": "robot", "primitives": [lower, upper]}],
           "skins": [{"joints": [2, 3, 4], "inverseBindMatrices": ibm}],
           "animations": [_animation(b, 2, 3, 4)]}
    _finish(path, b, doc)


def knight(path) -> None:
    """A body skinned to three joints (node transform ignored), a visor skinned by its own
    skin to the tip joint (a joint both skins share, with another inverse bind matrix) and a
    helmet plume with no skin, a child of the tip joint (it follows it rigidly)."""
    v, f = tube(7, 8, 0.2, H)
    j, w = _tube_weights(v)
    b = BufferBuilder()
    body = _primitive(b, v, f, j, w)
    armature = _matrix(ARMATURE["translation"], ARMATURE["rotation"])
    tip_rest = armature @ _matrix((0, 2 * STEP, 0))
    vv, vf = tube(2, 6, 0.25, 0.1, center=(0.0, 2 * STEP + 0.2, 0.0))
    vv = vv @ armature[:3, :3].T + armature[:3, 3]          # the visor at rest, as drawn
    visor = _primitive(b, vv, vf, np.zeros((len(vv), 4), np.uint8),
                       np.tile(np.float32([1, 0, 0, 0]), (len(vv), 1)))
    pv, pf = tube(3, 5, 0.05, 0.2)
    plume = _primitive(b, pv, pf)
    nodes = [{"name": "body", "mesh": 0, "skin": 0, **BODY_NODE}, *_skeleton_nodes(),
             {"name": "visor", "mesh": 1, "skin": 1, "translation": [0.0, -7.0, 0.0]},
             {"name": "plume", "mesh": 2, "translation": [0.0, 0.3, 0.0],
              "rotation": _quat((0, 0, 1), 20)}]
    nodes[4]["children"] = [6]
    doc = {"scenes": [{"nodes": [0, 1, 5]}], "nodes": nodes,
           "meshes": [{"name": "body", "primitives": [body]},
                      {"name": "visor", "primitives": [visor]},
                      {"name": "plume", "primitives": [plume]}],
           "skins": [{"joints": [2, 3, 4], "inverseBindMatrices": _ibm(
               b, [_matrix((0, -y, 0)) for y in (0.0, STEP, 2 * STEP)])},
                     {"joints": [4], "inverseBindMatrices": _ibm(b, [np.linalg.inv(tip_rest)])}],
           "animations": [_animation(b, 2, 3, 4)]}
    _finish(path, b, doc)


def _parts(g) -> list[tuple[int, int]]:
    """(node, primitive) of every triangle primitive the file's nodes draw."""
    return [(i, p) for i, n in enumerate(g.nodes) if n.mesh is not None
            for p in range(len(g.meshes[n.mesh].primitives))]


def _faces(g, node: int, p: int) -> np.ndarray:
    from helpers import gltf_accessor

    return gltf_accessor(g, g.meshes[g.nodes[node].mesh].primitives[p].indices).reshape(-1, 3)


def _drawn(g, parts, animation: int | None, t: float = 0.0) -> np.ndarray:
    return np.concatenate([numpy_skinning(g, n, t, animation, p) for n, p in parts])


def _order(g, anchor_rest: np.ndarray) -> list[tuple[int, int]]:
    """The order in which the converter concatenated the parts: the one whose drawn rest
    is the anchor mesh's (checked, not assumed)."""
    for parts in itertools.permutations(_parts(g)):
        rest = _drawn(g, parts, None)
        if rest.shape == anchor_rest.shape and np.allclose(rest, anchor_rest, atol=1e-5):
            return list(parts)
    raise AssertionError("the anchor mesh is not the drawn rest of the parts in any order")


def _splats_on_drawn_rest(g, path, n: int = 400):
    parts = _parts(g)
    rest = _drawn(g, parts, None)
    faces, offset = [], 0
    for node, p in parts:
        faces.append(_faces(g, node, p) + offset)
        offset += len(numpy_skinning(g, node, 0.0, None, p))
    cloud = surface_splats(TriangleMesh(rest, np.concatenate(faces).astype(np.uint32)), n, 3,
                           offset=0.0)
    gv.write(SplatAsset([SplatPrimitive(cloud, None, "character")]), path)


def _check_character(src, tmp_path) -> None:
    g = pygltflib.GLTF2().load(str(src))
    _splats_on_drawn_rest(g, tmp_path / "splats.glb")
    out = tmp_path / "out.glb"
    with warnings.catch_warnings():
        warnings.simplefilter("error", MeshFitWarning)   # the splats fit the drawn surface
        summary = gv.convert(tmp_path / "splats.glb", out, mesh=str(src))
    assert not any("dropped" in note for note in summary.notes), summary.notes
    report = gv.validate(out)
    assert report.count(Severity.ERROR) == 0 and report.count(Severity.WARNING) == 0, \
        report.to_json()
    asset = gv.read(out)
    prim = asset.anchored[0]
    anchor_rest = prim.anchoring.mesh.vertices.astype(np.float64)
    parts = _order(g, anchor_rest)
    assert len(anchor_rest) == sum(len(numpy_skinning(g, n, 0.0, None, p)) for n, p in parts)

    o = pygltflib.GLTF2().load(str(out))
    users = [i for i, n in enumerate(o.nodes) if n.skin is not None]
    assert len(users) == 1 and len(o.skins) == 1 and len(o.animations) == 1
    # the written skin draws the stored positions at rest, as the spec asks
    np.testing.assert_allclose(numpy_skinning(o, users[0], 0.0, None), anchor_rest, atol=1e-5)
    diag = float(np.linalg.norm(np.ptp(anchor_rest, axis=0)))
    posed_dir = tmp_path / "posed"
    assert pose_main([str(out), "--times", *map(str, TIMES), "-o", str(posed_dir), "-q"]) == 0
    source_dir = tmp_path / "posed_source"
    assert pose_main([str(out), "--source", str(src), "--times", *map(str, TIMES), "-o",
                      str(source_dir), "-q"]) == 0
    for i, t in enumerate(TIMES):
        want = _drawn(g, parts, 0, t)                       # the source as glTF draws it
        assert np.abs(want - anchor_rest).max() > 0.01 * diag
        np.testing.assert_allclose(numpy_skinning(o, users[0], t), want, atol=1e-5 * diag)
        feet = anchor_foot_points(prim, want)
        for folder in (posed_dir, source_dir):
            posed = gv.read(folder / f"{out.stem}_f{i:04d}.ply").primitives[0].splats.means
            np.testing.assert_allclose(posed[:len(prim.splats)], feet, atol=1e-4 * diag)


def test_robot_of_two_primitives_with_a_node_transform(tmp_path):
    src = tmp_path / "robot.glb"
    robot(src)
    g = pygltflib.GLTF2().load(str(src))
    # independent rest: the armature places the skeleton; the body node's transform is ignored
    v, _ = tube(7, 8, 0.2, H)
    armature = _matrix(ARMATURE["translation"], ARMATURE["rotation"])
    want = v @ armature[:3, :3].T + armature[:3, 3]
    mesh = read_mesh(src)
    assert mesh.rig is not None and len(mesh.rig.joints) == 3
    np.testing.assert_allclose(np.concatenate([want[:32], want[24:]]), mesh.vertices, atol=1e-5)
    np.testing.assert_allclose(_drawn(g, _parts(g), None), mesh.vertices, atol=1e-5)
    _check_character(src, tmp_path)


def test_knight_of_two_skins_and_a_rigid_attachment(tmp_path):
    src = tmp_path / "knight.glb"
    knight(src)
    mesh = read_mesh(src)
    # the two skins merged (the shared tip joint once) plus the plume's own node
    assert mesh.rig is not None and len(mesh.rig.joints) == 4 and not mesh.rig.notes
    _check_character(src, tmp_path)


def test_splats_on_the_node_transformed_surface_get_a_fit_warning(tmp_path):
    """Splats made for ``node transform · POSITION`` (not what glTF draws) are far from the
    drawn rest surface: the fit check says so."""
    src = tmp_path / "robot.glb"
    robot(src)
    v, f = tube(7, 8, 0.2, H)
    node = _matrix(BODY_NODE["translation"], BODY_NODE["rotation"], BODY_NODE["scale"])
    wrong = v @ node[:3, :3].T + node[:3, 3]
    cloud = surface_splats(TriangleMesh(wrong, f), 300, 1, offset=0.0)
    gv.write(SplatAsset([SplatPrimitive(cloud, None, "robot")]), tmp_path / "splats.glb")
    with pytest.warns(MeshFitWarning):
        gv.convert(tmp_path / "splats.glb", tmp_path / "out.glb", mesh=str(src))


def test_more_than_four_influences_are_refused_in_one_line(tmp_path, capsys):
    src = tmp_path / "robot8.glb"
    robot(src, joints_1="used")
    _splats_on_drawn_rest(pygltflib.GLTF2().load(str(src)), tmp_path / "splats.glb", 100)
    assert convert_main([str(tmp_path / "splats.glb"), str(tmp_path / "out.glb"), "--mesh",
                         str(src), "-q"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(src) in err and "JOINTS_1" in err, err
    assert "Traceback" not in err and not (tmp_path / "out.glb").exists()


def test_an_unused_second_influence_set_is_accepted(tmp_path):
    src = tmp_path / "robot0.glb"
    robot(src, joints_1="zero")
    mesh = read_mesh(src)
    assert mesh.rig is not None and mesh.rig.joints_0 is not None


def test_morph_targets_on_two_nodes_are_refused(tmp_path):
    v, f = tube(3, 6, 0.2, 1.0)
    b = BufferBuilder()
    prims = []
    for _ in range(2):
        prim = _primitive(b, v, f)
        prim["targets"] = [{"POSITION": b.add(np.full((len(v), 3), 0.1, np.float32), FLOAT,
                                              "VEC3", minmax=True)}]
        prims.append(prim)
    doc = {"scenes": [{"nodes": [0, 1]}],
           "nodes": [{"name": "a", "mesh": 0}, {"name": "b", "mesh": 1,
                                                "translation": [1.0, 0, 0]}],
           "meshes": [{"primitives": [prims[0]], "weights": [0.0]},
                      {"primitives": [prims[1]], "weights": [0.0]}]}
    src = tmp_path / "faces.glb"
    _finish(src, b, doc)
    with pytest.raises(FormatError, match="morph targets on 2 nodes") as info:
        read_mesh(src)
    assert str(src) in str(info.value)


def test_a_rest_pose_that_is_not_the_bind_pose_is_rebound_with_a_note(tmp_path):
    src = tmp_path / "bent.glb"
    robot(src, bent=True)
    g = pygltflib.GLTF2().load(str(src))
    mesh = read_mesh(src)
    np.testing.assert_allclose(_drawn(g, _parts(g), None), mesh.vertices, atol=1e-5)
    assert mesh.rig is not None and any("rebound" in n for n in mesh.rig.notes)
    _splats_on_drawn_rest(g, tmp_path / "splats.glb", 200)
    summary = gv.convert(tmp_path / "splats.glb", tmp_path / "out.glb", mesh=str(src))
    assert any("bent: " in n and "rebound" in n for n in summary.notes), summary.notes
    o = pygltflib.GLTF2().load(str(tmp_path / "out.glb"))
    anchor = [i for i, n in enumerate(o.nodes) if n.skin is not None][0]
    rest = gv.read(tmp_path / "out.glb").anchored[0].anchoring.mesh.vertices
    np.testing.assert_allclose(numpy_skinning(o, anchor, 0.0, None), rest, atol=1e-5)
