"""The public API at the package top: read, write, convert, remap, validate, bind."""
from __future__ import annotations

import numpy as np
import pytest

import gsverse_format as gv
from gsverse_format.errors import FormatError, UsageError

EXAMPLE = "examples/capsule"


@pytest.fixture(scope="module")
def anchored(tmp_path_factory):
    out = tmp_path_factory.mktemp("api") / "anchored.glb"
    summary = gv.convert(f"{EXAMPLE}/splats.ply", out, mesh=f"{EXAMPLE}/mesh.obj")
    assert summary.anchored == summary.splats > 0 and out.is_file()
    return out


def test_convert_read_remap_validate(anchored):
    asset = gv.read(anchored)
    prim = asset.anchored[0]
    rest = gv.remap(prim.anchoring)
    assert np.allclose(rest.means, prim.splats.means, atol=1e-5)
    stretched = prim.anchoring.mesh.vertices * np.array([1.0, 1.5, 1.0], np.float32)
    posed = gv.remap(prim.anchoring, stretched)
    assert posed.covariances.shape == (len(prim.splats), 3, 3)
    assert not np.allclose(posed.means, rest.means)
    report = gv.validate(anchored)
    assert report.exit_status == 0, [f.code for f in report.findings]


def test_bind_and_write_round_trip(anchored, tmp_path):
    asset = gv.read(anchored)
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


def test_readme_library_example_runs_as_written(tmp_path, monkeypatch):
    """The README's 'Using the library' block, executed verbatim next to the shipped example."""
    import os
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    text = (root / "README.md").read_text(encoding="utf-8")
    section = text[text.index("## Using the library"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    (tmp_path / "examples").mkdir()
    os.symlink(root / "examples" / "capsule", tmp_path / "examples" / "capsule")
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(code, "README.md", "exec"), namespace)
    assert namespace["report"].exit_status == 0
    assert (tmp_path / "anchored.glb").is_file() and (tmp_path / "anchored.usda").is_file()
    assert namespace["posed"].means.shape == namespace["prim"].splats.means.shape
