"""Faults: inputs a conversion must never replace, USD files that crash the USD library, outputs
the operating system refuses, closed or broken standard output, and signals. Every hostile
input is generated here; signals go to a real child process in the middle of a real write."""
from __future__ import annotations

import glob
import json
import os
import resource
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gsverse_format import atomic
from gsverse_format.errors import OutputError, UsageError
from gsverse_format.io.gltf import read_gltf
from gsverse_format.io.ply import read_splat_ply, write_splat_ply
from gsverse_format.io.usd import write_usd
from gsverse_format.model import SplatAsset, SplatPrimitive

from helpers import random_splats
from source_fixtures import games_scene, write_gsverse_folder

CONVERT = [sys.executable, "-m", "gsverse_format.cli.convert"]
VALIDATE = [sys.executable, "-m", "gsverse_format.validators.cli"]
RENDER = [sys.executable, "-m", "gsverse_format.cli.render"]
POSE = [sys.executable, "-m", "gsverse_format.cli.pose"]
#: Splats of the input written while a signal comes: big enough that writing its GLB takes a
#: while (about 47 MB), small enough for CI.
SIGNAL_SPLATS = 200_000


def _run(cmd, *, env=None, **kw) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, capture_output=True, text=True, timeout=300,
                          env={**os.environ, **(env or {})}, **kw)


def _one_line(stderr: str) -> str:
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert "Traceback" not in stderr and "internal error" not in stderr
    return lines[0]


def _temporaries(folder: Path) -> list[str]:
    return sorted(n for n in os.listdir(folder) if atomic.is_temporary(n) or n.startswith(".tmp"))


@pytest.fixture(scope="module")
def small_glb(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("small") / "small.glb"
    from gsverse_format.api import write

    write(SplatAsset([SplatPrimitive(random_splats(3000, seed=2, sh_degree=1), None, "s")]),
          path)
    return path


# --------------------------------------------------------------------- inputs never replaced

def test_games_folder_output_never_replaces_the_files_the_source_read(tmp_path):
    run = write_gsverse_folder(games_scene("blender"), tmp_path / "run")
    inputs = {name: (Path(run) / name).read_bytes()
              for name in ("point_cloud.ply", "model_params.json", "mesh.obj")}
    for extra in ([], ["-w"]):
        result = _run([*CONVERT, str(run), str(Path(run) / "point_cloud.ply"), "--from",
                       "games", *extra])
        assert result.returncode == 2, result.stderr
        line = _one_line(result.stderr)
        assert "point_cloud.ply" in line and ("input" in line or "exists" in line)
    # the input PLY named directly: the source reads the folder's parameters and mesh too
    result = _run([*CONVERT, str(Path(run) / "point_cloud.ply"),
                   str(Path(run) / "point_cloud.ply"), "--from", "games", "-w"])
    assert result.returncode == 2 and "would overwrite an input" in _one_line(result.stderr)
    assert {n: (Path(run) / n).read_bytes() for n in inputs} == inputs
    assert not _temporaries(Path(run))
    # an output in the run folder that is no input of it may be written and replaced
    out = Path(run) / "anchored.glb"
    for extra in ([], ["-w"]):
        result = _run([*CONVERT, str(run), str(out), "-q", *extra])
        assert result.returncode == 0, result.stderr
    assert read_gltf(out).splat_count() == len(read_splat_ply(Path(run) / "point_cloud.ply"))


def test_a_protected_folder_protects_every_file_inside_it(tmp_path):
    folder = tmp_path / "in"
    (folder / "deep").mkdir(parents=True)
    inside = folder / "deep" / "x.ply"
    inside.write_bytes(b"keep")
    with pytest.raises(UsageError, match="inside the input folder"):
        with atomic.atomic_write(inside, protect=(str(folder),)) as handle:
            handle.write(b"lost")
    assert inside.read_bytes() == b"keep"
    with atomic.atomic_write(folder / "new.ply", protect=(str(folder),)) as handle:
        handle.write(b"new")  # not an existing file of the folder: no input is lost
    assert (folder / "new.ply").read_bytes() == b"new"


# --------------------------------------------------------------------- USD crashes

def _nested_usda(path: Path, depth: int = 20_000) -> Path:
    """A small text layer of ``depth`` nested prims (USD's parser recurses per level)."""
    path.write_text("#usda 1.0\n" + "".join(f'def "p{i}" {{\n' for i in range(depth))
                    + "}\n" * depth)
    return path


def _flipped_usdc(path: Path) -> Path:
    """A valid binary layer with one byte of its token table flipped (usd-core aborts)."""
    good = path.with_name("good.usdc")
    write_usd(SplatAsset([SplatPrimitive(random_splats(50, seed=1, sh_degree=0), None, "s")]),
              good)
    data = bytearray(good.read_bytes())
    data[88] ^= 0xFF
    path.write_bytes(bytes(data))
    return path


def _crashes_in_process(path: Path, tmp: Path) -> bool:
    """Whether reading ``path`` without isolation kills the reading process by a signal."""
    code = ("import sys; from gsverse_format.io.usd.reader import read_in_process; "
            "read_in_process(sys.argv[1])")
    env = {**os.environ, "TMPDIR": str(tmp)}

    def limits() -> None:
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
        resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))

    proc = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True,
                          env=env, timeout=120, preexec_fn=limits)
    return proc.returncode < 0


@pytest.mark.parametrize("kind", ["nested.usda", "flipped.usdc"])
def test_usd_input_that_crashes_the_usd_library_is_one_line(kind, tmp_path, small_glb):
    hostile = (_nested_usda if kind.endswith("usda") else _flipped_usdc)(tmp_path / kind)
    reports = tmp_path / "tmp"
    reports.mkdir()
    if kind.endswith("usdc") and not _crashes_in_process(hostile, reports):
        pytest.skip("this usd-core reads the flipped file without crashing")
    for f in reports.iterdir():  # the crash report of the in-process read above
        f.unlink()
    out = tmp_path / "out"
    out.mkdir()
    env = {"TMPDIR": str(reports)}
    commands = [[*CONVERT, str(hostile), str(out / "a.glb")],
                [*RENDER, str(hostile), "-o", str(out / "a.png")],
                [*POSE, str(hostile), "--times", "0", "--deform", "stretch=0.1", "-o", str(out)]]
    for cmd in commands:
        result = _run(cmd, env=env)
        assert result.returncode == 1, (cmd, result.stderr)
        line = _one_line(result.stderr)
        assert str(hostile) in line, line
        assert not os.listdir(out), cmd
        assert not os.listdir(reports), (cmd, os.listdir(reports))  # no USD crash report


# --------------------------------------------------------------------- outputs refused

def _fsize_limit(limit: int):
    def apply() -> None:  # the child's writes past ``limit`` bytes fail with EFBIG
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return apply


@pytest.mark.parametrize("suffix", [".glb", ".ply", ".usdc", ".usdz"])
def test_full_disk_is_one_line_and_keeps_the_old_output(suffix, tmp_path, small_glb):
    out = tmp_path / f"a{suffix}"
    out.write_bytes(b"old output")
    result = subprocess.run([*CONVERT, str(small_glb), str(out), "-w"], capture_output=True,
                            text=True, timeout=300, preexec_fn=_fsize_limit(20_000))
    assert result.returncode == 1, result.stderr
    line = _one_line(result.stderr)
    assert str(out) in line and "File too large" in line, line
    assert out.read_bytes() == b"old output"
    assert not _temporaries(tmp_path)


def test_output_path_that_is_a_folder_or_lies_under_a_file(tmp_path, small_glb):
    folder = tmp_path / "folder.glb"
    folder.mkdir()
    for extra in ([], ["-w"]):
        result = _run([*CONVERT, str(small_glb), str(folder), *extra])
        assert result.returncode == 1, result.stderr
        assert "is a folder" in _one_line(result.stderr)
    assert not os.listdir(folder)
    under = small_glb.parent / "small.glb" / "x.glb"
    result = _run([*CONVERT, str(small_glb), str(under)])
    assert result.returncode == 1, result.stderr
    line = _one_line(result.stderr)
    assert str(under) in line and "not a folder" in line
    with pytest.raises(OutputError, match="is a folder"):
        with atomic.atomic_write(folder):
            pass


def _read_only_folder(tmp_path: Path) -> Path:
    """A folder this process may not create files in: a mode 0555 folder, or (for root, whom
    permissions do not stop) sysfs's root, which refuses new files to everyone."""
    if os.geteuid() != 0:
        folder = tmp_path / "ro"
        folder.mkdir()
        folder.chmod(0o555)
        return folder
    sysfs = Path("/sys")
    try:
        fd = os.open(sysfs / "gsverse-probe", os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except OSError:
        return sysfs
    os.close(fd)
    os.unlink(sysfs / "gsverse-probe")
    pytest.skip("no folder refuses new files to root here")


def test_read_only_folder_is_one_line(tmp_path, small_glb):
    folder = _read_only_folder(tmp_path)
    for name in ("a.glb", "a.ply", "a.usda"):
        target = folder / name
        result = _run([*CONVERT, str(small_glb), str(target)])
        assert result.returncode == 1, result.stderr
        line = _one_line(result.stderr)
        assert str(target) in line and "cannot write" in line, line
        assert any(w in line for w in ("denied", "not permitted", "Read-only")), line
        assert not target.exists()


def test_batch_reports_an_unwritable_output_folder_without_internal_error(tmp_path, small_glb):
    blocker = tmp_path / "blocker"
    blocker.write_bytes(b"a file where the output folder should go")
    result = _run([*CONVERT, str(small_glb), "-o", str(blocker / "sub"), "--json", "-j", "1"])
    assert result.returncode in (1, 2), result.stderr
    assert "internal error" not in result.stderr and "Traceback" not in result.stderr


# --------------------------------------------------------------------- standard output

def _close_stdout() -> None:
    os.close(1)


def test_closed_stdout(tmp_path, small_glb):
    result = subprocess.run([*VALIDATE, str(small_glb)], stdout=None, stderr=subprocess.PIPE,
                            text=True, timeout=300, preexec_fn=_close_stdout)
    assert result.returncode == 2
    assert "standard output is closed" in _one_line(result.stderr)
    result = subprocess.run([*CONVERT, str(small_glb), "-", "--to", "glb"],
                            stderr=subprocess.PIPE, text=True, timeout=300,
                            preexec_fn=_close_stdout)
    assert result.returncode == 2 and "standard output is closed" in _one_line(result.stderr)
    out = tmp_path / "a.glb"  # a file output needs no standard output: the summary is dropped
    result = subprocess.run([*CONVERT, str(small_glb), str(out)], stderr=subprocess.PIPE,
                            text=True, timeout=300, preexec_fn=_close_stdout)
    assert result.returncode == 0 and result.stderr == ""
    assert read_gltf(out).splat_count() == 3000


@pytest.mark.parametrize("command", ["validate", "convert to -", "convert summary"])
def test_stdout_reader_gone(command, small_glb, tmp_path):
    cmd = {"validate": [*VALIDATE, str(small_glb), str(small_glb)],
           "convert to -": [*CONVERT, str(small_glb), "-", "--to", "glb", "--plain"],
           "convert summary": [*CONVERT, str(small_glb), str(tmp_path / "a.glb")]}[command]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # "| head -0": the reader is gone before anything is written
    stderr = proc.stderr.read().decode()
    assert proc.wait(timeout=300) == 128 + signal.SIGPIPE
    assert stderr == "", stderr
    if command == "convert summary":  # the output was complete before the summary was printed
        assert read_gltf(tmp_path / "a.glb").splat_count() == 3000


# --------------------------------------------------------------------- signals

@pytest.fixture(scope="module")
def big_ply(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("big") / "big.ply"
    write_splat_ply(random_splats(SIGNAL_SPLATS, seed=5, sh_degree=3), path)
    return path


def _default_signals() -> None:  # runs in the child before exec
    """Default dispositions for the signals under test: a test run started under ``nohup``
    or in the background of a shell inherits SIGHUP/SIGINT ignored, which the tools (rightly)
    keep ignoring."""
    for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(signum, signal.SIG_DFL)


def _stopped(pid: int, timeout: float = 10.0) -> bool:
    """Wait until process ``pid`` is in the stopped state (``T`` in /proc), or has ended."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            with open(f"/proc/{pid}/stat", encoding="ascii") as handle:
                state = handle.read().rsplit(")", 1)[1].split()[0]
        except OSError:
            return False
        if state in "TtZX":
            return state in "Tt"
        time.sleep(0.0005)
    return False


def _stopped_while_writing(cmd, folder: Path) -> tuple[subprocess.Popen, str]:
    """Start ``cmd`` and stop it (SIGSTOP) as soon as its temporary output is in ``folder``;
    returns the stopped process and the temporary's name."""
    for _ in range(3):
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                preexec_fn=_default_signals)
        deadline = time.monotonic() + 240
        while proc.poll() is None and time.monotonic() < deadline:
            names = [n for n in os.listdir(folder) if atomic.is_temporary(n)]
            if names:
                os.kill(proc.pid, signal.SIGSTOP)
                # SIGSTOP takes effect asynchronously: wait until the process is stopped
                # before looking whether its temporary is still there.
                if _stopped(proc.pid) and os.path.exists(folder / names[0]):
                    return proc, names[0]
                os.kill(proc.pid, signal.SIGCONT)
            time.sleep(0.001)
        proc.kill()
        proc.communicate()
        for name in os.listdir(folder):
            os.unlink(folder / name)
    pytest.fail("the conversion never showed its temporary file while running")


@pytest.mark.parametrize("signame", ["SIGTERM", "SIGHUP", "SIGINT"])
def test_signal_during_a_write_leaves_nothing(signame, big_ply, tmp_path):
    signum = getattr(signal, signame)
    out = tmp_path / "out"
    out.mkdir()
    proc, tmp = _stopped_while_writing([*CONVERT, str(big_ply), str(out / "big.glb"),
                                        "--plain"], out)
    assert tmp.startswith(".big.glb" + atomic.TEMP_MARK) and str(proc.pid) in tmp
    os.kill(proc.pid, signum)
    os.kill(proc.pid, signal.SIGCONT)
    stdout, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 128 + signum, stderr
    assert _one_line(stderr) == "gsverse-convert: interrupted; no output written"
    assert os.listdir(out) == []


def test_sigterm_stops_a_batch_and_its_workers_cleanly(big_ply, tmp_path):
    inputs = tmp_path / "in"
    inputs.mkdir()
    for i in range(3):
        os.link(big_ply, inputs / f"c{i}.ply")
    out = tmp_path / "out"
    out.mkdir()
    proc, _ = _stopped_while_writing([*CONVERT, str(inputs / "*.ply"), "-o", str(out), "-j",
                                      "2", "--plain", "--json"], out)
    os.kill(proc.pid, signal.SIGCONT)  # the parent: only the worker was writing
    proc.send_signal(signal.SIGTERM)
    stdout, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 143, stderr  # the third asset was never started
    assert "Traceback" not in stderr and "interrupted" in stderr
    left = sorted(os.listdir(out))
    assert not [n for n in left if not n.endswith(".glb")], left  # no temporary file
    report = json.loads(stdout)
    assert report["interrupted"] > 0
    assert {Path(a["output"]).name for a in report["assets"] if a["status"] == "ok"} == set(left)
    for name in left:
        assert read_gltf(out / name).splat_count() == SIGNAL_SPLATS


def test_sigterm_while_validating_usd_stops_the_child_and_leaves_nothing(tmp_path):
    usd = tmp_path / "a.usdc"
    write_usd(SplatAsset([SplatPrimitive(random_splats(500, seed=1, sh_degree=0), None, "s")]),
              usd)
    work = tmp_path / "tmp"
    work.mkdir()
    proc = subprocess.Popen([*VALIDATE, str(usd)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "TMPDIR": str(work)})
    deadline = time.monotonic() + 240
    while proc.poll() is None and time.monotonic() < deadline:
        if os.listdir(work):  # the USD child's folder: the child runs
            os.kill(proc.pid, signal.SIGSTOP)
            if os.listdir(work):
                break
            os.kill(proc.pid, signal.SIGCONT)
        time.sleep(0.001)
    else:
        pytest.fail("the validator never started its USD child process")
    os.kill(proc.pid, signal.SIGTERM)
    os.kill(proc.pid, signal.SIGCONT)
    stdout, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 143, stderr
    assert _one_line(stderr) == "gsverse-validate: interrupted" and stdout == ""
    assert os.listdir(work) == []  # the child's folder (and any crash report) removed


def test_temporaries_left_by_sigkill_are_never_outputs_and_are_swept(big_ply, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    proc, tmp = _stopped_while_writing([*CONVERT, str(big_ply), str(out / "big.glb"),
                                        "--plain"], out)
    proc.kill()
    proc.communicate()
    assert os.listdir(out) == [tmp]
    # never taken for an output: not by a glob, nor by --skip-existing
    assert glob.glob(str(out / "*.glb")) == [] and glob.glob(str(out / "**"), recursive=True) \
        == [str(out) + os.sep]
    small = tmp_path / "small"
    small.mkdir()
    write_splat_ply(random_splats(100, seed=1, sh_degree=0), small / "big.ply")
    result = _run([*CONVERT, str(small / "big.ply"), "-o", str(out), "--skip-existing",
                   "--plain", "--json"])
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["assets"][0]["status"] == "ok"
    os.unlink(out / "big.glb")
    # a fresh leftover stays (its owner might be a process of another PID namespace) ...
    result = _run([*CONVERT, str(small / "big.ply"), str(out / "other.glb"), "--plain"])
    assert result.returncode == 0 and tmp in os.listdir(out)
    # ... one older than STALE_AFTER_S is removed by the next write into the folder; so is
    # a folder left by the USD writer; those of live processes and other machines stay
    old = time.time() - atomic.STALE_AFTER_S - 10
    os.utime(out / tmp, (old, old))
    host = tmp.split(atomic.TEMP_MARK)[1].split("-")[0]
    dead_dir = out / f".x.usdz{atomic.TEMP_MARK}{host}-{_dead_pid()}-0123abcd"
    dead_dir.mkdir()
    (dead_dir / "asset.usdc").write_bytes(b"partial")
    live = out / f".y.glb{atomic.TEMP_MARK}{host}-{os.getpid()}-0123abcd"
    other_host = out / f".z.glb{atomic.TEMP_MARK}{'f' * 8 if host != 'f' * 8 else '0' * 8}-" \
                       f"{_dead_pid()}-0123abcd"
    for path in (dead_dir, live, other_host):
        if path.is_file() or not path.exists():
            path.write_bytes(b"partial")
        os.utime(path, (old, old))
    result = _run([*CONVERT, str(small / "big.ply"), str(out / "third.glb"), "--plain"])
    assert result.returncode == 0, result.stderr
    assert sorted(os.listdir(out)) == sorted([live.name, other_host.name, "other.glb",
                                              "third.glb"])


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_temporary_names(tmp_path):
    long = "n" * 250 + ".glb"
    with atomic.atomic_write(tmp_path / long) as handle:
        names = os.listdir(tmp_path)
        assert len(names) == 1 and atomic.is_temporary(names[0])
        assert names[0].startswith(".") and not names[0].endswith(".glb")
        assert len(names[0].encode()) <= 255
        handle.write(b"x")
    assert os.listdir(tmp_path) == [long]
    for name in ("a.glb", ".a.glb", ".tmp-abc.glb", ".a.glb.gsverse-tmp-", ".a.gsverse-tmp-1-2-3"):
        assert not atomic.is_temporary(name)
    assert socket.gethostname()  # the host part is derived from it


# --------------------------------------------------------------------- interruption windows
# Where a signal lands is a matter of timing in the signal tests above; here each window is
# reached on purpose: the call that opens it does its work, then SIGINT comes, and its
# handler runs at the first point CPython runs handlers, as after a system call returns.

def _then_interrupted(function):
    def call(*args, **kwargs):
        result = function(*args, **kwargs)
        signal.raise_signal(signal.SIGINT)
        return result
    return call


@pytest.fixture
def sigint_raises():
    """SIGINT raises KeyboardInterrupt here, as in any interactive Python, whatever this test
    run inherited (started in a shell's background or under nohup, it has SIGINT ignored)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


@pytest.mark.parametrize("existing", [False, True])
def test_interruption_as_the_temporary_file_is_made_leaves_nothing(existing, tmp_path,
                                                                   monkeypatch, sigint_raises):
    out = tmp_path / "a.glb"
    if existing:
        out.write_bytes(b"old output")
    monkeypatch.setattr(os, "open", _then_interrupted(os.open))  # either call may make it
    monkeypatch.setattr(atomic, "open", _then_interrupted(open), raising=False)
    with pytest.raises(KeyboardInterrupt):
        with atomic.atomic_write(out) as handle:
            handle.write(b"new output")
    assert os.listdir(tmp_path) == (["a.glb"] if existing else [])
    assert not existing or out.read_bytes() == b"old output"
    assert not atomic._LIVE


def test_interruption_as_the_temporary_folder_is_made_leaves_nothing(tmp_path, monkeypatch,
                                                                   sigint_raises):
    monkeypatch.setattr(os, "mkdir", _then_interrupted(os.mkdir))
    with pytest.raises(KeyboardInterrupt):
        with atomic.temporary_folder(tmp_path / "a.usdz"):
            pass
    assert os.listdir(tmp_path) == [] and not atomic._LIVE


@pytest.mark.parametrize("existing", [False, True])
@pytest.mark.parametrize("kind", ["file", "folder"])
def test_interruption_during_the_rename_undoes_it(kind, existing, tmp_path, monkeypatch,
                                                  sigint_raises):
    """An interruption received while the output is renamed into place is raised just after
    the rename: the output must then be as it was, so that "no output written" is true."""
    out = tmp_path / "a.usdc"
    if existing:
        out.write_bytes(b"old output")
    monkeypatch.setattr(os, "replace", _then_interrupted(os.replace))
    with pytest.raises(KeyboardInterrupt):
        if kind == "file":
            with atomic.atomic_write(out) as handle:
                handle.write(b"new output")
        else:
            with atomic.temporary_folder(out, result="asset.usdc") as work:
                Path(work, "asset.usdc").write_bytes(b"new output")
    monkeypatch.undo()
    assert os.listdir(tmp_path) == (["a.usdc"] if existing else [])
    assert not existing or out.read_bytes() == b"old output"
    assert str(out) not in atomic.outputs_written() and not atomic._LIVE


def test_a_completed_write_is_recorded_and_leaves_no_backup(tmp_path):
    out = tmp_path / "a.glb"
    for content in (b"first", b"second"):
        with atomic.atomic_write(out) as handle:
            handle.write(content)
        assert os.listdir(tmp_path) == ["a.glb"] and out.read_bytes() == content
    with atomic.temporary_folder(out, result="x") as work:
        Path(work, "x").write_bytes(b"third")
    assert os.listdir(tmp_path) == ["a.glb"] and out.read_bytes() == b"third"
    assert atomic.outputs_written()[-3:] == [str(out)] * 3


def test_interruptions_deferred_raises_on_leaving(sigint_raises):
    seen = []
    with pytest.raises(KeyboardInterrupt):
        with atomic.interruptions_deferred():
            signal.raise_signal(signal.SIGINT)
            seen.append("still running")
    assert seen == ["still running"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    with atomic.interruptions_deferred():  # nothing received: nothing raised
        pass


@pytest.mark.parametrize("window", ["probe", "folder", "child"])
def test_interruption_as_the_usd_child_starts_leaves_no_folder_and_no_child(
        window, tmp_path, monkeypatch, sigint_raises):
    """The parent's first look at the temporary folder (Python writes and removes a probe file
    there), the child's private folder, the child process: an interruption as each comes into
    being leaves nothing in the temporary folder, and no child running."""
    import tempfile

    from gsverse_format.io.usd import isolation

    usd = tmp_path / "a.usda"
    write_usd(SplatAsset([SplatPrimitive(random_splats(50, seed=1, sh_degree=0), None, "s")]),
              usd)
    work = tmp_path / "tmp"
    work.mkdir()
    monkeypatch.setenv("TMPDIR", str(work))
    monkeypatch.setattr(tempfile, "tempdir", None)  # looked for (and probed) again
    children: list[subprocess.Popen] = []
    start = subprocess.Popen

    def popen(*args, **kwargs):
        children.append(start(*args, **kwargs))
        return children[-1]
    if window == "probe":
        monkeypatch.setattr(os, "open", _then_interrupted(os.open))
    elif window == "folder":
        monkeypatch.setattr(os, "mkdir", _then_interrupted(os.mkdir))
    else:
        monkeypatch.setattr(isolation.subprocess, "Popen", _then_interrupted(popen))
    with pytest.raises(KeyboardInterrupt):
        isolation.read_isolated(str(usd), None)
    monkeypatch.undo()
    assert os.listdir(work) == []
    assert len(children) == (window == "child")
    for child in children:  # the interruption came as the child started: it was ended
        assert child.returncode is not None
