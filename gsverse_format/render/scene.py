"""From an asset to pictures: Gaussians of every primitive in a pose, framing, wireframes and the
before/after sheet.

Poses. Anchored primitives are remapped (:func:`gsverse_format.remapping.reference.remap`, the
float64 reference) onto anchor vertices: the rest pose, a (V, 3) array given by the caller (one
primitive, or all anchored primitives' vertices concatenated in file order), an analytic quick
look (:func:`deform_vertices`: stretch, twist, bend about the anchor meshes' bounding box), or
:func:`pose_vertices` (the asset's own animation at a time). Plain primitives render as stored.
Coordinates are those the reader returns: each primitive's own space (+Y up). A
:class:`~gsverse_format.model.SplatAsset` carries no node transforms, so the transform of the
node that instantiates a splat mesh in a glTF file is not applied.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..errors import UsageError
from ..model import SplatAsset
from .camera import Camera, frame_bounds
from .project_reference import Settings
from .raster import Image, render_gaussians

__all__ = ["Gaussians", "gaussians", "pose_vertices", "split_pose", "deform_vertices",
           "DEFORMATIONS", "anchor_bounds", "auto_camera", "sheet_camera", "render_asset",
           "draw_wireframe", "sheet"]

DEFORMATIONS = ("stretch", "twist", "bend")


@dataclass
class Gaussians:
    """World-space Gaussians ready to render (float64 means/covariances, float32 SH)."""

    means: np.ndarray
    covariances: np.ndarray
    opacities: np.ndarray
    sh: np.ndarray
    color_space: str = "srgb_rec709_display"

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        if len(self.means) == 0:
            return np.zeros(3), np.ones(3)
        return self.means.min(0), self.means.max(0)


def pose_vertices(asset: SplatAsset, time: float, path: str | os.PathLike | None = None
                  ) -> list[np.ndarray]:
    """The anchor vertices of every anchored primitive at ``time`` (seconds) of the asset's own
    glTF animation (the skin / morph targets of its anchor mesh, sampled by
    :func:`gsverse_format.poses.gltf_source.open_gltf_source`); ``path`` is the asset's file.
    Refuses (:class:`~gsverse_format.errors.GsverseError`) assets without an animated anchor
    mesh and non-glTF files."""
    if path is None or not os.fspath(path).lower().endswith((".glb", ".gltf")):
        raise UsageError(f"--time {time:g}: only a glTF asset (.glb/.gltf) carries an animated "
                         "anchor mesh; use --pose FILE or --deform")
    if not asset.anchored:
        raise UsageError("the asset has no anchored primitive to pose")
    from ..poses.gltf_source import open_gltf_source

    source = open_gltf_source(path)
    rest = np.concatenate([p.anchoring.mesh.vertices for p in asset.anchored])  # type: ignore[union-attr]
    source.match(rest)
    return split_pose(asset, source.at(float(time)))


def split_pose(asset: SplatAsset, vertices: np.ndarray) -> list[np.ndarray]:
    """Split one (V, 3) array into per-anchored-primitive vertex arrays (their counts in order)."""
    v = np.asarray(vertices)
    counts = [len(p.anchoring.mesh.vertices) for p in asset.anchored]  # type: ignore[union-attr]
    if not counts:
        raise UsageError("the asset has no anchored primitive to pose")
    if v.ndim != 2 or v.shape[1] != 3:
        raise UsageError(f"a pose must be a (V, 3) array of anchor vertices, got shape {v.shape}")
    if v.shape[0] != sum(counts):
        raise UsageError(f"the pose has {v.shape[0]} vertices, the anchor mesh"
                         f"{'es have' if len(counts) > 1 else ' has'} {sum(counts)}")
    if not np.all(np.isfinite(v)):
        raise UsageError("the pose holds NaN or infinite coordinates")
    return np.split(v.astype(np.float64), np.cumsum(counts)[:-1])


def anchor_bounds(asset: SplatAsset) -> tuple[np.ndarray, np.ndarray]:
    verts = [p.anchoring.mesh.vertices for p in asset.anchored]  # type: ignore[union-attr]
    if not verts:
        raise UsageError("the asset has no anchored primitive to deform")
    allv = np.concatenate(verts).astype(np.float64)
    return allv.min(0), allv.max(0)


def deform_vertices(asset: SplatAsset, name: str, amount: float) -> list[np.ndarray]:
    """An analytic quick look at the anchor meshes, along the +Y extent of their bounding box:
    ``stretch`` (scale Y by ``amount`` about the centre), ``twist`` (rotation about the vertical
    axis through the centre growing to ``amount`` degrees from bottom to top), ``bend`` (the
    vertical axis bent into an arc of ``amount`` degrees in the XY plane)."""
    from ..poses.analytic import bend, stretch_along, twist

    lo, hi = anchor_bounds(asset)
    centre = 0.5 * (lo + hi)
    out = []
    for p in asset.anchored:
        v = p.anchoring.mesh.vertices.astype(np.float64)  # type: ignore[union-attr]
        if name == "stretch":
            if not amount > 0:
                raise UsageError(f"stretch={amount:g}: the factor must be positive")
            out.append(stretch_along(v, (0.0, 1.0, 0.0), amount, centre))
        elif name == "twist":
            out.append(twist(v, amount, centre, float(lo[1]), float(hi[1])))
        elif name == "bend":
            if amount == 0:
                out.append(v)
            else:
                out.append(bend(v, amount, centre, float(lo[1]), float(hi[1])))
        else:
            raise UsageError(f"unknown deformation {name!r} (stretch, twist, bend)")
    return out


def gaussians(asset: SplatAsset, poses: list[np.ndarray] | None = None) -> Gaussians:
    """All primitives' Gaussians; anchored ones remapped onto ``poses`` (one (V, 3) array per
    anchored primitive) or, without poses, onto their rest mesh."""
    from ..remapping.reference import remap

    means, covs, ops, shs, spaces = [], [], [], [], set()
    k = max((p.splats.sh.shape[1] for p in asset.primitives), default=1)
    ai = 0
    for prim in asset.primitives:
        s = prim.splats
        if prim.anchoring is not None:
            verts = None if poses is None else poses[ai]
            ai += 1
            r = remap(prim.anchoring, verts)
            means.append(r.means)
            covs.append(r.covariances)
        else:
            means.append(s.means.astype(np.float64))
            covs.append(s.covariances())
        ops.append(s.opacities)
        sh = np.zeros((len(s), k, 3), np.float32)
        sh[:, :s.sh.shape[1]] = s.sh
        shs.append(sh)
        spaces.add(s.color_space)
    if len(spaces) > 1:
        raise UsageError("the primitives use different colour spaces; render them separately")
    if not means:
        raise UsageError("the asset holds no splats")
    return Gaussians(np.concatenate(means), np.concatenate(covs), np.concatenate(ops),
                     np.concatenate(shs), spaces.pop())


def _framed_box(g: Gaussians) -> tuple[np.ndarray, np.ndarray]:
    """The box a camera frames: the means' 1st–99th percentile box (so stray splats do not
    shrink the object), or their whole box for 100 splats or fewer."""
    if len(g.means) > 100:
        return np.percentile(g.means, 1, axis=0), np.percentile(g.means, 99, axis=0)
    return g.bounds()


def auto_camera(g: Gaussians, width: int, height: int, **kw) -> Camera:
    """Frame the Gaussians' means (1st–99th percentile box, so stray splats do not shrink the
    object) from the front-right, slightly above."""
    lo, hi = _framed_box(g)
    return frame_bounds(lo, hi, width=width, height=height, **kw)


def sheet_camera(asset: SplatAsset, poses: list[np.ndarray] | None, width: int, height: int,
                 **kw) -> Camera:
    """The one camera of a :func:`sheet`: it frames the union of what the three panels show,
    the rest pose, the posed Gaussians (each their 1st–99th percentile box) and the posed
    anchor meshes, so that neither picture is cut when the pose moves the asset away from
    its rest place (a bend, a stretch)."""
    boxes = [_framed_box(gaussians(asset, None))]
    if poses is not None:
        boxes.append(_framed_box(gaussians(asset, poses)))
        boxes += [(v.min(0), v.max(0)) for v in poses if len(v)]
    lo = np.min([b[0] for b in boxes], axis=0)
    hi = np.max([b[1] for b in boxes], axis=0)
    return frame_bounds(lo, hi, width=width, height=height, **kw)


def render_asset(g: Gaussians, camera: Camera, settings: Settings = Settings(), *,
                 backend: str = "auto") -> Image:
    return render_gaussians(g.means, g.covariances, g.opacities, g.sh, camera, settings,
                            backend=backend, color_space=g.color_space)


def draw_wireframe(vertices: np.ndarray, faces: np.ndarray, camera: Camera,
                   color=(0.9, 0.9, 0.9), background=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(H, W, 3) uint8: the edges of a triangle mesh, one pixel wide (DDA line rasterizer, no
    hidden-line removal), over ``background``; edges with an end behind the camera are skipped."""
    w, h = camera.width, camera.height
    img = np.empty((h, w, 3), np.uint8)
    img[:] = np.round(np.asarray(background) * 255).astype(np.uint8)
    uv, z = camera.project_points(vertices)
    f = np.asarray(faces, np.int64)
    edges = np.unique(np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1), axis=0)
    edges = edges[(z[edges[:, 0]] > camera.near) & (z[edges[:, 1]] > camera.near)]
    p0, p1 = uv[edges[:, 0]], uv[edges[:, 1]]
    steps = np.ceil(np.max(np.abs(p1 - p0), axis=1)).astype(np.int64) + 1
    steps = np.minimum(steps, 4 * (w + h))
    reps = np.repeat(np.arange(len(edges)), steps)
    t = (np.arange(len(reps)) - np.repeat(np.cumsum(steps) - steps, steps)) / np.repeat(np.maximum(steps - 1, 1), steps)
    pts = p0[reps] + (p1[reps] - p0[reps]) * t[:, None]
    x, y = np.floor(pts[:, 0]).astype(np.int64), np.floor(pts[:, 1]).astype(np.int64)
    keep = (x >= 0) & (x < w) & (y >= 0) & (y < h)
    img[y[keep], x[keep]] = np.round(np.asarray(color) * 255).astype(np.uint8)
    return img


def sheet(asset: SplatAsset, poses: list[np.ndarray] | None, camera: Camera,
          settings: Settings = Settings(), *, background=(0.0, 0.0, 0.0),
          backend: str = "auto", progress=None) -> np.ndarray:
    """Before/after sheet (H, 3W, 3) uint8: rest | posed | posed anchor mesh wireframe, one
    camera for the three (:func:`sheet_camera` frames them all)."""
    from .output import to_rgba8

    panels = []
    for i, pose in enumerate((None, poses)):
        img = render_asset(gaussians(asset, pose), camera, settings, backend=backend)
        panels.append(to_rgba8(img, background)[..., :3])
        if progress is not None:
            progress.update(i + 1, 3)
    wire = np.empty((camera.height, camera.width, 3), np.uint8)
    wire[:] = np.round(np.asarray(background) * 255).astype(np.uint8)
    for k, prim in enumerate(asset.anchored):
        mesh = prim.anchoring.mesh  # type: ignore[union-attr]
        v = mesh.vertices if poses is None else poses[k]
        layer = draw_wireframe(v, mesh.faces, camera, background=background)
        mask = np.any(layer != np.round(np.asarray(background) * 255), axis=-1)
        wire[mask] = layer[mask]
    if progress is not None:
        progress.update(3, 3)
    panels.append(wire)
    return np.concatenate(panels, axis=1)
