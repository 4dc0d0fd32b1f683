"""Stop signals during long native calls (``atomic.interruptions_immediate``).

A Python signal handler runs only when the main thread is back in the interpreter, so a
SIGTERM that arrives during screened Poisson, a pymeshlab filter or manifold3d's constructor
would wait for the call to return (minutes, for some inputs). Inside those calls the stop
signals take the system's default action instead: the process ends at once, killed by the
signal.

Each test runs a child process. The first checks the mechanism with a native loop that holds
the interpreter (numba, no ``nogil``). The others check the real call sites: pymeshlab gives
the interpreter up while its filters run, so a thread of the child watches for the moment the
default action is in place and only then sends the signal; a call outside the block would let
the child finish and exit 0. Nothing here depends on timing: the signal is sent from inside
the call, or after the child said it is inside."""
from __future__ import annotations

import signal
import subprocess
import sys
import textwrap

import pytest

#: generous bound for a child that should die at once or finish a few seconds of work
CHILD_WALL_S = 300

#: the child's thread that sends SIGTERM once the stop signals take their default action
#: (which happens only inside ``interruptions_immediate``), then the call to test
_WATCH = """
import os, signal, sys, threading, time
import numpy as np
from gsverse_format.cli.boundary import Interrupted, interrupting_signals

done = threading.Event()

def watch():
    while not done.is_set():
        if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
            os.kill(os.getpid(), signal.SIGTERM)
            return
        time.sleep(0.0005)

with interrupting_signals():
    try:
        threading.Thread(target=watch, daemon=True).start()
        call()
    except Interrupted:
        sys.exit(143)
    finally:
        done.set()
print("finished")
"""


def _run_child(source: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", source], capture_output=True,
                          text=True, timeout=CHILD_WALL_S)


def _assert_killed_by_sigterm(proc: subprocess.CompletedProcess) -> None:
    assert proc.returncode == -signal.SIGTERM, (proc.returncode, proc.stdout, proc.stderr)
    assert "finished" not in proc.stdout
    assert "Traceback" not in proc.stderr


def test_a_stop_signal_ends_a_native_call_that_holds_the_interpreter():
    # The numba loop runs for minutes and never returns to the interpreter; the parent
    # signals once the child is inside the block.
    proc = subprocess.Popen([sys.executable, "-c", textwrap.dedent("""
        import sys
        import numba
        from gsverse_format.atomic import interruptions_immediate
        from gsverse_format.cli.boundary import Interrupted, interrupting_signals

        @numba.njit(cache=False)
        def spin(n):
            x = 0.0
            for i in range(n):
                x = x * 0.999999 + i % 7
            return x

        spin(10)
        with interrupting_signals():
            try:
                with interruptions_immediate():
                    print("inside", flush=True)
                    spin(10 ** 12)
            except Interrupted:
                sys.exit(143)
        print("finished")
        """)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == "inside"
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=CHILD_WALL_S)
    finally:
        if proc.poll() is None:
            proc.kill()
    _assert_killed_by_sigterm(subprocess.CompletedProcess(proc.args, proc.returncode, out, err))


def test_handlers_come_back_after_the_block_and_pending_signals_are_not_lost():
    proc = _run_child(textwrap.dedent("""
        import os, signal, sys
        from gsverse_format.atomic import interruptions_immediate
        from gsverse_format.cli.boundary import Interrupted, interrupting_signals

        with interrupting_signals():
            before = signal.getsignal(signal.SIGTERM)
            with interruptions_immediate():
                assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
                assert signal.getsignal(signal.SIGINT) is signal.SIG_DFL
            assert signal.getsignal(signal.SIGTERM) is before
            try:
                os.kill(os.getpid(), signal.SIGTERM)   # handled before the block starts
                with interruptions_immediate():
                    print("not reached")
            except Interrupted:
                print("interrupted before the block")
        ignored = signal.signal(signal.SIGHUP, signal.SIG_IGN)
        with interruptions_immediate():
            assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN   # ignored stays so
        print("finished")
        """))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["interrupted", "before", "the", "block", "finished"]


def test_sigterm_during_screened_poisson_ends_the_process():
    pytest.importorskip("pymeshlab")
    _assert_killed_by_sigterm(_run_child(textwrap.dedent("""
        from gsverse_format.converters.reconstruct import _poisson

        def call():
            rng = np.random.default_rng(0)
            p = rng.normal(size=(20_000, 3))
            p /= np.linalg.norm(p, axis=1, keepdims=True)
            _poisson(p, p.copy(), np.ones(len(p)), 8, 1)
        """) + _WATCH))


def test_sigterm_during_pymeshlab_decimation_ends_the_process():
    pytest.importorskip("pymeshlab")
    _assert_killed_by_sigterm(_run_child(textwrap.dedent("""
        import trimesh
        from gsverse_format.meshops import decimate
        from gsverse_format.model import TriangleMesh

        def call():
            sphere = trimesh.creation.icosphere(subdivisions=6)
            decimate(TriangleMesh(sphere.vertices.astype(np.float32), sphere.faces), 100)
        """) + _WATCH))


def test_sigterm_during_the_compiled_nearest_search_ends_the_process():
    # numba's compiled code calls back into Python (its progress callback here, unpickling
    # constants elsewhere): an Interrupted raised by a handler there became a SystemError or
    # a segmentation fault. The callback signals the child itself, from inside the search.
    pytest.importorskip("numba")
    _assert_killed_by_sigterm(_run_child(textwrap.dedent("""
        import os, signal, sys
        import numpy as np
        from gsverse_format.cli.boundary import Interrupted, interrupting_signals
        from gsverse_format.examples import example_mesh
        from gsverse_format.nearest.dispatch import nearest_triangles

        mesh = example_mesh()
        points = np.random.default_rng(0).normal(size=(200_000, 3)).astype(np.float32)

        def progress(done, total):
            os.kill(os.getpid(), signal.SIGTERM)

        with interrupting_signals():
            try:
                nearest_triangles(points, mesh.vertices, mesh.faces, chunk=4096,
                                  progress=progress, method="numba")
            except Interrupted:
                sys.exit(143)
        print("finished")
        """)))


def test_sigterm_while_trimesh_reads_a_mesh_ends_the_process(tmp_path):
    # trimesh's import and OBJ reader catch BaseException (falling back to slower paths), so
    # an Interrupted raised inside was swallowed and the conversion went on to write its output
    from gsverse_format.examples import example_mesh, write_obj

    obj = tmp_path / "mesh.obj"
    write_obj(example_mesh(subdivisions=6), str(obj))
    # a group statement: outside the plain subset that gsverse_format.io.obj reads itself,
    # so trimesh reads this file
    obj.write_bytes(b"g body\n" + obj.read_bytes())
    _assert_killed_by_sigterm(_run_child(textwrap.dedent(f"""
        from gsverse_format.io.mesh import read_mesh

        def call():
            read_mesh({str(obj)!r})
        """) + _WATCH))


def test_a_library_caller_gets_its_keyboard_interrupt_after_the_call():
    # Outside the command-line tools (an interactive session calling the package), a stop
    # signal must not end the interpreter: the block defers it to its end instead.
    proc = _run_child(textwrap.dedent("""
        import os, signal
        from gsverse_format.atomic import interruptions_immediate

        try:
            with interruptions_immediate():
                assert signal.getsignal(signal.SIGINT) is not signal.SIG_DFL
                os.kill(os.getpid(), signal.SIGINT)
                print("inside after the signal")
        except KeyboardInterrupt:
            print("KeyboardInterrupt after the block")
        """))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines() == ["inside after the signal",
                                        "KeyboardInterrupt after the block"]
