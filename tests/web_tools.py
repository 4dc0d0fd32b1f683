"""Running the web plugin (``plugins/web``) and its demo (``examples/web``) from the tests.

The plugin is an npm package: ``npm ci`` in ``plugins/web`` installs the engine (PlayCanvas),
the physics engine of the demo (jolt-physics), playwright-core and TypeScript. The browser runs
are headless Debian Chromium (``/usr/bin/chromium``, or ``GSVERSE_CHROMIUM``) on its software
WebGL2 rasterizer. :func:`require_web_tools` skips a test when any of that is missing, or fails
it when ``GSVERSE_REQUIRE_NODE_TOOLS=1`` (set by CI after installing them).
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
WEB = ROOT / "plugins" / "web"
DEMO = ROOT / "examples" / "web"
_PACKAGES = ("playcanvas", "playwright-core", "jolt-physics", "typescript")


def chromium() -> str | None:
    """The Chromium executable the browser runs use, or None."""
    path = os.environ.get("GSVERSE_CHROMIUM", "/usr/bin/chromium")
    return path if os.path.isfile(path) and os.access(path, os.X_OK) else None


def missing_web_tools(*, browser: bool, packages: tuple[str, ...] = ()) -> str | None:
    """Why the web tools (and the extra npm ``packages``) cannot run here, or None when they can."""
    if shutil.which("node") is None:
        return "node is not on PATH"
    modules = WEB / "node_modules"
    absent = [p for p in (*_PACKAGES, *packages) if not (modules / p / "package.json").is_file()]
    if absent:
        return f"npm packages missing in {WEB} ({', '.join(absent)}): run 'npm ci' there"
    if browser and chromium() is None:
        return "Chromium not found at /usr/bin/chromium (apt-get install chromium)"
    return None


def require_web_tools(*, browser: bool = False, packages: tuple[str, ...] = ()) -> None:
    """Skip (or, under ``GSVERSE_REQUIRE_NODE_TOOLS=1``, fail) when the web tools, or the extra
    npm ``packages`` of ``plugins/web`` a test needs, are missing."""
    import pytest

    reason = missing_web_tools(browser=browser, packages=packages)
    if reason is None:
        return
    if os.environ.get("GSVERSE_REQUIRE_NODE_TOOLS") == "1":
        pytest.fail(reason + "; required by GSVERSE_REQUIRE_NODE_TOOLS=1", pytrace=False)
    pytest.skip(reason)


def time_scale() -> float:
    """How much longer than on an idle machine the browser runs may take here: the one-minute
    load average per CPU core (``GSVERSE_TIME_SCALE`` when set), at least 1, at most 8. The
    time limits of the Node and browser runs are multiplied by it, and it is passed on to them,
    so a machine busy with other work is slower, not failing."""
    value = os.environ.get("GSVERSE_TIME_SCALE")
    try:
        scale = float(value) if value else os.getloadavg()[0] / max(1, os.cpu_count() or 1)
    except (ValueError, OSError):
        scale = 1.0
    return min(8.0, max(1.0, scale))


def run_node(args: list[str | os.PathLike], *, cwd: Path = WEB, timeout: float = 600.0,
             env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    """Run ``node ARGS...`` and return the finished process (output captured as text);
    ``timeout`` is for an idle machine and grows with :func:`time_scale`."""
    scale = time_scale()
    full_env = dict(os.environ, GSVERSE_TIME_SCALE=f"{scale:.2f}")
    browser = chromium()
    if browser is not None:  # the one executable every browser run of the tests uses
        full_env["GSVERSE_CHROMIUM"] = full_env["CHROMIUM"] = browser
    full_env.update(env or {})
    return subprocess.run(["node", *map(str, args)], cwd=cwd, env=full_env, capture_output=True,
                          text=True, timeout=timeout * scale, check=False)


def artifacts_dir(name: str) -> Path:
    """Where a test stores files a person looks at afterwards (``GSVERSE_ARTIFACTS`` or
    ``test-artifacts/`` in the repository), one folder per test."""
    base = Path(os.environ.get("GSVERSE_ARTIFACTS", ROOT / "test-artifacts"))
    folder = base / name
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    return folder
