"""Reading and checking USD files in a child process.

usd-core's binary reader can crash the process or exhaust its memory on some corrupted
``.usdc`` data (observed with usd-core 26.11). Here the file is read by a child interpreter
with a memory cap and an optional time limit; its result comes back as JSON plus an
uncompressed ``.npz`` of the arrays. The limits (memory, and time when the caller gives
none) are :data:`gsverse_format.limits.USD_CHILD_MEMORY_BASE` and
:func:`gsverse_format.limits.usd_child_seconds`; the child's standard error goes to a file
of which only the end is read (a corrupt file can make USD print hundreds of megabytes). A crash of the USD library in the child (a stack
overflow on deeply nested prims, an abort on corrupt ``.usdc`` data) is a :class:`FormatError`
(the file is corrupt), one line; the USD crash banner is not shown, and the crash report USD
writes to ``TMPDIR`` lands in the child's private temporary folder, removed with it. Any
other unexpected exception in the child is a bug, not bad input, and comes back as a
:class:`UsdInternalError` naming its type. When the parent is interrupted (Ctrl-C, or
SIGTERM/SIGHUP under the command-line tools) the child is killed and waited for and the
folder removed, wherever the interruption lands (as the folder or the child comes into
being, while the child runs, while the folder is removed).
"""
from __future__ import annotations

import contextlib
import json
import os
import pathlib
import secrets
import shutil
import signal
import subprocess
import sys
import tempfile
import traceback
from collections.abc import Callable, Iterator
from importlib import resources
from typing import IO, Any

import numpy as np

from ...atomic import interruptions_deferred
from ...errors import FormatError, GsverseError, UsageError
from ...limits import USD_CHILD_MEMORY_BASE, usd_child_seconds
from ...model import (Anchoring, GamesAnchors, LocalAnchors, SplatAsset, SplatCloud,
                      SplatPrimitive, TriangleMesh)
from ...vocabulary import allowed_fields
from .checks import inspect_in_process
from .problems import UsdInspection, UsdPrimInfo, UsdProblem
from .reader import read_in_process
from .schema import import_pxr
from .stage import check_path

__all__ = ["CHILD_CODE", "CHILD_MEMORY_BASE", "UsdInternalError", "child_limits", "read_isolated",
           "inspect_isolated", "child_main"]

#: Address-space cap of the child: this much plus 32 times the file size.
CHILD_MEMORY_BASE = USD_CHILD_MEMORY_BASE
#: Bytes of the child's standard error read back (its end) for a failure message.
_STDERR_TAIL = 1 << 16
#: The program the child interpreter runs (``python -c CHILD_CODE mode path out``).
CHILD_CODE = "from gsverse_format.io.usd.isolation import child_main; child_main()"


class UsdInternalError(RuntimeError):
    """An unexpected exception in the USD child process: a bug here, not bad input.

    ``type_name`` is the type of the exception the child raised, ``where`` the file and line.
    """

    def __init__(self, type_name: str, message: str, where: str = "") -> None:
        self.type_name = type_name
        self.where = where
        at = f" at {where}" if where else ""
        super().__init__(f"{type_name} in the USD child process: {message}{at}")


def child_limits(memory: int) -> Callable[[], None]:  # pragma: no cover - runs in the child
    """A ``preexec_fn`` giving a child process an address-space cap of ``memory`` bytes and
    no core files (the USD child here, and the fuzz harness's USD worker)."""
    def apply() -> None:
        try:
            import resource

            resource.setrlimit(resource.RLIMIT_AS, (memory, memory))
            resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
        except (ImportError, ValueError, OSError):
            pass
    return apply


def _run(mode: str, spath: str, timeout: float | None) -> dict[str, Any]:
    """Run ``mode`` on ``spath`` in a child interpreter: "read", or "check"/"inspect" with an
    optional "-validate" suffix (also run ``pxr.UsdValidation``)."""
    try:
        import_pxr()  # the missing-usd-core error belongs to the caller's process
        check_path(spath)
    except GsverseError as err:
        raise err.with_path(spath) from None
    size = os.path.getsize(spath)
    memory = CHILD_MEMORY_BASE + 32 * size
    if timeout is None:
        timeout = usd_child_seconds(size)
    env = dict(os.environ)
    package_root = str(pathlib.Path(str(resources.files("gsverse_format"))).parent)
    env["PYTHONPATH"] = package_root + (os.pathsep + env["PYTHONPATH"]
                                        if env.get("PYTHONPATH") else "")
    with _private_folder() as work:
        out = os.path.join(work, "result")
        # The child's temporary folder is this private one: USD writes its crash report
        # (st_python.<pid>) to TMPDIR, and it goes with the folder.
        env["TMPDIR"] = os.path.join(work, "tmp")
        os.mkdir(env["TMPDIR"])
        with open(os.path.join(work, "stderr"), "w+b") as err_file:
            returncode = _run_child(
                [sys.executable, "-c", CHILD_CODE, mode, os.path.abspath(spath), out], env,
                err_file, memory, timeout, spath)
            err_file.seek(max(0, err_file.seek(0, os.SEEK_END) - _STDERR_TAIL))
            stderr = err_file.read()
        try:
            with open(out + ".json", encoding="utf-8") as handle:
                result = json.load(handle)
        except (OSError, ValueError):
            result = None
        if result is None:
            if returncode < 0:
                try:
                    name = signal.Signals(-returncode).name
                except ValueError:
                    name = f"signal {-returncode}"
                raise FormatError(f"corrupt USD file: the USD library crashed reading it "
                                  f"({name})", spath)
            tail = stderr.decode("utf-8", "replace").strip().splitlines()
            raise FormatError(f"corrupt USD file: the USD library failed reading it (exit "
                              f"code {returncode}"
                              f"{': ' + tail[-1][:200] if tail else ''})", spath)
        if not result["ok"]:
            if result["error"] == "internal":
                raise UsdInternalError(result["type"], result["cause"], result.get("where", ""))
            kind = UsageError if result["error"] == "UsageError" else FormatError
            raise kind(result["cause"], spath)
        if "asset" in result:
            result["asset"] = _load_asset(out + ".npz", result["asset"])
        return result


@contextlib.contextmanager
def _private_folder() -> Iterator[str]:
    """A new folder (``gsverse-usd-*``, mode 0700) in the temporary folder, removed with
    everything in it on leaving, however the block ends: an interruption included, also one
    raised just as the folder came into being, and one received while it is removed."""
    with interruptions_deferred():  # its first call writes and removes a probe file there
        base = tempfile.gettempdir()
    work = os.path.join(base, f"gsverse-usd-{secrets.token_hex(8)}")
    try:
        os.mkdir(work, 0o700)
    except OSError:
        raise  # not made (a name taken, no temporary folder): nothing of ours to remove
    except BaseException:
        _remove_folder(work)
        raise
    try:
        yield work
    finally:
        _remove_folder(work)


def _remove_folder(work: str) -> None:
    with interruptions_deferred():
        shutil.rmtree(work, ignore_errors=True)


def _run_child(cmd: list[str], env: dict[str, str], err_file: IO[bytes], memory: int,
               timeout: float, spath: str) -> int:
    """Run the child ``cmd`` to its end and return its exit status (negative: the signal
    that ended it); past ``timeout`` seconds a :class:`FormatError`. However this ends (an
    interruption of the parent included) the child is ended and waited for before this
    returns or raises, so nothing writes into its folder any more: it is started with
    interruptions deferred, so that its process id is never lost, and stopped the same way."""
    proc: subprocess.Popen[bytes] | None = None
    try:
        with interruptions_deferred():
            proc = subprocess.Popen(
                cmd, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                stderr=err_file, preexec_fn=child_limits(memory) if os.name == "posix" else None)
        try:
            return proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            raise FormatError(f"reading the USD file took longer than {timeout:g} s",
                              spath) from None
    finally:
        if proc is not None:
            with interruptions_deferred():
                if proc.poll() is None:
                    proc.kill()
                proc.wait()


def read_isolated(spath: str, timeout: float | None) -> tuple[SplatAsset, list[UsdProblem]]:
    """:func:`.reader.read_in_process` in a child process."""
    result = _run("read", spath, timeout)
    return result["asset"], [UsdProblem.from_json(p) for p in result["problems"]]


def inspect_isolated(spath: str, timeout: float | None, *, usd_validation: bool,
                     data: bool) -> UsdInspection:
    """:func:`.checks.inspect_in_process` in a child process (``data=False``: problems
    only, an empty asset)."""
    mode = ("inspect" if data else "check") + ("-validate" if usd_validation else "")
    result = _run(mode, spath, timeout)
    problems = [UsdProblem.from_json(p) for p in result["problems"]]
    if not data:
        return UsdInspection(problems, SplatAsset([]), [])
    return UsdInspection(problems, result["asset"],
                         [UsdPrimInfo(**p) for p in result["prims"]])


def _save_asset(asset: SplatAsset, path: str) -> dict[str, Any]:
    """Store ``asset`` as an uncompressed .npz (arrays) plus a JSON-able description."""
    arrays: dict[str, Any] = {}
    meshes: dict[int, int] = {}
    prims: list[dict[str, Any]] = []
    for i, p in enumerate(asset.primitives):
        c = p.splats
        arrays.update({f"p{i}_means": c.means, f"p{i}_rotations": c.rotations,
                       f"p{i}_scales": c.scales, f"p{i}_opacities": c.opacities,
                       f"p{i}_sh": c.sh})
        entry: dict[str, Any] = {"name": p.name, "color_space": c.color_space}
        if p.anchoring is not None:
            mesh, a = p.anchoring.mesh, p.anchoring.anchors
            if id(mesh) not in meshes:
                j = meshes[id(mesh)] = len(meshes)
                arrays.update({f"m{j}_vertices": mesh.vertices, f"m{j}_faces": mesh.faces})
            entry.update(mesh=meshes[id(mesh)], profile=a.profile)
            if isinstance(a, LocalAnchors):
                entry["deformation"] = a.deformation
            for f in allowed_fields(a.profile):
                arrays[f"p{i}_{f.attribute}"] = getattr(a, f.attribute)
        prims.append(entry)
    np.savez(path, **arrays)
    return {"generator": asset.generator, "primitives": prims, "meshes": len(meshes)}


def _load_asset(path: str, meta: dict[str, Any]) -> SplatAsset:
    """Inverse of :func:`_save_asset`."""
    with np.load(path, allow_pickle=False) as z:
        meshes = [TriangleMesh(z[f"m{j}_vertices"], z[f"m{j}_faces"])
                  for j in range(meta["meshes"])]
        prims = []
        for i, e in enumerate(meta["primitives"]):
            cloud = SplatCloud(z[f"p{i}_means"], z[f"p{i}_rotations"], z[f"p{i}_scales"],
                               z[f"p{i}_opacities"], z[f"p{i}_sh"], e["color_space"])
            anchoring = None
            if "mesh" in e:
                fields = {f.attribute: z[f"p{i}_{f.attribute}"]
                          for f in allowed_fields(e["profile"])}
                anchors: LocalAnchors | GamesAnchors
                if e["profile"] == "local":
                    anchors = LocalAnchors(**fields, deformation=e["deformation"])
                else:
                    anchors = GamesAnchors(**fields)
                anchoring = Anchoring(meshes[e["mesh"]], anchors)
            prims.append(SplatPrimitive(cloud, anchoring, e["name"]))
    return SplatAsset(prims, meta["generator"])


def _where(err: BaseException) -> str:
    frames = traceback.extract_tb(err.__traceback__)
    return f"{os.path.basename(frames[-1].filename)}:{frames[-1].lineno}" if frames else ""


def child_main() -> None:  # pragma: no cover - runs in a child interpreter
    """The child's program: ``argv[1:4]`` are the mode, the USD file and the result stem."""
    from dataclasses import asdict

    mode, path, out = sys.argv[1:4]
    result: dict[str, Any] = {"ok": True, "problems": []}
    try:
        if mode == "read":
            asset, problems = read_in_process(path)
            result.update(asset=_save_asset(asset, out + ".npz"),
                          problems=[p.to_json() for p in problems])
        else:
            found = inspect_in_process(path, usd_validation_too=mode.endswith("-validate"))
            result["problems"] = [p.to_json() for p in found.problems]
            if mode.startswith("inspect"):
                result.update(asset=_save_asset(found.asset, out + ".npz"),
                              prims=[asdict(p) for p in found.prims])
    except GsverseError as err:
        result = {"ok": False, "error": type(err).__name__, "cause": err.cause}
    except MemoryError:
        result = {"ok": False, "error": "FormatError",
                  "cause": "not enough memory to read the asset"}
    except Exception as err:  # the process boundary: a bug, reported with its type
        result = {"ok": False, "error": "internal", "type": type(err).__name__,
                  "cause": " ".join(str(err).split())[:500], "where": _where(err)}
    with open(out + ".json", "w", encoding="utf-8") as handle:
        json.dump(result, handle)
