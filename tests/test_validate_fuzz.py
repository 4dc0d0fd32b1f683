"""The fuzz harness: short runs of every kind of input find no internal error or hang, and the
harness tells a clean refusal from an internal error. The long run is
``python -m fuzz.fuzz_readers --runs 100000`` (``--kinds`` to split it)."""
from __future__ import annotations

import json
import os
import pathlib
import random
import subprocess
import sys
import time

import pytest

from helpers import fuzz_module

ROOT = pathlib.Path(__file__).resolve().parents[1]
fz = fuzz_module("fuzz_readers")
mutations = fuzz_module("mutations")
#: Seconds the harness gives each target, where a test is about outcomes, not about telling a
#: hang: generous, so that a busy machine never turns a slow read into a "hang". (A real hang
#: is still one: it never ends.)
NO_HANG_LIMIT = 120.0


def _run(tmp_path, kinds: str, runs: int, seed: int) -> str:
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "fuzz.fuzz_readers", "--runs", str(runs),
                           "--kinds", kinds, "--quiet", "--seed", str(seed), "--timeout",
                           str(NO_HANG_LIMIT),
                           "--crash-dir", str(tmp_path / "crashes")],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    first = proc.stdout.splitlines()[0]
    assert first.startswith(f"inputs: {runs}  internal errors: 0  hangs: 0"), proc.stdout
    assert not (tmp_path / "crashes").exists()
    print(f"fuzz {kinds}: {first} (wall {time.perf_counter() - start:.1f} s)")
    return proc.stdout


def _counts(stdout: str) -> dict[str, dict[str, int]]:
    out = {}
    for line in stdout.splitlines()[1:]:
        words = line.split()
        if len(words) > 2 and words[1] == "runs":
            out[words[0]] = dict(zip(words[3::2], map(int, words[4::2])))
            out[words[0]]["runs"] = int(words[2])
    return out


def test_short_gltf_fuzz_run_has_no_internal_error(tmp_path):
    counts = _counts(_run(tmp_path, "glb,gltf", 2000, 7))
    assert set(counts) == {"read_gltf", "read_mesh", "validate"}
    for stats in counts.values():
        assert stats["runs"] == 2000 and stats["internal"] == stats["hang"] == 0
        assert stats["refused"] > 0  # the mutations reach the checks


def test_short_ply_fuzz_run_has_no_internal_error(tmp_path):
    counts = _counts(_run(tmp_path, "ply", 2000, 8))
    assert set(counts) == {"read_splat_ply", "read_ply_elements", "read_ply_mesh", "read_mesh"}
    assert all(s["ok"] > 0 and s["refused"] > 0 for s in counts.values())


def test_short_usd_fuzz_run_has_no_internal_error(tmp_path):
    pytest.importorskip("pxr")
    counts = _counts(_run(tmp_path, "usda,usdc", 200, 9))
    assert set(counts) == {"read_usd", "validate_usd"}
    assert all(s["runs"] == 200 and s["ok"] > 0 and s["refused"] > 0 for s in counts.values())


def test_seeds_are_valid(tmp_path):
    fuzzer = fz.Fuzzer(str(tmp_path), timeout=NO_HANG_LIMIT)
    try:
        for suffix, data in fz.seeds():
            fuzzer.run_one(suffix, data)
    finally:
        fuzzer.close()
    assert not fuzzer.failures
    # Every glTF and USD seed reads and validates (five glTF seeds, one SPZ-compressed); the
    # splat PLYs read as splats (the mesh PLYs do not).
    assert fuzzer.outcomes["validate"] == {"ok": 5}
    assert fuzzer.outcomes["read_gltf"] == {"ok": 5}
    assert fuzzer.outcomes["read_splat_ply"]["ok"] == 4
    if "read_usd" in fuzzer.outcomes:
        assert fuzzer.outcomes["read_usd"] == {"ok": 4}
        assert fuzzer.outcomes["validate_usd"] == {"ok": 4}


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


def test_gltf_mutations_are_structure_aware():
    """Most edits of a glTF document keep it valid JSON (so that they reach the glTF checks),
    and every kind of structural edit occurs: counts, references, offsets, enumerations,
    extension objects, deleted members, duplicated keys."""
    doc = json.loads(next(d for s, d in fz.seeds() if s == ".gltf"))
    rng = random.Random(3)
    seen = {"count": 0, "reference": 0, "offset": 0, "enum": 0, "extension": 0, "deleted": 0}
    parsed = duplicated = 0
    text = json.dumps(doc).encode()
    for _ in range(600):
        out = mutations._mutate_json(rng, text)
        twice = []

        def pairs(items):
            keys = [k for k, _ in items]
            twice.extend(k for k in set(keys) if keys.count(k) > 1)
            return dict(items)
        try:
            new = json.loads(out, object_pairs_hook=pairs)
        except ValueError:
            continue
        duplicated += bool(twice)
        parsed += 1
        _classify(doc, new, seen)
    assert parsed > 0.7 * 600
    assert duplicated > 0
    assert all(v > 0 for v in seen.values()), seen


def _classify(old, new, seen: dict[str, int]) -> None:
    """Which kinds of edit turned ``old`` into ``new`` (first differences only)."""
    ENUMS, OFFSET_KEYS, REFERENCE_KEYS = (mutations.ENUMS, mutations.OFFSET_KEYS,
                                          mutations.REFERENCE_KEYS)

    def walk(a, b, key=None, parent=None):
        if type(a) is not type(b):
            return
        if isinstance(a, dict):
            if set(a) - set(b):
                seen["deleted"] += 1
            if key == "extensions" and a != b:
                seen["extension"] += 1
            for k in set(a) & set(b):
                walk(a[k], b[k], k, a)
        elif isinstance(a, list):
            for x, y in zip(a, b):
                walk(x, y, key, a)
        elif a != b:
            if key == "count":
                seen["count"] += 1
            elif key in OFFSET_KEYS:
                seen["offset"] += 1
            elif key in ENUMS:
                seen["enum"] += 1
            elif key in REFERENCE_KEYS or (isinstance(key, str) and key.upper() == key):
                seen["reference"] += 1
    walk(old, new)


def test_harness_tells_refusals_from_internal_errors_and_hangs(tmp_path):
    from gsverse_format.errors import FormatError

    def internal(path):
        raise ValueError("boom")

    def refuse(path):
        raise FormatError("bad input", path)

    def memory(path):
        raise MemoryError()

    def hang(path):
        while True:
            pass

    fuzzer = fz.Fuzzer(str(tmp_path), timeout=0.2, crash_dir=str(tmp_path / "crashes"),
                       targets={".glb": [("internal", internal), ("refuse", refuse),
                                         ("memory", memory), ("hang", hang)]})
    fuzzer.run_one(".glb", b"glTF")
    kinds = sorted((f.target, f.kind) for f in fuzzer.failures)
    assert kinds == [("hang", "hang"), ("internal", "internal"), ("memory", "internal")]
    assert "ValueError: boom" in [f for f in fuzzer.failures if f.target == "internal"][0].detail
    assert all(os.path.isfile(f.saved) for f in fuzzer.failures)
    assert fuzzer.outcomes["refuse"] == {"refused": 1}


def test_validator_reports_are_classified(tmp_path):
    """A report with errors is a refusal, one with INTERNAL_ERROR an internal error."""
    from gsverse_format.codes import Code
    from gsverse_format.validators.issues import Issues
    from gsverse_format.validators.validate import Report

    def report(*codes):
        issues = Issues({})
        for code in codes:
            issues.add(code, "x")
        return Report("f.glb", issues)

    assert fz.classify_report(report())[0] == "ok"
    assert fz.classify_report(report(Code.SCALE_NEGATIVE))[0] == "refused"
    assert fz.classify_report(report(Code.SCALE_NEGATIVE, Code.INTERNAL_ERROR))[0] == "internal"


def test_usd_worker_counts_a_library_crash_as_a_refusal(tmp_path, monkeypatch):
    """The USD library ending the worker with a signal is a refusal (as the isolation child's
    crash is a FormatError); the worker is started again for the next input."""
    pytest.importorskip("pxr")
    monkeypatch.setattr(fz, "USD_WORKER_CODE", "import os, signal\n"
                        "from gsverse_format.io import usd\n"
                        "def crash(*a, **k):\n    os.kill(os.getpid(), signal.SIGSEGV)\n"
                        "usd.read_usd = crash\n" + fz.USD_WORKER_CODE)
    fuzzer = fz.Fuzzer(str(tmp_path / "work"), timeout=NO_HANG_LIMIT)
    (tmp_path / "work").mkdir()
    seed = next(d for s, d in fz.seeds() if s == ".usda")
    try:
        fuzzer.run_one(".usda", seed)
        fuzzer.run_one(".usda", seed)
    finally:
        fuzzer.close()
    assert not fuzzer.failures
    assert fuzzer.outcomes["read_usd"] == {"refused": 2}
    assert fuzzer.outcomes["validate_usd"] == {"ok": 2}  # run by the restarted worker
    assert fuzzer.usd_worker.library_crashes == 2 and fuzzer.usd_worker.starts == 3


def test_harness_reports_numpy_warnings(tmp_path):
    """A reader that lets numpy warn (printed on the user's terminal) is listed, refusal or
    not."""
    import numpy as np

    from gsverse_format.errors import FormatError

    def warn(path):
        with np.errstate(invalid="warn"):
            np.array([np.inf]) - np.array([np.inf])
        raise FormatError("bad input", path)

    fuzzer = fz.Fuzzer(str(tmp_path), timeout=NO_HANG_LIMIT, targets={".ply": [("warn", warn)]})
    fuzzer.run_one(".ply", b"ply")
    fuzzer.run_one(".ply", b"ply")
    assert fuzzer.outcomes["warn"] == {"refused": 2}
    assert fuzzer.warned["warn"][0] == 2 and "invalid value" in fuzzer.warned["warn"][1]
