"""TRELLIS, mesh reconstruction and KHR sources; mesh operations (decimate, weld, repair, stats).

Inputs are generated to mimic each tool's layout: a TRELLIS run is an object in TRELLIS's
internal Z-up frame whose splats are written as ``Gaussian.save_ply`` does (export rotation T
on positions and orientations, SH0, zero normals, logit/log values) and whose mesh is written
as ``to_glb`` does (vertices ``(x, z, −y)``, vertices duplicated along UV seams, textured GLB).
"""
from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from gsverse_format import meshops
from gsverse_format.converters import khr, reconstruct, trellis
from gsverse_format.converters.base import SourceOptions
from gsverse_format.pipeline import load_source
from gsverse_format.errors import FormatError, UsageError
from gsverse_format.io.gltf import write_gltf
from gsverse_format.io.mesh import read_mesh
from gsverse_format.io.ply import write_splat_ply
from gsverse_format.binding import bind_local
from gsverse_format.model import Anchoring, SplatAsset, SplatCloud, SplatPrimitive, TriangleMesh
from gsverse_format.transform import rotate_splats

T = trellis.T_EXPORT


# --------------------------------------------------------------------------- generators

def _icosphere(subdivisions: int = 3) -> TriangleMesh:
    ico = trimesh.creation.icosphere(subdivisions)
    return TriangleMesh(ico.vertices, ico.faces)


def _trellis_object(seed: int = 0) -> TriangleMesh:
    """An asymmetric bumpy ellipsoid inside [-0.5, 0.5]^3 (TRELLIS's internal Z-up frame)."""
    ico = trimesh.creation.icosphere(3)
    rng = np.random.default_rng(seed)
    v = ico.vertices * np.array([0.35, 0.25, 0.15])
    v = v * (1.0 + 0.1 * rng.uniform(-1, 1, (len(v), 1))) + np.array([0.08, 0.05, -0.1])
    return TriangleMesh(v, ico.faces)


def _surface_points(mesh: TriangleMesh, n: int, seed: int, offset: float = 0.0):
    rng = np.random.default_rng(seed)
    tri = mesh.triangles()
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    f = rng.choice(mesh.face_count, n, p=area / area.sum())
    p = np.einsum("nk,nkx->nx", rng.dirichlet([1, 1, 1], n), tri[f])
    nrm = np.cross(tri[f, 1] - tri[f, 0], tri[f, 2] - tri[f, 0])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    return p + nrm * rng.normal(0.0, offset, (n, 1)), nrm


def _trellis_splats(means: np.ndarray, seed: int) -> SplatCloud:
    """Splats with TRELLIS-like values: SH0, scales above the 9e-4 minimum kernel."""
    rng = np.random.default_rng(seed)
    n = len(means)
    return SplatCloud(means, Rotation.random(n, random_state=seed).as_quat(),
                      np.exp(rng.uniform(np.log(2e-3), np.log(2e-2), (n, 3))),
                      rng.uniform(0.1, 1.0, n), rng.normal(0.0, 0.5, (n, 1, 3)))


def _flat_splats(points: np.ndarray, normals: np.ndarray, seed: int) -> SplatCloud:
    """Flat 3DGS-like splats whose shortest axis is ``±normal`` (random sign, random column)."""
    rng = np.random.default_rng(seed)
    n = len(points)
    z = normals * np.where(rng.uniform(size=n) < 0.5, -1.0, 1.0)[:, None]
    a = np.where(np.abs(z[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    x = np.cross(a, z)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    r = np.stack([x, np.cross(z, x), z], axis=2)                  # columns x, y, z = normal
    scales = np.tile([0.01, 0.012, 0.001], (n, 1))
    perm = rng.permuted(np.tile([0, 1, 2], (n, 1)), axis=1)       # shuffle the axes per splat
    r = np.take_along_axis(r, perm[:, None, :], axis=2)
    scales = np.take_along_axis(scales, perm, axis=1)
    r[np.linalg.det(r) < 0, :, 0] *= -1                            # keep proper rotations
    return SplatCloud(points, Rotation.from_matrix(r).as_quat(), scales,
                      rng.uniform(0.3, 1.0, n), rng.normal(0.0, 0.3, (n, 1, 3)))


def _uv_split(mesh: TriangleMesh, seed: int = 0) -> TriangleMesh:
    """Duplicate vertices along a seam (two charts split at the object's middle), like xatlas."""
    f = mesh.faces.astype(np.int64).copy()
    v = mesh.vertices
    centre = v.mean(axis=0)
    right = mesh.triangles().mean(axis=1)[:, 0] > centre[0]
    used = np.unique(f[right])
    remap = np.arange(len(v))
    remap[used] = len(v) + np.arange(len(used))
    f[right] = remap[f[right]]
    return TriangleMesh(np.concatenate([v, v[used]]), f)


def _write_to_glb(internal: TriangleMesh, path) -> None:
    """Write ``internal`` (TRELLIS Z-up frame) as to_glb does: v @ T = (x, z, -y), UV-split."""
    split = _uv_split(internal)
    vg = split.vertices.astype(np.float64) @ T
    uv = np.random.default_rng(1).uniform(0, 1, (len(vg), 2))
    tm = trimesh.Trimesh(vg, split.faces, process=False,
                         visual=trimesh.visual.TextureVisuals(uv=uv))
    tm.export(str(path))


def _write_trellis_run(folder, *, legacy: bool = False, n: int = 4000, offset: float = 0.003):
    """A TRELLIS-like run: PLY + GLB. Returns (ply, glb, splats in the GLB frame)."""
    obj = _trellis_object()
    points, _ = _surface_points(obj, n, seed=2, offset=offset)
    internal = _trellis_splats(points, seed=3)
    ply, glb = folder / ("legacy.ply" if legacy else "run.ply"), folder / "run.glb"
    write_splat_ply(internal if legacy else rotate_splats(internal, T), ply, normals=True)
    _write_to_glb(obj, glb)
    return ply, glb, rotate_splats(internal, T.T)


# --------------------------------------------------------------------------- meshops

def test_weld_restores_uv_split_mesh_keeping_order():
    mesh = _icosphere(3)
    split = _uv_split(mesh)
    before = meshops.mesh_stats(split)
    assert before.components == 2 and before.boundary_edges > 0
    welded = meshops.weld(split)
    assert np.array_equal(welded.faces, mesh.faces)
    assert np.array_equal(welded.vertices, mesh.vertices)
    after = meshops.mesh_stats(welded)
    assert after.components == 1 and after.closed
    assert np.array_equal(meshops.weld(split, 1e-6).faces, mesh.faces)


def test_weld_tolerance_degenerate_faces_and_signed_zero():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1e-7, 0, 0], [-0.0, 1, 0], [0.5, 0.5, 1]],
                 np.float32)
    f = np.array([[0, 1, 2], [3, 1, 5], [4, 5, 0], [0, 3, 5]])
    mesh = TriangleMesh(v, f)
    exact = meshops.weld(mesh)               # -0.0 == 0.0 merges vertex 4 into 2 only
    assert len(exact.vertices) == 5 and exact.face_count == 4
    near = meshops.weld(mesh, tolerance=1e-6)
    assert len(near.vertices) == 4
    assert np.array_equal(near.vertices[0], v[0])        # lowest index keeps its position
    assert near.face_count == 4                          # collapsed face [0, 0, 5] kept ...
    assert meshops.weld(mesh, 1e-6, drop_degenerate=True).face_count == 3   # ... unless asked
    with pytest.raises(UsageError):
        meshops.weld(mesh, tolerance=-1.0)


def test_decimate_closed_mesh_reaches_target_and_is_clean():
    mesh = _icosphere(4)                                 # 5120 faces, unit sphere
    out = meshops.decimate(mesh, 1000)
    stats = meshops.mesh_stats(out)
    assert 950 <= stats.faces <= 1005
    assert stats.degenerate_faces == stats.duplicate_faces == stats.unreferenced_vertices == 0
    assert stats.closed and stats.components == 1
    radius = np.linalg.norm(out.vertices, axis=1)
    assert np.all(np.abs(radius - 1.0) < 0.02)


def test_decimate_open_mesh_keeps_its_border():
    mesh = _icosphere(4)
    keep = mesh.triangles().mean(axis=1)[:, 2] > 0.0
    half = meshops.clean(TriangleMesh(mesh.vertices, mesh.faces[keep]))
    out = meshops.decimate(half, 600)
    stats = meshops.mesh_stats(out)
    assert stats.faces <= 610 and stats.boundary_edges > 0 and stats.nonmanifold_edges == 0
    edges, counts = meshops.edge_valence(out.faces)
    rim = np.unique(edges[counts == 1])
    size = meshops.mesh_stats(half).diagonal  # the border of the input lies at its lowest z
    z_min = half.vertices[:, 2].min()
    assert np.allclose(out.vertices[rim, 2], z_min, atol=0.02 * size)


def test_decimate_arguments_and_small_meshes():
    mesh = _icosphere(1)
    assert meshops.decimate(mesh, 10_000).face_count == mesh.face_count
    with pytest.raises(UsageError):
        meshops.decimate(mesh, 3)
    with pytest.raises(FormatError, match="no faces"):
        meshops.decimate(TriangleMesh(np.zeros((3, 3)), np.zeros((0, 3), int)), 10)
    bad = TriangleMesh(np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]]), [[0, 1, 2]])
    with pytest.raises(FormatError, match="NaN"):
        meshops.decimate(bad, 10)


def test_repair_removes_defects_and_keeps_order():
    mesh = _icosphere(2)
    n, f = len(mesh.vertices), mesh.faces.astype(np.int64)
    v = np.concatenate([mesh.vertices, [[3.0, 3.0, 3.0], [9.0, 9.0, 9.0]]])  # fin tip, unused
    fin = [[f[0, 0], f[0, 1], n]]
    faces = np.concatenate([f, fin, f[:2], f[3:4, ::-1], [[0, 0, 1]], [[1, 2, 1]]])
    broken = TriangleMesh(v, faces)
    stats = meshops.mesh_stats(broken)
    assert stats.nonmanifold_edges > 0 and stats.duplicate_faces == 3
    assert stats.degenerate_faces == 2 and stats.unreferenced_vertices == 1
    fixed = meshops.repair(broken)
    after = meshops.mesh_stats(fixed)
    assert after.nonmanifold_edges == after.duplicate_faces == after.degenerate_faces == 0
    assert after.unreferenced_vertices == 0
    # surviving faces keep their positions and relative order
    def key(mesh_, faces_):
        return [tuple(np.round(mesh_.vertices[i], 6).tolist() for i in face) for face in faces_]
    original = key(broken, broken.faces)
    survived = key(fixed, fixed.faces)
    pos = [original.index(face) for face in survived]
    assert pos == sorted(pos)
    assert fixed.face_count >= mesh.face_count - 1


def test_mesh_stats_counts():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5], [6, 5, 5], [5, 6, 5], [1, 1, 0]])
    mesh = TriangleMesh(v, [[0, 1, 2], [1, 6, 2], [3, 4, 5]])
    s = meshops.mesh_stats(mesh)
    assert (s.faces, s.vertices, s.components, s.boundary_edges, s.edges) == (3, 7, 2, 7, 8)
    assert s.area == pytest.approx(1.5)
    assert not s.closed and meshops.mesh_stats(_icosphere(1)).closed


# --------------------------------------------------------------------------- TRELLIS

def test_trellis_run_lands_on_the_glb_mesh(tmp_path):
    ply, glb, expected = _write_trellis_run(tmp_path)
    result = trellis.load(str(ply), str(glb), SourceOptions())
    assert result.anchors is None
    # the splats are the internal ones seen in the GLB frame: p_glb = T^T p_internal
    np.testing.assert_allclose(result.splats.means, expected.means, atol=2e-7)
    np.testing.assert_allclose(result.splats.covariances(), expected.covariances(),
                               atol=1e-9, rtol=1e-5)
    np.testing.assert_array_equal(result.splats.sh, expected.sh)
    check = result.check
    assert check["frame"] == "current"
    assert check["distance_p50_rel"] < 0.005 and check["distance_p95_rel"] < 0.01
    assert check["distance_max_rel"] < 0.03
    # UV-seam copies welded: one closed component, fewer vertices than the GLB holds
    stats = meshops.mesh_stats(result.mesh)
    assert stats.components == 1 and stats.closed
    assert check["mesh_vertices_welded"] < check["mesh_vertices_read"]
    assert meshops.mesh_stats(read_mesh(glb)).components == 2
    assert any("diag(1,-1,-1)" in note for note in result.notes)


def test_trellis_legacy_frame_is_detected_and_named(tmp_path):
    _, glb, _ = _write_trellis_run(tmp_path)
    legacy, _, expected = _write_trellis_run(tmp_path, legacy=True)
    with pytest.raises(FormatError) as err:
        trellis.load(str(legacy), str(glb), SourceOptions())
    text = str(err.value)
    assert "frame mismatch?" in text and "pass --legacy-trellis-frame" in text
    assert "pre-2024-12-18 frame fits" in text and "\n" not in text
    result = trellis.load(str(legacy), str(glb), SourceOptions(trellis_frame="legacy"))
    assert result.check["frame"] == "legacy" and result.check["distance_p95_rel"] < 0.01
    np.testing.assert_allclose(result.splats.means, expected.means, atol=2e-7)
    with pytest.raises(FormatError, match="drop --legacy-trellis-frame"):
        trellis.load(str(tmp_path / "run.ply"), str(glb), SourceOptions(trellis_frame="legacy"))
    with pytest.raises(FormatError, match="drop --no-frame-change"):
        trellis.load(str(tmp_path / "run.ply"), str(glb), SourceOptions(trellis_frame="none"))


def test_trellis_unrelated_mesh_is_refused(tmp_path):
    ply, _, _ = _write_trellis_run(tmp_path)
    other = _icosphere(2)
    trimesh.Trimesh(other.vertices * 0.05 + 0.3, other.faces).export(str(tmp_path / "other.glb"))
    with pytest.raises(FormatError, match="same TRELLIS run"):
        trellis.load(str(ply), str(tmp_path / "other.glb"), SourceOptions())


def test_trellis_refuses_other_layouts(tmp_path):
    _, glb, expected = _write_trellis_run(tmp_path)
    sh1 = expected.with_sh_degree(1)
    write_splat_ply(sh1, tmp_path / "sh1.ply", normals=True)
    with pytest.raises(FormatError, match="--from 3dgs") as err:
        trellis.load(str(tmp_path / "sh1.ply"), str(glb), SourceOptions())
    assert "SH degree 1" in str(err.value)
    big = SplatCloud(expected.means * 3, expected.rotations, expected.scales,
                     expected.opacities, expected.sh)
    write_splat_ply(big, tmp_path / "big.ply", normals=True)
    with pytest.raises(FormatError, match="outside TRELLIS's cube"):
        trellis.load(str(tmp_path / "big.ply"), str(glb), SourceOptions())
    with pytest.raises(UsageError, match="--mesh"):
        trellis.load(str(tmp_path / "run.ply"), None, SourceOptions())


def test_trellis_layout_sample_from_another_tool(shared_data, tmp_path):
    """The DreamGaussian sample has TRELLIS's property layout but not its unit cube."""
    path = shared_data / "3dgs" / "404gen_tmp_model_dreamgaussian_sh0.ply"
    if not path.is_file():
        pytest.skip("sample not present")
    _, glb, _ = _write_trellis_run(tmp_path, n=200)
    with pytest.raises(FormatError, match="not a TRELLIS Gaussian PLY.*--from 3dgs"):
        trellis.load(str(path), str(glb), SourceOptions())


def test_trellis_real_glb_sample(shared_data, tmp_path):
    glb = shared_data / "trellis" / "AlexHe1234_TRELLIS_sample.glb"
    if not glb.is_file():
        pytest.skip("sample not present")
    raw = read_mesh(glb)
    welded = meshops.weld(raw, drop_degenerate=True)
    points, _ = _surface_points(welded, 8000, seed=5, offset=0.002)
    in_glb = _trellis_splats(points, seed=6)
    ply = tmp_path / "sample.ply"
    write_splat_ply(rotate_splats(in_glb, trellis.PLY_TO_GLB.T), ply, normals=True)
    result = trellis.load(str(ply), str(glb), SourceOptions())
    np.testing.assert_allclose(result.splats.means, in_glb.means, atol=2e-7)
    check = result.check
    assert check["mesh_vertices_read"] == len(raw.vertices) == 9519
    assert check["mesh_vertices_welded"] == 4507
    assert check["mesh_components"] < meshops.mesh_stats(raw).components
    assert check["distance_p50_rel"] < 0.003 and check["distance_p95_rel"] < 0.01
    # the legacy reading of the same PLY does not fit, and the error says which frame does
    with pytest.raises(FormatError, match="drop --legacy-trellis-frame"):
        trellis.load(str(ply), str(glb), SourceOptions(trellis_frame="legacy"))


def test_trellis_through_the_pipeline(tmp_path):
    from gsverse_format.pipeline import ConvertOptions, convert
    from gsverse_format.io.gltf import read_gltf

    ply, glb, expected = _write_trellis_run(tmp_path, n=1500)
    out = tmp_path / "out.glb"
    summary = convert(str(ply), str(out), ConvertOptions(mesh=str(glb)))
    assert summary.source == "trellis" and summary.anchored == 1500
    asset = read_gltf(out)
    assert asset.anchored[0].anchoring.mesh.face_count == 1280
    assert summary.distance["p95"] < 0.01 * summary.distance["mesh_diagonal"]


# --------------------------------------------------------------------------- reconstruction

def test_orient_normals_on_a_torus():
    tm = trimesh.creation.torus(0.5, 0.18, major_sections=64, minor_sections=32)
    points, fi = trimesh.sample.sample_surface(tm, 6000, seed=1)
    true = tm.face_normals[fi]
    signs = np.where(np.random.default_rng(2).uniform(size=len(points)) < 0.5, -1.0, 1.0)
    oriented, flipped = reconstruct.orient_normals(points, true * signs[:, None])
    assert np.all(np.einsum("ij,ij->i", oriented, true) > 0)   # outward everywhere, inner wall too
    assert flipped == int(np.count_nonzero(signs < 0))


def test_splat_normals_are_shortest_axes():
    mesh = _icosphere(2)
    points, normals = _surface_points(mesh, 500, seed=3)
    splats = _flat_splats(points, normals, seed=4)
    axis, flat = reconstruct.splat_normals(splats)
    assert np.allclose(np.abs(np.einsum("ij,ij->i", axis, normals)), 1.0, atol=1e-5)
    assert np.all(flat > 0.85)


def _reconstruct(tm: trimesh.Trimesh, n: int, faces: int, depth: int):
    points, fi = trimesh.sample.sample_surface(tm, n, seed=7)
    splats = _flat_splats(points, tm.face_normals[fi], seed=8)
    mesh, report = reconstruct.build_anchor_mesh(splats, faces, depth, threads=1)
    return splats, mesh, report


def test_poisson_sphere_has_requested_faces_and_fits():
    sphere = trimesh.creation.icosphere(5, radius=0.5)
    splats, mesh, report = _reconstruct(sphere, 5000, 1500, 5)
    stats = meshops.mesh_stats(mesh)
    assert abs(stats.faces - 1500) <= 0.02 * 1500
    assert stats.closed and stats.components == 1 and stats.degenerate_faces == 0
    assert report["trimmed_faces"] == 0 and report["points"] == 5000
    radius = np.linalg.norm(mesh.vertices, axis=1)                 # exact distance to the sphere
    assert np.mean(np.abs(radius - 0.5)) < 0.002 and np.max(np.abs(radius - 0.5)) < 0.005
    bound = bind_local(splats, mesh)
    diag = meshops.bbox_diagonal(mesh)
    assert np.percentile(bound.distance, 95) < 0.005 * diag
    assert bound.distance.max() < 0.01 * diag


def test_poisson_torus_keeps_its_genus():
    big, small = 0.4, 0.15
    torus = trimesh.creation.torus(big, small, major_sections=96, minor_sections=48)
    splats, mesh, _ = _reconstruct(torus, 6000, 1500, 5)
    stats = meshops.mesh_stats(mesh)
    assert abs(stats.faces - 1500) <= 0.02 * 1500 and stats.closed and stats.components == 1
    assert stats.vertices - stats.edges + stats.faces == 0          # Euler characteristic: genus 1
    v = mesh.vertices.astype(np.float64)                           # exact distance to the torus
    d = np.abs(np.hypot(np.hypot(v[:, 0], v[:, 1]) - big, v[:, 2]) - small)
    assert np.mean(d) < 0.003 and d.max() < 0.015
    check = reconstruct.distance_check(splats, mesh)
    assert check["distance_p95_rel"] < 0.006 and check["distance_max_rel"] < 0.015


def test_poisson_trims_unsupported_surface_and_ignores_faint_splats():
    sphere = trimesh.creation.icosphere(4, radius=0.5)
    points, fi = trimesh.sample.sample_surface(sphere, 10000, seed=9)
    upper = points[:, 1] > 0.0
    splats = _flat_splats(points[upper], sphere.face_normals[fi][upper], seed=10)
    faint = _flat_splats(np.random.default_rng(3).uniform(-0.5, 0.5, (300, 3)),
                         np.tile([0.0, 0.0, 1.0], (300, 1)), seed=11)
    faint.opacities[:] = 0.01
    mesh, report = reconstruct.build_anchor_mesh(SplatCloud.concatenate([splats, faint]),
                                                 1500, 5, threads=1)
    assert report["points"] == len(splats)
    assert report["trimmed_faces"] > 0
    stats = meshops.mesh_stats(mesh)
    assert stats.boundary_edges > 0 and stats.components == 1
    assert mesh.vertices[:, 1].min() > -0.15   # Poisson's closing cap below the rim is gone


def test_reconstruct_load_errors(tmp_path):
    few = _trellis_splats(np.random.default_rng(0).uniform(-1, 1, (5, 3)), seed=1)
    write_splat_ply(few, tmp_path / "few.ply")
    with pytest.raises(FormatError, match="too few"):
        load_source("3dgs", str(tmp_path / "few.ply"))
    with pytest.raises(UsageError):
        reconstruct.build_anchor_mesh(few, 2)
    assert reconstruct.poisson_depth(20000) == 7 and reconstruct.poisson_depth(10) == 5


def test_reconstruct_real_donut(shared_data):
    path = shared_data / "3dgs" / "donut_mipsplatting_sh0_fused.ply"
    if not path.is_file():
        pytest.skip("sample not present")
    from gsverse_format.io.ply import read_splat_ply

    splats = read_splat_ply(path)
    mesh, report = reconstruct.build_anchor_mesh(splats, 1500, 5, threads=1)
    stats = meshops.mesh_stats(mesh)
    assert 1400 <= stats.faces <= 1515 and stats.nonmanifold_edges == 0
    assert stats.degenerate_faces == 0 and stats.components >= 1
    check = reconstruct.distance_check(splats, mesh)
    assert check["distance_p50_rel"] < 0.01 and check["distance_p95_rel"] < 0.05


def test_reconstruct_load_through_ply(tmp_path):
    sphere = trimesh.creation.icosphere(4, radius=0.5)
    points, fi = trimesh.sample.sample_surface(sphere, 5000, seed=12)
    splats = _flat_splats(points + [0.0, 0.3, 0.0], sphere.face_normals[fi], seed=13)
    write_splat_ply(splats, tmp_path / "s.ply")
    result = load_source("3dgs", str(tmp_path / "s.ply"), reconstruct_faces=800)
    assert result.anchors is None and 780 <= result.mesh.face_count <= 808
    # glTF frame: 180 degrees about Z, so the sphere's centre moves to y = -0.3
    centre = result.mesh.vertices.mean(axis=0)
    assert abs(centre[1] + 0.3) < 0.01
    assert result.check["distance_p95_rel"] < 0.01
    assert any("reconstructed" in note for note in result.notes)


# --------------------------------------------------------------------------- KHR source

def _anchored_asset(tmp_path):
    mesh = _icosphere(2)
    points, normals = _surface_points(mesh, 400, seed=14, offset=0.01)
    splats = _trellis_splats(points, seed=15)
    anchors = bind_local(splats, mesh).anchors
    far = _trellis_splats(np.random.default_rng(5).uniform(3, 4, (50, 3)), seed=16)
    asset = SplatAsset([SplatPrimitive(splats.subset(slice(0, 300)),
                                       Anchoring(mesh, anchors.subset(slice(0, 300))), "a"),
                        SplatPrimitive(far, None, "static"),
                        SplatPrimitive(splats.subset(slice(300, 400)),
                                       Anchoring(mesh, anchors.subset(slice(300, 400))), "b")])
    path = tmp_path / "asset.glb"
    write_gltf(asset, path)
    return path, mesh, splats, anchors, far


def test_khr_source_keeps_anchoring_without_mesh(tmp_path):
    path, mesh, splats, anchors, far = _anchored_asset(tmp_path)
    result = khr.load(str(path), None, SourceOptions())
    assert len(result.splats) == 400 and len(result.anchors) == 400
    np.testing.assert_allclose(result.splats.means, splats.means, atol=1e-6)
    np.testing.assert_array_equal(result.anchors.face_index, anchors.face_index)
    np.testing.assert_allclose(result.mesh.vertices, mesh.vertices, atol=1e-6)
    assert result.check["splats_left_out"] == 50
    assert any("50 splats" in note and "--mesh" in note for note in result.notes)


def test_khr_source_with_mesh_rebinds_everything(tmp_path):
    path, mesh, splats, _, far = _anchored_asset(tmp_path)
    trimesh.Trimesh(mesh.vertices, mesh.faces).export(str(tmp_path / "mesh.obj"))
    result = khr.load(str(path), str(tmp_path / "mesh.obj"), SourceOptions())
    assert result.anchors is None and len(result.splats) == 450
    expected = np.concatenate([splats.means[:300], far.means, splats.means[300:]])
    np.testing.assert_allclose(result.splats.means, expected, atol=1e-6)
    assert result.mesh.face_count == mesh.face_count


def test_khr_source_plain_file_needs_mesh(tmp_path):
    splats = _trellis_splats(np.random.default_rng(0).uniform(-1, 1, (20, 3)), seed=2)
    write_gltf(SplatAsset([SplatPrimitive(splats)]), tmp_path / "plain.glb")
    with pytest.raises(FormatError, match="--mesh"):
        khr.load(str(tmp_path / "plain.glb"), None, SourceOptions())
