"""The rig cases of the conformance suite (spec/conformance.md §Rig cases): anchor meshes animated
by the asset itself, with a transformed splat node, so that an implementation must sample (or
read the deformed vertices p′) and bring skinned vertices into splat-local space by M⁻¹.

Every implementation passes them: the numpy reference (from the files and by sampling), the
fast path, the minimal reader, the C header (float and double), the web plugin in Node and in
Chromium; the deliberately broken variants (no M⁻¹, weights used as stored) fail exactly the
cases they should, in Python and in the web plugin.
"""
from __future__ import annotations

import ctypes
import json
from pathlib import Path

import numpy as np
import pytest

from gsverse_format.conformance.check import check_results, format_text
from gsverse_format.conformance.export import export_suite
from gsverse_format.conformance.harness import (FastPlugin, RawReferencePlugin, ReferencePlugin,
                                                read_asset, run_plugin, suite_cases)
from gsverse_format.conformance.rig_poses import sample_rig, splat_local, splat_node_matrix
from gsverse_format.io.gltf import read_gltf
from gsverse_format.remapping.reference import remap
from test_conformance_native import CPlugin, build, compiler
from web_tools import ROOT, require_web_tools, run_node

RIG_IDS = {"rig-skinned", "rig-skinned-hidden-anchor-node", "rig-morph-weights",
           "rig-two-parts-merged", "rig-weights-unnormalized"}
RIG_INVALID = {"invalid-rig-two-skinned-anchor-nodes", "invalid-rig-two-morphed-anchor-nodes"}
SKINNED = RIG_IDS - {"rig-morph-weights"}


@pytest.fixture(scope="module")
def suite(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("rig") / "suite"
    export_suite(path)
    return path


@pytest.fixture(scope="module")
def manifests(suite) -> dict[str, dict]:
    return {m["id"]: m for _, m in suite_cases(suite)}


def _rig_only(m: dict) -> bool:
    return m["id"] in RIG_IDS | RIG_INVALID


def _run(suite: Path, out: Path, factory) -> dict[str, str]:
    """Run ``factory`` over the rig cases and refusals; the verdict of each of them."""
    run_plugin(suite, out, factory, only=_rig_only)
    return _verdicts(suite, out)


def _verdicts(suite: Path, out: Path) -> dict[str, str]:
    report = check_results(suite, out, level="numbers")
    verdicts = {c.id: c.status for c in report.cases if c.id in RIG_IDS | RIG_INVALID}
    assert set(verdicts) == RIG_IDS | RIG_INVALID, format_text(report)
    return verdicts


def _failed(verdicts: dict[str, str]) -> set[str]:
    return {cid for cid, status in verdicts.items() if status != "pass"}


def _deformed(suite: Path, m: dict, p: int) -> np.ndarray:
    return np.fromfile(suite / "cases" / m["id"] / m["files"]["deformed"][p],
                       "<f4").reshape(-1, 3)


# --------------------------------------------------------------------------- the cases

def test_rig_cases_are_exported_with_their_layout(suite, manifests):
    index = json.loads((suite / "suite.json").read_text())
    assert index["counts"]["rig"] == len(RIG_IDS)
    assert {e["id"] for e in index["cases"] if e["kind"] == "rig"} == RIG_IDS
    assert RIG_INVALID <= {e["id"] for e in index["cases"] if e["kind"] == "invalid"}
    tags = {t for cid in RIG_IDS for t in manifests[cid]["tags"]}
    assert {"rig:skin", "rig:morph", "rig:hidden-anchor-node", "rig:merged-parts",
            "rig:weights-unnormalized", "profile:games", "deformation:rigid"} <= tags
    for cid in RIG_IDS:
        m = manifests[cid]
        rig = m["rig"]
        assert m["kind"] == "rig" and "poses" not in m["files"], cid
        assert rig["skinned"] == (cid in SKINNED) and rig["morphed"] == (cid not in SKINNED)
        assert rig["local_vertices"] == ("M^-1 p'" if rig["skinned"] else "p'")
        mat = splat_node_matrix(rig)
        # translated, rotated, uniformly scaled 1.3: M^-1 matters
        assert np.linalg.norm(mat[:3, 3]) > 0.3
        np.testing.assert_allclose(np.linalg.svd(mat[:3, :3], compute_uv=False), 1.3, rtol=1e-12)
        assert not np.allclose(mat[:3, :3] / 1.3, np.eye(3), atol=0.1)
        assert [p["source"]["kind"] for p in m["poses"]] == ["rest", "animation", "animation"]
        assert [p["source"].get("time") for p in m["poses"][1:]] == [0.35, 0.8]
        v = m["anchor"]["vertex_count"]
        for p in range(len(m["poses"])):
            assert _deformed(suite, m, p).shape == (v, 3)
        # the asset holds the animated anchor mesh itself: one node with the skin or weights
        doc = json.loads(_json_chunk(suite / "cases" / cid / "asset.glb"))
        users = [n for n in doc["nodes"] if n.get("mesh") == m["anchor"]["mesh"]]
        assert len(users) == 1 and ("skin" in users[0]) == rig["skinned"], cid
        hidden = users[0].get("extensions", {}).get("KHR_node_visibility") == {"visible": False}
        assert hidden == rig["anchor_node_hidden"] == (cid != "rig-skinned"), cid
        assert doc["animations"], cid
    merged = json.loads(_json_chunk(suite / "cases" / "rig-two-parts-merged" / "asset.glb"))
    assert len(merged["skins"]) == 1 and len(merged["skins"][0]["joints"]) == 5


def _json_chunk(path: Path) -> bytes:
    data = path.read_bytes()
    length = int.from_bytes(data[12:16], "little")
    return data[20:20 + length]


def test_deformed_vertices_are_the_animation_and_m_inverse_brings_them_home(suite, manifests):
    """p′ files are the file's animation as glTF skins it (global space), M⁻¹ · p′ is the
    splat-local pose; at rest that is the stored POSITION; a morph-only mesh's p′ is local."""
    for cid in RIG_IDS:
        m = manifests[cid]
        glb = (suite / "cases" / cid / "asset.glb").read_bytes()
        sampled = sample_rig(glb, [p["source"] for p in m["poses"]])
        rest = read_gltf(suite / "cases" / cid / "asset.glb").primitives[0].anchoring.mesh
        for p, (deformed, local) in enumerate(sampled):
            np.testing.assert_array_equal(_deformed(suite, m, p), deformed.astype(np.float32))
            scale = 1.0 + np.abs(local).max()
            assert np.abs(splat_local(_deformed(suite, m, p), m["rig"]) - local).max() \
                <= 1e-6 * scale
            if cid in SKINNED:      # global space: far from splat-local
                assert np.abs(deformed - local).max() > 0.3, (cid, p)
            else:
                np.testing.assert_array_equal(deformed, local)
        np.testing.assert_allclose(sampled[0][1], rest.vertices, atol=1e-6)
        assert np.abs(sampled[2][1] - sampled[0][1]).max() > 0.05, cid   # it moves


def test_expected_outputs_are_the_reference_on_the_splat_local_poses(suite, manifests):
    for cid in ("rig-skinned", "rig-morph-weights", "rig-two-parts-merged"):
        m = manifests[cid]
        folder = suite / "cases" / cid
        prim = read_asset(str(folder / "asset.glb")).primitives[0]
        sampled = sample_rig((folder / "asset.glb").read_bytes(), [p["source"] for p in m["poses"]])
        for (_, local), exp in zip(sampled, m["files"]["expected"]["poses"]):
            got = np.fromfile(folder / exp["means"], "<f8").reshape(-1, 3)
            np.testing.assert_array_equal(got, remap(prim.anchoring, local).means)
        assert "p'" in m["tolerances"]["mean"]["reason"]


def test_unnormalized_weights_are_stored_as_such(suite):
    doc_bytes = (suite / "cases" / "rig-weights-unnormalized" / "asset.glb").read_bytes()
    from gsverse_format.conformance.glb import accessor_bytes, anchor_primitive, unpack_glb

    doc, blob = unpack_glb(doc_bytes)
    w = accessor_bytes(doc, blob, anchor_primitive(doc)["attributes"]["WEIGHTS_0"])
    sums = w.astype(np.float64).sum(axis=1)
    assert sums.min() == 0.0 and np.count_nonzero(sums == 0.0) == 2
    assert np.count_nonzero(np.abs(sums - 1.0) > 0.1) > len(sums) // 2


# --------------------------------------------------------------------------- implementations

@pytest.mark.parametrize("name", ["reference-files", "reference-sampled", "fast", "minimal-reader"])
def test_python_implementations_pass_the_rig_cases(suite, tmp_path, name):
    factory = {"reference-files": ReferencePlugin,
               "reference-sampled": lambda: ReferencePlugin(rig="sample"),
               "fast": FastPlugin, "minimal-reader": RawReferencePlugin}[name]
    verdicts = _run(suite, tmp_path / name, factory)
    assert not _failed(verdicts), verdicts


@pytest.mark.parametrize("real", ["double", "float"])
def test_c_header_passes_the_rig_cases(suite, tmp_path, real):
    if compiler() is None:
        pytest.skip("no C compiler (cc) on this machine")
    lib = build(tmp_path, real=real)
    verdicts = _run(suite, tmp_path / "c", lambda: CPlugin(lib, "cov"))
    assert not _failed(verdicts), verdicts


def test_c_header_splat_local_is_m_inverse_in_double(tmp_path):
    if compiler() is None:
        pytest.skip("no C compiler (cc) on this machine")
    lib = build(tmp_path, real="float")
    rng = np.random.default_rng(7)
    m = np.eye(4)
    m[:3, :3] = rng.normal(size=(3, 3))
    m[:3, 3] = rng.normal(size=3) * 1e3
    p = rng.normal(size=(50, 3)).astype(np.float32) * 1e3
    out = np.zeros_like(p)
    flat = np.ascontiguousarray(m.T.reshape(-1))
    ptr = lambda a: a.ctypes.data_as(ctypes.c_void_p)  # noqa: E731
    assert lib.gsv_splat_local(ptr(p), len(p), ptr(flat), ptr(out)) == 1
    inv = np.linalg.inv(m)
    want = p.astype(np.float64) @ inv[:3, :3].T + inv[:3, 3]
    np.testing.assert_allclose(out, want, rtol=0, atol=2e-7 * np.abs(want).max())
    for bad in (np.diag([1.0, 0.0, 1.0, 1.0]), np.full((4, 4), np.nan)):
        flat = np.ascontiguousarray(bad.T.reshape(-1))
        assert lib.gsv_splat_local(ptr(p), len(p), ptr(flat), ptr(out)) == 0


def test_web_plugin_passes_the_rig_cases_in_node(suite, tmp_path):
    require_web_tools()
    out = tmp_path / "node"
    proc = run_node(["conformance/run-node.mjs", suite, out, "--cases", "*rig-*"])
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert not _failed(_verdicts(suite, out))


def test_web_plugin_passes_the_rig_cases_in_chromium(suite, tmp_path):
    require_web_tools(browser=True)
    out = tmp_path / "gpu"
    proc = run_node(["conformance/run-browser.mjs", suite, out, "--level", "numbers",
                     "--cases", "*rig-*"])
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert not _failed(_verdicts(suite, out))


# --------------------------------------------------------------------------- broken variants

_MUST_FAIL = {"skip-inverse-node": SKINNED, "raw-weights": {"rig-weights-unnormalized"}}


@pytest.mark.parametrize("fault, source", [("skip-inverse-node", "files"),
                                           ("skip-inverse-node", "sample"),
                                           ("raw-weights", "sample")])
def test_broken_python_rig_steps_fail_exactly_their_cases(suite, tmp_path, fault, source):
    verdicts = _run(suite, tmp_path / fault, lambda: ReferencePlugin(rig=source, fault=fault))
    assert _failed(verdicts) == _MUST_FAIL[fault]


def test_raw_weights_needs_a_sampler():
    with pytest.raises(ValueError):
        ReferencePlugin(fault="raw-weights")
    with pytest.raises(ValueError):
        ReferencePlugin(fault="no-such-fault")


@pytest.mark.parametrize("fault", sorted(_MUST_FAIL))
def test_broken_web_rig_steps_fail_exactly_their_cases(suite, tmp_path, fault):
    require_web_tools(browser=True)
    for runner, extra in (("run-node.mjs", []), ("run-browser.mjs", ["--level", "numbers"])):
        out = tmp_path / runner
        proc = run_node([f"conformance/{runner}", suite, out, "--cases", "rig-*", "--fault",
                         fault, *extra])
        assert proc.returncode == 0, proc.stdout + proc.stderr
        report = check_results(suite, out, level="numbers")
        failed = {c.id for c in report.cases if c.id in RIG_IDS and c.status != "pass"}
        assert failed == _MUST_FAIL[fault], (runner, failed)
        assert (report.harness or {}).get("fault") == fault


# --------------------------------------------------------------------------- documents

def test_the_guide_and_layout_describe_the_rig_cases(suite, manifests):
    guide = (ROOT / "spec" / "conformance.md").read_text(encoding="utf-8")
    index = json.loads((suite / "suite.json").read_text())
    counts = index["counts"]
    total = counts["remap"] + counts["rig"] + counts["invalid"]
    assert (f"writes {total} numbers-level *cases* ({counts['remap']} remap, {counts['rig']} rig, "
            f"{counts['invalid']} invalid)") in guide
    assert f"The {counts['invalid']} invalid cases of the suite" in guide
    assert f"the {counts['invalid']} assets of the table" in guide
    for cid in RIG_IDS | RIG_INVALID:
        assert f"`{cid}`" in guide, cid
    assert "deformed_NNN.f32" in guide and "splat_node_matrix" in guide
    layout = (suite / "LAYOUT.md").read_text(encoding="utf-8")
    assert "deformed_NNN.f32" in layout and "M^-1 p'" in layout


# --------------------------------------------------------------------------- gsverse-pose

def test_gsverse_pose_poses_the_rig_assets_as_the_suite_expects(suite, manifests, tmp_path):
    """``gsverse-pose ASSET`` (the asset's own animation, :func:`open_gltf_source`) poses the
    anchor mesh in splat-local space (M⁻¹ for skinned meshes, the anchor node's transform
    ignored for morph-only ones), so its posed splats are the suite's expected outputs."""
    from gsverse_format.cli.pose import main as pose_main
    from gsverse_format.poses.gltf_source import open_gltf_source

    for cid in RIG_IDS:
        m = manifests[cid]
        path = suite / "cases" / cid / "asset.glb"
        source = open_gltf_source(path)
        mesh = read_asset(str(path)).primitives[0].anchoring.mesh
        source.match(mesh.vertices)
        sampled = sample_rig(path.read_bytes(), [p["source"] for p in m["poses"]])
        for p in m["poses"][1:]:
            np.testing.assert_allclose(source.at(p["source"]["time"]),
                                       sampled[p["index"]][1], rtol=0, atol=1e-12)
    for cid in ("rig-skinned", "rig-morph-weights"):   # the command line, end to end
        m = manifests[cid]
        out = tmp_path / cid
        assert pose_main([str(suite / "cases" / cid / "asset.glb"), str(out), "--times", "0.35",
                          "0.8", "--to", "glb", "-q"]) == 0
        for p, posed in enumerate(sorted(out.glob("*.glb")), start=1):
            got = read_gltf(posed).primitives[0].splats.means
            exp = suite / "cases" / cid / m["files"]["expected"]["poses"][p]["means"]
            error = np.abs(got - np.fromfile(exp, "<f8").reshape(-1, 3)).max()
            assert error <= m["tolerances"]["mean"]["per_pose"][p], (cid, p, error)


def test_rig_assets_are_valid_and_warn_only_where_the_manifest_says(suite, manifests):
    from gsverse_format.validators.issues import Severity
    from gsverse_format.validators.validate import validate_file

    for cid in RIG_IDS:
        report = validate_file(suite / "cases" / cid / "asset.glb")
        assert not [f for f in report.findings if f.severity == Severity.ERROR], cid
        warned = {f.code for f in report.findings if f.severity <= Severity.WARNING}
        assert warned == set(manifests[cid].get("validator_codes", [])), (cid, warned)
    for cid in RIG_INVALID:
        report = validate_file(suite / "cases" / cid / "asset.glb")
        assert manifests[cid]["validator_code"] in report.codes(), cid
