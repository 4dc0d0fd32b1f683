"""``gsverse-convert`` end to end: conversions, round trips, errors, atomic output."""
from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import sys
import warnings

import numpy as np
import pytest

from gsverse_format.cli.convert import main
from gsverse_format.examples import make_example
from gsverse_format.io.gltf import read_gltf
from gsverse_format.io.ply import read_splat_ply, write_splat_ply
from gsverse_format.remapping.reference import remap
from gsverse_format.transform import PLY_TO_GLTF, rotate_splats

from helpers import max_rel_cov_error, random_splats

import khr_tools

# PLY -> GLB -> PLY: positions, rotations and SH come back bit for bit (the frame change is a
# signed permutation, applied twice); scales and opacities go through exp/log and
# sigmoid/logit in float64 with one float32 rounding each way: a few float32 ulps.
SCALE_OPACITY_ULPS = 4


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    folder = tmp_path_factory.mktemp("example")
    return make_example(str(folder))


def run_cli(*args: str) -> subprocess.CompletedProcess:
    """Run the installed console script's module in a subprocess (exit code, stderr, stdout)."""
    return subprocess.run([sys.executable, "-m", "gsverse_format.cli.convert", *args],
                          capture_output=True, text=True, timeout=300)


def _ulps(a: np.ndarray, b: np.ndarray) -> float:
    a = np.asarray(a, np.float32)
    b = np.asarray(b, np.float32)
    spacing = np.spacing(np.maximum(np.abs(a), np.abs(b)))
    return float(np.max(np.abs(a.astype(np.float64) - b) / spacing)) if a.size else 0.0


def assert_ply_roundtrip(original, back):
    assert len(back) == len(original)
    assert np.array_equal(back.means, original.means)
    assert np.array_equal(back.sh, original.sh)
    dots = np.abs(np.sum(back.rotations.astype(np.float64) * original.rotations, axis=1))
    assert np.min(dots) >= 1 - 1e-7
    assert _ulps(back.scales, original.scales) <= SCALE_OPACITY_ULPS
    assert _ulps(back.opacities, original.opacities) <= SCALE_OPACITY_ULPS


def test_example_converts_and_rest_pose_matches_anchors(example, tmp_path):
    ply, obj = example
    out = tmp_path / "anchored.glb"
    assert main([ply, str(out), "--mesh", obj, "--quiet"]) == 0
    asset = read_gltf(out)
    assert len(asset.anchored) == 1 and not asset.static
    prim = asset.anchored[0]
    anchors = prim.anchoring.anchors
    assert anchors.profile == "local" and anchors.deformation == "affine"
    assert np.all(np.diff(anchors.face_index.astype(np.int64)) >= 0)  # sorted by face
    r = remap(prim.anchoring)
    size = np.linalg.norm(np.ptp(prim.anchoring.mesh.vertices, axis=0))
    assert np.max(np.abs(r.means - prim.splats.means)) <= 1e-6 * size
    assert max_rel_cov_error(r.covariances, prim.splats.covariances()) <= 2e-6
    # The GLB's rest pose is the PLY's splats, rotated into the glTF frame, reordered by face.
    source = rotate_splats(read_splat_ply(ply), PLY_TO_GLTF)
    order = np.lexsort(source.means.T)
    got = np.lexsort(prim.splats.means.T)
    assert np.array_equal(source.means[order], prim.splats.means[got])
    assert max_rel_cov_error(prim.splats.covariances()[got], source.covariances()[order]) < 1e-6


def test_rigid_law_and_keep_order(example, tmp_path):
    ply, obj = example
    out = tmp_path / "rigid.gltf"
    assert main([ply, str(out), "--mesh", obj, "--deformation", "rigid", "--keep-order", "-q"]) == 0
    prim = read_gltf(out).anchored[0]
    assert prim.anchoring.anchors.deformation == "rigid"
    source = rotate_splats(read_splat_ply(ply), PLY_TO_GLTF)
    assert np.array_equal(prim.splats.means, source.means)


def test_json_summary(example, tmp_path):
    ply, obj = example
    proc = run_cli(ply, str(tmp_path / "a.glb"), "--mesh", obj, "--json")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert summary["splats"] == summary["anchored"] == 3000
    assert summary["static"] == 0 and summary["profile"] == "local"
    assert 0 < summary["distance"]["p50"] <= summary["distance"]["p95"] <= summary["distance"]["max"]
    assert summary["mesh_faces"] == 1280 and summary["output_bytes"] > 0
    assert proc.stderr == ""  # no progress bar when not on a terminal


@pytest.mark.parametrize("sh_degree", [0, 1, 2, 3])
@pytest.mark.parametrize("binary,order", [(True, "<"), (True, ">"), (False, "<")])
def test_ply_glb_ply_roundtrip_generated(tmp_path, sh_degree, binary, order):
    cloud = random_splats(200, seed=sh_degree, sh_degree=sh_degree)
    src = tmp_path / "in.ply"
    write_splat_ply(cloud, src, binary=binary, byte_order=order)
    original = read_splat_ply(src)
    assert main([str(src), str(tmp_path / "mid.glb"), "--plain", "-q"]) == 0
    assert main([str(tmp_path / "mid.glb"), str(tmp_path / "out.ply"), "-q"]) == 0
    assert_ply_roundtrip(original, read_splat_ply(tmp_path / "out.ply"))


@pytest.mark.parametrize("name", ["donut_mipsplatting_sh0_fused.ply",
                                  "404gen_tmp_model_dreamgaussian_sh0.ply",
                                  "schwa_test-splat.3-points-from-train.ply"])
def test_ply_glb_ply_roundtrip_real_files(shared_data, tmp_path, name):
    src = shared_data / "3dgs" / name
    original = read_splat_ply(src)
    assert main([str(src), str(tmp_path / "mid.glb"), "--plain", "-q"]) == 0
    assert main([str(tmp_path / "mid.glb"), str(tmp_path / "out.ply"), "-q"]) == 0
    assert_ply_roundtrip(original, read_splat_ply(tmp_path / "out.ply"))


def test_sh_degree_truncation(tmp_path):
    cloud = random_splats(50, seed=1, sh_degree=3)
    write_splat_ply(cloud, tmp_path / "in.ply")
    assert main([str(tmp_path / "in.ply"), str(tmp_path / "out.glb"), "--sh-degree", "1", "--plain",
                 "-q"]) == 0
    assert read_gltf(tmp_path / "out.glb").primitives[0].splats.sh_degree == 1


def test_anchored_glb_reads_as_plain_splats_in_playcanvas(example, tmp_path):
    khr_tools.require_node_tools()
    ply, obj = example
    out = tmp_path / "anchored.glb"
    assert main([ply, str(out), "--mesh", obj, "-q"]) == 0
    ours = read_gltf(out).primitives[0].splats
    found = khr_tools.read_with_playcanvas(out)
    assert len(found) == 1, "PlayCanvas must see exactly one splat primitive (not the anchor mesh)"
    pc = found[0]
    assert pc["count"] == len(ours)
    assert np.array_equal(pc["position"], ours.means)
    assert np.array_equal(pc["scale"], ours.scales)
    assert np.array_equal(pc["opacity"], ours.opacities)
    assert np.array_equal(pc["rotation"], ours.rotations)
    report = khr_tools.validate_gltf(out)
    assert report["numUnexpectedErrors"] == 0, report["messages"]


# --- errors: one line, no traceback, nothing written -------------------------------------

def _assert_clean_failure(proc, *names, code=1):
    assert proc.returncode == code, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    assert lines[0].startswith("gsverse-convert: error: ")
    for name in names:
        assert name in lines[0]


def test_missing_input(example, tmp_path):
    """A missing input (or mesh) is bad input: exit 1, one line naming it, as the README
    says."""
    proc = run_cli(str(tmp_path / "nope.ply"), str(tmp_path / "out.glb"))
    _assert_clean_failure(proc, "nope.ply", "file not found", code=1)
    assert not (tmp_path / "out.glb").exists()
    ply, _ = example
    proc = run_cli(ply, str(tmp_path / "out.glb"), "--mesh", str(tmp_path / "nope.obj"))
    _assert_clean_failure(proc, "nope.obj", "file not found", code=1)
    assert not (tmp_path / "out.glb").exists()


def test_truncated_ply_leaves_existing_output_untouched(example, tmp_path):
    ply, obj = example
    data = open(ply, "rb").read()
    bad = tmp_path / "truncated.ply"
    bad.write_bytes(data[: len(data) // 2])
    out = tmp_path / "out.glb"
    out.write_bytes(b"previous contents")
    proc = run_cli(str(bad), str(out), "--mesh", obj, "-w")
    _assert_clean_failure(proc, "truncated.ply")
    assert out.read_bytes() == b"previous contents"
    assert sorted(os.listdir(tmp_path)) == ["out.glb", "truncated.ply"]  # no temp files left


def test_bad_mesh(example, tmp_path):
    ply, _ = example
    mesh = tmp_path / "broken.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nf 1 2 7\n")
    proc = run_cli(ply, str(tmp_path / "out.glb"), "--mesh", str(mesh))
    _assert_clean_failure(proc, "broken.obj")
    assert not (tmp_path / "out.glb").exists()


def test_all_degenerate_mesh(example, tmp_path):
    ply, _ = example
    mesh = tmp_path / "flat.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")
    proc = run_cli(ply, str(tmp_path / "out.glb"), "--mesh", str(mesh))
    _assert_clean_failure(proc, "flat.obj", "degenerate")


def test_nan_in_ply(tmp_path):
    cloud = random_splats(10, seed=2, sh_degree=0)
    path = tmp_path / "nan.ply"
    write_splat_ply(cloud, path)
    data = bytearray(path.read_bytes())
    body = data.index(b"end_header\n") + len(b"end_header\n")
    data[body + 4: body + 8] = np.array([np.nan], "<f4").tobytes()  # y of the first splat
    path.write_bytes(bytes(data))
    proc = run_cli(str(path), str(tmp_path / "out.glb"), "--plain")
    _assert_clean_failure(proc, "nan.ply")


def test_refuses_to_overwrite_input(example, tmp_path):
    ply, obj = example
    copy = tmp_path / "in.ply"
    shutil.copy(ply, copy)
    before = copy.read_bytes()
    proc = run_cli(str(copy), str(copy))
    _assert_clean_failure(proc, "in.ply", code=2)
    assert copy.read_bytes() == before


def test_unsupported_output_extension(example, tmp_path):
    ply, _ = example
    proc = run_cli(ply, str(tmp_path / "out.xyz"))
    _assert_clean_failure(proc, "out.xyz", code=2)


def test_missing_output_folder(example, tmp_path):
    ply, _ = example
    proc = run_cli(ply, str(tmp_path / "no" / "such" / "out.glb"))
    _assert_clean_failure(proc, code=2)


# --- existing outputs, -q, standard input and output ----------------------------------------

def test_existing_output_needs_overwrite(example, tmp_path):
    ply, obj = example
    out = tmp_path / "out.glb"
    out.write_bytes(b"previous contents")
    proc = run_cli(ply, str(out), "--mesh", obj)
    _assert_clean_failure(proc, "out.glb", "--overwrite", code=2)
    assert out.read_bytes() == b"previous contents"
    proc = run_cli(ply, str(out), "--mesh", obj, "-w", "-q")
    assert proc.returncode == 0 and proc.stdout == proc.stderr == ""
    assert read_gltf(out).splat_count() == 3000


def test_quiet_silences_every_warning(example, tmp_path):
    """pymeshlab (--faces) loads its own older libtbb before numba's first parallel kernel,
    and numba then warns that its TBB threading layer is disabled: -q silences that too."""
    ply, obj = example
    suffix = ".usda" if importlib.util.find_spec("pxr") else ".glb"
    env = dict(os.environ)
    env.pop("PYTHONWARNINGS", None)
    runs = {}
    for quiet in (False, True):
        runs[quiet] = subprocess.run(
            [sys.executable, "-m", "gsverse_format.cli.convert", ply,
             str(tmp_path / f"out{quiet}{suffix}"), "--mesh", obj, "--faces", "600"]
            + (["-q"] if quiet else []), capture_output=True, text=True, timeout=300, env=env)
        assert runs[quiet].returncode == 0, runs[quiet].stderr
    # Where pymeshlab's libtbb is older than numba needs, the loud run shows the warning.
    assert "Traceback" not in runs[False].stderr
    assert runs[True].stdout == runs[True].stderr == ""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main([ply, str(tmp_path / "in-process.glb"), "--plain", "-q"]) == 0
        warnings.warn("a warning after main() returned")
    assert [str(w.message) for w in caught] == ["a warning after main() returned"]


def test_stdin_to_stdout_glb_and_ply(example, tmp_path):
    ply, obj = example
    data = open(ply, "rb").read()
    proc = subprocess.run([sys.executable, "-m", "gsverse_format.cli.convert", "-", "-",
                           "--to", "glb", "--mesh", obj, "--keep-order", "--json"], input=data,
                          capture_output=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout[:4] == b"glTF"
    summary = json.loads(proc.stderr)  # the summary goes to stderr when stdout is the output
    assert summary["input"] == summary["output"] == "-" and summary["anchored"] == 3000
    (tmp_path / "piped.glb").write_bytes(proc.stdout)
    prim = read_gltf(tmp_path / "piped.glb").anchored[0]
    assert prim.name == "stdin"
    # GLB on standard input (sniffed), PLY file out; and back to a PLY on standard output
    proc = subprocess.run([sys.executable, "-m", "gsverse_format.cli.convert", "-",
                           str(tmp_path / "back.ply"), "-q"], input=proc.stdout,
                          capture_output=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert_ply_roundtrip(read_splat_ply(ply), read_splat_ply(tmp_path / "back.ply"))
    proc = subprocess.run([sys.executable, "-m", "gsverse_format.cli.convert",
                           str(tmp_path / "piped.glb"), "-", "--to", "ply", "-q"],
                          capture_output=True, timeout=300)
    assert proc.returncode == 0 and proc.stdout == (tmp_path / "back.ply").read_bytes()


@pytest.mark.parametrize("args,stdin,needle", [
    (["-", "-"], b"ply\n", "--to glb or --to ply"),
    (["-", "-", "--to", "usda"], b"ply\n", "cannot go to standard output"),
    (["-", "OUT"], b"not a splat file", "neither a PLY nor a GLB"),
    (["-", "OUT"], b"", "standard input is empty"),
])
def test_stdio_refusals(tmp_path, args, stdin, needle):
    args = [str(tmp_path / "o.glb") if a == "OUT" else a for a in args]
    proc = subprocess.run([sys.executable, "-m", "gsverse_format.cli.convert", *args],
                          input=stdin, capture_output=True, timeout=300)
    err = proc.stderr.decode()
    assert proc.returncode == 2 and needle in err and len(err.strip().splitlines()) == 1, err
    assert proc.stdout == b"" and not (tmp_path / "o.glb").exists()


def test_single_and_batch_usage_errors(example, tmp_path):
    ply, _ = example
    for args in ([ply], [ply, str(tmp_path / "a.glb"), str(tmp_path / "b.glb")],
                 [ply, str(tmp_path / "a.glb"), "--jobs", "2"]):
        proc = run_cli(*args)
        _assert_clean_failure(proc, code=2)
    assert not os.listdir(tmp_path)


def test_dash_o_is_the_output_file_or_a_batch_folder(example, tmp_path):
    """-o means the output, as in every gsverse command: a file name is the output file
    (never a folder of that name), a folder makes a batch, anything else is refused."""
    ply, obj = example
    proc = run_cli(ply, "-o", str(tmp_path / "out.glb"), "--mesh", obj, "-q")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "out.glb").is_file() and read_gltf(tmp_path / "out.glb").anchored
    proc = run_cli(ply, "-o", str(tmp_path / "out.glb"), "--mesh", obj)   # exists, no -w
    _assert_clean_failure(proc, "out.glb", "--overwrite", code=2)
    proc = run_cli(ply, "-o", str(tmp_path / "batch"), "--plain", "-q")   # no suffix: a folder
    assert proc.returncode == 0 and os.listdir(tmp_path / "batch") == ["splats.glb"]
    for args, needle in (([ply, ply, "-o", str(tmp_path / "two.glb")], "--output-dir DIR"),
                         ([ply, "-o", str(tmp_path / "out.v2")], "--output-dir"),
                         ([ply, str(tmp_path / "a.glb"), "-o", str(tmp_path / "b.glb")],
                          "IN -o OUT"),
                         ([ply, "-o", str(tmp_path / "c.glb"), "--output-dir",
                           str(tmp_path / "d")], "not both")):
        proc = run_cli(*args)
        _assert_clean_failure(proc, needle, code=2)
    assert sorted(os.listdir(tmp_path)) == ["batch", "out.glb"]
