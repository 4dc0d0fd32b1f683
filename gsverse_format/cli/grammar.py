"""The grammar every ``gsverse-*`` command shares, written once.

Commands read ``TOOL INPUT OUTPUT`` (as splat-transform and gltf-transform do) and take the
same flags with the same meaning:

``-h``/``--help``
    the help, exit status 0.
``--version``
    ``<tool> <version>`` on standard output, exit status 0.
``--json``
    the result as one JSON document on standard output; an error too
    (``{"error": {...}, "input", "exit"}``, :func:`gsverse_format.cli.boundary.json_error`).
``-q``/``--quiet``
    no progress, summary or warnings: only errors (a command whose product is a report,
    ``gsverse-validate`` and ``gsverse-conformance check``, prints one verdict line per file or
    suite).
``-w``/``--overwrite``
    replace existing outputs; without it an existing output is refused (exit status 2) and left
    untouched.
``-o``/``--output PATH``
    the output, the same as the positional ``OUTPUT``: a file when ``PATH`` ends in one of the
    command's output suffixes, a folder when it names an existing folder, ends in ``/`` or has
    no suffix (for runs that write several files: a batch, one file per time). A path with any
    other suffix is refused (exit status 2) rather than made into a folder.

Exit statuses: 0 success, 1 bad input (a missing or unreadable input, one line naming it), 2
bad usage (one line ``<tool>: error: <message>``; no usage block), 70 internal error, 128 + the
signal's number when interrupted (:mod:`gsverse_format.cli.boundary`).
"""
from __future__ import annotations

import argparse
import os
from typing import Any, Iterable, NoReturn

from ..errors import FormatError, UsageError
from ..version import __version__

__all__ = ["Parser", "add_version", "add_json", "add_quiet", "add_overwrite", "add_output",
           "output_kind", "one_output", "require_input", "HELP_JSON", "HELP_QUIET",
           "HELP_OVERWRITE", "HELP_OUTPUT"]

HELP_JSON = ("print the result as JSON on standard output (an error too: {\"error\": ..., "
             "\"input\": ..., \"exit\": N})")
HELP_QUIET = "print nothing but errors: no progress, summary or warnings"
HELP_OVERWRITE = "replace existing outputs (default: refuse them, exit 2, nothing written)"
HELP_OUTPUT = "the output, the same as the positional OUT"


class Parser(argparse.ArgumentParser):
    """An :class:`argparse.ArgumentParser` whose usage errors are one line on standard error,
    ``<prog>: error: <message>``, exit status 2 (``--help`` shows the usage)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())}\n")


def add_version(p: argparse.ArgumentParser, prog: str) -> None:
    p.add_argument("--version", action="version", version=f"{prog} {__version__}",
                   help="print the version and exit")


def add_json(p: argparse.ArgumentParser | Any, more: str = "") -> None:
    p.add_argument("--json", action="store_true", help=HELP_JSON + more)


def add_quiet(p: argparse.ArgumentParser | Any, more: str = "") -> None:
    p.add_argument("-q", "--quiet", action="store_true", help=HELP_QUIET + more)


def add_overwrite(p: argparse.ArgumentParser | Any) -> None:
    p.add_argument("-w", "--overwrite", action="store_true", help=HELP_OVERWRITE)


def add_output(p: argparse.ArgumentParser | Any, metavar: str, more: str = "") -> None:
    p.add_argument("-o", "--output", metavar=metavar, help=HELP_OUTPUT + more)


def output_kind(path: str, suffixes: Iterable[str]) -> str | None:
    """``"file"`` when ``path`` ends in one of ``suffixes`` (``.glb`` ...), ``"folder"`` when
    it is an existing folder, ends in a path separator or has no suffix, else None (a name
    that is neither: refuse it rather than guess)."""
    if path.endswith(("/", os.sep)) or os.path.isdir(path):
        return "folder"
    ext = os.path.splitext(path)[1].lower()
    if ext in {s.lower() for s in suffixes}:
        return "file"
    return "folder" if not ext else None


def one_output(positional: str | None, option: str | None, what: str) -> str | None:
    """The output given as ``OUTPUT`` or as ``-o OUTPUT`` (both: the same path, else a
    :class:`UsageError`); None when neither is."""
    if positional is not None and option is not None and positional != option:
        raise UsageError(f"two outputs given ({positional} and -o {option}); give {what} "
                         "once, as OUTPUT or as -o OUTPUT")
    return positional if positional is not None else option


def require_input(path: str, what: str = "file") -> None:
    """A missing input is bad input (exit status 1), named: ``<path>: file not found``."""
    if path != "-" and not os.path.exists(path):
        raise FormatError(f"{what} not found", path)

