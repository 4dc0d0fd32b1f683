"""``KHR_gaussian_splatting`` glTF (.glb/.gltf) as the splat input.

Every ``KHR_gaussian_splatting`` primitive of the file is read (:func:`gsverse_format.io.gltf.
read_gltf`); positions are in the asset's local space, which is already the glTF frame (the
result's ``frame`` is ``"gltf"``: the pipeline applies no frame change).

* With ``--mesh``: the splats of all primitives are concatenated in file order (SH padded to
  the highest degree) and returned with the mesh (:func:`gsverse_format.io.mesh.read_mesh`,
  read as is: it must be in the same frame as the splats). Anchoring already present in the
  file is ignored — the pipeline binds every splat to its nearest triangle of the new mesh.
* Without a mesh the file must already be anchored. The first anchored primitive's anchor
  mesh and anchors are returned, together with every later primitive anchored to the *same*
  anchor mesh with the same profile (and, for ``local``, the same deformation law), splats and
  anchors concatenated in file order. Other primitives (plain splats, or anchored to another
  mesh) cannot share one anchor set and are left out; a note says how many splats that is and
  that ``--mesh`` rebinds everything to one mesh instead.
"""
from __future__ import annotations

import os

import numpy as np

from gsverse_format.converters.base import SourceOptions, SourceResult
from gsverse_format.converters.registry import register_source
from gsverse_format.errors import FormatError, UsageError
from gsverse_format.io.gltf import read_gltf
from gsverse_format.io.mesh import read_mesh
from gsverse_format.model import (Anchors, GamesAnchors, KhrProperties, LocalAnchors, SplatAsset,
                                  SplatCloud, SplatPrimitive, check_primitive)

__all__ = ["load", "detect", "require_valid_primitives"]


def require_valid_primitives(asset: SplatAsset, input_path: str) -> None:
    """Refuse an input whose primitives no writer would accept (:func:`~gsverse_format.model.
    check_primitive`: invalid splat values such as negative scales, anchors that do not match
    the splats or the anchor mesh) with a :class:`FormatError` naming the input, before any
    output is attempted: the problem is the input's, not the output's."""
    for i, prim in enumerate(asset.primitives):
        try:
            check_primitive(i, prim)
        except UsageError as err:
            raise FormatError(err.cause, input_path) from None


def _compatible(a: Anchors, b: Anchors) -> bool:
    if isinstance(a, LocalAnchors) and isinstance(b, LocalAnchors):
        return a.deformation == b.deformation
    return isinstance(a, GamesAnchors) and isinstance(b, GamesAnchors)


def _concat_anchors(items: list[Anchors]) -> Anchors:
    """One anchor set from compatible ones (:func:`_compatible`), in order."""
    local = [a for a in items if isinstance(a, LocalAnchors)]
    if local:
        return LocalAnchors(np.concatenate([a.face_index for a in local]),
                            np.concatenate([a.barycentrics for a in local]),
                            np.concatenate([a.normal_offset for a in local]),
                            np.concatenate([a.local_rotation for a in local]),
                            np.concatenate([a.local_scale for a in local]), local[0].deformation)
    games = [a for a in items if isinstance(a, GamesAnchors)]
    return GamesAnchors(np.concatenate([a.face_index for a in games]),
                        np.concatenate([a.barycentrics for a in games]),
                        np.concatenate([a.rho for a in games]))


def _common_khr(prims: list[SplatPrimitive], input_path: str) -> KhrProperties:
    """The KHR properties (kernel, projection, sorting method, nested extensions) shared by
    the primitives joined into one; primitives that differ cannot be joined."""
    first = prims[0].khr
    for prim in prims[1:]:
        if prim.khr != first:
            raise FormatError(f"splat primitives {prims[0].name or 'first'!r} and "
                              f"{prim.name or 'another'!r} differ in their "
                              f"KHR_gaussian_splatting kernel, projection, sorting method or "
                              f"nested extensions and cannot be joined into one", input_path)
    return first


def load(input_path: str, mesh_path: str | None, options: SourceOptions) -> SourceResult:
    """Splats of a KHR glTF, with ``mesh_path`` or with the file's own anchoring."""
    asset = read_gltf(input_path)
    prims: list[SplatPrimitive] = asset.primitives
    if not prims:
        raise FormatError("no KHR_gaussian_splatting primitive in the file", input_path)
    require_valid_primitives(asset, input_path)
    notes: list[str] = []
    total = sum(len(p.splats) for p in prims)
    if mesh_path is not None:
        splats = SplatCloud.concatenate([p.splats for p in prims])
        mesh = read_mesh(mesh_path)
        if len(prims) > 1:
            notes.append(f"{len(prims)} splat primitives joined ({total} splats)")
        if asset.anchored:
            notes.append("the file's own anchoring is ignored: splats are bound to --mesh")
        return SourceResult(splats, mesh, None, notes, {"primitives": len(prims)}, frame="gltf",
                            khr=_common_khr(prims, input_path))

    anchored = asset.anchored
    if not anchored:
        raise FormatError("the file has no anchored primitive and no mesh was given: pass the "
                          "anchor mesh with --mesh", input_path)
    pairs = [(p, p.anchoring) for p in anchored if p.anchoring is not None]
    first = pairs[0][1]
    chosen = [(p, a) for p, a in pairs
              if a.mesh is first.mesh and _compatible(a.anchors, first.anchors)]
    splats = SplatCloud.concatenate([p.splats for p, _ in chosen])
    anchors = _concat_anchors([a.anchors for _, a in chosen])
    left = total - len(splats)
    if left:
        notes.append(f"{left} splats of {len(prims) - len(chosen)} primitive(s) not anchored to "
                     f"the first anchor mesh were left out; pass --mesh to bind all {total} "
                     "splats to one mesh")
    notes.append(f"kept the file's {anchors.profile} anchoring of {len(splats)} splats "
                 f"({len(chosen)} primitive(s))")
    check = {"primitives": len(prims), "primitives_used": len(chosen), "splats_left_out": left}
    return SourceResult(splats, first.mesh, anchors, notes, check, frame="gltf",
                        khr=_common_khr([p for p, _ in chosen], input_path))


def detect(input_path: str, mesh_path: str | None) -> str | None:
    """A .glb/.gltf input is KHR_gaussian_splatting splats."""
    if os.path.splitext(input_path)[1].lower() in (".glb", ".gltf"):
        return "input is a glTF file (KHR_gaussian_splatting)"
    return None


register_source("khr", load, detect=detect, priority=20)
