"""``gsverse-validate FILE...``: validate glTF/GLB and USD splat assets.

The flags shared by every command (``--json``, ``-q``, ``--version``) are those of
:mod:`gsverse_format.cli.grammar`: ``--json`` is ``--format json`` (the report, or a usage
error, as JSON on standard output), ``-q`` prints one verdict line per file. Bad usage is one
line on standard error, exit status 2.

Exit status: 0 when no file has errors, 1 when some file has errors, 2 for bad usage, a file
that could not be read at all (missing, not glTF or USD, unreadable: also one line
``gsverse-validate: error: FILE: <cause>`` on standard error, beside its report), or a closed
standard output (``>&-``: the report has nowhere to go; one line on stderr, nothing
validated); 141 when the reader of standard output goes away
(``| head -1``), as if killed by SIGPIPE, without a message; 130 on Ctrl-C, 143 on SIGTERM, 129
on SIGHUP (a USD file being checked in a child process: the child is stopped and its
temporary folder removed). Severities can be raised, lowered or ignored per code
(``--severity CODE=LEVEL``, ``--ignore CODE``, or a ``--config`` JSON file in the style of the
Khronos glTF-Validator: ``{"severityOverrides": {"CODE": "warning"}, "ignoredIssues": [...],
"maxIssues": 100}``); sizes are capped with ``--max-bytes``, ``--max-data-uri-bytes`` and
``--max-splats``. Codes are documented in ``spec/validation.md``.
"""
from __future__ import annotations

import argparse
import difflib
import json
import re
import signal
import sys

from gsverse_format.textsafe import escape
from gsverse_format.cli.boundary import (EXIT_SIGPIPE, Interrupted, interrupting_signals,
                                         json_error, parse_args, quiet_broken_stdout)
from gsverse_format.cli.grammar import Parser, add_json, add_quiet, add_version
from gsverse_format.codes import Code

from .container import Options
from .issues import CATALOGUE, Severity, parse_severity
from .report import render_catalogue, render_json, render_text
from .validate import VALIDATOR_NAME, validate_file

__all__ = ["main", "build_parser"]

_SIZE = re.compile(r"^\s*(\d+)\s*([kmgt]?)(i?b?)\s*$", re.IGNORECASE)


class _Usage(Exception):
    pass


def parse_size(text: str) -> int:
    """``123``, ``64k``, ``512M``, ``2G``, ``1GiB`` -> bytes (binary multiples)."""
    m = _SIZE.match(str(text))
    if not m:
        raise argparse.ArgumentTypeError(f"not a size: {text!r} (examples: 1000000, 512M, 2G)")
    return int(m.group(1)) * 1024 ** " kmgt".index(m.group(2).lower() or " ")


def _count(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {value}")
    return value


def build_parser() -> argparse.ArgumentParser:
    p = Parser(
        prog=VALIDATOR_NAME,
        description="Validate mesh-anchored Gaussian splat assets (.glb, .gltf; .usda, .usdc, "
                    ".usd, .usdz): container, KHR_gaussian_splatting, "
                    "GSVERSE_gaussian_splatting_mesh_anchor or its USD schema, anchor mesh and "
                    "rest-pose consistency. Exit status 0: no errors, 1: errors, 2: bad usage "
                    "or unreadable file.")
    p.add_argument("files", nargs="*", metavar="FILE", help=".glb, .gltf or USD files")
    p.add_argument("--format", choices=("text", "json"), default=None,
                   help="report format (default: text; json is --json)")
    add_json(p, " (the same as --format json)")
    add_quiet(p, " (here: one verdict line per file, without the findings)")
    p.add_argument("--severity", action="append", default=[], metavar="CODE=LEVEL",
                   help="override a code's severity: error, warning, info, hint or ignore "
                        "(repeatable)")
    p.add_argument("--ignore", action="append", default=[], metavar="CODE",
                   help="do not report CODE (repeatable)")
    p.add_argument("--config", metavar="FILE",
                   help='JSON file: {"severityOverrides": {CODE: LEVEL}, "ignoredIssues": '
                        '[CODE...], "maxIssues": N}')
    p.add_argument("--max-issues", type=_count, metavar="N",
                   help="report at most N findings per file (default and 0: all)")
    p.add_argument("--max-examples", type=_count, default=5, metavar="N",
                   help="examples listed per aggregated finding (default: 5)")
    p.add_argument("--max-bytes", type=parse_size, metavar="SIZE",
                   help="cap on the file plus the buffers it loads (USD: the file; default: 8G)")
    p.add_argument("--max-data-uri-bytes", type=parse_size, metavar="SIZE",
                   help="cap on each decoded data: URI (default: 256M)")
    p.add_argument("--max-splats", type=_count, metavar="N",
                   help="do not read primitives with more than N splats (default: no cap)")
    p.add_argument("--list-codes", action="store_true",
                   help="print every issue code with its default severity and exit")
    add_version(p, VALIDATOR_NAME)
    return p


def _code(name: str, where: str) -> Code:
    code = str(name).strip().upper()
    if code not in CATALOGUE:
        close = difflib.get_close_matches(code, [str(c) for c in CATALOGUE], n=1)
        hint = f" (did you mean {close[0]}?)" if close else " (see --list-codes)"
        raise _Usage(f"{where}: unknown issue code {name!r}{hint}")
    return Code(code)


def _overrides(args: argparse.Namespace) -> tuple[dict[Code, Severity | None], int | None]:
    overrides: dict[Code, Severity | None] = {}
    max_issues = args.max_issues or None  # 0 = no cap, as in the Khronos validator
    if args.config:
        try:
            with open(args.config, encoding="utf-8") as handle:
                config = json.load(handle)
        except (OSError, ValueError) as err:
            raise _Usage(f"--config {args.config}: cannot read: {err}") from None
        if not isinstance(config, dict):
            raise _Usage(f"--config {args.config}: must hold a JSON object")
        unknown = set(config) - {"severityOverrides", "ignoredIssues", "maxIssues"}
        if unknown:
            raise _Usage(f"--config {args.config}: unknown key(s) {', '.join(sorted(unknown))}")
        sev = config.get("severityOverrides", {})
        ignored = config.get("ignoredIssues", [])
        if not isinstance(sev, dict) or not isinstance(ignored, list):
            raise _Usage(f"--config {args.config}: severityOverrides must be an object and "
                         f"ignoredIssues an array")
        for code, level in sev.items():
            try:
                overrides[_code(code, "--config")] = parse_severity(level)
            except ValueError as err:
                raise _Usage(f"--config {args.config}: {code}: {err}") from None
        for code in ignored:
            overrides[_code(code, "--config")] = None
        if "maxIssues" in config and max_issues is None:
            value = config["maxIssues"]
            if not isinstance(value, int) or isinstance(value, bool) or value < 0:
                raise _Usage(f"--config {args.config}: maxIssues must be an integer >= 0")
            max_issues = value or None
    for item in args.severity:
        if "=" not in item:
            raise _Usage(f"--severity {item!r}: expected CODE=LEVEL")
        code, level = item.split("=", 1)
        try:
            overrides[_code(code, "--severity")] = parse_severity(level)
        except ValueError as err:
            raise _Usage(f"--severity {item!r}: {err}") from None
    for code in args.ignore:
        overrides[_code(code, "--ignore")] = None
    return overrides, max_issues


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status.

    Each file's problems, including an unexpected exception while checking it, are reported
    in its report (INTERNAL_ERROR); an unexpected exception outside the checks is one line on
    stderr naming its type, with exit status 2.
    """
    try:
        with interrupting_signals():
            return _main(argv)
    except BrokenPipeError:  # "| head": the reader has what it wanted
        quiet_broken_stdout()
        return EXIT_SIGPIPE
    except KeyboardInterrupt as exc:  # Ctrl-C, SIGTERM, SIGHUP
        _say("interrupted")
        return 128 + (exc.signum if isinstance(exc, Interrupted) else signal.SIGINT)
    except Exception as err:  # process boundary: a bug, reported as one, never as bad input
        _say(f"internal error: {type(err).__name__}: {err}")
        return 2


def _say(message: str) -> None:
    """One line on stderr (when there is a stderr)."""
    if sys.stderr is not None:
        sys.stderr.write(f"{VALIDATOR_NAME}: {escape(' '.join(message.split()))}\n")


def _usage(err: _Usage, as_json: bool) -> int:
    """A usage error found after parsing: one line on stderr (with ``--json`` also the JSON
    error object on stdout, as every command prints it); exit status 2."""
    sys.stderr.write(f"{VALIDATOR_NAME}: error: {escape(' '.join(str(err).split()))}\n")
    if as_json and sys.stdout is not None:
        sys.stdout.write(json.dumps(json_error("usage", str(err), None, 2), indent=2) + "\n")
    return 2


def _main(argv: list[str] | None) -> int:
    parser = build_parser()
    try:
        args = parse_args(parser, argv)
    except SystemExit as exc:  # argparse exits 2 on bad usage, 0 on --help/--version
        return int(exc.code or 0)
    out = sys.stdout
    if out is None:
        _say("error: standard output is closed: the report has nowhere to go")
        return 2
    if args.json and args.format == "text":
        return _usage(_Usage("--json and --format text disagree: --json is --format json"),
                      True)
    as_json = args.json or args.format == "json"
    if args.list_codes:
        out.write(render_catalogue(as_json=as_json))
        return 0
    try:
        if not args.files:
            raise _Usage("no files given")
        overrides, max_issues = _overrides(args)
    except _Usage as err:
        return _usage(err, as_json)
    options = Options(max_examples=args.max_examples, max_splats=args.max_splats,
                      max_data_uri_bytes=args.max_data_uri_bytes)
    if args.max_bytes is not None:
        options.max_bytes = args.max_bytes
    reports = [validate_file(path, options, overrides=overrides, max_issues=max_issues)
               for path in args.files]
    for report in reports:
        if report.issues.unreadable:    # the report says why too; stderr names the file
            fatal = next((f for f in report.findings if f.severity == Severity.ERROR), None)
            _say(f"error: {report.path}: {fatal.message if fatal else 'cannot be read'}")
    if as_json:
        out.write(render_json(reports))
    else:
        out.write(render_text(reports, quiet=args.quiet))
    out.flush()
    return max((r.exit_status for r in reports), default=0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
