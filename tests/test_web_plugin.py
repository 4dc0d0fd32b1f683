"""The web engine plugin (``plugins/web``): its Node tests, the conformance suite through the
CPU path in Node and through the GPU shader in headless Chromium, a deliberately broken shader
that the suite must catch, and the demo's stretch/twist screenshots.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from gsverse_format.conformance.check import check_results
from gsverse_format.conformance.export import export_suite
from gsverse_format.conformance.harness import suite_cases
from web_tools import DEMO, ROOT, WEB, artifacts_dir, require_web_tools, run_node


@pytest.fixture(scope="module")
def suite(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("web-conformance") / "suite"
    export_suite(path)
    return path


@pytest.fixture(scope="module")
def manifests(suite) -> dict[str, dict]:
    return {m["id"]: m for _, m in suite_cases(suite)}


def _tagged(manifests: dict[str, dict], tag: str) -> set[str]:
    return {cid for cid, m in manifests.items() if tag in m["tags"]}


def _failed(report) -> set[str]:
    return {c.id for c in report.cases if c.status != "pass"}


def _explain(proc: subprocess.CompletedProcess) -> str:
    return f"exit {proc.returncode}\n--- stdout\n{proc.stdout[-4000:]}\n--- stderr\n{proc.stderr[-4000:]}"


def test_node_unit_tests_pass():
    require_web_tools(browser=True)
    proc = subprocess.run(["npm", "test", "--silent"], cwd=WEB, capture_output=True, text=True,
                          timeout=600, check=False)
    assert proc.returncode == 0, _explain(proc)
    assert "# fail 0" in proc.stdout, _explain(proc)
    assert "# skipped 0" in proc.stdout, _explain(proc)


def test_plugin_types_check():
    require_web_tools()
    proc = subprocess.run(["npm", "run", "typecheck", "--silent"], cwd=WEB, capture_output=True,
                          text=True, timeout=300, check=False)
    assert proc.returncode == 0, _explain(proc)


def test_cpu_path_passes_every_case_in_node(suite, tmp_path):
    require_web_tools()
    results = tmp_path / "results"
    proc = run_node(["conformance/run-node.mjs", suite, results])
    assert proc.returncode == 0, _explain(proc)
    report = check_results(suite, results)
    assert report.ok, [(c.id, c.message) for c in report.cases if c.status != "pass"]
    assert report.summary["total"] == len(json.loads((suite / "suite.json").read_text())["cases"])
    assert report.harness and report.harness.get("engine")


@pytest.fixture(scope="module")
def gpu_results(suite, tmp_path_factory) -> Path:
    require_web_tools(browser=True)
    results = tmp_path_factory.mktemp("web-gpu") / "results"
    proc = run_node(["conformance/run-browser.mjs", suite, results])
    assert proc.returncode == 0, _explain(proc)
    return results


def test_gpu_shader_passes_every_case_in_chromium(suite, gpu_results):
    report = check_results(suite, gpu_results)
    assert report.ok, [(c.id, c.message) for c in report.cases if c.status != "pass"]
    harness = report.harness or {}
    # the run names its GPU backend (here Chromium's software rasterizer) and its engine
    assert harness.get("engine", "").lower().startswith("playcanvas"), harness
    assert harness.get("backend"), harness
    # the remap cases were read back from the GPU as rotation + scale pairs, as rendered
    case = next(c.id for c in report.cases if c.kind == "remap")
    assert (gpu_results / case / "pose_000.rotation.f32").is_file()


@pytest.mark.parametrize("fault, profile", [("frame-axis", "local"), ("games-axis", "games")])
def test_broken_shader_fails_exactly_the_cases_it_should(suite, manifests, tmp_path, fault, profile):
    """A deliberately broken shader (a wrong frame axis of one profile) fails every remap case
    of that profile and nothing else; refusals are unaffected."""
    require_web_tools(browser=True)
    results = tmp_path / "results"
    proc = run_node(["conformance/run-browser.mjs", suite, results, "--fault", fault])
    assert proc.returncode == 0, _explain(proc)
    report = check_results(suite, results)
    assert _failed(report) == _tagged(manifests, f"profile:{profile}") - _tagged(manifests, "invalid")
    assert (report.harness or {}).get("fault") == fault, report.harness


def test_demo_physics_in_node():
    require_web_tools()
    proc = run_node(["--test", DEMO / "test" / "physics.test.mjs"], cwd=ROOT)
    assert proc.returncode == 0, _explain(proc)
    assert "# fail 0" in proc.stdout, _explain(proc)


def test_demo_stretch_and_twist_screenshots():
    """The demo in Chromium: a scripted 1.5x pull grows the rendered splats' extent about 1.5x,
    twists turn them, nothing is blank or exploded; the PNGs stay as artifacts."""
    require_web_tools(browser=True)
    asset = ROOT / "examples" / "capsule" / "anchored.glb"
    if not asset.is_file():  # made by the README's first command; make it here otherwise
        from gsverse_format.api import convert

        convert(ROOT / "examples/capsule/splats.ply", asset, mesh=ROOT / "examples/capsule/mesh.obj")
    out = artifacts_dir("demo-screenshots")
    proc = run_node([DEMO / "test" / "screenshots.mjs", out], cwd=ROOT)
    assert proc.returncode == 0, _explain(proc)
    results = json.loads((out / "results.json").read_text())
    assert results, results
    assert sorted(p.name for p in out.glob("*.png")), "no screenshots stored"


def test_conformance_guide_shows_the_shader_the_plugin_runs():
    """spec/conformance.md lays out the GLSL remap chunk for porting: it must be the plugin's."""
    require_web_tools()
    proc = run_node(["--input-type=module", "-e",
                     "import {remapChunkGLSL} from './src/playcanvas/shader.js';"
                     "process.stdout.write(remapChunkGLSL())"])
    assert proc.returncode == 0, _explain(proc)
    guide = (ROOT / "spec" / "conformance.md").read_text(encoding="utf-8")
    section = guide.split("### Web (PlayCanvas): the worked example", 1)[1]
    listing = section.split("```glsl\n", 1)[1].split("\n```", 1)[0]
    assert listing.strip("\n") == proc.stdout.strip("\n")
