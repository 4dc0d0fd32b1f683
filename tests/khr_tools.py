"""Independent glTF checks through two third-party JavaScript tools.

The scripts in ``tests/js`` run under Node.js:

* ``validate_gltf.mjs`` -- the Khronos glTF-Validator (npm ``gltf-validator``).
* ``read_khr_glb.mjs`` -- the PlayCanvas engine's glTF parser with its
  KHR_gaussian_splatting extension (npm ``playcanvas``) on a null graphics
  device.

Install them once with ``npm ci`` in ``tests/js`` (versions pinned in
``package-lock.json``).  :func:`node_tools_available` tells whether that has
been done; tests call :func:`require_node_tools`, which skips when it has
not (or fails, when ``GSVERSE_REQUIRE_NODE_TOOLS=1``).

Conventions of the values returned by :func:`read_with_playcanvas` are those
of KHR_gaussian_splatting: quaternions (x, y, z, w), linear scales, opacities
in [0, 1], SH as (N, K, 3) with K = (degree + 1)**2 and coefficient index
k = l*l + n for ``SH_DEGREE_l_COEF_n``.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np

JS_DIR = Path(__file__).resolve().parent / "js"
_REQUIRED_PACKAGES = ("gltf-validator", "playcanvas")
DEFAULT_TIMEOUT_S = 120.0


class NodeToolError(RuntimeError):
    """A Node.js check could not run or did not produce a usable result."""


def _node() -> str | None:
    return shutil.which("node")


def node_tools_available() -> bool:
    """True when ``node`` is on PATH and ``tests/js/node_modules`` holds the tools."""
    if _node() is None:
        return False
    modules = JS_DIR / "node_modules"
    return all((modules / name / "package.json").is_file() for name in _REQUIRED_PACKAGES)


def require_node_tools() -> None:
    """Skip the calling test when the Node tools are missing.

    With the environment variable ``GSVERSE_REQUIRE_NODE_TOOLS=1`` (set by CI
    after installing them) a missing tool fails the test instead.
    """
    import pytest

    if node_tools_available():
        return
    reason = f"Node tools not installed (node on PATH and 'npm ci' in {JS_DIR})"
    if os.environ.get("GSVERSE_REQUIRE_NODE_TOOLS") == "1":
        pytest.fail(reason + "; required by GSVERSE_REQUIRE_NODE_TOOLS=1", pytrace=False)
    pytest.skip(reason)


def _run(script: str, args: list[str], ok_codes: tuple[int, ...], timeout: float) -> Any:
    """Run ``node tests/js/<script> args...`` and parse its JSON stdout."""
    node = _node()
    if node is None:
        raise NodeToolError("node is not on PATH")
    if not node_tools_available():
        raise NodeToolError(f"Node tools are not installed: run 'npm ci' in {JS_DIR}")
    cmd = [node, str(JS_DIR / script), *args]
    try:
        proc = subprocess.run(
            cmd,
            cwd=JS_DIR,
            capture_output=True,
            text=True,
            timeout=timeout,
            env={**os.environ, "NODE_NO_WARNINGS": "1"},
            check=False,
        )
    except subprocess.TimeoutExpired as exc:
        raise NodeToolError(f"{script} timed out after {timeout:g} s: {' '.join(cmd)}") from exc
    if proc.returncode not in ok_codes:
        detail = (proc.stderr.strip() or proc.stdout.strip() or "no output").splitlines()
        raise NodeToolError(
            f"{script} failed with exit status {proc.returncode}: " + " | ".join(detail[-5:])
        )
    try:
        return json.loads(proc.stdout)
    except json.JSONDecodeError as exc:
        raise NodeToolError(f"{script} printed no valid JSON: {proc.stdout[:200]!r}") from exc


def validate_gltf(path: str | os.PathLike, timeout: float = DEFAULT_TIMEOUT_S) -> dict:
    """Validate a .glb/.gltf file with the Khronos glTF-Validator.

    Returns the JSON report of ``validate_gltf.mjs --json``: ``numErrors``,
    ``numWarnings``, ``numInfos``, ``numHints`` (the validator's totals),
    ``numUnexpectedErrors`` (errors other than the validator's complaint
    about valid ``KHR_gaussian_splatting:*`` attribute names, which it does
    not know yet), ``numExpectedKhrAttributeErrors``, ``validatorVersion``
    and ``messages`` (dicts with ``code``, ``severity`` -- "Error",
    "Warning", "Information" or "Hint" --, ``pointer``, ``message`` and
    ``expectedKhrAttribute``).  External resources are refused.

    Raises :class:`NodeToolError` when the file cannot be validated at all.
    """
    return _run("validate_gltf.mjs", [os.fspath(path), "--json"], (0, 1), timeout)


def _floats(values: list, shape: tuple[int, ...]) -> np.ndarray:
    # Non-finite numbers arrive as the strings "NaN", "Infinity", "-Infinity".
    arr = np.asarray(values, dtype=object)
    return arr.astype(np.float64).astype(np.float32).reshape(shape)


def playcanvas_report(path: str | os.PathLike, timeout: float = DEFAULT_TIMEOUT_S) -> dict:
    """Everything ``read_khr_glb.mjs`` reports about a file.

    ``{"engine_version": str, "meshes": [...], "splats": [...]}`` where
    ``splats`` is what :func:`read_with_playcanvas` returns and ``meshes``
    has one dict per glTF mesh: ``mesh``, ``name``, ``splatPrimitives`` (splat
    primitives decoded from it) and ``renderPrimitives`` (the engine's
    ordinary meshes for its other primitives: ``mode`` -- glTF mode numbers
    --, ``indexed``, ``count``, ``vertexCount``).
    Raises :class:`NodeToolError` when the engine cannot parse the file.
    """
    report = _run("read_khr_glb.mjs", [os.fspath(path)], (0,), timeout)
    splats: list[dict] = []
    for s in report["splats"]:
        n = int(s["count"])
        k = int(s["sh"]["coefficients"])
        splats.append(
            {
                "mesh": s["mesh"],
                "primitive": s["primitive"],
                "mesh_name": s["meshName"],
                "count": n,
                "position": _floats(s["position"], (n, 3)),
                "rotation": _floats(s["rotation"], (n, 4)),
                "scale": _floats(s["scale"], (n, 3)),
                "opacity": _floats(s["opacity"], (n,)),
                "sh": _floats(s["sh"]["values"], (n, k, 3)),
                "sh_degree": int(s["sh"]["degree"]),
                "file_index": np.asarray(s["fileIndex"], dtype=np.int64),
                "playcanvas": s["playcanvas"],
            }
        )
    return {"engine_version": report["engineVersion"], "meshes": report["meshes"], "splats": splats}


def read_with_playcanvas(path: str | os.PathLike, timeout: float = DEFAULT_TIMEOUT_S) -> list[dict]:
    """Decode the KHR_gaussian_splatting primitives of a file with PlayCanvas.

    Returns one dict per splat primitive the engine decoded, in mesh order:

    * ``mesh`` (int), ``primitive`` (int or None when ambiguous),
      ``mesh_name`` (str or None), ``count`` N;
    * ``position`` (N, 3), ``rotation`` (N, 4) xyzw, ``scale`` (N, 3) linear,
      ``opacity`` (N,) in [0, 1], ``sh`` (N, K, 3) -- all float32, rows in
      the file's order;
    * ``sh_degree`` (int), ``file_index`` (N,) int64: the file row held by
      each row of the engine's internal (Morton-sorted) storage;
    * ``playcanvas``: the engine's own view (``activated``, ``shBands``,
      ``properties``: its property names).

    A KHR primitive missing POSITION, ROTATION, SCALE, OPACITY or
    SH_DEGREE_0_COEF_0 yields nothing (the engine skips it).  Only
    self-contained files are read (GLB chunk or data: URIs).
    Raises :class:`NodeToolError` when the engine cannot parse the file.
    """
    return playcanvas_report(path, timeout)["splats"]
