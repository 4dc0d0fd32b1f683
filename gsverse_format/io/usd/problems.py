"""What reading and checking a USD file reports: problems, where each primitive came from, and
the warning category of :func:`~gsverse_format.io.usd.read_usd`."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ...codes import Code
from ...model import SplatAsset

__all__ = ["UsdReadWarning", "UsdProblem", "UsdPrimInfo", "UsdInspection"]


class UsdReadWarning(UserWarning):
    """:func:`read_usd` replaced or skipped data (foreign files; see ``spec/usd.md`` §Reading)."""


@dataclass(frozen=True)
class UsdProblem:
    """One finding of :func:`check_usd`.

    ``severity`` is ``"error"`` (the file breaks a MUST of ``spec/usd.md`` or cannot be read as
    written) or ``"warning"`` (a SHOULD, or data a reader replaces). ``location`` is a USD path:
    a prim (``/Asset/splats``), a property (``/Asset/splats.gsverse:anchor:faceIndices``) or
    ``""`` for the stage's root layer. ``code`` is the issue code of the catalogue
    (:class:`~gsverse_format.codes.Code`); findings of OpenUSD's own validators have the code
    ``USD_VALIDATOR_ERROR`` or ``USD_VALIDATOR_WARNING`` and the validator's name in
    ``validator``.
    """

    severity: str
    location: str
    message: str
    code: Code
    validator: str = ""

    def __str__(self) -> str:
        where = f"{self.location}: " if self.location else ""
        tag = f"{self.code}: {self.validator}" if self.validator else str(self.code)
        return f"{self.severity}: {where}{self.message} [{tag}]"

    def to_json(self) -> dict[str, str]:
        """A JSON-able dict that :meth:`from_json` turns back into the problem."""
        return {"severity": self.severity, "location": self.location, "message": self.message,
                "code": self.code.value, "validator": self.validator}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> "UsdProblem":
        return cls(data["severity"], data["location"], data["message"], Code(data["code"]),
                   data.get("validator", ""))


@dataclass(frozen=True)
class UsdPrimInfo:
    """Where a primitive of :class:`UsdInspection` comes from: its splat prim, its anchor
    ``Mesh`` (None when static), and whether the prim applies a GsVerse API schema (else it
    is foreign data, to which the writer rules of spec/usd.md do not apply)."""

    path: str
    mesh_path: str | None
    gsverse: bool


@dataclass
class UsdInspection:
    """What :func:`inspect_usd` found in a USD file.

    ``problems`` as :func:`check_usd` returns them. ``asset`` holds the splat primitives that
    could be read (anchored prims with errors are left out), with orientations, scales,
    opacities and local orientations **as authored** (not normalized, made positive or
    clamped), converted to +Y up and metres like :func:`read_usd`. ``prims`` says where
    each primitive comes from.
    """

    problems: list[UsdProblem]
    asset: SplatAsset
    prims: list[UsdPrimInfo]
