"""Fixtures shared by the whole suite. Tests build what they need in temporary folders: none
depends on files that only a command of the README writes into the checkout."""
from __future__ import annotations

import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
#: The example the repository ships: a bumpy capsule mesh and the splats on it.
CAPSULE = ROOT / "examples" / "capsule"


@pytest.fixture
def shared_data():
    if not SHARED.is_dir():
        pytest.skip("../shared/data not present")
    return SHARED


@pytest.fixture(scope="session")
def example_asset(tmp_path_factory) -> pathlib.Path:
    """The anchored example asset, as the README's first command makes it
    (``gsverse-convert examples/capsule/splats.ply examples/capsule/anchored.glb --mesh
    examples/capsule/mesh.obj``), but written to a temporary folder of this test run, never
    into the checkout: ``…/anchored.glb``. Read-only for the tests that use it."""
    from gsverse_format.api import convert

    out = tmp_path_factory.mktemp("example") / "anchored.glb"
    convert(CAPSULE / "splats.ply", out, mesh=CAPSULE / "mesh.obj")
    return out
