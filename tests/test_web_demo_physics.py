"""The web plugin reads physics records as ``gsverse-validate`` judges them (``readPhysics`` refuses
each error of the physics triggering assets with the validator's code and reads the clean ones),
and the web demo runs its physics scene (``examples/web/scene.glb``, the converter's physics example:
``tests/test_physics_scene.py`` checks the file): dropped, the rigid chair falls onto the ground
box and rests, the kinematic lamp stays, the soft pillow lands and stretches when pulled, the
background stays put; in Node (``rigid.test.mjs``) and in headless Chromium (``scene.mjs``), with
fixed physics steps only.
"""

from __future__ import annotations

import json
import subprocess

import pytest

import validation_assets as va
from gsverse_format.io.gltf import asset_to_gltf, gltf_to_bytes
from web_tools import DEMO, ROOT, WEB, artifacts_dir, require_web_tools, run_node

#: the physics errors of the validator (PHYSICS_KIND_MISMATCH is a warning: the reader follows
#: the rigid-body object)
PHYSICS_ERRORS = ("PHYSICS_GEOMETRY_INVALID", "PHYSICS_SHAPE_INVALID", "PHYSICS_MOTION_INVALID",
                  "PHYSICS_KIND_UNKNOWN", "PHYSICS_SOFT_NOT_ANCHORED")
#: readPhysics on each file named on the command line: its kinds, or the refusal's code
READ = ("import fs from 'node:fs'; import { readPhysics } from './src/index.js';"
        "for (const f of process.argv.slice(1)) { let r;"
        " try { const p = readPhysics(fs.readFileSync(f), { name: f });"
        " r = { kinds: p.objects.map((o) => o.kind), shapes: p.shapes.map((g) => g.type) }; }"
        " catch (e) { r = { code: e.code ?? String(e) }; }"
        " console.log(JSON.stringify(r)); }")


def _explain(proc: subprocess.CompletedProcess) -> str:
    return f"exit {proc.returncode}\n--- stdout\n{proc.stdout[-6000:]}\n--- stderr\n{proc.stderr[-4000:]}"


def _read_physics(paths) -> list[dict]:
    proc = run_node(["--input-type=module", "-e", READ, *paths], cwd=WEB)
    assert proc.returncode == 0, _explain(proc)
    return [json.loads(line) for line in proc.stdout.splitlines()]


@pytest.mark.parametrize("kind", ["rigid", "soft", "kinematic", "static"])
def test_read_physics_reads_what_the_writer_writes(tmp_path, kind):
    """A one-object asset of each kind, as the converter's writer writes it, over a ground box."""
    require_web_tools()
    path = tmp_path / f"{kind}.glb"
    path.write_bytes(gltf_to_bytes(asset_to_gltf(va.physics_asset(kind))))
    assert _read_physics([path]) == [{"kinds": [kind], "shapes": ["box"]}]


def test_read_physics_refuses_what_the_validator_calls_an_error(tmp_path):
    """readPhysics refuses each physics error's triggering asset with the validator's code."""
    require_web_tools()
    paths = [va.TRIGGERS[code](tmp_path).path for code in PHYSICS_ERRORS]
    assert [r.get("code") for r in _read_physics(paths)] == list(PHYSICS_ERRORS)


def test_the_scene_in_node():
    """rigid.test.mjs: the scene's objects in one Jolt world, fixed steps: lifted, the chair falls
    and rests on the ground, the lamp stays, the pillow lands; a grabbed chair is thrown."""
    require_web_tools()
    proc = run_node(["--test", DEMO / "test" / "rigid.test.mjs"], cwd=ROOT)
    assert proc.returncode == 0, _explain(proc)
    assert "# fail 0" in proc.stdout and "# skipped 0" in proc.stdout, _explain(proc)


@pytest.mark.parametrize("engine", ["playcanvas", "three"])
def test_the_scene_in_the_demo_falls_stretches_and_keeps_its_background(engine):
    """scene.mjs in Chromium, on each engine (?engine=three: three.js + Spark): dropped, after 240
    fixed steps the chair's node fell and its hull rests on the ground, the lamp stayed, a scripted
    1.5x pull stretched the pillow (anchor mesh and pixels), the background did not change; the
    PNGs stay as artifacts."""
    require_web_tools(browser=True)
    out = artifacts_dir("demo-physics-scene" if engine == "playcanvas" else f"demo-physics-scene-{engine}")
    proc = run_node([DEMO / "test" / "scene.mjs", out, "--engine", engine], cwd=ROOT)
    assert proc.returncode == 0, _explain(proc)
    checks = json.loads((out / "results.json").read_text())["checks"]
    names = {c["name"] for c in checks if c["ok"]}
    assert len(names) == len(checks) >= 13, checks
    assert {"the rigid chair fell", "the chair rests on the ground", "the background stayed put",
            "in the picture, the pillow stretched"} <= names, checks
    for png in ("scene-rest", "scene-dropped", "scene-settled", "scene-pulled"):
        assert (out / f"{png}.png").is_file(), png
