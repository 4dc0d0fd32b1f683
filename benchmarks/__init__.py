"""Benchmarks: reproducible timings of the package against other tools, run as modules.

They measure the installed package, editable or not. ``python -m benchmarks`` run from a
checkout puts the checkout first on ``sys.path``, where ``gsverse_format/`` is the source
folder alone: a regular install maps ``converters/`` and ``validators/`` into it as
``gsverse_format.converters`` and ``gsverse_format.validators`` (``pyproject.toml``), which
the folder lacks. So importing this package takes the checkout off ``sys.path`` when
``gsverse_format`` can be imported without it (the ``benchmarks`` modules are found through
the package itself), and child processes get :func:`child_env`.
"""
from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

#: The checkout that holds this folder.
CHECKOUT = Path(__file__).resolve().parents[1]


def _in_checkout(entry: str) -> bool:
    try:
        return Path(entry or os.getcwd()).resolve() == CHECKOUT
    except OSError:
        return False


def _use_installed_package() -> None:
    if "gsverse_format" in sys.modules:
        return
    kept = [entry for entry in sys.path if not _in_checkout(entry)]
    if len(kept) == len(sys.path):
        return
    saved = sys.path[:]
    sys.path[:] = kept
    if importlib.util.find_spec("gsverse_format") is None:
        sys.path[:] = saved   # not installed: the checkout's folder is all there is


def child_env(*, benchmarks: bool = False) -> dict[str, str]:
    """The environment of a child Python process that imports the package: its working
    folder never goes on ``sys.path`` (``PYTHONSAFEPATH``), and the checkout goes on
    ``PYTHONPATH`` only for a child that runs a ``benchmarks`` module (which takes it off
    again, above)."""
    env = dict(os.environ)
    env["PYTHONSAFEPATH"] = "1"
    paths = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p and not _in_checkout(p)]
    if benchmarks:
        paths.insert(0, str(CHECKOUT))
    if paths:
        env["PYTHONPATH"] = os.pathsep.join(paths)
    else:
        env.pop("PYTHONPATH", None)
    return env


_use_installed_package()
