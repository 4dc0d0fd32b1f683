"""The fuzz harness: a CI-sized run finds no crash or hang, and the harness itself detects
crashes and hangs. The long run is ``python -m fuzz.fuzz_readers --runs 100000``."""
from __future__ import annotations

import os
import pathlib
import random
import subprocess
import sys
import time

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fuzz import fuzz_readers as fz  # noqa: E402


def test_short_fuzz_run_has_no_failures(tmp_path):
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "fuzz.fuzz_readers", "--runs", "2000",
                           "--quiet", "--seed", "7", "--crash-dir", str(tmp_path / "crashes")],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    first = proc.stdout.splitlines()[0]
    assert first.startswith("inputs: 2000  crashes: 0  hangs: 0"), proc.stdout
    for target in ("read_gltf", "read_splat_ply", "read_ply_elements", "read_ply_mesh",
                   "read_mesh", "validate"):
        assert target in proc.stdout
    assert not (tmp_path / "crashes").exists()
    print(f"fuzz: {first} (wall {time.perf_counter() - start:.1f} s)")


def test_seeds_are_valid(tmp_path):
    fuzzer = fz.Fuzzer(str(tmp_path))
    for suffix, data in fz.seeds():
        fuzzer.run_one(suffix, data)
    assert not fuzzer.failures
    # Every glTF seed reads; the splat PLYs read as splats (the mesh PLYs do not).
    assert fuzzer.outcomes["validate"] == {"ok": 4}
    assert fuzzer.outcomes["read_gltf"] == {"ok": 4}
    assert fuzzer.outcomes["read_splat_ply"]["ok"] == 4


def test_mutations_are_deterministic_and_change_the_input():
    pool = fz.seeds()
    def run(seed):
        rng = random.Random(seed)
        return [fz.mutate(rng, s, d, pool) for s, d in pool * 20]
    first, second = run(1), run(1)
    assert first == second
    originals = [d for _, d in pool * 20]
    changed = sum(a != b for a, b in zip(first, originals))
    assert changed > 0.9 * len(first)


def test_harness_reports_crashes_and_hangs(tmp_path):
    from gsverse_format.errors import FormatError

    def crash(path):
        raise ValueError("boom")

    def reject(path):
        raise FormatError("bad input", path)

    def hang(path):
        while True:
            pass

    fuzzer = fz.Fuzzer(str(tmp_path), timeout=0.2, crash_dir=str(tmp_path / "crashes"),
                       targets={".glb": [("crash", crash), ("reject", reject), ("hang", hang)]})
    fuzzer.run_one(".glb", b"glTF")
    kinds = sorted((f.target, f.kind) for f in fuzzer.failures)
    assert kinds == [("crash", "crash"), ("hang", "hang")]
    assert "ValueError: boom" in [f for f in fuzzer.failures if f.kind == "crash"][0].detail
    assert all(os.path.isfile(f.saved) for f in fuzzer.failures)
    assert fuzzer.outcomes["reject"] == {"rejected": 1}
