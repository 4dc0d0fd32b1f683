"""The web demo runs its physics scene (``examples/web/scene.glb``, the converter's physics example:
``tests/test_physics_scene.py`` checks the file): dropped, the rigid chair falls onto the ground
box and rests, the kinematic lamp stays, the soft pillow lands and stretches when pulled, the
background stays put; in Node (``rigid.test.mjs``) and in headless Chromium (``scene.mjs``), with
fixed physics steps only.
"""

from __future__ import annotations

import json
import subprocess

from web_tools import DEMO, ROOT, artifacts_dir, require_web_tools, run_node


def _explain(proc: subprocess.CompletedProcess) -> str:
    return f"exit {proc.returncode}\n--- stdout\n{proc.stdout[-6000:]}\n--- stderr\n{proc.stderr[-4000:]}"


def test_the_scene_in_node():
    """rigid.test.mjs: the scene's objects in one Jolt world, fixed steps: lifted, the chair falls
    and rests on the ground, the lamp stays, the pillow lands; a grabbed chair is thrown."""
    require_web_tools()
    proc = run_node(["--test", DEMO / "test" / "rigid.test.mjs"], cwd=ROOT)
    assert proc.returncode == 0, _explain(proc)
    assert "# fail 0" in proc.stdout and "# skipped 0" in proc.stdout, _explain(proc)


def test_the_scene_in_the_demo_falls_stretches_and_keeps_its_background():
    """scene.mjs in Chromium: dropped, after 240 fixed steps the chair's node fell and its hull
    rests on the ground, the lamp stayed, a scripted 1.5x pull stretched the pillow (anchor mesh
    and pixels), the background did not change; the PNGs stay as artifacts."""
    require_web_tools(browser=True)
    out = artifacts_dir("demo-physics-scene")
    proc = run_node([DEMO / "test" / "scene.mjs", out], cwd=ROOT)
    assert proc.returncode == 0, _explain(proc)
    checks = json.loads((out / "results.json").read_text())["checks"]
    names = {c["name"] for c in checks if c["ok"]}
    assert len(names) == len(checks) >= 13, checks
    assert {"the rigid chair fell", "the chair rests on the ground", "the background stayed put",
            "in the picture, the pillow stretched"} <= names, checks
    for png in ("scene-rest", "scene-dropped", "scene-settled", "scene-pulled"):
        assert (out / f"{png}.png").is_file(), png
