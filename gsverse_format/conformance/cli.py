"""``gsverse-conformance``: export the engine-plugin conformance suite, check a plugin's dumps.

    gsverse-conformance export DIR                 write the suite into DIR
    gsverse-conformance check DIR RESULTS          check the dumps and pictures in RESULTS (exit 1
                                                   on failure; --level numbers|render|all)
    gsverse-conformance dump DIR RESULTS           write the reference implementation's dumps

Every subcommand takes ``--json`` (its result as JSON on standard output; for ``check`` the
same as ``--format json``; an error too) and ``-q`` (nothing but errors; ``check``: its verdict
line), as every command does (:mod:`gsverse_format.cli.grammar`).

Exit codes: 0 success (every case passed), 1 a case failed or is missing, 2 usage error. Errors
are one line on stderr, never a traceback. See ``spec/conformance.md``.
"""
from __future__ import annotations

import argparse
import json
import sys

from ..errors import GsverseError, UsageError
from ..cli.boundary import json_error, parse_args
from ..cli.grammar import Parser, add_json, add_quiet, add_version

PROG = "gsverse-conformance"


def build_parser() -> argparse.ArgumentParser:
    p = Parser(
        prog=PROG, description="Conformance suite for engine plugins of "
        "GSVERSE_gaussian_splatting_mesh_anchor (see spec/conformance.md).")
    add_version(p, PROG)
    sub = p.add_subparsers(dest="command", required=True)
    e = sub.add_parser("export", help="write the suite (assets, poses, expected outputs)")
    e.add_argument("dir", help="output folder (new or empty, or a previous suite to replace)")
    c = sub.add_parser("check", help="check a plugin's result dumps against the suite")
    c.add_argument("dir", help="the suite folder")
    c.add_argument("results", help="the plugin's results folder (RESULTS/<case id>/...)")
    c.add_argument("--format", choices=("text", "json"), default=None,
                   help="report format (default: text; json is --json)")
    c.add_argument("--failures-only", action="store_true",
                   help="text report: list only cases that did not pass")
    c.add_argument("--level", choices=("numbers", "render", "all"), default="all",
                   help="numbers: the remap and invalid cases; render: the render cases (pictures "
                        "of the engine); all (default): both")
    d = sub.add_parser("dump", help="write the dumps of a library implementation, and the "
                                    "reference renderer's pictures of the render cases (the "
                                    "layout, for harness authors)")
    d.add_argument("dir", help="the suite folder")
    d.add_argument("results", help="output folder for the dumps")
    d.add_argument("--impl", choices=("numpy", "fast"), default="numpy",
                   help="numpy: the float64 reference; fast: the compiled float32 path")
    for sp in (e, c, d):
        add_json(sp, " (check: the same as --format json)" if sp is c else "")
        add_quiet(sp, " (check: its verdict line)" if sp is c else "")
    return p


def _say(args, text: str, result: dict) -> None:
    """A subcommand's result: ``result`` as JSON with ``--json``, else ``text`` unless
    ``-q``."""
    if args.json:
        print(json.dumps(result, indent=1))
    elif not args.quiet:
        print(text)


def _export(args) -> int:
    from .export import export_suite

    suite = export_suite(args.dir)
    counts = suite["counts"]
    _say(args, f"{PROG}: wrote {counts['remap']} remap cases, {counts.get('rig', 0)} rig cases, "
               f"{counts['invalid']} invalid cases "
               f"and {counts['render']} render cases to {args.dir}",
         {"command": "export", "dir": args.dir, "counts": counts})
    return 0


def _check(args) -> int:
    from .check import check_results, format_text

    if args.json and args.format == "text":
        raise UsageError("--json and --format text disagree: --json is --format json")
    report = check_results(args.dir, args.results, level=args.level)
    if args.json or args.format == "json":
        print(json.dumps(report.to_json(), indent=1))
    elif args.quiet:
        print(format_text(report, failures_only=True).splitlines()[-1])
    else:
        print(format_text(report, failures_only=args.failures_only))
    return 0 if report.ok else 1


def _dump(args) -> int:
    from .harness import FastPlugin, ReferencePlugin, run_plugin
    from .render_export import copy_reference_pictures

    if args.impl == "fast":
        from ..remapping.fast import numba_available

        backend = "numba" if numba_available() else "numpy"
        run_plugin(args.dir, args.results, lambda: FastPlugin(backend),
                   info={"name": FastPlugin.name, "backend": backend, "precision": "float32"})
    else:
        run_plugin(args.dir, args.results, ReferencePlugin,
                   info={"name": ReferencePlugin.name, "precision": "float64"})
    copied = copy_reference_pictures(args.dir, args.results)
    _say(args, f"{PROG}: wrote {args.impl} dumps to {args.results}, and the reference "
               f"renderer's pictures of {copied} render cases",
         {"command": "dump", "dir": args.dir, "results": args.results, "impl": args.impl,
          "render_pictures": copied})
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parse_args(parser, argv)
    try:
        return {"export": _export, "check": _check, "dump": _dump}[args.command](args)
    except GsverseError as err:
        status = 2 if type(err).__name__ == "UsageError" else 1
        return _error(args, str(err), status, "usage" if status == 2 else "input", err)
    except (OSError, ValueError, KeyError) as err:
        return _error(args, f"{type(err).__name__}: {err}", 1, "input", err)


def _error(args, message: str, status: int, kind: str, err: BaseException) -> int:
    """One line on stderr; with ``--json`` also the JSON error object on stdout."""
    print(f"{PROG}: error: {message}", file=sys.stderr)
    if args.json:
        print(json.dumps(json_error(kind, message, getattr(args, "dir", None), status, err),
                         indent=2))
    return status


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
