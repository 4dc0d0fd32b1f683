"""Does an anchor mesh belong to its splats? A cheap test for the common mistakes.

A mesh exported in another frame (Z-up against Y-up), in other units (centimetres against
metres), or simply the wrong file binds without an error: every splat has *a* nearest
triangle. :func:`assess_fit` looks at the numbers the binding already has (the distance of
each splat to its triangle) and the two bounding boxes, and says when they do not fit. With D
the mesh's bounding-box diagonal, a splat is *near* when it lies within :data:`NEAR_FRACTION`
× D (5 %) of the mesh, and the splats' extent is the diagonal of the box holding the 1st to
99th percentile of their centres per axis (so a few floaters do not count). In this order:

* **units**: the splats' extent is below :data:`MIN_EXTENT_RATIO` × D (0.05): the mesh is more
  than 20 times larger than what it carries; the hint names the factor.
* **far**: fewer than :data:`MIN_NEAR_SHARE` (1 %) of the splats are near the mesh: it is not
  where the splats are; the hint names the offset between the boxes.
* **frame**: fewer than :data:`MAX_NEAR_SHARE_ROTATED` (75 %) are near and a quarter or half
  turn of the splats about the axes makes the two boxes overlap far better; the hint names the
  turn.
* **part**: the splats' extent is below :data:`MIN_SPAN_RATIO` × D (0.4): the mesh is more than
  2.5 times larger than the splats, which then cover a small part of it (another object's
  mesh, a whole scene's, or other units).
* **off**: of the splats *around* the mesh (inside its bounding box grown by
  :data:`AROUND_FRACTION` × D (0.15) on every side), fewer than :data:`MIN_AROUND_NEAR_SHARE`
  (50 %) are near it: the splats occupy the mesh's place but do not lie on its surface
  (another object of about the same size).

Splats spread far beyond the mesh are normal (a capture of a room around an anchored object):
the far splats are outside the grown box, so the object's own splats decide **off**, and no
rule counts the room against the mesh. Every splat near the mesh is also around it, so the
share around the mesh is never below the share of all splats.

How the thresholds were chosen. **units**, **far** and **frame** catch gross mistakes (a mesh
moved away, scaled by a power of ten, turned). **part** and **off** were calibrated with the
conversion itself (``gsverse-convert SPLATS OUT --mesh MESH --json``, the ``fit`` entry) on
the real files of ``../shared/data``: unrelated pairs, every 3DGS capture of ``3dgs/`` (a
Mip-Splatting donut, 45,624 splats; a DreamGaussian object, 49,744; 3 splats of a Tanks and
Temples scene) with every mesh there (``meshes/``: the Stanford bunny, the Fox, the SimpleSkin
strip; ``trellis/``: a TRELLIS GLB), and matching pairs (meshes reconstructed from the donut
and the DreamGaussian object at 300 and 1,500 faces, the shipped capsule, and the generated
pairs of ``tests/test_fit.py``: splats on a box with noise, a room of 20,000 splats around a
small object, floaters). Before **part** and **off**, five of the twelve unrelated pairs
passed; for them (→ for the matching pairs):

* splats' extent / D: 0.13 (donut, SimpleSkin) and 0.24 (donut, TRELLIS), 0.80–1.47 for the
  other three → 0.59 or more (a mesh reconstructed from a capture with floaters reaches
  beyond the captures' 1–99 % box). 0.4 lies between 0.24 and 0.59 (about their geometric
  mean) and catches the first two.
* near share of all splats: 11 % (bunny under the donut), 12 % and 16 % (SimpleSkin and
  TRELLIS through the DreamGaussian object), 55 % and 98 % for the two **part** pairs → 98 %
  or more, but 4.8 % for the room around an object: no threshold on the share of all splats
  separates them. Around the mesh: 0.20, 0.21, 0.22 (0.079 for the bunny under the
  DreamGaussian object, which **far** catches first) → 0.977 or more, the room 1.0. The box
  grown by 0.15 D (0.05 D: up to 0.93 for the flat SimpleSkin strip, whose box holds only
  splats near its plane; 0.25 D: at most 0.18, but more of a real scene's floor and
  background); 50 % is more than twice the highest unrelated share and about half the lowest
  matching one, which leaves room for matching pairs whose surroundings hold a floor or a
  background.

With these every unrelated pair warns and every matching pair passes (``tests/test_fit.py``).
The thresholds stay loose: they catch a wrong or misplaced mesh, not fine misalignment.

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
           "MIN_NEAR_SHARE", "MIN_EXTENT_RATIO", "MAX_NEAR_SHARE_ROTATED", "MIN_SPAN_RATIO",
           "AROUND_FRACTION", "MIN_AROUND_NEAR_SHARE", "MAX_SPLATS_JUDGED"]


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
#: Splat extent below this fraction of the mesh's diagonal means the splats cover a small part
#: of the mesh (**part**; calibrated in the module docstring).
MIN_SPAN_RATIO = 0.4
#: The splats *around* the mesh are those inside its bounding box grown by this fraction of its
#: diagonal on every side.
AROUND_FRACTION = 0.15
#: Fewer near splats than this share of the splats around the mesh means they are not on its
#: surface (**off**; calibrated in the module docstring).
MIN_AROUND_NEAR_SHARE = 0.5
#: Below this share of near splats, a quarter/half-turn rotation that makes the boxes fit
#: (see ``_ROTATION_IOU``) is reported as a frame difference.
MAX_NEAR_SHARE_ROTATED = 0.75
#: Offsets and turns are measured where the meshes are bound: in the output's frame (glTF,
#: +Y up, after the frame change). gsverse-convert's edits act in the input's frame unless
#: ``--edit-frame output`` is given, so the hints say which to use.
OUTPUT_FRAME_NOTE = ("these axes are the output's glTF frame: to apply them with "
                     "--mesh-translate or --mesh-rotate, add --edit-frame output")

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
    #: share of near splats among those around the mesh (AROUND_FRACTION); 1.0 when none is
    around_near_share: float = 1.0

    @property
    def ok(self) -> bool:
        return self.problem is None

    def as_dict(self) -> dict:
        """The numbers and the finding (``problem``/``hint`` ``None`` when it fits)."""
        return {"ok": self.ok, "near_share": self.near_share,
                "around_near_share": self.around_near_share,
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
                f"--no-frame-change and --from; {OUTPUT_FRAME_NOTE})")
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
    is_near = distance <= NEAR_FRACTION * diag_m
    near = float(np.mean(is_near))
    grow = AROUND_FRACTION * diag_m
    around = np.all((means >= lo_m - grow) & (means <= hi_m + grow), axis=1)
    around_near = float(np.mean(is_near[around])) if np.any(around) else 1.0
    report: dict[str, Any] = dict(near_share=near, median_distance=median, mesh_diagonal=diag_m,
                                  splat_diagonal=diag_s, around_near_share=around_near)
    ratio = diag_s / diag_m
    factor = diag_m / max(diag_s, 1e-300)
    if ratio < MIN_EXTENT_RATIO:
        return FitReport(**report, problem=(
            f"the anchor mesh is {factor:.3g}x larger than the splats (box diagonals "
            f"{diag_m:.3g} and {diag_s:.3g})"), hint=(
            "the two files likely use different units: scale one of them (for example "
            f"by {_round_factor(factor):g}) or check that the mesh belongs to these splats"))
    near_text = (f"only {_percent(near)} of the splats lie within {NEAR_FRACTION:g} mesh "
                 f"diagonals of the anchor mesh")
    if near < MIN_NEAR_SHARE:
        hint = _suggest_rotation(lo_s, hi_s, lo_m, hi_m, _iou(lo_s, hi_s, lo_m, hi_m))
        if hint is None:
            offset = (lo_s + hi_s) / 2 - (lo_m + hi_m) / 2
            hint = ("the splats' box centre is offset by "
                    f"({offset[0]:.3g}, {offset[1]:.3g}, {offset[2]:.3g}) from the mesh's: "
                    "check that the mesh belongs to these splats and shares their origin, "
                    f"frame (--no-frame-change, --from) and units; {OUTPUT_FRAME_NOTE}")
        return FitReport(**report, problem=(
            f"{near_text} (median distance {median:.3g}, {median / diag_m:.3g} mesh "
            "diagonals)"), hint=hint)
    turn = None
    if near < MAX_NEAR_SHARE_ROTATED:
        turn = _suggest_rotation(lo_s, hi_s, lo_m, hi_m, _iou(lo_s, hi_s, lo_m, hi_m))
        if turn is not None:
            return FitReport(**report, problem=f"{near_text}, and the boxes fit better rotated",
                             hint=turn)
    if ratio < MIN_SPAN_RATIO:
        return FitReport(**report, problem=(
            f"the anchor mesh is {factor:.3g}x larger than the splats (box diagonals "
            f"{diag_m:.3g} and {diag_s:.3g}): they cover a small part of it"), hint=(
            "check that the mesh belongs to these splats (not to a larger object or a whole "
            f"scene) and uses their units (else scale it by {1 / factor:.3g})"))
    if around_near < MIN_AROUND_NEAR_SHARE:
        return FitReport(**report, problem=(
            f"only {_percent(around_near)} of the {int(np.count_nonzero(around))} splats "
            f"around the anchor mesh lie within {NEAR_FRACTION:g} mesh diagonals of it "
            f"({_percent(near)} of all splats; median distance {median:.3g}, "
            f"{median / diag_m:.3g} mesh diagonals)"), hint=(
            "the splats fill the mesh's place but do not lie on its surface: check that the "
            "mesh is these splats' object, in their origin, frame and units"))
    return FitReport(**report)


def assess_anchored_fit(means: np.ndarray, vertices: np.ndarray, faces: np.ndarray,
                        face_index: np.ndarray) -> tuple[FitReport, int]:
    """:func:`assess_fit` of stored anchored splats: each splat's distance is to its own
    anchor triangle (``face_index`` into ``faces``, all in range). Above
    :data:`MAX_SPLATS_JUDGED` splats, every k-th splat is judged (deterministic); returns the
    report and how many splats were judged."""
    from .nearest.reference import closest_points_on_triangles

    n = len(means)
    step = max(1, -(-n // MAX_SPLATS_JUDGED))
    pick = slice(None, None, step)
    mu = np.asarray(means[pick], np.float64)
    v = np.asarray(vertices, np.float64)
    tri = v[np.asarray(faces, np.intp)[np.asarray(face_index[pick], np.intp)]]
    _, _, dist = closest_points_on_triangles(mu, tri[:, 0], tri[:, 1], tri[:, 2])
    return assess_fit(mu, v, dist), len(mu)


def _percent(share: float) -> str:
    """A share as a percentage with two significant digits (``0%``, ``8.6%``, ``45%``)."""
    return f"{100 * share:.2g}%"


def _round_factor(factor: float) -> float:
    """The nearest power of ten, or the factor itself to 3 digits when none is close."""
    p = 10.0 ** round(np.log10(factor))
    return p if 0.8 <= factor / p <= 1.25 else float(f"{factor:.3g}")
