"""``gsverse-info``: what a file holds, in text and JSON, for every readable format; one-line
errors. The numbers are checked against the files themselves: counts and bounds against what
the readers return, the sizes by part against the file size (for binary PLY and GLB every byte
belongs to exactly one part)."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from gsverse_format import api
from gsverse_format.cli.info import main
from gsverse_format.io.info import describe
from gsverse_format.io.ply import write_splat_ply
from gsverse_format.model import SplatAsset, SplatPrimitive
from helpers import bumpy_sphere, random_splats, surface_splats
from splat_writers import write_ksplat, write_sog, write_spz_v2


@pytest.fixture
def anchored_glb(tmp_path):
    mesh = bumpy_sphere(2)
    splats = surface_splats(mesh, 400, seed=3)
    path = tmp_path / "anchored.glb"
    ply, obj = tmp_path / "s.ply", tmp_path / "m.obj"
    write_splat_ply(splats, ply)
    obj.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in mesh.vertices) +
                   "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in mesh.faces))
    api.convert(ply, path, mesh=str(obj), deformation="rigid", anchors="explicit")
    return path, mesh


def test_anchored_glb_text_and_json(anchored_glb, capsys):
    path, mesh = anchored_glb
    assert main([str(path)]) == 0
    text = capsys.readouterr().out
    assert "gltf, glTF 2.0 (GLB)" in text and "400 in 1 primitive(s), SH degree 1" in text
    assert "anchored: profile local, deformation rigid, explicit encoding" in text
    assert f"anchor mesh {mesh.face_count} triangles" in text
    assert "size by part" in text and "anchors faceIndex" in text

    assert main([str(path), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    asset = api.read(path)
    assert info["splats"] == asset.splat_count() == 400
    means = asset.primitives[0].splats.means
    np.testing.assert_allclose(info["bounds"]["min"], means.min(axis=0), rtol=1e-6)
    np.testing.assert_allclose(info["bounds"]["max"], means.max(axis=0), rtol=1e-6)
    assert info["meshes"]["anchor_meshes"] == 1
    assert info["meshes"]["anchor_triangles"] == mesh.face_count
    assert info["meshes"]["triangles"] == mesh.face_count
    anchoring = info["primitives"][0]["anchoring"]
    assert anchoring == {"profile": "local", "deformation": "rigid", "encoding": "explicit",
                         "mesh_triangles": mesh.face_count,
                         "mesh_vertices": len(asset.primitives[0].anchoring.mesh.vertices)}
    # every byte of a GLB is in one part
    assert sum(info["parts"].values()) == info["bytes"] == path.stat().st_size
    assert info["parts"]["anchors faceIndex"] > 0 and info["parts"]["mesh indices"] > 0


def test_ply_parts_add_up_to_the_file(tmp_path):
    cloud = random_splats(250, sh_degree=3)
    path = tmp_path / "s.ply"
    write_splat_ply(cloud, path)
    info = describe(path)
    assert (info.format, info.frame, info.splats, info.sh_degree) == ("ply", "3dgs", 250, 3)
    assert sum(info.parts.values()) == path.stat().st_size
    assert info.parts["vertex f_rest_*"] == 250 * 45 * 4
    assert info.primitives[0]["anchoring"] is None


def test_web_formats(tmp_path, capsys):
    cloud = random_splats(300, sh_degree=2)
    write_spz_v2(cloud, tmp_path / "s.spz")
    write_ksplat(cloud, tmp_path / "s.ksplat", level=2)
    spz = describe(tmp_path / "s.spz")
    assert (spz.format, spz.version, spz.frame, spz.splats, spz.sh_degree) == \
        ("spz", "spz v2", "spz-rub", 300, 2)
    assert spz.parts["rotations"] == 300 * 3 and spz.parts["sh"] == 300 * 8 * 3
    ks = describe(tmp_path / "s.ksplat")
    assert ks.version == "ksplat 0.1, compression level 2" and ks.sh_degree == 2
    assert sum(ks.parts.values()) == (tmp_path / "s.ksplat").stat().st_size
    assert main([str(tmp_path / "s.ksplat")]) == 0
    assert "(3dgs frame)" in capsys.readouterr().out
    write_sog(cloud, tmp_path / "s.sog", version=1)
    sog = describe(tmp_path / "s.sog")
    assert (sog.version, sog.splats, sog.sh_degree) == ("SOG v1", 300, 2)
    import zipfile
    with zipfile.ZipFile(tmp_path / "s.sog") as archive:
        assert sog.parts == {i.filename: i.compress_size for i in archive.infolist()}


def test_several_primitives_and_a_static_one(anchored_glb, tmp_path, capsys):
    path, _ = anchored_glb
    asset = api.read(path)
    body = asset.primitives[0]
    static = SplatPrimitive(random_splats(30, sh_degree=0), None, "sky")
    two = tmp_path / "two.glb"
    api.write(SplatAsset([SplatPrimitive(body.splats, body.anchoring, "body"), static]), two)
    assert main([str(two)]) == 0
    out = capsys.readouterr().out
    assert "430 in 2 primitive(s), SH degree 1" in out
    assert "primitive 0 'body': 400 splats, SH degree 1, anchored" in out
    assert "primitive 1 'sky': 30 splats, SH degree 0, not anchored" in out


@pytest.mark.parametrize("content,suffix", [(b"glTF\x02\x00\x00\x00garbage", ".glb"),
                                            (b"ply\nformat ascii 1.0\nend", ".ply"),
                                            (b"\x00" * 31, ".splat")])
def test_bad_input_is_one_line_and_exit_1(tmp_path, capsys, content, suffix):
    path = tmp_path / f"bad{suffix}"
    path.write_bytes(content)
    assert main([str(path)]) == 1
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert out == "" and len(lines) == 1
    assert lines[0].startswith("gsverse-info: error: ") and str(path) in lines[0]
    assert main([str(path), "--json"]) == 1
    out, err = capsys.readouterr()
    error = json.loads(out)
    assert error["exit"] == 1 and error["input"] == str(path)
    assert error["error"]["kind"] == "input" and error["error"]["path"] == str(path)
    assert error["error"]["message"] == lines[0][len("gsverse-info: error: "):]


def test_missing_input_is_bad_input_and_unknown_formats_are_usage_errors(tmp_path, capsys):
    assert main([str(tmp_path / "none.glb")]) == 1
    assert "none.glb: file not found" in capsys.readouterr().err
    (tmp_path / "x.txt").write_text("hello")
    assert main([str(tmp_path / "x.txt")]) == 2
    assert "unsupported splat input format .txt" in capsys.readouterr().err


def test_the_command_runs_as_a_process(tmp_path):
    """The installed entry point: a bad file gives one line on stderr, exit 1, no traceback."""
    import shutil
    exe = shutil.which("gsverse-info")
    cmd = [exe] if exe else [sys.executable, "-m", "gsverse_format.cli.info"]
    proc = subprocess.run(cmd + ["--version"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and "gsverse-info" in proc.stdout
    (tmp_path / "bad.spz").write_bytes(b"nope")
    proc = subprocess.run(cmd + [str(tmp_path / "bad.spz")], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert proc.stderr.strip() == f"gsverse-info: error: {tmp_path / 'bad.spz'}: not an spz " \
        "file (neither a gzip stream nor an NGSP header)"
