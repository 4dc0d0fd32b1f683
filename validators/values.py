"""Value checks shared by every file format: splat rest poses, anchor meshes, anchor data and
the rest-pose consistency of spec §Rest-pose consistency.

The glTF checks (:mod:`.khr`, :mod:`.anchor`) and the USD checks (:mod:`.usd`) read the data
their own way, then hand numpy arrays and a location for each property (a JSON pointer, or a
USD property path) to these functions, so that both formats report the same problem with the
same code, message and tolerance. Arrays are float32 or float64 as stored (quantized data
already dequantized); ``step`` arguments are the quantization step of normalized-integer
data (0 for floats), which widens the tolerances by one step.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import cast

import numpy as np

from gsverse_format.codes import Code
from gsverse_format.fit import assess_anchored_fit
from gsverse_format.frames import EPS_DEGENERATE, degenerate_mask
from gsverse_format.manifold import manifold_report
from gsverse_format.model import (Anchoring, DeformationLaw, GamesAnchors, LocalAnchors,
                                  TriangleMesh)
from gsverse_format.remapping.reference import covariance_entries, iter_moments
from gsverse_format.tolerances import (REST_COVARIANCE_FLOOR, REST_COVARIANCE_RELATIVE,
                                       mesh_extent, rest_mean_tolerance)

from .context import CheckContext
from .issues import TOLERANCES

__all__ = ["RestPose", "AnchorMesh", "AnchorValues", "check_finite", "check_unit_quaternions",
           "check_nonnegative", "check_opacities", "check_triangles", "check_anchor_values",
           "check_fit", "check_rest_pose"]


@dataclass
class RestPose:
    """A primitive's stored rest pose (means in metres, xyzw unit quaternions, linear scales)
    and where the means and the rotations are stored (for rest-pose findings)."""

    means: np.ndarray
    rotations: np.ndarray
    scales: np.ndarray
    mean_location: str
    covariance_location: str


@dataclass
class AnchorMesh:
    """A checked anchor mesh: the mesh (``None`` when unusable), its degenerate triangles, the
    diagonal D of its bounding box and its largest absolute coordinate L (the length scales
    of the rest-pose tolerance)."""

    mesh: TriangleMesh | None
    degenerate: np.ndarray | None = None
    diagonal: float = 0.0
    largest: float = 0.0


@dataclass
class AnchorValues:
    """The anchor data of one splat primitive as stored.

    ``arrays`` maps glTF property names (``faceIndex`` as int64 (N,); ``barycentrics`` (N, 2);
    ``normalOffset`` (N, 1); ``localRotation`` (N, 4); ``localScale`` (N, 3); ``rho`` (N, 1))
    to finite arrays; a property that is absent or unusable (already reported) is missing.
    ``where`` maps each property to its location, ``steps`` to its quantization step.
    """

    profile: str | None
    arrays: dict[str, np.ndarray]
    where: dict[str, str]
    steps: dict[str, float] = field(default_factory=dict)
    deformation: str = "affine"


# ---------------------------------------------------------------------------- splat values

def check_finite(ctx: CheckContext, values: np.ndarray, location: str, what: str) -> bool:
    """Report NON_FINITE_VALUE for rows of ``values`` with NaN/Inf; True when all finite."""
    if values.dtype.kind != "f" or bool(np.isfinite(values).all()):
        return True
    bad = np.flatnonzero(~np.isfinite(values.reshape(len(values), -1)).all(axis=1))
    ctx.issues.add(Code.NON_FINITE_VALUE, f"{what}: {bad.size} of {len(values)} elements hold NaN "
                   f"or infinity", pointer=location, count=int(bad.size),
                   examples=ctx.examples(bad, index=np.arange(len(values)), value=values))
    return False


def check_unit_quaternions(ctx: CheckContext, q: np.ndarray, step: float, location: str,
                           what: str) -> bool:
    """ROTATION_NOT_UNIT for quaternions whose length is off by more than the tolerance
    (``unit_quaternion`` plus ``step``); True when all are unit."""
    tol = TOLERANCES["unit_quaternion"][0] + step
    q64 = q.astype(np.float64)
    norm2 = np.square(q64, out=q64) @ np.ones(q.shape[1])  # row sums, one BLAS pass
    if len(norm2) == 0 or ((1.0 - tol) ** 2 <= norm2.min() and norm2.max() <= (1.0 + tol) ** 2):
        return True
    norm = np.sqrt(norm2)
    off = np.abs(norm - 1.0)
    bad = np.flatnonzero(off > tol)
    if bad.size == 0:
        return True
    worst = bad[np.argsort(-off[bad], kind="stable")]
    ctx.issues.add(Code.ROTATION_NOT_UNIT, f"{what}: {bad.size} of {len(q)} quaternions are not of "
                   f"unit length (| |q| - 1 | up to {off[bad].max():.3g}, tolerance {tol:.3g})",
                   pointer=location, count=int(bad.size),
                   examples=ctx.examples(worst, index=np.arange(len(q)), norm=norm))
    return False


def check_nonnegative(ctx: CheckContext, s: np.ndarray, location: str, what: str) -> bool:
    """SCALE_NEGATIVE for rows of ``s`` with a negative component; True when there is none."""
    if s.size == 0 or s.min() >= 0:
        return True
    bad = np.flatnonzero((s < 0).any(axis=1))
    ctx.issues.add(Code.SCALE_NEGATIVE, f"{what}: {bad.size} of {len(s)} splats have negative "
                   f"scales (scales are linear and MUST NOT be negative; log-scales need exp())",
                   pointer=location, count=int(bad.size),
                   examples=ctx.examples(bad, index=np.arange(len(s)), value=s))
    return False


def check_opacities(ctx: CheckContext, o: np.ndarray, location: str, what: str) -> bool:
    """OPACITY_OUT_OF_RANGE for opacities (N,) outside [0, 1]; True when all are inside."""
    if o.size == 0 or (o.min() >= 0 and o.max() <= 1):
        return True
    bad = np.flatnonzero((o < 0) | (o > 1))
    ctx.issues.add(Code.OPACITY_OUT_OF_RANGE, f"{what}: {bad.size} of {len(o)} opacities are "
                   f"outside [0, 1] (opacities are linear, after the sigmoid)",
                   pointer=location, count=int(bad.size),
                   examples=ctx.examples(bad, index=np.arange(len(o)), value=o))
    return False


# ---------------------------------------------------------------------------- anchor mesh

def check_triangles(ctx: CheckContext, mesh: TriangleMesh, location: str) -> AnchorMesh:
    """Report degenerate, sliver and duplicate triangles of a valid anchor mesh (finite
    vertices, indices in range); return it with its degenerate mask and diagonal."""
    tri = mesh.triangles()
    degenerate = degenerate_mask(tri)
    n_deg = int(np.count_nonzero(degenerate))
    f = mesh.face_count
    if n_deg:
        faces = np.flatnonzero(degenerate)
        ctx.issues.add(Code.MESH_DEGENERATE_TRIANGLES, f"{n_deg} of {f} anchor triangles are "
                       f"degenerate (doubled area <= {EPS_DEGENERATE:g} x longest edge squared)",
                       pointer=location, count=n_deg,
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
        ctx.issues.add(Code.MESH_SLIVER_TRIANGLES, f"{n_thin} of {f} anchor triangles are slivers "
                       f"(doubled area <= {TOLERANCES['sliver'][0]:g} x longest edge squared)",
                       pointer=location, count=n_thin,
                       examples=ctx.examples(faces, face=np.arange(f), areaRatio=ratio))
    _check_duplicates(ctx, mesh, location)
    _check_manifold(ctx, mesh, location)
    return AnchorMesh(mesh, degenerate, *mesh_extent(mesh))


def _check_manifold(ctx: CheckContext, mesh: TriangleMesh, location: str) -> None:
    """ANCHOR_MESH_NOT_MANIFOLD (information: open anchor meshes are valid)."""
    if mesh.face_count == 0:
        return
    report = manifold_report(mesh)
    if not report.closed_manifold:
        ctx.issues.add(Code.ANCHOR_MESH_NOT_MANIFOLD, f"the anchor mesh is not a closed "
                       f"2-manifold: {report.why_not()} (soft bodies and mesh colliders need "
                       f"one; gsverse-convert --watertight repairs it)", pointer=location)


def _check_duplicates(ctx: CheckContext, mesh: TriangleMesh, location: str) -> None:
    """MESH_DUPLICATE_TRIANGLES: the same three corner positions, in any order."""
    f = mesh.face_count
    v = mesh.vertices.astype(np.float32) + np.float32(0.0)  # -0.0 -> 0.0: equal bytes
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
        ctx.issues.add(Code.MESH_DUPLICATE_TRIANGLES, f"{dup.size} of {f} anchor triangles repeat "
                       f"the corners of an earlier triangle", pointer=location,
                       count=int(dup.size),
                       examples=ctx.examples(dup, face=np.arange(f), duplicateOf=partner))


# ---------------------------------------------------------------------------- anchor values

def check_anchor_values(ctx: CheckContext, values: AnchorValues, mesh: AnchorMesh | None,
                        rest: RestPose | None, *, consistent: bool = True) -> None:
    """Check the anchor values of one primitive against its anchor mesh, then (when
    everything needed is valid and ``consistent``, i.e. nothing structural was wrong) the
    stored rest pose ``rest`` against the remap at the rest mesh."""
    arrays, where = values.arrays, values.where
    profile = values.profile
    ok = True
    face = arrays.get("faceIndex")
    if face is not None and face.size > 1 and bool(np.any(face[1:] < face[:-1])):
        ctx.issues.add(Code.ANCHOR_NOT_SORTED, "the splats are not sorted by faceIndex (sorted "
                       "order is about 2x faster to remap)", pointer=where["faceIndex"])
    if face is None or mesh is None or mesh.mesh is None:
        ok = False
    else:
        out = np.flatnonzero((face < 0) | (face >= mesh.mesh.face_count))
        if out.size:
            ctx.issues.add(Code.ANCHOR_FACE_OUT_OF_RANGE, f"{out.size} of {len(face)} splats have "
                           f"a faceIndex outside [0, {mesh.mesh.face_count}), the anchor "
                           f"triangle count", pointer=where["faceIndex"], count=int(out.size),
                           examples=ctx.examples(out, splat=np.arange(len(face)), face=face))
            ok = False
        elif mesh.degenerate is not None and mesh.degenerate.any():
            bound = np.flatnonzero(mesh.degenerate[face])
            if bound.size:
                ctx.issues.add(Code.ANCHOR_BOUND_TO_DEGENERATE, f"{bound.size} of {len(face)} "
                               f"splats are bound to {np.unique(face[bound]).size} triangle(s) "
                               f"that are degenerate at rest", pointer=where["faceIndex"],
                               count=int(bound.size),
                               examples=ctx.examples(bound, splat=np.arange(len(face)),
                                                     face=face))
    bary = arrays.get("barycentrics")
    if bary is None:
        ok = False
    else:
        _check_barycentrics(ctx, profile, bary, where["barycentrics"],
                            values.steps.get("barycentrics", 0.0))

    anchors: LocalAnchors | GamesAnchors | None = None
    if profile == "local":
        rotation = arrays.get("localRotation")
        if rotation is not None and not check_unit_quaternions(
                ctx, rotation, values.steps.get("localRotation", 0.0), where["localRotation"],
                "localRotation"):
            rotation = None
        scale = arrays.get("localScale")
        if scale is not None and not check_nonnegative(ctx, scale, where["localScale"],
                                                       "localScale"):
            scale = None
        offset = arrays.get("normalOffset")
        if ok and face is not None and bary is not None and offset is not None \
                and rotation is not None and scale is not None \
                and values.deformation in ("affine", "rigid"):
            anchors = LocalAnchors(face, bary, offset[:, 0], rotation, scale,
                                   cast(DeformationLaw, values.deformation))
    elif profile == "games":
        rho = arrays.get("rho")
        if rho is not None:
            neg = np.flatnonzero(rho[:, 0] < 0)
            if neg.size:
                ctx.issues.add(Code.GAMES_RHO_NEGATIVE, f"{neg.size} of {len(rho)} splats have "
                               f"rho < 0 (their scales collapse to 1e-8)", pointer=where["rho"],
                               count=int(neg.size),
                               examples=ctx.examples(neg, splat=np.arange(len(rho)),
                                                     rho=rho[:, 0]))
            if ok and face is not None and bary is not None:
                anchors = GamesAnchors(face, bary, rho[:, 0])
    if anchors is not None and rest is not None and mesh is not None and mesh.mesh is not None \
            and len(rest.means) == len(anchors.face_index):
        check_fit(ctx, rest, mesh.mesh, anchors.face_index)
    if anchors is not None and rest is not None and consistent and mesh is not None \
            and mesh.mesh is not None:
        check_rest_pose(ctx, rest, Anchoring(mesh.mesh, anchors), mesh.diagonal, mesh.largest)


def check_fit(ctx: CheckContext, rest: RestPose, mesh: TriangleMesh,
              face_index: np.ndarray) -> None:
    """ANCHOR_MESH_MISFIT when the anchor mesh does not belong to the splats
    (:func:`gsverse_format.fit.assess_anchored_fit`: the rest means, the mesh's box, each
    splat's distance to its own anchor triangle; face indices already checked in range)."""
    if not np.all(np.isfinite(rest.means)):
        return
    report, judged = assess_anchored_fit(rest.means, mesh.vertices, mesh.faces, face_index)
    if report.ok:
        return
    n = len(rest.means)
    subset = "" if judged == n else f"; judged on {judged} evenly spaced splats of {n}"
    ctx.issues.add(Code.ANCHOR_MESH_MISFIT, f"the anchor mesh does not fit its splats: "
                   f"{report.message()} (distances of the splats to their anchor triangles"
                   f"{subset})", pointer=rest.mean_location)


def _check_barycentrics(ctx: CheckContext, profile: str | None, bary: np.ndarray,
                        location: str, step: float) -> None:
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
        tol = TOLERANCES["simplex"][0] + step
        bad, weights, low = below(-tol)
        if bad.size:
            ctx.issues.add(Code.GAMES_BARYCENTRICS_OUTSIDE_SIMPLEX, f"{bad.size} of {len(b0)} "
                           f"games splats have barycentrics outside the triangle (smallest "
                           f"weight {low[bad].min():.3g}, tolerance {-tol:.3g})",
                           pointer=location, count=int(bad.size),
                           examples=ctx.examples(bad, splat=np.arange(len(b0)), weights=weights))
    elif profile == "local":
        bound = -TOLERANCES["local_far"][0]
        far, weights, low = below(bound)
        if far.size:
            ctx.issues.add(Code.LOCAL_BARYCENTRICS_FAR, f"{far.size} of {len(b0)} splats have a "
                           f"barycentric weight below {bound:g}: their foot point lies far "
                           f"outside their triangle (allowed by the spec; nothing to do for a converted "
                           f"asset unless ANCHOR_MESH_MISFIT is also reported or these splats are "
                           f"floaters, see spec/validation.md)",
                           pointer=location, count=int(far.size),
                           examples=ctx.examples(far, splat=np.arange(len(b0)), weights=weights))


# ---------------------------------------------------------------------------- rest pose

def check_rest_pose(ctx: CheckContext, rest: RestPose, anchoring: Anchoring,
                    diagonal: float, largest: float = 0.0) -> None:
    """spec §Rest-pose consistency: the remap at the rest mesh against the stored rest pose
    (bounds: :mod:`gsverse_format.tolerances`)."""
    n = len(anchoring.anchors)
    mean_tol = rest_mean_tolerance(diagonal, largest)
    floor = (REST_COVARIANCE_FLOOR * diagonal) ** 2
    rel_tol = REST_COVARIANCE_RELATIVE
    mean_err = np.empty(n)
    cov_ratio = np.empty(n)
    cov_rel = np.empty(n)
    with np.errstate(all="ignore"):  # 0/0 for zero covariances on a zero-size mesh: not flagged
        _compare(anchoring, rest, mean_err, cov_ratio, cov_rel, rel_tol, floor)
    k = ctx.options.max_examples
    index = np.arange(n)
    bad = np.flatnonzero(mean_err > mean_tol)
    if bad.size:
        worst = bad[np.argsort(-mean_err[bad], kind="stable")[:k]]
        ctx.issues.add(Code.REST_POSE_MEAN_MISMATCH, f"{bad.size} of {n} stored means differ from "
                       f"the remap at the rest mesh by more than {mean_tol:.3g} (1e-5 x the "
                       f"anchor mesh diagonal {diagonal:.4g} + 8 float32 ulps of its largest "
                       f"coordinate {largest:.4g}); worst {mean_err[bad].max():.3g}",
                       pointer=rest.mean_location, count=int(bad.size),
                       examples=ctx.examples(worst, splat=index, error=mean_err))
    bad = np.flatnonzero(cov_ratio > 1.0)
    if bad.size:
        worst = bad[np.argsort(-cov_rel[bad], kind="stable")[:k]]
        ctx.issues.add(Code.REST_POSE_COVARIANCE_MISMATCH, f"{bad.size} of {n} stored covariances "
                       f"differ from the remap at the rest mesh by more than {rel_tol:g} "
                       f"(relative Frobenius norm); worst {cov_rel[bad].max():.3g}",
                       pointer=rest.covariance_location, count=int(bad.size),
                       examples=ctx.examples(worst, splat=index, relativeError=cov_rel))


def _compare(anchoring: Anchoring, rest: RestPose, mean_err, cov_ratio, cov_rel, rel_tol,
             floor) -> None:
    """Fill the per-splat mean errors and covariance ratios, block by block."""
    for sl, mu, ref in iter_moments(anchoring):
        stored_mu = rest.means[sl].astype(np.float64)
        dx = mu[0] - stored_mu[:, 0]
        dy = mu[1] - stored_mu[:, 1]
        dz = mu[2] - stored_mu[:, 2]
        mean_err[sl] = np.sqrt(dx * dx + dy * dy + dz * dz)
        got = covariance_entries(rest.rotations[sl], rest.scales[sl])
        d = [g - r for g, r in zip(got, ref)]
        diff = np.sqrt(d[0] * d[0] + d[3] * d[3] + d[5] * d[5]
                       + 2.0 * (d[1] * d[1] + d[2] * d[2] + d[4] * d[4]))
        norm = np.sqrt(ref[0] * ref[0] + ref[3] * ref[3] + ref[5] * ref[5]
                       + 2.0 * (ref[1] * ref[1] + ref[2] * ref[2] + ref[4] * ref[4]))
        cov_ratio[sl] = diff / (rel_tol * norm + floor)
        cov_rel[sl] = diff / np.where(norm > 0, norm, 1.0)
