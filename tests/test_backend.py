"""The one backend switch (``gsverse_format.backend``) of the nearest search and the fast remap."""
from __future__ import annotations

import numpy as np
import pytest

from gsverse_format import backend
from gsverse_format.backend import (BackendUnavailableError, get_backend, numba_available,
                                    resolve_backend, set_backend)
from gsverse_format.model import Anchoring, GamesAnchors, TriangleMesh
from gsverse_format.nearest import nearest_triangles
from gsverse_format.remap_fast import FastRemapper


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
    monkeypatch.setattr("gsverse_format.nearest.nearest_triangles_numpy",
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
