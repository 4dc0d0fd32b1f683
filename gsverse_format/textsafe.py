"""Text from input files made safe to print on a terminal or in a CI log.

Names and values read from a file (glTF extension and attribute names, USD prim paths, file
names) reach the tools' text output. Printed raw, a crafted name could move the cursor or
recolour a terminal (escape sequences), start a new line that forges a report line, or start
a line with ``::`` that GitHub Actions reads as a workflow command (``::error file=...::``),
or ``##[`` / ``##vso[`` (older runners, Azure Pipelines). :func:`escape` writes every control
character (C0, DEL, C1), the Unicode line and paragraph separators and the bidirectional
overrides as visible ``\\xNN`` / ``\\uNNNN`` escapes (``\\n``, ``\\r``, ``\\t`` for the common
three); :func:`safe_line` also escapes a line start that a CI runner would take for a
command. JSON output needs neither: its strings are escaped by the JSON encoder.
"""
from __future__ import annotations

import re

__all__ = ["escape", "safe_line", "safe_text"]

_NAMED = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}
#: C0 controls, DEL, C1 controls, line/paragraph separators, bidirectional embeddings,
#: overrides and isolates.
_UNSAFE = re.compile("[\x00-\x1f\x7f-\x9f\u2028\u2029\u202a-\u202e\u2066-\u2069]")
#: Line starts that CI runners interpret (GitHub Actions ``::cmd``, ``##[cmd]``; Azure
#: ``##vso[``), after optional white space.
_COMMAND_START = re.compile(r"^(\s*)(::|##)")


def _code(match: re.Match[str]) -> str:
    c = match.group()
    if c in _NAMED:
        return _NAMED[c]
    n = ord(c)
    return f"\\x{n:02x}" if n < 0x100 else f"\\u{n:04x}"


def escape(text: object) -> str:
    """``str(text)`` with every control character written as a visible escape: the result is
    one line and moves no cursor."""
    return _UNSAFE.sub(_code, str(text))


def safe_line(line: object) -> str:
    """:func:`escape` ``line``, and escape its first character when it would start a CI
    workflow command (``::``, ``##``)."""
    text = escape(line)
    return _COMMAND_START.sub(lambda m: m.group(1) + f"\\x{ord(m.group(2)[0]):02x}"
                              + m.group(2)[1:], text, count=1)


def safe_text(text: str) -> str:
    """Each line of ``text`` (``\\n``-separated) through :func:`safe_line`; the line breaks
    themselves are kept."""
    return "\n".join(safe_line(line) for line in text.split("\n"))
