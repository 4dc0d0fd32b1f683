"""The ``encoding:spz`` cases of the conformance suite (spec/conformance.md): compressed remap
cases checked against the remap of the decoded rest pose and, second, of the uncompressed one
within the stated bounds; the compressed invalid cases; the harness's declaration of optional
features it does not implement (``unsupported`` in ``harness.json``); and deliberately broken
readers that must fail. A small suite holding these cases only is exported once per module."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from gsverse_format.conformance import export as export_module
from gsverse_format.conformance import minimal_reader
from gsverse_format.conformance.cases_spz import TAG, spz_cases, spz_invalid_cases
from gsverse_format.conformance.check import OPTIONAL_TAGS, check_results, format_text
from gsverse_format.conformance.harness import (FastPlugin, RawReferencePlugin, ReferencePlugin,
                                                Refused, run_plugin)
from gsverse_format.errors import FormatError
from gsverse_format.io.gltf import read_gltf
from gsverse_format.validators import validate_file

from test_conformance_native import CPlugin, build, compiler


@pytest.fixture(scope="module")
def suite(tmp_path_factory) -> Path:
    """The ``encoding:spz`` cases as a suite of their own (the layout of export_suite)."""
    root = tmp_path_factory.mktemp("spz-suite")
    entries = []
    for case in spz_cases():
        manifest = export_module._export_remap(case, root / "cases" / case.id)
        (root / "cases" / case.id / "case.json").write_text(json.dumps(manifest))
        entries.append({"id": case.id, "kind": "remap", "tags": case.tags,
                        "path": f"cases/{case.id}"})
    scratch = root / ".bases"
    scratch.mkdir()
    for case in spz_invalid_cases():
        manifest = export_module._export_invalid(case, root / "cases" / case.id, {}, scratch)
        (root / "cases" / case.id / "case.json").write_text(json.dumps(manifest))
        entries.append({"id": case.id, "kind": "invalid", "tags": manifest["tags"],
                        "path": f"cases/{case.id}"})
    shutil.rmtree(scratch)
    (root / "suite.json").write_text(json.dumps({"version": export_module.SUITE_VERSION,
                                                 "cases": entries, "render_cases": []}))
    return root


@pytest.fixture(scope="module")
def manifests(suite) -> dict[str, dict]:
    index = json.loads((suite / "suite.json").read_text())
    return {e["id"]: json.loads((suite / e["path"] / "case.json").read_text())
            for e in index["cases"]}


def _run(suite, out, factory, info=None):
    run_plugin(suite, out, factory, info=info)
    return check_results(suite, out, level="numbers")


def _failed(report) -> set[str]:
    return {c.id for c in report.cases if c.status != "pass"}


def _remap_ids(manifests) -> set[str]:
    return {cid for cid, m in manifests.items() if m["kind"] == "remap"}


# --------------------------------------------------------------------------- the cases

def test_cases_cover_both_laws_every_sh_degree_and_every_refusal(manifests):
    remap = [m for m in manifests.values() if m["kind"] == "remap"]
    assert all(TAG in m["tags"] and m["anchor"]["derived"] for m in remap)
    assert {m["anchor"]["deformation"] for m in remap} == {"affine", "rigid"}
    assert {m["sh_degree"] for m in remap} == {0, 1, 2, 3}
    codes = {m["validator_code"] for m in manifests.values() if m["kind"] == "invalid"}
    assert codes == {"SPZ_STREAM_INVALID", "SPZ_COUNT_MISMATCH", "SPZ_SH_MISMATCH",
                     "SPZ_BUFFER_VIEW_INVALID"}
    for m in remap:
        c = m["compression"]
        assert c["fractional_bits"] == 12 and len(c["uncompressed"]) == m["pose_count"]
        assert c["mean_bound"] == pytest.approx(3 ** 0.5 * 2 ** -13)


def test_the_compressed_rest_pose_differs_from_the_uncompressed_one(suite, manifests):
    """The second expectation is not the first: quantization moved the splats (by more than
    the usual tolerance), but within the bound."""
    for cid in _remap_ids(manifests):
        m = manifests[cid]
        decoded = np.fromfile(suite / "cases" / cid / m["files"]["expected"]["poses"][1]["means"])
        files = m["compression"]["uncompressed"][1]
        plain = np.fromfile(suite / "cases" / cid / files["means"])
        bound = np.fromfile(suite / "cases" / cid / files["bound"]).reshape(-1, 2)
        diff = np.linalg.norm((decoded - plain).reshape(-1, 3), axis=1)
        assert diff.max() > m["tolerances"]["mean"]["atol"]
        assert np.all(diff <= bound[:, 0])


def test_invalid_cases_carry_the_codes_the_reader_and_validator_report(suite, manifests):
    for cid, m in manifests.items():
        if m["kind"] != "invalid":
            continue
        path = suite / "cases" / cid / "asset.glb"
        with pytest.raises(FormatError) as info:
            read_gltf(path)
        assert info.value.code == m["validator_code"], cid
        assert m["validator_code"] in validate_file(path).codes(), cid
        with pytest.raises(minimal_reader.Refused):
            minimal_reader.read_anchored_glb(path)


# --------------------------------------------------------------------------- implementations

@pytest.mark.parametrize("factory", [ReferencePlugin, RawReferencePlugin, FastPlugin],
                         ids=["reference", "minimal_reader", "fast"])
def test_implementations_pass_every_spz_case(suite, tmp_path, factory):
    report = _run(suite, tmp_path, factory)
    assert report.ok and not _failed(report), format_text(report, failures_only=True)
    quantities = {c.quantity for r in report.cases for c in r.checks}
    assert {"mean (uncompressed)", "covariance (uncompressed)"} <= quantities


def test_c_header_passes_every_spz_case(suite, tmp_path, tmp_path_factory):
    if compiler() is None:
        pytest.skip("no C compiler (cc) on this machine")
    lib = build(tmp_path_factory.mktemp("native-spz"), real="double")
    report = _run(suite, tmp_path, lambda: CPlugin(lib))
    assert report.ok, format_text(report, failures_only=True)


# --------------------------------------------------------------------------- broken readers

def test_broken_reader_without_the_frame_change_fails_every_remap_case(suite, manifests,
                                                                        tmp_path, monkeypatch):
    monkeypatch.setattr(minimal_reader, "_SPZ_AXIS", np.ones(3))
    report = _run(suite, tmp_path, RawReferencePlugin)
    assert _failed(report) == _remap_ids(manifests)


def test_broken_reader_without_the_sh_signs_fails_the_cases_with_sh(suite, manifests,
                                                                     tmp_path, monkeypatch):
    monkeypatch.setattr(minimal_reader, "_SPZ_SH_SIGN", np.ones(16))
    report = _run(suite, tmp_path, RawReferencePlugin)
    assert _failed(report) == {cid for cid in _remap_ids(manifests)
                               if manifests[cid]["sh_degree"] > 0}


def test_broken_reader_deriving_from_the_uncompressed_rest_pose_fails_the_first_comparison(
        suite, manifests, tmp_path):
    """A reader whose anchors come from values other than the decoded float32 rest pose (here
    the uncompressed ones, as a writer holding them might be tempted to store): its remap is
    the uncompressed remap, within the second bound, but not the decoded one."""

    class FromUncompressed(ReferencePlugin):
        def load(self, asset_path: str) -> None:
            super().load(asset_path)
            cid = Path(asset_path).parent.name
            case = next(c for c in spz_cases() if c.id == cid)
            initial = export_module._initial_asset(case)
            plain = asset_path + ".plain.glb"
            from gsverse_format.io.gltf import write_gltf
            write_gltf(initial, plain, anchors="compact")
            self.prim = read_gltf(plain).primitives[0]
            self.anchoring = self.prim.anchoring

    report = _run(suite, tmp_path, FromUncompressed)
    assert _failed(report) == _remap_ids(manifests)
    for result in report.cases:
        if result.kind == "remap":
            per = {c.quantity: c.ratio for c in result.checks}
            assert per["mean"] > 1.0 and per["mean (uncompressed)"] <= 1.0, result.id


def test_second_comparison_catches_an_error_beyond_the_bound(suite, manifests, tmp_path):
    """Dumps moved off the uncompressed remap by more than the bound fail the second
    comparison (here by twice the bound plus the tolerance, along the decoded error)."""
    run_plugin(suite, tmp_path, ReferencePlugin)
    cid = sorted(_remap_ids(manifests))[0]
    m = manifests[cid]
    files = m["compression"]["uncompressed"][2]
    case_dir = suite / "cases" / cid
    plain = np.fromfile(case_dir / files["means"]).reshape(-1, 3)
    bound = np.fromfile(case_dir / files["bound"]).reshape(-1, 2)
    dump = tmp_path / cid / "pose_002.means.f64"
    if not dump.is_file():
        dump = tmp_path / cid / "pose_002.means.f32"
    got = np.fromfile(dump, "<f8" if dump.suffix == ".f64" else "<f4").reshape(-1, 3)
    atol = m["tolerances"]["mean"]["atol"]
    moved = plain.copy()
    moved[0] += np.array([1.0, 0.0, 0.0]) * (2 * bound[0, 0] + 2 * atol)
    dump.unlink()
    moved.astype("<f8").tofile(tmp_path / cid / "pose_002.means.f64")
    del got
    report = check_results(suite, tmp_path, level="numbers")
    result = next(r for r in report.cases if r.id == cid)
    assert result.status == "fail"
    per = {c.quantity: c for c in result.checks}
    assert per["mean (uncompressed)"].ratio > 1.0 and per["mean (uncompressed)"].splat == 0


# --------------------------------------------------------------------------- declared features

class _NoSpz(RawReferencePlugin):
    """An importer that does not know the SPZ extension: it refuses compressed assets."""

    def load(self, asset_path: str) -> None:
        if b"compression_spz" in Path(asset_path).read_bytes()[:20000]:
            raise Refused("KHR_gaussian_splatting_compression_spz_2 is not supported")
        super().load(asset_path)


def test_undeclared_missing_feature_fails(suite, manifests, tmp_path):
    report = _run(suite, tmp_path, _NoSpz)
    assert not report.ok and _failed(report) == _remap_ids(manifests)


def test_declared_unsupported_feature_is_reported_not_passed(suite, manifests, tmp_path):
    assert TAG in OPTIONAL_TAGS
    report = _run(suite, tmp_path, _NoSpz, info={"name": "no spz", "unsupported": [TAG]})
    assert report.ok and {c.status for c in report.cases} == {"unsupported"}
    assert report.summary["unsupported"] == len(manifests) and report.summary["passed"] == 0
    text = format_text(report)
    assert "UNSUPPORTED" in text and f"{len(manifests)} not supported" in text


def test_only_optional_features_can_be_declared(suite, manifests, tmp_path):
    report = _run(suite, tmp_path, _NoSpz,
                  info={"name": "no spz", "unsupported": ["profile:local", "invalid"]})
    assert not report.ok and report.summary["unsupported"] == 0
    assert _failed(report) == _remap_ids(manifests)
