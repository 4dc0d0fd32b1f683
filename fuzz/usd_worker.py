"""A long-lived child process that runs the USD targets of the fuzz harness.

usd-core can crash the process or exhaust its memory on corrupt files, which is why the
toolkit reads untrusted USD in a child interpreter (:mod:`gsverse_format.io.usd.isolation`).
Starting one interpreter per input costs about half a second, too slow for 10⁵ inputs, so the
harness keeps one child alive (with the same memory cap as the isolation child) and sends it
one request per input; when the USD library kills the child, the parent counts that input as
a refusal ("corrupt USD file: the USD library crashed reading it", as
:func:`~gsverse_format.io.usd.isolation.read_isolated` reports it) and starts a new child.

In the child, ``read_usd`` is :func:`~gsverse_format.io.usd.read_usd` in process and
``validate_usd`` is the whole validator (:func:`~gsverse_format.validators.validate.validate_file`)
with its USD inspection run in this same child instead of a grandchild. The outcome of each
target is classified here: ``ok``, ``refused`` (the toolkit's own error, running out of
memory, or a validator report with errors) or ``internal`` (any other exception, or an
``INTERNAL_ERROR`` finding) with its type and location.

Protocol: one JSON request per line on stdin, ``{"path": ..., "targets": [...]}``; one JSON
line per target on stdout, ``{"target", "outcome", "detail", "codes"}``, written as soon as
the target ends (so that a crash is attributed to the target that caused it). ``argv[1]``,
the parent's timeout per target, sets a backstop alarm that ends a worker whose parent is
gone.
"""
from __future__ import annotations

import json
import os
import signal
import sys
import traceback

__all__ = ["TARGETS", "main"]

#: The USD targets, in the order a request runs them.
TARGETS = ("read_usd", "validate_usd")


def _where(err: BaseException) -> str:
    frames = traceback.extract_tb(err.__traceback__)
    return f"{os.path.basename(frames[-1].filename)}:{frames[-1].lineno}" if frames else "?"


def main() -> None:  # pragma: no cover - runs in the child interpreter
    import functools

    import gsverse_format.io.usd as usd
    from gsverse_format.codes import Code
    from gsverse_format.errors import GsverseError
    from gsverse_format.validators.container import Options
    from gsverse_format.validators.validate import validate_file

    usd.inspect_usd = functools.partial(usd.inspect_usd, isolate=False)

    def read(path: str) -> tuple[str, str, list[str]]:
        usd.read_usd(path, isolate=False)
        return "ok", "", []

    def validate(path: str) -> tuple[str, str, list[str]]:
        report = validate_file(path, Options(max_bytes=64 * 2 ** 20))
        codes = sorted(c.value for c in report.codes())
        internal = [f for f in report.findings if f.code == Code.INTERNAL_ERROR]
        if internal:
            return "internal", f"validator INTERNAL_ERROR: {internal[0].message}", codes
        return ("refused" if report.exit_status else "ok"), "", codes

    run = {"read_usd": read, "validate_usd": validate}
    # A backstop for a worker left alone (its parent killed while the USD library loops): the
    # parent gives up on a target after its own timeout, well before this alarm.
    backstop = int(float(sys.argv[1]) * 3 + 30) if len(sys.argv) > 1 else 0
    out = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)  # whatever else writes to stdout (the USD library) cannot break the protocol
    for line in sys.stdin:
        request = json.loads(line)
        for target in request["targets"]:
            codes: list[str] = []
            if backstop and hasattr(signal, "alarm"):
                signal.alarm(backstop)
            try:
                outcome, detail, codes = run[target](request["path"])
            except GsverseError as err:
                outcome, detail = "refused", err.cause
            except MemoryError:
                outcome, detail = "refused", "not enough memory to read the asset"
            except Exception as err:  # the worker's boundary: anything else is the finding
                outcome = "internal"
                detail = f"{type(err).__name__}: {err} at {_where(err)}"[:400]
            out.write(json.dumps({"target": target, "outcome": outcome, "detail": detail,
                                  "codes": codes}) + "\n")
            out.flush()


if __name__ == "__main__":  # pragma: no cover
    main()
