"""Rendering reports: a human-readable text form and a JSON form modelled on the Khronos
glTF-Validator's (``issues.numErrors`` ... ``issues.messages[]`` with ``code``, ``severity``,
``pointer`` or ``offset``, ``message``; plus ``count`` and ``examples`` for aggregated
findings). Severities are written as words: ``error``, ``warning``, ``info``, ``hint``.
"""
from __future__ import annotations

import json
from typing import Iterable

from gsverse_format.textsafe import safe_line
from gsverse_format.version import __version__

from .issues import CATALOGUE, Finding, Severity
from .validate import VALIDATOR_NAME, Report

__all__ = ["render_text", "render_json", "render_catalogue"]


def _plural(n: int, word: str) -> str:
    return f"{n} {word}" + ("" if n == 1 else "s")


def _example(item: dict) -> str:
    def fmt(v):
        if isinstance(v, float):
            return f"{v:.4g}"
        if isinstance(v, list):
            return "(" + ", ".join(fmt(x) for x in v) + ")"
        return str(v)
    return " ".join(f"{k}={fmt(v)}" for k, v in item.items())


def _finding(f: Finding) -> str:
    where = f.pointer if f.pointer is not None else (f"@{f.offset}" if f.offset is not None
                                                     else "")
    where = where if where != "" or f.pointer is None else '""'
    line = f"  {f.severity.label:<8} {f.code}"
    if where:
        line += f" {where}"
    line += f": {f.message}"
    if f.examples:
        shown = "; ".join(_example(e) for e in f.examples[:3])
        more = "; ..." if len(f.examples) > 3 or (f.count or 0) > 3 else ""
        line += f" [e.g. {shown}{more}]"
    return line


def render_text(reports: Iterable[Report], *, quiet: bool = False) -> str:
    """One summary line per file, then (unless ``quiet``) one line per finding, errors first
    (:meth:`~.validate.Report.ordered_findings`). Names and
    values from the file are escaped (:func:`~gsverse_format.textsafe.safe_line`): control
    characters become visible escapes and no line starts a CI workflow command."""
    lines = []
    for r in reports:
        counts = ", ".join([_plural(r.count(Severity.ERROR), "error"),
                            _plural(r.count(Severity.WARNING), "warning"),
                            _plural(r.count(Severity.INFO), "info"),
                            _plural(r.count(Severity.HINT), "hint")])
        extra = []
        if r.info.get("splatPrimitives"):
            extra.append(f"{r.info.get('splats', 0)} splats in {r.info['splatPrimitives']} "
                         f"primitive(s), {r.info.get('anchoredPrimitives', 0)} anchored")
        if r.issues.truncated:
            extra.append("report truncated (--max-issues)")
        lines.append(f"{r.path}: {counts}" + (f" ({'; '.join(extra)})" if extra else ""))
        if not quiet:
            lines.extend(_finding(f) for f in r.ordered_findings())
    return "\n".join(map(safe_line, lines)) + ("\n" if lines else "")


def render_json(reports: Iterable[Report]) -> str:
    """``{"validator", "validatorVersion", "reports": [...]}`` as indented JSON."""
    out = {"validator": VALIDATOR_NAME, "validatorVersion": __version__,
           "reports": [r.to_json() for r in reports]}
    return json.dumps(out, indent=2, ensure_ascii=False, allow_nan=False) + "\n"


def render_catalogue(as_json: bool = False) -> str:
    """Every issue code with its default severity (``--list-codes``)."""
    if as_json:
        return json.dumps([{"code": c.code, "severity": c.severity.label, "group": c.group,
                            "trigger": c.trigger, "pointer": c.pointer, "fix": c.fix}
                           for c in CATALOGUE.values()], indent=2, ensure_ascii=False) + "\n"
    width = max(len(c) for c in CATALOGUE)
    return "".join(f"{c.code:<{width}}  {c.severity.label:<8} {c.group}\n"
                   for c in CATALOGUE.values())
