"""The row format of the issue catalogue.

Each group module (``issues_container``, ``issues_khr``, ``issues_anchor``, ``issues_usd``,
``issues_rig``, ``issues_compact``, ``issues_fit``, ``issues_input``) lists its codes as
``*_ENTRIES`` rows ``(code, severity name, group, trigger, pointer, fix)``, optionally
followed by :class:`Flags`. The rows are plain data that import nothing of the validator;
:mod:`.issues` turns every row into a :class:`.issues.CodeInfo` (the one conversion) and
assembles :data:`.issues.CATALOGUE` from them.
"""
from __future__ import annotations

from typing import TypedDict

from gsverse_format.codes import Code

__all__ = ["Flags", "Row", "UsdLocation"]


class Flags(TypedDict, total=False):
    """What a row adds to the defaults of :class:`.issues.CodeInfo`."""

    fatal: bool  # validation of the file stops after it
    unreadable: bool  # the file could not be validated at all (exit status 2)
    foreign_severity: str  # the severity name for foreign USD prims, when it differs


#: (code, severity name: ERROR, WARNING, INFO or HINT, group, trigger, pointer, fix[, flags])
Row = tuple[Code, str, str, str, str, str] | tuple[Code, str, str, str, str, str, Flags]

#: Where a code shared with glTF points in USD files, and its severity name for foreign USD
#: prims (None: the catalogue's severity).
UsdLocation = tuple[str, str | None]
