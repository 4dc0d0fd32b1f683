"""Meshes far from a manifold: bounded time, a clear outcome, SIGTERM obeyed.

manifold3d's constructor, given 100k copies of one triangle or the fan of one polygon of many
corners, runs for minutes in native code that holds the interpreter (no signal handler runs).
The manifold report decides in numpy alone (edge counts, then half-edges), and --watertight
asks manifold3d only after the edge counts (``manifold._edges_closed``)."""
from __future__ import annotations

import json
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

from gsverse_format.manifold import collider, manifold_report
from gsverse_format.model import TriangleMesh
from gsverse_format.errors import FormatError

REPO = Path(__file__).resolve().parents[1]
CAPSULE = REPO / "examples" / "capsule"
#: Generous limits for a child process on a busy machine (each case takes ~2-5 s alone).
CHILD_CPU_S = 120
CHILD_WALL_S = 300


def polygon_obj(path: Path, corners: int = 20_000) -> Path:
    """One face of ``corners`` corners on a circle around the capsule (about 360 KB)."""
    a = np.linspace(0, 2 * np.pi, corners, endpoint=False)
    lines = [f"v {np.cos(t):.6f} {0.3 * np.sin(3 * t):.6f} {np.sin(t):.6f}" for t in a]
    lines.append("f " + " ".join(str(i + 1) for i in range(corners)))
    path.write_text("\n".join(lines) + "\n")
    return path


def duplicate_glb(path: Path, copies: int = 100_000) -> Path:
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    vertices = np.tile(tri, (copies, 1))
    faces = np.arange(3 * copies).reshape(-1, 3)
    trimesh.Trimesh(vertices, faces, process=False).export(path)
    return path


def run_child(args: list[str]) -> tuple[subprocess.CompletedProcess, float]:
    """Run a command line tool as a child; returns it and the child's CPU seconds."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run([sys.executable, "-m", *args], capture_output=True, text=True,
                          timeout=CHILD_WALL_S)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return proc, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


@pytest.fixture(scope="module")
def hostile(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("hostile")
    return {"polygon": polygon_obj(root / "polygon.obj"),
            "duplicates": duplicate_glb(root / "duplicates.glb")}


def test_manifold_report_decides_far_from_manifold_meshes_in_numpy():
    copies = TriangleMesh(np.tile(np.eye(3, dtype=np.float32), (100_000, 1)),
                          np.arange(300_000).reshape(-1, 3))
    report = manifold_report(copies)
    assert not report.closed_manifold and report.nonmanifold_edges == 3
    box = trimesh.creation.box()
    closed = manifold_report(TriangleMesh(box.vertices.astype(np.float32), box.faces))
    assert closed.closed_manifold and closed.checked_by == "half-edges"


def test_a_flat_point_set_has_no_hull_collider():
    a = np.linspace(0, 2 * np.pi, 30_000, endpoint=False)
    flat = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], 1)
    tilted = flat @ trimesh.transformations.random_rotation_matrix(
        rand=np.array([0.1, 0.5, 0.9]))[:3, :3].T
    for points in (flat, tilted):
        mesh = TriangleMesh(points.astype(np.float32), np.array([[0, 1, 2]]))
        with pytest.raises(FormatError, match="span no volume"):
            collider(mesh)
    slab = trimesh.creation.box(extents=(1, 1, 1e-3))
    hull = collider(TriangleMesh(slab.vertices.astype(np.float32), slab.faces))
    assert hull.face_count == 12


@pytest.mark.parametrize("kind", ["polygon", "duplicates"])
def test_convert_with_a_far_from_manifold_mesh_is_bounded(hostile, tmp_path, kind):
    out = tmp_path / "out.glb"
    proc, cpu = run_child(["gsverse_format.cli.convert", str(CAPSULE / "splats.ply"), str(out),
                           "--mesh", str(hostile[kind]), "--json", "-q"])
    assert cpu < CHILD_CPU_S
    assert "Traceback" not in proc.stderr
    if proc.returncode == 0:
        summary = json.loads(proc.stdout)
        assert summary["anchor_meshes"][0]["closed_manifold"] is False
    else:
        assert proc.returncode == 1 and len(proc.stderr.strip().splitlines()) == 1
        assert not out.exists()


@pytest.mark.parametrize("kind", ["polygon", "duplicates"])
def test_validate_and_watertight_with_a_far_from_manifold_mesh_are_bounded(hostile, tmp_path,
                                                                          kind):
    out = tmp_path / "out.glb"
    proc, cpu = run_child(["gsverse_format.cli.convert", str(CAPSULE / "splats.ply"), str(out),
                           "--mesh", str(hostile[kind]), "--watertight", "--collider", "hull",
                           "-q"])
    assert cpu < CHILD_CPU_S and "Traceback" not in proc.stderr
    assert proc.returncode in (0, 1), proc.stderr
    if proc.returncode == 1:
        assert len(proc.stderr.strip().splitlines()) == 1 and not out.exists()
        return
    proc, cpu = run_child(["gsverse_format.validators.cli", str(out)])
    assert cpu < CHILD_CPU_S and "Traceback" not in proc.stderr and proc.returncode in (0, 1)


def test_sigterm_ends_a_conversion_with_a_far_from_manifold_mesh(hostile, tmp_path):
    out = tmp_path / "out.glb"
    proc = subprocess.Popen([sys.executable, "-m", "gsverse_format.cli.convert",
                             str(CAPSULE / "splats.ply"), str(out), "--mesh",
                             str(hostile["duplicates"]), "--watertight"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(1.0)  # somewhere in reading, checking or repairing the mesh (any moment will do)
    proc.send_signal(signal.SIGTERM)
    try:
        _, stderr = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    # 143: it unwound; -15: the signal came before the interpreter set up its handler (on a
    # busy machine a second may not reach it); 0/1: it finished before the signal
    assert proc.returncode in (143, -signal.SIGTERM, 0, 1), stderr
    assert "Traceback" not in stderr
    assert not [p for p in tmp_path.iterdir() if p.name != "out.glb"]
