"""``GSVERSE_gaussian_splatting_mesh_anchor`` checks: schema, accessors, anchor mesh, values,
and the rest-pose consistency of spec §Rest-pose consistency.

The anchor mesh is checked once per anchor primitive (mode, positions, indices; degenerate,
sliver and duplicate triangles). For every anchored splat primitive the anchor accessors are
checked against the spec's format table (``gsverse_format.io.gltf.ANCHOR_ACCESSOR_FORMATS``),
their values per profile, and finally the reference remap at the rest mesh
(:func:`gsverse_format.remap.iter_moments`) is compared with the stored rest pose.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from gsverse_format.frames import EPS_DEGENERATE, degenerate_mask
from gsverse_format.io import gltf as G
from gsverse_format.model import Anchoring, GamesAnchors, LocalAnchors, TriangleMesh
from gsverse_format.remap import covariance_entries, iter_moments

from .container import Context
from .issues import TOLERANCES
from .khr import (SplatData, check_finite, check_nonnegative, check_unit_quaternions,
                  describe_format, format_allowed, quantization_step, tok)
from .schema import schema_errors

__all__ = ["AnchorMesh", "check_anchor", "anchor_mesh"]

ANCHOR = G.ANCHOR
_INDEX_TYPES = (G.UNSIGNED_BYTE, G.UNSIGNED_SHORT, G.UNSIGNED_INT)


@dataclass
class AnchorMesh:
    """A checked anchor primitive: the mesh (``None`` when unusable) and its triangle classes."""

    mesh: TriangleMesh | None
    degenerate: np.ndarray | None = None
    diagonal: float = 0.0


def _triangle_quality(ctx: Context, mesh: TriangleMesh, pointer: str) -> np.ndarray:
    """Report degenerate, sliver and duplicate triangles; return the degenerate mask."""
    tri = mesh.triangles()
    degenerate = degenerate_mask(tri)
    n_deg = int(np.count_nonzero(degenerate))
    f = mesh.face_count
    if n_deg:
        faces = np.flatnonzero(degenerate)
        ctx.issues.add("MESH_DEGENERATE_TRIANGLES", f"{n_deg} of {f} anchor triangles are "
                       f"degenerate (doubled area <= {EPS_DEGENERATE:g} x longest edge squared)",
                       pointer=pointer, count=n_deg,
                       examples=ctx.examples(faces, face=np.arange(f), corners=mesh.faces))
    e1 = tri[:, 1] - tri[:, 0]
    e2 = tri[:, 2] - tri[:, 0]
    e3 = tri[:, 2] - tri[:, 1]
    area2 = np.linalg.norm(np.cross(e1, e2), axis=1)
    longest2 = np.maximum(np.maximum(np.einsum("ij,ij->i", e1, e1), np.einsum("ij,ij->i", e2, e2)),
                          np.einsum("ij,ij->i", e3, e3))
    thin = ~degenerate & (area2 <= TOLERANCES["sliver"][0] * longest2)
    n_thin = int(np.count_nonzero(thin))
    if n_thin:
        faces = np.flatnonzero(thin)
        ratio = area2 / np.where(longest2 > 0, longest2, 1.0)
        ctx.issues.add("MESH_SLIVER_TRIANGLES", f"{n_thin} of {f} anchor triangles are slivers "
                       f"(doubled area <= {TOLERANCES['sliver'][0]:g} x longest edge squared)",
                       pointer=pointer, count=n_thin,
                       examples=ctx.examples(faces, face=np.arange(f), areaRatio=ratio))
    # Duplicates: the same three corner positions, in any order.
    v = mesh.vertices + np.float32(0.0)  # -0.0 -> 0.0 so equal positions have equal bytes
    keys = np.ascontiguousarray(v).view(np.dtype((np.void, 12))).ravel()
    _, vid = np.unique(keys, return_inverse=True)
    ids = np.sort(vid.reshape(-1)[mesh.faces.astype(np.intp)], axis=1).astype(np.int64)
    nv = int(ids.max()) + 1 if ids.size else 1
    if nv < 2 ** 21:
        key = (ids[:, 0] * nv + ids[:, 1]) * nv + ids[:, 2]
        _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    else:
        _, first, inverse = np.unique(ids, axis=0, return_index=True, return_inverse=True)
    partner = first[inverse.reshape(-1)]
    dup = np.flatnonzero(partner != np.arange(f))
    if dup.size:
        ctx.issues.add("MESH_DUPLICATE_TRIANGLES", f"{dup.size} of {f} anchor triangles repeat "
                       f"the corners of an earlier triangle", pointer=pointer,
                       count=int(dup.size),
                       examples=ctx.examples(dup, face=np.arange(f), duplicateOf=partner))
    return degenerate


def anchor_mesh(ctx: Context, m: int, p: int) -> AnchorMesh:
    """Check anchor primitive ``p`` of mesh ``m`` once; cached per (m, p)."""
    key = ("anchor", m, p)
    if key in ctx.cache:
        return ctx.cache[key]
    result = AnchorMesh(None)
    ctx.cache[key] = result
    pointer = f"/meshes/{m}/primitives/{p}"
    prim = ctx.array("meshes")[m]["primitives"][p]
    mode = prim.get("mode", 4)
    if mode != 4:
        ctx.issues.add("ANCHOR_MESH_NOT_TRIANGLES", f"the anchor primitive has mode {mode!r}; "
                       f"it must be TRIANGLES (4)", pointer=f"{pointer}/mode")
        return result
    attrs = prim.get("attributes", {})
    if "POSITION" not in attrs:
        ctx.issues.add("ANCHOR_MESH_POSITION_INVALID", "the anchor primitive has no POSITION",
                       pointer=f"{pointer}/attributes")
        return result
    lay = ctx.accessor(attrs["POSITION"], f"{pointer}/attributes/POSITION")
    if lay is None:
        return result
    if not format_allowed(lay, (("VEC3",), ((G.FLOAT, False),))):
        ctx.issues.add("ANCHOR_MESH_POSITION_INVALID", f"anchor POSITION is "
                       f"{describe_format(lay)}; it must be VEC3 FLOAT",
                       pointer=f"{pointer}/attributes/POSITION")
        return result
    vertices = ctx.floats(lay, f"{pointer} POSITION")
    if vertices is None or not check_finite(ctx, vertices, f"{pointer}/attributes/POSITION",
                                            "anchor mesh POSITION"):
        return result
    ipointer = f"{pointer}/indices"
    if prim.get("indices") is not None:
        ilay = ctx.accessor(prim["indices"], ipointer)
        if ilay is None:
            return result
        if ilay.gtype != "SCALAR" or ilay.component_type not in _INDEX_TYPES or ilay.normalized:
            ctx.issues.add("ANCHOR_MESH_INDICES_INVALID", f"anchor indices are "
                           f"{describe_format(ilay)}; they must be SCALAR UNSIGNED_BYTE, "
                           f"UNSIGNED_SHORT or UNSIGNED_INT", pointer=ipointer)
            return result
        raw = ctx.read(ilay, f"{pointer} indices")
        if raw is None:
            return result
        idx = raw[:, 0].astype(np.int64)
        if len(idx) % 3:
            ctx.issues.add("ANCHOR_MESH_INDICES_INVALID", f"{len(idx)} anchor indices, not a "
                           f"multiple of 3", pointer=ipointer)
            return result
        bad = np.flatnonzero(idx >= len(vertices))
        if bad.size:
            ctx.issues.add("ANCHOR_MESH_INDICES_INVALID", f"{bad.size} anchor indices are out of "
                           f"range for {len(vertices)} vertices", pointer=ipointer,
                           count=int(bad.size),
                           examples=ctx.examples(bad, index=np.arange(len(idx)), value=idx))
            return result
        faces = idx.reshape(-1, 3)
    else:
        if len(vertices) % 3:
            ctx.issues.add("ANCHOR_MESH_INDICES_INVALID", f"the anchor primitive is not indexed "
                           f"and has {len(vertices)} vertices, not a multiple of 3",
                           pointer=f"{pointer}/attributes/POSITION")
            return result
        faces = np.arange(len(vertices), dtype=np.int64).reshape(-1, 3)
    mesh = TriangleMesh(vertices, faces)
    result.mesh = mesh
    result.degenerate = _triangle_quality(ctx, mesh, pointer)
    span = vertices.astype(np.float64).max(axis=0) - vertices.astype(np.float64).min(axis=0)
    result.diagonal = float(np.linalg.norm(span))
    for n, node in enumerate(ctx.array("nodes")):
        if isinstance(node, dict) and node.get("mesh") == m:
            ctx.issues.add("ANCHOR_MESH_INSTANTIATED", f"node {n} instantiates the anchor mesh "
                           f"{m}; KHR-only viewers draw its triangles over the splats",
                           pointer=f"/nodes/{n}/mesh")
    return result


def _index(ctx: Context, value: Any, size: int, what: str, pointer: str) -> int | None:
    if isinstance(value, int) and not isinstance(value, bool) and 0 <= value < size:
        return value
    ctx.issues.add("UNRESOLVED_REFERENCE", f"{what} {value!r:.40} does not exist (there are "
                   f"{size})", pointer=pointer)
    return None


def check_anchor(ctx: Context, splat: SplatData, obj: Any, pointer: str) -> None:
    """Check the anchor extension object ``obj`` of ``splat`` (found at ``pointer``)."""
    errors = schema_errors(obj, pointer)
    for where, message in errors:
        ctx.issues.add("ANCHOR_SCHEMA_VIOLATION", f"{ANCHOR}: {message}", pointer=where)
    if not isinstance(obj, dict):
        return
    bad_props = {where[len(pointer) + 1:].split("/")[0] for where, _ in errors if where != pointer}

    # -- the anchor mesh ------------------------------------------------------------
    mesh_info: AnchorMesh | None = None
    meshes = ctx.array("meshes")
    if "mesh" in obj and "mesh" not in bad_props:
        m = _index(ctx, obj["mesh"], len(meshes), "anchor mesh", f"{pointer}/mesh")
        if m is not None:
            prims = meshes[m].get("primitives", [])
            p_value = obj.get("primitive", 0)
            p = None
            if "primitive" not in bad_props:
                p = _index(ctx, p_value, len(prims), "anchor primitive", f"{pointer}/primitive")
            if m == splat.mesh:
                ctx.issues.add("ANCHOR_MESH_SAME_AS_SPLAT", f"the anchor primitive is in mesh "
                               f"{m}, the splat primitive's own mesh", pointer=f"{pointer}/mesh")
            if p is not None:
                mesh_info = anchor_mesh(ctx, m, p)

    profile = obj.get("profile") if obj.get("profile") in ("local", "games") else None
    props = ["faceIndex", "barycentrics"]
    if profile == "local":
        props += ["normalOffset", "localRotation", "localScale"]
    elif profile == "games":
        props += ["rho"]
    vertex_attributes = set(splat.attributes.values())

    # -- accessors --------------------------------------------------------------------
    layouts: dict[str, G.AccessorLayout] = {}
    for prop in props:
        if prop not in obj or prop in bad_props:
            continue
        ppointer = f"{pointer}/{prop}"
        lay = ctx.accessor(obj[prop], ppointer)
        if lay is None:
            continue
        fmt = G.ANCHOR_ACCESSOR_FORMATS[prop]
        if not format_allowed(lay, fmt):
            ctx.issues.add("ANCHOR_ACCESSOR_FORMAT", f"{prop} is {describe_format(lay)}; see the "
                           f"spec's table of accessor component types", pointer=ppointer)
            continue
        if splat.count is not None and lay.count != splat.count:
            ctx.issues.add("ANCHOR_ACCESSOR_COUNT", f"{prop} has {lay.count} elements but the "
                           f"primitive has {splat.count} splats", pointer=ppointer)
            continue
        view = ctx.array("bufferViews")[lay.view]
        if view.get("target") is not None and lay.accessor not in vertex_attributes:
            ctx.issues.add("ANCHOR_ACCESSOR_TARGET", f"bufferViews[{lay.view}] of {prop} sets "
                           f"target {view.get('target')}; anchor data are not vertex attributes",
                           pointer=ppointer)
        layouts[prop] = lay
    if splat.count is None or (ctx.options.max_splats is not None
                               and splat.count > ctx.options.max_splats):
        return

    # -- values -----------------------------------------------------------------------
    ok = True
    face = None
    mesh = mesh_info.mesh if mesh_info is not None else None
    if "faceIndex" in layouts:
        raw = ctx.read(layouts["faceIndex"], f"{pointer}/faceIndex")
        if raw is not None:
            face = raw[:, 0].astype(np.int64)
            if face.size > 1 and bool(np.any(face[1:] < face[:-1])):
                ctx.issues.add("ANCHOR_NOT_SORTED", "the splats are not sorted by faceIndex "
                               "(sorted order is about 2x faster to remap)",
                               pointer=f"{pointer}/faceIndex")
    if face is None or mesh is None:
        ok = False
    else:
        out = np.flatnonzero(face >= mesh.face_count)
        if out.size:
            ctx.issues.add("ANCHOR_FACE_OUT_OF_RANGE", f"{out.size} of {len(face)} splats have "
                           f"a faceIndex >= {mesh.face_count}, the anchor triangle count",
                           pointer=f"{pointer}/faceIndex", count=int(out.size),
                           examples=ctx.examples(out, splat=np.arange(len(face)), face=face))
            ok = False
        elif mesh_info.degenerate.any():
            bound = np.flatnonzero(mesh_info.degenerate[face])
            if bound.size:
                ctx.issues.add("ANCHOR_BOUND_TO_DEGENERATE", f"{bound.size} of {len(face)} splats "
                               f"are bound to {np.unique(face[bound]).size} triangle(s) that are "
                               f"degenerate at rest", pointer=f"{pointer}/faceIndex",
                               count=int(bound.size),
                               examples=ctx.examples(bound, splat=np.arange(len(face)), face=face))

    def values(prop: str) -> np.ndarray | None:
        lay = layouts.get(prop)
        if lay is None:
            return None
        arr = ctx.floats(lay, f"{pointer}/{prop}")
        if arr is None or not check_finite(ctx, arr, f"{pointer}/{prop}", prop):
            return None
        return arr

    bary = values("barycentrics")
    if bary is not None:
        b1 = bary[:, 0].astype(np.float64)
        b2 = bary[:, 1].astype(np.float64)
        b0 = 1.0 - b1 - b2
        lowest = min(b0.min(), b1.min(), b2.min()) if len(b0) else 0.0

        def below(limit: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            """Splats with a weight below ``limit``, their (b0, b1, b2), their lowest weight."""
            if lowest >= limit:
                return np.zeros(0, np.intp), np.zeros((0, 3)), np.zeros(0)
            low = np.minimum(np.minimum(b0, b1), b2)
            idx = np.flatnonzero(low < limit)
            return idx, np.stack([b0, b1, b2], axis=1), low

        if profile == "games":
            tol = TOLERANCES["simplex"][0] + quantization_step(layouts["barycentrics"])
            bad, weights, low = below(-tol)
            if bad.size:
                ctx.issues.add("GAMES_BARYCENTRICS_OUTSIDE_SIMPLEX", f"{bad.size} of {len(b0)} "
                               f"games splats have barycentrics outside the triangle (smallest "
                               f"weight {low[bad].min():.3g}, tolerance {-tol:.3g})",
                               pointer=f"{pointer}/barycentrics", count=int(bad.size),
                               examples=ctx.examples(bad, splat=np.arange(len(b0)),
                                                     weights=weights))
        elif profile == "local":
            bound = -TOLERANCES["local_far"][0]
            far, weights, low = below(bound)
            if far.size:
                ctx.issues.add("LOCAL_BARYCENTRICS_FAR", f"{far.size} of {len(b0)} splats have a "
                               f"barycentric weight below {bound:g}: their foot point lies far "
                               f"outside their triangle (allowed by the spec)",
                               pointer=f"{pointer}/barycentrics", count=int(far.size),
                               examples=ctx.examples(far, splat=np.arange(len(b0)),
                                                     weights=weights))
    else:
        ok = False

    anchors = None
    if profile == "local":
        offset = values("normalOffset")
        rotation = values("localRotation")
        if rotation is not None and not check_unit_quaternions(
                ctx, rotation, layouts["localRotation"], f"{pointer}/localRotation",
                "localRotation"):
            rotation = None
        scale = values("localScale")
        if scale is not None and not check_nonnegative(ctx, scale, f"{pointer}/localScale",
                                                       "localScale"):
            scale = None
        scale_accessor = splat.attributes.get(f"{G.KHR}:SCALE")
        if "localScale" in layouts and scale_accessor is not None \
                and layouts["localScale"].accessor != scale_accessor:
            ctx.issues.add("LOCAL_SCALE_NOT_SHARED", f"localScale uses accessor "
                           f"{layouts['localScale'].accessor}, not the SCALE accessor "
                           f"{scale_accessor}", pointer=f"{pointer}/localScale")
        deformation = obj.get("deformation", "affine")
        if ok and offset is not None and rotation is not None and scale is not None \
                and deformation in ("affine", "rigid"):
            anchors = LocalAnchors(face, bary, offset[:, 0], rotation, scale, deformation)
    elif profile == "games":
        rho = values("rho")
        if rho is not None:
            neg = np.flatnonzero(rho[:, 0] < 0)
            if neg.size:
                ctx.issues.add("GAMES_RHO_NEGATIVE", f"{neg.size} of {len(rho)} splats have "
                               f"rho < 0 (their scales collapse to 1e-8)",
                               pointer=f"{pointer}/rho", count=int(neg.size),
                               examples=ctx.examples(neg, splat=np.arange(len(rho)),
                                                     rho=rho[:, 0]))
            if ok:
                anchors = GamesAnchors(face, bary, rho[:, 0])
    if anchors is not None and splat.rest_ok and not errors:
        _check_rest_pose(ctx, splat, Anchoring(mesh, anchors), mesh_info.diagonal)


def _check_rest_pose(ctx: Context, splat: SplatData, anchoring: Anchoring,
                     diagonal: float) -> None:
    """spec §Rest-pose consistency: the remap at the rest mesh against the stored rest pose."""
    n = len(anchoring.anchors)
    mean_tol = TOLERANCES["rest_mean"][0] * diagonal
    floor = (1e-7 * diagonal) ** 2
    rel_tol = TOLERANCES["rest_covariance"][0]
    mean_err = np.empty(n)
    cov_ratio = np.empty(n)
    cov_rel = np.empty(n)
    means, rotations, scales = splat.means, splat.rotations, splat.scales
    with np.errstate(all="ignore"):  # 0/0 for zero covariances on a zero-size mesh: not flagged
        _compare(anchoring, means, rotations, scales, mean_err, cov_ratio, cov_rel, rel_tol,
                 floor)
    k = ctx.options.max_examples
    index = np.arange(n)
    bad = np.flatnonzero(mean_err > mean_tol)
    if bad.size:
        worst = bad[np.argsort(-mean_err[bad], kind="stable")[:k]]
        ctx.issues.add("REST_POSE_MEAN_MISMATCH", f"{bad.size} of {n} stored means differ from "
                       f"the remap at the rest mesh by more than {mean_tol:.3g} (1e-5 x the "
                       f"anchor mesh diagonal {diagonal:.4g}); worst {mean_err[bad].max():.3g}",
                       pointer=f"{splat.pointer}/attributes/POSITION", count=int(bad.size),
                       examples=ctx.examples(worst, splat=index, error=mean_err))
    bad = np.flatnonzero(cov_ratio > 1.0)
    if bad.size:
        worst = bad[np.argsort(-cov_rel[bad], kind="stable")[:k]]
        ctx.issues.add("REST_POSE_COVARIANCE_MISMATCH", f"{bad.size} of {n} stored covariances "
                       f"differ from the remap at the rest mesh by more than {rel_tol:g} "
                       f"(relative Frobenius norm); worst {cov_rel[bad].max():.3g}",
                       pointer=f"{splat.pointer}/attributes/{tok(G.KHR + ':ROTATION')}",
                       count=int(bad.size),
                       examples=ctx.examples(worst, splat=index, relativeError=cov_rel))


def _compare(anchoring, means, rotations, scales, mean_err, cov_ratio, cov_rel, rel_tol,
             floor) -> None:
    """Fill the per-splat mean errors and covariance ratios, block by block."""
    for sl, mu, ref in iter_moments(anchoring):
        stored_mu = means[sl].astype(np.float64)
        dx = mu[0] - stored_mu[:, 0]
        dy = mu[1] - stored_mu[:, 1]
        dz = mu[2] - stored_mu[:, 2]
        mean_err[sl] = np.sqrt(dx * dx + dy * dy + dz * dz)
        got = covariance_entries(rotations[sl], scales[sl])
        d = [g - r for g, r in zip(got, ref)]
        diff = np.sqrt(d[0] * d[0] + d[3] * d[3] + d[5] * d[5]
                       + 2.0 * (d[1] * d[1] + d[2] * d[2] + d[4] * d[4]))
        norm = np.sqrt(ref[0] * ref[0] + ref[3] * ref[3] + ref[5] * ref[5]
                       + 2.0 * (ref[1] * ref[1] + ref[2] * ref[2] + ref[4] * ref[4]))
        cov_ratio[sl] = diff / (rel_tol * norm + floor)
        cov_rel[sl] = diff / np.where(norm > 0, norm, 1.0)
