"""Physics-ready anchor meshes: the closed 2-manifold report, --watertight repair and re-binding,
--collider hull, and the validator's ANCHOR_MESH_NOT_MANIFOLD."""
from __future__ import annotations

import json
import pathlib

import numpy as np
import pytest
from gsverse_format.validators import validate_file

from gsverse_format.cli.convert import main
from gsverse_format.io.gltf import read_gltf
from gsverse_format.io.mesh import read_mesh
from gsverse_format.manifold import (BackgroundReport, collider, make_watertight,
                                     manifold_report)
from gsverse_format.model import TriangleMesh
from gsverse_format.nearest import closest_points_on_triangles, nearest_triangles

manifold3d = pytest.importorskip("manifold3d")

ROOT = pathlib.Path(__file__).resolve().parents[1]
CAPSULE = ROOT / "examples" / "capsule"
DONUT = "3dgs/donut_mipsplatting_sh0_fused.ply"


def _is_manifold(mesh: TriangleMesh) -> bool:
    """manifold3d's own verdict, independently of gsverse_format.manifold."""
    m = manifold3d.Mesh(vert_properties=np.array(mesh.vertices, np.float32),
                        tri_verts=np.array(mesh.faces, np.uint32))
    m.merge()
    return manifold3d.Manifold(m).status() == manifold3d.Error.NoError


def _open_capsule(folder: pathlib.Path) -> pathlib.Path:
    mesh = read_mesh(CAPSULE / "mesh.obj")
    path = folder / "open.obj"
    from gsverse_format.examples import write_obj

    write_obj(TriangleMesh(mesh.vertices, mesh.faces[24:]), str(path))   # a hole at one pole
    return path


def _convert_json(capsys, *args: str) -> dict:
    assert main([*args, "-w", "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def _bound_distance(asset) -> tuple[np.ndarray, np.ndarray, TriangleMesh]:
    """Each anchored splat's distance to the triangle it is bound to, the splat means, the mesh."""
    (prim,) = asset.anchored
    mesh, anchors = prim.anchoring.mesh, prim.anchoring.anchors
    tri = mesh.triangles()[anchors.face_index.astype(np.intp)]
    means = prim.splats.means.astype(np.float64)
    _, _, d = closest_points_on_triangles(means, tri[:, 0], tri[:, 1], tri[:, 2])
    return d, means, mesh


def test_report_agrees_with_manifold3d():
    closed = read_mesh(CAPSULE / "mesh.obj")
    opened = TriangleMesh(closed.vertices, closed.faces[24:])
    r = manifold_report(closed)
    assert r.closed_manifold and _is_manifold(closed) and r.checked_by == "half-edges"
    r = manifold_report(opened)
    assert not r.closed_manifold and not _is_manifold(opened) and r.boundary_edges > 0
    assert "boundary edges" in r.why_not()


def _variant(base, kind: int, rng) -> TriangleMesh:
    """``base`` (a trimesh) changed in one of nine ways that keep or break manifoldness."""
    v, f = base.vertices.astype(np.float32), base.faces.astype(np.int64).copy()
    if kind == 1:                                   # a few faces flipped
        i = rng.choice(len(f), rng.integers(1, 4), replace=False)
        f[i] = f[i][:, ::-1]
    elif kind == 2:                                 # a hole or two
        f = np.delete(f, rng.choice(len(f), rng.integers(1, 3), replace=False), 0)
    elif kind == 3:                                 # one face twice
        f = np.vstack([f, f[rng.integers(len(f))][None]])
    elif kind == 4:                                 # needle faces (a corner repeated)
        i = int(rng.integers(len(f)))
        v = np.vstack([v, v[:1] + 3])
        f = np.vstack([f, [[f[i, 0], f[i, 0], len(v) - 1]], [[len(v) - 1] * 3]])
    elif kind == 5:                                 # a collapsed corner
        i = rng.integers(len(f))
        f[i, 1] = f[i, 0]
    elif kind == 6:                                 # unwelded seam copies
        dup = rng.choice(len(v), 5, replace=False)
        remap = np.arange(len(v))
        remap[dup] = np.arange(len(v), len(v) + 5)
        v = np.vstack([v, v[dup]])
        i = rng.choice(len(f), len(f) // 3, replace=False)
        f[i] = remap[f[i]]
    elif kind == 7:                                 # a second, inside-out copy
        f = np.vstack([f, f[:, ::-1] + len(v)])
        v = np.vstack([v, v + 5])
    elif kind == 8:                                 # a copy sharing one vertex (pinched)
        f = np.vstack([f, np.where(f == 0, 0, f + len(v))])
        v = np.vstack([v, 2 * v[0] - v])
    elif kind == 9:                                 # faces shuffled, corners rotated
        f = np.roll(f[rng.permutation(len(f))], int(rng.integers(0, 3)), axis=1)
    return TriangleMesh(v, f)


def test_half_edge_verdict_is_manifold3d_verdict():
    """The report's numpy verdict (two faces an edge, no directed edge twice) against
    manifold3d's constructor on 200 meshes: spheres, boxes, capsules and cylinders with faces
    flipped, removed, repeated or collapsed, needle faces, seam copies, inside-out and pinched
    copies. manifold3d also accepts some meshes with edges of four faces, which the report
    (like the earlier manifold3d-backed one, which asked manifold3d only with two faces an
    edge) calls not closed: they are left out of the comparison."""
    import trimesh

    rng = np.random.default_rng(7)
    bases = [trimesh.creation.icosphere(2), trimesh.creation.box(),
             trimesh.creation.capsule(1.0, 0.5, count=[8, 8]), trimesh.creation.cylinder(1, 2, 10)]
    verdicts = set()
    for trial in range(200):
        kind = trial % 10
        mesh = _variant(bases[trial // 10 % len(bases)], kind, rng)
        r = manifold_report(mesh)
        if r.nonmanifold_edges:
            assert not r.closed_manifold
            continue
        assert r.closed_manifold == _is_manifold(mesh), (trial, kind, r)
        verdicts.add((kind, r.closed_manifold))
    assert {(0, True), (1, False), (2, False), (4, True), (6, True), (7, True), (8, True),
            (9, True)} <= verdicts


def test_background_report_is_the_report_and_raises_what_it_raised():
    """The report the convert pipeline computes while it writes its output: the same report,
    and an error inside it reaches the caller that waits."""
    closed = read_mesh(CAPSULE / "mesh.obj")
    opened = TriangleMesh(closed.vertices, closed.faces[24:])
    pending = [BackgroundReport(m) for m in (closed, opened)]
    assert [p.result() for p in pending] == [manifold_report(closed), manifold_report(opened)]
    assert pending[0].result() == manifold_report(closed)          # asked again: the same

    class Broken(TriangleMesh):
        @property
        def face_count(self) -> int:
            raise RuntimeError("no faces today")

    broken = BackgroundReport(Broken(closed.vertices, closed.faces))
    with pytest.raises(RuntimeError, match="no faces today"):
        broken.result()


def test_reconstructed_capsule_is_reported(tmp_path, capsys):
    """The pipeline's reconstruct path (no --mesh) reports its anchor mesh."""
    out = tmp_path / "rebuilt.glb"
    summary = _convert_json(capsys, str(CAPSULE / "splats.ply"), str(out),
                            "--reconstruct-faces", "2000")
    (entry,) = summary["anchor_meshes"]
    (prim,) = read_gltf(out).anchored
    assert entry["closed_manifold"] == _is_manifold(prim.anchoring.mesh)
    assert entry["faces"] == prim.anchoring.mesh.face_count


def test_open_mesh_reported_repaired_and_rebound(tmp_path, capsys):
    open_mesh = _open_capsule(tmp_path)
    plain = tmp_path / "open.glb"
    summary = _convert_json(capsys, str(CAPSULE / "splats.ply"), str(plain), "--mesh",
                            str(open_mesh))
    assert summary["anchor_meshes"][0]["closed_manifold"] is False
    assert summary["anchor_meshes"][0]["boundary_edges"] > 0
    report = validate_file(plain)
    found = [f for f in report.findings if f.code == "ANCHOR_MESH_NOT_MANIFOLD"]
    assert len(found) == 1 and found[0].severity.label == "info"
    assert report.exit_status == 0   # information only: open anchor meshes are valid

    fixed = tmp_path / "watertight.glb"
    summary = _convert_json(capsys, str(CAPSULE / "splats.ply"), str(fixed), "--mesh",
                            str(open_mesh), "--watertight")
    assert summary["anchor_meshes"][0]["closed_manifold"] is True
    assert any(n.startswith("--watertight (open): repaired") for n in summary["notes"])
    assert "ANCHOR_MESH_NOT_MANIFOLD" not in validate_file(fixed).codes()
    d, means, repaired = _bound_distance(read_gltf(fixed))
    assert _is_manifold(repaired)
    # Re-bound: each splat is bound to its nearest triangle of the repaired surface ...
    nearest = nearest_triangles(means, repaired.vertices.astype(np.float64),
                                repaired.faces.astype(np.int64))
    assert np.allclose(d, nearest.distance, atol=1e-6)
    # ... which is no farther than the open surface it came from (only holes were filled).
    before, _, opened = _bound_distance(read_gltf(plain))   # in the output's frame
    d_open = nearest_triangles(means, opened.vertices.astype(np.float64),
                               opened.faces.astype(np.int64)).distance
    assert np.all(d <= d_open + 1e-6) and d.max() <= before.max() + 1e-6


def test_collider_hull_written_and_found(tmp_path, capsys):
    out = tmp_path / "collider.glb"
    summary = _convert_json(capsys, str(CAPSULE / "splats.ply"), str(out), "--mesh",
                            str(CAPSULE / "mesh.obj"), "--collider", "hull")
    assert summary["anchor_meshes"][0]["collider"]["kind"] == "hull"
    data = out.read_bytes()
    doc = json.loads(data[20:20 + int.from_bytes(data[12:16], "little")])
    anchor = doc["meshes"][0]["primitives"][0]["extensions"]["KHR_gaussian_splatting"][
        "extensions"]["GSVERSE_gaussian_splatting_mesh_anchor"]["mesh"]
    found = [i for i, m in enumerate(doc["meshes"])
             if m.get("extras", {}).get("gsverse", {}).get("collider") == "hull"]
    assert len(found) == 1 and doc["meshes"][found[0]]["extras"]["gsverse"]["for"] == anchor
    assert all(n.get("mesh") != found[0] for n in doc["nodes"])   # drawn by no node
    assert validate_file(out).findings == []
    mesh = read_mesh(CAPSULE / "mesh.obj")
    hull = collider(mesh)
    assert _is_manifold(hull) and summary["anchor_meshes"][0]["collider"]["faces"] == \
        hull.face_count
    # every anchor vertex lies inside (or on) the convex hull
    tri = hull.triangles()
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    side = np.einsum("fk,vfk->vf", normal, mesh.vertices[:, None, :] - tri[None, :, 0])
    assert side.max() <= 1e-6 * np.abs(side).max()


def test_watertight_failure_is_a_clear_error(tmp_path, capsys):
    mesh = read_mesh(CAPSULE / "mesh.obj")
    # every other face removed: a lace of single-triangle holes meeting at vertices
    lace = TriangleMesh(mesh.vertices, np.concatenate([mesh.faces[::2][:400],
                                                       mesh.faces[1::2]]))
    with pytest.raises(Exception) as info:
        make_watertight(lace)
    assert "could not make the anchor mesh a closed 2-manifold" in str(info.value)


def test_reconstructed_donut_repaired(shared_data, tmp_path, capsys):
    """A real capture: its reconstructed mesh is trimmed open; --watertight closes it."""
    ply = shared_data / DONUT
    if not ply.is_file():
        pytest.skip(f"{DONUT} not present")
    out = tmp_path / "donut.glb"
    summary = _convert_json(capsys, str(ply), str(out), "--reconstruct-faces", "3000",
                            "--watertight", "--collider", "hull")
    (entry,) = summary["anchor_meshes"]
    assert entry["closed_manifold"] and entry["collider"]["kind"] == "hull"
    assert any(n.startswith("--watertight") for n in summary["notes"])
    d, means, repaired = _bound_distance(read_gltf(out))
    assert _is_manifold(repaired)
    nearest = nearest_triangles(means, repaired.vertices.astype(np.float64),
                                repaired.faces.astype(np.int64))
    assert np.allclose(d, nearest.distance, atol=1e-6)
    assert summary["distance"]["p95"] < 0.05 * summary["distance"]["mesh_diagonal"]
    assert validate_file(out).exit_status == 0
