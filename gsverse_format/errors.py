"""Error types.

Every error the toolkit raises for bad input is a :class:`GsverseError` whose
string form is one line: ``<file>: <cause>``. Command-line tools print that line
and exit non-zero without a traceback.
"""
from __future__ import annotations

import os


class GsverseError(Exception):
    """A problem with an input or output the user can fix.

    ``path`` names the file involved (may be ``None``), ``cause`` says what is
    wrong in one line.
    """

    def __init__(self, cause: str, path: str | os.PathLike | None = None):
        self.cause = " ".join(str(cause).split())
        self.path = None if path is None else os.fspath(path)
        super().__init__(str(self))

    def __str__(self) -> str:  # one line, always
        return f"{self.path}: {self.cause}" if self.path else self.cause

    def with_path(self, path: str | os.PathLike) -> "GsverseError":
        """Return a copy of this error naming ``path`` (if it names none yet)."""
        if self.path is None:
            return type(self)(self.cause, path)
        return self


class FormatError(GsverseError):
    """A file is malformed, truncated, inconsistent or uses an unsupported variant."""


class UsageError(GsverseError):
    """The caller asked for something that cannot be done (bad options or combination)."""


class BindingError(GsverseError):
    """Splats cannot be bound to the given mesh (e.g. the mesh has no usable triangles)."""


class OutputError(GsverseError):
    """An output cannot be written where asked: the operating system refused (permissions,
    a read-only or full file system, a file-size limit) or the path is a folder."""


class NonFiniteError(FormatError):
    """A reader met splat values that are not finite (NaN, infinity, beyond float32 once
    decoded, a zero rotation quaternion); ``gsverse-convert --drop-nonfinite`` drops such
    splats where the reader can keep them for it."""
