"""Edits ``gsverse-convert`` makes to the splats and anchor meshes it reads, before binding.

Every edit acts in the **input file's frame** (the coordinates the file holds: the 3DGS
+Y-down frame of a PLY, glTF's +Y-up frame of a GLB), before the pipeline's frame change into
glTF, or with ``frame="output"`` in the **output's frame**, after it (glTF's, unless the
conversion keeps the input's frame). The output frame is the one splat-transform's actions
act in (it turns a PLY 180° about Z on reading, as this package does): there its numbers
mean the same, while in a PLY's own frame its ``-t x,y,z`` is ``translate (-x, -y, z)`` and
its ``-r a,b,c`` is ``rotate (-a, -b, c)`` (the 180° turn ``F`` about Z conjugates
``Rx(a)`` into ``Rx(-a)``, ``Ry(b)`` into ``Ry(-b)`` and keeps ``Rz(c)``:
``F R(a, b, c) F = R(-a, -b, c)``). The steps, in this order (step 1 involves no frame and
runs before the frame change in both cases; :meth:`SplatEdit.split`):

1. ``drop_nonfinite``: splats with a NaN or infinity in their mean, rotation, scales, opacity
   or SH, or a zero rotation quaternion (which no rotation is: the readers refuse it, and one
   asked to keep such rows passes it on as a NaN rotation), are dropped; the
   values are those decoded: a 3DGS PLY's opacity logit of −∞ is opacity 0 and its log-scale
   of −∞ a scale of 0, both finite and kept;
2. the similarity of the splats, ``x' = t + R (s x)``: uniform ``scale`` s > 0 first, then
   ``rotate`` R, then ``translate`` t; means, orientations (``q' = q_R ⊗ q``), linear scales
   (times s) and the SH coefficients (rotated exactly by :func:`gsverse_format.sh.rotate_sh`;
   a uniform scale leaves a splat's colour function as it is) move together, so that the
   covariance becomes ``Σ' = s² R Σ Rᵀ``; the same similarity, with its own values, for the
   anchor meshes (``mesh_scale``, ``mesh_rotate``, ``mesh_translate``: every ``--mesh``);
3. ``crop_box`` / ``crop_sphere``: only splats whose means lie inside (bounds included) are
   kept, tested on the edited means (after step 2, in the same frame);
4. ``min_opacity``: splats whose opacity (linear, after the sigmoid, as
   ``KHR_gaussian_splatting`` stores it) is below it are dropped.

Rotations are Euler angles in degrees ``(x, y, z)``, the convention of PlayCanvas's
``Quat.setFromEulerAngles`` (which splat-transform's ``--rotate`` uses): ``R = Rz(z) Ry(y)
Rx(x)``, a turn about the fixed X axis first, then about Y, then about Z (right-handed,
counter-clockwise looking down each axis). A non-uniform scale is refused: it would shear the
covariances out of the rotation-and-scales form and leave no exact SH rotation.

The transform math is float64, rounded once into the float32 arrays.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np

from . import quaternion as quat
from .errors import UsageError
from .model import SplatCloud, TriangleMesh
from .sh import rotate_sh

__all__ = ["SplatEdit", "Similarity", "EditCounts", "euler_matrix", "parse_numbers",
           "transform_splats", "transform_mesh", "nonfinite_rows", "inside_box",
           "inside_sphere", "edit_splats", "EDIT_FLAGS"]

#: ConvertOptions field -> (flag, how many numbers). ``scale`` and ``mesh_scale`` are one number.
EDIT_FLAGS: dict[str, tuple[str, int]] = {
    "translate": ("--translate", 3), "rotate": ("--rotate", 3), "scale": ("--scale", 1),
    "mesh_translate": ("--mesh-translate", 3), "mesh_rotate": ("--mesh-rotate", 3),
    "mesh_scale": ("--mesh-scale", 1), "crop_box": ("--crop-box", 6),
    "crop_sphere": ("--crop-sphere", 4), "min_opacity": ("--min-opacity", 1),
}


def parse_numbers(flag: str, value: Any, count: int) -> tuple[float, ...]:
    """``value`` (``"x,y,z"``, a number or a list of numbers) as ``count`` finite floats; a
    :class:`UsageError` naming ``flag`` otherwise (wrong count, not a number, NaN or
    infinity)."""
    if isinstance(value, str):
        parts: Sequence[Any] = [p for p in value.replace(" ", "").split(",")]
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        parts = [value]
    elif isinstance(value, (list, tuple)):
        parts = list(value)
    else:
        raise UsageError(f"{flag} takes {_numbers(count)}, not {value!r}")
    if len(parts) != count:
        raise UsageError(f"{flag} takes {_numbers(count)}, not {len(parts)} "
                         f"({_show(value)})")
    out = []
    for p in parts:
        try:
            if isinstance(p, bool):
                raise ValueError
            number = float(p)
        except (TypeError, ValueError):
            raise UsageError(f"{flag}: {p!r} is not a number ({_show(value)})") from None
        if not math.isfinite(number):
            raise UsageError(f"{flag}: {p!r} is not a finite number ({_show(value)})")
        out.append(number)
    return tuple(out)


def _numbers(count: int) -> str:
    return "one number" if count == 1 else f"{count} comma-separated numbers"


def _show(value: Any) -> str:
    return value if isinstance(value, str) else repr(value)


@dataclass(frozen=True)
class Similarity:
    """``x' = translate + R(rotate) (scale x)``: ``rotate`` Euler degrees (module docstring)."""

    translate: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotate: tuple[float, float, float] = (0.0, 0.0, 0.0)
    scale: float = 1.0

    @property
    def is_identity(self) -> bool:
        return self.translate == (0.0, 0.0, 0.0) and self.rotate == (0.0, 0.0, 0.0) \
            and self.scale == 1.0

    @property
    def matrix(self) -> np.ndarray:
        """The rotation R, float64 (3, 3)."""
        return euler_matrix(self.rotate)


@dataclass
class SplatEdit:
    """What :func:`edit_splats` does (see the module docstring); built from
    :class:`~gsverse_format.convert_options.ConvertOptions` by :meth:`from_options`."""

    splats: Similarity = field(default_factory=Similarity)
    mesh: Similarity = field(default_factory=Similarity)
    drop_nonfinite: bool = False
    crop_box: tuple[float, ...] | None = None
    crop_sphere: tuple[float, ...] | None = None
    min_opacity: float | None = None
    #: "input": the edits act in the input file's frame; "output": in the output's
    frame: str = "input"

    @classmethod
    def from_options(cls, options: Any, *, require_mesh: bool = True) -> "SplatEdit":
        """The edits ``options`` (a ``ConvertOptions``) ask for, checked: a
        :class:`UsageError` naming the flag for bad values, and for mesh edits without a
        mesh unless not ``require_mesh`` (a batch's assets may each name theirs)."""
        v: dict[str, Any] = {}
        for name, (flag, count) in EDIT_FLAGS.items():
            value = getattr(options, name)
            v[name] = None if value is None else parse_numbers(flag, value, count)
        for name in ("scale", "mesh_scale"):
            if v[name] is not None and not v[name][0] > 0:
                raise UsageError(f"{EDIT_FLAGS[name][0]} must be > 0, not {v[name][0]:g} (a "
                                 f"uniform scale; mirror with --rotate instead)")
        box, sphere = v["crop_box"], v["crop_sphere"]
        if box is not None and not all(box[i] <= box[i + 3] for i in range(3)):
            raise UsageError(f"--crop-box is XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX with each minimum "
                             f"<= its maximum, not {','.join(f'{b:g}' for b in box)}")
        if sphere is not None and not sphere[3] >= 0:
            raise UsageError(f"--crop-sphere radius must be >= 0, not {sphere[3]:g}")
        if v["min_opacity"] is not None and not 0 <= v["min_opacity"][0] <= 1:
            raise UsageError(f"--min-opacity must be in [0, 1] (opacity after the sigmoid), "
                             f"not {v['min_opacity'][0]:g}")

        def similarity(prefix: str) -> Similarity:
            t, r, s = (v[prefix + k] for k in ("translate", "rotate", "scale"))
            return Similarity(t if t is not None else (0.0, 0.0, 0.0),
                              r if r is not None else (0.0, 0.0, 0.0),
                              s[0] if s is not None else 1.0)

        if options.edit_frame not in ("input", "output"):
            raise UsageError(f"--edit-frame must be input or output, not {options.edit_frame!r}")
        edit = cls(similarity(""), similarity("mesh_"), bool(options.drop_nonfinite), box,
                   sphere, v["min_opacity"][0] if v["min_opacity"] is not None else None,
                   options.edit_frame)
        if require_mesh and not edit.mesh.is_identity and not (options.mesh or options.meshes):
            raise UsageError("--mesh-translate, --mesh-rotate and --mesh-scale move the anchor "
                             "meshes given with --mesh: give one")
        return edit

    @property
    def is_identity(self) -> bool:
        return all(getattr(self, f.name) in (None, False) for f in fields(self)
                   if f.name not in ("splats", "mesh", "frame")) \
            and self.splats.is_identity and self.mesh.is_identity

    def split(self) -> tuple["SplatEdit", "SplatEdit | None"]:
        """(what acts before the frame change, what acts after it): all of it before in the
        input frame; in the output frame only the dropping of non-finite splats (no frame
        involved) before, the rest after."""
        if self.frame == "input":
            return self, None
        return (SplatEdit(drop_nonfinite=self.drop_nonfinite),
                replace(self, drop_nonfinite=False))

    @property
    def filters(self) -> bool:
        """Whether any splats may be dropped."""
        return self.drop_nonfinite or self.crop_box is not None \
            or self.crop_sphere is not None or self.min_opacity is not None


@dataclass
class EditCounts:
    """How many splats each step dropped (the summary's ``edits``)."""

    nonfinite: int = 0
    cropped: int = 0
    below_opacity: int = 0


def euler_matrix(degrees: Sequence[float]) -> np.ndarray:
    """``R = Rz(z) Ry(y) Rx(x)`` for Euler angles ``(x, y, z)`` in degrees, float64 (3, 3)."""
    x, y, z = (math.radians(float(a)) for a in degrees)

    def axis(i: int, a: float) -> np.ndarray:
        c, s = math.cos(a), math.sin(a)
        j, k = (i + 1) % 3, (i + 2) % 3
        m = np.eye(3)
        m[j, j], m[j, k], m[k, j], m[k, k] = c, -s, s, c
        return m

    r = axis(2, z) @ axis(1, y) @ axis(0, x)
    # quarter turns come out exact: sin/cos of multiples of 90° are 1e-16 off 0 and ±1
    for target in (-1.0, 0.0, 1.0):
        r[np.abs(r - target) < 1e-15] = target
    return r


def transform_splats(cloud: SplatCloud, edit: Similarity) -> SplatCloud:
    """``cloud`` moved by the similarity ``edit`` (module docstring, step 2); a new cloud."""
    if edit.is_identity:
        return cloud
    r, s = edit.matrix, float(edit.scale)
    means = (cloud.means.astype(np.float64) @ (s * r).T) + np.asarray(edit.translate)
    if edit.rotate != (0.0, 0.0, 0.0):
        rotations = quat.canonical_sign(quat.multiply(quat.from_matrix(r),
                                                      quat.normalize(cloud.rotations)))
        sh = rotate_sh(cloud.sh, r) if cloud.sh_degree > 0 else cloud.sh
    else:
        rotations, sh = cloud.rotations, cloud.sh
    scales = cloud.scales if s == 1.0 else cloud.scales.astype(np.float64) * s
    return SplatCloud(means, rotations, scales, cloud.opacities, sh, cloud.color_space,
                      dict(cloud.extra))


def transform_mesh(mesh: TriangleMesh, edit: Similarity) -> TriangleMesh:
    """``mesh`` moved by the similarity ``edit`` (faces and their order unchanged; a rig's
    skin, morph targets and animations with it)."""
    if edit.is_identity:
        return mesh
    linear = edit.scale * edit.matrix
    translate = np.asarray(edit.translate, np.float64)
    rig = mesh.rig.transformed(linear, translate) if mesh.rig is not None else None
    return TriangleMesh(mesh.vertices.astype(np.float64) @ linear.T + translate, mesh.faces,
                        rig)


def nonfinite_rows(cloud: SplatCloud) -> np.ndarray:
    """Boolean (N,): splats with a NaN or infinity in mean, rotation, scales, opacity or SH,
    or a zero rotation quaternion (which no rotation is, as the readers hold)."""
    n = len(cloud)
    bad = ~np.isfinite(cloud.opacities) | ~np.any(cloud.rotations != 0, axis=1)
    for values in (cloud.means, cloud.rotations, cloud.scales):
        bad |= ~np.isfinite(values).all(axis=1)
    bad |= ~np.isfinite(cloud.sh.reshape(n, -1)).all(axis=1)
    return bad


def inside_box(means: np.ndarray, box: Sequence[float]) -> np.ndarray:
    """Boolean (N,): means inside ``box`` = (xmin, ymin, zmin, xmax, ymax, zmax), bounds in."""
    lo, hi = np.asarray(box[:3], np.float64), np.asarray(box[3:], np.float64)
    m = means.astype(np.float64)
    return np.all((m >= lo) & (m <= hi), axis=1)


def inside_sphere(means: np.ndarray, sphere: Sequence[float]) -> np.ndarray:
    """Boolean (N,): means within distance r of the centre, ``sphere`` = (x, y, z, r)."""
    d = means.astype(np.float64) - np.asarray(sphere[:3], np.float64)
    return np.einsum("ij,ij->i", d, d) <= float(sphere[3]) ** 2


def edit_splats(cloud: SplatCloud, edit: SplatEdit,
                counts: EditCounts) -> tuple[SplatCloud, np.ndarray | None]:
    """Steps 1–4 of the module docstring on ``cloud``: the edited cloud, and the indices of
    the input's splats it keeps (None: all of them, in order), for anchors that follow the
    splats. ``counts`` is added to."""
    keep: np.ndarray | None = None
    if edit.drop_nonfinite:
        bad = nonfinite_rows(cloud)
        if bad.any():
            counts.nonfinite += int(bad.sum())
            keep = np.flatnonzero(~bad)
            cloud = cloud.subset(keep)
    cloud = transform_splats(cloud, edit.splats)
    inside = np.ones(len(cloud), bool)
    if edit.crop_box is not None:
        inside &= inside_box(cloud.means, edit.crop_box)
    if edit.crop_sphere is not None:
        inside &= inside_sphere(cloud.means, edit.crop_sphere)
    counts.cropped += int(np.count_nonzero(~inside))
    if edit.min_opacity is not None:
        low = inside & (cloud.opacities < edit.min_opacity)
        counts.below_opacity += int(np.count_nonzero(low))
        inside &= ~low
    if not inside.all():
        index = np.flatnonzero(inside)
        cloud = cloud.subset(index)
        keep = index if keep is None else keep[index]
    return cloud, keep
