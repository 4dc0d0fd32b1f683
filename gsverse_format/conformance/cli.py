"""``gsverse-conformance``: export the engine-plugin conformance suite, check a plugin's dumps.

    gsverse-conformance export DIR                 write the suite into DIR
    gsverse-conformance check DIR RESULTS          check the dumps in RESULTS (exit 1 on failure)
    gsverse-conformance dump DIR RESULTS           write the reference implementation's dumps

Exit codes: 0 success (every case passed), 1 a case failed or is missing, 2 usage error. Errors
are one line on stderr, never a traceback. See ``spec/conformance.md``.
"""
from __future__ import annotations

import argparse
import json
import sys

from ..version import __version__
from ..errors import GsverseError

PROG = "gsverse-conformance"


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG, description="Conformance suite for engine plugins of "
        "GSVERSE_gaussian_splatting_mesh_anchor (see spec/conformance.md).")
    p.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    e = sub.add_parser("export", help="write the suite (assets, poses, expected outputs)")
    e.add_argument("dir", help="output folder (new or empty, or a previous suite to replace)")
    c = sub.add_parser("check", help="check a plugin's result dumps against the suite")
    c.add_argument("dir", help="the suite folder")
    c.add_argument("results", help="the plugin's results folder (RESULTS/<case id>/...)")
    c.add_argument("--format", choices=("text", "json"), default="text",
                   help="report format (default: text)")
    c.add_argument("--failures-only", action="store_true",
                   help="text report: list only cases that did not pass")
    d = sub.add_parser("dump", help="write the dumps of a library implementation (a reference "
                                    "for harness authors)")
    d.add_argument("dir", help="the suite folder")
    d.add_argument("results", help="output folder for the dumps")
    d.add_argument("--impl", choices=("numpy", "fast"), default="numpy",
                   help="numpy: the float64 reference; fast: the compiled float32 path")
    return p


def _export(args) -> int:
    from .export import export_suite

    suite = export_suite(args.dir)
    counts = suite["counts"]
    print(f"{PROG}: wrote {counts['remap']} remap cases and {counts['invalid']} invalid cases "
          f"to {args.dir}")
    return 0


def _check(args) -> int:
    from .check import check_results, format_text

    report = check_results(args.dir, args.results)
    if args.format == "json":
        print(json.dumps(report.to_json(), indent=1))
    else:
        print(format_text(report, failures_only=args.failures_only))
    return 0 if report.ok else 1


def _dump(args) -> int:
    from .harness import FastPlugin, ReferencePlugin, run_plugin

    if args.impl == "fast":
        from ..remap_fast import numba_available

        backend = "numba" if numba_available() else "numpy"
        run_plugin(args.dir, args.results, lambda: FastPlugin(backend),
                   info={"name": FastPlugin.name, "backend": backend, "precision": "float32"})
    else:
        run_plugin(args.dir, args.results, ReferencePlugin,
                   info={"name": ReferencePlugin.name, "precision": "float64"})
    print(f"{PROG}: wrote {args.impl} dumps to {args.results}")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return {"export": _export, "check": _check, "dump": _dump}[args.command](args)
    except GsverseError as err:
        print(f"{PROG}: error: {err}", file=sys.stderr)
        return 2 if type(err).__name__ == "UsageError" else 1
    except (OSError, ValueError, KeyError) as err:
        print(f"{PROG}: error: {type(err).__name__}: {err}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
