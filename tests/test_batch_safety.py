"""Batches keep to their output folder and survive a dead worker.

A manifest's outputs are relative to ``--output-dir`` and must stay inside it (no absolute
path, no ``..`` out of it, no symbolic link out of it); no output may be a file that some
asset of the batch reads. A worker process that dies (SIGKILL, as the kernel's
out-of-memory killer sends) fails only the asset it was converting."""
from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gsverse_format.atomic import is_temporary
from gsverse_format.batch import plan, read_manifest
from gsverse_format.errors import UsageError
from gsverse_format.io.gltf import read_gltf
from gsverse_format.pipeline import ConvertOptions

REPO = Path(__file__).resolve().parents[1]
CAPSULE = REPO / "examples" / "capsule"


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "gsverse_format.cli.convert", *args],
                          capture_output=True, text=True, timeout=300)


def digest(folder: Path) -> dict[str, str]:
    """Every file under ``folder`` (symbolic links not followed) and its checksum."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and not p.is_symlink()}


@pytest.fixture()
def tree(tmp_path: Path) -> Path:
    """``inputs/`` with two copies of the capsule splats, an empty ``out/`` folder, an
    ``elsewhere/`` folder and ``out/link`` pointing at it."""
    (tmp_path / "inputs").mkdir()
    for name in ("a.ply", "b.ply"):
        shutil.copy(CAPSULE / "splats.ply", tmp_path / "inputs" / name)
    (tmp_path / "out").mkdir()
    (tmp_path / "elsewhere").mkdir()
    os.symlink(tmp_path / "elsewhere", tmp_path / "out" / "link")
    return tmp_path


@pytest.mark.parametrize("output", ["../x.glb", "sub/../../x.glb", "link/x.glb", "ABSOLUTE",
                                    ".", "sub/.."])
def test_manifest_outputs_stay_inside_the_output_folder(tree, output):
    if output == "ABSOLUTE":
        output = str(tree / "elsewhere" / "x.glb")
    manifest = tree / "m.csv"
    manifest.write_text("input,output,plain\n"
                        "inputs/a.ply,fine.glb,yes\n"
                        f"inputs/b.ply,{output},yes\n")
    before = digest(tree)
    proc = run_cli(str(manifest), "--output-dir", str(tree / "out"), "-j", "1")
    assert proc.returncode == 2, proc.stderr
    line = proc.stderr.strip()
    assert "\n" not in line and "Traceback" not in line
    assert "m.csv:3" in line and ("outside --output-dir" in line or "absolute" in line), line
    assert digest(tree) == before  # nothing written anywhere, the first row included
    assert sorted(os.listdir(tree / "out")) == ["link"]


def test_an_output_that_is_an_input_of_the_batch_is_refused(tree):
    plain = tree / "inputs" / "b.glb"
    assert run_cli(str(tree / "inputs" / "b.ply"), str(plain), "--plain", "-q").returncode == 0
    manifest = tree / "m.csv"
    # Row 2 would overwrite row 3's input (the folder of inputs is the output folder).
    manifest.write_text("input,output,plain\n"
                        "inputs/a.ply,a.glb,yes\n"
                        "inputs/a.ply,b.glb,yes\n"
                        "inputs/b.glb,c.glb,yes\n")
    before = digest(tree)
    proc = run_cli(str(manifest), "--output-dir", str(tree / "inputs"), "-w", "-j", "1")
    assert proc.returncode == 2, proc.stderr
    assert "m.csv:3" in proc.stderr and "an input of" in proc.stderr and "m.csv:4" in proc.stderr
    assert digest(tree) == before
    # A hard link to an input under another name is the same file.
    os.link(tree / "inputs" / "a.ply", tree / "out" / "same.glb")
    specs = read_manifest(str(manifest), ConvertOptions())[:1]
    specs = [s.__class__(s.input, s.options, "same.glb", s.origin) for s in specs]
    with pytest.raises(UsageError, match="its own input"):
        plan(specs, str(tree / "out"), overwrite=True)


def _stopped(pid: int) -> bool:
    """Stop process ``pid`` (SIGSTOP) and wait until the kernel reports it stopped; False
    when it is gone."""
    try:
        os.kill(pid, signal.SIGSTOP)
        for _ in range(10_000):
            with open(f"/proc/{pid}/stat") as stat:
                state = stat.read().rpartition(")")[2].split()[0]
            if state in ("T", "t"):
                return True
            if state in ("Z", "X"):
                return False
            time.sleep(0.001)
    except (ProcessLookupError, FileNotFoundError):
        return False
    raise AssertionError(f"worker {pid} did not stop")


def _resume(pid: int) -> None:
    try:
        os.kill(pid, signal.SIGCONT)
    except ProcessLookupError:
        pass


def test_a_killed_worker_fails_only_its_own_asset(tmp_path):
    from test_batch import start_batch

    proc, out, cloud = start_batch(tmp_path, 60_000, seed=5)
    killed = None
    deadline = time.monotonic() + 240
    try:
        # Kill the worker that is writing an output (its process id is in the temporary
        # file's name): it leaves a half-written temporary behind, which must not stay.
        # The worker is stopped first, and killed only if its temporary still exists once
        # it is stopped (else it finished that output: it goes on, and the next is tried),
        # so the kill always lands while an output is half written.
        while time.monotonic() < deadline and proc.poll() is None and killed is None:
            for name in os.listdir(out) if out.is_dir() else []:
                m = re.search(r"-(\d+)-[0-9a-f]{8}$", name)
                if is_temporary(name) and m:
                    pid = int(m.group(1))
                    if _stopped(pid) and (out / name).exists():
                        killed = pid
                        os.kill(pid, signal.SIGKILL)
                    else:
                        _resume(pid)
                    break
            time.sleep(0.005)
        stdout, stderr = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert killed is not None, "no worker was seen converting"
    assert "Traceback" not in stderr
    report = json.loads(stdout)
    assert proc.returncode == 1
    failed = [a for a in report["assets"] if a["status"] == "failed"]
    assert len(failed) == 1 and report["ok"] == 5, report
    assert "killed by SIGKILL" in failed[0]["error"] and failed[0]["input"] in failed[0]["error"]
    assert not Path(failed[0]["output"]).exists()
    for a in report["assets"]:
        if a["status"] == "ok":
            assert read_gltf(a["output"]).splat_count() == len(cloud)
    assert not [p for p in out.rglob(".*")]  # the dead worker's temporary file removed


@pytest.mark.parametrize("answer", [b"", b"HTTP/1.1 200 OK\r\n\r\nnot a scheduler\r\n"])
def test_a_scheduler_address_that_is_not_dask_is_a_usage_error(monkeypatch, answer):
    """A TCP server that accepts and then says nothing (or something else) is refused
    within the connection and handshake limits, not waited on forever."""
    import socket
    import threading

    from gsverse_format import batch_workers

    monkeypatch.setattr(batch_workers, "DASK_CONNECT_S", 2)
    monkeypatch.setattr(batch_workers, "DASK_HANDSHAKE_S", 3)
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(4)
    held: list[socket.socket] = []

    def serve() -> None:
        while True:
            try:
                conn, _ = server.accept()
            except OSError:
                return
            held.append(conn)
            if answer:
                conn.sendall(answer)

    threading.Thread(target=serve, daemon=True).start()
    address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
    try:
        with pytest.raises(UsageError) as info:
            batch_workers._dask_client(address)
    finally:
        server.close()
        for conn in held:
            conn.close()
    assert address in str(info.value)
    assert "Dask scheduler" in str(info.value)
