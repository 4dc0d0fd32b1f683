"""Compile the package's numba kernels into numba's on-disk cache before their first use.

    python -m gsverse_format.precompile [--jobs N] [--quiet | --json]

The compiled paths (the per-frame remap, the CPU renderer, and the numba nearest-triangle
search, which binding uses where the C search of :mod:`gsverse_format.nearest.native` was not
built) are numba kernels cached on disk (``cache=True``: in ``__pycache__`` beside each
module, or under ``NUMBA_CACHE_DIR``; a folder that cannot be written falls back to numba's
per-user cache). Nothing numba compiles ships with the package, because its machine code is
specific to the CPU and the numba version. Without this step the first job of a size that
takes the compiled path compiles what it uses there and then: about 15 s for the numba search
of a 100k-splat conversion on a 2-core machine, where the conversion itself takes about 1.5 s.
This command does that once, at install time (the README's set-up runs it), so that the first
real job runs as fast as later ones.

Each group of kernels runs the package's own entry points on a tiny problem with the numba
backend forced, so that the signatures compiled are those real jobs use (the tests check that
a conversion, a validation, a pose and a render after this command compile nothing):

* ``nearest``: :func:`gsverse_format.binding.bind_local` (the numba search and its BVH);
* ``remap-sorted-local``, ``remap-sorted-games`` and ``remap-unsorted``:
  :class:`gsverse_format.remapping.fast.FastRemapper` for the ``local`` profile under both
  laws, with and without rotations, and ``games``, on float32 and float64 vertices, with the
  splats sorted by face (as assets store them: the kernels over runs of one face; one group a
  profile, the longest two) and not (the per-splat kernels);
* ``render``: :func:`gsverse_format.render.render_gaussians`.

The groups compile in separate processes, ``--jobs`` at a time (default: the CPU count, at
most the five groups). Run again, it loads every kernel from the cache and compiles nothing;
after numba or the package changes it compiles what changed. Exit status 0 when every group
finished, 1 otherwise (numba cannot be imported, or the cache cannot be written: the message
says which).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from typing import Any, Callable

import numpy as np

__all__ = ["GROUPS", "compile_group", "main"]


def _mesh_and_splats(n_splats: int = 64) -> tuple[Any, Any]:
    """A closed tetrahedron-like mesh (a bumpy octahedron) and splats near its faces."""
    from .model import SplatCloud, TriangleMesh

    v = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1.2], [0, 0, -1]],
                 np.float32)
    f = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4],
                  [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]], np.uint32)
    rng = np.random.default_rng(0)
    means = (rng.normal(size=(n_splats, 3)) * 0.5).astype(np.float32)
    rot = rng.normal(size=(n_splats, 4)).astype(np.float32)
    rot /= np.linalg.norm(rot, axis=1, keepdims=True)
    scales = rng.uniform(0.01, 0.05, (n_splats, 3)).astype(np.float32)
    opac = rng.uniform(0.2, 0.9, n_splats).astype(np.float32)
    sh = rng.normal(0, 0.2, (n_splats, 16, 3)).astype(np.float32)
    return TriangleMesh(v, f), SplatCloud(means, rot, scales, opac, sh)


def _nearest() -> None:
    from .binding import bind_local

    mesh, splats = _mesh_and_splats()
    bind_local(splats, mesh)


def _remap(sorted_by_face: bool, profiles: tuple[str, ...] = ("local", "games")) -> None:
    from dataclasses import replace

    from .backend import set_backend
    from .binding import bind_local
    from .model import Anchoring, GamesAnchors
    from .remapping.fast import FastRemapper

    mesh, splats = _mesh_and_splats()
    set_backend("numpy")     # the anchors only: the search's kernels are the nearest group's
    try:
        bound = bind_local(splats, mesh).anchors
    finally:
        set_backend("numba")
    if sorted_by_face:   # as assets store them: the kernels over runs of one face
        bound = bound.subset(np.argsort(bound.face_index, kind="stable"))
    n = len(bound)
    games = GamesAnchors(bound.face_index, np.full((n, 2), 1 / 3, np.float32),
                         np.full(n, 0.05, np.float32))
    deformed = mesh.vertices * np.float32(1.1)
    every = ([bound, replace(bound, deformation="rigid")] if "local" in profiles else []) + (
        [games] if "games" in profiles else [])
    for anchors in every:
        for rotations in (False, True):
            remapper = FastRemapper(Anchoring(mesh, anchors), rotations=rotations)
            for vertices in (deformed, deformed.astype(np.float64)):
                remapper.remap(vertices)


def _render() -> None:
    from .render import look_at, render_gaussians

    _, splats = _mesh_and_splats()
    camera = look_at((0, 0, 4), (0, 0, 0), width=32, height=32)
    render_gaussians(splats.means, splats.covariances(), splats.opacities, splats.sh, camera)


#: Group name -> what it runs (each compiles the kernels that entry point uses). Groups start in
#: this order as processes free up, the longest first. Measured on 2 cores, both busy: the
#: sorted ``local`` kernels (vectorised loops, both laws, float32 and float64 vertices) 40 s,
#: the per-splat kernels 21 s, the sorted ``games`` kernels 17 s, the search 13 s, the
#: renderer 7 s; about 55 s in all.
GROUPS: dict[str, Callable[[], None]] = {
    "remap-sorted-local": lambda: _remap(True, ("local",)),
    "nearest": _nearest,
    "remap-unsorted": lambda: _remap(False),
    "remap-sorted-games": lambda: _remap(True, ("games",)),
    "render": _render,
}


def _dispatchers() -> list[Any]:
    """Every numba dispatcher of the package's compiled modules that are imported."""
    from numba.core.registry import CPUDispatcher

    found = []
    for name, module in list(sys.modules.items()):
        if name.startswith("gsverse_format.") and module is not None:
            for value in vars(module).values():
                if isinstance(value, CPUDispatcher) and value not in found:
                    found.append(value)
    return found


def compile_group(name: str) -> dict[str, Any]:
    """Run group ``name`` in this process with the numba backend forced; returns its seconds
    and the kernels it compiled (cache misses) and loaded (cache hits)."""
    from .backend import set_backend

    set_backend("numba")
    t0 = time.perf_counter()
    GROUPS[name]()
    seconds = time.perf_counter() - t0
    compiled = loaded = 0
    for dispatcher in _dispatchers():
        stats = dispatcher.stats
        compiled += sum(stats.cache_misses.values())
        loaded += sum(stats.cache_hits.values())
    return {"group": name, "seconds": round(seconds, 2), "compiled": compiled,
            "loaded": loaded}


def _run_groups(jobs: int, report: Callable[[str], None]) -> list[dict[str, Any]]:
    """Each group in its own process, ``jobs`` at a time, in the order of :data:`GROUPS`; a
    process that ends frees its slot for the next group at once (results in the order the
    groups finish)."""
    from concurrent.futures import ThreadPoolExecutor, as_completed

    def run(name: str) -> dict[str, Any]:
        proc = subprocess.run([sys.executable, "-m", "gsverse_format.precompile", "--group", name],
                              capture_output=True, text=True)
        if proc.returncode == 0:
            result: dict[str, Any] = json.loads(proc.stdout.strip().splitlines()[-1])
            return result
        lines = [line for line in proc.stderr.strip().splitlines() if line.strip()]
        return {"group": name, "error": lines[-1] if lines else f"exit {proc.returncode}"}

    results: list[dict[str, Any]] = []
    with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        futures = []
        for name in GROUPS:           # submitted in order: a free worker takes the next one
            futures.append(pool.submit(run, name))
        started = min(max(1, jobs), len(futures))
        for name in list(GROUPS)[:started]:
            report(f"compiling {name} ...")
        names = list(GROUPS)
        for future in as_completed(futures):
            result = future.result()
            results.append(result)
            report(_line(result))
            if started < len(names):
                report(f"compiling {names[started]} ...")
                started += 1
    return results


def _line(result: dict[str, Any]) -> str:
    if "error" in result:
        return f"{result['group']}: failed: {result['error']}"
    return (f"{result['group']}: {result['compiled']} kernels compiled, {result['loaded']} "
            f"loaded from the cache, {result['seconds']:.1f} s")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m gsverse_format.precompile",
                                description=(__doc__ or "").splitlines()[0])
    p.add_argument("--jobs", type=int, default=min(len(GROUPS), os.cpu_count() or 1),
                   help="groups compiled at once, each in its own process (default: the CPU "
                        "count, at most %(default)s)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    g.add_argument("--json", action="store_true", help="one JSON object on standard output")
    p.add_argument("--group", choices=list(GROUPS), help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.group is not None:   # a worker: one group, its result as JSON
        print(json.dumps(compile_group(args.group)))
        return 0
    from .backend import numba_unavailable_reason

    reason = numba_unavailable_reason()
    if reason is not None:
        print(f"gsverse-format precompile: numba cannot be imported: {reason}", file=sys.stderr)
        return 1
    t0 = time.perf_counter()
    quiet = args.quiet or args.json
    results = _run_groups(max(1, args.jobs),
                          (lambda _: None) if quiet else (lambda m: print(m, flush=True)))
    failed = [r for r in results if "error" in r]
    if args.json:
        print(json.dumps({"groups": results, "seconds": round(time.perf_counter() - t0, 2),
                          "ok": not failed}))
    else:
        for r in failed:
            print(f"gsverse-format precompile: {_line(r)}", file=sys.stderr)
        if not args.quiet:
            print(f"done in {time.perf_counter() - t0:.1f} s")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
