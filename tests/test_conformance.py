"""The engine-plugin conformance suite: export, runner, reference implementations, native
header, and deliberately broken implementations that must fail the cases they should.

The suite is exported once per module. Every implementation runs as a plugin would: it writes
dumps (``RESULTS/<case>/...``) and the runner (:func:`check_results`) judges them.
"""
from __future__ import annotations

import json
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

import gsverse_format.quaternion as quaternion
import gsverse_format.remapping.reference as remap_module
from gsverse_format import frames as frames_module
from gsverse_format.conformance import cases as case_defs
from gsverse_format.conformance import cases_rig as rig_defs
from gsverse_format.conformance import cases_spz as spz_defs
from gsverse_format.conformance import invalid_cases as invalid_defs
from gsverse_format.conformance import render_export
from gsverse_format.conformance.render_export import copy_reference_pictures
from gsverse_format.conformance.check import check_results, format_text, quat_to_matrix
from gsverse_format.conformance.cli import main
from gsverse_format.conformance.export import export_suite
from gsverse_format.conformance.harness import (FastPlugin, RawReferencePlugin, ReferencePlugin,
                                                Refused, read_asset, run_plugin, suite_cases)
from gsverse_format.conformance.minimal_reader import Raw
from gsverse_format.frames import LocalFrames

from test_conformance_native import CPlugin, build, compiler


# --------------------------------------------------------------------------- fixtures

@pytest.fixture(scope="module")
def suite(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("conformance") / "suite"
    export_suite(path)
    return path


@pytest.fixture(scope="module")
def manifests(suite) -> dict[str, dict]:
    return {m["id"]: m for _, m in suite_cases(suite)}


@pytest.fixture(scope="module")
def clib(tmp_path_factory):
    if compiler() is None:
        pytest.skip("no C compiler (cc) on this machine")
    return build(tmp_path_factory.mktemp("native"), real="double")


def _run(suite: Path, out: Path, factory) -> "Report":  # noqa: F821
    run_plugin(suite, out, factory)
    return check_results(suite, out, level="numbers")


def _failed(report) -> set[str]:
    return {c.id for c in report.cases if c.status != "pass"}


def _ids(manifests: dict, pred) -> set[str]:
    return {cid for cid, m in manifests.items() if pred(m)}


def _tagged(manifests: dict, prefix: str) -> set[str]:
    return _ids(manifests, lambda m: any(t.startswith(prefix) for t in m["tags"]))


# --------------------------------------------------------------------------- the suite

def test_suite_covers_what_plugins_must_handle(suite, manifests):
    index = json.loads((suite / "suite.json").read_text())
    assert index["version"] == 3 and (suite / "LAYOUT.md").is_file()
    tags = {t for m in manifests.values() for t in m["tags"]}
    for needed in ["profile:local", "profile:games", "deformation:affine", "deformation:rigid",
                   "sh_degree:0", "sh_degree:1", "sh_degree:2", "sh_degree:3",
                   "splats_per_face:1-6", "placement:vertices-edges", "face_index:u16",
                   "face_index:u32", "quantized:barycentrics=unsigned_short",
                   "quantized:barycentrics=unsigned_byte", "quantized:localRotation=short",
                   "quantized:localRotation=byte", "source:stretch", "source:twist",
                   "source:bend", "source:shake", "source:skin", "extreme:zero-area",
                   "extreme:degenerate-rest", "extreme:sliver", "extreme:inverted",
                   "extreme:stretch-100x", "extreme:compress-0.01x", "extreme:offset-1e5",
                   "extreme:scales", "extreme:near-coincident", "invalid", "rule:threshold",
                   "rule:games-degenerate", "rule:ties", "rule:scale", "rule:rest-precision",
                   "rule:quaternion-norm", "encoding:face-counts", "encoding:derived"]:
        assert needed in tags, needed
    # every family exists for both profiles and both laws
    for family in ("stretch", "twist", "bend", "shake", "skinned", "zero-area-pose", "sliver",
                   "inverted", "stretch-100x", "compress-0.01x", "offset-1e5",
                   "extreme-scales", "near-coincident-vertices", "degenerate-rest",
                   "threshold-crossing", "scale-1e-4", "scale-1", "scale-1e4"):
        for law in ("local-affine", "local-rigid", "games"):
            assert f"{law}-{family}" in manifests
    # per-face counts 1..6 really occur
    m = manifests["local-affine-splats-per-face-1-to-6"]
    face = np.unique(_anchor_faces(suite, m), return_counts=True)[1]
    assert set(face) == {1, 2, 3, 4, 5, 6}
    assert len(_ids(manifests, lambda m: m["kind"] == "invalid")) >= 15
    size = sum(p.stat().st_size for p in suite.rglob("*") if p.is_file())
    # a few MB: the numbers level about 6.2 (the rig cases 0.4), the render level 0.9
    assert size < 7.5e6, size


def test_suite_covers_valid_encodings(suite, manifests):
    """The encodings a reader must accept besides the writer's own layout (cases_encodings)."""
    from gsverse_format.conformance.glb import unpack_glb

    tags = {t for m in manifests.values() for t in m["tags"]}
    for needed in ("encoding:localScale=unsigned_byte", "encoding:localScale=unsigned_short",
                   "encoding:localScale=unsigned_byte_normalized",
                   "encoding:localScale=unsigned_short_normalized", "encoding:rest-quantized",
                   "encoding:byte-stride", "encoding:non-indexed", "encoding:node-transforms"):
        assert needed in tags, needed
    for family in ("rest-quantized", "byte-stride", "non-indexed", "node-transforms"):
        for law in ("local-affine", "local-rigid", "games"):
            assert f"{law}-{family}" in manifests
    for cid in _tagged(manifests, "encoding:non-indexed"):
        anchor = manifests[cid]["anchor"]
        assert not anchor["indexed"] and anchor["face_count"] * 3 == anchor["vertex_count"]
    for cid in _tagged(manifests, "encoding:byte-stride"):
        doc, _ = unpack_glb((suite / "cases" / cid / "asset.glb").read_bytes())
        ext = [p for m in doc["meshes"] for p in m["primitives"] if p["mode"] == 0][0][
            "extensions"]["KHR_gaussian_splatting"]["extensions"][
            "GSVERSE_gaussian_splatting_mesh_anchor"]
        views = {doc["accessors"][ext[k]]["bufferView"] for k in ("faceIndex", "barycentrics")}
        assert len(views) == 1 and "byteStride" in doc["bufferViews"][views.pop()]
        pos = doc["meshes"][ext["mesh"]]["primitives"][0]["attributes"]["POSITION"]
        assert "byteStride" in doc["bufferViews"][doc["accessors"][pos]["bufferView"]]
    for cid in _tagged(manifests, "encoding:node-transforms"):
        doc, _ = unpack_glb((suite / "cases" / cid / "asset.glb").read_bytes())
        moved = [n for n in doc["nodes"] if n.get("mesh") is not None
                 and ({"matrix", "translation", "rotation", "scale"} & set(n))]
        assert {n["mesh"] for n in moved} == {0, 1}, cid
    invalid = _ids(manifests, lambda m: m["kind"] == "invalid")
    for cid in ("invalid-local-rotation-zero", "invalid-local-scale-negative",
                "invalid-non-finite-rest-position", "invalid-non-finite-rest-rotation",
                "invalid-non-finite-rest-scale", "invalid-splat-primitive-not-points",
                "invalid-anchor-mesh-multiple-instances", "invalid-splat-primitive-mode-absent",
                "invalid-anchor-mesh-instance-outside-scenes",
                "invalid-anchor-accessor-no-buffer-view"):
        assert cid in invalid


def _anchor_faces(suite: Path, manifest: dict) -> np.ndarray:
    return read_asset(str(suite / "cases" / manifest["id"] / "asset.glb")).primitives[0] \
        .anchoring.anchors.face_index


def test_manifests_files_and_tolerances(suite, manifests):
    for cid, m in manifests.items():
        folder = suite / "cases" / cid
        assert (folder / m["files"]["asset"]).is_file()
        if m["kind"] == "invalid":
            assert m["expect"] == "refuse" and m["rule"]
            continue
        v = m["anchor"]["vertex_count"]
        n = m["splat_count"]
        key = "deformed" if m["kind"] == "rig" else "file"   # rig cases ship p', not poses
        for pose in m["poses"]:
            assert (folder / pose[key]).stat().st_size == v * 3 * 4
        for exp in m["files"]["expected"]["poses"]:
            assert (folder / exp["means"]).stat().st_size == n * 3 * 8
            assert (folder / exp["cov"]).stat().st_size == n * 6 * 8
        assert m["poses"][0]["source"]["kind"] == "rest"
        pose0 = np.fromfile(folder / m["poses"][0][key], "<f4").reshape(-1, 3)
        for key, tol in m["tolerances"].items():
            assert tol["reason"] and tol["metric"], (cid, key)
        assert 0 < m["tolerances"]["mean"]["atol"] and 0 < m["tolerances"]["covariance"]["rtol"]
        # per pose; at rest every case is well conditioned
        assert len(m["tolerances"]["covariance"]["per_pose"]) == len(m["poses"])
        if "rule:rest-precision" not in m["tags"]:   # those rest on slivers of height ~2e-6
            assert m["tolerances"]["covariance"]["per_pose"][0] < 0.02, cid
        assert max(m["tolerances"]["mean"]["per_pose"]) <= m["tolerances"]["mean"]["atol"]
        assert pose0.shape == (v, 3)
    # skinned cases ship the animation they were sampled from
    assert (suite / "cases" / "games-skinned" / "skinned.glb").is_file()
    assert "quantized" in " ".join(manifests["games-quantized-bary-u8"]["tags"])
    assert manifests["games-quantized-bary-u8"]["anchor"]["component_types"]["barycentrics"] \
        == "UNSIGNED_BYTE normalized"
    assert manifests["local-rigid-face-index-u32"]["anchor"]["component_types"]["faceIndex"] \
        == "UNSIGNED_INT"


def test_expected_outputs_are_the_reference_on_the_stored_values(suite, manifests):
    """Spot check: expected arrays equal the float64 reference on the file's anchors and the
    float32 pose, and pose 0 (the rest) reproduces the stored rest pose."""
    from gsverse_format.io.gltf import read_gltf
    from gsverse_format.remapping.reference import remap

    for cid in ("local-affine-quantized-bary-u8-rot-i16", "games-offset-1e5", "local-rigid-skinned"):
        m = manifests[cid]
        folder = suite / "cases" / cid
        prim = read_gltf(folder / "asset.glb").primitives[0]   # uncached: the file as it is
        for p, exp in enumerate(m["files"]["expected"]["poses"]):
            verts = np.fromfile(folder / m["poses"][p]["file"], "<f4").reshape(-1, 3)
            r = remap(prim.anchoring, verts)
            got = np.fromfile(folder / exp["means"], "<f8").reshape(-1, 3)
            np.testing.assert_array_equal(got, r.means)
        rest = np.fromfile(folder / m["files"]["expected"]["poses"][0]["means"], "<f8").reshape(-1, 3)
        scale = np.abs(prim.splats.means).max() + 1.0
        assert np.max(np.abs(rest - prim.splats.means)) <= 1e-6 * scale


# --------------------------------------------------------------------------- reference implementations

def test_numpy_reference_passes_every_case(suite, tmp_path):
    report = _run(suite, tmp_path / "numpy", ReferencePlugin)
    assert report.ok, format_text(report)
    assert report.summary["passed"] == len(report.cases) >= 70


def test_numpy_reference_passes_with_rotation_scale_dumps(suite, tmp_path):
    report = _run(suite, tmp_path / "numpy-rs", lambda: ReferencePlugin("rotscale"))
    assert report.ok, format_text(report)


def test_minimal_reader_passes_every_case(suite, tmp_path):
    """The importer written without a glTF library refuses exactly the invalid assets."""
    report = _run(suite, tmp_path / "raw", RawReferencePlugin)
    assert report.ok, format_text(report)


def test_fast_path_passes_every_case(suite, tmp_path):
    fast = pytest.importorskip("gsverse_format.remapping.fast")
    backend = "numba" if fast.numba_available() else "numpy"
    report = _run(suite, tmp_path / "fast", lambda: FastPlugin(backend))
    assert report.ok, format_text(report)


@pytest.mark.parametrize("real,form", [("double", "cov"), ("double", "rotscale"),
                                       ("float", "cov"), ("float", "rotscale")])
def test_c_header_passes_every_case(suite, tmp_path, real, form, clib):
    lib = clib if real == "double" else build(tmp_path, real=real)
    report = _run(suite, tmp_path / f"c-{real}-{form}", lambda: CPlugin(lib, form))
    assert report.ok, format_text(report)


# --------------------------------------------------------------------------- runner and CLI

def test_cli_check_text_json_and_exit_codes(suite, tmp_path, capsys, manifests):
    results = tmp_path / "res"
    run_plugin(suite, results, ReferencePlugin, info={"name": "reference"})
    # numbers only: the render cases are missing, and the default level checks both
    assert main(["check", str(suite), str(results)]) == 1
    assert main(["check", str(suite), str(results), "--level", "numbers"]) == 0
    capsys.readouterr()
    n_render = copy_reference_pictures(suite, results)   # what 'dump' adds
    assert n_render >= 7
    assert main(["check", str(suite), str(results)]) == 0
    out = capsys.readouterr().out
    total = len(manifests) + n_render
    assert f"{total} passed, 0 failed, 0 missing" in out and "harness: name=reference" in out
    assert main(["check", str(suite), str(results), "--format", "json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["summary"] == {"total": total, "passed": total, "failed": 0, "missing": 0,
                                 "unsupported": 0,
                                 "render": n_render}
    turn = next(c for c in report["cases"] if c["id"] == "render-turn-180")
    assert turn["kind"] == "render" and len(turn["frames"]) == 3
    case = next(c for c in report["cases"] if c["id"] == "local-affine-twist")
    assert case["status"] == "pass" and case["worst"]["quantity"] in ("mean", "covariance")
    assert {c["quantity"] for c in case["checks"]} == {"mean", "covariance", "opacity", "sh"}

    # break one case: shift one mean by 10x its tolerance
    folder = results / "local-affine-twist"
    means = np.fromfile(folder / "pose_002.means.f64", "<f8").reshape(-1, 3)
    atol = manifests["local-affine-twist"]["tolerances"]["mean"]["atol"]
    means[7, 1] += 10 * atol
    means.astype("<f8").tofile(folder / "pose_002.means.f64")
    assert main(["check", str(suite), str(results), "--format", "json"]) == 1
    report = json.loads(capsys.readouterr().out)
    case = next(c for c in report["cases"] if c["id"] == "local-affine-twist")
    assert case["status"] == "fail"
    assert case["worst"]["dump"] == "pose_002" and case["worst"]["splat"] == 7
    assert case["worst"]["pose"] == 2 and 9 < case["worst"]["ratio"] < 11
    assert report["summary"]["failed"] == 1
    assert main(["check", str(suite), str(tmp_path / "nowhere")]) == 2
    assert main(["check", str(tmp_path), str(results)]) == 2
    capsys.readouterr()


def test_runner_flags_missing_wrong_nonfinite_and_refusals(suite, tmp_path, manifests):
    results = tmp_path / "res"
    run_plugin(suite, results, ReferencePlugin)
    (results / "local-rigid-bend" / "pose_001.cov.f64").unlink()
    bad = results / "games-twist" / "pose_002.means.f64"
    bad.write_bytes(bad.read_bytes()[:-8])
    nan = results / "games-bend" / "pose_001.cov.f64"
    cov = np.fromfile(nan, "<f8")
    cov[3] = np.nan
    cov.tofile(nan)
    (results / "local-affine-stretch" / "refused").write_text("nope")
    (results / "invalid-unknown-profile" / "refused").unlink()
    import shutil

    shutil.rmtree(results / "games-shake")
    report = check_results(suite, results, level="numbers")
    by = {c.id: c for c in report.cases}
    assert "missing dump pose_001.cov" in by["local-rigid-bend"].message
    assert "has" in by["games-twist"].message and "expected" in by["games-twist"].message
    assert by["games-bend"].status == "fail" and "not finite" in by["games-bend"].message
    assert "refused a valid asset: nope" in by["local-affine-stretch"].message
    assert by["invalid-unknown-profile"].status == "fail"
    assert "accepted an invalid asset" in by["invalid-unknown-profile"].message
    assert by["games-shake"].status == "missing"
    assert report.summary == {"total": len(manifests), "passed": len(manifests) - 6,
                              "failed": 5, "missing": 1, "unsupported": 0, "render": 0}
    text = format_text(report)
    assert "FAIL    games-bend" in text and "MISSING games-shake" in text


def test_cli_export_and_dump(tmp_path, capsys, monkeypatch):
    """The console entry points (export and dump on a reduced suite)."""
    remap_cases, invalid_cases = case_defs._per_face_cases, invalid_defs.invalid_cases
    renders = render_export.render_cases
    monkeypatch.setattr(case_defs, "remap_cases", lambda: remap_cases()[:1])
    monkeypatch.setattr(invalid_defs, "invalid_cases", lambda: invalid_cases()[:2])
    monkeypatch.setattr(render_export, "render_cases", lambda: renders()[:1])
    monkeypatch.setattr(rig_defs, "rig_cases", lambda: [])
    monkeypatch.setattr(rig_defs, "rig_invalid_cases", lambda: [])
    monkeypatch.setattr(spz_defs, "spz_invalid_cases", lambda: [])
    assert main(["export", str(tmp_path / "s")]) == 0
    out = capsys.readouterr().out
    assert "1 render cases" in out and "0 rig cases" in out
    assert main(["dump", str(tmp_path / "s"), str(tmp_path / "r")]) == 0
    assert main(["check", str(tmp_path / "s"), str(tmp_path / "r")]) == 0
    assert "4 passed" in capsys.readouterr().out
    assert main(["export", str(tmp_path / "s")]) == 0            # a previous suite is replaced
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "file.txt").write_text("x")
    assert main(["export", str(tmp_path / "other")]) == 2        # a foreign folder is not
    assert "not an empty folder" in capsys.readouterr().err


# --------------------------------------------------------------------------- broken implementations

def _wrong_axis_local_frames(tri):
    """Local frames with t along e2 instead of e1 (a wrong frame axis)."""
    good = _ORIGINAL_LOCAL(tri)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    t = e2 / np.linalg.norm(e2, axis=1, keepdims=True)
    n = good.rotation[:, :, 2]
    b = np.cross(n, t)
    rot = np.stack([t, b, n], axis=-1)
    shape = np.stack([np.stack([np.einsum("ij,ij->i", e1, t), np.einsum("ij,ij->i", e2, t)], -1),
                      np.stack([np.einsum("ij,ij->i", e1, b), np.einsum("ij,ij->i", e2, b)], -1)], 1)
    reg = good.regular[:, None, None]
    return LocalFrames(good.origin, np.where(reg, rot, good.rotation), np.where(reg, shape, good.shape),
                       good.area2, good.regular)


def _general_prepare_rest(rest_triangles):
    """prepare_rest with a general 2x2 inverse (the wrong-axis frames are not triangular)."""
    fr = remap_module.local_frames(rest_triangles)
    inv = np.tile(np.eye(2), (len(fr.shape), 1, 1))
    inv[fr.regular] = np.linalg.inv(fr.shape[fr.regular])
    return remap_module.RestData(fr.rotation, inv, fr.area2, fr.regular)


def _wrong_axis_games_frames(tri):
    """GaMeS frames with b1 towards v2 instead of v1."""
    rot, base, c = _ORIGINAL_GAMES(tri[:, [0, 2, 1]])
    return rot, base, c


def _no_rule_local_frames(tri):
    """The regular-triangle formulas for every triangle (no degenerate rules)."""
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    cross = np.cross(e1, e2)
    with np.errstate(all="ignore"):
        a = np.linalg.norm(cross, axis=1)
        l1 = np.linalg.norm(e1, axis=1)
        t = e1 / l1[:, None]
        n = cross / a[:, None]
        b = np.cross(n, t)
        shape = np.zeros((len(tri), 2, 2))
        shape[:, 0, 0] = l1
        shape[:, 0, 1] = np.einsum("ij,ij->i", e2, t)
        shape[:, 1, 1] = a / l1
    return LocalFrames(tri[:, 0].copy(), np.stack([t, b, n], -1), shape, a,
                       np.ones(len(tri), bool))


def _no_rule_games_frames(tri):
    rot, base, c = _ORIGINAL_GAMES(tri)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    cross = np.cross(e1, e2)
    with np.errstate(all="ignore"):
        n = cross / np.linalg.norm(cross, axis=1, keepdims=True)
        b1 = rot[:, :, 1]
        b2 = np.cross(n, b1)
        w = tri[:, 2] - c
        base = base.copy()
        base[:, 2] = np.einsum("ij,ij->i", w, b2) / 2
    return np.stack([n, b1, b2], -1), base, c


def _absolute_eps_local_frames(tri):
    """Degenerate when the doubled area is below 1e-12 (an absolute epsilon)."""
    good = _ORIGINAL_LOCAL(tri)
    bad = _no_rule_local_frames(tri)
    a = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    use_bad = (a > 1e-12) != good.regular
    sel = use_bad[:, None, None]
    point = ~(a > 1e-12)
    rot = np.where(sel, bad.rotation, good.rotation)
    rot[point] = np.eye(3)
    shape = np.where(sel, bad.shape, good.shape)
    shape[point] = 0.0
    return LocalFrames(good.origin, rot, shape, np.where(a > 1e-12, a, 0.0), a > 1e-12)


_ORIGINAL_LOCAL = frames_module.local_frames
_ORIGINAL_GAMES = frames_module.games_frames


class _Float16Plugin(ReferencePlugin):
    """Per-face data from the reference, per-splat sums accumulated in float16."""

    def apply_pose(self, vertices):
        h = np.float16
        anchoring = self.prim.anchoring
        a = anchoring.anchors
        tri = anchoring.mesh.triangles(vertices)
        face = a.face_index.astype(np.intp)
        v0 = tri[face, 0].astype(h)
        e1 = (tri[face, 1] - tri[face, 0]).astype(h)
        e2 = (tri[face, 2] - tri[face, 0]).astype(h)
        b = a.barycentrics.astype(h)
        if a.profile == "games":
            rot, base, _ = frames_module.games_frames(tri)
            sc = (np.maximum(a.rho[:, None].astype(h) * base[face].astype(h), h(0)) + h(1e-8))
            m = rot[face].astype(h) * sc[:, None, :]
            means = v0 + b[:, 0:1] * e1 + b[:, 1:2] * e2
        else:
            ref = remap_module.remap(anchoring, vertices, rest=self.rest_data)
            fr = frames_module.local_frames(tri)
            k = remap_module._size_factor(fr.area2, self.rest_data, face)
            n = fr.rotation[face][:, :, 2]
            means = v0 + b[:, 0:1] * e1 + b[:, 1:2] * e2 + (a.normal_offset * k)[:, None].astype(h) * n.astype(h)
            # M = R S from the reference pair, summed in float16
            m = (quat_to_matrix(ref.rotations) * ref.scales[:, None, :]).astype(h)
        cov = np.zeros((len(face), 3, 3), h)
        for i in range(3):
            for j in range(3):
                acc = np.zeros(len(face), h)
                for kk in range(3):
                    acc = (acc + m[:, i, kk] * m[:, j, kk]).astype(h)
                cov[:, i, j] = acc
        from gsverse_format.conformance.harness import cov6

        return {"means": means.astype(np.float32), "cov": cov6(cov.astype(np.float32))}


class _ShRotatingPlugin(ReferencePlugin):
    """Negates the degree-1 SH band after posing (as if it rotated SH with the splat)."""

    def splat_data(self):
        out = super().splat_data()
        sh = out["sh"].copy()
        sh[:, 1:4] *= -1.0
        return {"opacity": out["opacity"], "sh": sh}


class _LenientPlugin(ReferencePlugin):
    """Never refuses: when the importer fails it silently loads nothing."""

    def load(self, asset_path):
        try:
            super().load(asset_path)
            self.empty = False
        except Refused:
            self.empty = True

    def rest(self):
        return {} if self.empty else super().rest()

    def apply_pose(self, vertices):
        return {} if self.empty else super().apply_pose(vertices)

    def splat_data(self):
        return {} if self.empty else super().splat_data()


def _pow2_dequantize(raw: Raw) -> np.ndarray:
    """Normalized integers divided by 2^n instead of 2^n - 1."""
    v = raw.values.astype(np.float64)
    if not raw.normalized:
        return v
    return v / {5121: 256.0, 5123: 65536.0, 5120: 128.0, 5122: 32768.0}[raw.component_type]


def _to_matrix_unnormalized(q):
    """Rotation matrix formula applied to a quaternion that is not unit length."""
    q = np.asarray(q, dtype=np.float64)
    x, y, z, w = np.moveaxis(q, -1, 0)
    m = np.empty(x.shape + (3, 3))
    m[..., 0, 0] = w * w + x * x - y * y - z * z
    m[..., 0, 1] = 2 * (x * y - w * z)
    m[..., 0, 2] = 2 * (x * z + w * y)
    m[..., 1, 0] = 2 * (x * y + w * z)
    m[..., 1, 1] = w * w - x * x + y * y - z * z
    m[..., 1, 2] = 2 * (y * z - w * x)
    m[..., 2, 0] = 2 * (x * z - w * y)
    m[..., 2, 1] = 2 * (y * z + w * x)
    m[..., 2, 2] = w * w - x * x - y * y + z * z
    return m


@contextmanager
def _patched(monkeypatch, **attrs):
    with monkeypatch.context() as mp:
        for dotted, value in attrs.items():
            module, name = dotted.rsplit(".", 1)
            mp.setattr({"remap": remap_module, "quaternion": quaternion}[module], name, value)
        yield


def test_broken_wrong_local_frame_axis_fails_exactly_the_local_cases(suite, manifests,
                                                                   tmp_path, monkeypatch):
    with _patched(monkeypatch, **{"remap.local_frames": _wrong_axis_local_frames,
                                  "remap.prepare_rest": _general_prepare_rest}), \
            np.errstate(all="ignore"):
        report = _run(suite, tmp_path / "r", ReferencePlugin)
    # the affine rest-sliver case has rest triangles of height ~2e-6 of their length, whose
    # float32 covariances have no resolution to tell the frame axes apart (its means are exact)
    assert _failed(report) == (_tagged(manifests, "profile:local") - _tagged(manifests, "invalid")
                               - {"local-affine-rest-sliver-opened"})


def test_broken_wrong_games_frame_axis_fails_exactly_the_games_cases(suite, manifests,
                                                                   tmp_path, monkeypatch):
    with _patched(monkeypatch, **{"remap.games_frames": _wrong_axis_games_frames}):
        report = _run(suite, tmp_path / "r", ReferencePlugin)
    assert _failed(report) == _tagged(manifests, "profile:games") - _tagged(manifests, "invalid")


def test_broken_missing_degenerate_rules_fail_exactly_the_degenerate_cases(suite, manifests,
                                                                         tmp_path, monkeypatch):
    with _patched(monkeypatch, **{"remap.local_frames": _no_rule_local_frames,
                                  "remap.games_frames": _no_rule_games_frames}), \
            np.errstate(all="ignore"):
        report = _run(suite, tmp_path / "r", ReferencePlugin)
    # the affine law and the means need no frame of the current triangle (spec v1.1), so the
    # affine zero-area poses pass without the degenerate frame rules
    assert _failed(report) == _tagged(manifests, "degenerate:") - {"local-affine-zero-area-pose"}
    assert all("not finite" in c.message or "harness error" in c.message
               for c in report.cases if c.status == "fail")


def test_broken_absolute_epsilon_fails_the_tiny_and_degenerate_cases(suite, manifests,
                                                                    tmp_path, monkeypatch):
    with _patched(monkeypatch, **{"remap.local_frames": _absolute_eps_local_frames}), \
            np.errstate(all="ignore"):
        report = _run(suite, tmp_path / "r", ReferencePlugin)
    failed = _failed(report)
    local_tiny = _tagged(manifests, "extreme:near-coincident") & _tagged(manifests, "profile:local")
    assert local_tiny <= failed
    assert failed <= (_tagged(manifests, "degenerate:") | local_tiny)


def test_broken_float16_accumulation_fails(suite, manifests, tmp_path):
    with np.errstate(all="ignore"):
        report = _run(suite, tmp_path / "r", _Float16Plugin)
    failed = _failed(report)
    remap_cases = _ids(manifests, lambda m: m["kind"] in ("remap", "rig"))
    for cid in ("local-affine-offset-1e5", "games-offset-1e5", "local-rigid-extreme-scales",
                "local-affine-stretch", "games-twist", "local-rigid-skinned",
                "games-near-coincident-vertices"):
        assert cid in failed
    assert failed == remap_cases          # every remap case, and no invalid case


def test_broken_dequantization_fails_exactly_the_quantized_barycentric_and_scale_cases(
        suite, manifests, tmp_path):
    report = _run(suite, tmp_path / "r", lambda: RawReferencePlugin(_pow2_dequantize))
    # normalized localScale is dequantized with the same wrong divisor (quaternions are
    # renormalized, so a wrong divisor does not show there)
    assert _failed(report) == (_tagged(manifests, "quantized:barycentrics")
                               | _tagged(manifests, "encoding:localScale-normalized"))


def test_broken_missing_quaternion_renormalization_fails_the_quantized_rotation_cases(
        suite, manifests, tmp_path, monkeypatch):
    with _patched(monkeypatch, **{"quaternion.to_matrix": _to_matrix_unnormalized}):
        report = _run(suite, tmp_path / "r", lambda: RawReferencePlugin(renormalize=False))
    assert _failed(report) == (_tagged(manifests, "quantized:localRotation")
                               | _tagged(manifests, "rule:quaternion-norm"))


def test_broken_sh_rotation_fails_exactly_the_cases_with_higher_sh(suite, manifests, tmp_path):
    report = _run(suite, tmp_path / "r", _ShRotatingPlugin)
    higher = _ids(manifests, lambda m: m["kind"] in ("remap", "rig") and m["sh_degree"] >= 1)
    assert _failed(report) == higher
    assert all(c.worst.quantity == "sh" and c.worst.dump == "posed"
               for c in report.cases if c.status == "fail")


def test_broken_lenient_importer_fails_exactly_the_invalid_cases(suite, manifests, tmp_path):
    report = _run(suite, tmp_path / "r", _LenientPlugin)
    assert _failed(report) == _tagged(manifests, "invalid")


def _naive_rotation_scale_failures(suite: Path, results: Path, manifests: dict) -> set[str]:
    """A checker that compares rotation and scale instead of covariance (wrong: pairs are
    not unique). Reference pairs come from the library's reference remap."""
    from gsverse_format.remapping.reference import remap

    failed = set()
    for cid, m in manifests.items():
        if m["kind"] != "remap":
            continue
        prim = read_asset(str(suite / "cases" / cid / "asset.glb")).primitives[0]
        for p, pose in enumerate(m["poses"]):
            verts = np.fromfile(suite / "cases" / cid / pose["file"], "<f4").reshape(-1, 3)
            r = remap(prim.anchoring, verts)
            stem = results / cid / f"pose_{p:03d}"
            q = np.fromfile(f"{stem}.rotation.f32", "<f4").reshape(-1, 4)
            s = np.fromfile(f"{stem}.scale.f32", "<f4").reshape(-1, 3)
            q = np.where(q[:, 3:4] < 0, -q, q)
            if np.max(np.abs(q - r.rotations)) > 1e-3 or \
                    np.max(np.abs(s - r.scales) / (np.abs(r.scales) + 1e-30)) > 1e-3:
                failed.add(cid)
                break
    return failed


def test_comparing_rotation_scale_instead_of_covariance_rejects_correct_plugins(
        suite, manifests, tmp_path, clib):
    """The header's rotation/scale pairs (eigen-decomposition for affine) are correct: the
    covariance runner passes them; a rotation/scale comparison would wrongly fail them."""
    results = tmp_path / "c-rs"
    report = _run(suite, results, lambda: CPlugin(clib, "rotscale"))
    assert report.ok, format_text(report)
    naive = _naive_rotation_scale_failures(suite, results, manifests)
    affine = _tagged(manifests, "deformation:affine")
    assert len(naive & affine) >= 0.8 * len(affine)


def test_equivalent_rotation_scale_pairs_pass(suite, tmp_path, manifests):
    """Permuting a splat's axes (and flipping quaternion signs) leaves its covariance, hence
    the verdict, unchanged."""

    class Permuted(ReferencePlugin):
        def apply_pose(self, vertices):
            out = super().apply_pose(vertices)
            r = remap_module.remap(self.prim.anchoring, vertices, rest=self.rest_data)
            rot = quat_to_matrix(r.rotations)[:, :, [1, 2, 0]]
            q = quaternion.from_matrix(rot)
            q[::2] *= -1.0
            return {"means": out["means"], "rotation": q, "scale": r.scales[:, [1, 2, 0]]}

    results = tmp_path / "perm"
    report = _run(suite, results, Permuted)
    assert report.ok, format_text(report)


# --------------------------------------------------------------------------- links to validators

def test_invalid_cases_carry_the_codes_gsverse_validate_reports(suite, manifests):
    validators = pytest.importorskip("gsverse_format.validators.validate")
    from gsverse_format.validators.issues import Severity

    for cid, m in manifests.items():
        if m["kind"] != "invalid" and "validator_codes" not in m and "skinned" not in cid \
                and "stretch" != cid.rsplit("-", 1)[-1]:
            continue
        report = validators.validate_file(suite / "cases" / cid / "asset.glb")
        errors = {f.code for f in report.findings if f.severity == Severity.ERROR}
        if m["kind"] == "invalid":
            assert m["validator_code"] in errors, (cid, errors)
        elif "validator_codes" in m:
            assert set(m["validator_codes"]) <= report.codes(), (cid, report.codes())
            assert "refuse" not in m["expect"]
        else:
            assert not errors, (cid, errors)


def test_assets_pass_the_khronos_validator(suite):
    khr_tools = pytest.importorskip("khr_tools")
    if not khr_tools.node_tools_available():
        pytest.skip("Khronos glTF-Validator (tests/js) not installed")
    for cid in ("local-affine-skinned", "games-quantized-bary-u8", "local-rigid-face-index-u32"):
        report = khr_tools.validate_gltf(suite / "cases" / cid / "asset.glb")
        assert report["numUnexpectedErrors"] == 0, report["messages"][:3]
    report = khr_tools.validate_gltf(suite / "cases" / "local-affine-skinned" / "skinned.glb")
    assert report["numErrors"] == 0 and report["numWarnings"] == 0, report["messages"][:3]
    report = khr_tools.validate_gltf(suite / "cases" / "invalid-non-finite-normal-offset" / "asset.glb")
    assert "ACCESSOR_INVALID_FLOAT" in {m["code"] for m in report["messages"]}


def test_skinned_poses_are_the_sampled_animation(suite, manifests):
    from gsverse_format.conformance.skin import sample_skin

    for cid in ("local-affine-skinned", "games-skinned"):
        folder = suite / "cases" / cid
        glb = (folder / "skinned.glb").read_bytes()
        for pose in manifests[cid]["poses"][1:]:
            src = pose["source"]
            assert src["kind"] == "skin" and src["asset"] == "skinned.glb"
            verts = np.fromfile(folder / pose["file"], "<f4").reshape(-1, 3)
            np.testing.assert_array_equal(verts, sample_skin(glb, src["time"]).astype(np.float32))


# --------------------------------------------------------------------------- spec v1.1 rules

def _v1_degenerate_rest_face_matrices(rest, cur, tri, deformation):
    """v1's rule for faces degenerate at rest: C_r⁻¹ := I and k := 1, i.e. under the affine
    law G = blockdiag(C_c, 1) (the splat scaled by the current edge lengths in scene units)."""
    k, m, a = _ORIGINAL_FACE_MATRICES(rest, cur, tri, deformation)
    if deformation == "affine":
        deg = ~rest.regular
        g = np.zeros((int(deg.sum()), 3, 3))
        g[:, :2, :2] = cur.shape[deg]
        g[:, 2, 2] = 1.0
        a = a.copy()
        a[deg] = cur.rotation[deg] @ g
    return k, m, a


def _v1_threshold_face_matrices(rest, cur, tri, deformation):
    """v1's rule for current triangles below the threshold: a := 0 (k = 0, no normal offset)
    and the edges projected on the segment's direction."""
    k, m, a = _ORIGINAL_FACE_MATRICES(rest, cur, tri, deformation)
    sel = ~cur.regular & rest.regular
    k, m, a = k.copy(), m.copy(), a.copy()
    k[sel] = 0.0
    m[sel] = 0.0
    if deformation == "rigid":
        a[sel] = 0.0
    else:
        g = cur.shape[sel] @ rest.inverse_shape[sel]
        a[sel] = 0.0
        a[sel, :, :2] = cur.rotation[sel][:, :, :2] @ g
    return k, m, a


def _float32_prepare_rest(rest_triangles):
    """Rest quantities computed in float32 (v1 allowed it; v1.1 requires double)."""
    tri = np.asarray(rest_triangles, dtype=np.float32)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    cross = np.cross(e1, e2).astype(np.float32)
    a = np.sqrt(np.sum(cross * cross, axis=1, dtype=np.float32)).astype(np.float32)
    good = _ORIGINAL_PREPARE_REST(rest_triangles)
    len1 = np.sqrt(np.sum(e1 * e1, axis=1, dtype=np.float32)).astype(np.float32)
    with np.errstate(all="ignore"):
        t = e1 / len1[:, None]
        c01 = np.sum(e2 * t, axis=1, dtype=np.float32)
        h = (a / len1).astype(np.float32)
        inv = good.inverse_shape.copy()
        reg = good.regular
        inv[reg, 0, 0] = (np.float32(1) / len1)[reg]
        inv[reg, 0, 1] = (-c01 / (len1 * h)).astype(np.float32)[reg]
        inv[reg, 1, 1] = (np.float32(1) / h)[reg]
    return remap_module.RestData(good.rotation, inv, np.where(reg, a.astype(np.float64),
                                                              good.area2), reg)


def _v1_games_frames(tri):
    """v1's games degenerate rule: b1 = unit(v1 − c) whenever v1 ≠ c (an absolute test),
    n = perp(b1), b2 = n × b1; the centroid from absolute coordinates."""
    rot, base, c = _ORIGINAL_GAMES(tri)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    cross = np.cross(e1, e2)
    a = np.linalg.norm(cross, axis=1)
    l2 = np.max(np.stack([np.sum(e * e, axis=1) for e in (e1, e2, e2 - e1)]), axis=0)
    deg = ~(a > 1e-6 * l2)
    if np.any(deg):
        cc = tri[deg].mean(axis=1)
        u = tri[deg, 1] - cc
        w = tri[deg, 2] - cc
        lu = np.linalg.norm(u, axis=1)
        lw = np.linalg.norm(w, axis=1)
        b1 = np.where((lu > 0)[:, None], u / np.where(lu > 0, lu, 1)[:, None],
                      np.where((lw > 0)[:, None], w / np.where(lw > 0, lw, 1)[:, None],
                               np.array([1.0, 0, 0])))
        n = frames_module.perpendicular_unit(b1)
        b2 = np.cross(n, b1)
        rot = rot.copy()
        base = base.copy()
        rot[deg] = np.stack([n, b1, b2], -1)
        base[deg, 1] = (lu + 1e-8) / 2
        base[deg, 2] = np.einsum("ij,ij->i", w, b2) / 2
    return rot, base, c


def _last_on_ties_local_frames(tri):
    """Degenerate segments take the LAST longest edge on ties."""
    good = _ORIGINAL_LOCAL(tri)
    e = np.stack([tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], tri[:, 2] - tri[:, 1]], 1)
    sq = np.sum(e * e, axis=2)
    line = ~good.regular & (sq.max(axis=1) > 0)
    if not np.any(line):
        return good
    which = 2 - np.argmax(sq[line][:, ::-1], axis=1)
    d = e[line][np.arange(which.size), which]
    t = d / np.linalg.norm(d, axis=1, keepdims=True)
    n = frames_module.perpendicular_unit(t)
    rot = good.rotation.copy()
    rot[line] = np.stack([t, np.cross(n, t), n], -1)
    return LocalFrames(good.origin, rot, good.shape, good.area2, good.regular, good.cross)


def _absolute_eps_prepare_rest(rest_triangles):
    """Rest faces with doubled area below 1e-9 treated as degenerate (an absolute epsilon)."""
    good = _ORIGINAL_PREPARE_REST(rest_triangles)
    tri = np.asarray(rest_triangles, dtype=np.float64)
    a = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    reg = good.regular & (a > 1e-9)
    inv = np.where(reg[:, None, None], good.inverse_shape, np.eye(2))
    return remap_module.RestData(good.rotation, inv, good.area2, reg)


_ORIGINAL_FACE_MATRICES = remap_module.face_matrices
_ORIGINAL_PREPARE_REST = remap_module.prepare_rest


def test_broken_v1_degenerate_rest_rule_fails_the_affine_degenerate_rest_cases(
        suite, manifests, tmp_path, monkeypatch):
    with _patched(monkeypatch, **{"remap.face_matrices": _v1_degenerate_rest_face_matrices}):
        report = _run(suite, tmp_path / "r", ReferencePlugin)
    assert _failed(report) == (_tagged(manifests, "degenerate:rest")
                               & _tagged(manifests, "deformation:affine"))


def test_broken_v1_threshold_rule_fails_exactly_the_threshold_cases(suite, manifests, tmp_path,
                                                                    monkeypatch):
    with _patched(monkeypatch, **{"remap.face_matrices": _v1_threshold_face_matrices}):
        report = _run(suite, tmp_path / "r", ReferencePlugin)
    assert _failed(report) == (_tagged(manifests, "rule:threshold")
                               & _tagged(manifests, "profile:local"))
    assert all(c.worst.quantity == "mean" for c in report.cases if c.status == "fail")


def test_broken_float32_rest_quantities_fail_the_rest_sliver_cases(suite, manifests, tmp_path,
                                                                    monkeypatch):
    with _patched(monkeypatch, **{"remap.prepare_rest": _float32_prepare_rest}):
        report = _run(suite, tmp_path / "r", ReferencePlugin)
    assert _failed(report) == _tagged(manifests, "rule:rest-precision")


def test_broken_v1_games_rule_fails_the_midpoint_cases(suite, manifests, tmp_path, monkeypatch):
    with _patched(monkeypatch, **{"remap.games_frames": _v1_games_frames}):
        report = _run(suite, tmp_path / "r", ReferencePlugin)
    # the zero-area case has a triangle with v1 exactly at the centroid
    assert _failed(report) == _tagged(manifests, "rule:games-degenerate") | {"games-zero-area-pose"}


def test_broken_tie_rule_fails_exactly_the_tie_cases(suite, manifests, tmp_path, monkeypatch):
    with _patched(monkeypatch, **{"remap.local_frames": _last_on_ties_local_frames}):
        report = _run(suite, tmp_path / "r", ReferencePlugin)
    assert _failed(report) == _tagged(manifests, "rule:ties")


def test_broken_absolute_rest_epsilon_fails_the_small_scale_cases(suite, manifests, tmp_path,
                                                                  monkeypatch):
    with _patched(monkeypatch, **{"remap.prepare_rest": _absolute_eps_prepare_rest}):
        report = _run(suite, tmp_path / "r", ReferencePlugin)
    failed = _failed(report)
    small = _ids(manifests, lambda m: "scale:1e-4" in m["tags"] and "profile:local" in m["tags"])
    tiny = _tagged(manifests, "extreme:near-coincident") & _tagged(manifests, "profile:local")
    assert failed == small | tiny


def test_scaled_cases_agree_after_scaling(suite, manifests):
    """The expected outputs of the *-scale-* cases agree after scaling: exactly up to rounding
    for the local profile, within |1 − c| (1 + ρ) ε per scale for games."""
    from gsverse_format.conformance.cases_rules import SCALES

    for law in ("local-affine", "local-rigid", "games"):
        ref = {}
        for c in SCALES:
            name = {1e-4: "1e-4", 1.0: "1", 1e4: "1e4"}[c]
            folder = suite / "cases" / f"{law}-scale-{name}"
            m = manifests[f"{law}-scale-{name}"]
            out = []
            for pose in m["files"]["expected"]["poses"]:
                means = np.fromfile(folder / pose["means"], "<f8").reshape(-1, 3) / c
                cov = np.fromfile(folder / pose["cov"], "<f8").reshape(-1, 6) / (c * c)
                out.append((means, cov))
            ref[c] = out
        for c in (1e-4, 1e4):
            for (m1, c1), (mc, cc) in zip(ref[1.0], ref[c]):
                assert np.max(np.linalg.norm(mc - m1, axis=1)) <= 1e-6 * np.max(np.abs(m1))
                rel = np.linalg.norm(cc - c1, axis=1) / np.linalg.norm(c1, axis=1)
                if law == "games":
                    # scale_j(cV)/c − scale_j(V) <= |1/c − 1| (1 + ρ) ε; relative to Σ's norm
                    assert np.max(np.linalg.norm(cc - c1, axis=1)) <= \
                        2 * abs(1 / c - 1) * 3e-8 * np.sqrt(np.max(np.abs(c1))) * 4 + 1e-12
                else:
                    assert np.max(rel) <= 1e-5   # float32 rounding of each scaled file


def test_library_reader_refuses_every_invalid_case(suite, manifests):
    """gsverse_format.read_gltf itself (not only the suite's harness) refuses every asset the
    spec says readers MUST refuse, with a one-line FormatError."""
    from gsverse_format.errors import FormatError
    from gsverse_format.io.gltf import read_gltf

    for cid in _tagged(manifests, "invalid"):
        with pytest.raises(FormatError) as err:
            read_gltf(suite / "cases" / cid / "asset.glb")
        assert "\n" not in str(err.value), cid


def _splat_node_scale(asset_path: str) -> float:
    from gsverse_format.conformance.glb import unpack_glb

    doc, _ = unpack_glb(Path(asset_path).read_bytes())
    splat_mesh = next(i for i, m in enumerate(doc["meshes"]) for p in m["primitives"]
                      if "KHR_gaussian_splatting" in p.get("extensions", {}))
    node = next((n for n in doc.get("nodes", []) if n.get("mesh") == splat_mesh), {})
    return float(node.get("scale", [1.0])[0])


class _WorldSpacePlugin(ReferencePlugin):
    """Remaps games splats in world space (the splat node's scale applied to the anchor mesh
    first, undone on the outputs): GaMeS's ε then acts after the node transform."""

    def load(self, asset_path):
        super().load(asset_path)
        self.scale = _splat_node_scale(asset_path)

    def apply_pose(self, vertices):
        from gsverse_format.model import Anchoring, TriangleMesh

        if self.prim.anchoring.anchors.profile != "games":
            return super().apply_pose(vertices)
        s = self.scale
        mesh = self.prim.anchoring.mesh
        world = Anchoring(TriangleMesh(mesh.vertices.astype(np.float64) * s, mesh.faces),
                          self.prim.anchoring.anchors)
        r = remap_module.remap(world, vertices.astype(np.float64) * s)
        from gsverse_format.conformance.harness import cov6

        return {"means": r.means / s, "cov": cov6(r.covariances / (s * s))}


def test_broken_games_epsilon_after_node_transform_fails_the_node_scale_case(suite, manifests,
                                                                            tmp_path):
    report = _run(suite, tmp_path / "r", _WorldSpacePlugin)
    assert _failed(report) == _tagged(manifests, "rule:games-epsilon-space")


class _RhoOnCovariancePlugin(ReferencePlugin):
    """Reads ρ as a factor of the covariance (the GaMeS paper's N(m, ρ Σ_V)): √ρ on scales."""

    def load(self, asset_path):
        super().load(asset_path)
        a = self.prim.anchoring.anchors
        if a.profile == "games":
            from dataclasses import replace

            from gsverse_format.model import Anchoring

            self.prim.anchoring = Anchoring(self.prim.anchoring.mesh,
                                            replace(a, rho=np.sqrt(np.maximum(a.rho, 0.0))))


def test_broken_rho_on_covariance_fails_the_games_cases(suite, manifests, tmp_path):
    from gsverse_format.conformance import harness

    harness._CACHE.clear()          # the plugin edits the cached asset: start from a fresh copy
    try:
        report = _run(suite, tmp_path / "r", _RhoOnCovariancePlugin)
    finally:
        harness._CACHE.clear()
    games = _ids(manifests, lambda m: m["kind"] in ("remap", "rig") and "profile:games" in m["tags"])
    assert _failed(report) == games


def _games_float32(tri64: np.ndarray, literal_centroid: bool):
    """The regular games frame in float32 arithmetic; the centroid either relative to v0
    (spec v1.1) or as the literal (v0 + v1 + v2)/3 from absolute coordinates."""
    f = np.float32
    tri = tri64.astype(f)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    if literal_centroid:
        c = (tri[:, 0] + tri[:, 1] + tri[:, 2]) / f(3)
        u, w = tri[:, 1] - c, tri[:, 2] - c
    else:
        g = (e1 + e2) / f(3)
        u, w = e1 - g, e2 - g
    cross = np.cross(e1, e2)
    with np.errstate(all="ignore"):
        n = cross / np.linalg.norm(cross, axis=1, keepdims=True).astype(f)
        lu = np.linalg.norm(u, axis=1).astype(f)
        b1 = u / lu[:, None]
        b2 = np.cross(n, b1)
        base = np.stack([np.full(len(tri), f(1e-8)), (lu + f(1e-8)) / f(2),
                         np.einsum("ij,ij->i", w, b2) / f(2)], -1)
    return np.stack([n, b1, b2], -1).astype(np.float64), base.astype(np.float64)


class _Float32GamesPlugin(ReferencePlugin):
    """games in float32: frames of regular faces as above (degenerate ones from the reference),
    the mean either v0 + α1 e1 + α2 e2 or the naive α0 v0 + α1 v1 + α2 v2, both in float32."""

    literal_centroid = False
    naive_mean = True

    def apply_pose(self, vertices):
        a = self.prim.anchoring.anchors
        if a.profile != "games":
            return super().apply_pose(vertices)
        from gsverse_format.conformance.harness import cov6

        tri = self.prim.anchoring.mesh.triangles(vertices)
        rot, base, _ = frames_module.games_frames(tri)
        rot32, base32 = _games_float32(tri, self.literal_centroid)
        reg = ~frames_module.degenerate_mask(tri)
        rot[reg], base[reg] = rot32[reg], base32[reg]
        face = a.face_index.astype(np.intp)
        t = tri.astype(np.float32)[face]
        al = a.barycentrics.astype(np.float32)
        if self.naive_mean:
            means = (np.float32(1) - al[:, :1] - al[:, 1:]) * t[:, 0] + al[:, :1] * t[:, 1] \
                + al[:, 1:] * t[:, 2]
        else:
            means = t[:, 0] + al[:, :1] * (t[:, 1] - t[:, 0]) + al[:, 1:] * (t[:, 2] - t[:, 0])
        sc = (np.maximum(a.rho[:, None].astype(np.float32) * base[face].astype(np.float32), 0)
              + np.float32(1e-8))
        m = rot[face].astype(np.float32) * sc[:, None, :]
        return {"means": means, "cov": cov6(m @ np.swapaxes(m, 1, 2))}


class _LiteralCentroidPlugin(_Float32GamesPlugin):
    literal_centroid = True


def test_float32_games_needs_the_relative_centroid_not_the_relative_mean(suite, manifests,
                                                                         tmp_path):
    """Spec v1.1 item 11: the naive α0 v0 + α1 v1 + α2 v2 passes in float32; the literal
    centroid (v0 + v1 + v2)/3 fails the far-from-origin and micro-triangle cases."""
    with np.errstate(all="ignore"):
        naive = _failed(_run(suite, tmp_path / "naive", _Float32GamesPlugin))
        literal = _failed(_run(suite, tmp_path / "literal", _LiteralCentroidPlugin))
    games = _ids(manifests, lambda m: m["kind"] in ("remap", "rig") and "profile:games" in m["tags"])
    assert not naive & games, sorted(naive & games)
    assert {"games-offset-1e5", "games-near-coincident-vertices"} <= literal
    assert literal <= games


# --------------------------------------------------------------------------- compact anchors (1.2)

def _counts_reversed(asset):
    """Broken: the faces of faceCounts assigned from the last face down (ignores the order)."""
    from gsverse_format.conformance.minimal_reader import face_index

    face = face_index(asset)
    if asset.face_counts is None:
        return face
    counts = asset.face_counts.values[:, 0].astype(np.int64)
    last = len(counts) - 1
    return np.repeat(np.arange(last, -1, -1, dtype=np.uint32), counts[::-1])


def _derive_wrong_offset_sign(asset):
    """Broken: the normal offset derived with the wrong sign (d = −z)."""
    from gsverse_format.conformance.minimal_reader import derive_local

    out = derive_local(asset)
    out["normalOffset"] = -out["normalOffset"]
    return out


def _derive_wrong_rotation_order(asset):
    """Broken: q_l = q ⊗ conj(q_r) instead of conj(q_r) ⊗ q."""
    from gsverse_format.conformance import minimal_reader as mr

    out = mr.derive_local(asset)
    q = mr.dequantize(asset.rotations)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    qr = quaternion.multiply(q, quaternion.conjugate(out["localRotation"]))   # = q_r
    out["localRotation"] = quaternion.multiply(q, quaternion.conjugate(qr))
    return out


def test_broken_face_counts_order_fails_exactly_the_face_counts_cases(suite, manifests,
                                                                     tmp_path, monkeypatch):
    from gsverse_format.conformance import harness

    monkeypatch.setattr(harness, "face_index", _counts_reversed)
    report = _run(suite, tmp_path / "r", RawReferencePlugin)
    counted = _ids(manifests, lambda m: m["kind"] == "remap"
                   and m["anchor"]["face_encoding"] == "faceCounts")
    assert counted >= {"local-rigid-face-counts", "games-face-counts", "local-affine-derived"}
    assert _failed(report) == counted


@pytest.mark.parametrize("broken", [_derive_wrong_offset_sign, _derive_wrong_rotation_order])
def test_broken_derivation_fails_exactly_the_derived_cases(suite, manifests, tmp_path,
                                                           monkeypatch, broken):
    from gsverse_format.conformance import harness

    monkeypatch.setattr(harness, "derive_local", broken)
    report = _run(suite, tmp_path / "r", RawReferencePlugin)
    derived = _tagged(manifests, "encoding:derived")
    assert len(derived) == 9     # 5 uncompressed, 4 SPZ-compressed
    assert _failed(report) == derived
