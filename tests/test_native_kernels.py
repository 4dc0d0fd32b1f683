"""The native remap kernels (native/kernels/: GLSL 450 and HLSL compute, the C# core) pass the
conformance suite on real runtimes: the shaders compiled by glslang and run on Mesa's lavapipe
through Vulkan (tests/native_kernels.py), the C# core under Mono (tests/csharp_core.py); and a
deliberately broken variant of each fails exactly the cases it should.

The tools are Debian packages that ``scripts/test`` installs (glslang-tools, mesa-vulkan-drivers,
libvulkan-dev, mono-mcs, mono-runtime); without them these tests skip, and fail under
``GSVERSE_REQUIRE_NODE_TOOLS=1`` (CI, after installing them).
"""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from gsverse_format.conformance.check import check_results
from gsverse_format.conformance.export import export_suite
from gsverse_format.conformance.harness import suite_cases

import native_kernels


def _require(missing: list[str]) -> None:
    if not missing:
        return
    reason = "not installed: " + ", ".join(missing)
    if os.environ.get("GSVERSE_REQUIRE_NODE_TOOLS") == "1":
        pytest.fail(reason + "; required by GSVERSE_REQUIRE_NODE_TOOLS=1", pytrace=False)
    pytest.skip(reason)


@pytest.fixture(scope="module")
def suite(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("native-kernels") / "suite"
    export_suite(path)
    return path


@pytest.fixture(scope="module")
def manifests(suite) -> dict[str, dict]:
    return {m["id"]: m for _, m in suite_cases(suite)}


def _tagged(manifests: dict, prefix: str) -> set[str]:
    return {cid for cid, m in manifests.items()
            if m["kind"] != "invalid" and any(t.startswith(prefix) for t in m["tags"])}


def _failed(report) -> set[str]:
    """Cases that did not pass, those the harness declared unsupported left out."""
    return {c.id for c in report.cases if c.status not in ("pass", "unsupported")}


def _unsupported(report) -> set[str]:
    return {c.id for c in report.cases if c.status == "unsupported"}


def _spz(manifests: dict) -> set[str]:
    return {cid for cid, m in manifests.items() if "encoding:spz" in m["tags"]}


def _report(language: str, suite: Path, out: Path, fault: str | None = None,
            form: str = "cov"):
    _require(native_kernels.missing_tools(language))
    info = native_kernels.run(language, suite, out, fault=fault, form=form)
    if language in native_kernels.KERNEL_LANGUAGES:
        assert info["device"].startswith("lavapipe: llvmpipe")
    else:
        assert info["runtime"].startswith("Mono ")
    return check_results(suite, out, level="numbers")


def _with_fault(fault: str) -> list[str]:
    return sorted(native_kernels.FAULTS[fault][1])


@pytest.mark.parametrize("language", native_kernels.LANGUAGES)
def test_passes_every_numbers_case(language, suite, manifests, tmp_path):
    report = _report(language, suite, tmp_path / "r")
    assert report.ok, [(c.id, c.message) for c in report.cases if c.status != "pass"][:5]
    # every case of the numbers level ran: remap and rig cases dumped, invalid ones refused
    assert {c.id for c in report.cases} == set(manifests)
    assert {m["kind"] for m in manifests.values()} == {"remap", "rig", "invalid"}
    assert report.harness["name"]
    if language == "csharp":     # the per-frame remap allocates no managed memory
        assert report.harness["bytes_allocated_per_frame"] == 0
        # its own importer decodes no SPZ stream, and says so: those cases are not passed
        assert _unsupported(report) == _spz(manifests) and _spz(manifests)
    else:                        # the C header's importer (the minimal reader) decodes SPZ
        assert not _unsupported(report)


@pytest.mark.parametrize("language", native_kernels.LANGUAGES)
def test_rotation_scale_outputs_pass_every_numbers_case(language, suite, manifests, tmp_path):
    """The rotation + scale outputs of the kernels and of the C# core (rigid and games
    directly, affine by Jacobi), dumped instead of the covariances, pass too."""
    report = _report(language, suite, tmp_path / "r", form="rotscale")
    assert report.ok, [(c.id, c.message) for c in report.cases if c.status != "pass"][:5]
    assert report.harness["outputs"] == "rotation + scale"
    assert (tmp_path / "r" / "local-affine-bend" / "pose_000.rotation.f32").is_file()
    assert not (tmp_path / "r" / "local-affine-bend" / "pose_000.cov.f32").exists()


@pytest.mark.parametrize("language", _with_fault("scale-order"))
def test_broken_decomposition_fails_exactly_the_affine_cases(language, suite, manifests,
                                                             tmp_path):
    report = _report(language, suite, tmp_path / "r", "scale-order", form="rotscale")
    assert _failed(report) == _tagged(manifests, "deformation:affine") - _unsupported(report)


@pytest.mark.parametrize("language", _with_fault("frame-axis"))
def test_broken_frame_axis_fails_the_local_cases(language, suite, manifests, tmp_path):
    report = _report(language, suite, tmp_path / "r", "frame-axis")
    failed = _failed(report)
    local = _tagged(manifests, "profile:local") - _unsupported(report)
    # the float32 covariances of the rest sliver cannot tell the axes apart (test_conformance)
    assert local - {"local-affine-rest-sliver-opened"} <= failed <= local


@pytest.mark.parametrize("language", _with_fault("games-axis"))
def test_broken_games_axis_fails_exactly_the_games_cases(language, suite, manifests, tmp_path):
    failed = _failed(_report(language, suite, tmp_path / "r", "games-axis"))
    assert failed == _tagged(manifests, "profile:games")


def test_csharp_importer_accepting_a_zero_rotation_fails_exactly_those_invalid_cases(
        suite, tmp_path):
    failed = _failed(_report("csharp", suite, tmp_path / "r", "zero-rotation-accepted"))
    assert failed == {"invalid-local-rotation-zero", "invalid-derived-zero-rest-rotation"}


def test_every_fault_edits_its_sources_once(tmp_path):
    """The broken variants are the shipped sources with one edit (the correct text occurs
    exactly once) and still compile."""
    for fault, (_, variants) in native_kernels.FAULTS.items():
        for language in variants:
            _require(native_kernels.missing_tools(language))
            if language == "csharp":
                out = native_kernels.build_csharp(tmp_path, fault)
            else:
                out = native_kernels.compile_kernel(language, tmp_path, fault)
            assert out.stat().st_size > 0


def test_csharp_core_declares_no_engine_reference():
    """The runtime assembly is pure C#: its assembly definition declares no engine
    references and no source names UnityEngine (it runs under Mono here)."""
    import json

    runtime = native_kernels.UNITY / "Runtime"
    asmdef = json.loads((runtime / "Gsverse.MeshAnchor.asmdef").read_text(encoding="utf-8"))
    assert asmdef["noEngineReferences"] is True and asmdef["references"] == []
    sources = list(runtime.glob("*.cs"))
    assert len(sources) >= 4
    for path in sources:
        assert "UnityEngine" not in path.read_text(encoding="utf-8"), path.name


def test_unity_binding_include_compiles(tmp_path):
    """engines/unity.compute (plain global buffers and constants, Unity's kernel pragma) goes
    through glslang's HLSL front-end: the core needs no Vulkan attributes."""
    import subprocess

    _require(native_kernels.missing_tools("hlsl"))
    src = native_kernels.KERNELS / "hlsl" / "engines" / "unity.compute"
    run = subprocess.run([native_kernels.glslang(), "-D", "-V", "-S", "comp", "-e", "GsvRemap",
                          "--auto-map-bindings", str(src), "-o", str(tmp_path / "unity.spv")],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "vk::" not in (native_kernels.KERNELS / "hlsl" / "gsverse_remap_core.hlsli").read_text()


def test_kernel_benchmark_quick_prints_right_rows():
    """``python -m benchmarks.kernels --quick --sizes 5k`` prints one row per kernel and
    profile, each checked against the float64 reference (timings are not checked)."""
    import subprocess
    import sys

    _require(native_kernels.missing_tools("glsl"))
    out = subprocess.run([sys.executable, "-m", "benchmarks.kernels", "--quick", "--sizes", "5k"],
                         cwd=native_kernels.ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    rows = [line.split("|") for line in out.stdout.splitlines()
            if line.startswith("| GLSL") or line.startswith("| HLSL")]
    assert len(rows) == 2 * 3
    for row in rows:
        assert "lavapipe" in row[2] and row[4].strip() == "5,000"
        assert float(row[9]) < 1e-5           # max |Δμ| against the float64 reference


def test_native_conformance_script_exit_status(suite, tmp_path):
    """``scripts/native-conformance`` runs the harness and the check: exit 0 when every case
    passes, 1 when a broken variant fails some (nothing to install: the tools are here)."""
    import subprocess
    import sys

    _require(native_kernels.missing_tools("csharp") + native_kernels.missing_tools("glsl"))
    script = native_kernels.ROOT / "scripts" / "native-conformance"
    env = dict(os.environ, PATH=os.pathsep.join([str(Path(sys.executable).parent),
                                                 os.environ.get("PATH", "")]))
    good = subprocess.run([str(script), "csharp", str(suite), str(tmp_path / "good")],
                          capture_output=True, text=True, timeout=600, env=env)
    assert good.returncode == 0, good.stdout + good.stderr
    spz = len([m for _, m in suite_cases(suite) if "encoding:spz" in m["tags"]])
    assert (f"{len(suite_cases(suite)) - spz} passed, 0 failed, 0 missing, {spz} not supported "
            f"(declared by the harness)") in good.stdout
    bad = subprocess.run([str(script), "glsl", str(suite), str(tmp_path / "bad"), "--fault",
                          "games-axis"], capture_output=True, text=True, timeout=600, env=env)
    assert bad.returncode == 1, bad.stdout + bad.stderr
    assert "FAIL    games-bend" in bad.stdout
