"""Commands timed as fresh processes, as the benchmarks run them: :func:`run_process`.

Peak RSS is measured by a small launcher process that starts the command and reads
``getrusage(RUSAGE_CHILDREN)`` after it exits: the child inherits only the launcher's few MiB
as its starting high-water mark (a child forked from the benchmark process directly would
inherit that process's).

Memory made resident before a timed run (``warm``): the conversions allocate hundreds of MiB,
and on a virtual machine whose guest reports free memory back to the host (Linux free page
reporting, ``page_reporting``), a page freed a few seconds earlier must be backed by the host
again when it is next touched. On the development machine touching 768 MB that an earlier
process had freed took 0.05 s right after the free and 0.65-1.1 s four seconds later, and a
1M-splat ``--plain`` conversion 1.35-2.28 s against 1.06-1.16 s. So before a timed command a
helper process touches as much memory as the command is expected to use
(:func:`warm_memory`; the convert benchmark asks for its peak of the previous round, or three
times the input file at first) and exits, and the command starts on memory that is resident.
The helper runs outside the timed interval.
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

__all__ = ["run_process", "warm_memory"]

_LAUNCHER = """
import os, resource, subprocess, sys
with open(sys.argv[1], "w") as out:
    rc = subprocess.call(sys.argv[2:])
    out.write(str(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss))
sys.exit(rc)
"""


def warm_memory(nbytes: int) -> None:
    """Touch ``nbytes`` of fresh memory in a helper process that then exits, so that the next
    process starts on memory the machine holds resident (see the module docstring); at most
    half of what the system has available (``MemAvailable``), nothing off Linux."""
    try:
        with open("/proc/meminfo") as info:
            available = next(int(line.split()[1]) * 1024 for line in info
                             if line.startswith("MemAvailable:"))
    except (OSError, StopIteration, ValueError):
        return
    nbytes = min(int(nbytes), available // 2)
    if nbytes > 0:
        subprocess.run([sys.executable, "-c", "import sys, numpy as np; "
                        "np.ones(int(sys.argv[1]) // 8)", str(nbytes)], check=True)


def run_process(args: list[str], cwd: str | None = None, env: dict | None = None,
                warm: int = 0) -> dict:
    """Run a command as a fresh process; wall seconds, exit status, peak RSS (MiB) and its
    output. The peak comes from a launcher (see the module docstring); the wall time includes
    the launcher's start, a few tens of milliseconds, the same for every command. ``warm``:
    bytes made resident first (:func:`warm_memory`, untimed)."""
    if warm:
        warm_memory(warm)
    with tempfile.TemporaryDirectory() as d:
        peak_file = os.path.join(d, "peak")
        with tempfile.TemporaryFile() as out:
            t0 = time.perf_counter()
            p = subprocess.run([sys.executable, "-c", _LAUNCHER, peak_file, *args], stdout=out,
                               stderr=subprocess.STDOUT, cwd=cwd, env=env)
            wall = time.perf_counter() - t0
            out.seek(0)
            text = out.read().decode("utf-8", "replace")
        try:
            peak = int(Path(peak_file).read_text()) / 1024.0
        except (OSError, ValueError):
            peak = float("nan")
    return {"wall_s": wall, "rc": p.returncode, "peak_rss_mb": peak, "output": text}
