"""How this copy of gsverse-format was installed, for install lines in error messages.

A dependency that cannot be imported (usd-core, whose ``pxr`` a broken or partial
installation can lack) is fixed by reinstalling the package the way it was installed:
``pip install -e <checkout>`` for an editable install from a checkout (pip's
``direct_url.json`` records ``dir_info.editable`` and the folder), ``pip install <folder>``
for one installed from a local folder, ``pip install gsverse-format`` otherwise (pip installs
the missing dependencies of a package that is already installed).
"""
from __future__ import annotations

import json
import shlex
from importlib import metadata
from urllib.parse import unquote, urlparse

__all__ = ["DISTRIBUTION", "reinstall_command", "missing_usd_core"]

#: The distribution name on package indexes.
DISTRIBUTION = "gsverse-format"


def _direct_url() -> dict | None:
    """pip's record of where the package came from (the first installed copy that has one:
    a checkout's own ``*.egg-info`` folder, found first from the checkout, has none)."""
    for dist in metadata.distributions(name=DISTRIBUTION):
        text = dist.read_text("direct_url.json")
        try:
            data = json.loads(text) if text else None
        except ValueError:
            continue
        if isinstance(data, dict):
            return data
    return None


def reinstall_command() -> str:
    """The pip command that reinstalls this package as it was installed (with its
    dependencies)."""
    direct = _direct_url()
    if direct is not None:
        url = urlparse(str(direct.get("url", "")))
        info = direct.get("dir_info")
        if url.scheme == "file" and isinstance(info, dict):
            folder = shlex.quote(unquote(url.path))
            return f"pip install -e {folder}" if info.get("editable") else f"pip install {folder}"
    return f"pip install {DISTRIBUTION}"


def _usd_requirement() -> str:
    """usd-core's requirement as the package's metadata states it (``usd-core>=26.3``)."""
    try:
        for req in metadata.requires(DISTRIBUTION) or ():
            name = req.split(";")[0].strip()
            if name.replace("_", "-").lower().startswith("usd-core") and "extra ==" not in req:
                return name.replace(" ", "")
    except metadata.PackageNotFoundError:
        pass
    return "usd-core"


def missing_usd_core() -> str:
    """The one-line message when ``pxr`` (usd-core) cannot be imported."""
    return (f"USD support needs usd-core, a dependency of {DISTRIBUTION} that cannot be "
            f"imported: reinstall the package ({reinstall_command()}) or "
            f"pip install '{_usd_requirement()}'")
