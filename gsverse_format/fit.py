"""Does an anchor mesh belong to its splats? A cheap test for the common mistakes.

A mesh exported in another frame (Z-up against Y-up), in other units (centimetres against
metres), or simply the wrong file binds without an error: every splat has *a* nearest
triangle. :func:`assess_fit` looks at the numbers the binding already has (the distance of
each splat to its triangle) and the two bounding boxes, and says when they do not fit:

* **far**: fewer than :data:`MIN_NEAR_SHARE` of the splats lie within
  :data:`NEAR_FRACTION` × D of the mesh (D the mesh's bounding-box diagonal). A splat
  capture of a whole scene around a small object mesh still has the object's splats near the
  mesh, so it passes; a mesh moved or rotated away from its splats does not.
* **scale**: the splats' extent (the diagonal of the box holding the 1st to 99th percentile
  of their centres per axis, so a few floaters do not count) is below
  :data:`MIN_EXTENT_RATIO` × D: the mesh is more than 20 times larger than what it carries.
  (Splats much larger than the mesh are normal: a scene around an anchored object.)
* **frame**: fewer than :data:`MAX_NEAR_SHARE_ROTATED` of the splats are near the mesh and
  a quarter or half turn of the splats about the axes makes the two boxes overlap far better.

The hint names the likely cause: a rotation by a quarter or half turn that makes the boxes
fit (a frame difference between the two files), a scale factor (units), or an offset.
The thresholds are deliberately loose; they catch gross mistakes, not fine misalignment.

Used by the conversion pipeline (:func:`gsverse_format.scene.judge_fit`: a
:class:`MeshFitWarning`, an error with ``--strict``) and by ``gsverse-validate``
(``ANCHOR_MESH_MISFIT``, through :func:`assess_anchored_fit` on the stored anchors), so that
both judge alike. Above :data:`MAX_SPLATS_JUDGED` splats an evenly spaced subset is judged.
"""
from __future__ import annotations

from dataclasses import dataclass
from itertools import permutations, product
from typing import Any

import numpy as np

__all__ = ["FitReport", "MeshFitWarning", "assess_fit", "assess_anchored_fit", "NEAR_FRACTION",
           "MIN_NEAR_SHARE", "MIN_EXTENT_RATIO", "MAX_SPLATS_JUDGED"]


class MeshFitWarning(UserWarning):
    """An anchor mesh that does not fit its splats (:func:`assess_fit`): issued by the
    conversion pipeline, shown by ``gsverse-convert`` as a ``warning:`` line (silenced by
    ``-q``), an error with ``--strict``."""


#: A splat is *near* the mesh within this fraction of the mesh's bounding-box diagonal.
NEAR_FRACTION = 0.05
#: Fewer near splats than this share means the mesh is not where the splats are.
MIN_NEAR_SHARE = 0.01
#: Splat extent below this fraction of the mesh's diagonal means the units differ.
MIN_EXTENT_RATIO = 0.05
#: Below this share of near splats, a quarter/half-turn rotation that makes the boxes fit
#: (see ``_ROTATION_IOU``) is reported as a frame difference.
MAX_NEAR_SHARE_ROTATED = 0.75
#: A quarter/half-turn rotation is suggested when the rotated splat box overlaps the mesh's
#: box by at least this intersection-over-union, and at least twice as much as unrotated.
_ROTATION_IOU = 0.5
#: :func:`assess_fit` judges at most this many splats (every k-th above it): the
#: verdict is about shares and boxes, which a subset of 200 000 gives to well under a percent,
#: and validation stays fast on assets of millions of splats.
MAX_SPLATS_JUDGED = 200_000


@dataclass(frozen=True)
class FitReport:
    """How splats and an anchor mesh fit; ``problem`` is ``None`` when they do."""

    near_share: float        #: share of splats within NEAR_FRACTION × mesh_diagonal
    median_distance: float   #: median splat-to-mesh distance (scene units)
    mesh_diagonal: float     #: the mesh's bounding-box diagonal
    splat_diagonal: float    #: the diagonal of the splats' 1–99 percentile box
    problem: str | None = None  #: one line with the numbers, or None
    hint: str | None = None     #: the likely fix

    @property
    def ok(self) -> bool:
        return self.problem is None

    def as_dict(self) -> dict:
        """The numbers and the finding (``problem``/``hint`` ``None`` when it fits)."""
        return {"ok": self.ok, "near_share": self.near_share,
                "median_distance": self.median_distance, "mesh_diagonal": self.mesh_diagonal,
                "splat_diagonal": self.splat_diagonal, "problem": self.problem,
                "hint": self.hint}

    def message(self) -> str:
        """``problem`` and ``hint`` as one line (empty when the fit is fine)."""
        if self.problem is None:
            return ""
        return self.problem + (f"; {self.hint}" if self.hint else "")


def _box(points: np.ndarray, robust: bool) -> tuple[np.ndarray, np.ndarray]:
    if robust and len(points) >= 100:
        lo, hi = np.percentile(points, [1, 99], axis=0)
    else:
        lo, hi = points.min(axis=0), points.max(axis=0)
    return np.asarray(lo, np.float64), np.asarray(hi, np.float64)


def _iou(lo_a: np.ndarray, hi_a: np.ndarray, lo_b: np.ndarray, hi_b: np.ndarray) -> float:
    """Intersection over union of two boxes; flat boxes get a small thickness."""
    pad = 1e-3 * max(float(np.linalg.norm(hi_a - lo_a)), float(np.linalg.norm(hi_b - lo_b)), 1e-30)
    lo_a, hi_a, lo_b, hi_b = lo_a - pad, hi_a + pad, lo_b - pad, hi_b + pad
    inter = np.clip(np.minimum(hi_a, hi_b) - np.maximum(lo_a, lo_b), 0, None).prod()
    union = (hi_a - lo_a).prod() + (hi_b - lo_b).prod() - inter
    return float(inter / union) if union > 0 else 0.0


def _rotations() -> list[tuple[str, np.ndarray]]:
    """The 23 proper rotations that permute and flip the axes, by a readable name."""
    out = []
    names = "xyz"
    for perm in permutations(range(3)):
        for signs in product((1, -1), repeat=3):
            m = np.zeros((3, 3))
            for row, (col, s) in enumerate(zip(perm, signs)):
                m[row, col] = s
            if np.linalg.det(m) < 0 or np.array_equal(m, np.eye(3)):
                continue
            desc = ", ".join(f"{'-' if s < 0 else ''}{names[c]}" for c, s in zip(perm, signs))
            out.append((f"(x, y, z) -> ({desc})", m))
    return out


def _suggest_rotation(lo_s: np.ndarray, hi_s: np.ndarray, lo_m: np.ndarray, hi_m: np.ndarray,
                      base_iou: float) -> str | None:
    """The best quarter/half turn of the splats' box (``lo_s``, ``hi_s``) onto the mesh's. A
    turn permutes and flips the axes, so the turned box of the splats (percentiles included:
    the 1st percentile of −x is −(the 99th of x)) is the turned corners' box: no pass over
    the splats per turn."""
    best, best_name = base_iou, None
    for name, m in _rotations():
        a, b = m @ lo_s, m @ hi_s
        iou = _iou(np.minimum(a, b), np.maximum(a, b), lo_m, hi_m)
        if iou > best:
            best, best_name = iou, name
    if best_name is not None and best >= _ROTATION_IOU and best >= 2 * base_iou:
        return (f"the splats fit the mesh's box when turned {best_name} (a frame difference "
                "between the two files: convert the mesh into the splats' frame, or check "
                "--no-frame-change and --from)")
    return None


def assess_fit(means: np.ndarray, vertices: np.ndarray, distance: np.ndarray) -> FitReport:
    """Judge whether the mesh with ``vertices`` belongs to splats at ``means``.

    ``distance`` is each splat's distance to the mesh (the binding's, or to its anchor
    triangle). All in the same frame and units. Above :data:`MAX_SPLATS_JUDGED` splats every
    k-th is judged (shares, percentiles and boxes barely change; the rotation search stays
    fast).
    """
    step = max(1, -(-len(means) // MAX_SPLATS_JUDGED))
    means = np.asarray(means[::step], np.float64).reshape(-1, 3)
    vertices = np.asarray(vertices, np.float64).reshape(-1, 3)
    distance = np.asarray(distance[::step], np.float64).reshape(-1)
    if means.size == 0 or vertices.size == 0:
        return FitReport(1.0, 0.0, 0.0, 0.0)
    lo_m, hi_m = vertices.min(axis=0), vertices.max(axis=0)
    diag_m = float(np.linalg.norm(hi_m - lo_m))
    lo_s, hi_s = _box(means, robust=True)
    diag_s = float(np.linalg.norm(hi_s - lo_s))
    median = float(np.median(distance))
    if diag_m <= 0:
        return FitReport(1.0, median, diag_m, diag_s)
    near = float(np.mean(distance <= NEAR_FRACTION * diag_m))
    report: dict[str, Any] = dict(near_share=near, median_distance=median, mesh_diagonal=diag_m,
                  splat_diagonal=diag_s)
    ratio = diag_s / diag_m
    if ratio < MIN_EXTENT_RATIO:
        factor = diag_m / max(diag_s, 1e-300)
        return FitReport(**report, problem=(
            f"the anchor mesh is {factor:.3g}x larger than the splats (box diagonals "
            f"{diag_m:.3g} and {diag_s:.3g})"), hint=(
            "the two files likely use different units: scale one of them (for example "
            f"by {_round_factor(factor):g}) or check that the mesh belongs to these splats"))
    if near < MIN_NEAR_SHARE:
        hint = _suggest_rotation(lo_s, hi_s, lo_m, hi_m, _iou(lo_s, hi_s, lo_m, hi_m))
        if hint is None:
            offset = (lo_s + hi_s) / 2 - (lo_m + hi_m) / 2
            hint = ("the splats' box centre is offset by "
                    f"({offset[0]:.3g}, {offset[1]:.3g}, {offset[2]:.3g}) from the mesh's: "
                    "check that the mesh belongs to these splats and shares their origin, "
                    "frame (--no-frame-change, --from) and units")
        return FitReport(**report, problem=(
            f"only {100 * near:.2g}% of the splats lie within {NEAR_FRACTION:g} mesh "
            f"diagonals of the anchor mesh (median distance {median:.3g}, "
            f"{median / diag_m:.3g} mesh diagonals)"), hint=hint)
    if near < MAX_NEAR_SHARE_ROTATED:
        hint = _suggest_rotation(lo_s, hi_s, lo_m, hi_m, _iou(lo_s, hi_s, lo_m, hi_m))
        if hint is not None:
            return FitReport(**report, problem=(
                f"only {100 * near:.2g}% of the splats lie within {NEAR_FRACTION:g} mesh "
                f"diagonals of the anchor mesh, and the boxes fit better rotated"), hint=hint)
    return FitReport(**report)


def assess_anchored_fit(means: np.ndarray, vertices: np.ndarray, faces: np.ndarray,
                        face_index: np.ndarray) -> tuple[FitReport, int]:
    """:func:`assess_fit` of stored anchored splats: each splat's distance is to its own
    anchor triangle (``face_index`` into ``faces``, all in range). Above
    :data:`MAX_SPLATS_JUDGED` splats, every k-th splat is judged (deterministic); returns the
    report and how many splats were judged."""
    from .nearest_reference import closest_points_on_triangles

    n = len(means)
    step = max(1, -(-n // MAX_SPLATS_JUDGED))
    pick = slice(None, None, step)
    mu = np.asarray(means[pick], np.float64)
    v = np.asarray(vertices, np.float64)
    tri = v[np.asarray(faces, np.intp)[np.asarray(face_index[pick], np.intp)]]
    _, _, dist = closest_points_on_triangles(mu, tri[:, 0], tri[:, 1], tri[:, 2])
    return assess_fit(mu, v, dist), len(mu)


def _round_factor(factor: float) -> float:
    """The nearest power of ten, or the factor itself to 3 digits when none is close."""
    p = 10.0 ** round(np.log10(factor))
    return p if 0.8 <= factor / p <= 1.25 else float(f"{factor:.3g}")
