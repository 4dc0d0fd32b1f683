"""gsverse-validate: every catalogue code is triggered by a test asset, valid assets are clean,
the catalogue document matches the code, and the command line behaves as documented."""
from __future__ import annotations

import json
import pathlib
import re

import numpy as np
import pytest

from gsverse_format.codes import Code
from gsverse_format.validators import cli, validate as validate_module
from gsverse_format.validators.catalogue import render_markdown
from gsverse_format.validators.container import Options
from gsverse_format.validators.issues import CATALOGUE, Severity, parse_severity
from gsverse_format.validators.validate import validate_file

import validation_assets as va
from gsverse_format.binding import bind_local
from gsverse_format.model import Anchoring, SplatAsset, SplatCloud, SplatPrimitive, TriangleMesh
from gsverse_format.remapping.reference import remap

ROOT = pathlib.Path(__file__).resolve().parents[1]
#: Codes glTF files can trigger (the USD group is tested in test_validate_usd.py).
GLTF_CODES = [c for c, info in CATALOGUE.items() if info.group != "USD"]


@pytest.fixture
def folder(tmp_path):
    path = tmp_path / "assets"
    path.mkdir()
    return path


def _run(trigger: va.Trigger, monkeypatch=None):
    if trigger.fault:
        def broken(*args, **kwargs):
            raise RuntimeError("injected fault")
        monkeypatch.setattr(validate_module, "check_anchor", broken)
    return validate_file(trigger.path, Options(**trigger.options))


# ---------------------------------------------------------------------------- catalogue

def test_catalogue_has_exactly_the_issue_codes():
    assert set(CATALOGUE) == set(Code)
    assert all(type(code) is Code and info.code is code for code, info in CATALOGUE.items())


def test_every_code_has_a_trigger():
    assert set(va.TRIGGERS) == set(GLTF_CODES)


def test_catalogue_document_is_generated_from_the_registry():
    text = (ROOT / "spec" / "validation.md").read_text(encoding="utf-8")
    assert text == render_markdown(), ("spec/validation.md is out of date: run python -m "
                                       "gsverse_format.validators.catalogue spec/validation.md")
    for code in CATALOGUE:
        assert f"| `{code}` |" in text


def test_catalogue_entries_are_complete():
    for info in CATALOGUE.values():
        assert info.code == info.code.upper() and " " not in info.code
        assert info.trigger and info.pointer and info.fix and info.group
        assert info.trigger.endswith((".", ")")), info.code
    # Codes the spec requires to be errors.
    for code in ("ANCHOR_EXTENSION_REQUIRED", "EXTENSION_NOT_DECLARED", "ANCHOR_FACE_OUT_OF_RANGE",
                 "ANCHOR_BOUND_TO_DEGENERATE", "GAMES_BARYCENTRICS_OUTSIDE_SIMPLEX",
                 "REST_POSE_MEAN_MISMATCH", "REST_POSE_COVARIANCE_MISMATCH",
                 "ANCHOR_MESH_MULTIPLE_INSTANCES"):
        assert CATALOGUE[code].severity == Severity.ERROR
    # Barycentrics outside the simplex are legal for `local`: information at most.
    assert CATALOGUE["LOCAL_BARYCENTRICS_FAR"].severity >= Severity.INFO
    assert CATALOGUE["MESH_DEGENERATE_TRIANGLES"].severity > Severity.ERROR


# ---------------------------------------------------------------------------- triggers

@pytest.mark.parametrize("code", GLTF_CODES)
def test_code_is_triggered(code, folder, monkeypatch):
    trigger = va.TRIGGERS[code](folder)
    report = _run(trigger, monkeypatch)
    found = [f for f in report.findings if f.code == code]
    assert found, f"{code} not reported; got {sorted(report.codes())}"
    info = CATALOGUE[code]
    for f in found:
        assert f.severity == info.severity
        assert "\n" not in f.message and f.message
        assert f.pointer is None or f.pointer == "" or f.pointer.startswith("/")
        if f.examples is not None:
            assert len(f.examples) <= Options().max_examples
            assert f.count is not None and f.count >= len(f.examples)
    expected = 2 if info.unreadable else 1 if info.severity == Severity.ERROR else None
    if expected is not None:
        assert report.exit_status == expected
    json.dumps(report.to_json(), allow_nan=False)  # always serializable


@pytest.mark.parametrize("code", [c for c in GLTF_CODES if CATALOGUE[c].fatal])
def test_fatal_codes_stop_validation(code, folder, monkeypatch):
    report = _run(va.TRIGGERS[code](folder), monkeypatch)
    assert report.findings[-1].code == code
    assert report.info.get("splatPrimitives") is None


def test_glb_findings_carry_byte_offsets(folder):
    report = validate_file(va.TRIGGERS["GLB_UNKNOWN_CHUNK"](folder).path)
    (f,) = [f for f in report.findings if f.code == "GLB_UNKNOWN_CHUNK"]
    assert f.pointer is None and f.offset > 12
    report = validate_file(va.TRIGGERS["GLB_UNSUPPORTED_VERSION"](folder).path)
    assert report.findings[0].offset == 4


def test_pointers_name_the_offending_member(folder):
    report = validate_file(va.TRIGGERS["ANCHOR_FACE_OUT_OF_RANGE"](folder).path)
    (f,) = [f for f in report.findings if f.code == "ANCHOR_FACE_OUT_OF_RANGE"]
    assert f.pointer == ("/meshes/0/primitives/0/extensions/KHR_gaussian_splatting/extensions/"
                         "GSVERSE_gaussian_splatting_mesh_anchor/faceIndex")
    assert f.count == 1 and f.examples[0]["face"] == 200
    report = validate_file(va.TRIGGERS["ROTATION_NOT_UNIT"](folder).path)
    (f,) = [f for f in report.findings if f.code == "ROTATION_NOT_UNIT"]
    assert f.pointer == "/meshes/0/primitives/0/attributes/KHR_gaussian_splatting:ROTATION"
    assert f.count == 60


def test_rest_pose_reports_the_worst_splats(folder):
    d = va.Doc.of(va.local_asset())
    pos = d.values(d.attr("POSITION"))
    pos[[3, 9, 20]] += np.array([[0.01, 0, 0], [0.2, 0, 0], [0, 0.05, 0]], np.float32)
    report = validate_file(d.write(folder, "moved.glb"))
    (f,) = [f for f in report.findings if f.code == "REST_POSE_MEAN_MISMATCH"]
    assert f.count == 3
    assert [e["splat"] for e in f.examples] == [9, 20, 3]
    assert f.examples[0]["error"] == pytest.approx(0.2, rel=1e-3)


def test_rest_pose_tolerance_is_the_spec_tolerance(folder):
    # A mean moved by 0.5 x the tolerance passes; 2 x fails.
    for factor, flagged in ((0.5, False), (2.0, True)):
        d = va.Doc.of(va.local_asset())
        report = validate_file(d.write(folder, "ok.glb"))
        assert not report.findings
        v = d.values(d.doc["meshes"][2]["primitives"][0]["attributes"]["POSITION"])
        diagonal = float(np.linalg.norm(v.max(0).astype(float) - v.min(0)))
        largest = float(np.abs(v).max())
        pos = d.values(d.attr("POSITION"))
        pos[4, 2] += np.float32(factor * (1e-5 * diagonal + 8 * 2.0 ** -23 * largest))
        report = validate_file(d.write(folder, f"moved{factor}.glb"))
        assert ("REST_POSE_MEAN_MISMATCH" in report.codes()) == flagged


def test_rest_pose_tolerance_allows_float32_rounding_far_from_the_origin(folder):
    """A 1 mm mesh 100 m from the origin: float32 positions are 8e-6 m apart, more than
    1e-5 x D = 1.7e-8 m; the spec's 8 ulp term accepts the rounding, nothing more."""
    asset = va.local_asset()
    p = asset.primitives[0]
    mesh, cloud = p.anchoring.mesh, p.splats
    shift, size = np.array([100.0, -60.0, 30.0]), 1e-3
    far_mesh = TriangleMesh((mesh.vertices * size + shift).astype(np.float32), mesh.faces)
    anchors = bind_local(SplatCloud((cloud.means * size + shift).astype(np.float32),
                                    cloud.rotations, cloud.scales * size, cloud.opacities,
                                    cloud.sh), far_mesh).anchors
    rest = remap(Anchoring(far_mesh, anchors))
    far = SplatCloud(rest.means.astype(np.float32), rest.rotations.astype(np.float32),
                     rest.scales.astype(np.float32), cloud.opacities, cloud.sh)
    path = va.Doc.of(SplatAsset([SplatPrimitive(far, Anchoring(far_mesh, anchors), "far")])
                     ).write(folder, "far.glb")
    assert validate_file(path).findings == []
    d = va.Doc.of(SplatAsset([SplatPrimitive(far, Anchoring(far_mesh, anchors), "far")]))
    d.values(d.attr("POSITION"))[2, 0] += np.float32(2e-4)  # ~26 ulps: flagged
    assert "REST_POSE_MEAN_MISMATCH" in validate_file(d.write(folder, "farmoved.glb")).codes()


def test_barycentric_tolerances(folder):
    # games: a weight of -1e-6 is within the tolerance, -1e-3 is not.
    for low, flagged in ((-1e-6, False), (-1e-3, True)):
        d = va.Doc.of(va.games_asset())
        bary = d.values(d.ext()["barycentrics"])
        bary[0] = (0.25, 0.75 - low)
        report = validate_file(d.write(folder, "games.glb"))
        assert ("GAMES_BARYCENTRICS_OUTSIDE_SIMPLEX" in report.codes()) == flagged
    # local: weights outside the simplex are fine (foot of an edge/corner splat) ...
    d = va.Doc.of(va.local_asset(n=200, lift=0.1))
    bary = d.values(d.ext()["barycentrics"]).astype(np.float64)
    b0 = 1 - bary.sum(axis=1)
    assert (np.minimum(b0, bary.min(axis=1)) < -1e-3).any()
    assert not validate_file(d.write(folder, "local.glb")).findings


def test_severity_overrides_and_ignores(folder):
    path = va.TRIGGERS["ANCHOR_ACCESSOR_TARGET"](folder).path
    assert validate_file(path).exit_status == 0
    report = validate_file(path, overrides={"ANCHOR_ACCESSOR_TARGET": Severity.ERROR})
    assert report.exit_status == 1
    report = validate_file(path, overrides={"ANCHOR_ACCESSOR_TARGET": None})
    assert not report.findings
    path = va.TRIGGERS["REST_POSE_MEAN_MISMATCH"](folder).path
    report = validate_file(path, overrides={"REST_POSE_MEAN_MISMATCH": Severity.WARNING})
    assert report.exit_status == 0 and report.count(Severity.WARNING) == 1


def test_max_issues_truncates(folder):
    path = va.TRIGGERS["ANCHOR_MESH_SAME_AS_SPLAT"](folder).path
    report = validate_file(path, max_issues=1)
    assert len(report.findings) == 1 and report.issues.truncated


def _mixed(folder: pathlib.Path) -> pathlib.Path:
    """A file whose findings are found in the order warning, warning, hint, info, error: an
    unknown GLB chunk, a target on an anchor accessor's bufferView, splats out of face order,
    a floater far from the mesh, a moved rest POSITION."""
    d = va.Doc.of(va.local_asset(floater=True, shuffle=True))
    d.doc["bufferViews"][d.doc["accessors"][d.ext()["faceIndex"]]["bufferView"]]["target"] = 34962
    d.values(d.attr("POSITION"))[5, 0] += 0.05
    path = folder / "mixed.glb"
    path.write_bytes(va._append_chunk(d.glb(), 0x12345678, b"abcd"))
    return path


def test_reports_list_errors_then_warnings_infos_hints(folder, capsys):
    path = _mixed(folder)
    report = validate_file(path)
    found = [f.severity for f in report.findings]
    assert found[0] == Severity.WARNING and found[-1] == Severity.ERROR   # found out of order
    assert set(found) == set(Severity) and found.count(Severity.WARNING) == 2
    ordered = report.ordered_findings()
    assert [f.severity for f in ordered] == sorted(found)
    for severity in Severity:       # stable: in the order found within a severity
        assert [f for f in ordered if f.severity == severity] == \
            [f for f in report.findings if f.severity == severity]
    expected = [(str(f.code), f.severity.label) for f in ordered]
    assert cli.main(["--format", "json", str(path)]) == 1
    messages = json.loads(capsys.readouterr().out)["reports"][0]["issues"]["messages"]
    assert [(m["code"], m["severity"]) for m in messages] == expected
    assert cli.main([str(path)]) == 1
    lines = capsys.readouterr().out.splitlines()[1:]
    assert [tuple(line.split()[1::-1]) for line in lines] == expected


def test_max_issues_keeps_the_most_severe_findings(folder):
    """A capped report keeps the errors (and so its exit status): the most severe findings,
    the first found within a severity."""
    path = _mixed(folder)
    everything = validate_file(path).ordered_findings()
    for cap in (1, 2, 4):
        report = validate_file(path, max_issues=cap)
        assert report.issues.truncated and report.exit_status == 1
        assert report.ordered_findings() == everything[:cap]


def test_parse_severity():
    assert parse_severity("Warning") == Severity.WARNING
    assert parse_severity("information") == Severity.INFO
    assert parse_severity("0") == Severity.ERROR
    assert parse_severity("ignore") is None
    with pytest.raises(ValueError):
        parse_severity("fatal")


# ---------------------------------------------------------------------------- valid assets

def test_clean_assets_have_no_findings(folder):
    for path in va.clean_assets(folder):
        report = validate_file(path)
        assert report.findings == [], (path.name, [(f.code, f.message) for f in report.findings])
        assert report.exit_status == 0


@pytest.mark.parametrize("suffix,extra", [(".glb", []), (".gltf", ["--deformation", "rigid"])])
def test_convert_output_validates_clean(tmp_path, suffix, extra, capsys):
    from gsverse_format.cli.convert import main as convert

    out = tmp_path / f"anchored{suffix}"
    assert convert([str(ROOT / "examples/capsule/splats.ply"), str(out), "--mesh",
                    str(ROOT / "examples/capsule/mesh.obj"), "-q", *extra]) == 0
    report = validate_file(out)
    assert report.findings == [], [(f.code, f.message) for f in report.findings]
    assert report.info["splats"] == 3000 and report.info["anchoredPrimitives"] == 1


def test_far_barycentrics_of_converted_output_are_information_that_needs_nothing(tmp_path):
    """gsverse-convert binds every splat to its nearest triangle: splats off the surface next
    to an edge of small triangles get a barycentric weight below -1. That is information, and
    the catalogue says when it needs nothing and when it points at a real problem, with fixes
    that exist."""
    from gsverse_format.cli.convert import build_parser, main as convert
    from gsverse_format.examples import example_mesh, example_splats, write_obj
    from gsverse_format.io.ply import write_splat_ply

    mesh = example_mesh(subdivisions=4)
    cloud = example_splats(mesh, 500, seed=3)
    outward = cloud.means / np.linalg.norm(cloud.means, axis=1, keepdims=True)
    cloud.means = (cloud.means + 0.06 * outward).astype(np.float32)      # off the surface
    write_splat_ply(cloud, tmp_path / "splats.ply")
    write_obj(mesh, str(tmp_path / "mesh.obj"))
    out = tmp_path / "out.glb"
    assert convert([str(tmp_path / "splats.ply"), str(out), "--mesh",
                    str(tmp_path / "mesh.obj"), "-q"]) == 0
    report = validate_file(out)
    assert report.codes() == {Code.LOCAL_BARYCENTRICS_FAR} and report.exit_status == 0
    (finding,) = report.findings
    assert finding.severity == Severity.INFO and 0 < finding.count < 500 // 10
    info = CATALOGUE[Code.LOCAL_BARYCENTRICS_FAR]
    assert "Expected in converted assets" in info.trigger
    assert info.fix.startswith("Nothing, for a converted asset, unless ANCHOR_MESH_MISFIT")
    options = {o for action in build_parser()._actions for o in action.option_strings}
    named = set(re.findall(r"--[a-z-]+", info.fix))
    assert named and named <= options, named - options


def test_validator_never_writes(folder):
    paths = va.clean_assets(folder)
    before = {p: p.read_bytes() for p in folder.iterdir()}
    for p in paths:
        validate_file(p)
    assert {p: p.read_bytes() for p in folder.iterdir()} == before


# ---------------------------------------------------------------------------- command line

def test_cli_exit_status_and_text(folder, capsys):
    good = va.clean_assets(folder)[0]
    bad = va.TRIGGERS["REST_POSE_MEAN_MISMATCH"](folder).path
    assert cli.main([str(good)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{good}: 0 errors, 0 warnings, 0 infos, 0 hints")
    assert cli.main([str(good), str(bad)]) == 1
    out = capsys.readouterr().out
    assert "error    REST_POSE_MEAN_MISMATCH /meshes/0/primitives/0/attributes/POSITION" in out
    assert "e.g. splat=5" in out
    assert cli.main([str(good), str(bad), str(folder / "nope.glb")]) == 2
    assert "IO_ERROR: file not found" in capsys.readouterr().out
    assert cli.main(["-q", str(bad)]) == 1
    assert len(capsys.readouterr().out.splitlines()) == 1


def test_cli_json(folder, capsys):
    bad = va.TRIGGERS["ANCHOR_FACE_OUT_OF_RANGE"](folder).path
    assert cli.main(["--format", "json", str(bad)]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc["validator"] == "gsverse-validate"
    (report,) = doc["reports"]
    assert report["mimeType"] == "model/gltf-binary"
    assert report["exitStatus"] == 1
    issues = report["issues"]
    assert issues["numErrors"] == len([m for m in issues["messages"] if m["severity"] == "error"])
    msg = [m for m in issues["messages"] if m["code"] == "ANCHOR_FACE_OUT_OF_RANGE"][0]
    assert set(msg) >= {"code", "severity", "message", "pointer", "count", "examples"}


def test_cli_overrides_config_and_usage_errors(folder, tmp_path, capsys):
    path = va.TRIGGERS["REST_POSE_MEAN_MISMATCH"](folder).path
    assert cli.main(["--severity", "REST_POSE_MEAN_MISMATCH=warning", str(path)]) == 0
    assert cli.main(["--ignore", "REST_POSE_MEAN_MISMATCH", str(path)]) == 0
    config = tmp_path / "config.json"
    config.write_text(json.dumps({"severityOverrides": {"REST_POSE_MEAN_MISMATCH": "hint"},
                                  "ignoredIssues": [], "maxIssues": 0}))
    assert cli.main(["--config", str(config), str(path)]) == 0
    capsys.readouterr()
    assert cli.main(["--severity", "REST_POSE_MEAN_MISMATCHH=warning", str(path)]) == 2
    assert "did you mean REST_POSE_MEAN_MISMATCH" in capsys.readouterr().err
    assert cli.main(["--severity", "REST_POSE_MEAN_MISMATCH=fatal", str(path)]) == 2
    assert cli.main(["--severity", "REST_POSE_MEAN_MISMATCH", str(path)]) == 2
    config.write_text(json.dumps({"severity": {}}))
    assert cli.main(["--config", str(config), str(path)]) == 2
    assert cli.main([]) == 2
    assert cli.main(["--max-bytes", "lots", str(path)]) == 2
    assert cli.main(["--bogus", str(path)]) == 2
    assert cli.main(["--version"]) == 0


def test_cli_caps(folder, capsys):
    path = va.clean_assets(folder)[1]  # .gltf with an embedded data: URI
    assert cli.main(["--max-data-uri-bytes", "1k", str(path)]) == 1
    assert "DATA_URI_TOO_LARGE" in capsys.readouterr().out
    assert cli.main(["--max-bytes", "2K", str(path)]) == 1
    assert "SIZE_LIMIT_EXCEEDED" in capsys.readouterr().out
    assert cli.main(["--max-splats", "10", str(path)]) == 1
    assert cli.main(["--max-bytes", "1G", "--max-splats", "1000", str(path)]) == 0
    assert cli.parse_size("512M") == 512 * 2 ** 20 and cli.parse_size("7") == 7
    assert cli.parse_size("2GiB") == 2 ** 31


def test_cli_list_codes(capsys):
    assert cli.main(["--list-codes"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines] == list(CATALOGUE)
    assert cli.main(["--list-codes", "--format", "json"]) == 0
    assert [c["code"] for c in json.loads(capsys.readouterr().out)] == list(CATALOGUE)


def test_console_script_is_declared():
    text = (ROOT / "pyproject.toml").read_text()
    assert 'gsverse-validate = "gsverse_format.validators.cli:main"' in text


def test_matrix_accessors_are_bounds_checked_not_rejected(folder):
    d = va.Doc.of(va.local_asset())
    i = d.add_accessor(np.tile(np.eye(4, dtype=np.float32).reshape(1, 16), (3, 1)), 5126, "VEC4")
    d.doc["accessors"][i].update(type="MAT4", count=3)  # 3 matrices in the 3x16 floats
    d.doc["skins"] = [{"joints": [0], "inverseBindMatrices": i}]
    assert validate_file(d.write(folder, "skin.glb")).findings == []
    d.doc["accessors"][i]["count"] = 4
    report = validate_file(d.write(folder, "skin_oob.glb"))
    assert report.codes() == {"ACCESSOR_OUT_OF_BOUNDS"}


def test_shared_sample_files_never_fail_internally(shared_data):
    files = sorted(p for p in shared_data.rglob("*") if p.suffix in (".glb", ".gltf"))
    assert files
    for path in files:
        report = validate_file(path)
        assert "INTERNAL_ERROR" not in report.codes(), path
        assert report.exit_status in (0, 1)
    matrix = validate_file(shared_data / "khr_gaussian" / "bevy_khr_conformance_matrix.glb")
    assert matrix.info["splatPrimitives"] == 15
    # Its signed-integer scales are not among the formats KHR_gaussian_splatting allows.
    assert "KHR_ATTRIBUTE_FORMAT" in matrix.codes()


# ---------------------------------------------------------------------------- reader rules

def test_every_node_counts_for_multiple_instances_scene_or_not(folder, tmp_path):
    """spec §The anchor mesh: every entry of nodes that instantiates the anchor mesh counts,
    whether a scene lists it or not. The validator, the reader and the minimal reader agree."""
    from gsverse_format.conformance.minimal_reader import Refused, read_anchored_glb
    from gsverse_format.io.gltf import GltfFormatError, read_gltf

    d = va.Doc.of(va.local_asset())
    scene_nodes = d.doc["scenes"][0]["nodes"]
    d.doc["nodes"].append({"mesh": d.ext()["mesh"], "name": "in the scene"})
    scene_nodes.append(len(d.doc["nodes"]) - 1)
    one = d.write(folder, "one.glb")
    d.doc["nodes"].append({"mesh": d.ext()["mesh"], "name": "in no scene"})
    two = d.write(folder, "two.glb")
    assert "ANCHOR_MESH_MULTIPLE_INSTANCES" not in validate_file(one).codes()
    read_gltf(one)
    read_anchored_glb(one)
    assert "ANCHOR_MESH_MULTIPLE_INSTANCES" in validate_file(two).codes()
    with pytest.raises(GltfFormatError) as err:
        read_gltf(two)
    assert err.value.code == Code.ANCHOR_MESH_MULTIPLE_INSTANCES
    with pytest.raises(Refused, match="instantiated by 2 nodes"):
        read_anchored_glb(two)


def test_a_splat_primitive_without_mode_is_triangles_and_refused(folder):
    """glTF's default mode is TRIANGLES (4): an anchored splat primitive without mode is
    refused (spec §Where the extension object lives)."""
    from gsverse_format.conformance.minimal_reader import Refused, read_anchored_glb
    from gsverse_format.io.gltf import GltfFormatError, read_gltf

    d = va.Doc.of(va.local_asset())
    del d.prim(0)["mode"]
    path = d.write(folder, "no-mode.glb")
    report = validate_file(path)
    assert "KHR_PRIMITIVE_NOT_POINTS" in report.codes() and report.exit_status == 1
    with pytest.raises(GltfFormatError) as err:
        read_gltf(path)
    assert err.value.code == Code.KHR_PRIMITIVE_NOT_POINTS
    with pytest.raises(Refused, match="POINTS"):
        read_anchored_glb(path)
