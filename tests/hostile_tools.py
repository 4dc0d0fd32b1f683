"""Running a command line tool on a hostile input in a child, measured: its exit status, its
standard error, and its CPU seconds and peak memory (a middle process reads the child's
resource usage alone), and the checks every refusal shares (one line, no traceback, nothing
written). A tiny GLB writer builds glTF inputs in the tests."""
from __future__ import annotations

import json
import struct
import subprocess
import sys
from pathlib import Path

#: Generous bounds for one refusal in a child on a busy machine: CPU seconds and peak memory.
CHILD_CPU_S = 60
CHILD_PEAK_MIB = 1024

_MEASURE = ("import resource, subprocess, sys\n"
            "p = subprocess.run(sys.argv[1:], capture_output=True, text=True)\n"
            "r = resource.getrusage(resource.RUSAGE_CHILDREN)\n"
            "sys.stdout.write(p.stdout); sys.stderr.write(p.stderr)\n"
            "sys.stderr.write(f'\\n@@ {r.ru_utime + r.ru_stime} {r.ru_maxrss}\\n')\n"
            "sys.exit(p.returncode)\n")


def run_measured(module: str, *args: str) -> tuple[int, str, float, float]:
    """``python -m MODULE ARGS`` in a child of a child: exit status, its stderr, and its CPU
    seconds and peak memory (MiB), measured by the middle process alone."""
    proc = subprocess.run([sys.executable, "-c", _MEASURE, sys.executable, "-m", module,
                           *map(str, args)], capture_output=True, text=True, timeout=600)
    err, _, tail = proc.stderr.rpartition("\n@@ ")
    cpu, peak_kib = tail.split()
    return proc.returncode, err.strip(), float(cpu), int(peak_kib) / 1024


def convert_measured(source: Path, out: Path, *extra: str) -> tuple[int, str, float, float]:
    """``gsverse-convert SOURCE OUT --plain`` (or SOURCE OUT EXTRA) measured as
    :func:`run_measured`."""
    return run_measured("gsverse_format.cli.convert", str(source), str(out),
                        *(extra or ("--plain",)))


def assert_one_line(code: int, err: str, cpu: float, peak: float, *words: str,
                    status: int = 1) -> str:
    """A refusal: exit ``status``, one line on stderr holding ``words``, no traceback, CPU
    and peak memory within the generous bounds."""
    assert code == status, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    for word in words:
        assert word in err, err
    assert cpu < CHILD_CPU_S and peak < CHILD_PEAK_MIB, (cpu, peak, err)
    return err


def glb_bytes(doc: dict, binary: bytes) -> bytes:
    """A GLB of the JSON ``doc`` (its ``buffers[0].byteLength`` set here) and ``binary``."""
    binary = binary + b"\0" * (-len(binary) % 4)
    doc = dict(doc, buffers=[{"byteLength": len(binary)}], asset={"version": "2.0"})
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    total = 12 + 8 + len(text) + 8 + len(binary)
    return (struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<I4s", len(text), b"JSON")
            + text + struct.pack("<I4s", len(binary), b"BIN\0") + binary)
