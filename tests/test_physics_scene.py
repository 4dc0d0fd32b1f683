"""Scenes with physics: ``gsverse-convert --physics ... --ground`` writes KHR_physics_rigid_bodies
and KHR_implicit_shapes as spec/README.md §Physics lays them out, the readers keep them, both
validators accept them, and bad requests are usage errors.

The scene is the physics example (:func:`gsverse_format.examples.make_physics_scene`): a box
``chair`` (rigid), a closed squashed sphere ``pillow`` (soft), a cylinder ``lamp`` (kinematic)
and a floor of plain splats.
"""
from __future__ import annotations

import json
import pathlib
import struct

import numpy as np
import pytest

import gsverse_format as gv
from gsverse_format.cli.convert import main
from gsverse_format.examples import (PHYSICS_SCENE_KINDS, make_physics_scene,
                                     physics_scene_arguments)
from gsverse_format.physics import GROUND_EXTENT, GROUND_THICKNESS, PHYSICS, SHAPES
from gsverse_format.validators import validate_file

ROOT = pathlib.Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "examples" / "web" / "scene.glb"
SHIPPED_INPUTS = ROOT / "examples" / "physics"


def _json(path: pathlib.Path) -> dict:
    data = path.read_bytes()
    (length,) = struct.unpack("<I", data[12:16])
    return json.loads(data[20:20 + length])


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """The example's inputs, converted with every object's kind by name and a ground; the
    folder, the output and the --json summary."""
    folder = tmp_path_factory.mktemp("physics")
    make_physics_scene(str(folder))
    out = folder / "scene.glb"
    import contextlib
    import io

    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        assert main(physics_scene_arguments(str(folder), str(out)) + ["--json"]) == 0
    return folder, out, json.loads(buffer.getvalue())


def test_object_nodes_carry_the_rigid_body_objects(scene):
    _, out, _ = scene
    doc = _json(out)
    nodes = {n["name"]: (i, n) for i, n in enumerate(doc["nodes"])}
    in_scene = set(doc["scenes"][doc["scene"]]["nodes"])
    motions = {"rigid": {}, "soft": {}, "kinematic": {"isKinematic": True}}
    for name, kind in PHYSICS_SCENE_KINDS.items():
        i, node = nodes[name]
        h, holder = nodes[f"{name} collider"]
        assert node["extensions"] == {PHYSICS: {"motion": motions[kind], "collider": {
            "geometry": {"node": h, "convexHull": True}}}}
        assert node["extras"] == {"gsverse": {"physics": kind}}
        assert i in in_scene and h not in in_scene
        assert set(holder) == {"name", "mesh"}  # identity transform, nothing else
        anchor = doc["meshes"][node["mesh"]]["primitives"][0]["extensions"][
            "KHR_gaussian_splatting"]["extensions"]["GSVERSE_gaussian_splatting_mesh_anchor"]
        assert doc["meshes"][holder["mesh"]]["extras"] == {
            "gsverse": {"collider": "hull", "for": anchor["mesh"]}}
    static = nodes["room static"][1]
    assert "extensions" not in static and "extras" not in static
    assert doc["extensionsUsed"][-2:] == [PHYSICS, SHAPES]
    assert "extensionsRequired" not in doc
    assert "physicsMaterials" not in json.dumps(doc)


def test_colliders_are_the_convex_hulls_of_the_anchor_meshes(scene):
    import manifold3d as m3d

    _, out, _ = scene
    asset = gv.read(out)
    assert len(asset.colliders) == 3
    for prim in asset.anchored:
        mesh = prim.anchoring.mesh
        (hull,) = [c.mesh for c in asset.colliders if c.anchor is mesh]
        volume = m3d.Manifold(m3d.Mesh(vert_properties=np.asarray(mesh.vertices, np.float32),
                                       tri_verts=np.asarray(mesh.faces, np.uint32))).volume()
        hull_volume = m3d.Manifold(m3d.Mesh(
            vert_properties=np.asarray(hull.vertices, np.float32),
            tri_verts=np.asarray(hull.faces, np.uint32))).volume()
        assert hull_volume >= volume * (1 - 1e-6) > 0, prim.name
        tri = hull.triangles().astype(np.float64)
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        # every anchor vertex on the inner side of every hull face (float32 rounding allowed)
        side = np.einsum("fk,vfk->vf", normal, mesh.vertices.astype(np.float64)[:, None] - tri[:, 0])
        assert side.max() <= 1e-5 * np.ptp(mesh.vertices, axis=0).max(), prim.name


def test_ground_box_is_under_the_lowest_splat(scene):
    _, out, summary = scene
    doc = _json(out)
    (g, node), = [(i, n) for i, n in enumerate(doc["nodes"]) if n["name"] == "ground"]
    assert g in doc["scenes"][0]["nodes"] and "mesh" not in node
    assert node["extensions"] == {PHYSICS: {"collider": {"geometry": {"shape": 0}}}}
    (shape,) = doc["extensions"][SHAPES]["shapes"]
    assert shape["type"] == "box"
    size, centre = np.array(shape["box"]["size"]), np.array(node["translation"])
    means = np.concatenate([p.splats.means for p in gv.read(out).primitives]).astype(np.float64)
    lo, hi = means.min(axis=0), means.max(axis=0)
    assert centre[1] + size[1] / 2 == pytest.approx(lo[1], abs=1e-9)
    assert size[1] == pytest.approx(GROUND_THICKNESS * np.linalg.norm(hi - lo))
    for axis, k in ((0, 0), (2, 2)):
        assert size[k] == pytest.approx(GROUND_EXTENT * (hi[axis] - lo[axis]))
        assert centre[axis] == pytest.approx((lo[axis] + hi[axis]) / 2)
    assert summary["ground"]["top"] == pytest.approx(lo[1], abs=1e-9)


def test_summary_names_each_body(scene):
    _, _, summary = scene
    assert [(b["name"], b["kind"], b["mass"], b["collider"]["kind"]) for b in summary["physics"]] \
        == [(n, k, None, "hull") for n, k in PHYSICS_SCENE_KINDS.items()]
    assert all(b["collider"]["faces"] > 0 for b in summary["physics"])


def test_round_trip_keeps_the_physics(scene, tmp_path):
    _, out, _ = scene
    first = gv.read(out)
    again = tmp_path / "again.glb"
    assert main([str(out), str(again), "-q"]) == 0   # glb -> glb keeps what it read
    second = gv.read(again)
    assert [(p.name, p.physics) for p in second.primitives] == \
        [(p.name, p.physics) for p in first.primitives]
    assert second.ground == first.ground
    for a, b in zip(first.colliders, second.colliders):
        np.testing.assert_array_equal(a.mesh.vertices, b.mesh.vertices)
        np.testing.assert_array_equal(a.mesh.faces, b.mesh.faces)
    strip = lambda d: [{k: v for k, v in n.items()} for n in d["nodes"]]  # noqa: E731
    assert strip(_json(again)) == strip(_json(out))
    assert _json(again)["extensions"] == _json(out)["extensions"]


def test_info_shows_the_physics(scene, capsys):
    from gsverse_format.cli.info import main as info_main

    _, out, _ = scene
    assert info_main([str(out)]) == 0
    text = capsys.readouterr().out
    for name, kind in PHYSICS_SCENE_KINDS.items():
        assert f"'{name}'" in text and f"physics {kind}" in text
    assert "  ground      static box" in text


def test_validators_accept_the_scene(scene):
    from khr_tools import require_node_tools, validate_gltf

    _, out, _ = scene
    assert validate_file(out).findings == []
    require_node_tools()
    report = validate_gltf(out)
    assert report["numUnexpectedErrors"] == 0, report["messages"][:5]
    others = {(m["code"], m["severity"]) for m in report["messages"]
              if not m["expectedKhrAttribute"]}
    # what the Khronos validator says besides its known KHR attribute-name complaint: it knows
    # none of the extensions, and sees the collider nodes (in no scene) and the anchor data
    # (read through the extension only) as unused
    assert others == {("UNSUPPORTED_EXTENSION", "Information"),
                      ("UNUSED_OBJECT", "Information")}
    unused = {m["pointer"] for m in report["messages"] if m["code"] == "UNUSED_OBJECT"}
    doc = _json(out)
    colliders = {f"/nodes/{i}" for i, n in enumerate(doc["nodes"])
                 if n["name"].endswith(" collider")}
    assert colliders <= unused


def _usage(capsys, *argv: str) -> str:
    try:
        status = main(list(argv))
    except SystemExit as exc:  # argparse's own usage errors
        status = exc.code
    assert status == 2
    return capsys.readouterr().err


@pytest.mark.parametrize("flags, says", [
    (["--physics", "jelly"], "unknown kind 'jelly'"),
    (["--physics", "rigid", "--physics", "soft"], "given 2 times for 3 objects"),
    (["--physics", "rigid", "--physics", "chair=soft"], "not both"),
    (["--physics", "sofa=rigid"], "no object is named 'sofa'"),
    (["--physics", "chair=rigid,chair=soft"], "given twice"),
    (["--physics", "chair="], "expected NAME=VALUE"),
    (["--physics", "static", "--mass", "chair=3"], "static physics"),
    (["--physics", "rigid", "--mass", "chair=-1"], "above 0"),
    (["--mass", "chair=1"], "--mass needs --physics"),
    (["--ground", "--no-frame-change"], "--no-frame-change"),
])
def test_bad_physics_requests_are_usage_errors(scene, capsys, flags, says):
    folder, _, _ = scene
    meshes = [a for n in PHYSICS_SCENE_KINDS for a in ("--mesh", str(folder / f"{n}.obj"))]
    err = _usage(capsys, str(folder / "room.ply"), str(folder / "bad.glb"), *meshes, *flags)
    assert says in err and err.count("\n") == 1, err
    assert not (folder / "bad.glb").exists()


@pytest.mark.parametrize("suffix", [".usda", ".ply"])
def test_physics_needs_gltf_output(scene, capsys, suffix):
    folder, _, _ = scene
    err = _usage(capsys, str(folder / "room.ply"), str(folder / f"bad{suffix}"), "--mesh",
                 str(folder / "chair.obj"), "--physics", "rigid")
    assert "glTF output (.glb, .gltf) only" in err


def test_kinds_in_mesh_order_and_masses(scene, tmp_path):
    folder, _, _ = scene
    out = tmp_path / "ordered.glb"
    args = [str(folder / "room.ply"), str(out), "-q", "--max-distance", "0.04"]
    for name in ("lamp", "chair", "pillow"):
        args += ["--mesh", str(folder / f"{name}.obj")]
    args += ["--physics", "static", "--physics", "rigid", "--physics", "soft",
             "--mass", "chair=4.5,pillow=0.5"]
    assert main(args) == 0
    nodes = {n["name"]: n for n in _json(out)["nodes"]}
    assert "motion" not in nodes["lamp"]["extensions"][PHYSICS]
    assert nodes["lamp"]["extras"] == {"gsverse": {"physics": "static"}}
    assert nodes["chair"]["extensions"][PHYSICS]["motion"] == {"mass": 4.5}
    assert nodes["pillow"]["extensions"][PHYSICS]["motion"] == {"mass": 0.5}
    assert "ground" not in nodes and SHAPES not in _json(out)["extensionsUsed"]
    assert {p.name: p.physics.mass for p in gv.read(out).anchored} == \
        {"lamp": None, "chair": 4.5, "pillow": 0.5}
    assert validate_file(out).findings == []


def test_named_kinds_leave_the_others_without_physics(scene, tmp_path):
    folder, _, _ = scene
    out = tmp_path / "one.glb"
    args = [str(folder / "room.ply"), str(out), "-q", "--max-distance", "0.04"]
    for name in PHYSICS_SCENE_KINDS:
        args += ["--mesh", str(folder / f"{name}.obj")]
    assert main(args + ["--physics", "pillow=soft"]) == 0
    doc = _json(out)
    assert [n["name"] for n in doc["nodes"] if "extensions" in n] == ["pillow"]
    assert len(gv.read(out).colliders) == 1  # no --collider: only the body gets a hull


def test_manifest_rows_take_physics_and_ground(tmp_path):
    src = ROOT / "examples" / "capsule"
    manifest = tmp_path / "assets.csv"
    manifest.write_text("input,mesh,output,physics,mass,ground\n"
                        f"{src / 'splats.ply'},{src / 'mesh.obj'},soft.glb,soft,mesh=3,yes\n"
                        f"{src / 'splats.ply'},{src / 'mesh.obj'},plain.glb,,,\n")
    out = tmp_path / "out"
    assert main([str(manifest), "--output-dir", str(out), "-q", "-j", "1"]) == 0
    soft = _json(out / "soft.glb")
    assert soft["nodes"][0]["extensions"][PHYSICS]["motion"] == {"mass": 3.0}
    assert soft["nodes"][0]["extras"] == {"gsverse": {"physics": "soft"}}
    assert any(n.get("name") == "ground" for n in soft["nodes"])
    plain = _json(out / "plain.glb")
    assert PHYSICS not in plain["extensionsUsed"]


def test_shipped_physics_example_is_what_the_builder_and_converter_write(tmp_path):
    """examples/physics/ is what ``python -m gsverse_format.examples --physics-scene`` writes,
    and examples/web/scene.glb is its conversion by today's converter."""
    hint = ("examples/web/scene.glb is stale: regenerate it with python -m gsverse_format."
            "examples --physics-scene examples/physics && gsverse-convert -w "
            "examples/physics/room.ply examples/web/scene.glb --mesh examples/physics/chair.obj "
            "--mesh examples/physics/pillow.obj --mesh examples/physics/lamp.obj "
            "--max-distance 0.04 --physics chair=rigid,pillow=soft,lamp=kinematic --ground "
            "--anchors compact")
    made = make_physics_scene(str(tmp_path / "in"))
    for path in made:
        name = pathlib.Path(path).name
        assert (SHIPPED_INPUTS / name).read_bytes() == pathlib.Path(path).read_bytes(), hint
    out = tmp_path / "scene.glb"
    assert main(physics_scene_arguments(str(SHIPPED_INPUTS), str(out)) + ["-q"]) == 0
    fresh, shipped = gv.read(out), gv.read(SHIPPED)
    assert len(fresh.primitives) == len(shipped.primitives) == 4, hint
    for a, b in zip(fresh.primitives, shipped.primitives):
        assert (a.name, a.physics) == (b.name, b.physics), hint
        for field in ("means", "rotations", "scales", "opacities", "sh"):
            np.testing.assert_array_equal(getattr(a.splats, field), getattr(b.splats, field),
                                          err_msg=hint)
        if a.anchoring is not None:
            np.testing.assert_array_equal(a.anchoring.mesh.vertices, b.anchoring.mesh.vertices,
                                          err_msg=hint)
            np.testing.assert_array_equal(a.anchoring.anchors.face_index,
                                          b.anchoring.anchors.face_index, err_msg=hint)
    assert fresh.ground == shipped.ground, hint
    assert [n for n in _json(out)["nodes"]] == [n for n in _json(SHIPPED)["nodes"]], hint
