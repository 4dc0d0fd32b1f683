"""``gsverse-conformance check DIR RESULTS``: compare a plugin's dumps with the reference.

For each case of the suite in ``DIR`` the runner reads ``RESULTS/<id>/`` (layout in
``spec/conformance.md`` and ``DIR/LAYOUT.md``) and checks:

* remap cases — the imported rest pose (means, covariance, opacity, SH), the means and
  covariances after every pose, and opacity and SH after the last pose (pass-through), each
  against the tolerance in the case manifest. Covariances are compared, never rotation/scale
  pairs (which are not unique): dumps of rotation + scale are turned into R diag(s)² Rᵀ first;
* ``encoding:spz`` remap cases, in addition — the means and covariances after every pose
  against the remap of the *uncompressed* rest pose, within the per-splat bound the case ships
  (spec §SPZ-compressed rest pose) plus the case's usual tolerance (quantities
  ``mean (uncompressed)`` and ``covariance (uncompressed)``);
* invalid cases — that the plugin refused the asset (a ``refused`` file);
* render cases (the render level, :mod:`.render_check`) — the engine's picture of every frame
  against the reference picture: PSNR over the covered pixels and coverage IoU.

``level`` picks what is checked: ``numbers`` (remap and invalid cases), ``render`` (render
cases) or ``all``.

A case passes when every value is finite and within tolerance. The report names, per case,
the worst error relative to its tolerance and where it is (dump, pose, splat).

*Optional features.* An implementation may declare, in ``RESULTS/harness.json``, the optional
features it does not implement: ``"unsupported": ["encoding:spz"]``. Only the tags of
:data:`OPTIONAL_TAGS` can be declared; a case carrying a declared tag is reported
``unsupported`` (neither passed nor failed, counted apart, listed in the report) whatever its
dumps hold, and :attr:`Report.ok` does not count it against the run. A declaration of any other
tag is ignored (the case is checked as usual).
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..errors import UsageError
from .render_check import FrameScore, check_render_case

__all__ = ["Check", "CaseResult", "Report", "check_results", "format_text", "quat_to_matrix",
           "OPTIONAL_TAGS"]

#: Case tags of the optional features an implementation may declare unsupported in
#: ``harness.json`` (``"unsupported": [...]``): the SPZ-compressed rest pose (version 1.2).
OPTIONAL_TAGS = ("encoding:spz",)


@dataclass
class Check:
    """The worst value of one quantity in one case."""

    quantity: str            # "mean", "covariance", "opacity", "sh"
    dump: str                # e.g. "pose_002" or "rest"
    pose: int | None
    splat: int
    error: float
    tolerance: float
    ratio: float             # error / tolerance (inf for non-finite values)
    component: int | None = None


@dataclass
class CaseResult:
    id: str
    kind: str
    status: str              # "pass", "fail", "missing" or "unsupported" (declared)
    message: str = ""
    worst: Check | None = None
    checks: list[Check] = field(default_factory=list)
    #: render cases: the score of every frame
    frames: list[FrameScore] = field(default_factory=list)


@dataclass
class Report:
    suite: str
    results: str
    version: int
    harness: dict | None
    cases: list[CaseResult]

    level: str = "all"

    @property
    def summary(self) -> dict[str, int]:
        return {"total": len(self.cases),
                "passed": sum(c.status == "pass" for c in self.cases),
                "failed": sum(c.status == "fail" for c in self.cases),
                "missing": sum(c.status == "missing" for c in self.cases),
                "unsupported": sum(c.status == "unsupported" for c in self.cases),
                "render": sum(c.kind == "render" for c in self.cases)}

    @property
    def ok(self) -> bool:
        """Every case passed, except those of an optional feature the harness declared
        unsupported."""
        return all(c.status in ("pass", "unsupported") for c in self.cases)

    def to_json(self) -> dict:
        def clean(value):
            if isinstance(value, float) and not math.isfinite(value):
                return str(value)
            if isinstance(value, dict):
                return {k: clean(v) for k, v in value.items()}
            if isinstance(value, list):
                return [clean(v) for v in value]
            return value

        return clean({"suite": self.suite, "results": self.results, "version": self.version,
                      "level": self.level, "harness": self.harness, "summary": self.summary,
                      "cases": [asdict(c) for c in self.cases]})


class _DumpError(Exception):
    pass


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) of quaternions (N, 4) x, y, z, w (normalized first)."""
    q = np.asarray(q, dtype=np.float64)
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    q = q / np.where(norm > 0, norm, 1.0)
    x, y, z, w = q.T
    m = np.empty((len(q), 3, 3))
    m[:, 0, 0] = 1 - 2 * (y * y + z * z)
    m[:, 0, 1] = 2 * (x * y - w * z)
    m[:, 0, 2] = 2 * (x * z + w * y)
    m[:, 1, 0] = 2 * (x * y + w * z)
    m[:, 1, 1] = 1 - 2 * (x * x + z * z)
    m[:, 1, 2] = 2 * (y * z - w * x)
    m[:, 2, 0] = 2 * (x * z - w * y)
    m[:, 2, 1] = 2 * (y * z + w * x)
    m[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return m


def _cov_matrix(c6: np.ndarray) -> np.ndarray:
    m = np.empty((len(c6), 3, 3))
    for j, (r, s) in enumerate(((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))):
        m[:, r, s] = c6[:, j]
        m[:, s, r] = c6[:, j]
    return m


def _read(folder: Path, stem: str, shape: tuple[int, ...]) -> np.ndarray:
    """Dump ``stem`` (.f32 or .f64) as float64 of ``shape``; _DumpError if missing/wrong."""
    for ext, dtype in ((".f32", "<f4"), (".f64", "<f8")):
        path = folder / (stem + ext)
        if path.is_file():
            data = np.fromfile(path, dtype=dtype)
            want = int(np.prod(shape))
            if data.size != want or path.stat().st_size % np.dtype(dtype).itemsize:
                raise _DumpError(f"{path.name} has {data.size} values, expected {want} "
                                 f"(shape {shape})")
            return data.reshape(shape).astype(np.float64)
    raise _DumpError(f"missing dump {stem}.f32 (or .f64)")


def _has(folder: Path, stem: str) -> bool:
    return (folder / f"{stem}.f32").is_file() or (folder / f"{stem}.f64").is_file()


def _read_cov(folder: Path, stem: str, n: int) -> np.ndarray:
    """(N, 3, 3) covariance from ``stem.cov`` or from ``stem.rotation`` + ``stem.scale``."""
    if _has(folder, f"{stem}.cov"):
        return _cov_matrix(_read(folder, f"{stem}.cov", (n, 6)))
    if _has(folder, f"{stem}.rotation") or _has(folder, f"{stem}.scale"):
        q = _read(folder, f"{stem}.rotation", (n, 4))
        s = _read(folder, f"{stem}.scale", (n, 3))
        rs = quat_to_matrix(q) * s[:, None, :]
        cov = rs @ np.swapaxes(rs, 1, 2)
        bad = ~(np.all(np.isfinite(q), axis=1) & np.all(np.isfinite(s), axis=1))
        cov[bad] = np.nan
        return cov
    raise _DumpError(f"missing dump {stem}.cov (or {stem}.rotation + {stem}.scale)")


def _worst(quantity: str, dump: str, pose: int | None, error: np.ndarray, tol: np.ndarray,
           component: np.ndarray | None = None) -> Check:
    ratio = np.where(np.isfinite(error), error / tol, np.inf)
    i = int(np.argmax(ratio))
    return Check(quantity, dump, pose, i, float(error[i]), float(tol[i]), float(ratio[i]),
                 None if component is None else int(component[i]))


def _check_means(got, ref, atol, dump, pose) -> Check:
    err = np.linalg.norm(got - ref, axis=1)
    err = np.where(np.all(np.isfinite(got), axis=1), err, np.inf)
    return _worst("mean", dump, pose, err, np.full(len(err), atol))


def _pose_tolerance(tol: dict, key: str, pose: int | None) -> float:
    """The tolerance of pose ``pose`` (the rest dump: pose 0), or the case's."""
    per = tol.get("per_pose")
    return float(per[pose or 0]) if per else float(tol[key])


def _check_cov(got, ref, rest_ref, tol: dict, dump, pose) -> Check:
    err = np.linalg.norm(got - ref, axis=(1, 2))
    err = np.where(np.all(np.isfinite(got), axis=(1, 2)), err, np.inf)
    scale = np.maximum(np.linalg.norm(ref, axis=(1, 2)),
                       tol["floor"] * np.linalg.norm(rest_ref, axis=(1, 2)))
    scale = np.where(scale > 0, scale, np.finfo(np.float64).tiny)
    rest_norm = np.linalg.norm(rest_ref, axis=(1, 2))
    extra = 0.0
    if "rest_rtol" in tol:
        per = tol.get("rest_rtol_per_pose")
        extra = float(per[pose or 0]) if per else float(tol["rest_rtol"])
    return _worst("covariance", dump, pose, err,
                  _pose_tolerance(tol, "rtol", pose) * scale + extra * rest_norm)


def _check_values(quantity, got, ref, atol, rtol, dump, pose) -> Check:
    flat_got = got.reshape(len(got), -1)
    flat_ref = ref.reshape(len(ref), -1)
    err = np.abs(flat_got - flat_ref)
    err = np.where(np.isfinite(flat_got), err, np.inf)
    tol = atol + rtol * np.abs(flat_ref)
    ratio = np.where(np.isfinite(err), err / tol, np.inf)
    comp = np.argmax(ratio, axis=1)
    rows = np.arange(len(err))
    return _worst(quantity, dump, pose, err[rows, comp], tol[rows, comp], comp)


def _check_remap(case_dir: Path, manifest: dict, folder: Path) -> CaseResult:
    cid = manifest["id"]
    n, k = manifest["splat_count"], manifest["sh_coefficients"]
    tol = manifest["tolerances"]
    files = manifest["files"]["expected"]

    def ref(rel: str, shape) -> np.ndarray:
        dtype = "<f8" if rel.endswith(".f64") else "<f4"
        return np.fromfile(case_dir / rel, dtype=dtype).reshape(shape).astype(np.float64)

    if (folder / "refused").is_file():
        reason = (folder / "refused").read_text(encoding="utf-8", errors="replace").strip()
        return CaseResult(cid, "remap", "fail", f"refused a valid asset: {reason[:300]}")
    if (folder / "error").is_file():
        reason = (folder / "error").read_text(encoding="utf-8", errors="replace").strip()
        return CaseResult(cid, "remap", "fail", f"harness error: {reason[:300]}")
    checks: list[Check] = []
    try:
        rest_means = ref(files["rest"]["means"], (n, 3))
        rest_cov = _cov_matrix(ref(files["rest"]["cov"], (n, 6)))
        opacity = ref(files["rest"]["opacity"], (n,))
        sh = ref(files["rest"]["sh"], (n, k, 3))
        checks.append(_check_means(_read(folder, "rest.means", (n, 3)), rest_means,
                                   _pose_tolerance(tol["mean"], "atol", None), "rest", None))
        checks.append(_check_cov(_read_cov(folder, "rest", n), rest_cov, rest_cov,
                                 tol["covariance"], "rest", None))
        for stem, expected, quantity, t in (("rest", opacity, "opacity", tol["opacity"]),
                                            ("posed", opacity, "opacity", tol["opacity"]),
                                            ("rest", sh, "sh", tol["sh"]),
                                            ("posed", sh, "sh", tol["sh"])):
            got = _read(folder, f"{stem}.{quantity}", expected.shape)
            checks.append(_check_values(quantity, got, expected, t["atol"], t.get("rtol", 0.0),
                                        stem, None))
        for p, exp in enumerate(files["poses"]):
            stem = f"pose_{p:03d}"
            checks.append(_check_means(_read(folder, f"{stem}.means", (n, 3)),
                                       ref(exp["means"], (n, 3)),
                                       _pose_tolerance(tol["mean"], "atol", p), stem, p))
            checks.append(_check_cov(_read_cov(folder, stem, n),
                                     _cov_matrix(ref(exp["cov"], (n, 6))), rest_cov,
                                     tol["covariance"], stem, p))
        if "compression" in manifest:
            checks += _check_uncompressed(manifest, folder, ref, rest_cov)
    except _DumpError as err:
        return CaseResult(cid, "remap", "fail", str(err), None, checks)
    worst = max(checks, key=lambda c: c.ratio)
    # keep, per quantity, the worst check only
    per: dict[str, Check] = {}
    for c in checks:
        if c.quantity not in per or c.ratio > per[c.quantity].ratio:
            per[c.quantity] = c
    status = "pass" if all(c.ratio <= 1.0 for c in checks) else "fail"
    msg = "" if status == "pass" else _describe(worst)
    return CaseResult(cid, "remap", status, msg, worst, list(per.values()))


def _check_uncompressed(manifest: dict, folder: Path, ref, rest_cov: np.ndarray) -> list[Check]:
    """``encoding:spz``: every pose against the remap of the uncompressed rest pose, within the
    shipped bound (per splat: mean, covariance) plus the case's usual tolerance."""
    n, tol = manifest["splat_count"], manifest["tolerances"]
    out = []
    for p, exp in enumerate(manifest["compression"]["uncompressed"]):
        stem = f"pose_{p:03d}"
        bound = ref(exp["bound"], (n, 2))
        got = _read(folder, f"{stem}.means", (n, 3))
        err = np.linalg.norm(got - ref(exp["means"], (n, 3)), axis=1)
        err = np.where(np.all(np.isfinite(got), axis=1), err, np.inf)
        out.append(_worst("mean (uncompressed)", stem, p, err,
                          bound[:, 0] + _pose_tolerance(tol["mean"], "atol", p)))
        got_cov = _read_cov(folder, stem, n)
        expected = _cov_matrix(ref(exp["cov"], (n, 6)))
        err = np.linalg.norm(got_cov - expected, axis=(1, 2))
        err = np.where(np.all(np.isfinite(got_cov), axis=(1, 2)), err, np.inf)
        # the usual covariance tolerance of each splat, recomputed as _check_cov does
        scale = np.maximum(np.linalg.norm(expected, axis=(1, 2)),
                           tol["covariance"]["floor"] * np.linalg.norm(rest_cov, axis=(1, 2)))
        out.append(_worst("covariance (uncompressed)", stem, p, err,
                          bound[:, 1] + _pose_tolerance(tol["covariance"], "rtol", p) * scale
                          + np.finfo(np.float64).tiny))   # tiny: never a zero divisor
    return out


def _describe(c: Check) -> str:
    where = f"{c.dump}, splat {c.splat}"
    if c.component is not None:
        where += f", component {c.component}"
    if not math.isfinite(c.error) or not math.isfinite(c.ratio):
        return f"{c.quantity} not finite at {where}"
    return f"{c.quantity} error {c.error:.3g} > tolerance {c.tolerance:.3g} at {where}"


def _check_invalid(manifest: dict, folder: Path) -> CaseResult:
    cid = manifest["id"]
    if (folder / "refused").is_file():
        return CaseResult(cid, "invalid", "pass", "refused as required")
    code = manifest.get("validator_code")
    return CaseResult(cid, "invalid", "fail", f"accepted an invalid asset; it must be refused "
                      f"({manifest['rule']}" + (f"; validator code {code})" if code else ")"))


def _check_render(case_dir: Path, manifest: dict, folder: Path) -> CaseResult:
    status, message, scores = check_render_case(case_dir, manifest, folder)
    return CaseResult(manifest["id"], "render", status, message, frames=scores)


LEVELS = ("numbers", "render", "all")


def check_results(suite_dir: str | os.PathLike, results_dir: str | os.PathLike, *,
                  level: str = "all") -> Report:
    """Check the cases of the suite in ``suite_dir`` against the dumps in ``results_dir``:
    ``level`` ``numbers`` (remap and invalid cases), ``render`` (render cases) or ``all``."""
    if level not in LEVELS:
        raise UsageError(f"level must be one of {', '.join(LEVELS)}, got {level!r}")
    root = Path(suite_dir)
    index_path = root / "suite.json"
    if not index_path.is_file():
        raise UsageError("not a conformance suite (no suite.json); create one with "
                         "'gsverse-conformance export DIR'", suite_dir)
    index = json.loads(index_path.read_text(encoding="utf-8"))
    results = Path(results_dir)
    if not results.is_dir():
        raise UsageError("results folder does not exist", results_dir)
    harness = None
    if (results / "harness.json").is_file():
        try:
            harness = json.loads((results / "harness.json").read_text(encoding="utf-8"))
        except ValueError:
            harness = {"error": "harness.json is not valid JSON"}
    declared = harness.get("unsupported", []) if isinstance(harness, dict) else []
    unsupported = {t for t in declared if isinstance(t, str) and t in OPTIONAL_TAGS}
    out = []
    entries = (index["cases"] if level != "render" else []) + \
        (index.get("render_cases", []) if level != "numbers" else [])
    for entry in entries:
        case_dir = root / entry["path"]
        manifest = json.loads((case_dir / "case.json").read_text(encoding="utf-8"))
        folder = results / manifest["id"]
        skipped = sorted(unsupported.intersection(manifest.get("tags", [])))
        if skipped:
            out.append(CaseResult(manifest["id"], manifest["kind"], "unsupported",
                                  f"not supported by the harness ({', '.join(skipped)}); "
                                  f"not checked"))
        elif not folder.is_dir():
            out.append(CaseResult(manifest["id"], manifest["kind"], "missing",
                                  f"no results folder {manifest['id']}/"))
        elif manifest["kind"] == "invalid":
            out.append(_check_invalid(manifest, folder))
        elif manifest["kind"] == "render":
            out.append(_check_render(case_dir, manifest, folder))
        else:
            out.append(_check_remap(case_dir, manifest, folder))
    return Report(str(root), str(results), index.get("version", 0), harness, out, level)


def format_text(report: Report, *, failures_only: bool = False) -> str:
    """The human-readable report: one line per case (or per case that did not pass), then
    the summary of all cases."""
    lines = [f"suite {report.suite} (version {report.version}), results {report.results}"]
    if report.harness:
        lines.append("harness: " + ", ".join(f"{k}={v}" for k, v in report.harness.items()))
    shown = [c for c in report.cases if not failures_only or c.status != "pass"]
    width = max((len(c.id) for c in shown), default=10)
    for c in shown:
        status = c.status.upper()
        if c.kind == "render" and c.status == "pass" and c.frames:
            detail = (f"worst frame: PSNR {min(f.psnr_db for f in c.frames):.1f} dB, coverage "
                      f"IoU {min(f.iou for f in c.frames):.3f} ({len(c.frames)} frames)")
        elif c.kind == "invalid" or c.worst is None:
            detail = c.message
        else:
            w = c.worst
            detail = (f"worst {w.quantity} {w.error:.3g} (tol {w.tolerance:.3g}, "
                      f"{w.ratio:.2g}x) at {w.dump} splat {w.splat}")
            if c.status != "pass":
                detail = c.message
        lines.append(f"{status:7} {c.id:{width}}  {detail}")
    s = report.summary
    unsupported = (f", {s['unsupported']} not supported (declared by the harness)"
                   if s["unsupported"] else "")
    lines.append(f"{s['passed']} passed, {s['failed']} failed, {s['missing']} missing"
                 f"{unsupported}, {s['total']} cases (level {report.level}: {s['render']} "
                 f"render cases)")
    return "\n".join(lines)
