"""The one backend switch (``gsverse_format.backend``) of the nearest search and the fast remap."""
from __future__ import annotations

import numpy as np
import pytest

from gsverse_format import backend
from gsverse_format.backend import (BackendUnavailableError, get_backend, numba_available,
                                    resolve_backend, set_backend)
from gsverse_format.model import Anchoring, GamesAnchors, TriangleMesh
from gsverse_format.nearest import nearest_triangles
from gsverse_format.remapping.fast import FastRemapper


@pytest.fixture(autouse=True)
def clean_switch(monkeypatch):
    monkeypatch.delenv("GSVERSE_BACKEND", raising=False)
    set_backend("auto")
    yield
    set_backend("auto")


def _anchoring() -> Anchoring:
    mesh = TriangleMesh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32),
                        np.array([[0, 1, 2]], np.int64))
    anchors = GamesAnchors(np.zeros(2, np.int64), np.full((2, 2), 0.25, np.float32),
                           np.ones(2, np.float32))
    return Anchoring(mesh, anchors)


def test_auto_is_numba_when_importable():
    assert get_backend() == "auto"
    assert resolve_backend() == ("numba" if numba_available() else "numpy")
    assert resolve_backend("numpy") == "numpy"


def test_environment_variable_and_set_backend(monkeypatch):
    monkeypatch.setenv("GSVERSE_BACKEND", "NumPy")
    assert get_backend() == "numpy" and resolve_backend() == "numpy"
    assert FastRemapper(_anchoring()).backend == "numpy"
    if numba_available():
        assert resolve_backend("numba") == "numba"        # an explicit name wins
        set_backend("numba")                              # and set_backend wins over the variable
        assert get_backend() == "numba" and resolve_backend() == "numba"
    set_backend("numpy")
    monkeypatch.setenv("GSVERSE_BACKEND", "")
    assert resolve_backend() == "numpy"
    set_backend("auto")
    assert get_backend() == "auto"


def test_set_backend_reaches_both_dispatchers(monkeypatch):
    calls = []
    monkeypatch.setattr("gsverse_format.nearest.dispatch.nearest_triangles_numpy",
                        lambda *a, **k: calls.append("numpy"))
    set_backend("numpy")
    nearest_triangles(np.zeros((1, 3)), np.eye(3), np.array([[0, 1, 2]]))
    assert calls == ["numpy"]
    assert FastRemapper(_anchoring()).backend == "numpy"


def test_bad_names_are_refused(monkeypatch):
    with pytest.raises(ValueError, match="backend"):
        set_backend("cuda")
    with pytest.raises(ValueError, match="method"):
        nearest_triangles(np.zeros((1, 3)), np.eye(3), np.array([[0, 1, 2]]), method="fortran")
    monkeypatch.setenv("GSVERSE_BACKEND", "gpu")
    with pytest.raises(ValueError, match="GSVERSE_BACKEND"):
        resolve_backend()


def test_numba_missing(monkeypatch):
    monkeypatch.setattr(backend, "numba_unavailable_reason", lambda: "ImportError: no numba")
    assert not numba_available()
    assert resolve_backend() == "numpy"                    # auto falls back to the reference
    assert FastRemapper(_anchoring()).backend == "numpy"
    with pytest.raises(BackendUnavailableError, match="no numba"):
        resolve_backend("numba")
    with pytest.raises(ImportError):
        nearest_triangles(np.zeros((1, 3)), np.eye(3), np.array([[0, 1, 2]]), method="numba")
    monkeypatch.setenv("GSVERSE_BACKEND", "numba")
    with pytest.raises(BackendUnavailableError):
        FastRemapper(_anchoring())


def test_small_jobs_run_the_reference_under_auto(monkeypatch):
    assert resolve_backend(size=99, numpy_below=100) == "numpy"
    assert resolve_backend(size=100, numpy_below=100) == ("numba" if numba_available() else "numpy")
    assert resolve_backend("numpy", size=10**9, numpy_below=100) == "numpy"
    if numba_available():
        # an explicit choice (argument, set_backend, environment) is never overridden by size
        assert resolve_backend("numba", size=1, numpy_below=100) == "numba"
        set_backend("numba")
        assert resolve_backend(size=1, numpy_below=100) == "numba"
        set_backend("auto")
        monkeypatch.setenv("GSVERSE_BACKEND", "numba")
        assert resolve_backend(size=1, numpy_below=100) == "numba"


def test_nearest_dispatch_by_size(monkeypatch):
    """Under auto the C search runs at any size; where it was not built, small jobs run the
    reference and larger ones numba."""
    calls = []
    monkeypatch.setattr("gsverse_format.nearest.dispatch.nearest_triangles_numpy",
                        lambda *a, **k: calls.append("numpy"))
    p, v, f = np.zeros((3, 3)), np.eye(3), np.array([[0, 1, 2]])
    assert nearest_triangles(p, v, f).face.tolist() == [0, 0, 0] and calls == []
    monkeypatch.setattr("gsverse_format.nearest.dispatch.native_available", lambda: False)
    nearest_triangles(p, v, f)
    assert calls == ["numpy"]                          # 4 points + faces, far below the threshold
    assert backend.NEAREST_NUMPY_BELOW > 3 + 1
    if numba_available():
        monkeypatch.setattr("gsverse_format.nearest.dispatch.NEAREST_NUMPY_BELOW", 4)
        result = nearest_triangles(p, v, f)            # 4 is not below 4: the compiled search
        assert calls == ["numpy"] and result.face.tolist() == [0, 0, 0]


_COLD_START = r"""
import json, os, sys
from gsverse_format.cli.convert import main as convert
from gsverse_format.validators.cli import main as validate
out = os.path.join(sys.argv[1], "x.glb")
rc = convert(["-q", "-w", "examples/capsule/splats.ply", out, "--mesh", "examples/capsule/mesh.obj"])
rc2 = validate([out])
cache = [os.path.join(d, f) for d, _, fs in os.walk(os.environ["NUMBA_CACHE_DIR"]) for f in fs]
print(json.dumps({"rc": [rc, rc2], "numba": "numba" in sys.modules, "cache": cache}))
"""


def test_readme_example_compiles_nothing(tmp_path):
    """The README's first command and a validation of its output, in a fresh process with an
    empty numba cache: the small job runs the numpy paths and never imports numba, so nothing
    is compiled (the cold-start cost of issue 16)."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    cache = tmp_path / "numba-cache"
    cache.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "GSVERSE_BACKEND"}
    env["NUMBA_CACHE_DIR"] = str(cache)
    proc = subprocess.run([sys.executable, "-c", _COLD_START, str(tmp_path)], cwd=root, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    assert report["rc"] == [0, 0]
    assert report["numba"] is False and report["cache"] == []


_TBB_CLASH = r"""
import warnings
import numpy as np
import pymeshlab  # noqa: F401  (bundles an older libtbb)
warnings.simplefilter("always")
from gsverse_format.nearest import nearest_triangles
rng = np.random.default_rng(0)
v = rng.random((30, 3))
f = rng.integers(0, 30, (40, 3))
nearest_triangles(rng.random((50, 3)), v, f, method="numba")
import numba
print(numba.threading_layer())
"""


def test_no_tbb_clash_with_pymeshlab():
    """pymeshlab loaded first used to make numba's TBB probe warn; the package's threading
    layer priority (OpenMP first) never probes TBB when OpenMP is there."""
    import os
    import subprocess
    import sys

    pytest.importorskip("pymeshlab")
    if not numba_available():
        pytest.skip("numba not installed")
    env = {k: v for k, v in os.environ.items()
           if k not in ("NUMBA_THREADING_LAYER", "NUMBA_THREADING_LAYER_PRIORITY")}
    proc = subprocess.run([sys.executable, "-c", _TBB_CLASH], env=env, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    layer = proc.stdout.split()[-1]
    assert layer in ("omp", "tbb", "workqueue")
    if layer == "omp":
        assert "TBB" not in proc.stderr, proc.stderr


def test_without_512_bit_vectors():
    """Every AVX-512, AVX10 and evex512 feature that is on goes off; nothing else changes."""
    features = ("+64bit,+avx2,+avx512f,-avx512fp16,+avx512vl,+evex512,+avx10.1-512,"
                "+avxvnni,+fma,-amx-tile")
    assert backend.without_512_bit_vectors(features) == (
        "+64bit,+avx2,-avx512f,-avx512fp16,-avx512vl,-evex512,-avx10.1-512,+avxvnni,+fma,"
        "-amx-tile")
    assert backend.without_512_bit_vectors("+sse2,+avx2") == "+sse2,+avx2"
    assert backend.without_512_bit_vectors("") == ""


_FEATURES = r"""
from gsverse_format.backend import configure_numba
configure_numba()
import numba
from numba.core.codegen import get_host_cpu_features
print(repr(numba.config.CPU_FEATURES))
print(repr(get_host_cpu_features()))
"""


@pytest.mark.parametrize("given", [None, "+sse2,+avx2"])
def test_kernels_compile_without_avx512(given):
    """configure_numba turns AVX-512 off for numba's code (see "Vector width" in the backend's
    docstring) on a host that has it, and leaves a feature list set in the environment alone."""
    import ast
    import os
    import subprocess
    import sys

    if not numba_available():
        pytest.skip("numba not installed")
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CPU_FEATURES", "NUMBA_CPU_NAME")}
    if given:
        env["NUMBA_CPU_FEATURES"] = given
    proc = subprocess.run([sys.executable, "-c", _FEATURES], env=env, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    chosen, host = (ast.literal_eval(line) for line in proc.stdout.split("\n")[-3:-1])
    if given:
        assert chosen == given
    elif "+avx512f" in host.split(","):
        assert chosen == backend.without_512_bit_vectors(host) and "+avx512f" not in chosen
        assert "+avx2" in chosen.split(",")
    else:
        assert chosen is None
