"""``gsverse-info FILE``: what a splat file holds — format, splat count, SH degree, bounds,
anchoring (profile, deformation, encoding), meshes and the size of each part.

Text by default (names read from the file escaped, as in every text report), ``--json`` for
machines (an error is then the JSON object of :func:`.boundary.json_error` on standard output
too, as for the other tools), ``-q`` for the first line only (the file, its format and size).
The flags shared by every command are those of :mod:`gsverse_format.cli.grammar`. A missing or
unreadable file is one line on standard error and exit status 1 (:mod:`.boundary`); bad usage
(an unknown file type included) exit status 2.
"""
from __future__ import annotations

import argparse
import json
import sys

from ..io.info import describe, format_text
from ..progress import Progress
from ..textsafe import safe_text
from .boundary import parse_args, run_command
from .grammar import Parser, add_json, add_quiet, add_version, require_input

PROG = "gsverse-info"


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog=PROG, description="Print what a splat file holds: format, splat count, SH degree, "
        "bounds, anchoring, meshes and the bytes of each part. Reads every input format of "
        "gsverse-convert (glTF/GLB, 3DGS PLY, USD, .splat, .ksplat, .spz, compressed PLY, "
        "SOG).")
    parser.add_argument("file", metavar="FILE", help="the file to describe")
    add_json(parser)
    add_quiet(parser, " (here: the first line, the file's format and size)")
    add_version(parser, PROG)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = parse_args(build_parser(), argv)
    progress = Progress(enabled=False)

    def work() -> int:
        require_input(args.file)
        info = describe(args.file)
        if args.json:
            print(json.dumps(info.as_dict(), indent=2))
            return 0
        # Names inside the file (primitives, meshes, generator) are escaped in text output.
        text = safe_text(format_text(info))
        print(text.splitlines()[0] if args.quiet and text else text)
        return 0

    return run_command(PROG, args.file, progress, work, quiet=args.quiet, json_errors=args.json)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
