"""TRELLIS: the Gaussian PLY and the GLB mesh of the same run.

Inputs
    * ``input_path`` — the PLY written by TRELLIS's ``Gaussian.save_ply``: SH degree 0,
      properties ``x y z nx ny nz f_dc_0..2 opacity scale_0..2 rot_0..3`` (normals are zeros),
      pre-activation values with TRELLIS's biases already folded in, object inside the cube
      [−0.5, 0.5]³.
    * ``mesh_path`` — the GLB written by ``postprocessing_utils.to_glb`` for the same run.

Frames
    TRELLIS works in a right-handed Z-up frame. Since commit ``f094d9f`` (2024-12-18)
    ``save_ply`` rotates positions and orientations by ``T = [[1,0,0],[0,0,−1],[0,1,0]]``
    (``p ↦ (x, −z, y)``), and ``to_glb`` rotates the mesh by ``Tᵀ`` (``p ↦ (x, z, −y)``, glTF's
    +Y up). So ``p_glb = Tᵀ·Tᵀ·p_ply = D·p_ply`` with ``D = diag(1, −1, −1)``, a rotation of
    180° about +X; it is applied to the splats (means and orientations; SH0 needs no rotation).
    PLYs saved before that commit have no export rotation: ``p_glb = Tᵀ·p_ply``
    (``options.trellis_frame == "legacy"``, ``--legacy-trellis-frame``); with ``"none"``
    (``--no-frame-change``) the PLY is taken to be in the GLB's frame already. The mesh is read
    from the GLB (node transforms applied) and is already in the glTF frame, and so is the
    result (``frame`` ``"gltf"``).

Mesh
    ``to_glb`` decimates the mesh, fills holes and unwraps it with xatlas, which duplicates
    every vertex on a UV seam. Those copies are welded (bit-identical positions merged,
    :func:`gsverse_format.meshops.weld`) so that the anchor mesh is connected across seams;
    faces that collapse are dropped. The GLB's faces bear no relation to the Gaussians (separate
    decoders), so no anchors are returned: the pipeline binds every splat to its nearest
    triangle.

Checks
    The layout must be TRELLIS's (SH0, normals, no extra properties, inside the unit cube with a
    margin), otherwise the file is refused with a pointer to ``--from 3dgs``. Splat-to-mesh
    distances (p50/p95/max relative to the welded mesh's bounding-box diagonal, exact nearest
    triangles) go into ``check``; a median above 5 % of the diagonal means the frames do not
    match, and the error names the frame that fits (legacy, current, or none) and its flag.
"""
from __future__ import annotations

import os

import numpy as np

from gsverse_format.converters.base import SourceOptions, SourceResult, require_splats
from gsverse_format.converters.registry import register_source
from gsverse_format.errors import FormatError, GsverseError, UsageError
from gsverse_format.io.mesh import read_mesh
from gsverse_format.io.ply import describe_ply, read_ply_elements, read_splat_ply
from gsverse_format.meshops import bbox_diagonal, mesh_stats, weld
from gsverse_format.model import TriangleMesh
from gsverse_format.nearest import nearest_faces
from gsverse_format.transform import rotate_splats

__all__ = ["T_EXPORT", "PLY_TO_GLB", "LEGACY_PLY_TO_GLB", "load", "detect", "frame_distances"]

#: TRELLIS ``save_ply`` export rotation (internal Z-up frame -> PLY), since 2024-12-18.
T_EXPORT = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
#: PLY (with export rotation) -> GLB frame: ``D = Tᵀ·Tᵀ = diag(1, −1, −1)``.
PLY_TO_GLB = np.diag([1.0, -1.0, -1.0])
#: Legacy PLY (internal frame, before 2024-12-18) -> GLB frame: ``Tᵀ``.
LEGACY_PLY_TO_GLB = T_EXPORT.T.copy()

#: Largest |coordinate| of a TRELLIS splat centre: the unit cube plus a margin for offsets.
CUBE_LIMIT = 0.6
#: TRELLIS's minimum kernel size (every decoded scale is at least this).
MIN_KERNEL = 9e-4
#: A median splat-to-mesh distance above this fraction of the diagonal is a frame mismatch.
MISMATCH = 0.05
#: ... as is one above MISMATCH / 10 when another frame fits this many times better.
BETTER = 3.0
_PROBE = 5_000
_CHECK = 200_000

_FRAMES = {
    "current": (PLY_TO_GLB, "TRELLIS's export frame (since 2024-12-18)", ""),
    "legacy": (LEGACY_PLY_TO_GLB, "the pre-2024-12-18 frame", "--legacy-trellis-frame"),
    "none": (np.eye(3), "the GLB's own frame (no rotation)", "--no-frame-change"),
}


def _subset(n: int, limit: int) -> np.ndarray:
    return np.arange(n) if n <= limit else np.linspace(0, n - 1, limit).astype(np.int64)


def frame_distances(means: np.ndarray, mesh: TriangleMesh, rotation: np.ndarray) -> np.ndarray:
    """Exact distances from ``rotation @ means`` to the nearest triangle of ``mesh``."""
    p = np.asarray(means, dtype=np.float64) @ np.asarray(rotation, dtype=np.float64).T
    return nearest_faces(p, mesh.vertices, mesh.faces.astype(np.int64))[1]


def _check_layout(path: str) -> None:
    info = describe_ply(path)
    problems = []
    if info["sh_degree"] != 0:
        problems.append(f"SH degree {info['sh_degree']} (TRELLIS writes degree 0)")
    if not info["has_normals"]:
        problems.append("no nx/ny/nz properties")
    if info["extra"]:
        problems.append(f"extra properties {', '.join(info['extra'][:4])}")
    if info["color"] != "f_dc":
        problems.append("colours as red/green/blue instead of f_dc")
    if problems:
        raise FormatError(f"not a TRELLIS Gaussian PLY ({'; '.join(problems)}); for other 3DGS "
                          "PLYs use --from 3dgs --mesh MESH", path)


def _name(frame: str) -> str:
    return _FRAMES[frame][1]


def load(input_path: str, mesh_path: str | None, options: SourceOptions) -> SourceResult:
    """TRELLIS PLY + GLB of the same run -> splats and welded mesh in the glTF frame."""
    if mesh_path is None:
        raise UsageError("TRELLIS needs the mesh of the same run: pass its GLB with --mesh "
                         "(or use --from 3dgs to reconstruct a mesh from the splats)", input_path)
    _check_layout(input_path)
    splats = read_splat_ply(input_path, keep_nonfinite=options.keep_nonfinite)
    require_splats(splats, input_path)
    reach = float(np.max(np.abs(splats.means)))
    if reach > CUBE_LIMIT:
        raise FormatError(f"splat centres reach {reach:.3g}, outside TRELLIS's cube [-0.5, 0.5]^3: "
                          "not a TRELLIS Gaussian PLY; for other 3DGS PLYs use --from 3dgs "
                          "--mesh MESH", input_path)
    notes: list[str] = []
    smallest = float(np.min(splats.scales))
    if smallest < MIN_KERNEL * 0.99:
        notes.append(f"smallest splat scale {smallest:.3g} is below TRELLIS's minimum kernel "
                     f"{MIN_KERNEL:g}: the PLY may not come from TRELLIS")

    raw = read_mesh(mesh_path)
    mesh = weld(raw, drop_degenerate=True)
    if mesh.face_count == 0:
        raise FormatError("the mesh has no faces left after welding its vertices", mesh_path)
    stats = mesh_stats(mesh)
    notes.append(f"GLB mesh welded: {len(raw.vertices)} -> {len(mesh.vertices)} vertices "
                 f"(UV-seam copies merged), {stats.faces} faces, {stats.components} "
                 f"component(s), {stats.boundary_edges} boundary and {stats.nonmanifold_edges} "
                 "non-manifold edges")

    frame = options.trellis_frame
    if frame not in _FRAMES:
        raise UsageError(f"unknown TRELLIS frame {frame!r}; use one of {', '.join(_FRAMES)}")
    diag = bbox_diagonal(mesh)
    if not diag > 0:
        raise FormatError("the welded mesh has a zero-size bounding box", mesh_path)

    probe = splats.means[_subset(len(splats), _PROBE)]
    medians = {name: float(np.median(frame_distances(probe, mesh, rot))) / diag
               for name, (rot, _, _) in _FRAMES.items()}
    best = min(medians, key=medians.__getitem__)
    if medians[frame] > MISMATCH or (medians[frame] > MISMATCH / 10
                                     and medians[best] * BETTER < medians[frame]):
        raise FormatError(_mismatch(frame, medians) + "; if this is not TRELLIS output, use "
                          "--from 3dgs", input_path)

    rotation = _FRAMES[frame][0]
    if frame != "none":
        splats = rotate_splats(splats, rotation)
    if frame == "current":
        notes.append("TRELLIS PLY rotated 180 degrees about +X into the GLB frame "
                     "(p_glb = diag(1,-1,-1) p_ply)")
    elif frame == "legacy":
        notes.append("pre-2024-12-18 TRELLIS PLY rotated from TRELLIS's Z-up frame into the GLB "
                     "frame (p_glb = T^T p_ply)")

    idx = _subset(len(splats), _CHECK)
    d = nearest_faces(splats.means[idx], mesh.vertices, mesh.faces.astype(np.int64))[1]
    p50, p95 = np.percentile(d, [50, 95])
    check = {"frame": frame, "distance_p50_rel": float(p50 / diag),
             "distance_p95_rel": float(p95 / diag), "distance_max_rel": float(d.max() / diag),
             "checked": int(idx.size), "mesh_vertices_read": int(len(raw.vertices)),
             "mesh_vertices_welded": int(len(mesh.vertices)), "mesh_faces": stats.faces,
             "mesh_components": stats.components, "mesh_boundary_edges": stats.boundary_edges,
             "mesh_nonmanifold_edges": stats.nonmanifold_edges}
    notes.append(f"splat-to-mesh distance: median {100 * p50 / diag:.2g}%, p95 "
                 f"{100 * p95 / diag:.2g}%, max {100 * d.max() / diag:.2g}% of the mesh diagonal")
    return SourceResult(splats, mesh, None, notes, check, frame="gltf")


def _values_evidence(path: str) -> str | None:
    """Why the PLY's values are TRELLIS's, or None: zero normals (``save_ply`` writes zeros),
    every centre inside TRELLIS's cube (:data:`CUBE_LIMIT`) and every scale at least its
    minimum kernel (:data:`MIN_KERNEL`, 1 % slack for float32 and ``log``/``exp``). A plain
    3DGS PLY of the same layout (SH0 with normals) fails at least one of these: scenes are
    not inside a unit cube, and trained scales go below 9e-4."""
    try:
        v = read_ply_elements(path, ["vertex"])["vertex"]
    except (GsverseError, KeyError):
        return None  # not readable as a splat PLY: the chosen source's loader says why
    names = v.dtype.names or ()
    need = ("x", "y", "z", "nx", "ny", "nz", "scale_0", "scale_1", "scale_2")
    if not len(v) or not all(n in names for n in need):
        return None
    with np.errstate(all="ignore"):
        xyz = np.stack([v[n].astype(np.float64) for n in ("x", "y", "z")], axis=1)
        normals = np.stack([v[n].astype(np.float64) for n in ("nx", "ny", "nz")], axis=1)
        scales = np.exp(np.stack([v[n].astype(np.float64) for n in need[6:]], axis=1))
        # judged on the finite rows: NaN rows (which --drop-nonfinite drops) do not hide a run
        finite = np.isfinite(xyz).all(axis=1) & np.isfinite(scales).all(axis=1)
        if not finite.any():
            return None
        xyz, scales = xyz[finite], scales[finite]
        reach = float(np.max(np.abs(xyz)))
        smallest = float(np.min(scales))
    if np.any(normals != 0) or not reach <= CUBE_LIMIT or not smallest >= MIN_KERNEL * 0.99:
        return None
    return (f"centres within {reach:.2g} of the origin (TRELLIS's unit cube), smallest scale "
            f"{smallest:.2g} >= its minimum kernel {MIN_KERNEL:g}, zero normals")


def detect(input_path: str, mesh_path: str | None) -> str | None:
    """TRELLIS's layout (an SH0 PLY with normals and nothing else, and a GLB mesh) *and*
    TRELLIS's values (:func:`_values_evidence`): the layout alone is also that of plain 3DGS
    PLYs, which then go to ``3dgs``."""
    if mesh_path is None or os.path.splitext(input_path)[1].lower() != ".ply" \
            or os.path.splitext(mesh_path)[1].lower() != ".glb":
        return None
    info = describe_ply(input_path)
    if info.get("sh_degree") == 0 and info.get("has_normals") and not info.get("extra") \
            and info.get("color") == "f_dc":
        evidence = _values_evidence(input_path)
        if evidence is not None:
            return (f"SH0 PLY with normals and a GLB mesh, {evidence} (TRELLIS); --from 3dgs "
                    f"if it is not")
    return None


def _mismatch(frame: str, medians: dict[str, float]) -> str:
    """The one-line cause for splats far from the mesh, naming the frame that fits."""
    median = medians[frame]
    best = min((f for f in medians if f != frame), key=medians.__getitem__)
    head = (f"splats lie far from the mesh (median distance {100 * median:.3g}% of its diagonal) "
            f"in {_name(frame)}: frame mismatch?")
    if medians[best] > MISMATCH or medians[best] * BETTER >= median:
        return (f"{head} no known TRELLIS frame fits (best: {_name(best)}, median "
                f"{100 * medians[best]:.3g}%): are the PLY and the GLB from the same TRELLIS run?")
    fit = f"{_name(best)} fits: median {100 * medians[best]:.2g}%"
    if best == "legacy":
        also = " and drop --no-frame-change" if frame == "none" else ""
        return (f"{head} if the PLY predates TRELLIS's 2024-12-18 export rotation, pass "
                f"--legacy-trellis-frame{also} ({fit})")
    if best == "current":
        return (f"{head} the PLY has TRELLIS's 2024-12-18 export rotation: drop "
                f"{'--legacy-trellis-frame' if frame == 'legacy' else '--no-frame-change'} ({fit})")
    return f"{head} the PLY is already in the GLB's frame: pass --no-frame-change ({fit})"


register_source("trellis", load, detect=detect, priority=40)
