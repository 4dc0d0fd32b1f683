"""Reading the splat prims of an open USD stage (spec/usd.md §Reading).

:class:`StageReader` turns every ``ParticleField3DGaussianSplat`` prim into a
:class:`SplatPrimitive` and records each problem as a :class:`UsdProblem` with its issue code
instead of stopping: an error stops the prim concerned (an anchored prim is never read without
its anchors), a warning notes data replaced by the schema's defaults. The writer rules that a
reader does not need are checked by its subclass in :mod:`.checks`.
"""
from __future__ import annotations

import math
import types
from typing import Any, NoReturn, cast

import numpy as np

from ...codes import Code
from ...errors import FormatError
from ...model import (Anchoring, DeformationLaw, GamesAnchors, LocalAnchors, SplatAsset,
                      SplatCloud, SplatPrimitive, TriangleMesh, sh_coefficient_count)
from ...quaternion import unit_quaternions
from ...vocabulary import (DEFORMATIONS, PROFILES, USD_DEFORMATION, USD_PROFILE, AnchorField,
                           recorded_frame)
from .problems import UsdPrimInfo, UsdProblem
from .schema import (ANCHOR_API, COLOR_SPACE_API, COLOR_SPACE_ATTR, DEFAULT_COLOR_SPACE,
                     FIELDS, MESH_REL, REST_ATTRS, SH_COEFFS, SH_DEGREE, SPLAT_TYPE, USD_TYPES,
                     anchor_attribute_names, components, pxr, pxr_errors, usd_allowed_names, usd_required)
from .stage import input_errors, open_stage

__all__ = ["InvalidPrim", "StageReader", "read_in_process"]


class InvalidPrim(Exception):
    """Aborts reading one prim after an error was recorded."""


class StageReader:
    """Reads the splat prims of an open stage; records problems instead of stopping.

    ``errors`` stop the prim concerned (an anchored prim is never read without its anchors);
    ``warnings`` note data replaced by the schema's defaults. A reader for validators
    (``conformance``, see :class:`.checks.ConformanceReader`) keeps orientations, scales and
    opacities as authored (not normalized, made positive or clamped), so that validators can
    check the values themselves, and reports missing stage metadata as errors.
    """

    #: Whether the writer rules are checked too (set by the subclass that checks them).
    conformance = False

    def __init__(self, px: types.SimpleNamespace, stage: Any) -> None:
        self.px = px
        self.stage = stage
        self.problems: list[UsdProblem] = []
        self.meshes: dict[str, TriangleMesh | InvalidPrim] = {}
        self.mesh_prims: list[Any] = []
        #: Where every primitive read came from, in order.
        self.locations: list[UsdPrimInfo] = []
        self.up_axis = "Y"
        self.meters = 1.0
        self._mesh_key: str | None = None

    # -- recording
    def error(self, location: Any, message: str, code: Code) -> None:
        """Record an error and go on."""
        self.problems.append(UsdProblem("error", str(location), message, code))

    def fail(self, location: Any, message: str, code: Code) -> NoReturn:
        """Record an error and stop reading the prim (raise :class:`InvalidPrim`)."""
        self.error(location, message, code)
        raise InvalidPrim(message)

    def warn(self, location: Any, message: str, code: Code) -> None:
        """Record a warning."""
        self.problems.append(UsdProblem("warning", str(location), message, code))

    def rule(self, strict: bool, location: Any, message: str, code: Code) -> None:
        """A writer rule: an error for prims that claim conformance, else a warning."""
        if strict:
            self.error(location, message, code)
        else:
            self.warn(location, message, code)

    # -- values
    def specs(self, attr: Any) -> list[Any]:
        """The attribute's authored specs, strongest first.

        With the schemas registered, ``UsdAttribute.GetTypeName`` and ``IsCustom`` report the
        schema's declaration, not what the file authored; the specs tell the truth.
        """
        try:
            return list(attr.GetPropertyStack(self.px.Usd.TimeCode.Default()))
        except pxr_errors():
            return []

    def authored_type(self, attr: Any) -> Any:
        """The value type the file authored for ``attr`` (see :meth:`specs`); ``"relationship"``
        when the file authored a relationship of that name."""
        for spec in self.specs(attr):
            if not isinstance(spec, self.px.Sdf.AttributeSpec):
                return "relationship"
            if spec.typeName:
                return spec.typeName
        return attr.GetTypeName()

    def value(self, attr: Any) -> Any:
        """The default value (the rest pose) of ``attr`` if authored, else None."""
        if not attr or not attr.HasAuthoredValue():
            return None
        return attr.Get(self.px.Usd.TimeCode.Default())

    def array(self, attr: Any, components: int, *,
              exact_type: str | None = None) -> np.ndarray | None:
        """Default value of ``attr`` as a float/int numpy array, checked for shape and NaN.

        Returns None when unauthored (or authored only as time samples). Raises through
        :meth:`error` for a wrong type (``exact_type``: the Sdf type name required) or
        non-finite values.
        """
        value = self.value(attr)
        if value is None:
            return None
        where = attr.GetPath()
        if exact_type is not None:
            expected = getattr(self.px.Sdf.ValueTypeNames, exact_type)
            authored = self.authored_type(attr)
            if authored != expected:
                self.fail(where, f"has type {authored}, expected {expected}",
                          Code.USD_TYPE_MISMATCH)
        try:
            a: np.ndarray | None = np.array(value)
        except (TypeError, ValueError):
            a = None
        expected = (-1,) if components == 0 else (-1, components)
        if a is None or a.dtype.kind not in "fiu" or a.ndim != len(expected) or (
                components and a.shape[1] != components):
            self.fail(where, f"has type {attr.GetTypeName()}, not an array of "
                             f"{'scalars' if components == 0 else f'{components}-vectors'}",
                      Code.USD_TYPE_MISMATCH)
        assert a is not None
        if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
            self.fail(where, "contains NaN or infinite values", Code.NON_FINITE_VALUE)
        return a

    def token(self, attr: Any) -> str | None:
        """The default value of a token attribute, None when unauthored."""
        value = self.value(attr)
        if value is None:
            return None
        if not isinstance(value, str):
            self.fail(attr.GetPath(), f"has type {attr.GetTypeName()}, expected token",
                      Code.USD_TYPE_MISMATCH)
        return value

    # -- stage
    def read(self) -> SplatAsset:
        """Every splat prim of the stage that could be read, in +Y up and metres."""
        px = self.px
        splat_type = px.UsdVol.ParticleField3DGaussianSplat
        self.stage_checks()
        primitives: list[SplatPrimitive] = []
        for prim in self.stage.Traverse():
            if prim.IsA(splat_type):
                self._mesh_key = None
                try:
                    result = self.splat_prim(prim)
                except InvalidPrim:
                    continue
                if result is not None:
                    primitives.append(result)
                    apis = prim.GetPrimTypeInfo().GetAppliedAPISchemas()
                    self.locations.append(UsdPrimInfo(
                        str(prim.GetPath()),
                        self._mesh_key if result.anchoring is not None else None,
                        ANCHOR_API in apis or COLOR_SPACE_API in apis))
            elif prim.IsA(px.UsdVol.ParticleField):
                self.warn(prim.GetPath(), f"{prim.GetTypeName() or 'ParticleField'} prim is not "
                          f"a {SPLAT_TYPE} (no KHR_gaussian_splatting equivalent): skipped",
                          Code.USD_PARTICLE_FIELD_SKIPPED)
        asset = self.convert_units(SplatAsset(primitives, self.generator()))
        data = self.stage.GetRootLayer().customLayerData or {}
        asset.frame = recorded_frame(data.get("gsverse"))
        return asset

    def generator(self) -> str | None:
        """The ``generator`` of the root layer's ``customLayerData``."""
        data = self.stage.GetRootLayer().customLayerData or {}
        value = data.get("generator")
        return value if isinstance(value, str) else None

    def stage_checks(self) -> None:
        """Stage metadata: what a reader must honour (upAxis, metersPerUnit)."""
        px, stage = self.px, self.stage
        if stage.HasAuthoredMetadata("upAxis"):
            self.up_axis = str(px.UsdGeom.GetStageUpAxis(stage))
            if self.up_axis not in ("Y", "Z"):
                self.fail("", f"upAxis {self.up_axis!r} is neither 'Y' nor 'Z'",
                          Code.USD_UP_AXIS_INVALID)
            if self.up_axis == "Z":
                self.warn("", "upAxis is 'Z': read rotated into +Y up",
                          Code.USD_UP_AXIS_CONVERTED)
        elif self.conformance:
            self.error("", "stage does not author upAxis (must be 'Y')", Code.USD_UP_AXIS_MISSING)
        else:
            self.warn("", "stage does not author upAxis: read as 'Y'", Code.USD_UP_AXIS_MISSING)
        if stage.HasAuthoredMetadata("metersPerUnit"):
            self.meters = float(px.UsdGeom.GetStageMetersPerUnit(stage))
            if not (math.isfinite(self.meters) and self.meters > 0):
                self.fail("", f"metersPerUnit {self.meters} is not a positive number",
                          Code.USD_METERS_PER_UNIT_INVALID)
            if self.meters != 1.0:
                self.warn("", f"metersPerUnit is {self.meters:g}: read scaled to metres",
                          Code.USD_UNITS_CONVERTED)
        elif self.conformance:
            self.error("", "stage does not author metersPerUnit (must be 1)",
                       Code.USD_METERS_PER_UNIT_MISSING)
        else:
            self.warn("", "stage does not author metersPerUnit: read as metres (not the USD "
                          "fallback, centimetres)", Code.USD_METERS_PER_UNIT_MISSING)

    def convert_units(self, asset: SplatAsset) -> SplatAsset:
        """Z-up stages rotated to +Y up, other units scaled to metres (spec/usd.md)."""
        if self.up_axis == "Y" and self.meters == 1.0:
            return asset
        from ...transform import rotate_mesh, rotate_splats

        rotation = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]]) if self.up_axis == "Z" \
            else None
        m = self.meters
        meshes: dict[int, TriangleMesh] = {}

        def mesh_of(mesh: TriangleMesh) -> TriangleMesh:
            if id(mesh) not in meshes:
                out = rotate_mesh(mesh, rotation) if rotation is not None else mesh
                meshes[id(mesh)] = TriangleMesh(out.vertices.astype(np.float64) * m, out.faces)
            return meshes[id(mesh)]

        prims = []
        for p in asset.primitives:
            c = rotate_splats(p.splats, rotation) if rotation is not None else p.splats
            c = SplatCloud(c.means.astype(np.float64) * m, c.rotations,
                           c.scales.astype(np.float64) * m, c.opacities, c.sh, c.color_space,
                           dict(c.extra))
            anchoring = None
            if p.anchoring is not None:
                a = p.anchoring.anchors
                if isinstance(a, LocalAnchors):
                    a = LocalAnchors(a.face_index, a.barycentrics,
                                     a.normal_offset.astype(np.float64) * m, a.local_rotation,
                                     a.local_scale.astype(np.float64) * m, a.deformation)
                anchoring = Anchoring(mesh_of(p.anchoring.mesh), a)
            prims.append(SplatPrimitive(c, anchoring, p.name))
        return SplatAsset(prims, asset.generator)

    # -- splat prims
    def rest_array(self, prim: Any, name: str, n: int | None,
                   strict: bool) -> tuple[np.ndarray | None, Any]:
        """A rest-pose array, float preferred to half; None if it must be replaced by defaults.

        ``strict`` (anchored prims): missing or wrong-length arrays are errors. Otherwise the
        USD schema's rules: longer arrays are truncated, shorter ones ignored (warning).
        """
        rest = REST_ATTRS[name]
        attr = prim.GetAttribute(name)
        a = self.array(attr, rest.components)
        if a is None:
            attr = prim.GetAttribute(rest.half)
            a = self.array(attr, rest.components)
        if a is None:
            if strict:
                self.fail(prim.GetAttribute(name).GetPath(), "has no default value",
                          Code.USD_PROPERTY_MISSING)
            return None, attr
        a = a.astype(np.float32)
        if n is None:
            return a, attr
        if len(a) != n:
            if strict:
                self.fail(attr.GetPath(), f"has {len(a)} elements, positions has {n}",
                          Code.USD_LENGTH_MISMATCH)
            if len(a) < n:
                self.warn(attr.GetPath(), f"has {len(a)} elements for {n} particles: ignored, "
                          f"defaults used", Code.USD_REPLACED_BY_DEFAULT)
                return None, attr
            self.warn(attr.GetPath(), f"has {len(a)} elements for {n} particles: truncated",
                      Code.USD_TRUNCATED)
            a = a[:n]
        return a, attr

    def prim_rules(self, prim: Any, authored_apis: list[str], ours: bool) -> None:
        """The writer rules of a splat prim: none for reading (see :mod:`.checks`)."""

    def splat_prim(self, prim: Any) -> SplatPrimitive | None:
        """One splat prim (None when it has no particles and is skipped)."""
        path = prim.GetPath()
        authored_apis = list(prim.GetPrimTypeInfo().GetAppliedAPISchemas())
        anchored = ANCHOR_API in authored_apis
        ours = anchored or COLOR_SPACE_API in authored_apis
        self.prim_rules(prim, authored_apis, ours)

        positions, _ = self.rest_array(prim, "positions", None, anchored)
        if positions is None or len(positions) == 0:
            if anchored:
                self.fail(prim.GetAttribute("positions").GetPath(), "has no particles",
                          Code.USD_PROPERTY_MISSING)
            self.warn(path, "has no particles (no positions): skipped", Code.USD_EMPTY_PRIM)
            return None
        n = len(positions)
        rot, _ = self.rest_array(prim, "orientations", n, anchored)
        scales, _ = self.rest_array(prim, "scales", n, anchored)
        opac, _ = self.rest_array(prim, "opacities", n, anchored)
        sh = self.spherical_harmonics(prim, n, anchored)

        rot = np.tile(np.array([0, 0, 0, 1], np.float32), (n, 1)) if rot is None else rot
        scales = np.ones((n, 3), np.float32) if scales is None else scales
        opac = np.ones(n, np.float32) if opac is None else opac
        if not self.conformance:  # validators check the values as authored
            negative = np.flatnonzero(np.any(scales < 0, axis=1))
            if anchored and negative.size:   # they are the local scales unless authored apart
                self.fail(prim.GetAttribute("scales").GetPath(),
                          f"{negative.size} splat(s) with a negative scale (splat "
                          f"{int(negative[0])}); scales are linear, >= 0", Code.SCALE_NEGATIVE)
            rot, scales, opac = unit_quaternions(rot), np.abs(scales), np.clip(opac, 0.0, 1.0)

        cs_attr = prim.GetAttribute(COLOR_SPACE_ATTR)
        color_space = self.token(cs_attr)
        if color_space is None:
            color_space = DEFAULT_COLOR_SPACE
        cloud = SplatCloud(positions, rot, scales, opac, sh, color_space)
        anchoring = self.anchoring(prim, cloud) if anchored else None
        name = prim.GetDisplayName() or prim.GetName()
        return SplatPrimitive(cloud, anchoring, name)

    def spherical_harmonics(self, prim: Any, n: int, strict: bool) -> np.ndarray:
        """The SH coefficients (n, k, 3); the schema's rules for foreign prims."""
        degree_attr = prim.GetAttribute(SH_DEGREE)
        degree = degree_attr.Get() if degree_attr else None
        if degree is None:
            degree = 3  # the schema's fallback
        if not isinstance(degree, int) or isinstance(degree, bool):
            self.fail(degree_attr.GetPath(),
                      f"has type {degree_attr.GetTypeName()}, expected int",
                      Code.USD_TYPE_MISMATCH)
        coeffs = self.array(prim.GetAttribute(SH_COEFFS), 3)
        if coeffs is None:
            coeffs = self.array(prim.GetAttribute(SH_COEFFS + "h"), 3)
        where = prim.GetAttribute(SH_COEFFS).GetPath()
        if strict:
            if not 0 <= degree <= 3:
                self.fail(degree_attr.GetPath(), f"is {degree}, must be 0..3",
                          Code.USD_SH_DEGREE_INVALID)
            k = sh_coefficient_count(degree)
            got = 0 if coeffs is None else len(coeffs)
            if got != n * k:
                hint = (" (author radiance:sphericalHarmonicsDegree: its fallback is 3)"
                        if not degree_attr.HasAuthoredValue() else "")
                self.fail(where, f"has {got} elements, degree {degree} needs {n} x {k} = "
                                 f"{n * k}{hint}", Code.USD_LENGTH_MISMATCH)
            assert coeffs is not None  # n * k > 0 elements
            return coeffs.astype(np.float32).reshape(n, k, 3)
        default = np.zeros((n, 1, 3), np.float32)
        if degree < 0:
            self.warn(degree_attr.GetPath(), f"is {degree}: SH ignored, colour 0.5 used",
                      Code.USD_REPLACED_BY_DEFAULT)
            return default
        k_file = (degree + 1) ** 2
        if coeffs is None or len(coeffs) < n * k_file:
            got = 0 if coeffs is None else len(coeffs)
            self.warn(where, f"has {got} elements, degree {degree} needs {n * k_file}: ignored, "
                             f"colour 0.5 used", Code.USD_REPLACED_BY_DEFAULT)
            return default
        sh = coeffs[: n * k_file].astype(np.float32).reshape(n, k_file, 3)
        if degree > 3:
            self.warn(degree_attr.GetPath(), f"is {degree}: truncated to 3", Code.USD_TRUNCATED)
            sh = sh[:, :16]
        return sh

    def anchoring(self, prim: Any, cloud: SplatCloud) -> Anchoring:
        """The anchors and anchor mesh of a prim with ``GsVerseMeshAnchorAPI``."""
        n = len(cloud)
        attr = prim.GetAttribute
        profile = self.token(attr(USD_PROFILE))
        if profile not in PROFILES:
            self.fail(attr(USD_PROFILE).GetPath() if attr(USD_PROFILE)
                      else prim.GetPath().AppendProperty(USD_PROFILE),
                      "is missing" if profile is None else
                      f"is {profile!r}, must be {' or '.join(map(repr, PROFILES))}",
                      Code.USD_PROFILE_INVALID)
        allowed = usd_allowed_names(profile)
        for name in anchor_attribute_names():
            a = attr(name)
            if name not in allowed and a and a.HasAuthoredValue():
                message = f"must not be authored with the {profile} profile: ignored"
                if self.conformance:
                    self.error(a.GetPath(), message, Code.USD_PROPERTY_EXCLUDED)
                else:
                    self.warn(a.GetPath(), message, Code.USD_PROPERTY_EXCLUDED)
        required = usd_required(profile)

        def per_splat(field: AnchorField) -> np.ndarray | None:
            a = attr(field.usd)
            values = (self.array(a, components(field), exact_type=USD_TYPES[field.attribute].sdf)
                      if a else None)
            if values is None:
                if field in required:
                    self.fail(prim.GetPath().AppendProperty(field.usd),
                              f"is missing (required by the {profile} profile)",
                              Code.USD_PROPERTY_MISSING)
                return None
            if len(values) != n:
                self.fail(a.GetPath(), f"has {len(values)} elements, the prim has {n} particles",
                          Code.USD_LENGTH_MISMATCH)
            return values

        def need(field: AnchorField) -> np.ndarray:
            values = per_splat(field)
            assert values is not None  # per_splat stops the prim without a required field
            return values

        face_field = FIELDS["face_index"]
        face, bary = need(face_field), need(FIELDS["barycentrics"])
        mesh = self.anchor_mesh(prim)
        if face.size and (int(face.min()) < 0 or int(face.max()) >= mesh.face_count):
            bad = int(face.min()) if int(face.min()) < 0 else int(face.max())
            self.fail(attr(face_field.usd).GetPath(),
                      f"value {bad} out of range for anchor mesh with {mesh.face_count} "
                      f"triangles", Code.ANCHOR_FACE_OUT_OF_RANGE)
        face = face.astype(np.uint32)
        if profile != "local":
            return Anchoring(mesh, GamesAnchors(face, bary, need(FIELDS["rho"])))
        deformation = self.token(attr(USD_DEFORMATION)) or DEFORMATIONS[0]
        if deformation not in DEFORMATIONS:
            self.fail(attr(USD_DEFORMATION).GetPath(),
                      f"is {deformation!r}, must be {' or '.join(map(repr, DEFORMATIONS))}",
                      Code.USD_DEFORMATION_INVALID)
        offsets = need(FIELDS["normal_offset"])
        rotations = need(FIELDS["local_rotation"])
        local_scales = per_splat(FIELDS["local_scale"])
        if local_scales is None:  # the rest scales stand for it
            local_scales = cloud.scales
        if not self.conformance:  # validators check the values as authored
            zero = np.flatnonzero(~np.any(np.asarray(rotations) != 0, axis=1))
            if zero.size:
                self.fail(attr(FIELDS["local_rotation"].usd).GetPath(),
                          f"{zero.size} zero quaternion(s) (splat {int(zero[0])}); a "
                          f"rotation must have non-zero length", Code.ROTATION_NOT_UNIT)
            negative = np.flatnonzero(np.any(np.asarray(local_scales) < 0, axis=1))
            if negative.size:
                self.fail(prim.GetPath(), f"{negative.size} splat(s) with a negative local "
                          f"scale (splat {int(negative[0])}); scales are linear, >= 0",
                          Code.SCALE_NEGATIVE)
            rotations = unit_quaternions(rotations)
        return Anchoring(mesh, LocalAnchors(face, bary, offsets, rotations, local_scales,
                                            cast(DeformationLaw, deformation)))

    def anchor_mesh(self, prim: Any) -> TriangleMesh:
        """The anchor mesh the prim's relationship targets (read once per Mesh prim)."""
        rel = prim.GetRelationship(MESH_REL)
        where = rel.GetPath() if rel else prim.GetPath().AppendProperty(MESH_REL)
        targets = list(rel.GetTargets()) if rel else []
        if len(targets) != 1:
            self.fail(where, f"has {len(targets)} targets, must have exactly one (the anchor "
                              f"Mesh)", Code.USD_MESH_TARGET_INVALID)
        key = self._mesh_key = str(targets[0])
        if key not in self.meshes:
            try:
                self.meshes[key] = self.read_mesh(targets[0], where)
            except InvalidPrim as err:
                self.meshes[key] = err
                raise
        mesh = self.meshes[key]
        if isinstance(mesh, InvalidPrim):
            raise mesh
        return mesh

    def read_mesh(self, target: Any, rel_path: Any) -> TriangleMesh:
        """A ``Mesh`` prim as an anchor mesh: triangles only, indices in range, no holes."""
        px = self.px
        mesh_prim = self.stage.GetPrimAtPath(target)
        if not mesh_prim or not mesh_prim.IsA(px.UsdGeom.Mesh):
            self.fail(rel_path, f"target {target} is not a Mesh prim",
                      Code.USD_MESH_TARGET_INVALID)
        self.mesh_prims.append(mesh_prim)
        m = px.UsdGeom.Mesh(mesh_prim)
        points = self.array(m.GetPointsAttr(), 3)
        counts = self.array(m.GetFaceVertexCountsAttr(), 0, exact_type="IntArray")
        indices = self.array(m.GetFaceVertexIndicesAttr(), 0, exact_type="IntArray")
        for value, attr in ((points, m.GetPointsAttr()), (counts, m.GetFaceVertexCountsAttr()),
                            (indices, m.GetFaceVertexIndicesAttr())):
            if value is None:
                self.fail(attr.GetPath(), "has no default value", Code.USD_PROPERTY_MISSING)
        assert points is not None and counts is not None and indices is not None
        if counts.size and np.any(counts != 3):
            bad = int(np.flatnonzero(counts != 3)[0])
            self.fail(m.GetFaceVertexCountsAttr().GetPath(),
                      f"face {bad} has {int(counts[bad])} vertices: anchor meshes must be "
                      f"triangles only", Code.ANCHOR_MESH_NOT_TRIANGLES)
        if counts.size == 0:
            self.fail(m.GetFaceVertexCountsAttr().GetPath(), "has no faces",
                      Code.ANCHOR_MESH_NOT_TRIANGLES)
        if len(indices) != 3 * len(counts):
            self.fail(m.GetFaceVertexIndicesAttr().GetPath(),
                      f"has {len(indices)} elements for {len(counts)} triangles",
                      Code.USD_LENGTH_MISMATCH)
        if indices.size and (int(indices.min()) < 0 or int(indices.max()) >= len(points)):
            bad = int(indices.min()) if int(indices.min()) < 0 else int(indices.max())
            self.fail(m.GetFaceVertexIndicesAttr().GetPath(),
                      f"index {bad} out of range for {len(points)} points",
                      Code.ANCHOR_MESH_INDICES_INVALID)
        holes = self.value(m.GetHoleIndicesAttr())
        if holes is not None and len(holes):
            self.fail(m.GetHoleIndicesAttr().GetPath(), "must be empty for an anchor mesh",
                      Code.USD_MESH_HOLES)
        return TriangleMesh(points.astype(np.float32), indices.reshape(-1, 3))


def read_in_process(spath: str) -> tuple[SplatAsset, list[UsdProblem]]:
    """Read ``spath`` in this process: the asset and the problems (warnings only; the first
    error is raised as a :class:`FormatError`). Raises :class:`FormatError` for files USD
    cannot read, :class:`UsageError` without usd-core; any other exception is a bug here."""
    with input_errors(spath):
        px = pxr()
        stage = open_stage(px, spath)
        reader = StageReader(px, stage)
        try:
            asset: SplatAsset | None = reader.read()
        except InvalidPrim:
            asset = None
    errors = [p for p in reader.problems if p.severity == "error"]
    if errors:
        first = errors[0]
        where = f"{first.location}: " if first.location else ""
        raise FormatError(f"{where}{first.message}", spath)
    assert asset is not None  # reading stops early only after an error
    return asset, reader.problems
