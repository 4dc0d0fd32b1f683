"""The public API at the package top: read, write, convert, remap, validate, bind."""
from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest

import gsverse_format as gv
from gsverse_format.errors import FormatError, UsageError

ROOT = Path(__file__).resolve().parents[1]
CAPSULE = ROOT / "examples" / "capsule"


def test_convert_read_remap_validate(example_asset):
    asset = gv.read(example_asset)
    prim = asset.anchored[0]
    rest = gv.remap(prim.anchoring)
    assert np.allclose(rest.means, prim.splats.means, atol=1e-5)
    stretched = prim.anchoring.mesh.vertices * np.array([1.0, 1.5, 1.0], np.float32)
    posed = gv.remap(prim.anchoring, stretched)
    assert posed.covariances.shape == (len(prim.splats), 3, 3)
    assert not np.allclose(posed.means, rest.means)
    report = gv.validate(example_asset)
    assert report.exit_status == 0, [f.code for f in report.findings]


def test_bind_and_write_round_trip(example_asset, tmp_path):
    asset = gv.read(example_asset)
    prim = asset.anchored[0]
    anchoring = gv.bind(prim.splats, prim.anchoring.mesh)
    again = gv.remap(anchoring)
    assert np.max(np.linalg.norm(again.means - prim.splats.means, axis=1)) < 1e-5
    out = tmp_path / "copy.glb"
    gv.write(asset, out)
    copy = gv.read(out)
    assert np.array_equal(copy.anchored[0].splats.means, prim.splats.means)


def test_errors_are_typed(tmp_path):
    bad = tmp_path / "bad.glb"
    bad.write_bytes(b"glTF\x02\x00\x00\x00")
    with pytest.raises(FormatError):
        gv.read(bad)
    with pytest.raises(UsageError):
        gv.read(tmp_path / "splats.xyz")
    assert gv.validate(bad).exit_status != 0


def test_every_public_function_takes_path_objects(example_asset, tmp_path):
    """``pathlib.Path`` wherever a path goes: the six functions (and every file option of
    ``convert``), and the public entry points of posing and rendering."""
    from validation_assets import rigged_asset

    from gsverse_format import poses, render

    out = tmp_path / "out"
    out.mkdir()
    summary = gv.convert(CAPSULE / "splats.ply", out / "a.glb", mesh=CAPSULE / "mesh.obj")
    assert summary.anchored == summary.splats > 0
    assert summary.input == str(CAPSULE / "splats.ply") and summary.output == str(out / "a.glb")
    assert (out / "a.glb").read_bytes() == example_asset.read_bytes()
    gv.convert(CAPSULE / "splats.ply", out / "b.glb", meshes=[CAPSULE / "mesh.obj"])
    assert (out / "b.glb").read_bytes() == example_asset.read_bytes()

    asset = gv.read(out / "a.glb")
    gv.write(asset, out / "c.usda", protect=(out / "a.glb",))
    with pytest.raises(UsageError, match="overwrite an input"):
        gv.write(asset, out / "a.glb", protect=(out / "a.glb",))
    assert gv.validate(out / "c.usda").exit_status == 0
    assert gv.read(out / "c.usda").splat_count() == asset.splat_count()
    rest = asset.anchored[0].anchoring.mesh.vertices
    np.savez(out / "poses.npz", vertices=np.stack([rest, rest * 1.1]), times=np.array([0., 1.]))
    baked = gv.convert(out / "a.glb", out / "d.usda", bake_poses=out / "poses.npz")
    assert any("baked 2" in note for note in baked.notes)

    assert poses.read_npz(out / "poses.npz").duration() == 1.0
    assert poses.open_source(out / "poses.npz").duration() == 1.0
    poses.write_vat(out / "v.exr", np.array([0.0, 1.0]), np.stack([rest, rest * 1.1]))
    assert poses.read_vat(out / "v.exr").at(1.0).shape == rest.shape
    gv.write(rigged_asset(), out / "rigged.glb")
    rigged = gv.read(out / "rigged.glb")
    assert poses.open_gltf_source(out / "rigged.glb").duration() == 1.0
    assert len(render.pose_vertices(rigged, 0.5, out / "rigged.glb")) == 1


@pytest.mark.parametrize("call", ["write", "convert"])
def test_an_existing_output_is_replaced_unless_overwrite_is_false(call, example_asset,
                                                                  tmp_path):
    """The API replaces an existing output (as Python's writers do); ``overwrite=False``
    refuses it as the command line does without -w: one line naming it, nothing written."""
    out = tmp_path / "a.glb"
    out.write_bytes(b"old output")

    def run(**overwrite):
        if call == "write":
            gv.write(gv.read(example_asset), out, **overwrite)
        else:
            gv.convert(CAPSULE / "splats.ply", out, mesh=CAPSULE / "mesh.obj", **overwrite)

    with pytest.raises(UsageError) as refused:
        run(overwrite=False)
    assert str(refused.value) == f"{out}: output exists; pass overwrite=True to replace it"
    assert out.read_bytes() == b"old output" and os.listdir(tmp_path) == ["a.glb"]
    run()
    assert gv.read(out).splat_count() == gv.read(example_asset).splat_count()
    out.unlink()
    run(overwrite=False)  # nothing there: written
    assert os.listdir(tmp_path) == ["a.glb"]


def test_readme_library_example_runs_as_written(tmp_path, monkeypatch):
    """The README's 'Using the library' block, executed verbatim next to the shipped example:
    it runs, and leaves nothing behind."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text[text.index("## Using the library"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    (tmp_path / "examples").mkdir()
    os.symlink(CAPSULE, tmp_path / "examples" / "capsule")
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(code, "README.md", "exec"), namespace)
    assert namespace["report"].exit_status == 0
    assert namespace["posed"].means.shape == namespace["prim"].splats.means.shape
    assert os.listdir(tmp_path) == ["examples"]
    assert not Path(namespace["folder"]).exists()
