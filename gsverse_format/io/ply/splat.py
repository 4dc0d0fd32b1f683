"""The 3D Gaussian splatting (3DGS) PLY layout, built on the PLY container (:mod:`.container`).

:func:`read_splat_ply` reads the ``vertex`` element written by the reference 3DGS code and its
descendants::

    x y z [nx ny nz] f_dc_0..2 [f_rest_0..M-1] opacity scale_0..2 rot_0..3 [others...]

in any property order. The file stores *pre-activation* values; the model
(:class:`~gsverse_format.model.SplatCloud`) holds activated ones:

* ``opacity`` is a logit: ``opacities = sigmoid(opacity)`` (a stable form, no overflow).
* ``scale_i`` are natural logs: ``scales = exp(scale_i)``.
* ``rot_0..3`` is an unnormalized quaternion ``(w, x, y, z)``: it is normalized and reordered
  to the model's ``(x, y, z, w)``. A zero quaternion is an error.
* ``f_rest`` is **channel-major**: ``f_rest[c·(K−1) + (j−1)]`` is coefficient ``j``
  (1..K−1) of colour channel ``c``; it becomes ``sh[:, j, c]``. ``M = 3·(K−1)`` must be 0, 9,
  24 or 45 (SH degree 0..3). ``f_dc_c`` is ``sh[:, 0, c]``.
* Without ``f_dc_*``, ``red/green/blue`` give ``f_dc = (rgb − 0.5) / 0.28209479177387814``
  with ``rgb`` in [0, 1] (``uchar`` divided by 255, ``ushort`` by 65535, floats taken as is).
* ``nx ny nz`` (normals, unused by 3DGS) are dropped; any other scalar vertex property (for
  example ``filter_3D`` or ``binding_0``) is kept in ``SplatCloud.extra`` as float32.

Activations are computed in float64 and rounded once to float32. Values that are not finite
in a required property, decoded values beyond the float32 range (``exp`` of a log-scale above
88.72) and zero quaternions are rejected (or, asked to, kept for the caller to drop). SuperSplat/PlayCanvas compressed PLY files (element
``chunk``, ``packed_*`` properties) and 2D Gaussian splats (only ``scale_0``, ``scale_1``) are
recognised and refused with a clear message.

:func:`write_splat_ply` writes the inverse, all properties ``float``, in the order above
(``nx ny nz`` as zeros when ``normals=True``; extras after ``rot_3``), in any of the three
formats. Rotations are written as stored (``(x, y, z, w)`` → ``rot_0..3 = (w, x, y, z)``).
Two clamps keep every written value finite:

* opacities are clamped to ``[2⁻¹⁵², 1 − 2⁻²⁶]`` before the logit. No float32 value inside
  (0, 1) is affected: only 0 (→ logit −105.36) and 1 (→ logit 18.02) are, and both decode
  back to exactly 0.0 and 1.0 in float32. Values outside [0, 1] are clamped as well.
* scales below ``2⁻¹⁵²`` (zero, or negative) are written as ``log(2⁻¹⁵²) = −105.36``, which
  decodes back to exactly 0.0 in float32; every positive float32 scale is written unchanged.

Round-trip accuracy (PLY → SplatCloud → PLY, each stored float32 value ``v`` → ``v'``)
------------------------------------------------------------------------------------------
``log(exp(v))`` and ``logit(sigmoid(v))`` are not bit-exact once the activated value is
rounded to float32 (relative error ≤ 2⁻²⁴). The bounds below follow from that rounding and
hold on the sample files and on random values (both tested in ``tests/test_ply.py``):

* ``x y z``, ``f_dc_*``, ``f_rest_*`` and extra float properties: bit-exact.
* ``scale_i`` (log-scale ``L``, −87.3 ≤ L ≤ 88.7): ``|L' − L| ≤ 2⁻²⁴ + ulp(L)/2 ≤ 2⁻²³``
  (≈1.2e-7; measured maximum 2⁻²⁴ ≈ 6e-8), and bit-exact for ``|L| > 1``, where that error
  is below half a float32 step of ``L``. Below −87.3 the scale is a float32 subnormal and
  loses relative precision; below −103.9 it decodes to 0 and is re-written as −105.36.
* ``opacity`` (logit ``L``, −87.3 ≤ L ≤ 16.6): ``|L' − L| ≤ 2⁻²⁴·(1 + e^L) + ulp(L)``:
  bit-exact for ``L < −2``, ≤ 1.2e-7 for ``−2 ≤ L ≤ 0``, then growing with ``e^L`` as the
  opacity approaches 1, because float32 resolves opacities near 1 only in steps of 2⁻²⁴
  (measured: 4.8e-6 at L = 5, 7e-4 at L = 10, 0.1 at L = 15). In opacity space the error is
  below one float32 step: ``|sigmoid(L') − sigmoid(L)| ≤ 2⁻²⁴`` for every ``L``. Logits
  above ≈17.3 decode to opacity 1.0 and are re-written as 18.02; logits below −103.9 decode
  to 0.0 and are re-written as −105.36.
* ``rot_0..3``: the quaternion is re-written normalized, ``|q' − q/|q|| ≤ 2⁻²⁴`` per
  component (measured 3e-8), so files with unnormalized quaternions (common) reproduce the
  rotation, not the raw values.
* ``nx ny nz`` are dropped on reading (written as zeros with ``normals=True``); integer extra
  properties come back as floats; colours given only as ``red/green/blue`` come back as
  ``f_dc_*``.
"""
from __future__ import annotations

import os
import re
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...errors import FormatError, NonFiniteError, UsageError
from ...model import SplatAsset, SplatCloud, SplatPrimitive
from ...vocabulary import SH_C0
from .container import read_ply_elements, write_ply
from .header import PlyElement, PlyHeader, read_ply_header

__all__ = ["SH_C0", "OPACITY_CLAMP", "SCALE_FLOOR", "SH_REST_COUNTS", "sh_degree_of",
           "describe_ply", "read_splat_ply", "read_splat_means", "write_splat_ply",
           "read_ply_asset", "write_ply_asset"]

#: Opacities are clamped to this range before the logit is written (see the module docstring).
OPACITY_CLAMP = (2.0 ** -152, 1.0 - 2.0 ** -26)
#: Scales below this are written as ``log(SCALE_FLOOR)`` instead of ``log(0) = -inf``.
SCALE_FLOOR = 2.0 ** -152
#: Number of ``f_rest_*`` properties -> SH degree.
SH_REST_COUNTS = {0: 0, 9: 1, 24: 2, 45: 3}

_LAYOUT_SCALARS = ("x", "y", "z", "opacity", "scale_0", "scale_1", "scale_2",
                   "rot_0", "rot_1", "rot_2", "rot_3")
_DC = ("f_dc_0", "f_dc_1", "f_dc_2")
_RGB = ("red", "green", "blue")
_NORMALS = ("nx", "ny", "nz")
_F_REST = re.compile(r"f_rest_(\d+)\Z")
_COMPRESSED = ("compressed PLY (SuperSplat/PlayCanvas) is not the 3DGS PLY layout; "
               "read it as compressed-ply (gsverse-convert --from compressed-ply)")


def sh_degree_of(f_rest_count: int) -> int | None:
    """The SH degree (0..3) that ``f_rest_count`` properties ``f_rest_*`` stand for, or ``None``."""
    return SH_REST_COUNTS.get(f_rest_count)


@dataclass
class _Layout:
    element: PlyElement
    f_rest: list[str]
    sh_degree: int
    dc_source: str            # "f_dc" or "rgb"
    has_normals: bool
    extra: list[str]


def _splat_layout(header: PlyHeader, path: str) -> _Layout:
    vertex = header.element("vertex")
    names = set(vertex.names) if vertex is not None else set()
    if header.element("chunk") is not None or any(n.startswith("packed_") for n in names):
        raise FormatError(_COMPRESSED, path)
    if vertex is None:
        raise FormatError("no 'vertex' element: not a 3DGS splat PLY", path)
    lists = [p.name for p in vertex.properties if p.is_list]
    if lists:
        raise FormatError(f"vertex property {lists[0]!r} is a list; 3DGS splat PLY files store "
                          "one scalar per property", path)
    if {"scale_0", "scale_1"} <= names and "scale_2" not in names:
        raise FormatError("2D Gaussian splats (2DGS: only scale_0 and scale_1) are not supported; "
                          "only 3D Gaussian splats with scale_0..2 can be read", path)
    missing = [n for n in _LAYOUT_SCALARS if n not in names]
    dc_source = "f_dc"
    if not all(n in names for n in _DC):
        if any(n in names for n in _DC) or not all(n in names for n in _RGB):
            missing += [n for n in _DC if n not in names]
        else:
            dc_source = "rgb"
    if missing:
        if not names & {"opacity", "scale_0", "rot_0", *_DC}:
            raise FormatError("no 3DGS splat properties (x, opacity, scale_0, rot_0, f_dc_0 …): "
                              "not a Gaussian splat PLY (a mesh or point cloud?)", path)
        raise FormatError(f"missing required vertex properties: {', '.join(missing)}", path)
    rest = [n for n in vertex.names if _F_REST.match(n)]
    expected = [f"f_rest_{i}" for i in range(len(rest))]
    if sorted(rest, key=lambda n: int(n[len("f_rest_"):])) != expected:
        absent = sorted(set(expected) - set(rest), key=lambda n: int(n[7:]))
        raise FormatError(f"f_rest properties are not numbered f_rest_0..f_rest_{len(rest) - 1}"
                          + (f" (missing {absent[0]})" if absent else ""), path)
    degree = sh_degree_of(len(rest))
    if degree is None:
        raise FormatError(f"{len(rest)} f_rest properties do not match an SH degree 0..3 "
                          "(expected 0, 9, 24 or 45)", path)
    has_normals = all(n in names for n in _NORMALS)
    used = set(_LAYOUT_SCALARS) | set(rest) | set(_DC if dc_source == "f_dc" else _RGB)
    if has_normals:
        used |= set(_NORMALS)
    extra = [n for n in vertex.names if n not in used]
    return _Layout(vertex, expected, degree, dc_source, has_normals, extra)


def describe_ply(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Summary of a 3DGS splat PLY from its header alone (the body is not read).

    Keys: ``format``, ``count``, ``sh_degree``, ``has_normals``, ``color`` (``"f_dc"`` or
    ``"rgb"``), ``extra`` (property names kept in ``SplatCloud.extra``), ``elements``
    (name → row count) and ``comments``. Raises ``FormatError`` for non-splat or unsupported
    files, exactly as :func:`read_splat_ply` would for the header.
    """
    path = os.fspath(path)
    header = read_ply_header(path)
    layout = _splat_layout(header, path)
    return {
        "format": header.format,
        "count": layout.element.count,
        "sh_degree": layout.sh_degree,
        "has_normals": layout.has_normals,
        "color": layout.dc_source,
        "extra": list(layout.extra),
        "elements": {e.name: e.count for e in header.elements},
        "comments": list(header.comments),
    }


def _sigmoid(x: np.ndarray) -> np.ndarray:
    """Logistic function in float64 without overflow for any finite input."""
    x = np.asarray(x, dtype=np.float64)
    e = np.exp(-np.abs(x))
    return np.asarray(np.where(x >= 0, 1.0 / (1.0 + e), e / (1.0 + e)))


def _logit(p: np.ndarray) -> np.ndarray:
    p = np.clip(np.asarray(p, dtype=np.float64), *OPACITY_CLAMP)
    return np.asarray(np.log(p) - np.log1p(-p))


def _rows(k: int) -> str:
    return f"{k} row{'s' if k != 1 else ''}"


def _field_block(table: np.ndarray, names: list[str]) -> np.ndarray:
    """The named scalar fields of ``table`` as an (N, len(names)) array: a view into its rows
    when they are consecutive fields of one type (as in every 3DGS file), else a copy."""
    fields: dict[str, Any] = dict(table.dtype.fields or {})
    ftype, start = fields[names[0]][0], fields[names[0]][1]
    if table.flags.c_contiguous and all(
            fields[name][0] == ftype and fields[name][1] == start + i * ftype.itemsize
            for i, name in enumerate(names)):
        rows = table.view(np.uint8).reshape(len(table), table.dtype.itemsize)
        return rows[:, start:start + len(names) * ftype.itemsize].view(ftype)
    return np.stack([table[name] for name in names], axis=1)


def _all_finite(values: np.ndarray) -> bool:
    """Whether every value is finite, without a temporary the size of ``values``."""
    if values.dtype.kind != "f" or values.size == 0:
        return True
    return bool(np.isfinite(np.min(values)) and np.isfinite(np.max(values)))


def read_splat_means(path: str | os.PathLike[str]) -> np.ndarray:
    """Only the (N, 3) float32 means of a 3DGS splat PLY: the values :func:`read_splat_ply`
    gives as ``means``, without decoding or checking anything else (not even their
    finiteness), for a caller that needs the positions alone (source detection). The file is
    refused as :func:`read_splat_ply` refuses a file that is not a splat PLY."""
    path = os.fspath(path)
    _splat_layout(read_ply_header(path), path)
    vertex = read_ply_elements(path, elements=("vertex",))["vertex"]
    with np.errstate(over="ignore", invalid="ignore"):
        return np.array(_field_block(vertex, ["x", "y", "z"]), np.float32)


def read_splat_ply(path: str | os.PathLike[str], *, keep_nonfinite: bool = False) -> SplatCloud:
    """Read a 3DGS splat PLY into a :class:`SplatCloud` (activated values, (x, y, z, w)
    quaternions, coefficient-major SH). See the module docstring for the layout.

    Splats with values that are not finite (NaN or infinity in a required property, values
    beyond the float32 range once decoded, zero quaternions) are refused with a
    :class:`~gsverse_format.errors.NonFiniteError`; with ``keep_nonfinite`` they are kept,
    non-finite (a zero quaternion as a NaN rotation), for the caller to drop
    (:func:`gsverse_format.edit.nonfinite_rows`).

    The body is memory-mapped (:mod:`.binary_body`) and decoded straight into the model's
    float32 arrays: the SH coefficients are copied once, from the file's rows into their
    coefficient-major array; the float64 temporaries are per-splat scalars only.
    """
    path = os.fspath(path)
    layout = _splat_layout(read_ply_header(path), path)
    vertex = read_ply_elements(path, elements=("vertex",))["vertex"]
    n = len(vertex)
    dc_names = list(_DC if layout.dc_source == "f_dc" else ())
    blocks = {"means": ["x", "y", "z"], "dc": dc_names, "rest": layout.f_rest,
              "opacity": ["opacity"], "scales": ["scale_0", "scale_1", "scale_2"],
              "rot": ["rot_0", "rot_1", "rot_2", "rot_3"]}
    block = {key: _field_block(vertex, names) for key, names in blocks.items() if names}
    # Decode first into contiguous arrays, then check those (fast); only when a check fails
    # are the file's columns searched, to name the properties.
    k = (layout.sh_degree + 1) ** 2
    sh = np.empty((n, k, 3), np.float32)
    with np.errstate(over="ignore", invalid="ignore"):
        means = np.array(block["means"], np.float32)
        if layout.dc_source == "f_dc":
            sh[:, 0, :] = block["dc"]
        if k > 1:  # channel-major (N, 3·(K−1)) → (N, K−1, 3), one strided copy
            sh[:, 1:, :] = block["rest"].reshape(n, 3, k - 1).transpose(0, 2, 1)
        logit = block["opacity"][:, 0].astype(np.float64)  # NaN is refused below, not warned
        log_scales = block["scales"].astype(np.float64)
        q = block["rot"].astype(np.float64)[:, [1, 2, 3, 0]]      # (w, x, y, z) → (x, y, z, w)
    decoded = (means, sh if layout.dc_source == "f_dc" else sh[:, 1:, :], logit, log_scales, q)
    if not keep_nonfinite and not all(_all_finite(values) for values in decoded):
        bad = []
        for key, names in blocks.items():
            if names and not bool(np.all(np.isfinite(block[key]))):
                counts = np.count_nonzero(~np.isfinite(block[key]), axis=0)
                bad += [(name, int(c)) for name, c in zip(names, counts) if c]
        if bad:
            listed = ", ".join(f"{name} ({_rows(k)})" for name, k in bad[:6])
            more = f" and {len(bad) - 6} more properties" if len(bad) > 6 else ""
            raise NonFiniteError(f"{sum(k for _, k in bad)} NaN or Inf values in required "
                                 f"properties: {listed}{more}", path)

    def overflow(out: np.ndarray, what: str) -> None:
        """Refuse values that became infinite in float32 (the input's are finite)."""
        if not keep_nonfinite and not _all_finite(out):
            raise NonFiniteError(f"{int(np.count_nonzero(~np.isfinite(out)))} value(s) of "
                                 f"{what} exceed the float32 range", path)

    def f32(values: np.ndarray, what: str) -> np.ndarray:
        with np.errstate(over="ignore"):
            out = values.astype(np.float32, copy=False)
        overflow(out, what)
        return out

    overflow(means, "x, y, z")
    if layout.dc_source == "f_dc":
        overflow(sh[:, 0, :], "f_dc")
    else:
        for c, name in enumerate(_RGB):
            values = vertex[name].astype(np.float64)
            ptype = vertex.dtype[name].str[1:]
            if ptype[0] in "iu":
                values /= float(np.iinfo(ptype).max)
            elif not keep_nonfinite and not np.all(np.isfinite(values)):
                raise NonFiniteError(f"NaN or Inf values in {name}", path)
            sh[:, 0, c] = f32((values - 0.5) / SH_C0, name)
    if k > 1:
        overflow(sh[:, 1:, :], "f_rest")

    extra: dict[str, np.ndarray] = {}
    for name in layout.extra:
        source = vertex[name]
        with np.errstate(over="ignore", invalid="ignore"):
            extra[name] = source.astype(np.float32)
        if source.dtype.kind == "f" and source.dtype.itemsize > 4 and \
                not _all_finite(extra[name]):
            grown = int(np.count_nonzero(np.isfinite(source) & ~np.isfinite(extra[name])))
            if grown:
                raise FormatError(f"{grown} value(s) of {name} exceed the float32 range", path)
        del source
    # No view into the file is left: its pages are released here, before the float64 work.
    del block, vertex, decoded

    with np.errstate(invalid="ignore"):   # NaN logits kept with keep_nonfinite
        opacities = _sigmoid(logit).astype(np.float32)
    with np.errstate(over="ignore", invalid="ignore"):
        np.exp(log_scales, out=log_scales)
    scales = f32(log_scales, "exp(scale_0..2) (log-scales above 88.72)")
    del logit, log_scales

    peak = np.max(np.abs(q), axis=1, keepdims=True)
    zero = peak[:, 0] == 0.0
    if zero.any() and not keep_nonfinite:
        first = int(np.flatnonzero(zero)[0])
        raise NonFiniteError(f"{_rows(int(zero.sum()))} (first: row {first}) have a zero "
                             "rotation quaternion (rot_0..rot_3 all 0)", path)
    peak[zero] = np.nan   # kept: no rotation, a NaN quaternion for the caller to drop
    with np.errstate(invalid="ignore"):
        q /= peak
        q /= np.linalg.norm(q, axis=1, keepdims=True)

    return SplatCloud(means, q.astype(np.float32), scales, opacities, sh, extra=extra)


# --------------------------------------------------------------------------------------------
# Writing


def _splat_columns(cloud: SplatCloud, normals: bool) -> tuple[list[str], np.ndarray]:
    n, k = len(cloud), cloud.sh.shape[1]
    checks = {"means": cloud.means, "rotations": cloud.rotations, "scales": cloud.scales,
              "opacities": cloud.opacities, "sh": cloud.sh}
    for what, values in checks.items():
        if not np.all(np.isfinite(values)):
            raise UsageError(f"cannot write a splat PLY: {what} contain NaN or Inf values")
    zero = ~np.any(cloud.rotations != 0, axis=1)
    if zero.any():
        raise UsageError(f"cannot write a splat PLY: {int(zero.sum())} splats have a zero "
                         "rotation quaternion")
    rest = [f"f_rest_{i}" for i in range(3 * (k - 1))]
    names = ["x", "y", "z", *(_NORMALS if normals else ()), *_DC, *rest, "opacity",
             "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    taken = set(names) | set(_NORMALS)
    for name in cloud.extra:
        if not name or not (name.isascii() and name.isprintable()) or " " in name:
            raise UsageError(f"extra property name {name!r} cannot be written to PLY "
                             "(must be printable ASCII without spaces)")
        if name in taken or _F_REST.match(name) or name.startswith("packed_"):
            raise UsageError(f"extra property {name!r} clashes with a 3DGS layout property")
    names += list(cloud.extra)
    table = np.empty((n, len(names)), np.float32)
    col = 0

    def put(values: np.ndarray) -> None:
        nonlocal col
        values = np.asarray(values).reshape(n, int(np.prod(np.shape(values)[1:])))
        table[:, col:col + values.shape[1]] = values
        col += values.shape[1]

    put(cloud.means)
    if normals:
        put(np.zeros((n, 3), np.float32))
    put(cloud.sh[:, 0, :])
    if k > 1:  # (N, K−1, 3) → channel-major (N, 3, K−1)
        put(cloud.sh[:, 1:, :].transpose(0, 2, 1).reshape(n, 3 * (k - 1)))
    put(_logit(cloud.opacities).astype(np.float32))
    put(np.log(np.maximum(cloud.scales.astype(np.float64), SCALE_FLOOR)).astype(np.float32))
    put(cloud.rotations[:, [3, 0, 1, 2]])
    for values in cloud.extra.values():
        put(values)
    return names, table


def write_splat_ply(cloud: SplatCloud, path: str | os.PathLike[str], *, binary: bool = True,
                    byte_order: str = "<", normals: bool = False,
                    protect: Iterable[str | os.PathLike[str]] = ()) -> None:
    """Write ``cloud`` as a 3DGS splat PLY (pre-activation values, all ``float``).

    ``binary=False`` writes ASCII (9 significant digits: float32 values are reproduced
    exactly); ``byte_order`` is ``"<"`` (little endian, the usual) or ``">"``. ``normals=True``
    adds zero ``nx ny nz`` as the reference implementation does. Extra properties follow
    ``rot_3``. The file is written atomically; ``protect`` lists inputs it must not replace.
    """
    if byte_order not in ("<", ">"):
        raise UsageError(f"byte_order must be '<' or '>', got {byte_order!r}", path)
    if not isinstance(cloud, SplatCloud):
        raise UsageError(f"expected a SplatCloud, got {type(cloud).__name__}", path)
    try:
        names, table = _splat_columns(cloud, normals)
    except UsageError as exc:
        raise exc.with_path(path) from None
    fmt = "ascii" if not binary else ("binary_little_endian" if byte_order == "<"
                                      else "binary_big_endian")
    vertex = table.view(np.dtype([(name, np.float32) for name in names])).reshape(len(table))
    write_ply(path, {"vertex": vertex}, format=fmt, protect=protect)


# --------------------------------------------------------------------------------------------
# The format table's entries: a splat asset in the PLY file's own (3DGS) frame


def read_ply_asset(path: str | os.PathLike[str], *, keep_nonfinite: bool = False) -> SplatAsset:
    """Read a 3DGS splat PLY as a one-primitive :class:`SplatAsset` named after the file, in
    the file's own coordinate frame (the 3DGS frame; no rotation here); ``keep_nonfinite`` as
    for :func:`read_splat_ply`."""
    cloud = read_splat_ply(path, keep_nonfinite=keep_nonfinite)
    name = os.path.splitext(os.path.basename(os.fspath(path)))[0]
    return SplatAsset([SplatPrimitive(cloud, None, name)])


def write_ply_asset(asset: SplatAsset, path: str | os.PathLike[str], *,
                    protect: Iterable[str | os.PathLike[str]] = ()) -> None:
    """Write all splats of all primitives of ``asset`` as one 3DGS splat PLY (no anchoring),
    coordinates as they are (the caller puts them in the 3DGS frame)."""
    if not asset.primitives:
        raise UsageError("nothing to write: the asset has no splats", path)
    cloud = SplatCloud.concatenate([p.splats for p in asset.primitives])
    write_splat_ply(cloud, path, protect=protect)
