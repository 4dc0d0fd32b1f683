"""The writer rules of spec/usd.md that a reader does not need, for validators.

:class:`ConformanceReader` reads a stage like :class:`.reader.StageReader` and also checks
stage metadata and layout, the authoring of the API schemas, the anchor-mesh rules and baked
animation; :func:`usd_validation` runs OpenUSD's own validators. :func:`inspect_in_process`
puts them together (``check_usd`` / ``inspect_usd`` run it, usually in a child process).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ...codes import Code
from ...model import SplatAsset
from .problems import UsdInspection, UsdProblem
from .reader import InvalidPrim, StageReader
from .schema import (ANCHOR_API, API_ATTRIBUTE_TYPES, COLOR_SPACE_API, COLOR_SPACE_ATTR,
                     DEFAULT_COLOR_SPACE, FIELDS, MESH_REL, REST_ATTRS, SH_COEFFS, SH_DEGREE,
                     SPLAT_TYPE, pxr)
from .stage import OutsideFolder, input_errors, open_stage

__all__ = ["ConformanceReader", "usd_validation", "inspect_in_process"]


def _floats(value: Any) -> np.ndarray | None:
    """``value`` as a float64 array, None when it holds no numbers."""
    try:
        return np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        return None


class ConformanceReader(StageReader):
    """A :class:`StageReader` that also checks the writer rules (``check_usd`` only): values
    are kept as authored, missing stage metadata and broken writer rules of prims that claim
    conformance (a GsVerse API schema) are errors, those of foreign prims warnings."""

    conformance = True

    def stage_checks(self) -> None:
        """Stage metadata, plus a defaultPrim that is an Xform."""
        super().stage_checks()
        root = self.stage.GetDefaultPrim()
        if not root:
            self.error("", "stage has no valid defaultPrim", Code.USD_DEFAULT_PRIM_MISSING)
        elif root.GetTypeName() != "Xform":
            kind = root.GetTypeName() or "typeless prim"
            self.error(root.GetPath(), f"the defaultPrim is a {kind}, not an Xform",
                       Code.USD_DEFAULT_PRIM_NOT_XFORM)

    def prim_rules(self, prim: Any, authored_apis: list[str], ours: bool) -> None:
        """Authoring rules of one splat prim: API schemas, hints, rest pose, extent, types."""
        path = prim.GetPath()
        if ANCHOR_API in authored_apis and COLOR_SPACE_API in authored_apis:
            self.error(path, f"applies both {ANCHOR_API} and {COLOR_SPACE_API} (the first "
                             f"includes the second)", Code.USD_BOTH_APIS)
        if not ours:
            self.warn(path, f"plain {SPLAT_TYPE} without {COLOR_SPACE_API}: read with colour "
                            f"space {DEFAULT_COLOR_SPACE}", Code.USD_PLAIN_SPLATS)
        else:
            cs = prim.GetAttribute(COLOR_SPACE_ATTR)
            if not cs or not cs.HasAuthoredValue():
                self.error(path.AppendProperty(COLOR_SPACE_ATTR), "must be authored",
                           Code.USD_PROPERTY_MISSING)
        sorting = prim.GetAttribute("sortingModeHint")
        if self.value(sorting) != "cameraDistance":
            self.rule(ours, sorting.GetPath(), "should be authored as 'cameraDistance' "
                      "(KHR's sortingMethod; the USD fallback is zDepth)", Code.USD_SORTING_MODE)
        if self.value(prim.GetAttribute("projectionModeHint")) is None:
            self.warn(path.AppendProperty("projectionModeHint"),
                      "not authored (SHOULD be 'perspective')", Code.USD_PROJECTION_MODE)
        if not prim.GetAttribute(SH_DEGREE).HasAuthoredValue():
            self.rule(ours, path.AppendProperty(SH_DEGREE),
                      "is not authored (its fallback is 3)", Code.USD_SH_DEGREE_MISSING)
        for full, rest in REST_ATTRS.items():
            a = prim.GetAttribute(rest.half)
            if a and a.HasAuthoredValue():
                self.rule(ours, a.GetPath(), "half-precision variant authored (writers use "
                          f"{full})", Code.USD_HALF_PRECISION)
            a = prim.GetAttribute(full)
            if a and a.HasAuthoredValue() and a.GetNumTimeSamples() and \
                    a.Get(self.px.Usd.TimeCode.Default()) is None:
                self.error(a.GetPath(), "has time samples but no default value (no rest pose)",
                           Code.USD_NO_REST_POSE)
        for name in ("opacities", SH_COEFFS, SH_DEGREE):
            a = prim.GetAttribute(name)
            if a and a.GetNumTimeSamples():
                self.error(a.GetPath(), "must not be time-sampled", Code.USD_TIME_SAMPLED)
        extent = self.value(prim.GetAttribute("extent"))
        positions = self.value(prim.GetAttribute("positions"))
        if extent is None:
            self.rule(ours, path.AppendProperty("extent"), "is not authored",
                      Code.USD_EXTENT_MISSING)
        elif positions is not None:
            e, p = _floats(extent), _floats(positions)
            # positions of another type are the reader's finding (USD_TYPE_MISMATCH)
            if p is not None and p.ndim == 2 and p.shape[1] == 3 and len(p) and (
                    e is None or e.shape != (2, 3) or np.any(p < e[0]) or np.any(p > e[1])):
                self.rule(ours, path.AppendProperty("extent"),
                          "does not contain every position", Code.USD_EXTENT_INVALID)
        for name, type_name in API_ATTRIBUTE_TYPES.items():
            a = prim.GetAttribute(name)
            if not a or not a.IsAuthored():
                continue
            if any(spec.custom for spec in self.specs(a)):
                self.error(a.GetPath(), "is authored as a custom attribute (must be the "
                           "schema's non-custom property)", Code.USD_CUSTOM_PROPERTY)
            if any(spec.variability != self.px.Sdf.VariabilityUniform
                   for spec in self.specs(a)):
                self.error(a.GetPath(), "must be uniform", Code.USD_NOT_UNIFORM)
            if a.GetNumTimeSamples():
                self.error(a.GetPath(), "must not be time-sampled", Code.USD_TIME_SAMPLED)
            expected = getattr(self.px.Sdf.ValueTypeNames, type_name)
            authored = self.authored_type(a)
            if authored != expected:
                self.error(a.GetPath(), f"has type {authored}, expected {expected}",
                           Code.USD_TYPE_MISMATCH)
        rel = prim.GetRelationship(MESH_REL)
        if rel and any(spec.custom for spec in rel.GetPropertyStack()):
            self.error(rel.GetPath(), "is authored as a custom relationship (must be the "
                       "schema's non-custom property)", Code.USD_CUSTOM_PROPERTY)
        if ANCHOR_API in authored_apis:
            local_name = FIELDS["local_scale"].usd
            local_scales = self.value(prim.GetAttribute(local_name))
            scales = self.value(prim.GetAttribute("scales"))
            if local_scales is not None and scales is not None and np.array_equal(
                    np.array(local_scales), np.array(scales)):
                self.warn(path.AppendProperty(local_name), "equals scales: should not be "
                          "authored", Code.USD_LOCAL_SCALES_REDUNDANT)
        if prim.GetAttribute("xformOpOrder").HasAuthoredValue():
            self.warn(path, "authors xformOps (splat prims should not)", Code.USD_XFORM_OPS)
        if prim.GetAttribute("colorSpace:name").HasAuthoredValue():
            self.warn(path, "UsdColorSpaceAPI colorSpace:name is ignored for splat prims",
                      Code.USD_COLOR_SPACE_API_IGNORED)

    def layout_rules(self, splat_paths: list[Any]) -> None:
        """Hierarchy and anchor-mesh rules (check_usd only)."""
        px = self.px
        root = self.stage.GetDefaultPrim()
        root_path = root.GetPath() if root else None
        gprim = px.UsdGeom.Gprim
        for path in splat_paths + [m.GetPath() for m in self.mesh_prims]:
            if root_path is not None and not path.HasPrefix(root_path):
                self.error(path, f"is not a descendant of the defaultPrim {root_path}",
                           Code.USD_OUTSIDE_DEFAULT_PRIM)
            parent = self.stage.GetPrimAtPath(path).GetParent()
            while parent and not parent.IsPseudoRoot():
                if parent.IsA(gprim):
                    self.error(path, f"is nested under the Gprim {parent.GetPath()}",
                               Code.USD_NESTED_GPRIM)
                    break
                parent = parent.GetParent()
        seen: set[Any] = set()
        for mesh_prim in self.mesh_prims:
            if mesh_prim.GetPath() in seen:
                continue
            seen.add(mesh_prim.GetPath())
            m = px.UsdGeom.Mesh(mesh_prim)
            path = mesh_prim.GetPath()
            if m.GetPurposeAttr().Get() != px.UsdGeom.Tokens.guide:
                self.warn(m.GetPurposeAttr().GetPath(), "should be 'guide'",
                          Code.USD_MESH_PURPOSE)
            if m.GetSubdivisionSchemeAttr().Get() != px.UsdGeom.Tokens.none:
                self.warn(m.GetSubdivisionSchemeAttr().GetPath(), "should be 'none'",
                          Code.USD_MESH_SUBDIVISION)
            if not m.GetExtentAttr().HasAuthoredValue():
                self.error(m.GetExtentAttr().GetPath(), "is not authored",
                           Code.USD_EXTENT_MISSING)
            for a in (m.GetFaceVertexCountsAttr(), m.GetFaceVertexIndicesAttr()):
                if a.GetNumTimeSamples():
                    self.error(a.GetPath(), "topology must not be time-sampled",
                               Code.USD_TIME_SAMPLED)
            if m.GetOrientationAttr().Get() != px.UsdGeom.Tokens.rightHanded:
                self.warn(m.GetOrientationAttr().GetPath(), "should be 'rightHanded' (it is "
                          "ignored for anchoring)", Code.USD_MESH_ORIENTATION)
            if mesh_prim.GetAttribute("xformOpOrder").HasAuthoredValue():
                self.warn(path, "authors xformOps (ignored for anchoring)", Code.USD_XFORM_OPS)

    def animation_rules(self, splat_prims: list[Any]) -> None:
        """Baked animation needs authored time codes."""
        stage = self.stage
        sampled = any(prim.GetAttribute(n).GetNumTimeSamples()
                      for prim in splat_prims for n in ("positions", "orientations", "scales"))
        if not sampled:
            return
        for key in ("startTimeCode", "endTimeCode", "timeCodesPerSecond"):
            if not stage.HasAuthoredMetadata(key):
                self.error("", f"baked animation without authored {key}",
                           Code.USD_TIME_CODES_MISSING)


def usd_validation(stage: Any) -> list[UsdProblem]:
    """The findings of OpenUSD's own validators (``pxr.UsdValidation``) on ``stage``."""
    from pxr import UsdValidation

    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    found = UsdValidation.ValidationContext(validators).Validate(stage)
    out = []
    for e in found:
        kind = e.GetType()
        if kind == UsdValidation.ValidationErrorType.Error:
            severity, code = "error", Code.USD_VALIDATOR_ERROR
        elif kind == UsdValidation.ValidationErrorType.Warn:
            severity, code = "warning", Code.USD_VALIDATOR_WARNING
        else:
            continue
        location = ""
        for site in e.GetSites():
            if site.IsProperty():
                location = str(site.GetProperty().GetPath())
            elif site.IsPrim():
                location = str(site.GetPrim().GetPath())
            if location:
                break
        validator = e.GetValidator()
        name = validator.GetMetadata().name if validator else e.GetName()
        out.append(UsdProblem(severity, location, " ".join(e.GetMessage().split()), code,
                              validator=str(name)))
    return out


def inspect_in_process(spath: str, *, usd_validation_too: bool = True) -> UsdInspection:
    """Check ``spath`` in this process: every problem, and the data as authored.

    Raises :class:`FormatError` when the file cannot be opened as a USD stage at all,
    :class:`UsageError` without usd-core; any other exception is a bug here.
    """
    with input_errors(spath):
        px = pxr()
        try:
            stage = open_stage(px, spath)
        except OutsideFolder as err:
            return UsdInspection([UsdProblem("error", "", err.cause,
                                             Code.USD_LAYER_OUTSIDE_FOLDER)], SplatAsset([]), [])
        reader = ConformanceReader(px, stage)
        try:
            asset = reader.read()
        except InvalidPrim:
            asset = SplatAsset([])
            reader.locations = []
        splats = [p for p in stage.Traverse() if p.IsA(px.UsdVol.ParticleField3DGaussianSplat)]
        reader.layout_rules([p.GetPath() for p in splats])
        reader.animation_rules(splats)
        problems = list(reader.problems)
        if usd_validation_too:
            problems += usd_validation(stage)
    return UsdInspection(problems, asset, list(reader.locations))
