"""Timing helpers: repeated measurements with a record of what else used the CPU.

The machines this runs on are often shared. Every batch of repetitions records how many cores
*other* processes kept busy while it ran (the busy time in ``/proc/stat`` minus this process's
own CPU time, divided by the wall time) and how many cores the measured code itself used. The
summary prefers batches in which other processes used less than a quarter of a core.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

__all__ = ["Timing", "measure", "cpu_busy_seconds", "QUIET"]

#: A batch counts as uncontended when other processes used less than this many cores.
QUIET = 0.25

_HZ = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def cpu_busy_seconds() -> float | None:
    """Machine-wide busy CPU seconds since boot (all cores), or None where /proc is absent."""
    try:
        with open("/proc/stat") as fh:
            parts = fh.readline().split()
    except OSError:
        return None
    vals = [int(x) for x in parts[1:]]
    idle = vals[3] + (vals[4] if len(vals) > 4 else 0)  # idle + iowait
    busy = sum(vals[:8]) - idle                          # user..steal, without guest
    return busy / _HZ


def _own_cpu() -> float:
    """CPU seconds of this process and of its finished children (work it delegated, such as
    the child process that parses USD files, is not load from other processes)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


@dataclass
class Timing:
    """Seconds per call: every sample, and per batch the other processes' and our own cores."""

    samples: list[float] = field(default_factory=list)
    batches: list[dict] = field(default_factory=list)

    def _quiet_samples(self) -> list[float]:
        quiet = [s for b in self.batches if b["other"] is not None and b["other"] < QUIET
                 for s in b["samples"]]
        return quiet

    @property
    def contended(self) -> bool:
        """True when no batch ran without load from other processes."""
        return not self._quiet_samples()

    @property
    def median(self) -> float:
        """Median over uncontended batches (over all batches when there are none)."""
        quiet = self._quiet_samples()
        return float(np.median(quiet if quiet else self.samples))

    @property
    def best(self) -> float:
        return float(min(self.samples))

    @property
    def spread(self) -> tuple[float, float]:
        return float(min(self.samples)), float(max(self.samples))

    @property
    def other_cores(self) -> tuple[float, float]:
        vals = [b["other"] for b in self.batches if b["other"] is not None]
        return (float(min(vals)), float(max(vals))) if vals else (float("nan"), float("nan"))

    @property
    def own_cores(self) -> float:
        vals = [b["own"] for b in self.batches]
        return float(np.median(vals)) if vals else float("nan")

    def as_dict(self) -> dict:
        return {"median_s": self.median, "best_s": self.best, "min_s": self.spread[0],
                "max_s": self.spread[1], "contended": self.contended,
                "other_cores": self.other_cores, "own_cores": self.own_cores,
                "samples": len(self.samples), "quiet_samples": len(self._quiet_samples())}


def measure(fn: Callable[[], object], *, repeat: int = 5, batches: int = 3,
            warmup: int = 1, budget_s: float | None = None, retry_contended: int = 0,
            min_quiet: int = 0, max_wait_s: float = 0.0) -> Timing:
    """Time ``fn()``: ``warmup`` untimed calls, then ``batches`` batches of ``repeat`` calls.

    ``budget_s`` stops adding batches once that much wall time was spent (at least one batch
    runs). ``retry_contended`` adds up to that many further batches while no batch so far was
    uncontended. ``min_quiet`` keeps adding batches (pausing half a second after each
    contended one) until that many uncontended batches were collected or ``max_wait_s``
    seconds have passed: on a shared machine this waits for quiet moments.
    """
    for _ in range(warmup):
        fn()
    timing = Timing()
    start = time.perf_counter()
    extra = retry_contended
    b = 0
    while True:
        busy0, own0, wall0 = cpu_busy_seconds(), _own_cpu(), time.perf_counter()
        samples = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            fn()
            samples.append(time.perf_counter() - t0)
        wall = time.perf_counter() - wall0
        busy1, own1 = cpu_busy_seconds(), _own_cpu()
        own = (own1 - own0) / wall if wall > 0 else float("nan")
        other = None
        if busy0 is not None and busy1 is not None and wall > 0:
            other = max(0.0, ((busy1 - busy0) - (own1 - own0)) / wall)
        timing.samples.extend(samples)
        timing.batches.append({"samples": samples, "other": other, "own": own})
        b += 1
        if budget_s is not None and time.perf_counter() - start > budget_s:
            break
        quiet = sum(1 for x in timing.batches if x["other"] is not None and x["other"] < QUIET)
        if b >= batches and quiet < min_quiet and time.perf_counter() - start < max_wait_s:
            if other is None or other >= QUIET:
                time.sleep(0.5)
            continue
        if b >= batches:
            if timing.contended and extra > 0:
                extra -= 1
                continue
            break
    return timing
