"""The table of sources: each source module registers itself here (like meshio's formats).

A source is a tool whose output ``gsverse-convert`` reads (``--from NAME``). Its module calls
:func:`register_source` once, at its end, with

* ``load(input_path, mesh_path, options) -> SourceResult`` (:mod:`.base`), and
* ``detect(input_path, mesh_path) -> str | None``: the reason the inputs look like this source's
  output, or None. A detector answers only on positive evidence, something the layout or the
  values of this source's output have and others' do not (a file layout shared with plain
  3DGS PLYs is not enough), and its reason names that evidence. ``--from auto`` tries the
  sources by ascending ``priority`` and takes the first that answers; the plain ``3dgs``
  source answers always, last.

:mod:`gsverse_format.converters` imports every source module, so importing it fills the table.
Sources never import each other, nor this table's callers.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional

from gsverse_format.converters.base import SourceOptions, SourceResult
from gsverse_format.errors import UsageError

__all__ = ["Source", "SOURCES", "register_source", "get_source", "detect_source"]

Loader = Callable[[str, Optional[str], SourceOptions], SourceResult]
Detector = Callable[[str, Optional[str]], Optional[str]]


@dataclass(frozen=True)
class Source:
    """A registered source: its ``--from`` name, loader, detector and detection priority."""

    name: str
    load: Loader
    detect: Detector | None = None
    priority: int = 50


#: ``--from`` name -> source, in registration order (the order ``--help`` lists them).
SOURCES: dict[str, Source] = {}


def register_source(name: str, load: Loader, *, detect: Detector | None = None,
                    priority: int = 50) -> None:
    """Register a source (each source module calls this once)."""
    SOURCES[name] = Source(name, load, detect, priority)


def get_source(name: str) -> Source:
    """The source registered as ``name`` (:class:`UsageError` for an unknown name)."""
    try:
        return SOURCES[name]
    except KeyError:
        raise UsageError(f"unknown source {name!r}; use one of auto, "
                         f"{', '.join(SOURCES)}") from None


def detect_source(input_path: str, mesh_path: str | None) -> tuple[str, str]:
    """Guess the source from the inputs; returns (source, reason). Only unambiguous layouts
    are detected: everything else is plain ``3dgs`` (``--from`` overrides)."""
    for source in sorted(SOURCES.values(), key=lambda s: s.priority):
        reason = source.detect(input_path, mesh_path) if source.detect else None
        if reason is not None:
            return source.name, reason
    raise UsageError("no source recognises the input; name it with --from", input_path)
