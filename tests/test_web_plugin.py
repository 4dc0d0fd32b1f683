"""The web engine plugin (``plugins/web``): its Node tests, the conformance suite through the
CPU path in Node and through the GPU shader in headless Chromium at both levels (numbers and
rendered pictures), deliberately broken shaders, render wrappers and sorting that the suite must
catch, and the demo's stretch/twist screenshots.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from gsverse_format.conformance.check import check_results
from gsverse_format.conformance.export import export_suite
from gsverse_format.conformance.harness import suite_cases
from gsverse_format.conformance.render_check import read_rgb, score_frame
from web_tools import DEMO, ROOT, WEB, artifacts_dir, require_web_tools, run_node, time_scale


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
    scale = time_scale()
    proc = subprocess.run(["npm", "test", "--silent"], cwd=WEB, capture_output=True, text=True,
                          timeout=900 * scale, check=False,
                          env=dict(os.environ, GSVERSE_TIME_SCALE=f"{scale:.2f}",
                                   GSVERSE_PYTHON=sys.executable))   # test/spz_fixtures.py
    assert proc.returncode == 0, _explain(proc)
    assert "# fail 0" in proc.stdout, _explain(proc)
    assert "# skipped 0" in proc.stdout, _explain(proc)


def test_plugin_types_check():
    require_web_tools()
    proc = subprocess.run(["npm", "run", "typecheck", "--silent"], cwd=WEB, capture_output=True,
                          text=True, timeout=300 * time_scale(), check=False)
    assert proc.returncode == 0, _explain(proc)


def test_cpu_path_passes_every_case_in_node(suite, tmp_path):
    require_web_tools()
    results = tmp_path / "results"
    proc = run_node(["conformance/run-node.mjs", suite, results])
    assert proc.returncode == 0, _explain(proc)
    report = check_results(suite, results, level="numbers")
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
    report = check_results(suite, gpu_results, level="numbers")
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
    proc = run_node(["conformance/run-browser.mjs", suite, results, "--fault", fault, "--level", "numbers"])
    assert proc.returncode == 0, _explain(proc)
    report = check_results(suite, results, level="numbers")
    assert _failed(report) == _tagged(manifests, f"profile:{profile}") - _tagged(manifests, "invalid")
    assert (report.harness or {}).get("fault") == fault, report.harness


def test_plugin_passes_every_render_case_in_chromium(suite, gpu_results):
    """The render level: the engine's pictures of every frame of every render case (remap in
    the work-buffer pass, splats sorted by the engine, node transforms, plain splats, the file's
    animation) against the reference pictures."""
    report = check_results(suite, gpu_results, level="render")
    assert report.summary["render"] == len(json.loads((suite / "suite.json").read_text())["render_cases"]) >= 7
    assert report.ok, [(c.id, c.message) for c in report.cases if c.status != "pass"]
    worst = min(f.psnr_db for c in report.cases for f in c.frames)
    assert worst >= 22.0, worst
    assert (gpu_results / "render-turn-180" / "frame_002.png").is_file()
    # the skinned character's frames at two animation times differ as the reference's do (and
    # each matches its reference, above): the plugin plays the file's animation
    engine = gpu_results / "render-skinned"
    ref = suite / "cases" / "render-skinned" / "reference"
    th = json.loads((suite / "cases" / "render-skinned" / "case.json").read_text())["thresholds"]
    for a, b in ((0, 1), (1, 2)):
        moved = score_frame(read_rgb(engine / f"frame_00{a}.png"), read_rgb(engine / f"frame_00{b}.png"), th)
        expected = score_frame(read_rgb(ref / f"frame_00{a}.png"), read_rgb(ref / f"frame_00{b}.png"), th)
        assert expected.iou < 0.7 and moved.iou < 0.7, (a, b, moved, expected)
        assert abs(moved.iou - expected.iou) < 0.1, (a, b, moved, expected)


#: What each deliberately broken render variant must fail (at least), and may fail besides.
_RENDER_FAULTS = {
    # splats sorted by their rest positions: the turned and folded sheets show the wrong side;
    # a twisted or bent tube may too
    "rest-sort": ({"render-turn-180", "render-fold"},
                  {"render-node-transforms", "render-plain-and-anchored", "render-skinned",
                   "render-spz-turn"}),
    # scales handed over as (y, x, z): every anisotropic splat turns
    "scale-swizzle": ({"render-packing", "render-sliver-stretched"},
                      {"render-node-transforms", "render-plain-and-anchored", "render-skinned",
                       "render-fold", "render-turn-180", "render-spz-turn"}),
    # the splat node's transform ignored: only the case with a transformed splat node
    "node-transform": ({"render-node-transforms"}, set()),
}


@pytest.mark.parametrize("fault", sorted(_RENDER_FAULTS))
def test_broken_render_variants_fail_their_cases(suite, tmp_path, fault):
    """A broken render wrapper (scales packed as y, x, z), a sort by rest positions and an
    ignored splat node transform each fail the render cases built to show them, while the
    numbers of the remap (read back from the GPU) stay right."""
    require_web_tools(browser=True)
    results = tmp_path / "results"
    proc = run_node(["conformance/run-browser.mjs", suite, results, "--fault", fault, "--level", "render"])
    assert proc.returncode == 0, _explain(proc)
    report = check_results(suite, results, level="render")
    must, may = _RENDER_FAULTS[fault]
    failed = _failed(report)
    assert must <= failed, (fault, sorted(failed), [(c.id, c.message) for c in report.cases])
    assert failed <= must | may, (fault, sorted(failed - must - may))


@pytest.mark.parametrize("fault", ["spz-frame", "spz-sh-signs"])
def test_broken_spz_decoding_fails_exactly_the_cases_it_should(suite, manifests, tmp_path, fault):
    """A deliberately broken SPZ decoder (src/spz.js SPZ_FAULTS, shared by both engines and the
    CPU path): without the frame change every encoding:spz remap case fails, without the SH
    signs those with SH above degree 0; the refusals still pass."""
    require_web_tools()
    results = tmp_path / "results"
    proc = run_node(["conformance/run-node.mjs", suite, results, "--cases", "*spz*", "--fault", fault])
    assert proc.returncode == 0, _explain(proc)
    spz = _tagged(manifests, "encoding:spz")
    remaps = {cid for cid in spz if manifests[cid]["kind"] == "remap"}
    must = remaps if fault == "spz-frame" else {cid for cid in remaps if manifests[cid]["sh_degree"] > 0}
    report = check_results(suite, results, level="numbers")
    failed = {c.id for c in report.cases if c.status == "fail"}
    assert must and failed == must, (fault, sorted(failed ^ must))


def test_demo_physics_in_node():
    require_web_tools()
    proc = run_node(["--test", DEMO / "test" / "physics.test.mjs"], cwd=ROOT)
    assert proc.returncode == 0, _explain(proc)
    assert "# fail 0" in proc.stdout, _explain(proc)


@pytest.mark.parametrize("engine", ["playcanvas", "three"])
def test_demo_stretch_and_twist_screenshots(engine):
    """The demo in Chromium, on each engine (?engine=three: three.js + Spark): a scripted 1.5x
    pull grows the rendered splats' extent about 1.5x, twists turn them, nothing is blank or
    exploded; the PNGs stay as artifacts."""
    require_web_tools(browser=True)
    out = artifacts_dir("demo-screenshots" if engine == "playcanvas" else f"demo-screenshots-{engine}")
    proc = run_node([DEMO / "test" / "screenshots.mjs", out, "--engine", engine], cwd=ROOT)
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
