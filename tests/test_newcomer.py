"""What a newcomer trips over: a mesh that does not belong to its splats, a --faces target the
decimation cannot reach, stages without progress, a missing usd-core found late, misleading
messages (--from khr on a PLY, "anchored" beside a PLY output), --json without JSON on errors,
and a README usage block that lacks options.

Generated data throughout; the real samples of ../shared/data where present (skipped cleanly
otherwise)."""
from __future__ import annotations

import contextlib
import io
import json
import os
import pathlib
import re
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from gsverse_format import fit
from gsverse_format.cli.convert import build_parser, main
from gsverse_format.codes import Code
from gsverse_format.converters import SOURCES
from gsverse_format.examples import example_mesh, example_splats, write_obj
from gsverse_format.install import missing_usd_core
from gsverse_format.io.mesh import read_mesh
from gsverse_format.io.ply import write_splat_ply
from gsverse_format.model import TriangleMesh
from gsverse_format.validators.issues import CATALOGUE, Issues, Severity
from gsverse_format.validators.validate import validate_file

from helpers import surface_splats

REPO = pathlib.Path(__file__).resolve().parents[1]
CAPSULE = REPO / "examples" / "capsule"


def _run(*args: str) -> tuple[int, str, str]:
    """``gsverse-convert`` in this process: (exit status, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in args])
    return code, out.getvalue(), err.getvalue()


def _subprocess(*args: str, prelude: str = "", **kw) -> subprocess.CompletedProcess:
    """``gsverse-convert`` in a fresh interpreter, after ``prelude``."""
    code = prelude + "\nimport sys\nfrom gsverse_format.cli.convert import main\n" \
        "sys.exit(main(sys.argv[1:]))\n"
    return subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True,
                          text=True, cwd=str(REPO), timeout=600, **kw)


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """Splats on a capsule mesh (a 3DGS PLY), the mesh, and the mesh moved 40 diagonals away."""
    folder = tmp_path_factory.mktemp("pair")
    mesh = example_mesh(subdivisions=2)
    write_splat_ply(example_splats(mesh, 1500), folder / "splats.ply")
    write_obj(mesh, str(folder / "mesh.obj"))
    diagonal = float(np.linalg.norm(mesh.vertices.max(0) - mesh.vertices.min(0)))
    moved = TriangleMesh(mesh.vertices + np.array([40 * diagonal, 0, 0], np.float32), mesh.faces)
    write_obj(moved, str(folder / "moved.obj"))
    return folder


# ---------------------------------------------------------------------------- mesh fit

def test_a_moved_mesh_warns_with_numbers_and_still_converts(pair, tmp_path):
    code, out, err = _run(pair / "splats.ply", tmp_path / "o.glb", "--mesh", pair / "moved.obj")
    assert code == 0 and (tmp_path / "o.glb").exists()
    (line,) = err.strip().splitlines()
    assert line.startswith(f"gsverse-convert: warning: {pair / 'moved.obj'}: the anchor mesh "
                           f"does not fit the splats: only 0% of the splats")
    assert "median distance" in line and "offset by" in line
    assert "note       moved: the anchor mesh does not fit" in out


def test_the_fit_is_in_json_and_quiet_silences_the_warning(pair, tmp_path):
    code, out, err = _run(pair / "splats.ply", tmp_path / "o.glb", "--mesh", pair / "moved.obj",
                          "--json", "-q")
    assert code == 0 and err == ""
    (entry,) = json.loads(out)["fit"]
    assert entry["ok"] is False and entry["near_share"] == 0.0
    assert entry["median_distance"] > 30 * entry["mesh_diagonal"]
    assert entry["path"] == str(pair / "moved.obj") and "offset by" in entry["hint"]


def test_strict_refuses_a_moved_mesh_and_writes_nothing(pair, tmp_path):
    code, out, err = _run(pair / "splats.ply", tmp_path / "o.glb", "--mesh", pair / "moved.obj",
                          "--strict")
    assert code == 1 and out == "" and not (tmp_path / "o.glb").exists()
    (line,) = err.strip().splitlines()
    assert line.startswith(f"gsverse-convert: error: {pair / 'moved.obj'}: the anchor mesh "
                           "does not fit") and line.endswith("(--strict)")


def test_a_matching_mesh_is_silent_even_when_strict(pair, tmp_path):
    code, out, err = _run(pair / "splats.ply", tmp_path / "o.glb", "--mesh", pair / "mesh.obj",
                          "--strict", "--json")
    assert code == 0 and err == ""
    (entry,) = json.loads(out)["fit"]
    assert entry["ok"] is True and entry["near_share"] > 0.99 and entry["problem"] is None


def test_the_shipped_example_does_not_warn(tmp_path):
    code, out, err = _run(CAPSULE / "splats.ply", tmp_path / "o.glb", "--mesh",
                          CAPSULE / "mesh.obj", "--strict")
    assert code == 0 and "warning" not in err and "does not fit" not in out


def test_a_scene_judges_each_object_on_its_splats(pair, tmp_path):
    code, out, err = _run(pair / "splats.ply", tmp_path / "o.glb", "--mesh", pair / "mesh.obj",
                          "--mesh", pair / "moved.obj", "--json")
    summary = json.loads(out)
    fits = {f["mesh"]: f for f in summary["fit"]}
    # every splat is nearer the capsule than its moved copy: the copy gets none, said so
    assert code == 0 and fits["mesh"]["ok"] and "moved" not in fits and err == ""
    assert any(n.startswith("no splat is anchored to moved") for n in summary["notes"])
    mesh = read_mesh(pair / "moved.obj")
    write_obj(TriangleMesh(mesh.vertices * np.float32(3), mesh.faces), str(tmp_path / "far.obj"))
    code, out, err = _run(pair / "splats.ply", tmp_path / "p.glb", "--mesh", pair / "moved.obj",
                          "--mesh", tmp_path / "far.obj", "--json")
    fits = {f["mesh"]: f for f in json.loads(out)["fit"]}
    assert code == 0 and not fits["moved"]["ok"] and "far" not in fits
    assert f"warning: {pair / 'moved.obj'}: the anchor mesh does not fit" in err


def test_the_validator_warns_with_numbers(pair, tmp_path):
    _run(pair / "splats.ply", tmp_path / "bad.glb", "--mesh", pair / "moved.obj", "-q")
    _run(pair / "splats.ply", tmp_path / "good.glb", "--mesh", pair / "mesh.obj", "-q")
    bad = [f for f in validate_file(tmp_path / "bad.glb").findings
           if f.code == Code.ANCHOR_MESH_MISFIT]
    assert len(bad) == 1 and bad[0].severity == Severity.WARNING
    assert CATALOGUE[Code.ANCHOR_MESH_MISFIT].severity == Severity.WARNING
    assert re.search(r"only 0% of the splats .*\(median distance [0-9.]+", bad[0].message)
    assert bad[0].pointer.endswith("/attributes/POSITION")
    # the information finding stays beside it
    assert Code.LOCAL_BARYCENTRICS_FAR in validate_file(tmp_path / "bad.glb").codes()
    assert Code.ANCHOR_MESH_MISFIT not in validate_file(tmp_path / "good.glb").codes()


def test_the_validator_judges_an_even_subset_of_large_assets(monkeypatch):
    mesh = example_mesh(subdivisions=1)
    cloud = example_splats(mesh, 1000)
    far = mesh.vertices + np.array([100.0, 0, 0], np.float32)
    from gsverse_format.nearest import nearest_triangles

    face = nearest_triangles(cloud.means, far, mesh.faces, method="numpy").face
    monkeypatch.setattr(fit, "MAX_SPLATS_JUDGED", 300)
    report, judged = fit.assess_anchored_fit(cloud.means, far, mesh.faces, face)
    assert judged == 250 and not report.ok    # every 4th of 1000
    report, judged = fit.assess_anchored_fit(cloud.means, mesh.vertices, mesh.faces, face)
    assert judged == 250
    # the validator says so
    from gsverse_format.validators.container import Options
    from gsverse_format.validators.context import CheckContext
    from gsverse_format.validators.values import RestPose, check_fit

    ctx = CheckContext("x.glb", Options(), Issues())
    rest = RestPose(cloud.means, cloud.rotations, cloud.scales, "/pos", "/rot")
    check_fit(ctx, rest, TriangleMesh(far, mesh.faces), face)
    (finding,) = ctx.issues.findings
    assert finding.code == Code.ANCHOR_MESH_MISFIT and finding.pointer == "/pos"
    assert "judged on 250 evenly spaced splats of 1000" in finding.message


def test_real_bunny_moved_ten_units_warns(shared_data, tmp_path):
    bunny = read_mesh(shared_data / "meshes" / "trimesh_bunny_stanford_res2.ply")
    write_splat_ply(surface_splats(bunny, 4000, 0, offset=0.002, sh_degree=0),
                    tmp_path / "bunny.ply")
    write_obj(bunny, str(tmp_path / "bunny.obj"))
    moved = TriangleMesh(bunny.vertices + np.array([10, 0, 0], np.float32), bunny.faces)
    write_obj(moved, str(tmp_path / "moved.obj"))
    code, out, err = _run(tmp_path / "bunny.ply", tmp_path / "o.glb", "--mesh",
                          tmp_path / "moved.obj", "--json")
    (entry,) = json.loads(out)["fit"]
    assert code == 0 and not entry["ok"] and "warning" in err
    assert entry["median_distance"] / entry["mesh_diagonal"] > 30     # ~40 diagonals away
    code, out, err = _run(tmp_path / "bunny.ply", tmp_path / "good.glb", "--mesh",
                          tmp_path / "bunny.obj", "--strict")
    assert code == 0 and "warning" not in err
    finding = [f for f in validate_file(tmp_path / "o.glb").findings
               if f.code == Code.ANCHOR_MESH_MISFIT]
    assert finding and "median distance" in finding[0].message


def test_real_fox_under_the_donut_is_a_unit_mismatch(shared_data, tmp_path):
    donut = shared_data / "3dgs" / "donut_mipsplatting_sh0_fused.ply"
    fox = shared_data / "meshes" / "Fox.glb"
    code, out, err = _run(donut, tmp_path / "o.glb", "--mesh", fox, "--json")
    (entry,) = json.loads(out)["fit"]
    assert code == 0 and "x larger than the splats" in entry["problem"]
    assert entry["mesh_diagonal"] / entry["splat_diagonal"] > 100 and "warning" in err
    code, out, err = _run(donut, tmp_path / "s.glb", "--mesh", fox, "--strict")
    assert code == 1 and not (tmp_path / "s.glb").exists()
    finding = [f for f in validate_file(tmp_path / "o.glb").findings
               if f.code == Code.ANCHOR_MESH_MISFIT]
    assert finding and re.search(r"box diagonals [0-9.]+ and [0-9.]+", finding[0].message)


def test_a_mesh_reconstructed_from_real_splats_fits(shared_data, tmp_path):
    src = shared_data / "3dgs" / "404gen_tmp_model_dreamgaussian_sh0.ply"
    code, out, err = _run(src, tmp_path / "o.glb", "--reconstruct-faces", "1500", "--strict",
                          "--json")
    assert code == 0 and json.loads(out)["fit"][0]["ok"], err


# ---------------------------------------------------------------------------- --faces

def test_faces_above_the_target_say_why(tmp_path):
    """An open grid: the decimation keeps its border's outline, so --faces 8 cannot be met."""
    n = 12
    xs, ys = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    v = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], 1)
    i = np.arange(n * n).reshape(n, n) + np.arange(n)[:, None]
    a, b, c, d = i.ravel(), i.ravel() + 1, i.ravel() + n + 1, i.ravel() + n + 2
    grid = TriangleMesh(v, np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)]))
    write_obj(grid, str(tmp_path / "grid.obj"))
    write_splat_ply(surface_splats(grid, 500, 0, offset=0.01, sh_degree=0),
                    tmp_path / "s.ply")
    code, out, err = _run(tmp_path / "s.ply", tmp_path / "o.glb", "--mesh",
                          tmp_path / "grid.obj", "--faces", "8", "--json", "--no-frame-change")
    summary = json.loads(out)
    assert code == 0 and summary["mesh_faces"] > 8
    (note,) = [n for n in summary["notes"] if n.startswith("--faces 8:")]
    assert f"the anchor mesh has {summary['mesh_faces']} faces" in note
    assert "boundary edges" in note


# ---------------------------------------------------------------------------- progress

def test_a_terminal_sees_every_stage_in_order(tmp_path):
    """Under a pseudo-terminal the stage line names what runs: reading, each step of the
    mesh reconstruction, binding, writing."""
    import pty

    master, slave = pty.openpty()
    proc = subprocess.Popen([sys.executable, "-m", "gsverse_format.cli.convert",
                             str(CAPSULE / "splats.ply"), str(tmp_path / "o.glb"),
                             "--reconstruct-faces", "400"], stdin=slave, stdout=slave,
                            stderr=slave, cwd=str(REPO), close_fds=True)
    os.close(slave)
    chunks = []
    while True:
        try:
            chunk = os.read(master, 65536)
        except OSError:        # the child closed the terminal
            break
        if not chunk:
            break
        chunks.append(chunk)
    os.close(master)
    assert proc.wait(timeout=600) == 0
    text = b"".join(chunks).decode()
    stages = ["reading 3dgs input ...",
              "reconstructing the anchor mesh: normals of 3000 splats ...",
              "reconstructing the anchor mesh: screened Poisson",
              "reconstructing the anchor mesh: trimming",
              "reconstructing the anchor mesh: decimating",
              "binding to the nearest triangles ...",
              "binding to the nearest triangles [",
              "writing o.glb ..."]
    at = [text.find(s) for s in stages]
    assert -1 not in at, [s for s, i in zip(stages, at) if i < 0]
    assert at == sorted(at)


# ---------------------------------------------------------------------------- usd-core

_BLOCK_PXR = textwrap.dedent("""
    import importlib.abc, sys
    class _NoPxr(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name == "pxr" or name.startswith("pxr."):
                raise ModuleNotFoundError(f"No module named {name!r}", name=name)
            return None
    sys.meta_path.insert(0, _NoPxr())
    """)


def test_a_missing_usd_core_is_said_before_any_work(tmp_path):
    """pxr refused by the import machinery: the input is not even read (it is not a PLY at
    all, which would otherwise be the error), and the line is the install line that fits."""
    (tmp_path / "in.ply").write_bytes(b"not a ply at all")
    for out in ("o.usda", "o.glb"):
        args = [tmp_path / "in.ply", tmp_path / out] if out.endswith("usda") else \
            [tmp_path / "in.usda", tmp_path / out]
        if out == "o.glb":
            (tmp_path / "in.usda").write_text("#usda 1.0\n")
        proc = _subprocess(*args, "--json", prelude=_BLOCK_PXR)
        assert proc.returncode == 2, proc.stderr
        (line,) = proc.stderr.strip().splitlines()
        assert line.endswith(missing_usd_core()) and "USD support needs usd-core" in line
        error = json.loads(proc.stdout)["error"]
        assert error["kind"] == "usage" and error["cause"] == missing_usd_core()
        assert not (tmp_path / out).exists()
    check = subprocess.run([sys.executable, "-c", _BLOCK_PXR + "import pxr"],
                           capture_output=True, text=True)
    assert check.returncode != 0 and "ModuleNotFoundError" in check.stderr


def test_the_install_line_fits_an_editable_install():
    from importlib import metadata

    direct = None
    for dist in metadata.distributions(name="gsverse-format"):
        text = dist.read_text("direct_url.json")
        if text:
            direct = json.loads(text)
            break
    line = missing_usd_core()
    if direct and direct.get("dir_info", {}).get("editable"):
        assert "pip install -e " in line
    else:
        assert "pip install " in line and "-e " not in line
    assert "usd-core" in line


# ---------------------------------------------------------------------------- messages

def test_from_khr_on_a_ply_says_it_is_not_gltf(tmp_path):
    code, out, err = _run(CAPSULE / "splats.ply", tmp_path / "o.glb", "--from", "khr",
                          "--mesh", CAPSULE / "mesh.obj")
    assert code == 1 and "UTF-8" not in err
    assert "not a glTF file" in err and "a PLY file" in err


def test_ply_output_does_not_claim_anchored_splats(tmp_path):
    code, out, err = _run(CAPSULE / "splats.ply", tmp_path / "o.ply", "--mesh",
                          CAPSULE / "mesh.obj")
    assert code == 0
    assert "splats     3000 written as plain splats (anchoring not written to PLY)" in out
    assert "anchored 3000" not in out
    code, out, err = _run(CAPSULE / "splats.ply", tmp_path / "p.ply", "--mesh",
                          CAPSULE / "mesh.obj", "--json")
    summary = json.loads(out)
    assert summary["anchored"] == 0 and summary["static"] == 3000 and summary["plain_output"]


@pytest.mark.parametrize("args, status, kind", [
    (["missing.ply", "o.glb"], 1, "input"),
    (["bad.ply", "o.glb"], 1, "input"),
    (["a.ply", "b.ply", "--output-dir", "out", "--jobs", "0"], 2, "usage"),
])
def test_json_errors_are_json(tmp_path, monkeypatch, args, status, kind):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nend_header\n")
    code, out, err = _run(*args, "--json")
    assert code == status and err.startswith("gsverse-convert: error: ")
    doc = json.loads(out)
    assert doc["exit"] == status and doc["input"] == args[0]
    assert doc["error"]["kind"] == kind
    assert err.strip() == f"gsverse-convert: error: {doc['error']['message']}"


def test_json_usage_errors_of_the_parser_are_json(tmp_path):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), \
            pytest.raises(SystemExit) as stop:
        main(["a.ply", "b.glb", "--bogus", "--json"])
    assert stop.value.code == 2
    assert err.getvalue().rstrip().endswith("gsverse-convert: error: unrecognized arguments: "
                                            "--bogus")
    doc = json.loads(out.getvalue())
    assert doc == {"error": {"kind": "usage", "message": "unrecognized arguments: --bogus",
                             "path": None, "cause": "unrecognized arguments: --bogus"},
                   "input": None, "exit": 2}


@pytest.mark.parametrize("tool", ["pose", "render"])
def test_json_errors_of_pose_and_render(tmp_path, tool):
    from gsverse_format.cli import pose, render

    argv = {"pose": ["missing.glb", "--fps", "2", "-o", str(tmp_path / "o"), "--json"],
            "render": ["missing.glb", "-o", str(tmp_path / "o.png"), "--json"]}[tool]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = {"pose": pose, "render": render}[tool].main(argv)
    doc = json.loads(out.getvalue())
    assert code == 1 and doc == {"error": doc["error"], "input": "missing.glb", "exit": 1}
    assert doc["error"]["path"] == "missing.glb" and doc["error"]["kind"] == "input"


# ---------------------------------------------------------------------------- README

def _usage_block() -> str:
    text = (REPO / "README.md").read_text(encoding="utf-8")
    start = text.index("## `gsverse-convert`")
    block = text[start:].split("```", 2)[1]
    assert block.lstrip().startswith("gsverse-convert ")
    return block


def test_the_readme_usage_block_has_every_option():
    block = _usage_block()
    missing = []
    for action in build_parser()._actions:
        if not action.option_strings or "--help" in action.option_strings:
            continue
        if not any(re.search(rf"(?<![\w-]){re.escape(o)}(?![\w-])", block)
                   for o in action.option_strings):
            missing.append(action.option_strings[-1])
        for choice in action.choices or ():
            if not re.search(rf"(?<![\w-]){re.escape(str(choice))}(?![\w-])", block):
                missing.append(f"{action.option_strings[-1]} {choice}")
    assert not missing, f"README usage block lacks {missing}"
    assert set(SOURCES) <= set(re.findall(r"[\w-]+", block))


def test_the_readme_precision_claim_is_true_for_rotations():
    text = (REPO / "README.md").read_text(encoding="utf-8")
    precision = text[text.index("## Precision"):text.index("## Layout")]
    assert "positions, rotations and SH exactly" not in precision
    assert "normalized" in precision and "−q" in precision
