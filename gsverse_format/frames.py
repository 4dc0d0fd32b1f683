"""Triangle frames: the normative constructions of ``spec/README.md`` §Triangle frames.

All functions take triangles as an (F, 3, 3) float64 array ``tri[f, corner, xyz]`` and are
vectorized. Nothing here divides by zero or returns NaN for finite input: degenerate triangles
(zero or near-zero area) follow the fallback rules below.

Epsilons (dimensionless unless stated):

* ``EPS_DEGENERATE = 1e-6`` — a triangle is *degenerate* when its doubled area
  ``a = |e1 × e2|`` satisfies ``a <= EPS_DEGENERATE · ℓ²`` with ℓ its longest edge, i.e. its
  smallest height is at most 1e-6 of its longest edge. That is ~8x float32's unit roundoff, below
  which the cross product of float32 edges carries no reliable direction.
* ``GAMES_EPS = 1e-8`` — the absolute ε of the GaMeS parameterization (scene units), used only
  by the ``games`` profile exactly where GaMeS uses it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

EPS_DEGENERATE = 1e-6
GAMES_EPS = 1e-8

__all__ = ["EPS_DEGENERATE", "GAMES_EPS", "LocalFrames", "local_frames", "games_frames",
           "perpendicular_unit", "degenerate_mask", "regular_mask"]


def _norm(v: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("...i,...i->...", v, v))


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def perpendicular_unit(t: np.ndarray) -> np.ndarray:
    """A deterministic unit vector perpendicular to unit vectors ``t`` (..., 3).

    ``normalize(t × a)`` where ``a`` is the coordinate axis with the smallest ``|t_k|``
    (lowest k on ties). Used only for degenerate triangles.
    """
    t = np.asarray(t, dtype=np.float64)
    axis = np.argmin(np.abs(t), axis=-1)
    a = np.zeros_like(t)
    np.put_along_axis(a, axis[..., None], 1.0, axis=-1)
    p = np.cross(t, a)
    return p / _norm(p)[..., None]


def _edges(tri: np.ndarray):
    e1 = tri[:, 1] - tri[:, 0]
    e2 = tri[:, 2] - tri[:, 0]
    e3 = tri[:, 2] - tri[:, 1]
    cross = np.cross(e1, e2)
    area2 = _norm(cross)
    # squared lengths: the longest edge and its ties are decided on |e|² (spec §Triangle frames)
    q1, q2, q3 = _dot(e1, e1), _dot(e2, e2), _dot(e3, e3)
    squared = np.stack([q1, q2, q3], axis=-1)
    longest2 = np.maximum(np.maximum(q1, q2), q3)   # = squared.max(-1), a third of the time
    return e1, e2, e3, cross, area2, squared, longest2


def _regular(area2: np.ndarray, longest2: np.ndarray) -> np.ndarray:
    return area2 > EPS_DEGENERATE * longest2


def regular_mask(tri: np.ndarray) -> np.ndarray:
    """(F,) bool: :attr:`LocalFrames.regular` of triangles (F, 3, 3) without the frames (a
    third of the work: the edges and the doubled area only)."""
    _, _, _, _, area2, _, longest2 = _edges(np.asarray(tri, dtype=np.float64))
    return _regular(area2, longest2)


def degenerate_mask(tri: np.ndarray) -> np.ndarray:
    """(F,) bool: triangles with ``|e1 × e2| <= EPS_DEGENERATE · ℓ²`` (ℓ = longest edge)."""
    _, _, _, _, area2, _, longest2 = _edges(np.asarray(tri, dtype=np.float64))
    return area2 <= EPS_DEGENERATE * longest2


@dataclass
class LocalFrames:
    """Per-triangle frame of the ``local`` profile.

    * ``rotation`` (F, 3, 3): columns ``[t, b, n]`` (right-handed, orthonormal).
    * ``shape``    (F, 2, 2): edge matrix ``C`` with columns = (e1, e2) in (t, b) coordinates;
      upper triangular ``[[|e1|, e2·t], [0, a/|e1|]]`` for regular triangles.
    * ``area2``    (F,): doubled area ``a = |e1 × e2|`` (the true value, also for degenerate
      triangles: spec v1.1 no longer sets it to 0).
    * ``cross``    (F, 3): ``e1 × e2``.
    * ``regular``  (F,): True where the triangle is not degenerate.
    """

    origin: np.ndarray
    rotation: np.ndarray
    shape: np.ndarray
    area2: np.ndarray
    regular: np.ndarray
    cross: np.ndarray | None = None

    @property
    def normal(self) -> np.ndarray:
        return self.rotation[:, :, 2]


def local_frames(tri: np.ndarray) -> LocalFrames:
    """Frames of the ``local`` profile for triangles (F, 3, 3) (spec §Triangle frames).

    Regular triangle: t = e1/|e1|, n = (e1 × e2)/a, b = n × t.
    Degenerate, ℓ > 0 (a segment): t = unit vector of the longest of (e1, e2, e2 − e1) by
    squared length, the first on exact ties; n = perpendicular_unit(t); b = n × t;
    C = [[e1·t, e2·t], [0, 0]].
    All corners coincide (ℓ = 0): t, b, n = x, y, z axes; C = 0.
    """
    tri = np.asarray(tri, dtype=np.float64)
    e1, e2, e3, cross, area2, squared, longest2 = _edges(tri)
    f = tri.shape[0]
    regular = _regular(area2, longest2)
    point = longest2 == 0.0
    line = ~regular & ~point

    t = np.zeros((f, 3))
    n = np.zeros((f, 3))
    shape = np.zeros((f, 2, 2))

    if np.any(regular):
        # every triangle regular (the usual mesh): a slice, so no masked copies (the same
        # values; 100k faces 27 -> 19 ms)
        r: slice | np.ndarray = slice(None) if regular.all() else regular
        len1 = np.sqrt(squared[r, 0])
        t[r] = e1[r] / len1[:, None]
        n[r] = cross[r] / area2[r, None]
        shape[r, 0, 0] = len1
        shape[r, 0, 1] = _dot(e2[r], t[r])
        shape[r, 1, 1] = area2[r] / len1
    if np.any(line):
        which = np.argmax(squared[line], axis=-1)  # argmax returns the first maximum
        d = np.stack([e1[line], e2[line], e3[line]], axis=1)[np.arange(which.size), which]
        t[line] = d / np.sqrt(longest2[line])[:, None]
        n[line] = perpendicular_unit(t[line])
        shape[line, 0, 0] = _dot(e1[line], t[line])
        shape[line, 0, 1] = _dot(e2[line], t[line])
    if np.any(point):
        t[point] = (1.0, 0.0, 0.0)
        n[point] = (0.0, 0.0, 1.0)
    b = np.cross(n, t)
    rotation = np.stack([t, b, n], axis=-1)
    return LocalFrames(tri[:, 0].copy(), rotation, shape, area2, regular, cross)


def games_frames(tri: np.ndarray):
    """GaMeS frame and base scales for triangles (F, 3, 3) (spec §The games profile).

    Returns ``(rotation (F,3,3) with columns [n, b1, b2], base_scales (F,3), centroid (F,3))``.
    Everything is relative to the first corner: g = c − v0 = (e1 + e2)/3, u = v1 − c = e1 − g,
    w = v2 − c = e2 − g, ℓ the longest edge, a = |e1 × e2|.

    * regular (a > ε_deg ℓ²): n = (e1 × e2)/a;  b1 = u/|u|;  b2 = n × b1;
    * degenerate, |u| > ε_deg ℓ: b1 = u/|u|; r = w − (w·b1) b1; b2 = r/|r| if |r| > ε_deg ℓ,
      else perpendicular_unit(b1); n = b1 × b2;
    * degenerate, |u| ≤ ε_deg ℓ, ℓ > 0 (v1 at the centroid: v1 is the midpoint of v0v2):
      b2 = w/|w|; b1 = perpendicular_unit(b2); n = b1 × b2 (the splat lies along w, as
      GaMeS's ε-regularized normalization gives);
    * ℓ = 0: n, b1, b2 = z, x, y.

    Base scales s = (ε, (|u| + ε)/2, (w·b2)/2) with ε = GAMES_EPS (GaMeS's values). In exact
    arithmetic the degenerate rules give the regular frame wherever both apply, so the frame
    is continuous across the threshold.
    """
    tri = np.asarray(tri, dtype=np.float64)
    e1, e2, _, cross, area2, _, longest2 = _edges(tri)
    regular = area2 > EPS_DEGENERATE * longest2
    ell = np.sqrt(longest2)
    g = (e1 + e2) / 3.0
    c = tri[:, 0] + g
    u = e1 - g
    w = e2 - g
    len_u = _norm(u)
    len_w = _norm(w)
    f = len(tri)
    n = np.zeros((f, 3))
    b1 = np.zeros((f, 3))
    b2 = np.zeros((f, 3))

    # a = 3 |u × w| <= 3 |u| |w| <= 2 |u| ℓ: a regular triangle has |u| > ε_deg ℓ / 2 > 0
    reg = regular
    has_u = regular | (len_u > EPS_DEGENERATE * ell)
    b1[has_u] = u[has_u] / len_u[has_u, None]
    n[reg] = cross[reg] / area2[reg, None]
    b2[reg] = np.cross(n[reg], b1[reg])

    deg_u = ~reg & has_u
    if np.any(deg_u):
        bb = b1[deg_u]
        r = w[deg_u] - _dot(w[deg_u], bb)[:, None] * bb
        len_r = _norm(r)
        ok = len_r > EPS_DEGENERATE * ell[deg_u]
        second = np.empty_like(bb)
        second[ok] = r[ok] / len_r[ok, None]
        if np.any(~ok):
            second[~ok] = perpendicular_unit(bb[~ok])
        b2[deg_u] = second
        n[deg_u] = np.cross(bb, second)

    mid = ~has_u & (longest2 > 0.0)
    if np.any(mid):
        b2[mid] = w[mid] / len_w[mid, None]
        b1[mid] = perpendicular_unit(b2[mid])
        n[mid] = np.cross(b1[mid], b2[mid])

    point = longest2 == 0.0
    n[point] = (0.0, 0.0, 1.0)
    b1[point] = (1.0, 0.0, 0.0)
    b2[point] = (0.0, 1.0, 0.0)

    base = np.stack([np.full(f, GAMES_EPS), (len_u + GAMES_EPS) / 2.0, _dot(w, b2) / 2.0], -1)
    rotation = np.stack([n, b1, b2], axis=-1)
    return rotation, base, c
