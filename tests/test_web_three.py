"""The three.js plugin of the web package (``plugins/web/src/three``: Spark's splats, the remap
as a Spark object modifier): the conformance suite through it in headless Chromium at both
levels (WebGL2; the numbers read back from the GPU by Spark's Readback, the render cases drawn
by Spark), and the deliberately broken variants the suite must catch, as
``tests/test_web_plugin.py`` does for the PlayCanvas plugin.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from gsverse_format.conformance.check import check_results
from gsverse_format.conformance.export import export_suite
from gsverse_format.conformance.harness import suite_cases
from gsverse_format.conformance.render_check import read_rgb, score_frame
from test_conformance_rig import _MUST_FAIL as _RIG_MUST_FAIL
from test_conformance_rig import RIG_IDS
from test_web_plugin import _RENDER_FAULTS
from web_tools import require_web_tools, run_node

#: the npm packages of plugins/web the three.js plugin needs besides the usual ones
THREE_PACKAGES = ("three", "@sparkjsdev/spark")


@pytest.fixture(scope="module")
def suite(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("web-three-conformance") / "suite"
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


def _run(suite: Path, results: Path, *extra: str) -> None:
    require_web_tools(browser=True, packages=THREE_PACKAGES)
    proc = run_node(["conformance/run-browser.mjs", suite, results, "--engine", "three", *extra])
    assert proc.returncode == 0, _explain(proc)


@pytest.fixture(scope="module")
def three_results(suite, tmp_path_factory) -> Path:
    results = tmp_path_factory.mktemp("web-three") / "results"
    _run(suite, results)
    return results


def test_three_plugin_passes_every_case_in_chromium(suite, three_results):
    report = check_results(suite, three_results, level="numbers")
    assert report.ok, [(c.id, c.message) for c in report.cases if c.status != "pass"]
    assert report.summary["total"] == len(json.loads((suite / "suite.json").read_text())["cases"])
    harness = report.harness or {}
    assert harness.get("engine", "").startswith("three.js + Spark"), harness
    assert "three.js plugin" in harness.get("name", ""), harness
    # the remap cases were read back from the GPU as rotation + scale pairs
    case = next(c.id for c in report.cases if c.kind == "remap")
    assert (three_results / case / "pose_000.rotation.f32").is_file()


@pytest.mark.parametrize("fault, profile", [("frame-axis", "local"), ("games-axis", "games")])
def test_broken_three_modifier_fails_exactly_the_cases_it_should(suite, manifests, tmp_path, fault, profile):
    """A deliberately broken remap in the Spark modifier (a wrong frame axis of one profile)
    fails every remap case of that profile and nothing else; refusals are unaffected."""
    results = tmp_path / "results"
    _run(suite, results, "--fault", fault, "--level", "numbers")
    report = check_results(suite, results, level="numbers")
    assert _failed(report) == _tagged(manifests, f"profile:{profile}") - _tagged(manifests, "invalid")
    assert (report.harness or {}).get("fault") == fault, report.harness


@pytest.mark.parametrize("fault", sorted(_RIG_MUST_FAIL))
def test_broken_rig_steps_fail_exactly_their_cases_on_three(suite, tmp_path, fault):
    """The animation faults (skinned vertices left in global space, raw skin weights) fail the
    same rig cases through the three.js plugin as through PlayCanvas."""
    results = tmp_path / "results"
    _run(suite, results, "--cases", "rig-*", "--fault", fault, "--level", "numbers")
    report = check_results(suite, results, level="numbers")
    assert {c.id for c in report.cases if c.id in RIG_IDS and c.status != "pass"} == _RIG_MUST_FAIL[fault]
    assert (report.harness or {}).get("fault") == fault


def test_three_plugin_passes_every_render_case_in_chromium(suite, three_results):
    """The render level: Spark's pictures of every frame of every render case (the remap in
    Spark's object modifier, splats sorted by Spark from the modified centres, node transforms,
    plain splats, the file's animation) against the reference pictures."""
    report = check_results(suite, three_results, level="render")
    assert report.summary["render"] == len(json.loads((suite / "suite.json").read_text())["render_cases"]) >= 7
    assert report.ok, [(c.id, c.message) for c in report.cases if c.status != "pass"]
    assert (three_results / "render-turn-180" / "frame_002.png").is_file()


#: The render faults of the PlayCanvas plugin the three.js plugin builds too. (Not 'rest-sort':
#: Spark sorts by the centres its modifiers output, so a sort by rest positions is not a mistake
#: this plugin can make.)
_THREE_RENDER_FAULTS = {f: _RENDER_FAULTS[f] for f in ("scale-swizzle", "node-transform")}


@pytest.mark.parametrize("fault", sorted(_THREE_RENDER_FAULTS))
def test_broken_three_render_variants_fail_their_cases(suite, tmp_path, fault):
    """Scales handed to Spark as (y, x, z) and an ignored splat node transform each fail the
    render cases built to show them (the same cases as for PlayCanvas)."""
    results = tmp_path / "results"
    _run(suite, results, "--fault", fault, "--level", "render")
    report = check_results(suite, results, level="render")
    must, may = _THREE_RENDER_FAULTS[fault]
    failed = _failed(report)
    assert must <= failed, (fault, sorted(failed), [(c.id, c.message) for c in report.cases])
    assert failed <= must | may, (fault, sorted(failed - must - may))


#: Both engines' pictures of the same posed asset: PSNR over the pixels either covers and the
#: coverage IoU (the render check's metric, render_check.score_frame, with each case's coverage
#: level and margin). Measured on SwiftShader between PlayCanvas 2.23.3 and three 0.187 + Spark
#: 2.2.0: 24.4 dB and IoU 0.925 at worst over all 20 frames (the needles of render-packing and
#: render-sliver-stretched: Spark stores scales as 8-bit logarithms), 30 dB typical. Asserted:
ENGINE_AGREEMENT = {"psnr_db": 22.0, "iou": 0.88}


def test_the_two_engines_render_the_same_posed_asset_alike(suite, three_results, tmp_path):
    """Every frame of every render case (rest, deformed, animated, transformed nodes, plain
    splats) drawn by PlayCanvas and by three.js + Spark, compared picture to picture with the
    render check's metric: at least ENGINE_AGREEMENT everywhere; and the metric tells two poses
    apart (the sheet turned 150 degrees against its rest, across engines, lands far below)."""
    pc = tmp_path / "playcanvas"
    require_web_tools(browser=True, packages=THREE_PACKAGES)
    proc = run_node(["conformance/run-browser.mjs", suite, pc, "--level", "render"])
    assert proc.returncode == 0, _explain(proc)
    compared = 0
    for case in json.loads((suite / "suite.json").read_text())["render_cases"]:
        cid = Path(case["path"]).name
        th = json.loads((suite / case["path"] / "case.json").read_text())["thresholds"]
        for frame in sorted((pc / cid).glob("frame_*.png")):
            score = score_frame(read_rgb(three_results / cid / frame.name), read_rgb(frame), th)
            assert score.psnr_db >= ENGINE_AGREEMENT["psnr_db"] and score.iou >= ENGINE_AGREEMENT["iou"], (cid, frame.name, score)
            compared += 1
    assert compared >= 20
    th = json.loads((suite / "cases" / "render-turn-180" / "case.json").read_text())["thresholds"]
    apart = score_frame(read_rgb(three_results / "render-turn-180" / "frame_000.png"),
                        read_rgb(pc / "render-turn-180" / "frame_001.png"), th)
    assert apart.psnr_db < ENGINE_AGREEMENT["psnr_db"], apart


def test_three_engine_refuses_webgpu(suite, tmp_path):
    """Spark renders through three.js's WebGLRenderer: asked for WebGPU, the run says so."""
    require_web_tools(browser=True, packages=THREE_PACKAGES)
    proc = run_node(["conformance/run-browser.mjs", suite, tmp_path / "r", "--engine", "three",
                     "--level", "numbers", "--backend", "webgpu", "--cases", "local-affine-bend"])
    assert proc.returncode != 0
    assert "WebGL2 only" in proc.stderr + proc.stdout, _explain(proc)


@pytest.mark.parametrize("case", ["rig-skinned", "rig-morph-weights", "rig-two-parts-merged"])
def test_follow_skinned_mesh_matches_the_file_animation(suite, case):
    """The anchor mesh as three.js builds it (GLTFLoader) and plays it (AnimationMixer), its
    vertices taken by ``followSkinnedMesh``, is the package's own sampling of the file's
    animation (src/animation.js, the one the rig cases pass with) at every time: to float32
    roundoff of the skinning sums (1e-6 of the mesh's extent), while the poses move the mesh
    by a tenth of its extent or more. The last time is past the clip's end (both clamp)."""
    require_web_tools(browser=True, packages=THREE_PACKAGES)
    proc = run_node(["test/three-follow.mjs", suite / "cases" / case / "asset.glb", "0", "0.3", "0.7", "1.5"])
    assert proc.returncode == 0, _explain(proc)
    r = json.loads(proc.stdout.strip().splitlines()[-1])
    assert r["moved"] > 0.1 * r["extent"], r
    assert r["maxError"] <= 1e-6 * r["extent"], r
