"""``python -m gsverse_format.precompile``: after it, the jobs that take the compiled paths
compile nothing (every kernel they use comes from numba's on-disk cache), and a second run
compiles nothing either. In a fresh, empty ``NUMBA_CACHE_DIR``."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("numba")

_JOBS = r"""
import sys
import numpy as np
import trimesh
from gsverse_format.cli.convert import main as convert
from gsverse_format.cli.render import main as render
from gsverse_format.io.ply import write_splat_ply
from gsverse_format.io.registry import read_asset
from gsverse_format.model import SplatCloud
from gsverse_format.remapping.fast import FastRemapper

folder = sys.argv[1]
# a bumpy sphere of 5,120 faces and 30,000 splats on it: 35,120 points + faces, above the
# size where the nearest-triangle search takes the compiled path
sphere = trimesh.creation.icosphere(subdivisions=5)
sphere.export(f"{folder}/mesh.ply")
rng = np.random.default_rng(1)
n = 30_000
points, _ = trimesh.sample.sample_surface(sphere, n, seed=2)
rot = rng.normal(size=(n, 4)); rot /= np.linalg.norm(rot, axis=1, keepdims=True)
write_splat_ply(SplatCloud(points.astype(np.float32), rot.astype(np.float32),
                           rng.uniform(0.005, 0.02, (n, 3)).astype(np.float32),
                           rng.uniform(0.2, 0.9, n).astype(np.float32),
                           rng.normal(0, 0.2, (n, 16, 3)).astype(np.float32)),
                f"{folder}/splats.ply")
out = f"{folder}/out.glb"
assert convert(["-q", "-w", f"{folder}/splats.ply", out, "--mesh", f"{folder}/mesh.ply"]) == 0
# the same conversion with the numba search, which binding runs where the C one was not built
from gsverse_format.backend import set_backend
set_backend("numba")
assert convert(["-q", "-w", f"{folder}/splats.ply", f"{folder}/numba.glb", "--mesh",
                f"{folder}/mesh.ply"]) == 0
set_backend("auto")
assert open(out, "rb").read() == open(f"{folder}/numba.glb", "rb").read()
assert render(["-q", "-w", out, f"{folder}/posed.png", "--deform", "twist=30",
               "--size", "48x48"]) == 0
(prim,) = read_asset(out).primitives
for rotations in (False, True):
    remapper = FastRemapper(prim.anchoring, rotations=rotations, backend="numba")
    remapper.remap(prim.anchoring.mesh.vertices * np.float32(1.2))
print("done")
"""


def _run(args: list[str], env: dict, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *args], env=env, cwd=cwd, capture_output=True,
                          text=True, timeout=900)


def test_precompiled_jobs_compile_nothing(tmp_path):
    cache = tmp_path / "numba-cache"
    cache.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "GSVERSE_BACKEND"}
    env["NUMBA_CACHE_DIR"] = str(cache)

    first = _run(["-m", "gsverse_format.precompile", "--json"], env, tmp_path)
    assert first.returncode == 0, first.stderr
    report = json.loads(first.stdout)
    assert report["ok"] and {g["group"] for g in report["groups"]} == {
        "nearest", "remap-sorted-local", "remap-sorted-games", "remap-unsorted", "render"}
    assert all(g["compiled"] > 0 for g in report["groups"])

    again = _run(["-m", "gsverse_format.precompile", "--json"], env, tmp_path)
    assert again.returncode == 0, again.stderr
    assert all(g["compiled"] == 0 and g["loaded"] > 0 for g in json.loads(again.stdout)["groups"])

    env["NUMBA_DEBUG_CACHE"] = "1"   # numba prints each cache load and save
    jobs = _run(["-c", _JOBS, str(tmp_path)], env, tmp_path)
    assert jobs.returncode == 0, jobs.stderr[-2000:]
    log = jobs.stdout + jobs.stderr
    loaded = [line for line in log.splitlines() if "data loaded" in line]
    saved = [line for line in log.splitlines() if "data saved" in line]
    for module in ("nearest/compiled.", "remapping/compiled", "render/project_compiled."):
        # the search, the remap and the renderer ran compiled ...
        assert any(module.split("/")[1] in line and f"{module.split('/')[0]}_" in line
                   for line in loaded), (module, loaded)
    assert saved == []                # ... and compiled nothing
