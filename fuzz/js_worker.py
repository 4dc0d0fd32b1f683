"""The parent side of the JS target: one Node process (``fuzz/js_worker.mjs``) kept alive
across inputs, speaking the USD worker's protocol (:class:`fuzz.fuzz_readers.UsdWorker`).

A hang (no reply within the timeout) kills the process and a new one starts. The process
ending by itself (V8 out of heap, a crash) is an internal error of that input, unlike the
USD worker, where the USD library crashing is its way of refusing a corrupt file. The heap
is capped (``--max-old-space-size``) so that an unchecked allocation ends the process
instead of the machine; the address-space limit of the Python side is lifted for Node,
which reserves large virtual ranges at start.
"""
from __future__ import annotations

import os
import pathlib
import shutil
import subprocess

from fuzz.fuzz_readers import UsdWorker

__all__ = ["JsWorker", "node_available", "HEAP_MIB"]

#: V8 old-space limit of the worker (MiB).
HEAP_MIB = 4096
_SCRIPT = pathlib.Path(__file__).resolve().with_name("js_worker.mjs")


def node_available() -> bool:
    """Whether Node runs here (the web plugin needs no installed packages to read files)."""
    return shutil.which("node") is not None


def _no_address_limit() -> None:
    try:
        import resource

        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        resource.setrlimit(resource.RLIMIT_AS, (hard, hard))
    except (ImportError, ValueError, OSError):
        pass


class JsWorker(UsdWorker):
    """One Node child running the web plugin's reader; ``timeout`` seconds per input."""

    def _start(self) -> None:
        self.proc = subprocess.Popen(
            ["node", f"--max-old-space-size={HEAP_MIB}", "--stack-size=984", str(_SCRIPT)],
            cwd=str(_SCRIPT.parent), stdin=subprocess.PIPE, stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL, preexec_fn=_no_address_limit if os.name == "posix"
            else None)
        self.buffer = b""
        self.starts += 1
        self.fresh = True

    def _ended(self) -> tuple[str, str]:
        assert self.proc is not None
        code = self.proc.wait()
        self.proc = None
        return "internal", f"the Node reader process ended with status {code}"
