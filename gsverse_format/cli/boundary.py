"""The process boundary shared by the command-line tools: one place that turns what a command
raises into its one-line message and exit status.

Exit statuses: 0 success, 1 bad input (``GsverseError``, out of memory), 2 bad usage
(``UsageError``), 70 an internal error (a bug: one line with the exception's type;
``GSVERSE_DEBUG=1`` re-raises it for the traceback), 130 interrupted.
"""
from __future__ import annotations

import os
import sys
from typing import Callable

from ..errors import GsverseError, UsageError
from ..progress import Progress, silenced_warnings


def run_command(prog: str, label: str, progress: Progress, work: Callable[[], int], *,
                quiet: bool = False, interrupted: str = "interrupted") -> int:
    """Run ``work`` (which prints its own results and returns the exit status) with every
    warning silenced under ``quiet``; an exception becomes one line on stderr prefixed by
    ``prog`` (``label`` names the input when memory runs out) and its exit status."""
    try:
        with silenced_warnings(quiet):
            return work()
    except UsageError as exc:
        message, status = f"error: {exc}", 2
    except GsverseError as exc:
        message, status = f"error: {exc}", 1
    except MemoryError:
        message, status = f"error: {label}: out of memory", 1
    except KeyboardInterrupt:
        message, status = interrupted, 130
    except Exception as exc:  # a bug, not bad input: still one line; GSVERSE_DEBUG=1 shows it all
        if os.environ.get("GSVERSE_DEBUG"):
            progress.close()
            raise
        message = (f"internal error: {type(exc).__name__}: {exc} "
                   f"(set GSVERSE_DEBUG=1 for a traceback, and please report it)").replace("\n", " ")
        status = 70
    progress.close()
    print(f"{prog}: {message}", file=sys.stderr)
    return status
