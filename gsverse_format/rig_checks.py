"""The rules an animated anchor mesh's data keep (spec/README.md §Animated anchor meshes; glTF
2.0 §3.7.3 skins, §3.8 morph targets, §3.11 animations), written once: the converter refuses a
``--mesh`` rig that breaks one (:mod:`gsverse_format.io.gltf.rig_read`, a ``FormatError``) and
the validator reports the same in an output file (:mod:`gsverse_format.validators.rig`, by
``Code``).

Each check returns ``None`` when the data keep the rule, else what is wrong as a phrase that
follows the name of the thing checked ("key times (accessor 7) …"); callers name the thing.
"""
from __future__ import annotations

import numpy as np

__all__ = ["is_index", "key_times_problem", "non_finite_problem", "sampler_count_problem",
           "joints_out_of_range", "weights_count_problem"]

#: glTF 2.0 §3.11: how many output elements a sampler stores per key time.
_PER_KEY = {"LINEAR": 1, "STEP": 1, "CUBICSPLINE": 3}


def is_index(value: object, size: int) -> bool:
    """Whether ``value`` is an integer index into ``size`` things (``True`` is not one)."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool) \
        and 0 <= int(value) < size


def key_times_problem(times: np.ndarray) -> str | None:
    """A sampler's key times: at least one, finite, and none before the key it follows. glTF
    2.0 §3.11 asks for strictly increasing times; two equal neighbours (a jump) are accepted,
    as the web reader does (``plugins/web/src/animation.js``), since sampling them is defined."""
    t = np.asarray(times, dtype=np.float64).reshape(-1)
    if t.size == 0:
        return "hold no key time"
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        return f"hold NaN or infinity ({bad.size} of {t.size}, the first at key {int(bad[0])})"
    down = np.flatnonzero(np.diff(t) < 0.0)
    if down.size:
        k = int(down[0]) + 1
        return (f"decrease (key {k} at {t[k]:.6g} s follows {t[k - 1]:.6g} s; {down.size} "
                f"key(s) before the one they follow)")
    return None


def non_finite_problem(values: np.ndarray, what: str) -> str | None:
    """NaN or infinity among ``values`` (rows of elements), e.g. morph deltas, inverse bind
    matrices, key values, default weights."""
    v = np.asarray(values)
    if v.dtype.kind != "f":
        return None
    rows = v.reshape(len(v), -1) if v.ndim else v.reshape(1, 1)
    bad = np.flatnonzero(~np.isfinite(rows).all(axis=1))
    if bad.size:
        return f"hold NaN or infinity ({bad.size} of {len(rows)} {what}, the first at {int(bad[0])})"
    return None


def sampler_count_problem(keys: int, values: int, width: int, interpolation: object) -> str | None:
    """A sampler's output count: ``width`` values per key (morph weights: one per target), three
    times that for ``CUBICSPLINE`` (in-tangent, value, out-tangent)."""
    if interpolation not in _PER_KEY:
        return f"have the interpolation {interpolation!r} (LINEAR, STEP or CUBICSPLINE)"
    want = keys * width * _PER_KEY[str(interpolation)]
    if values != want:
        return (f"hold {values} output values for {keys} key times ({want} for "
                f"{interpolation} with {width} per key)")
    return None


def joints_out_of_range(joints: np.ndarray, joint_count: int) -> np.ndarray:
    """The vertices (indices) of a (V, 4) ``JOINTS_0`` with an index that is not one of the
    skin's ``joint_count`` joints."""
    j = np.asarray(joints)
    return np.flatnonzero(((j < 0) | (j >= joint_count)).any(axis=1)) if j.size else \
        np.zeros(0, np.intp)


def weights_count_problem(weights: object, target_count: int) -> str | None:
    """Default morph weights (a node's or a mesh's ``weights``): one finite number per target."""
    if not isinstance(weights, list):
        return f"are {type(weights).__name__}, not a list of numbers"
    if len(weights) != target_count:
        return f"are {len(weights)} for {target_count} morph targets"
    if not all(isinstance(w, (int, float)) and not isinstance(w, bool) and np.isfinite(w)
               for w in weights):
        return "are not all finite numbers"
    return None
