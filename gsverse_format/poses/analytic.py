"""Analytic deformations of a mesh's vertices, for quick looks and for the conformance suite.

The functions (:func:`stretch`, :func:`stretch_along`, :func:`taper`, :func:`twist`,
:func:`bend`, :func:`shake`) take vertices (V, 3) and return new ones; the conformance cases
(:mod:`gsverse_format.conformance.case_tools`) use them with explicit centres and ranges.
:class:`QuickLook` and :func:`parse_deformations` are what ``gsverse-pose --deform`` uses: each
deformation is placed on the mesh's bounding box, along the glTF up axis (+Y):

* ``stretch=F``: scale by ``F`` along +Y about the box centre (1 = unchanged);
* ``twist=D``: rotate about the vertical axis through the box centre, by 0 at the bottom
  growing to ``D`` degrees at the top;
* ``bend=D``: bend the vertical axis into an arc of ``D`` degrees in the XY plane, keeping its
  length;
* ``shake=A``: move the mesh rigidly by up to ``A`` and jitter every vertex by a normal noise of
  standard deviation ``A / 4``, both in units of the box diagonal; seeded by the time, so every
  time shakes differently and the same time always the same way.

Several deformations apply in the order given. Only ``shake`` changes with the time
(:attr:`QuickLook.timed`): ``gsverse-pose`` writes the others alone once, never as identical
frames.
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

from ..errors import UsageError

__all__ = ["stretch", "stretch_along", "taper", "twist", "bend", "shake", "random_quaternions",
           "random_rotation", "QuickLook", "parse_deformations", "KINDS", "TIMED_KINDS"]

#: The quick-look deformations and what their amount means.
KINDS = {"stretch": "factor along +Y", "twist": "degrees", "bend": "degrees",
         "shake": "fraction of the bounding-box diagonal"}
#: The quick looks that change with the time (:attr:`QuickLook.timed`).
TIMED_KINDS = ("shake",)


def random_quaternions(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` uniformly random unit quaternions (x, y, z, w), w >= 0."""
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return np.where(q[:, 3:4] < 0, -q, q)


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random 3x3 rotation matrix."""
    x, y, z, w = random_quaternions(rng, 1)[0]
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])



def stretch(v: np.ndarray, factors, center) -> np.ndarray:
    """Scale about ``center`` by per-axis ``factors``."""
    c = np.asarray(center, dtype=np.float64)
    return c + (v - c) * np.asarray(factors, dtype=np.float64)


def stretch_along(v: np.ndarray, direction, factor: float, center) -> np.ndarray:
    """Scale by ``factor`` along unit ``direction`` about ``center``."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    rel = v - np.asarray(center, dtype=np.float64)
    along = rel @ d
    return v + (factor - 1.0) * along[:, None] * d[None, :]


def taper(v: np.ndarray, center, y0: float, y1: float, top: float) -> np.ndarray:
    """Scale x and z about the +Y axis through ``center`` by 1 → ``top`` from y0 to y1."""
    c = np.asarray(center, dtype=np.float64)
    s = 1.0 + (top - 1.0) * np.clip((v[:, 1] - y0) / (y1 - y0), 0.0, 1.0)
    out = v.copy()
    out[:, 0] = c[0] + (v[:, 0] - c[0]) * s
    out[:, 2] = c[2] + (v[:, 2] - c[2]) * s
    return out


def twist(v: np.ndarray, degrees: float, center, y0: float, y1: float) -> np.ndarray:
    """Rotate about the +Y axis through ``center`` by an angle growing linearly from 0 at
    y0 to ``degrees`` at y1."""
    c = np.asarray(center, dtype=np.float64)
    a = np.radians(degrees) * (v[:, 1] - y0) / (y1 - y0)
    x, z = v[:, 0] - c[0], v[:, 2] - c[2]
    out = v.copy()
    out[:, 0] = c[0] + np.cos(a) * x + np.sin(a) * z
    out[:, 2] = c[2] - np.sin(a) * x + np.cos(a) * z
    return out


def bend(v: np.ndarray, degrees: float, center, y0: float, y1: float) -> np.ndarray:
    """Bend the +Y axis through ``center`` (from y0 to y1) into a circular arc of total angle
    ``degrees`` in the XY plane, keeping arc length on the axis."""
    c = np.asarray(center, dtype=np.float64)
    theta_total = np.radians(degrees)
    radius = (y1 - y0) / theta_total
    s = v[:, 1] - y0
    xr = v[:, 0] - c[0]
    theta = s / radius
    out = v.copy()
    out[:, 0] = c[0] - radius + (radius + xr) * np.cos(theta)
    out[:, 1] = y0 + (radius + xr) * np.sin(theta)
    return out


def shake(v: np.ndarray, rng: np.random.Generator, center, amplitude: float,
          move: float) -> np.ndarray:
    """A random rigid motion about ``center`` (translation up to ``move``) plus independent
    per-vertex noise of standard deviation ``amplitude``."""
    c = np.asarray(center, dtype=np.float64)
    r = random_rotation(rng)
    t = rng.uniform(-move, move, 3)
    return (v - c) @ r.T + c + t + rng.normal(0.0, amplitude, v.shape)


@dataclass(frozen=True)
class QuickLook:
    """One quick-look deformation (``kind`` of :data:`KINDS`, ``amount``)."""

    kind: str
    amount: float

    @property
    def timed(self) -> bool:
        """Whether the look changes with the time (``shake``, seeded by it); the others give
        the same vertices at every time, so several times of them alone are one pose."""
        return self.kind in TIMED_KINDS

    def apply(self, v: np.ndarray, rest: np.ndarray, t: float = 0.0) -> np.ndarray:
        """``v`` (V, 3) deformed; the placement comes from the bounding box of ``rest``."""
        v = np.asarray(v, dtype=np.float64)
        rest = np.asarray(rest, dtype=np.float64)
        lo, hi = rest.min(axis=0), rest.max(axis=0)
        center = 0.5 * (lo + hi)
        y0, y1 = float(lo[1]), float(hi[1])
        if y1 <= y0:
            y1 = y0 + 1.0
        if self.kind == "stretch":
            return stretch_along(v, (0.0, 1.0, 0.0), self.amount, center)
        if self.kind == "twist":
            return twist(v, self.amount, center, y0, y1)
        if self.kind == "bend":
            if self.amount == 0.0:
                return v.copy()
            return bend(v, self.amount, center, y0, y1)
        diag = float(np.linalg.norm(hi - lo)) or 1.0
        rng = np.random.default_rng(zlib.crc32(np.float64(t).tobytes()))
        move = rng.uniform(-1.0, 1.0, 3) * self.amount * diag
        return v + move + rng.normal(0.0, 0.25 * self.amount * diag, v.shape)


#: The largest stretch factor (and the smallest, its inverse) and shake amount (in bounding-box
#: diagonals) of a quick look: beyond them the posed splats' covariances and positions overflow
#: float64 products (NumPy warned of it on stderr) long before anything is worth looking at.
MAX_STRETCH = 1e6
MAX_SHAKE = 1e3


def parse_deformations(specs: list[str] | None) -> list[QuickLook]:
    """``["stretch=1.5", "twist=90"]`` -> quick looks; :class:`UsageError` for anything else."""
    out = []
    for spec in specs or []:
        kind, sep, value = spec.partition("=")
        kind = kind.strip().lower()
        if kind not in KINDS or not sep:
            raise UsageError(f"--deform {spec!r}: use KIND=AMOUNT with KIND one of "
                             f"{', '.join(KINDS)}")
        try:
            amount = float(value)
        except ValueError:
            raise UsageError(f"--deform {spec!r}: the amount must be a number") from None
        if not np.isfinite(amount):
            raise UsageError(f"--deform {spec!r}: the amount must be finite")
        if kind == "stretch" and not 1.0 / MAX_STRETCH <= amount <= MAX_STRETCH:
            raise UsageError(f"--deform {spec!r}: a stretch factor must lie in "
                             f"{1.0 / MAX_STRETCH:g}..{MAX_STRETCH:g}")
        if kind == "shake" and not 0.0 <= amount <= MAX_SHAKE:
            raise UsageError(f"--deform {spec!r}: a shake amount must lie in 0..{MAX_SHAKE:g} "
                             f"(fractions of the bounding-box diagonal)")
        out.append(QuickLook(kind, amount))
    return out
