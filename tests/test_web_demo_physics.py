"""The web demo's physics scene (``examples/web/scene.glb``): the shipped file is what its documented
command writes, it validates, and the demo runs it — the rigid chair falls onto the ground box and
rests, the kinematic lamp stays, the soft pillow lands and stretches when pulled, the background
stays put — in Node (``rigid.test.mjs``) and in headless Chromium (``scene.mjs``), with fixed
physics steps only.
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from web_tools import DEMO, ROOT, artifacts_dir, require_web_tools, run_node

SCENE = DEMO / "scene.glb"
COMMAND = "python examples/web/make_scene.py examples/web/scene.glb"
PHYSICS = ("KHR_physics_rigid_bodies", "KHR_implicit_shapes")


def _explain(proc: subprocess.CompletedProcess) -> str:
    return f"exit {proc.returncode}\n--- stdout\n{proc.stdout[-6000:]}\n--- stderr\n{proc.stderr[-4000:]}"


def _make_scene():
    spec = importlib.util.spec_from_file_location("make_scene", DEMO / "make_scene.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _json(path: Path) -> dict:
    from gsverse_format.io.gltf.container import parse_glb

    return json.loads(bytes(parse_glb(path.read_bytes())[0]))


def test_the_shipped_scene_is_what_its_command_writes(tmp_path):
    """examples/web/scene.glb is what `python examples/web/make_scene.py` writes today: the same
    splats, anchor meshes and anchors, and the same physics records."""
    import gsverse_format as gv

    out = tmp_path / "scene.glb"
    _make_scene().build(str(out))
    hint = f"examples/web/scene.glb is stale: regenerate it with {COMMAND}"
    fresh, shipped = gv.read(out), gv.read(SCENE)
    assert [p.name for p in fresh.primitives] == [p.name for p in shipped.primitives], hint
    for a, b in zip(fresh.primitives, shipped.primitives):
        for field in ("means", "rotations", "scales", "opacities", "sh"):
            np.testing.assert_array_equal(getattr(a.splats, field), getattr(b.splats, field), err_msg=hint)
        assert (a.anchoring is None) == (b.anchoring is None), hint
        if a.anchoring is not None:
            np.testing.assert_array_equal(a.anchoring.mesh.vertices, b.anchoring.mesh.vertices, err_msg=hint)
            np.testing.assert_array_equal(a.anchoring.mesh.faces, b.anchoring.mesh.faces, err_msg=hint)
            np.testing.assert_array_equal(a.anchoring.anchors.face_index, b.anchoring.anchors.face_index, err_msg=hint)
    fj, sj = _json(out), _json(SCENE)
    assert fj["nodes"] == sj["nodes"], hint
    assert fj.get("extensions") == sj.get("extensions"), hint
    assert fj["scenes"] == sj["scenes"], hint


def test_the_scene_holds_the_objects_by_kind_and_a_ground_under_them():
    """The shipped scene: chair rigid, pillow soft, lamp kinematic, each with a convex-hull
    collider node outside the scene; a `ground` box whose top face is at the scene's lowest
    point; plain background splats; small (under 1 MB); no validation errors."""
    import gsverse_format as gv

    assert SCENE.stat().st_size < 1_000_000
    doc = _json(SCENE)
    nodes = doc["nodes"]
    in_scene = set(doc["scenes"][doc.get("scene", 0)]["nodes"])
    kinds = {n["name"]: n["extras"]["gsverse"]["physics"] for n in nodes if "extras" in n}
    assert kinds == {"chair": "rigid", "pillow": "soft", "lamp": "kinematic"}
    for node in nodes:
        record = node.get("extensions", {}).get(PHYSICS[0])
        if record is None or node.get("name") == "ground":
            continue
        hull = record["collider"]["geometry"]
        assert hull["convexHull"] is True and hull["node"] not in in_scene
        assert ("motion" in record) and (record["motion"].get("isKinematic", False) == (node["name"] == "lamp"))
    ground = next(n for n in nodes if n.get("name") == "ground")
    shape = doc["extensions"][PHYSICS[1]]["shapes"][ground["extensions"][PHYSICS[0]]["collider"]["geometry"]["shape"]]
    assert shape["type"] == "box"
    top = ground["translation"][1] + shape["box"]["size"][1] / 2
    asset = gv.read(SCENE)
    lowest = min(float(p.splats.means[:, 1].min()) for p in asset.primitives)
    assert top == pytest.approx(lowest, abs=1e-6)
    assert [p.anchoring is None for p in asset.primitives] == [False, False, False, True]
    report = gv.validate(SCENE)
    assert report.exit_status == 0, report.findings


def test_the_scene_in_node():
    """rigid.test.mjs: the scene's objects in one Jolt world, fixed steps: the chair falls and
    rests on the ground, the lamp stays, the pillow lands, a grabbed chair is thrown."""
    require_web_tools()
    proc = run_node(["--test", DEMO / "test" / "rigid.test.mjs"], cwd=ROOT)
    assert proc.returncode == 0, _explain(proc)
    assert "# fail 0" in proc.stdout and "# skipped 0" in proc.stdout, _explain(proc)


def test_the_scene_in_the_demo_falls_stretches_and_keeps_its_background():
    """scene.mjs in Chromium: after 240 fixed steps the chair's node dropped and its hull rests on
    the ground, the lamp stayed, a scripted 1.5x pull stretched the pillow (anchor mesh and
    pixels), the background did not change; the PNGs stay as artifacts."""
    require_web_tools(browser=True)
    out = artifacts_dir("demo-physics-scene")
    proc = run_node([DEMO / "test" / "scene.mjs", out], cwd=ROOT)
    assert proc.returncode == 0, _explain(proc)
    checks = json.loads((out / "results.json").read_text())["checks"]
    names = {c["name"] for c in checks if c["ok"]}
    assert len(names) == len(checks) >= 12, checks
    assert {"the rigid chair fell", "the chair rests on the ground", "the background stayed put",
            "in the picture, the pillow stretched"} <= names, checks
    for png in ("scene-rest", "scene-settled", "scene-pulled"):
        assert (out / f"{png}.png").is_file(), png
