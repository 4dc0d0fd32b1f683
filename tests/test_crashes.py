"""A bug is a crash, never "bad input": an unexpected exception injected deep inside each reader
propagates out of the library as itself, the validator reports it as INTERNAL_ERROR naming
its type, and the fuzz harness counts it as an internal error."""
from __future__ import annotations

import base64
import json
import pathlib

import numpy as np
import pytest

from gsverse_format.codes import Code
from gsverse_format.errors import GsverseError
from gsverse_format.io.gltf import accessors as gltf_accessors
from gsverse_format.io.gltf import read_gltf, read_gltf_triangles
from gsverse_format.model import SplatCloud
from gsverse_format.validators import cli
from gsverse_format.validators.validate import validate_file

from helpers import fuzz_module

fz = fuzz_module("fuzz_readers")
#: Seconds the fuzz harness gives each target here: these tests are about outcomes, not speed,
#: so a busy machine (a USD child starting a fresh interpreter) must not make a read a hang.
NO_HANG_LIMIT = 600.0


class Injected(KeyError):
    """The injected bug (a KeyError, the exception the old catch-all used to swallow)."""


def _boom(*args, **kwargs):
    raise Injected("injected")


@pytest.fixture(scope="module")
def seed_files(tmp_path_factory) -> dict[str, pathlib.Path]:
    """One valid file per kind the fuzz harness feeds: .glb, .gltf, splat .ply; and "mesh":
    a .gltf whose scene holds a triangle mesh (what ``read_mesh`` reads)."""
    folder = tmp_path_factory.mktemp("seeds")
    out: dict[str, pathlib.Path] = {}
    for suffix, data in fz.seeds():
        if suffix not in out:
            out[suffix] = folder / f"seed{suffix}"
            out[suffix].write_bytes(data)
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32).tobytes()
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": [{"mesh": 0}], "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                          "min": [0, 0, 0], "max": [1, 1, 0]}],
           "bufferViews": [{"buffer": 0, "byteLength": len(vertices)}],
           "buffers": [{"byteLength": len(vertices), "uri": "data:application/octet-stream;"
                        "base64," + base64.b64encode(vertices).decode()}]}
    out["mesh"] = folder / "mesh.gltf"
    out["mesh"].write_text(json.dumps(doc))
    return out


@pytest.fixture
def broken_accessors(monkeypatch):
    """Every glTF accessor read fails with an unexpected KeyError."""
    monkeypatch.setattr(gltf_accessors.Accessors, "raw", _boom)


@pytest.fixture
def broken_model(monkeypatch):
    """Every reader's construction of the splats fails with an unexpected KeyError."""
    monkeypatch.setattr(SplatCloud, "__post_init__", _boom)


def _crash_targets(fuzzer: fz.Fuzzer) -> dict[str, str]:
    """Target -> detail of the internal errors the fuzz harness found."""
    return {f.target: f.detail for f in fuzzer.failures if f.kind == "internal"}


# ---------------------------------------------------------------------------- glTF

@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_gltf_reader_lets_a_bug_propagate(seed_files, broken_accessors, suffix):
    with pytest.raises(Injected) as info:
        read_gltf(seed_files[suffix])
    assert not isinstance(info.value, GsverseError)


def test_gltf_scene_reader_lets_a_bug_propagate(seed_files, broken_accessors):
    with pytest.raises(Injected):
        read_gltf_triangles(seed_files["mesh"])


def test_gltf_reader_bug_in_the_model_propagates(seed_files, broken_model):
    with pytest.raises(Injected):
        read_gltf(seed_files[".glb"])


def test_validator_reports_a_bug_as_internal_error(seed_files, broken_accessors):
    report = validate_file(seed_files[".glb"])
    internal = [f for f in report.findings if f.code == Code.INTERNAL_ERROR]
    assert internal, sorted(report.codes())
    assert all("KeyError" in f.message or "Injected" in f.message for f in internal)
    assert internal[0].message.startswith("Injected: ")
    assert report.exit_status == 1
    # Nothing else is blamed on the file.
    assert report.codes() == {Code.INTERNAL_ERROR}


def test_validator_cli_reports_a_bug_as_internal_error(seed_files, broken_accessors, capsys):
    status = cli.main(["--format", "json", str(seed_files[".glb"])])
    report = json.loads(capsys.readouterr().out)
    codes = {m["code"] for r in report["reports"] for m in r["issues"]["messages"]}
    assert codes == {"INTERNAL_ERROR"}
    assert status == 1


def test_validator_cli_boundary_names_the_exception(seed_files, monkeypatch, capsys):
    monkeypatch.setattr(cli, "validate_file", _boom)
    assert cli.main([str(seed_files[".glb"])]) == 2
    assert "internal error: Injected: 'injected'" in capsys.readouterr().err


def test_fuzz_harness_counts_a_gltf_bug_as_a_crash(seed_files, broken_accessors, tmp_path):
    fuzzer = fz.Fuzzer(str(tmp_path), timeout=NO_HANG_LIMIT)
    fuzzer.run_one(".glb", seed_files[".glb"].read_bytes())
    crashes = _crash_targets(fuzzer)
    assert set(crashes) == {"read_gltf", "validate"}
    assert crashes["read_gltf"].startswith("Injected: ")
    assert "INTERNAL_ERROR: Injected: " in crashes["validate"]
    assert "refused" not in fuzzer.outcomes["read_gltf"]
    fuzzer.run_one(".gltf", seed_files["mesh"].read_bytes())
    assert _crash_targets(fuzzer)["read_mesh"].startswith("Injected: ")


# ---------------------------------------------------------------------------- PLY

def test_ply_reader_lets_a_bug_propagate(seed_files, broken_model):
    from gsverse_format.io.ply import read_splat_ply

    with pytest.raises(Injected):
        read_splat_ply(seed_files[".ply"])


def test_fuzz_harness_counts_a_ply_bug_as_a_crash(seed_files, broken_model, tmp_path):
    fuzzer = fz.Fuzzer(str(tmp_path), timeout=NO_HANG_LIMIT)
    fuzzer.run_one(".ply", seed_files[".ply"].read_bytes())
    crashes = _crash_targets(fuzzer)
    assert "read_splat_ply" in crashes and crashes["read_splat_ply"].startswith("Injected: ")
    assert "refused" not in fuzzer.outcomes["read_splat_ply"]


# ---------------------------------------------------------------------------- USD

def test_usd_reader_lets_a_bug_propagate(tmp_path, monkeypatch):
    pytest.importorskip("pxr")
    from gsverse_format.examples import example_mesh, example_splats
    from gsverse_format.io.usd import read_usd, write_usd
    from gsverse_format.model import SplatAsset, SplatPrimitive

    path = tmp_path / "a.usda"
    write_usd(SplatAsset([SplatPrimitive(example_splats(example_mesh(0), 8), None, "a")]), path)
    monkeypatch.setattr(SplatCloud, "__post_init__", _boom)
    with pytest.raises(Injected):
        read_usd(path)


@pytest.mark.parametrize("usd", ["worker", "api"])
def test_fuzz_harness_counts_a_usd_bug_as_a_crash(tmp_path, monkeypatch, usd):
    """An unexpected exception in the USD reader (in the fuzz harness's USD worker, or in the
    isolation child of the public API) is an internal error for the fuzz harness and an
    INTERNAL_ERROR for the validator, never a refused input."""
    pytest.importorskip("pxr")
    from gsverse_format.io.usd import isolation, write_usd
    from usd_validation_assets import BROKEN_READER, local_asset

    good = tmp_path / "good.usda"
    write_usd(local_asset(), good)
    monkeypatch.setattr(isolation, "CHILD_CODE", BROKEN_READER + isolation.CHILD_CODE)
    monkeypatch.setattr(fz, "USD_WORKER_CODE", BROKEN_READER + fz.USD_WORKER_CODE)
    fuzzer = fz.Fuzzer(str(tmp_path / "work"), timeout=NO_HANG_LIMIT,
                       targets=fz.make_targets(usd))
    (tmp_path / "work").mkdir()
    try:
        fuzzer.run_one(".usda", good.read_bytes())
    finally:
        fuzzer.close()
    crashes = _crash_targets(fuzzer)
    assert set(crashes) == {"read_usd", "validate_usd"}, fuzzer.outcomes
    assert "KeyError" in crashes["read_usd"] and "INTERNAL_ERROR" in crashes["validate_usd"]
    assert "refused" not in fuzzer.outcomes["read_usd"]
