"""Findings, severities and the catalogue of every issue code ``gsverse-validate`` reports.

Reporting follows the Khronos glTF-Validator: every finding has a stable ``code``, a
``severity`` (error, warning, info, hint), a location (a JSON pointer into the glTF JSON, or a
byte ``offset`` into a GLB file) and a one-line ``message``. Findings about many splats or
triangles at once are aggregated: one finding with a ``count`` and a few ``examples``.

:data:`CATALOGUE` gives every code of :class:`gsverse_format.codes.Code` its severity, group,
trigger, location and fix; ``spec/validation.md`` is generated from it. The entries are written
by group, as rows (:mod:`.issues_rows`), in ``issues_container`` (the file, GLB, JSON, buffers,
accessors, the validator itself), ``issues_khr``, ``issues_anchor`` (the extension object, the
anchor mesh, the rest pose), ``issues_compact``, ``issues_rig``, ``issues_fit``,
``issues_physics``, ``issues_spz``, ``issues_input`` and ``issues_usd``; this module makes them entries, once for all.
"""
from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Any

from gsverse_format.codes import Code

from .issues_anchor import ANCHOR_ENTRIES
from .issues_compact import COMPACT_ENTRIES
from .issues_container import CONTAINER_ENTRIES, VALIDATOR_ENTRIES
from .issues_fit import FIT_ENTRIES, FIT_USD
from .issues_input import INPUT_ENTRIES
from .issues_khr import KHR_ENTRIES
from .issues_physics import PHYSICS_ENTRIES
from .issues_rig import RIG_ENTRIES
from .issues_rows import Flags, Row
from .issues_spz import SPZ_ENTRIES
from .issues_usd import USD_ENTRIES, USD_SHARED

__all__ = ["Severity", "CodeInfo", "CATALOGUE", "Finding", "Issues", "TOLERANCES",
           "parse_severity"]


class Severity(enum.IntEnum):
    """Severities, numbered as in the Khronos glTF-Validator (0 is the most severe)."""

    ERROR = 0
    WARNING = 1
    INFO = 2
    HINT = 3

    @property
    def label(self) -> str:
        return self.name.lower()


def parse_severity(text: str) -> Severity | None:
    """``error``/``warning``/``info``/``hint`` (or 0..3) -> :class:`Severity`; ``ignore`` ->
    ``None``. Raises ``ValueError`` for anything else."""
    word = str(text).strip().lower()
    if word in ("ignore", "off", "none"):
        return None
    aliases = {"information": "info", "err": "error", "warn": "warning"}
    word = aliases.get(word, word)
    for sev in Severity:
        if word in (sev.label, str(int(sev))):
            return sev
    raise ValueError(f"unknown severity {text!r}; use error, warning, info, hint or ignore")


@dataclass(frozen=True)
class CodeInfo:
    """One catalogue entry: what triggers the code, where it points, how to fix the asset."""

    code: Code
    severity: Severity
    group: str
    trigger: str
    pointer: str
    fix: str
    fatal: bool = False  # validation of the file stops after it
    unreadable: bool = False  # the file could not be validated at all (exit status 2)
    #: The default severity for foreign USD prims (no GsVerse API schema), when it differs.
    foreign_severity: Severity | None = None
    #: Where the code points in a USD file, for codes shared with glTF ("" if not reported).
    usd: str = ""


#: Numerical tolerances used by the checks (documented in ``spec/validation.md``).
TOLERANCES: dict[str, tuple[float, str]] = {
    "unit_quaternion": (1e-5, "| ‖q‖ − 1 | allowed for FLOAT quaternions (ROTATION, "
                              "localRotation); normalized-integer quaternions are allowed one "
                              "quantization step more (1/127 for BYTE, 1/32767 for SHORT)"),
    "simplex": (1e-5, "how far below 0 a barycentric weight b0 = 1 − b1 − b2, b1 or b2 of a "
                      "`games` splat may lie; normalized-integer barycentrics are allowed one "
                      "quantization step more (1/255 or 1/65535)"),
    "local_far": (1.0, "a `local` splat whose smallest barycentric weight is below −1 has its "
                       "foot point farther outside its triangle than the triangle's own "
                       "height over that edge"),
    "sliver": (1e-3, "a regular triangle is a sliver when its doubled area a ≤ 1e-3 · ℓ² "
                     "(smallest height ≤ 0.1 % of the longest edge)"),
    "rest_mean": (1e-5, "spec §Rest-pose consistency: |Δμ| ≤ 1e-5 · D + 8 ε₃₂ L, D the "
                        "diagonal of the anchor mesh's bounding box, L its largest absolute "
                        "coordinate, ε₃₂ = 2⁻²³ (float32 rounding far from the origin)"),
    "rest_covariance": (1e-4, "spec §Rest-pose consistency: ‖ΔΣ‖_F ≤ 1e-4 · ‖Σ‖_F, plus an "
                              "absolute floor of (1e-7 · D)² for covariances below float32 "
                              "resolution"),
}


#: Where the codes shared with glTF point in USD files, and their severity for foreign prims.
_USD_SHARED = {**USD_SHARED, **FIT_USD}


def _entry(row: Row) -> CodeInfo:
    """The catalogue entry of one row of a group module (:mod:`.issues_rows`): the USD codes
    point where their pattern says, the codes shared with glTF where :data:`_USD_SHARED` says."""
    code, severity, group, trigger, pointer, fix = row[:6]
    flags: Flags = row[6] if len(row) == 7 else {}
    usd, foreign = _USD_SHARED.get(code, (pointer if group == "USD" else "",
                                          flags.get("foreign_severity")))
    return CodeInfo(code, Severity[severity], group, trigger, pointer, fix,
                    fatal=flags.get("fatal", False), unreadable=flags.get("unreadable", False),
                    foreign_severity=None if foreign is None else Severity[foreign], usd=usd)


#: Every row, in catalogue order (the order of ``spec/validation.md`` and ``--list-codes``).
_ROWS: list[Row] = (CONTAINER_ENTRIES + KHR_ENTRIES + ANCHOR_ENTRIES + USD_ENTRIES
                    + VALIDATOR_ENTRIES + RIG_ENTRIES + COMPACT_ENTRIES + FIT_ENTRIES
                    + PHYSICS_ENTRIES + SPZ_ENTRIES + INPUT_ENTRIES)

#: Every code, in catalogue order.
CATALOGUE: dict[Code, CodeInfo] = {row[0]: _entry(row) for row in _ROWS}
assert len(CATALOGUE) == len(_ROWS), "duplicate issue code"


@dataclass
class Finding:
    """One reported issue. ``count``/``examples`` are set for aggregated per-element issues."""

    code: Code
    severity: Severity
    message: str
    pointer: str | None = None
    offset: int | None = None
    count: int | None = None
    examples: list[dict] | None = None

    def to_json(self, location_key: str = "pointer") -> dict:
        """The Khronos-style message object; ``location_key`` names the location member
        (``pointer`` for JSON pointers, ``usdPath`` for USD paths)."""
        out: dict[str, Any] = {"code": str(self.code), "severity": self.severity.label,
                               "message": self.message}
        for key, value in ((location_key, self.pointer), ("offset", self.offset),
                           ("count", self.count)):
            if value is not None:
                out[key] = value
        if self.examples:
            out["examples"] = self.examples
        return out


@dataclass
class Issues:
    """Collects the findings of one file, applying severity overrides and the issue cap.

    ``overrides`` maps a code to its new severity, or to ``None`` to ignore it. ``findings``
    are in the order found; :meth:`ordered` is the order of the reports. With ``max_issues``
    the most severe findings are kept (the first found within a severity), so that a capped
    report still counts the file's errors.
    """

    overrides: dict[Code, Severity | None] = field(default_factory=dict)
    max_issues: int | None = None
    findings: list[Finding] = field(default_factory=list)
    truncated: bool = False
    unreadable: bool = False
    #: Set while checking a foreign USD prim: codes with a ``foreign_severity`` default to it.
    foreign: bool = False

    def add(self, code: Code, message: str, *, pointer: str | None = None,
            offset: int | None = None, count: int | None = None,
            examples: list[dict] | None = None) -> None:
        """Record a finding of ``code`` (its severity: an override, else the catalogue's)."""
        info = CATALOGUE.get(code)
        if info is None:  # a code outside the catalogue is a bug of the validator itself
            message = f"[{code}] {message}"
            info = CATALOGUE[Code.INTERNAL_ERROR]
        code = info.code
        if info.unreadable:
            self.unreadable = True
        default = info.foreign_severity if self.foreign and info.foreign_severity is not None \
            else info.severity
        severity = self.overrides[code] if code in self.overrides else default
        if severity is None:
            return
        finding = Finding(code, Severity(severity), message, pointer, offset, count, examples)
        if self.max_issues is not None and len(self.findings) >= self.max_issues:
            self.truncated = True
            # full: the new finding replaces the last found of the least severe ones
            last = max(range(len(self.findings)),
                       key=lambda k: (self.findings[k].severity, k), default=None)
            if last is None or self.findings[last].severity <= finding.severity:
                return
            del self.findings[last]
        self.findings.append(finding)

    def ordered(self) -> list[Finding]:
        """The findings as the reports list them: errors, then warnings, infos and hints;
        in the order found within a severity."""
        return sorted(self.findings, key=lambda f: f.severity)

    def codes(self) -> set[Code]:
        return {f.code for f in self.findings}

    def count(self, severity: Severity) -> int:
        return sum(1 for f in self.findings if f.severity == severity)
