"""The gltf-transform CLI (``plugins/web``'s pinned @gltf-transform/cli) over anchored assets.

With ``plugins/web/gltf-transform.config.mjs`` (which registers the package's
``KHR_gaussian_splatting`` and ``GSVERSE_gaussian_splatting_mesh_anchor`` extensions) every command
either writes an asset that ``gsverse-validate`` passes and whose remap, at rest and on a deformed
anchor mesh, is the original's, or exits non-zero with a one-line message and writes nothing.
Without the config gltf-transform drops both extensions. The outcome of each command here is the
table of ``plugins/web/README.md`` §glTF-Transform.
"""
from __future__ import annotations

import json
import pathlib
import re
import struct

import numpy as np
import pytest
import validation_assets as va
from web_tools import ROOT, WEB, require_web_tools, run_node

from gsverse_format import api
from gsverse_format.io.gltf import write_gltf

CLI = WEB / "node_modules" / "@gltf-transform" / "cli" / "bin" / "cli.js"
CONFIG = WEB / "gltf-transform.config.mjs"
ANCHOR = "GSVERSE_gaussian_splatting_mesh_anchor"
KHR = "KHR_gaussian_splatting"
NPM = ("@gltf-transform/cli", "@gltf-transform/core", "@gltf-transform/extensions")

# Commands that keep every asset valid and its remap identical.
SAFE = ["copy", "dedup", "prune", "resample", "sparse", "flatten", "center", "dequantize"]
# Commands that refuse, with the message they print (a regular expression).
_CHANGED = rf"^error: {ANCHOR}: refusing to write meshes\[0\]\.primitives\[0\] \(\"\w+\"\): the anchor mesh's vertex positions changed"
REFUSED = {
    # gltf-transform's quantize stops on the KHR_gaussian_splatting:* attribute semantics.
    "quantize": r'^error: quantize: Unexpected semantic, "KHR_gaussian_splatting:ROTATION"\.$',
    "quantize --pattern POSITION": _CHANGED,  # the positions alone: the anchor mesh moves
    "meshopt": _CHANGED,        # reorder + quantize of the anchor mesh
    "weld": _CHANGED,           # renumbers the anchor vertices in order of first use
    # gltf-transform 4.5.1 fails on a POINTS primitive with an UNSIGNED_BYTE COLOR_0 (the COLOR_0
    # every GS-Verse writer stores); see test_simplify_reaching_the_writer_is_refused.
    "simplify": r"^error: Assertion failed$",
    "reorder": _CHANGED,
    "draco": _CHANGED,          # weld, then Draco (which also re-orders points)
    "unweld": _CHANGED,
    "join": rf"^error: {ANCHOR}: refusing to write",
}
REQUIRED = ["copy", "dedup", "prune", "resample", "quantize", "quantize --pattern POSITION", "meshopt",
            "weld", "simplify"]
ASSETS = ["capsule", "games", "quantized"]


def _cases(commands) -> list[tuple[str, str]]:
    """(asset, command): the commands of the issue on every asset, the others on the capsule."""
    return [(name, command) for command in commands
            for name in (ASSETS if command in REQUIRED else ["capsule"])]


@pytest.fixture(scope="module")
def assets(tmp_path_factory) -> dict[str, pathlib.Path]:
    """A converted capsule (local, affine), a games asset and a local rigid asset with quantized
    anchors and a plain primitive beside the anchored one."""
    require_web_tools(packages=NPM)
    folder = tmp_path_factory.mktemp("gltf_transform_assets")
    capsule = folder / "capsule.glb"
    api.convert(ROOT / "examples" / "capsule" / "splats.ply", capsule,
                mesh=str(ROOT / "examples" / "capsule" / "mesh.obj"))
    games = folder / "games.glb"
    write_gltf(va.games_asset(48), games)
    quantized = folder / "quantized.glb"
    write_gltf(va.local_asset(60, deformation="rigid"), quantized,
               quantize={"barycentrics": "unsigned_short", "localRotation": "short"})
    for path in (capsule, games, quantized):
        assert api.validate(path).exit_status == 0
    return {"capsule": capsule, "games": games, "quantized": quantized}


def _run(command: str, src: pathlib.Path, dst: pathlib.Path, *, config: bool = True):
    require_web_tools(packages=NPM)
    name, *options = command.split()
    args = [CLI, *(["--config", CONFIG] if config else []), name, src, dst, *options]
    return run_node(args, cwd=ROOT, timeout=300)


def _glb_json(path: pathlib.Path) -> dict:
    data = path.read_bytes()
    length, kind = struct.unpack_from("<II", data, 12)
    assert kind == 0x4E4F534A
    return json.loads(data[20:20 + length])


def _deformed(vertices: np.ndarray) -> np.ndarray:
    """A smooth, non-affine pose of the anchor mesh."""
    v = np.asarray(vertices, np.float64)
    return v + 0.15 * np.sin(3.0 * v[:, [1, 2, 0]]) + 0.05 * v[:, [2, 0, 1]] ** 2


def _assert_same_anchoring(original: pathlib.Path, written: pathlib.Path) -> None:
    report = api.validate(written)
    assert report.exit_status == 0, [str(f) for f in report.findings]
    a, b = api.read(original), api.read(written)
    assert len(b.primitives) == len(a.primitives)
    assert len(b.anchored) == len(a.anchored) >= 1
    for pa, pb in zip(a.anchored, b.anchored):
        assert pb.name == pa.name
        np.testing.assert_array_equal(pb.anchoring.mesh.vertices, pa.anchoring.mesh.vertices)
        np.testing.assert_array_equal(pb.anchoring.mesh.faces, pa.anchoring.mesh.faces)
        assert pb.anchoring.anchors.profile == pa.anchoring.anchors.profile
        np.testing.assert_array_equal(pb.anchoring.anchors.face_index, pa.anchoring.anchors.face_index)
        for vertices in (None, _deformed(pa.anchoring.mesh.vertices)):
            ra, rb = api.remap(pa.anchoring, vertices), api.remap(pb.anchoring, vertices)
            np.testing.assert_allclose(rb.means, ra.means, rtol=0, atol=1e-6)
            np.testing.assert_allclose(rb.covariances, ra.covariances, rtol=1e-6, atol=1e-12)
        np.testing.assert_array_equal(pb.splats.means, pa.splats.means)
        np.testing.assert_array_equal(pb.splats.scales, pa.splats.scales)


@pytest.mark.parametrize(("name", "command"), _cases(SAFE))
def test_safe_commands_keep_the_asset_anchored(assets, tmp_path, name, command):
    out = tmp_path / f"{command}.glb"
    proc = _run(command, assets[name], out)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    _assert_same_anchoring(assets[name], out)
    doc = _glb_json(out)
    assert set(doc["extensionsUsed"]) == {KHR, ANCHOR}
    assert ANCHOR not in doc.get("extensionsRequired", [])
    assert not any("sparse" in acc for acc in doc["accessors"])


@pytest.mark.parametrize(("name", "command"), _cases(REFUSED))
def test_unsafe_commands_refuse_and_write_nothing(assets, tmp_path, name, command):
    out = tmp_path / "out.glb"
    proc = _run(command, assets[name], out)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert not out.exists()
    errors = [line for line in (proc.stdout + proc.stderr).splitlines() if line.startswith("error:")]
    assert len(errors) == 1, proc.stdout + proc.stderr
    assert re.search(REFUSED[command], errors[0]), errors[0]


def test_config_after_the_command(assets, tmp_path):
    """The CLI's own place for global options works as well as the issue's form."""
    require_web_tools(packages=NPM)
    before, after = tmp_path / "before.glb", tmp_path / "after.glb"
    assert _run("copy", assets["games"], before).returncode == 0
    proc = run_node([CLI, "copy", assets["games"], after, "--config", CONFIG], cwd=ROOT, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert after.read_bytes() == before.read_bytes()


def test_refusal_leaves_an_existing_output_untouched(assets, tmp_path):
    out = tmp_path / "out.glb"
    out.write_bytes(b"previous")
    proc = _run("weld", assets["capsule"], out)
    assert proc.returncode != 0
    assert out.read_bytes() == b"previous"


def test_simplify_reaching_the_writer_is_refused(tmp_path):
    """Without the UNSIGNED_BYTE COLOR_0 that stops gltf-transform's point simplification, simplify
    drops splats and collapses the anchor mesh; the write is refused."""
    doc = va.Doc.of(va.games_asset(48))
    del doc.prim()["attributes"]["COLOR_0"]
    src = doc.write(tmp_path, "nocolor.glb")
    out = tmp_path / "simplified.glb"
    proc = _run("simplify", src, out)
    assert proc.returncode != 0
    assert not out.exists()
    assert f"error: {ANCHOR}: refusing to write" in proc.stdout + proc.stderr


def test_without_the_config_the_anchoring_is_lost(assets, tmp_path):
    """Why the config is needed: gltf-transform alone drops both extensions (the output has no
    splats, only points), and prune then drops the anchor mesh no node uses."""
    out = tmp_path / "copy.glb"
    proc = _run("copy", assets["capsule"], out, config=False)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert f'Missing optional extension, "{ANCHOR}"' in proc.stdout + proc.stderr
    doc = _glb_json(out)
    assert "extensionsUsed" not in doc and "extensions" not in json.dumps(doc["meshes"])
    assert "KHR_NO_SPLATS" in {f.code for f in api.validate(out).findings}

    pruned = tmp_path / "prune.glb"
    assert _run("prune", assets["capsule"], pruned, config=False).returncode == 0
    assert len(_glb_json(pruned)["meshes"]) == 1
    assert len(_glb_json(assets["capsule"])["meshes"]) == 2


def _splat_objects(doc: dict) -> list[dict | None]:
    """The KHR_gaussian_splatting object of every primitive (None where there is none)."""
    return [p.get("extensions", {}).get(KHR) for m in doc["meshes"] for p in m["primitives"]]


def test_config_keeps_the_extension_objects(assets, tmp_path):
    """KHR properties as they were, the plain splat primitive plain, the anchor object the same
    but for renumbered indices, quantized anchor accessors as they were stored."""
    out = tmp_path / "copy.glb"
    assert _run("copy", assets["quantized"], out).returncode == 0
    before, after = _glb_json(assets["quantized"]), _glb_json(out)
    assert [k is None for k in _splat_objects(after)] == [k is None for k in _splat_objects(before)]
    for kb, ka in zip(_splat_objects(before), _splat_objects(after)):
        if kb is None:
            continue
        assert {k: v for k, v in ka.items() if k != "extensions"} == \
            {k: v for k, v in kb.items() if k != "extensions"}
        assert set(ka.get("extensions", {})) == set(kb.get("extensions", {}))
        if ANCHOR in kb.get("extensions", {}):
            eb, ea = kb["extensions"][ANCHOR], ka["extensions"][ANCHOR]
            assert set(ea) == set(eb)
            assert {k: v for k, v in ea.items() if isinstance(v, str)} == \
                {k: v for k, v in eb.items() if isinstance(v, str)}
            accessors = after["accessors"]
            bary, rotation = accessors[ea["barycentrics"]], accessors[ea["localRotation"]]
            assert (bary["componentType"], bary.get("normalized")) == (5123, True)
            assert (rotation["componentType"], rotation.get("normalized")) == (5122, True)
            assert all(node.get("mesh") != ea["mesh"] for node in after["nodes"])
            assert after["meshes"][ea["mesh"]]["primitives"][ea.get("primitive", 0)]["mode"] == 4


def test_merge_keeps_both_assets_anchored(assets, tmp_path):
    out = tmp_path / "merged.glb"
    require_web_tools(packages=NPM)
    proc = run_node([CLI, "--config", CONFIG, "merge", assets["capsule"], assets["games"], out],
                    cwd=ROOT, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert api.validate(out).exit_status == 0
    merged = api.read(out).anchored
    originals = api.read(assets["capsule"]).anchored + api.read(assets["games"]).anchored
    assert [p.name for p in merged] == [p.name for p in originals]
    for pa, pb in zip(originals, merged):
        vertices = _deformed(pa.anchoring.mesh.vertices)
        ra, rb = api.remap(pa.anchoring, vertices), api.remap(pb.anchoring, vertices)
        np.testing.assert_allclose(rb.means, ra.means, rtol=0, atol=1e-6)
        np.testing.assert_allclose(rb.covariances, ra.covariances, rtol=1e-6, atol=1e-12)


def test_optimize_is_refused_unless_its_geometry_steps_are_off(assets, tmp_path):
    out = tmp_path / "optimized.glb"
    proc = _run("optimize", assets["capsule"], out)
    assert proc.returncode != 0 and not out.exists()
    require_web_tools(packages=NPM)
    off = ["--simplify", "false", "--weld", "false", "--join", "false", "--compress", "false"]
    proc = run_node([CLI, "optimize", assets["capsule"], out, "--config", CONFIG, *off],
                    cwd=ROOT, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    _assert_same_anchoring(assets["capsule"], out)


SPZ = "KHR_gaussian_splatting_compression_spz_2"


def _spz_stream(path: pathlib.Path) -> bytes:
    """The SPZ stream (the buffer view's bytes) of the first primitive of a GLB."""
    data = path.read_bytes()
    doc = _glb_json(path)
    length = struct.unpack_from("<I", data, 12)[0]
    bin_start = 20 + length + 8
    view = doc["bufferViews"][doc["meshes"][0]["primitives"][0]["extensions"][KHR]["extensions"][SPZ]["bufferView"]]
    start = bin_start + view.get("byteOffset", 0)
    return data[start:start + view["byteLength"]]


@pytest.mark.parametrize("command", ["copy", "dedup", "prune"])
def test_a_compressed_asset_stays_compressed(tmp_path, command):
    """An SPZ-compressed rest pose (gsverse-convert --compress spz) goes through the stream byte for
    byte, its placeholders stay placeholders, gsverse-validate passes it, and it reads back as the
    same splats and anchors."""
    src = tmp_path / "capsule-spz.glb"
    api.convert(ROOT / "examples" / "capsule" / "splats.ply", src,
                mesh=str(ROOT / "examples" / "capsule" / "mesh.obj"), compress="spz")
    out = tmp_path / f"{command}.glb"
    proc = _run(command, src, out)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert _spz_stream(out) == _spz_stream(src)
    before, after = _glb_json(src), _glb_json(out)
    assert after["extensionsRequired"] == [SPZ]
    attrs_b, attrs_a = before["meshes"][0]["primitives"][0]["attributes"], after["meshes"][0]["primitives"][0]["attributes"]
    assert set(attrs_a) == set(attrs_b)
    for name in attrs_b:
        acc_b, acc_a = before["accessors"][attrs_b[name]], after["accessors"][attrs_a[name]]
        assert "bufferView" not in acc_a, name
        assert {k: acc_a.get(k) for k in ("type", "componentType", "count", "normalized", "min", "max")} == \
            {k: acc_b.get(k) for k in ("type", "componentType", "count", "normalized", "min", "max")}, name
    a, b = api.read(src).primitives[0], api.read(out).primitives[0]
    for field in ("means", "rotations", "scales", "opacities", "sh"):
        np.testing.assert_array_equal(getattr(b.splats, field), getattr(a.splats, field))
    np.testing.assert_array_equal(b.anchoring.anchors.face_index, a.anchoring.anchors.face_index)
    vertices = _deformed(a.anchoring.mesh.vertices)
    np.testing.assert_array_equal(api.remap(b.anchoring, vertices).means, api.remap(a.anchoring, vertices).means)
    report = api.validate(out)
    assert report.exit_status == 0 and not report.findings, [str(f) for f in report.findings]
