"""Validate one file: ``.glb``/``.gltf`` (container, ``KHR_gaussian_splatting``, anchor extension,
anchor mesh and rest-pose consistency) or ``.usda``/``.usdc``/``.usd``/``.usdz`` (spec/usd.md,
:mod:`.usd`). Returns a :class:`Report`; never raises for bad input.
"""
from __future__ import annotations

import os
import time
import traceback
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gsverse_format.version import __version__
from gsverse_format.codes import Code
from gsverse_format.vocabulary import EXTENSION, KHR, SPZ_EXTENSION
from gsverse_format.io.gltf import GltfFormatError
from gsverse_format.io.gltf.scene import check_instancing
from gsverse_format.io.gltf.spz import is_compressed

from .anchor import check_anchor
from .container import GLB_MIME, GLTF_MIME, Context, Options, file_problem, load_container
from .context import CheckContext
from .graph import check_mesh_indices, check_node_graph
from .physics import check_physics
from .issues import Finding, Issues, Severity
from .khr import check_splat_primitive
from .spz import check_compressed_anchor, check_compressed_primitive
from .usd import usd_mime_type, validate_usd

#: File name suffixes validated as USD.
USD_SUFFIXES = (".usda", ".usdc", ".usd", ".usdz")

__all__ = ["Report", "validate_file", "VALIDATOR_NAME"]

VALIDATOR_NAME = "gsverse-validate"


@dataclass
class Report:
    """The findings for one file and a short description of what it holds (``info``).

    Findings locate problems by JSON pointer (glTF; written as ``pointer`` in JSON) or by USD
    path (USD files, ``usd`` true; written as ``usdPath``).
    """

    path: str
    issues: Issues
    mime_type: str | None = None
    info: dict[str, Any] = field(default_factory=dict)
    seconds: float = 0.0
    usd: bool = False

    @property
    def findings(self) -> list[Finding]:
        """The findings in the order found (the reports list them by severity:
        :meth:`ordered_findings`)."""
        return self.issues.findings

    def ordered_findings(self) -> list[Finding]:
        """The findings as the text and JSON reports list them: errors, then warnings, infos
        and hints; in the order found within a severity."""
        return self.issues.ordered()

    def codes(self) -> set[Code]:
        return self.issues.codes()

    def count(self, severity: Severity) -> int:
        return self.issues.count(severity)

    @property
    def exit_status(self) -> int:
        """2: the file could not be validated; 1: errors; 0: no errors."""
        if self.issues.unreadable:
            return 2
        return 1 if self.count(Severity.ERROR) else 0

    def to_json(self) -> dict:
        return {
            "uri": self.path,
            "mimeType": self.mime_type,
            "validatorVersion": f"{VALIDATOR_NAME} {__version__}",
            "issues": {
                "numErrors": self.count(Severity.ERROR),
                "numWarnings": self.count(Severity.WARNING),
                "numInfos": self.count(Severity.INFO),
                "numHints": self.count(Severity.HINT),
                "messages": [f.to_json("usdPath" if self.usd else "pointer")
                             for f in self.ordered_findings()],
                "truncated": self.issues.truncated,
            },
            "info": self.info,
            "exitStatus": self.exit_status,
        }


def _where(err: BaseException) -> str:
    frames = traceback.extract_tb(err.__traceback__)
    if not frames:
        return ""
    last = frames[-1]
    return f" at {os.path.basename(last.filename)}:{last.lineno}"


def _internal(issues: Issues, err: BaseException, pointer: str | None = None) -> None:
    """Report an unexpected exception (a bug, not bad input) as INTERNAL_ERROR with its type
    and where it was raised."""
    issues.add(Code.INTERNAL_ERROR, f"{type(err).__name__}: {err}{_where(err)}"[:300],
               pointer=pointer)


def _check_document(ctx: Context, info: dict) -> None:
    doc = ctx.doc
    nodes, cyclic = check_node_graph(ctx)
    try:  # instancing beyond the limits, counted without expanding (not with a cycle)
        if not cyclic:
            check_instancing(doc)
    except GltfFormatError as err:
        if err.code == Code.SIZE_LIMIT_EXCEEDED:  # bad references: check_node_graph's
            ctx.add_error(err)
    used = doc.get("extensionsUsed", [])
    if not isinstance(used, list):
        ctx.issues.add(Code.GLTF_SCHEMA_VIOLATION, "extensionsUsed must be an array",
                       pointer="/extensionsUsed")
        used = []
    required = doc.get("extensionsRequired", [])
    if isinstance(required, list):
        for i, name in enumerate(required):
            if name == EXTENSION:
                ctx.issues.add(Code.ANCHOR_EXTENSION_REQUIRED, f"{EXTENSION} must not be listed "
                               f"in extensionsRequired (the rest pose is a complete fallback)",
                               pointer=f"/extensionsRequired/{i}")
    khr_uses: list[str] = []
    anchor_uses: list[str] = []
    spz_uses: list[str] = []
    splats = anchored = total = 0
    failed = False  # a bug in a primitive's checks: its splats are not counted
    for m, mesh in enumerate(ctx.array("meshes")):
        for p, prim in enumerate(mesh.get("primitives", [])):
            pointer = f"/meshes/{m}/primitives/{p}"
            extensions = prim.get("extensions", {})
            if EXTENSION in extensions:
                ctx.issues.add(Code.ANCHOR_EXTENSION_MISPLACED, f"{EXTENSION} belongs inside "
                               f"extensions.{KHR}.extensions, not directly in the primitive's "
                               f"extensions", pointer=f"{pointer}/extensions/{EXTENSION}")
            if KHR not in extensions:
                continue
            khr = extensions[KHR]
            khr_uses.append(f"{pointer}/extensions/{KHR}")
            try:
                spz = is_compressed(khr)
                if spz:
                    spz_uses.append(f"{pointer}/extensions/{KHR}/extensions/{SPZ_EXTENSION}")
                    data = check_compressed_primitive(ctx, m, p, prim, khr)
                else:
                    data = check_splat_primitive(ctx, m, p, prim, khr)
                splats += 1
                total += data.count or 0
                nested = khr.get("extensions") if isinstance(khr, dict) else None
                if isinstance(nested, dict) and EXTENSION in nested:
                    apointer = f"{pointer}/extensions/{KHR}/extensions/{EXTENSION}"
                    anchor_uses.append(apointer)
                    anchored += 1
                    if spz:
                        check_compressed_anchor(ctx, nested[EXTENSION], apointer)
                    check_anchor(ctx, data, nested[EXTENSION], apointer)
            except Exception as err:  # boundary of one primitive's checks: a bug there is
                _internal(ctx.issues, err, pointer)  # INTERNAL_ERROR, the others still run
                failed = True
    if not khr_uses:
        ctx.issues.add(Code.KHR_NO_SPLATS, f"the file has no {KHR} primitive")
    for name, uses in ((KHR, khr_uses), (EXTENSION, anchor_uses), (SPZ_EXTENSION, spz_uses)):
        if uses and name not in used:
            ctx.issues.add(Code.EXTENSION_NOT_DECLARED, f"{name} is used ({len(uses)} time(s)) "
                           f"but not listed in extensionsUsed", pointer=uses[0])
    check_physics(ctx, used)
    info.update({"splatPrimitives": splats, "anchoredPrimitives": anchored, "splats": total,
                 "anchorPrimitives": sum(1 for k in ctx.cache if k[0] == "anchor")})
    generator = doc.get("asset", {}).get("generator") if isinstance(doc.get("asset"), dict) \
        else None
    if isinstance(generator, str):
        info["generator"] = generator
    meshes = check_mesh_indices(ctx)
    if not total and not failed:
        held = (f"its {splats} {KHR} primitive(s) hold 0 splats" if splats
                else f"no {KHR} primitive")
        ctx.issues.add(Code.NO_SPLATS, f"the file holds no splats ({held}): checked its "
                       f"container, buffers, {nodes} node(s) and the indices of {meshes} other "
                       f"mesh primitive(s); materials, textures, animations and the rest of "
                       f"the glTF are not checked (use the Khronos glTF validator for those)")


def validate_file(path: str | os.PathLike, options: Options | None = None, *,
                  overrides: dict[Code, Severity | None] | None = None,
                  max_issues: int | None = None) -> Report:
    """Validate ``path``. ``overrides`` maps issue codes to severities (``None``: ignore).

    Never raises: bad input is reported under its code, and an unexpected exception (a bug)
    as INTERNAL_ERROR naming its type.
    """
    start = time.perf_counter()
    spath = os.fspath(path)
    options = options or Options()
    issues = Issues(dict(overrides or {}), max_issues)
    report = Report(spath, issues)
    if os.path.splitext(spath)[1].lower() in USD_SUFFIXES:
        report.usd = True
        try:
            if not file_problem(spath, issues, USD_SUFFIXES):
                report.mime_type = usd_mime_type(spath)
                validate_usd(CheckContext(spath, options, issues), report.info)
                if report.info.get("splatPrimitives") is not None and \
                        not report.info.get("splats"):
                    prims = report.info["splatPrimitives"]
                    issues.add(Code.NO_SPLATS, "the stage holds no splats (" + (
                        f"its {prims} splat prim(s) hold 0 splats" if prims else
                        "no ParticleField3DGaussianSplat prim") + ")")
        except Exception as err:  # boundary: a bug is INTERNAL_ERROR with its type, not bad input
            _internal(issues, err)
        report.seconds = time.perf_counter() - start
        return report
    try:
        ctx = load_container(spath, options, issues)
        if ctx is not None:
            report.mime_type = GLB_MIME if ctx.document.glb else GLTF_MIME
            report.info["bytes"] = ctx.document.size
            with np.errstate(all="ignore"):  # overflow in hostile data is reported, not warned
                _check_document(ctx, report.info)
    except Exception as err:  # boundary: a bug is INTERNAL_ERROR with its type, not bad input
        _internal(issues, err)
    report.seconds = time.perf_counter() - start
    return report
