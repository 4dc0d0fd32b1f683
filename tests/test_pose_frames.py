"""Posed outputs in the frame the asset was converted in: ``gsverse-convert`` with and without
``--no-frame-change``, then ``gsverse-pose`` at rest, gives back the input's positions in every
output format where a frame change applies (PLY), and keeps the asset's values and frame record
in the others (GLB, USD)."""
from __future__ import annotations

import numpy as np
import pygltflib
import pytest

import gsverse_format as gv
from gsverse_format.cli.convert import main as convert_main
from gsverse_format.cli.pose import main as pose_main
from gsverse_format.io.registry import FRAMES, read_asset
from gsverse_format.model import SplatAsset, SplatPrimitive
from gsverse_format.vocabulary import RECORDED_FRAMES

from helpers import bumpy_sphere, surface_splats
from source_fixtures import write_obj

#: a stretch by 1 is the rest pose: quick looks need an amount, and this one moves nothing
AT_REST = ["--deform", "stretch=1"]


@pytest.fixture
def ply_input(tmp_path):
    """A 3DGS PLY (values in the 3DGS frame, as the file holds them) and an OBJ mesh in the
    same frame, both placed off-centre so that a 180° turn about Z moves every point."""
    mesh = bumpy_sphere(1, 0)
    mesh.vertices = mesh.vertices + np.array([2.0, 1.0, 0.5])
    cloud = surface_splats(mesh, 300, 3, offset=0.01)
    ply, obj = tmp_path / "in.ply", tmp_path / "mesh.obj"
    gv.write(SplatAsset([SplatPrimitive(cloud, None, "in")]), ply, frame_change=False)
    write_obj(obj, mesh.vertices, mesh.faces)
    raw = read_asset(ply, frame_change=False).primitives[0].splats.means.astype(np.float64)
    return ply, obj, raw


def _sorted(points: np.ndarray) -> np.ndarray:
    """Rows in lexicographic order: the converter sorts anchored splats by face."""
    return points[np.lexsort(points.T[::-1])]


def _all_means(asset) -> np.ndarray:
    return np.concatenate([p.splats.means for p in asset.primitives]).astype(np.float64)


def test_recorded_frames_are_frames():
    assert set(RECORDED_FRAMES) == set(FRAMES) - {"gltf"}


@pytest.mark.parametrize("frame_change", [True, False], ids=["frame-change", "no-frame-change"])
def test_posed_ply_at_rest_gives_back_the_input(tmp_path, ply_input, frame_change):
    ply, obj, raw = ply_input
    glb = tmp_path / "anchored.glb"
    flags = [] if frame_change else ["--no-frame-change"]
    assert convert_main([str(ply), str(glb), "--mesh", str(obj), *flags, "-q"]) == 0
    extras = pygltflib.GLTF2().load(str(glb)).asset.extras
    assert (extras or {}).get("gsverse") == (None if frame_change else {"frame": "3dgs"})
    asset = gv.read(glb)
    assert asset.frame == ("gltf" if frame_change else "3dgs")
    stored = _all_means(asset)
    want = raw @ FRAMES["3dgs"].to_gltf.T if frame_change else raw
    np.testing.assert_allclose(_sorted(stored), _sorted(want), atol=1e-6)

    posed = tmp_path / "posed.ply"
    assert pose_main([str(glb), str(posed), *AT_REST, "-q"]) == 0
    got = read_asset(posed, frame_change=False).primitives[0].splats.means.astype(np.float64)
    # float32 storage, and a remap at rest recomputes each mean from its anchor (float64)
    np.testing.assert_allclose(_sorted(got), _sorted(raw), atol=1e-5)
    # the posed PLY is in the input's frame: far from where a wrong turn would put it
    assert np.abs(_sorted(got) - _sorted(raw @ FRAMES["3dgs"].to_gltf.T)).max() > 1.0


@pytest.mark.parametrize("suffix", [".glb", ".usda"])
def test_posed_glb_and_usd_keep_the_assets_frame(tmp_path, ply_input, suffix):
    """glTF and USD outputs hold the asset's values as they are and record its frame."""
    if suffix == ".usda":
        pytest.importorskip("pxr")
    ply, obj, raw = ply_input
    glb = tmp_path / "anchored.glb"
    assert convert_main([str(ply), str(glb), "--mesh", str(obj), "--no-frame-change",
                         "-q"]) == 0
    posed = tmp_path / f"posed{suffix}"
    times = ["--times", "0"] if suffix == ".usda" else []
    assert pose_main([str(glb), str(posed), *AT_REST, *times, "-q"]) == 0
    back = gv.read(posed)
    assert back.frame == "3dgs"
    np.testing.assert_allclose(_sorted(_all_means(back)), _sorted(raw), atol=1e-5)


def test_no_frame_change_flag_for_an_asset_that_records_nothing(tmp_path, ply_input):
    """An asset another tool wrote in the source's frame records nothing: --no-frame-change
    on gsverse-pose keeps its values; without it the PLY gets the glTF-to-3DGS turn."""
    ply, obj, raw = ply_input
    glb = tmp_path / "anchored.glb"
    assert convert_main([str(ply), str(glb), "--mesh", str(obj), "--no-frame-change",
                         "-q"]) == 0
    g = pygltflib.GLTF2().load(str(glb))
    g.asset.extras = None
    plain = tmp_path / "plain.glb"
    g.save(str(plain))
    assert gv.read(plain).frame == "gltf"
    kept, turned = tmp_path / "kept.ply", tmp_path / "turned.ply"
    assert pose_main([str(plain), str(kept), *AT_REST, "--no-frame-change", "-q"]) == 0
    assert pose_main([str(plain), str(turned), *AT_REST, "-q"]) == 0
    got = read_asset(kept, frame_change=False).primitives[0].splats.means.astype(np.float64)
    np.testing.assert_allclose(_sorted(got), _sorted(raw), atol=1e-5)
    got = read_asset(turned, frame_change=False).primitives[0].splats.means.astype(np.float64)
    np.testing.assert_allclose(_sorted(got), _sorted(raw @ FRAMES["3dgs"].to_gltf), atol=1e-5)


def test_a_converted_ply_back_to_ply_keeps_its_frame(tmp_path, ply_input):
    """gsverse-convert of an asset that records the 3DGS frame back to PLY (frame change on)
    writes the values as they are: they are in the PLY's frame already."""
    ply, obj, raw = ply_input
    glb, back = tmp_path / "plain.glb", tmp_path / "back.ply"
    assert convert_main([str(ply), str(glb), "--no-frame-change", "-q"]) == 0
    assert gv.read(glb).frame == "3dgs"
    assert convert_main([str(glb), str(back), "-q"]) == 0
    got = read_asset(back, frame_change=False).primitives[0].splats.means.astype(np.float64)
    np.testing.assert_allclose(_sorted(got), _sorted(raw), atol=1e-5)
