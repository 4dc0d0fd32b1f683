"""A minimal terminal progress bar (stderr), silent when not on a terminal or when quiet."""
from __future__ import annotations

import contextlib
import os
import sys
import time
import warnings
from typing import Iterator, TextIO


class Progress:
    """Draws ``label [#####.....] 42%`` on one stderr line, at most ~10 times a second."""

    def __init__(self, enabled: bool | None = None, stream: TextIO | None = None, width: int = 30):
        self.stream = stream or sys.stderr
        if self.stream is None:  # standard error closed (2>&-): nothing to draw on
            enabled = False
        self.enabled = (self.stream.isatty() if enabled is None else enabled)
        self.width = width
        self._last = 0.0
        self._label = ""

    def stage(self, label: str) -> None:
        """Start a new stage (finishes the previous line)."""
        self._finish_line()
        self._label = label
        if self.enabled:
            self.stream.write(f"{label} ...")
            self.stream.flush()

    def update(self, done: int, total: int, detail: str = "") -> None:
        """Redraw the bar at ``done`` of ``total``; ``detail`` follows the percentage."""
        if not self.enabled or total <= 0:
            return
        now = time.monotonic()
        if done < total and now - self._last < 0.1:
            return
        self._last = now
        frac = min(max(done / total, 0.0), 1.0)
        filled = int(round(frac * self.width))
        bar = "#" * filled + "." * (self.width - filled)
        tail = f" {detail}" if detail else ""
        self.stream.write(f"\r{self._label} [{bar}] {frac * 100:3.0f}%{tail}")
        self.stream.flush()

    def _finish_line(self) -> None:
        if self.enabled and self._label:
            self.stream.write("\n")
            self.stream.flush()
        self._label = ""

    def close(self) -> None:
        self._finish_line()


@contextlib.contextmanager
def silenced_warnings(quiet: bool) -> Iterator[None]:
    """Under ``-q``: no Python warning in this process, nor in the processes it starts
    (``PYTHONWARNINGS``), e.g. numba's TBB threading-layer warning. A no-op otherwise."""
    if not quiet:
        yield
        return
    saved = os.environ.get("PYTHONWARNINGS")
    os.environ["PYTHONWARNINGS"] = "ignore"
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        if saved is None:
            os.environ.pop("PYTHONWARNINGS", None)
        else:
            os.environ["PYTHONWARNINGS"] = saved
