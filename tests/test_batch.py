"""``gsverse-convert IN... --output-dir DIR``: batches of real PLYs, locally and on Dask."""
from __future__ import annotations

import io
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gsverse_format.batch import collect, plan, read_manifest
from gsverse_format.cli.convert import main
from gsverse_format.errors import UsageError
from gsverse_format.io.gltf import read_gltf
from gsverse_format.pipeline import ConvertOptions

REPO = Path(__file__).resolve().parents[1]
CAPSULE = REPO / "examples" / "capsule"
SHARED_3DGS = REPO.parent / "shared" / "data" / "3dgs"
SHARED_NAMES = ("donut_mipsplatting_sh0_fused.ply", "404gen_tmp_model_dreamgaussian_sh0.ply")


def run_cli(*args: str, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "gsverse_format.cli.convert", *args],
                          capture_output=True, text=True, timeout=300, **kwargs)


@pytest.fixture(scope="module")
def library(tmp_path_factory) -> Path:
    """A small library: the capsule twice (one in a subfolder), a truncated PLY, and the
    shared 3DGS PLYs when ../shared is present."""
    root = tmp_path_factory.mktemp("library")
    shutil.copy(CAPSULE / "splats.ply", root / "capsule.ply")
    (root / "sub").mkdir()
    shutil.copy(CAPSULE / "splats.ply", root / "sub" / "capsule.ply")
    data = (CAPSULE / "splats.ply").read_bytes()
    (root / "corrupt.ply").write_bytes(data[: len(data) // 3])
    return root


def shared_plys() -> list[Path]:
    return [SHARED_3DGS / n for n in SHARED_NAMES if (SHARED_3DGS / n).is_file()]


def manifest_assets(library: Path) -> list[dict]:
    """Anchored capsules (with the mesh), plain shared PLYs, and the corrupt file."""
    assets = [{"input": str(library / "capsule.ply"), "mesh": str(CAPSULE / "mesh.obj"),
               "output": "capsule.glb"},
              {"input": str(library / "sub" / "capsule.ply"), "mesh": str(CAPSULE / "mesh.obj"),
               "output": "rigid/capsule.glb", "deformation": "rigid", "keep_order": True},
              {"input": str(library / "corrupt.ply"), "plain": True, "output": "corrupt.glb"}]
    assets += [{"input": str(p), "plain": True, "output": p.stem + ".glb"} for p in shared_plys()]
    return assets


def outputs(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def test_local_batch_json_corrupt_file_reported(library, tmp_path, capsys):
    out = tmp_path / "out"
    manifest = tmp_path / "assets.json"
    manifest.write_text(json.dumps({"assets": manifest_assets(library)}))
    code = main([str(manifest), "--output-dir", str(out), "--jobs", "2", "--json"])
    report = json.loads(capsys.readouterr().out)
    assert code == 1
    assert report["total"] == 3 + len(shared_plys())
    assert report["failed"] == 1 and report["ok"] == report["total"] - 1
    assert report["skipped"] == 0 and not report["interrupted"] and report["jobs"] == 2
    by_name = {Path(a["input"]).name + a["output"]: a for a in report["assets"]}
    bad = next(a for a in report["assets"] if a["status"] == "failed")
    assert "corrupt.ply" in bad["error"] and bad["summary"] is None
    assert not Path(bad["output"]).exists()
    for asset in report["assets"]:
        assert set(asset) == {"input", "output", "status", "error", "summary"}
        if asset["status"] == "ok":
            assert asset["error"] is None and Path(asset["output"]).is_file()
            assert asset["summary"]["output_bytes"] == Path(asset["output"]).stat().st_size
    assert len(by_name) == report["total"]
    anchored = read_gltf(out / "capsule.glb").anchored[0].anchoring.anchors
    rigid = read_gltf(out / "rigid" / "capsule.glb").anchored[0].anchoring.anchors
    assert anchored.deformation == "affine" and rigid.deformation == "rigid"
    for p in shared_plys():
        asset = read_gltf(out / (p.stem + ".glb"))
        assert not asset.anchored and asset.splat_count() > 0
    assert not [p for p in out.rglob(".*")]  # no temporary file (hidden, see atomic.py)


def test_dask_cluster_outputs_are_byte_identical(library, tmp_path, capsys):
    distributed = pytest.importorskip("distributed")
    manifest = tmp_path / "assets.json"
    manifest.write_text(json.dumps(manifest_assets(library)))
    local, remote = tmp_path / "local", tmp_path / "dask"
    assert main([str(manifest), "-o", str(local), "-j", "2", "-q"]) == 1
    with distributed.LocalCluster(processes=True, n_workers=2, threads_per_worker=1,
                                  dashboard_address=None) as cluster:
        code = main([str(manifest), "-o", str(remote), "--scheduler",
                     cluster.scheduler_address, "--json"])
    report = json.loads(capsys.readouterr().out)
    assert code == 1 and report["failed"] == 1 and report["scheduler"]
    assert "corrupt.ply" in next(a["error"] for a in report["assets"] if a["status"] == "failed")
    got, want = outputs(remote), outputs(local)
    assert len(want) == 2 + len(shared_plys())
    assert sorted(got) == sorted(want)
    for name in want:
        assert got[name] == want[name], f"{name} differs between the local and the Dask run"


def test_globs_csv_manifest_and_output_names(library, tmp_path, capsys):
    csv_path = tmp_path / "list.csv"
    csv_path.write_text(f"input,mesh,output,sh-degree,plain\n"
                        f"{library / 'capsule.ply'},{CAPSULE / 'mesh.obj'},from_csv.glb,0,no\n"
                        f"\n")
    out = tmp_path / "out"
    pattern = str(library / "**" / "capsule.ply")  # quoted glob: a.ply and sub/a.ply
    code = main([pattern, str(csv_path), "-o", str(out), "--plain", "--jobs", "1", "-q"])
    assert code == 0
    assert sorted(outputs(out)) == ["capsule.glb", "from_csv.glb", "sub/capsule.glb"]
    from_csv = read_gltf(out / "from_csv.glb")
    assert from_csv.anchored and from_csv.primitives[0].splats.sh_degree == 0
    assert not read_gltf(out / "capsule.glb").anchored  # --plain from the command line
    assert capsys.readouterr().out == ""  # -q


def test_manifest_errors_are_usage_errors(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("input,colour\na.ply,red\n")
    with pytest.raises(UsageError, match="unknown column 'colour'"):
        read_manifest(str(bad), ConvertOptions())
    bad.write_text("input,faces\na.ply,many\n")
    with pytest.raises(UsageError, match=r"bad.csv:2.*faces"):
        read_manifest(str(bad), ConvertOptions())
    js = tmp_path / "m.json"
    js.write_text(json.dumps(["x.ply", {"input": "y.ply", "plain": "yes", "k": 4}]))
    specs = read_manifest(str(js), ConvertOptions(faces=9))
    assert [Path(s.input).name for s in specs] == ["x.ply", "y.ply"]
    assert specs[1].options.plain and specs[1].options.k == 4 and specs[1].options.faces == 9
    assert Path(specs[1].input).parent == tmp_path  # relative to the manifest
    with pytest.raises(UsageError, match="no file matches"):
        collect([str(tmp_path / "*.nothing")], ConvertOptions())
    twice = collect([str(CAPSULE / "splats.ply")] * 2, ConvertOptions())
    with pytest.raises(UsageError, match="would both be written"):
        plan(twice, str(tmp_path / "o"))
    proc = run_cli(str(bad), "-o", str(tmp_path / "o"))
    assert proc.returncode == 2 and proc.stderr.startswith("gsverse-convert: error: ")
    assert not (tmp_path / "o").exists() or not os.listdir(tmp_path / "o")


def test_existing_outputs_refused_overwritten_or_skipped(library, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "capsule.glb").write_bytes(b"old")
    args = [str(library / "capsule.ply"), "-o", str(out), "--plain", "-j", "1"]
    assert main(args + ["-q"]) == 2
    assert (out / "capsule.glb").read_bytes() == b"old"
    assert "--overwrite" in capsys.readouterr().err
    assert main(args + ["--skip-existing", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["skipped"] == 1 and report["assets"][0]["status"] == "skipped"
    assert (out / "capsule.glb").read_bytes() == b"old"
    assert main(args + ["-w", "-q"]) == 0
    assert read_gltf(out / "capsule.glb").splat_count() == 3000


def test_json_lists_assets_in_input_order_with_skip_existing(tmp_path, capsys):
    """A skipped asset keeps its place: the report follows the inputs, not the work done."""
    inputs = []
    for name in ("a", "b", "c", "d"):
        shutil.copy(CAPSULE / "splats.ply", tmp_path / f"{name}.ply")
        inputs.append(str(tmp_path / f"{name}.ply"))
    out = tmp_path / "out"
    out.mkdir()
    (out / "b.glb").write_bytes(b"old")
    (out / "d.glb").write_bytes(b"old")
    assert main([*inputs, "--output-dir", str(out), "--plain", "--skip-existing", "-j", "1",
                 "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert [Path(a["input"]).name for a in report["assets"]] == ["a.ply", "b.ply", "c.ply",
                                                                 "d.ply"]
    assert [a["status"] for a in report["assets"]] == ["ok", "skipped", "ok", "skipped"]
    assert (out / "b.glb").read_bytes() == b"old"


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_bar_over_files_and_off_under_quiet(library, tmp_path, monkeypatch):
    args = [str(library / "capsule.ply"), str(library / "sub" / "capsule.ply"), "--plain",
            "-j", "1"]
    for quiet, expect_bar in ((False, True), (True, False)):
        err = _Tty()
        monkeypatch.setattr(sys, "stderr", err)
        code = main(args + ["-o", str(tmp_path / f"o{quiet}")] + (["-q"] if quiet else []))
        monkeypatch.undo()
        assert code == 0
        assert ("converting 2 assets" in err.getvalue()) is expect_bar
        assert ("2/2" in err.getvalue()) is expect_bar
        if quiet:
            assert err.getvalue() == ""


def start_batch(tmp_path: Path, splats: int, seed: int):
    """Six copies of ``splats`` random splats anchored to the capsule's mesh by a batch of two
    local workers, started as a child (``--json``); returns (process, output folder, the
    splats)."""
    from helpers import random_splats
    from gsverse_format.io.ply import write_splat_ply

    inputs = tmp_path / "in"
    inputs.mkdir()
    cloud = random_splats(splats, seed=seed, sh_degree=0)
    for i in range(6):
        write_splat_ply(cloud, inputs / f"c{i}.ply")
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "gsverse_format.cli.convert",
                             str(inputs / "*.ply"), "-o", str(out), "--mesh",
                             str(CAPSULE / "mesh.obj"), "-j", "2", "--json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    return proc, out, cloud


def test_interrupted_batch_leaves_no_partial_outputs(tmp_path):
    proc, out, cloud = start_batch(tmp_path, 100_000, seed=3)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if out.is_dir() and any(out.iterdir()):  # a conversion is writing
            break
        time.sleep(0.01)
    proc.send_signal(signal.SIGINT)  # Ctrl-C
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode in (130, 0), stderr  # 0: it finished before the signal came
    assert "Traceback" not in stderr
    report = json.loads(stdout)
    if proc.returncode == 130:
        assert report["interrupted"] > 0 and "interrupted" in stderr
    left = sorted(p.name for p in out.iterdir())
    assert not [n for n in left if not n.endswith(".glb")], left  # no temporary files
    for name in left:  # every output there is complete
        assert read_gltf(out / name).splat_count() == len(cloud)
    done = {Path(a["output"]).name for a in report["assets"] if a["status"] == "ok"}
    assert done == set(left)
