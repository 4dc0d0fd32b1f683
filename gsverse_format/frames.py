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
           "perpendicular_unit", "degenerate_mask"]


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
    lengths = np.stack([_norm(e1), _norm(e2), _norm(e3)], axis=-1)
    longest = lengths.max(axis=-1)
    return e1, e2, e3, cross, area2, lengths, longest


def degenerate_mask(tri: np.ndarray) -> np.ndarray:
    """(F,) bool: triangles with ``|e1 × e2| <= EPS_DEGENERATE · ℓ²`` (ℓ = longest edge)."""
    _, _, _, _, area2, _, longest = _edges(np.asarray(tri, dtype=np.float64))
    return area2 <= EPS_DEGENERATE * longest * longest


@dataclass
class LocalFrames:
    """Per-triangle frame of the ``local`` profile.

    * ``rotation`` (F, 3, 3): columns ``[t, b, n]`` (right-handed, orthonormal).
    * ``shape``    (F, 2, 2): edge matrix ``C`` with columns = (e1, e2) in (t, b) coordinates;
      upper triangular ``[[|e1|, e2·t], [0, a/|e1|]]`` for regular triangles.
    * ``area2``    (F,): doubled area ``a`` (0 for degenerate triangles).
    * ``regular``  (F,): True where the triangle is not degenerate.
    """

    origin: np.ndarray
    rotation: np.ndarray
    shape: np.ndarray
    area2: np.ndarray
    regular: np.ndarray

    @property
    def normal(self) -> np.ndarray:
        return self.rotation[:, :, 2]


def local_frames(tri: np.ndarray) -> LocalFrames:
    """Frames of the ``local`` profile for triangles (F, 3, 3) (spec §Triangle frames).

    Regular triangle: t = e1/|e1|, n = (e1 × e2)/a, b = n × t.
    Degenerate, ℓ > 0 (a segment): t = unit vector of the longest of (e1, e2, e2 − e1), first on
    ties; n = perpendicular_unit(t); b = n × t; C = [[e1·t, e2·t], [0, 0]]; a := 0.
    All corners coincide (ℓ = 0): t, b, n = x, y, z axes; C = 0; a := 0.
    """
    tri = np.asarray(tri, dtype=np.float64)
    e1, e2, e3, cross, area2, lengths, longest = _edges(tri)
    f = tri.shape[0]
    regular = area2 > EPS_DEGENERATE * longest * longest
    point = longest == 0.0
    line = ~regular & ~point

    t = np.zeros((f, 3))
    n = np.zeros((f, 3))
    shape = np.zeros((f, 2, 2))

    if np.any(regular):
        len1 = lengths[regular, 0]
        t[regular] = e1[regular] / len1[:, None]
        n[regular] = cross[regular] / area2[regular, None]
        shape[regular, 0, 0] = len1
        shape[regular, 0, 1] = _dot(e2[regular], t[regular])
        shape[regular, 1, 1] = area2[regular] / len1
    if np.any(line):
        which = np.argmax(lengths[line], axis=-1)  # argmax returns the first maximum
        d = np.stack([e1[line], e2[line], e3[line]], axis=1)[np.arange(which.size), which]
        t[line] = d / _norm(d)[:, None]
        n[line] = perpendicular_unit(t[line])
        shape[line, 0, 0] = _dot(e1[line], t[line])
        shape[line, 0, 1] = _dot(e2[line], t[line])
    if np.any(point):
        t[point] = (1.0, 0.0, 0.0)
        n[point] = (0.0, 0.0, 1.0)
    b = np.cross(n, t)
    rotation = np.stack([t, b, n], axis=-1)
    return LocalFrames(tri[:, 0].copy(), rotation, shape, np.where(regular, area2, 0.0), regular)


def games_frames(tri: np.ndarray):
    """GaMeS frame and base scales for triangles (F, 3, 3) (spec §The games profile).

    Returns ``(rotation (F,3,3) with columns [n, b1, b2], base_scales (F,3), centroid (F,3))``
    where, with c the centroid and w = v2 − c:

    * n  = (e1 × e2)/a;  b1 = (v1 − c)/|v1 − c|;  b2 = unit(w − (w·n) n − (w·b1) b1) = n × b1;
    * base scales s = (ε, (|v1 − c| + ε)/2, (w·b2)/2) with ε = GAMES_EPS (GaMeS's values).

    Degenerate triangles: b1 = unit(v1 − c) if v1 ≠ c, else unit(v2 − c) if v2 ≠ c, else x;
    n = perpendicular_unit(b1); b2 = n × b1. (The in-plane base scale then follows from w·b2.)
    """
    tri = np.asarray(tri, dtype=np.float64)
    _, _, _, cross, area2, _, longest = _edges(tri)
    regular = area2 > EPS_DEGENERATE * longest * longest
    c = tri.mean(axis=1)
    u1 = tri[:, 1] - c
    w = tri[:, 2] - c
    len_u1 = _norm(u1)

    b1 = np.zeros_like(u1)
    ok1 = len_u1 > 0.0
    b1[ok1] = u1[ok1] / len_u1[ok1, None]
    len_w = _norm(w)
    use_w = ~ok1 & (len_w > 0.0)
    b1[use_w] = w[use_w] / len_w[use_w, None]
    b1[~ok1 & ~use_w] = (1.0, 0.0, 0.0)

    n = np.zeros_like(u1)
    n[regular] = cross[regular] / area2[regular, None]
    n[~regular] = perpendicular_unit(b1[~regular])
    # For a regular triangle the Gram–Schmidt residual of w is parallel to n × b1 with a
    # positive coefficient (w·(n × b1) = a / (3 |v1 − c|) > 0), so b2 = n × b1 exactly.
    b2 = np.cross(n, b1)
    base = np.stack([np.full(len(tri), GAMES_EPS), (len_u1 + GAMES_EPS) / 2.0, _dot(w, b2) / 2.0], -1)
    rotation = np.stack([n, b1, b2], axis=-1)
    return rotation, base, c
