"""``gsverse-info FILE``: what a splat file holds — format, splat count, SH degree, bounds,
anchoring (profile, deformation, encoding), meshes and the size of each part.

Text by default (names read from the file escaped, as in every text report), ``--json`` for
machines (an error is then the JSON object of :func:`.boundary.json_error` on standard output
too, as for the other tools). Bad input is one line on standard error and exit status 1 (:mod:`.boundary`).
"""
from __future__ import annotations

import argparse
import json
import sys

from ..io.info import describe, format_text
from ..progress import Progress
from ..textsafe import safe_text
from ..version import __version__
from .boundary import run_command

PROG = "gsverse-info"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG, description="Print what a splat file holds: format, splat count, SH degree, "
        "bounds, anchoring, meshes and the bytes of each part. Reads every input format of "
        "gsverse-convert (glTF/GLB, 3DGS PLY, USD, .splat, .ksplat, .spz, compressed PLY, "
        "SOG).")
    parser.add_argument("file", help="the file to describe")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")
    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    progress = Progress(enabled=False)

    def work() -> int:
        info = describe(args.file)
        # Names inside the file (primitives, meshes, generator) are escaped in text output.
        print(json.dumps(info.as_dict(), indent=2) if args.json else safe_text(format_text(info)))
        return 0

    return run_command(PROG, args.file, progress, work, json_errors=args.json)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
