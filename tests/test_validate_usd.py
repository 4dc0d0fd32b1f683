"""gsverse-validate on USD files: every code that applies to USD is triggered by a USD asset
with a USD path as location, files the writer produces are clean, foreign prims get warnings
where their readers repair the data, and the command line reports USD like glTF."""
from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("pxr")

from gsverse_format.io.usd import write_usd  # noqa: E402
from gsverse_format.validators import cli, usd as usd_module  # noqa: E402
from gsverse_format.validators.container import Options  # noqa: E402
from gsverse_format.validators.issues import CATALOGUE, Severity  # noqa: E402
from gsverse_format.validators.validate import validate_file  # noqa: E402

import usd_validation_assets as ua  # noqa: E402
from validation_assets import local_asset  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
USD_CODES = [c for c, info in CATALOGUE.items() if info.usd]


@pytest.fixture
def folder(tmp_path):
    path = tmp_path / "assets"
    path.mkdir()
    return path


def _validate_without_pxr(path: pathlib.Path) -> dict:
    """Validate ``path`` in a fresh interpreter in which ``import pxr`` fails."""
    code = ("import json, sys\nsys.modules['pxr'] = None\n"
            "from gsverse_format.validators.validate import validate_file\n"
            "print(json.dumps(validate_file(sys.argv[1]).to_json()))\n")
    proc = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True,
                          text=True, timeout=300, cwd=str(ROOT))
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _run(trigger, monkeypatch):
    if trigger.fault is True:
        def broken(*args, **kwargs):
            raise RuntimeError("injected fault")
        monkeypatch.setattr(usd_module, "check_anchor_values", broken)
    return validate_file(trigger.path, Options(**trigger.options))


def test_every_usd_code_has_a_trigger():
    assert set(ua.USD_TRIGGERS) == set(USD_CODES)
    for code, info in CATALOGUE.items():
        assert (info.group == "USD") <= bool(info.usd), code
        if info.foreign_severity is not None:
            assert info.foreign_severity > info.severity, code


@pytest.mark.parametrize("code", USD_CODES)
def test_usd_code_is_triggered(code, folder, monkeypatch):
    trigger = ua.USD_TRIGGERS[code](folder)
    info = CATALOGUE[code]
    if trigger.fault == "block_pxr":
        report = _validate_without_pxr(trigger.path)
        assert [m["code"] for m in report["issues"]["messages"]] == [code]
        assert report["exitStatus"] == 2
        return
    report = _run(trigger, monkeypatch)
    found = [f for f in report.findings if f.code == code]
    assert found, f"{code} not reported; got {[(f.code, f.message) for f in report.findings]}"
    for f in found:
        assert f.severity == info.severity, (code, f.severity)
        assert "\n" not in f.message and f.message
        assert f.pointer is None or f.pointer == "" or f.pointer.startswith("/"), f.pointer
        if f.examples is not None:
            assert len(f.examples) <= Options().max_examples
            assert f.count is not None and f.count >= len(f.examples)
    expected = 2 if info.unreadable else 1 if info.severity == Severity.ERROR else None
    if expected is not None:
        assert report.exit_status == expected
    out = report.to_json()
    json.dumps(out, allow_nan=False)
    assert all("pointer" not in m for m in out["issues"]["messages"])
    if trigger.path.exists():
        assert report.mime_type in usd_module.USD_MIME.values()


@pytest.mark.parametrize("code", [c for c in USD_CODES if CATALOGUE[c].fatal])
def test_fatal_usd_codes_stop_validation(code, folder, monkeypatch):
    trigger = ua.USD_TRIGGERS[code](folder)
    if trigger.fault == "block_pxr":  # usd-core unavailable: a child interpreter without pxr
        out = _validate_without_pxr(trigger.path)
        assert out["issues"]["messages"][-1]["code"] == code
        assert out["info"].get("splatPrimitives") is None
        return
    report = _run(trigger, monkeypatch)
    assert report.findings[-1].code == code
    assert report.info.get("splatPrimitives") is None


def test_clean_usd_assets_have_no_findings(folder):
    for path in ua.clean_usd_assets(folder):
        report = validate_file(path)
        assert report.findings == [], (path.name, [(f.code, f.message) for f in report.findings])
        assert report.exit_status == 0
        assert report.info["anchoredPrimitives"] >= 1 and report.info["splats"] > 0
    assert validate_file(folder / "games.usdz").mime_type == "model/vnd.usdz+zip"
    assert validate_file(folder / "games.usd").mime_type == "model/x-usdc"


def test_locations_name_the_offending_usd_property(folder, monkeypatch):
    report = _run(ua.USD_TRIGGERS["REST_POSE_MEAN_MISMATCH"](folder), monkeypatch)
    (mean,) = [f for f in report.findings if f.code == "REST_POSE_MEAN_MISMATCH"]
    assert mean.pointer == "/Asset/body.positions" and mean.count == 1
    assert mean.examples[0]["splat"] == 3
    report = _run(ua.USD_TRIGGERS["MESH_DEGENERATE_TRIANGLES"](folder), monkeypatch)
    (deg,) = [f for f in report.findings if f.code == "MESH_DEGENERATE_TRIANGLES"]
    assert deg.pointer == "/Asset/anchor_mesh"
    report = _run(ua.USD_TRIGGERS["USD_TYPE_MISMATCH"](folder), monkeypatch)
    assert any(f.pointer == "/Asset/body.gsverse:anchor:faceIndices" for f in report.findings)


def test_same_problem_same_code_in_glb_and_usd(folder):
    """A rest pose moved off its anchors is the same finding in both formats."""
    from validation_assets import Doc

    asset = local_asset(24)
    asset.primitives[0].splats.means[5] += 0.02
    glb = Doc.of(asset).write(folder, "moved.glb")
    usda = folder / "moved.usda"
    write_usd(asset, usda)
    g, u = validate_file(glb), validate_file(usda)
    assert g.codes() == u.codes() == {"REST_POSE_MEAN_MISMATCH"}
    gf, uf = g.findings[0], u.findings[0]
    assert gf.message == uf.message and gf.examples == uf.examples


def test_foreign_prims_get_warnings_where_readers_repair(folder):
    """Prims without a GsVerse API schema: writer rules and repaired values are warnings."""
    trigger = ua.USD_TRIGGERS["USD_PLAIN_SPLATS"](folder)
    text = trigger.path.read_text(encoding="utf-8")
    static = text.index('"static"')
    head, tail = text[:static], text[static:]
    tail = tail.replace('        uniform token sortingModeHint = "cameraDistance"\n', "", 1)
    tail = tail.replace("float[] opacities = [", "float[] opacities = [1.5, ", 1)
    trigger.path.write_text(head + tail, encoding="utf-8")  # one opacity too many: truncated
    report = validate_file(trigger.path)
    by_code = {f.code: f for f in report.findings}
    assert by_code["USD_PLAIN_SPLATS"].severity == Severity.INFO
    assert by_code["USD_SORTING_MODE"].severity == Severity.WARNING
    assert by_code["OPACITY_OUT_OF_RANGE"].severity == Severity.WARNING
    assert by_code["USD_TRUNCATED"].severity == Severity.WARNING
    assert report.exit_status == 0
    # the same problems on a prim that claims conformance are errors
    report = validate_file(ua.USD_TRIGGERS["USD_SORTING_MODE"](folder).path)
    assert {f.code: f.severity for f in report.findings}["USD_SORTING_MODE"] == Severity.ERROR


def test_convert_to_usd_then_validate_is_clean(tmp_path):
    from gsverse_format.cli.convert import main as convert_main

    src = ROOT / "examples" / "capsule"
    for suffix in (".usda", ".usdz"):
        out = tmp_path / f"capsule{suffix}"
        assert convert_main([str(src / "splats.ply"), str(out), "--mesh", str(src / "mesh.obj"),
                             "--quiet"]) == 0
        report = validate_file(out)
        assert report.findings == [] and report.info["anchoredPrimitives"] == 1


def test_cli_on_usd_text_json_and_exit_status(folder, capsys):
    clean = ua.clean_usd_assets(folder)[0]
    bad = ua.USD_TRIGGERS["USD_PROFILE_INVALID"](folder).path
    assert cli.main([str(clean)]) == 0
    assert cli.main([str(clean), str(bad)]) == 1
    text = capsys.readouterr().out
    assert "USD_PROFILE_INVALID /Asset/body.gsverse:anchor:profile:" in text
    assert cli.main([str(bad), "--format", "json", "--severity",
                     "USD_PROFILE_INVALID=warning"]) == 0
    report = json.loads(capsys.readouterr().out)["reports"][0]
    (message,) = [m for m in report["issues"]["messages"] if m["code"] == "USD_PROFILE_INVALID"]
    assert message["usdPath"] == "/Asset/body.gsverse:anchor:profile"
    assert message["severity"] == "warning" and report["mimeType"] == "model/vnd.usda"
    assert cli.main([str(folder / "garbage.usda")]) == 2


def test_a_crash_in_the_usd_reader_is_an_internal_error(folder, monkeypatch):
    """An unexpected exception in the USD child process is a validator crash naming its type,
    never a finding about the file."""
    from gsverse_format.io.usd import isolation

    path = ua.clean_usd_assets(folder)[0]
    monkeypatch.setattr(isolation, "CHILD_CODE", ua.BROKEN_READER + isolation.CHILD_CODE)
    report = validate_file(path)
    assert report.codes() == {"INTERNAL_ERROR"}, [(f.code, f.message) for f in report.findings]
    assert "KeyError" in report.findings[0].message and report.exit_status == 1


def test_validator_never_writes_and_survives_byte_flips(folder):
    good = ua.clean_usd_assets(folder)[1]  # .usdc
    data = good.read_bytes()
    before = sorted(os.listdir(folder))
    rng = np.random.default_rng(3)
    path = folder / "flipped.usdc"
    for _ in range(6):
        mutated = bytearray(data)
        for pos in rng.integers(0, len(data), 3):
            mutated[pos] = rng.integers(0, 256)
        path.write_bytes(bytes(mutated))
        report = validate_file(path)
        assert "INTERNAL_ERROR" not in report.codes(), [f.message for f in report.findings]
        json.dumps(report.to_json(), allow_nan=False)
    assert sorted(os.listdir(folder)) == sorted(before + ["flipped.usdc"])
