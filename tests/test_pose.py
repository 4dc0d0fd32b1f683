"""``gsverse-pose`` and the deformation sources of :mod:`gsverse_format.poses`.

The Fox test checks posed splats against linear blend skinning written here from the glTF
specification (own GLB parsing, scipy's Slerp), independent of the package's sampler.
"""
from __future__ import annotations

import json
import os

import numpy as np
import pygltflib
import pytest

import gsverse_format as gv
from gsverse_format.cli.pose import main
from gsverse_format.conformance.skin import sample_skin, skinned_tube
from gsverse_format.errors import FormatError, UsageError
from gsverse_format.io.registry import FRAMES
from gsverse_format.model import SplatAsset, SplatPrimitive, TriangleMesh
from gsverse_format.poses import (GltfAnimation, Instance, parse_deformations, read_npz,
                                  read_sequence, read_vat, sample_channel, write_vat)
from gsverse_format.poses.analytic import QuickLook

from helpers import anchor_foot_points, bumpy_sphere, numpy_skinning, surface_splats
from source_fixtures import write_obj

PREFIX = "gsverse-pose: error: "


# ---------------------------------------------------------------------------- fixtures

def _anchored(mesh: TriangleMesh, path, n: int = 400, seed: int = 0, offset: float = 0.0):
    cloud = surface_splats(mesh, n, seed, offset=offset)
    anchoring = gv.bind(cloud, mesh)
    gv.write(SplatAsset([SplatPrimitive(cloud, anchoring, "obj")]), path)
    return gv.read(path)


@pytest.fixture
def sphere_asset(tmp_path):
    mesh = bumpy_sphere(1, 0)
    path = tmp_path / "sphere.glb"
    asset = _anchored(mesh, path)
    return path, asset


@pytest.fixture
def tube_asset(tmp_path):
    glb, rest, faces, _ = skinned_tube()
    src = tmp_path / "skinned.glb"
    src.write_bytes(glb)
    path = tmp_path / "tube.glb"
    _anchored(TriangleMesh(rest, faces), path, 300, 1)
    return path, src, glb


# ---------------------------------------------------------------------------- Fox (real asset)

def _independent_fox_skin(fox_path, animation: int, times):
    """Skinned Fox vertices at ``times`` from the tests' own numpy skinning."""
    g = pygltflib.GLTF2().load(str(fox_path))
    node = next(i for i, n in enumerate(g.nodes) if n.mesh == 0 and n.skin is not None)
    return [numpy_skinning(g, node, t, animation) for t in times]


def test_fox_posed_splats_follow_independent_skinning(shared_data, tmp_path):
    fox = shared_data / "meshes" / "Fox.glb"
    from gsverse_format.io.mesh import read_mesh

    mesh = read_mesh(fox)
    cloud = surface_splats(mesh, 1500, 3, offset=0.0)
    cloud.scales = np.full_like(cloud.scales, 0.4)
    gv.write(SplatAsset([SplatPrimitive(cloud, None, "fox")]), tmp_path / "splats.glb")
    gv.convert(tmp_path / "splats.glb", tmp_path / "fox.glb", mesh=str(fox))
    asset = gv.read(tmp_path / "fox.glb")
    prim = asset.anchored[0]
    np.testing.assert_allclose(prim.anchoring.mesh.vertices, mesh.vertices, atol=1e-4)
    # the stated distance: splats sampled on the surface, |normal offset| tiny at rest
    diag = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
    stated = np.abs(prim.anchoring.anchors.normal_offset.astype(np.float64)) + 1e-4 * diag
    assert stated.max() < 2e-4 * diag

    times = [0.0, 0.3, 0.55, 0.7]     # Walk is 0.708 s long
    out = tmp_path / "posed"
    assert main([str(tmp_path / "fox.glb"), "--source", str(fox), "--animation", "Walk",
                 "--times", *map(str, times), "-o", str(out), "-q"]) == 0
    skinned = _independent_fox_skin(fox, 1, times)
    moved = 0.0
    for i, v in enumerate(skinned):
        posed = gv.read(out / f"fox_f{i:04d}.ply").primitives[0].splats.means
        # distance to the skinned mesh <= distance to the splat's own skinned triangle point
        d = np.linalg.norm(posed - anchor_foot_points(prim, v), axis=1)
        assert np.all(d <= stated), (times[i], d.max(), stated.max())
        moved = max(moved, float(np.abs(posed - prim.splats.means).max()))
    assert moved > 0.05 * diag         # the walk really moves the splats

    # plain KHR GLB output and the anchor mesh as a VAT at a frame rate
    vat = tmp_path / "fox.exr"
    assert main([str(tmp_path / "fox.glb"), "--source", str(fox), "--animation", "1",
                 "--fps", "12", "--format", "glb", "-o", str(tmp_path / "glb"),
                 "--vat", str(vat), "--vat-mode", "offset", "-q"]) == 0
    files = sorted(os.listdir(tmp_path / "glb"))
    assert len(files) == 9 and files[0] == "fox_f0000.glb"      # 0 .. 0.667 s at 12 fps
    posed = gv.read(tmp_path / "glb" / files[6])
    assert posed.anchored == [] and len(posed.primitives[0].splats) == len(cloud)
    v6 = _independent_fox_skin(fox, 1, [0.5])[0]
    assert np.all(np.linalg.norm(posed.primitives[0].splats.means - anchor_foot_points(prim, v6),
                                 axis=1) <= stated)
    cache = read_vat(vat, rest=prim.anchoring.mesh.vertices)
    np.testing.assert_allclose(cache.times, np.arange(9) / 12.0)
    np.testing.assert_allclose(cache.vertices[6], v6, atol=1e-4 * diag)


def test_fox_refuses_a_source_with_other_vertices(shared_data, tmp_path, sphere_asset, capsys):
    path, _ = sphere_asset
    fox = shared_data / "meshes" / "Fox.glb"
    assert main([str(path), "--source", str(fox), "--times", "0", "-o",
                 str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert err.startswith(PREFIX + str(fox)) and "1728 vertices" in err and err.count("\n") == 1
    assert not (tmp_path / "o").exists()


# ---------------------------------------------------------------------------- glTF sources

def test_skinned_source_and_frame_rotation(tmp_path, tube_asset):
    path, src, glb = tube_asset
    asset = gv.read(path)
    prim = asset.anchored[0]
    assert main([str(path), "--source", str(src), "--times", "0.3", "1.0", "-o",
                 str(tmp_path / "o"), "--format", "glb", "-q"]) == 0
    for i, t in enumerate((0.3, 1.0)):
        means = gv.read(tmp_path / "o" / f"tube_f{i:04d}.glb").primitives[0].splats.means
        want = gv.remap(prim.anchoring, sample_skin(glb, t)).means
        np.testing.assert_allclose(means, want, atol=1e-5)
    # an anchor mesh rotated by a converter frame change is matched, and posed rotated too
    r = FRAMES["3dgs"].to_gltf
    mesh = TriangleMesh(prim.anchoring.mesh.vertices @ r.T, prim.anchoring.mesh.faces)
    _anchored(mesh, tmp_path / "rot.glb", 200, 2)
    rot = gv.read(tmp_path / "rot.glb").anchored[0]
    assert main([str(tmp_path / "rot.glb"), "--source", str(src), "--times", "0.75", "-o",
                 str(tmp_path / "r"), "--format", "glb", "-q"]) == 0
    means = gv.read(tmp_path / "r" / "rot_f0000.glb").primitives[0].splats.means
    want = gv.remap(rot.anchoring, sample_skin(glb, 0.75) @ r.T).means
    np.testing.assert_allclose(means, want, atol=1e-5)


def test_rest_mismatch_is_refused(tmp_path, tube_asset, capsys):
    _, src, _ = tube_asset
    _, rest, faces, _ = skinned_tube()
    _anchored(TriangleMesh(rest * 1.01, faces), tmp_path / "fat.glb", 100)
    assert main([str(tmp_path / "fat.glb"), "--source", str(src), "--times", "0", "-o",
                 str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert err.startswith(PREFIX + str(src)) and "rest positions differ" in err


def test_asset_without_animation_needs_a_source(sphere_asset, tmp_path, capsys):
    path, _ = sphere_asset
    assert main([str(path), "--times", "0", "-o", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert err.startswith(PREFIX + str(path)) and "--source" in err


def _doc_and_accessor(arrays):
    return lambda i: np.asarray(arrays[i], np.float64).reshape(len(arrays[i]), -1)


def test_step_cubic_and_morph_weights():
    times = np.array([0.0, 1.0, 3.0])
    vals = np.array([[0.0], [2.0], [4.0]])
    assert sample_channel(times, vals, "STEP", "translation", 0.99)[0] == 0.0
    assert sample_channel(times, vals, "STEP", "translation", 1.5)[0] == 2.0
    assert sample_channel(times, vals, "LINEAR", "translation", 2.0)[0] == 3.0
    # CUBICSPLINE: (in, value, out) per key; Hermite with tangents scaled by the interval
    cubic = np.array([[0.0], [0.0], [1.0], [1.0], [2.0], [0.0], [0.0], [4.0], [0.0]])
    s, dt = 0.5, 1.0
    want = ((2 * s**3 - 3 * s**2 + 1) * 0.0 + (s**3 - 2 * s**2 + s) * dt * 1.0
            + (-2 * s**3 + 3 * s**2) * 2.0 + (s**3 - s**2) * dt * 1.0)
    assert sample_channel(times, cubic, "CUBICSPLINE", "translation", 0.5)[0] == \
        pytest.approx(want)
    assert sample_channel(times, cubic, "CUBICSPLINE", "translation", 9.0)[0] == 4.0
    with pytest.raises(FormatError):
        sample_channel(times, vals, "BEZIER", "translation", 0.5)
    # a morphed (not skinned) mesh animated by a weights channel and a node translation
    base = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    target = [[0, 0, 1], [0, 0, 1], [0, 0, 1]]
    arrays = [base, target, [[0.0], [2.0]], [[0.0], [1.0]], [[0, 0, 0], [5, 0, 0]]]
    doc = {"scenes": [{"nodes": [0]}], "scene": 0,
           "nodes": [{"mesh": 0, "translation": [0, 0, 0]}],
           "meshes": [{"weights": [0.25], "primitives": [{"attributes": {"POSITION": 0},
                                                          "targets": [{"POSITION": 1}]}]}],
           "animations": [{"samplers": [{"input": 2, "output": 3},
                                        {"input": 2, "output": 4}],
                           "channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}},
                                        {"sampler": 1,
                                         "target": {"node": 0, "path": "translation"}}]}]}
    anim = GltfAnimation(doc, _doc_and_accessor(arrays), 0)
    assert anim.duration() == 2.0
    v = anim.vertices(1.0, [Instance(0, 0, 0)])
    np.testing.assert_allclose(v, np.asarray(base) + [2.5, 0, 0.5])
    rest = GltfAnimation(doc, _doc_and_accessor(arrays), None).vertices(None)
    np.testing.assert_allclose(rest, np.asarray(base) + [0, 0, 0.25])
    with pytest.raises(FormatError, match="no animation named"):
        GltfAnimation(doc, _doc_and_accessor(arrays), "Run")


# ---------------------------------------------------------------------------- vertex caches

def test_npz_and_obj_sequence_sources(sphere_asset, tmp_path):
    path, asset = sphere_asset
    prim = asset.anchored[0]
    rest = prim.anchoring.mesh.vertices.astype(np.float64)
    frames = np.stack([rest * [1.0, 1.0 + 0.2 * k, 1.0] for k in range(4)])
    np.savez(tmp_path / "cache.npz", vertices=frames, times=[0.0, 0.1, 0.2, 0.4])
    assert main([str(path), "--source", str(tmp_path / "cache.npz"), "--times", "0.1", "0.3",
                 "-o", str(tmp_path / "n"), "--format", "glb", "-q"]) == 0
    got = gv.read(tmp_path / "n" / "sphere_f0001.glb").primitives[0].splats.means
    want = gv.remap(prim.anchoring, 0.5 * (frames[2] + frames[3])).means   # linear in time
    np.testing.assert_allclose(got, want, atol=1e-5)
    assert read_npz(tmp_path / "cache.npz").duration() == pytest.approx(0.4)

    seq = tmp_path / "seq"
    seq.mkdir()
    for k in (0, 1, 2, 10):        # natural order: frame_10 is the last
        write_obj(seq / f"frame_{k}.obj", rest * [1.0, 1.0, 1.0 + 0.1 * k],
                  prim.anchoring.mesh.faces)
    cache = read_sequence(str(seq), fps=10)
    np.testing.assert_allclose(cache.times, [0.0, 0.1, 0.2, 0.3])
    np.testing.assert_allclose(cache.vertices[3], rest * [1, 1, 2.0], atol=1e-5)
    assert main([str(path), "--source", str(seq / "frame_*.obj"), "--source-fps", "10",
                 "--fps", "10", "-o", str(tmp_path / "s"), "--format", "glb", "-q"]) == 0
    assert len(os.listdir(tmp_path / "s")) == 4
    got = gv.read(tmp_path / "s" / "sphere_f0003.glb").primitives[0].splats.means
    np.testing.assert_allclose(got, gv.remap(prim.anchoring, rest * [1, 1, 2.0]).means,
                               atol=1e-4)


def test_cache_with_other_vertex_count_is_refused(sphere_asset, tmp_path, capsys):
    path, _ = sphere_asset
    np.savez(tmp_path / "bad.npz", vertices=np.zeros((2, 5, 3)))
    assert main([str(path), "--source", str(tmp_path / "bad.npz"), "--times", "0", "-o",
                 str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert err.startswith(PREFIX + str(tmp_path / "bad.npz")) and "5 vertices" in err


# ---------------------------------------------------------------------------- VAT

@pytest.mark.parametrize("mode", ["position", "offset"])
@pytest.mark.parametrize("half,normalized", [(False, False), (True, False), (False, True)])
def test_vat_round_trip_and_layout(tmp_path, mode, half, normalized):
    import OpenEXR

    rng = np.random.default_rng(5)
    rest = rng.normal(size=(10, 3))
    poses = rest[None] + 0.1 * rng.normal(size=(3, 10, 3))
    times = np.array([0.0, 0.5, 1.0])
    path = tmp_path / "v.exr"
    write_vat(path, times, poses, rest=rest, mode=mode, half=half, width=4,
              normalized=normalized)
    cache = read_vat(path, rest=rest)
    tol = 2e-3 if half else 1e-6
    np.testing.assert_allclose(cache.vertices, poses, atol=tol)
    np.testing.assert_allclose(cache.times, times)
    with OpenEXR.File(str(path)) as exr:          # the documented layout, texel by texel
        header = dict(exr.header())
        pixels = np.asarray(exr.channels()["RGB"].pixels, np.float64)
    assert pixels.shape == (3 * 3, 4, 3)            # 10 vertices in rows of 4: 3 rows a frame
    assert pixels.dtype == np.float64 and header["gsverseVat:rowsPerFrame"] == 3
    assert header["gsverseVat:mode"] == mode and header["gsverseVat:vertexCount"] == 10
    stored = poses - rest[None] if mode == "offset" else poses
    if normalized:
        lo, hi = header["gsverseVat:boundsMin"], header["gsverseVat:boundsMax"]
        stored = (stored - lo) / (hi - lo)
    f, v = 2, 9                                      # frame 2, vertex 9: row 2*3 + 2, column 1
    np.testing.assert_allclose(pixels[8, 1], stored[f, v], atol=tol * 10)
    assert np.all(pixels[8, 2:] == 0)                # padding after the last vertex


def test_vat_of_another_tool_and_errors(tmp_path):
    import OpenEXR

    rng = np.random.default_rng(1)
    frames = rng.normal(size=(3, 6, 3)).astype(np.float32)
    with OpenEXR.File({"type": OpenEXR.scanlineimage},
                      {"RGB": frames}) as exr:   # no attributes: one row a frame
        exr.write(str(tmp_path / "plain.exr"))
    cache = read_vat(tmp_path / "plain.exr", fps=30)
    np.testing.assert_allclose(cache.vertices, frames, atol=1e-7)
    np.testing.assert_allclose(cache.times, np.arange(3) / 30)
    with pytest.raises(FormatError, match="not a multiple"):
        read_vat(tmp_path / "plain.exr", vertex_count=10)
    (tmp_path / "junk.exr").write_bytes(b"not an exr")
    with pytest.raises(FormatError, match="junk.exr"):
        read_vat(tmp_path / "junk.exr")
    with pytest.raises(UsageError):
        write_vat(tmp_path / "o.exr", [0.0], frames[:1], mode="offset")


def test_vat_from_the_command_line(sphere_asset, tmp_path):
    path, asset = sphere_asset
    rest = asset.anchored[0].anchoring.mesh.vertices
    vat = tmp_path / "twist.exr"
    # a quick look is one pose: one frame (t = 0, by default)
    assert main([str(path), "--deform", "twist=60", "--vat", str(vat), "--vat-width", "7",
                 "--vat-half", "-q"]) == 0
    cache = read_vat(vat)
    want = QuickLook("twist", 60.0).apply(rest, rest)
    assert len(cache.vertices) == 1
    np.testing.assert_allclose(cache.vertices[0], want, atol=2e-3)
    # the VAT drives a pose again: same splats as the quick look itself
    assert main([str(path), "--source", str(vat), "--times", "0", "-o", str(tmp_path / "o"),
                 "--format", "glb", "-q"]) == 0
    got = gv.read(tmp_path / "o" / "sphere_f0000.glb").primitives[0].splats.means
    np.testing.assert_allclose(got, gv.remap(asset.anchored[0].anchoring, want).means,
                               atol=5e-3)


# ---------------------------------------------------------------------------- analytic

def test_quick_looks(sphere_asset, tmp_path):
    path, asset = sphere_asset
    prim = asset.anchored[0]
    rest = prim.anchoring.mesh.vertices.astype(np.float64)
    looks = parse_deformations(["stretch=1.5", "bend=45", "shake=0.01"])
    assert [q.kind for q in looks] == ["stretch", "bend", "shake"]
    stretched = looks[0].apply(rest, rest)
    assert np.ptp(stretched[:, 1]) == pytest.approx(1.5 * np.ptp(rest[:, 1]))
    np.testing.assert_allclose(np.ptp(stretched[:, [0, 2]], axis=0), np.ptp(rest[:, [0, 2]], 0))
    a, b = looks[2].apply(rest, rest, 0.5), looks[2].apply(rest, rest, 0.5)
    np.testing.assert_array_equal(a, b)                      # seeded by the time
    assert not np.allclose(a, looks[2].apply(rest, rest, 1.0))
    assert main([str(path), "--deform", "stretch=1.5", "--deform", "twist=90", "--times", "0",
                 "-o", str(tmp_path / "o"), "--format", "glb", "-q"]) == 0
    want = QuickLook("twist", 90).apply(QuickLook("stretch", 1.5).apply(rest, rest), rest)
    got = gv.read(tmp_path / "o" / "sphere_f0000.glb").primitives[0].splats.means
    np.testing.assert_allclose(got, gv.remap(prim.anchoring, want).means, atol=1e-5)
    for bad in ("squash=2", "stretch", "stretch=-1", "twist=abc"):
        with pytest.raises(UsageError):
            parse_deformations([bad])


# ---------------------------------------------------------------------------- command line

def _usd_positions(path) -> list[np.ndarray]:
    """The splat positions of the first splat prim of a USD file, at each time sample."""
    from pxr import Usd, UsdVol

    stage = Usd.Stage.Open(str(path))
    prim = next(p for p in stage.Traverse() if p.IsA(UsdVol.ParticleField3DGaussianSplat))
    attr = UsdVol.ParticleField3DGaussianSplat(prim).GetPositionsAttr()
    return [np.asarray(attr.Get(t)) for t in attr.GetTimeSamples()]


def test_ply_and_usd_outputs(sphere_asset, tmp_path):
    pytest.importorskip("pxr")
    path, asset = sphere_asset
    looks = ["--deform", "bend=30", "--deform", "shake=0.01"]    # shake: a new pose each time
    # the older spelling: --format usd into a folder writes <asset>.usda
    assert main([str(path), *looks, "--fps", "2", "--duration", "1", "--format", "usd",
                 "-o", str(tmp_path / "u"), "-q"]) == 0
    usda = tmp_path / "u" / "sphere.usda"
    assert usda.is_file() and "timeSamples" in usda.read_text()
    # a .usdc OUT is a binary crate with the same time samples; --to picks it for a folder
    assert main([str(path), str(tmp_path / "posed.usdc"), *looks, "--fps", "2", "--duration",
                 "1", "-q"]) == 0
    assert main([str(path), *looks, "--fps", "2", "--duration", "1", "--to", "usdc",
                 "--output-dir", str(tmp_path / "c"), "-q"]) == 0
    want = _usd_positions(usda)
    assert len(want) == 3 and not np.array_equal(want[1], want[2])
    for crate in (tmp_path / "posed.usdc", tmp_path / "c" / "sphere.usdc"):
        assert crate.read_bytes()[:8] == b"PXR-USDC"
        got = _usd_positions(crate)
        assert len(got) == 3 and all(np.array_equal(a, b) for a, b in zip(got, want))
    # the suffix decides; a --to that disagrees with it is bad usage, nothing written
    assert main([str(path), str(tmp_path / "x.usdc"), *looks, "--to", "usda", "--times", "0",
                 "1"]) == 2
    assert not (tmp_path / "x.usdc").exists()
    # a quick look alone: one time (t = 0) by default, written to the file OUT names
    assert main([str(path), str(tmp_path / "look.ply"), "--deform", "bend=30", "-q"]) == 0
    ply = gv.read(tmp_path / "look.ply")      # 3DGS PLY, read back into glTF
    rest = asset.anchored[0].anchoring.mesh.vertices
    want = gv.remap(asset.anchored[0].anchoring, QuickLook("bend", 30).apply(rest, rest)).means
    np.testing.assert_allclose(ply.primitives[0].splats.means, want, atol=1e-5)
    assert main([str(path), "--deform", "bend=30", "--times", "0", "-o", str(tmp_path / "p"),
                 "-q"]) == 0
    ply = gv.read(tmp_path / "p" / "sphere_f0000.ply")
    np.testing.assert_allclose(ply.primitives[0].splats.means, want, atol=1e-5)
    assert sorted(os.listdir(tmp_path / "p")) == ["sphere_f0000.ply"]


def test_quick_looks_never_write_identical_frames(sphere_asset, tmp_path, capsys):
    """Quick looks alone are one pose: several times of them are refused (they would be the
    same frame), unless a look changes with time (shake); a time given twice is refused."""
    path, _ = sphere_asset
    for when in (["--times", "0", "1"], ["--fps", "4", "--duration", "1"]):
        assert main([str(path), str(tmp_path / "o"), "--deform", "twist=45", *when]) == 2
        (line,) = capsys.readouterr().err.strip().splitlines()
        assert "identical frames" in line and "shake" in line
        assert not (tmp_path / "o").exists()
    assert main([str(path), str(tmp_path / "s"), "--deform", "twist=45", "--deform",
                 "shake=0.02", "--times", "0", "1", "--to", "glb", "-q"]) == 0
    frames = [gv.read(tmp_path / "s" / f"sphere_f000{i}.glb").primitives[0].splats.means
              for i in range(2)]
    assert not np.allclose(frames[0], frames[1])
    assert main([str(path), str(tmp_path / "t"), "--deform", "shake=0.02", "--times", "1",
                 "1"]) == 2
    assert "more than once" in capsys.readouterr().err
    # several posed files named after a file OUT: OUT_fNNNN beside it
    assert main([str(path), str(tmp_path / "shaken.ply"), "--deform", "shake=0.02",
                 "--times", "0", "0.5", "1", "-q"]) == 0
    assert sorted(p.name for p in tmp_path.glob("shaken*")) == \
        ["shaken_f0000.ply", "shaken_f0001.ply", "shaken_f0002.ply"]


def test_command_line_errors(sphere_asset, tmp_path, capsys):
    path, _ = sphere_asset
    out = tmp_path / "o"
    base = [str(path), "--deform", "twist=10", "--deform", "shake=0.01"]
    assert main(base + ["--times", "0"]) == 2                       # nothing to write
    assert "nothing to write" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(base + ["--times", "0", "--fps", "3", "-o", str(out)])
    assert exc.value.code == 2
    capsys.readouterr()
    assert main([str(tmp_path / "missing.glb"), "--times", "0", "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert err == PREFIX + f"{tmp_path / 'missing.glb'}: file not found\n"
    assert main(base + ["--deform", "wobble=3", "--times", "0", "-o", str(out)]) == 2
    assert "wobble" in capsys.readouterr().err
    assert main(base + ["--times", "0", "--vat", str(tmp_path / "v.png")]) == 2
    assert main(base + ["--times", "0", "--source", str(tmp_path / "nope.npz"),
                        "-o", str(out)]) == 1
    capsys.readouterr()
    # plain (unanchored) splats cannot be posed
    plain = tmp_path / "plain.glb"
    gv.write(SplatAsset([SplatPrimitive(surface_splats(bumpy_sphere(1, 0), 50), None)]), plain)
    assert main([str(plain), "--deform", "twist=5", "--times", "0", "-o", str(out)]) == 1
    assert "no anchored splats" in capsys.readouterr().err
    # existing outputs: refused without -w (nothing written), replaced with it
    assert main(base + ["--times", "0", "1", "-o", str(out), "-q"]) == 0
    first = (out / "sphere_f0000.ply").stat().st_mtime_ns
    assert main(base + ["--times", "0", "1", "2", "-o", str(out)]) == 2
    assert "-w/--overwrite" in capsys.readouterr().err
    assert not (out / "sphere_f0002.ply").exists()
    assert (out / "sphere_f0000.ply").stat().st_mtime_ns == first
    assert main(base + ["--times", "0", "1", "2", "-o", str(out), "-w", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["times"] == [0.0, 1.0, 2.0] and len(summary["outputs"]) == 3
    assert not [f for f in os.listdir(out) if f.startswith(".tmp")]


def _with_own_skin(asset_path, glb: bytes, out_path) -> None:
    """The anchored asset at ``asset_path`` with the skin, joints and animation of the skinned
    tube ``glb`` added to its anchor mesh (the layout an animated anchor mesh has in a file)."""
    from gsverse_format.conformance.glb import (accessor_bytes, anchor_extension, append_accessor,
                                                pack_glb, unpack_glb)

    doc, blob = unpack_glb(asset_path.read_bytes())
    sdoc, sblob = unpack_glb(glb)
    ext = anchor_extension(doc)
    prim = doc["meshes"][ext["mesh"]]["primitives"][ext.get("primitive", 0)]
    sattrs = sdoc["meshes"][0]["primitives"][0]["attributes"]
    copied: dict[int, int] = {}

    def copy(i: int) -> int:
        if i not in copied:
            a = sdoc["accessors"][i]
            values = accessor_bytes(sdoc, sblob, i)
            nonlocal blob
            copied[i], blob = append_accessor(doc, blob, values, a["componentType"], a["type"])
            if "min" in a:
                doc["accessors"][copied[i]].update(min=a["min"], max=a["max"])
        return copied[i]

    prim["attributes"]["JOINTS_0"] = copy(sattrs["JOINTS_0"])
    prim["attributes"]["WEIGHTS_0"] = copy(sattrs["WEIGHTS_0"])
    base = len(doc["nodes"])
    joints = [dict(n) for n in sdoc["nodes"][1:]]
    for n in joints:
        if "children" in n:
            n["children"] = [c - 1 + base for c in n["children"]]
    doc["nodes"] += joints + [{"name": "anchor mesh", "mesh": ext["mesh"],
                               "skin": len(doc.get("skins", []))}]
    doc["scenes"][doc.get("scene", 0)]["nodes"] += [base, base + len(joints)]
    skin = sdoc["skins"][0]
    doc.setdefault("skins", []).append({"joints": [j - 1 + base for j in skin["joints"]],
                                        "inverseBindMatrices": copy(skin["inverseBindMatrices"]),
                                        "skeleton": base})
    anim = sdoc["animations"][0]
    doc["animations"] = [{"name": anim["name"], "samplers": [
        {"input": copy(s["input"]), "output": copy(s["output"]),
         "interpolation": s.get("interpolation", "LINEAR")} for s in anim["samplers"]],
        "channels": [{"sampler": c["sampler"], "target": {"node": c["target"]["node"] - 1 + base,
                                                         "path": c["target"]["path"]}}
                     for c in anim["channels"]]}]
    out_path.write_bytes(pack_glb(doc, blob))


def test_the_assets_own_skinned_anchor_mesh(tmp_path, tube_asset):
    path, _, glb = tube_asset
    own = tmp_path / "own.glb"
    _with_own_skin(path, glb, own)
    prim = gv.read(own).anchored[0]
    assert main([str(own), "--fps", "4", "-o", str(tmp_path / "o"), "--format", "glb",
                 "-q"]) == 0                                   # 0 .. 1 s: the animation's length
    assert len(os.listdir(tmp_path / "o")) == 5
    means = gv.read(tmp_path / "o" / "own_f0003.glb").primitives[0].splats.means
    np.testing.assert_allclose(means, gv.remap(prim.anchoring, sample_skin(glb, 0.75)).means,
                               atol=1e-5)
