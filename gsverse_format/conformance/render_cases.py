"""The render cases of the conformance suite: what a person sees in the engine.

The remap cases check numbers a harness reads back; they cannot see what happens after the
remap: how the engine packs rotation and scale, in which order it blends the splats (sorted by
their *deformed* positions or by the rest pose), whether it applies the splat node's transform,
leaves plain splats alone, or plays a skinned anchor mesh. A render case is an asset, a few
*frames* (a deformation of the anchor mesh and a camera each) and a reference image per frame
from the reference renderer; a harness renders the same frames in its engine and the check
compares the pictures (:mod:`.render_check`).

Each case is built to make one class of mistake visible (``catches``):

* ``render-turn-180``: a sheet with a red front layer and a blue back layer whose anchor mesh
  turns half a revolution about the vertical axis: the blue layer is then in front. A renderer
  that sorts by rest positions keeps drawing red over blue.
* ``render-fold``: the same two-tone sheet folded about its middle until one half lies in
  front of the other: the depth order changes within one primitive.
* ``render-packing``: thin needles of many colours at many angles on a sheet, turned and
  stretched: scales handed over in the wrong order, or quaternion components swapped, turn
  every needle.
* ``render-node-transforms``: a tube on a splat node with a translation, a rotation and a
  uniform scale, and a node instantiating the anchor mesh elsewhere (that node's transform is
  ignored for anchoring, and the anchor mesh is not drawn).
* ``render-plain-and-anchored``: an anchored tube between plain (unanchored) splats in front of
  and behind it: the plain ones never move, and all are blended in one depth order.
* ``render-skinned``: an anchor mesh with a skin and an animation in the file, rendered at two
  animation times: the engine's (or the plugin's) playback of the file's animation.
* ``render-sliver-stretched``: splats on sliver triangles stretched along the slivers.
* ``render-spz-turn``: the two-tone sheet of ``render-turn-180`` written as a compact asset with
  an SPZ-compressed rest pose (tags ``encoding:spz``, optional): a reader that skips the SPZ
  frame change (RUB to glTF) draws the blue back layer in front at rest and the sheet mirrored.

Everything is deterministic (seeded by the case id). Coordinates: glTF, +Y up, metres.
"""
from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..model import Anchoring, LocalAnchors, SplatAsset, SplatCloud, SplatPrimitive, TriangleMesh
from ..poses.analytic import bend, stretch, twist
from ..quaternion import from_matrix
from ..remapping.reference import remap
from ..render.camera import Camera, look_at
from ..sh import SH_C0
from .case_tools import case_rng, random_barycentrics, tube_mesh
from .skin import skinned_tube

__all__ = ["RenderFrame", "RenderCase", "render_cases", "IMAGE_SIZE"]

#: Width and height of every render case's images (pixels).
IMAGE_SIZE = 160


@dataclass
class RenderFrame:
    """One picture of a case: how the anchor meshes are posed, and the camera.

    ``deformation``: ``{"kind": "rest"}``; ``{"kind": "vertices", "vertices": (V, 3)}`` (the
    anchor vertices of every anchored primitive, concatenated in file order, splat-local
    space); or ``{"kind": "animation", "animation": i, "time": t}`` (the file's own animation
    of its anchor mesh at ``t`` seconds)."""

    label: str
    deformation: dict
    camera: Camera


@dataclass
class RenderCase:
    id: str
    description: str
    catches: str
    tags: list[str]
    asset: SplatAsset
    frames: list[RenderFrame]
    #: edits the written GLB (JSON document, binary chunk), e.g. node transforms
    edit: Callable[[dict, bytes], tuple[dict, bytes]] | None = None
    #: global matrix of the node of every splat primitive (in file order), None = identity
    node_matrices: list[np.ndarray] = field(default_factory=list)
    #: ``"spz"``: written as a compact asset with an SPZ-compressed rest pose (the reference
    #: pictures are rendered from the decoded rest pose, what readers get)
    compress: str | None = None


# --------------------------------------------------------------------------- building blocks

def _rgb_sh(rgb: np.ndarray) -> np.ndarray:
    """SH degree 0 coefficients (N, 1, 3) of display colours in [0, 1]."""
    return ((np.asarray(rgb, np.float64) - 0.5) / SH_C0)[:, None, :].astype(np.float32)


def _grid(nx: int, ny: int, x0: float, x1: float, y0: float, y1: float) -> TriangleMesh:
    """A flat grid in the z = 0 plane, faces wound counter-clockwise seen from +z (normal +z)."""
    xs, ys = np.linspace(x0, x1, nx + 1), np.linspace(y0, y1, ny + 1)
    v = np.stack(np.meshgrid(xs, ys, indexing="xy"), -1).reshape(-1, 2)
    v = np.concatenate([v, np.zeros((len(v), 1))], 1)
    faces = []
    for j in range(ny):
        for i in range(nx):
            a = j * (nx + 1) + i
            b, c, d = a + 1, a + nx + 1, a + nx + 2
            faces += [(a, b, d), (a, d, c)]
    return TriangleMesh(v.astype(np.float32), np.array(faces, np.uint32))


def _anchored(mesh: TriangleMesh, anchors: LocalAnchors, rgb: np.ndarray, opacity: np.ndarray,
              name: str) -> SplatPrimitive:
    """An anchored primitive whose stored rest pose is the reference remap of its anchors."""
    anchoring = Anchoring(mesh, anchors)
    r = remap(anchoring)
    cloud = SplatCloud(r.means, r.rotations, r.scales, opacity.astype(np.float32), _rgb_sh(rgb))
    return SplatPrimitive(cloud, anchoring, name=name)


def _layers(mesh: TriangleMesh, rng: np.random.Generator, per_face: int, offset: float,
            colors: tuple[tuple[float, float, float], ...], size: float) -> SplatPrimitive:
    """``per_face`` splats per face and layer, one layer per colour at normal offsets +offset,
    −offset (front, back): flat discs in the triangle's plane, opaque enough to hide the layer
    behind."""
    nf = len(mesh.faces)
    parts = []
    for k, rgb in enumerate(colors):
        face = np.repeat(np.arange(nf), per_face)
        n = len(face)
        bary = random_barycentrics(rng, n)
        d = np.full(n, offset if k == 0 else -offset)
        angle = rng.uniform(0, np.pi, n)
        quat = np.stack([np.zeros(n), np.zeros(n), np.sin(angle / 2), np.cos(angle / 2)], 1)
        scales = np.stack([size * rng.uniform(0.8, 1.2, n), size * rng.uniform(0.8, 1.2, n),
                           np.full(n, 0.15 * size)], 1)
        col = np.clip(np.asarray(rgb) + rng.normal(0, 0.04, (n, 3)), 0, 1)
        parts.append((face, bary, d, quat, scales, col))
    face, bary, d, quat, scales, col = (np.concatenate(x) for x in zip(*parts))
    order = np.argsort(face, kind="stable")
    anchors = LocalAnchors(face[order], bary[order], d[order], quat[order], scales[order], "affine")
    return _anchored(mesh, anchors, col[order], np.full(len(face), 0.97), "two-tone sheet")


def _front_camera(center, distance: float, *, fov: float = 40.0, azimuth: float = 0.0,
                  elevation: float = 0.0) -> Camera:
    az, el = math.radians(azimuth), math.radians(elevation)
    c = np.asarray(center, np.float64)
    eye = c + distance * np.array([math.sin(az) * math.cos(el), math.sin(el), math.cos(az) * math.cos(el)])
    return look_at(eye, c, fov=fov, width=IMAGE_SIZE, height=IMAGE_SIZE,
                   near=0.05 * distance, far=4.0 * distance)


def _rotate_y(v: np.ndarray, degrees: float, center=(0.0, 0.0, 0.0)) -> np.ndarray:
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    r = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    p = np.asarray(v, np.float64) - center
    return p @ r.T + center


def _vertices(v: np.ndarray) -> dict:
    return {"kind": "vertices", "vertices": np.asarray(v, np.float32)}


# --------------------------------------------------------------------------- cases

def _turn_case() -> RenderCase:
    cid = "render-turn-180"
    rng = case_rng(cid)
    mesh = _grid(6, 6, -0.5, 0.5, -0.5, 0.5)
    prim = _layers(mesh, rng, 10, 0.02, ((0.95, 0.15, 0.1), (0.1, 0.25, 0.95)), 0.07)
    v = mesh.vertices.astype(np.float64)
    cam = _front_camera((0, 0, 0), 2.3)
    frames = [RenderFrame("rest: the red front layer faces the camera", {"kind": "rest"}, cam),
              RenderFrame("anchors turned 150 degrees about y: the blue back layer in front",
                          _vertices(_rotate_y(v, 150.0)), cam),
              RenderFrame("anchors turned 180 degrees about y: the blue back layer in front",
                          _vertices(_rotate_y(v, 180.0)), cam)]
    return RenderCase(cid, "A sheet with a red front layer and a blue back layer; its anchor mesh "
                      "turns by 150 and 180 degrees about the vertical axis.",
                      "splats sorted by their rest positions (red stays in front)",
                      ["render", "render:depth-order"], SplatAsset([prim], "gsverse-conformance"),
                      frames)


def _spz_turn_case() -> RenderCase:
    cid = "render-spz-turn"
    rng = case_rng(cid)
    mesh = _grid(6, 6, -0.5, 0.5, -0.5, 0.5)
    prim = _layers(mesh, rng, 10, 0.02, ((0.95, 0.15, 0.1), (0.1, 0.25, 0.95)), 0.07)
    v = mesh.vertices.astype(np.float64)
    cam = _front_camera((0, 0, 0), 2.3, azimuth=25.0)
    frames = [RenderFrame("rest: the red front layer faces the camera", {"kind": "rest"}, cam),
              RenderFrame("anchors turned 180 degrees about y: the blue back layer in front",
                          _vertices(_rotate_y(v, 180.0)), cam)]
    return RenderCase(cid, "The two-tone sheet of render-turn-180 as a compact asset whose rest "
                      "pose is SPZ-compressed; its anchor mesh turns by 180 degrees about the "
                      "vertical axis.",
                      "the SPZ frame change (RUB to glTF) skipped: the blue back layer in front "
                      "at rest; anchors derived from other values than the decoded rest pose",
                      ["render", "render:depth-order", "encoding:spz"],
                      SplatAsset([prim], "gsverse-conformance"), frames, compress="spz")


def _fold_case() -> RenderCase:
    cid = "render-fold"
    rng = case_rng(cid)
    mesh = _grid(8, 4, -0.8, 0.8, -0.4, 0.4)
    prim = _layers(mesh, rng, 8, 0.02, ((0.95, 0.15, 0.1), (0.1, 0.25, 0.95)), 0.07)
    v = mesh.vertices.astype(np.float64)

    def fold(deg: float) -> np.ndarray:
        out = v.copy()
        right = v[:, 0] > 0
        # the right half turns about the y axis (x = 0) towards the camera (+z)
        out[right] = _rotate_y(v[right], -deg)
        return out

    cam = _front_camera((0, 0, 0.2), 3.0, azimuth=20.0, elevation=10.0)
    frames = [RenderFrame("rest", {"kind": "rest"}, cam),
              RenderFrame("right half folded 100 degrees towards the camera", _vertices(fold(100.0)), cam),
              RenderFrame("right half folded 170 degrees: in front of the left half",
                          _vertices(fold(170.0)), cam)]
    return RenderCase(cid, "The two-tone sheet folded about its middle until one half lies in "
                      "front of the other (its blue back facing the camera).",
                      "splats sorted by their rest positions (the order changes within one "
                      "primitive)", ["render", "render:depth-order"],
                      SplatAsset([prim], "gsverse-conformance"), frames)


def _needles(mesh: TriangleMesh, rng: np.random.Generator, n: int, length: float,
             name: str, law: str = "affine") -> SplatPrimitive:
    """``n`` needles (scales length : length/6 : length/6) at random in-plane angles, coloured
    by their angle, so that a needle turned by 90 degrees changes colour and shape. Their thin
    axis stays above a pixel in the case's pictures: narrower footprints depend on each
    renderer's antialiasing more than on the splat."""
    nf = len(mesh.faces)
    face = np.sort(rng.integers(0, nf, n))
    bary = random_barycentrics(rng, n)
    angle = rng.uniform(0, np.pi, n)
    quat = np.stack([np.zeros(n), np.zeros(n), np.sin(angle / 2), np.cos(angle / 2)], 1)
    scales = np.stack([np.full(n, length), np.full(n, length / 6), np.full(n, length / 6)], 1)
    hue = angle / np.pi
    col = np.stack([0.5 + 0.5 * np.cos(2 * np.pi * hue), 0.5 + 0.5 * np.cos(2 * np.pi * (hue - 1 / 3)),
                    0.5 + 0.5 * np.cos(2 * np.pi * (hue - 2 / 3))], 1)
    anchors = LocalAnchors(face, bary, rng.uniform(-0.01, 0.01, n), quat, scales, law)  # type: ignore[arg-type]
    return _anchored(mesh, anchors, col, np.full(n, 0.9), name)


def _packing_case() -> RenderCase:
    cid = "render-packing"
    rng = case_rng(cid)
    mesh = _grid(4, 4, -0.5, 0.5, -0.5, 0.5)
    prim = _needles(mesh, rng, 150, 0.09, "needles")
    v = mesh.vertices.astype(np.float64)
    a = math.radians(35.0)
    rz = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    posed = stretch(v @ rz.T, (1.0, 1.4, 1.0), (0.0, 0.0, 0.0))
    cam = _front_camera((0, 0, 0), 2.6)
    frames = [RenderFrame("rest", {"kind": "rest"}, cam),
              RenderFrame("turned 35 degrees about z and stretched 1.4x along y", _vertices(posed), cam)]
    return RenderCase(cid, "Needles (6:1:1) at random angles, coloured by angle, on a sheet "
                      "that turns and stretches.",
                      "rotation or scale handed to the renderer in the wrong order or packing",
                      ["render", "render:packing"], SplatAsset([prim], "gsverse-conformance"), frames)


def _tube_prim(rng: np.random.Generator, name: str, *, per_face: int = 6,
               center=(0.0, 0.0, 0.0), mesh: TriangleMesh | None = None) -> SplatPrimitive:
    """A tube (or ``mesh``) covered by splats coloured from red (bottom) to blue (top), with a
    white stripe along +x so that turns about the axis are visible."""
    if mesh is None:
        mesh = tube_mesh(center, rings=6, segments=10, radius=0.22, height=1.0)
    nf = len(mesh.faces)
    face = np.repeat(np.arange(nf), per_face)
    n = len(face)
    bary = random_barycentrics(rng, n)
    tri = mesh.vertices.astype(np.float64)[mesh.faces[face]]
    foot = tri[:, 0] + bary[:, :1] * (tri[:, 1] - tri[:, 0]) + bary[:, 1:] * (tri[:, 2] - tri[:, 0])
    lo, hi = mesh.vertices[:, 1].min(), mesh.vertices[:, 1].max()
    t = np.clip((foot[:, 1] - lo) / max(hi - lo, 1e-9), 0, 1)
    col = np.stack([0.95 - 0.8 * t, 0.2 + 0.2 * np.sin(np.pi * t), 0.15 + 0.8 * t], 1)
    c = np.asarray(mesh.vertices, np.float64).mean(0)
    stripe = np.arctan2(-(foot[:, 2] - c[2]), foot[:, 0] - c[0])
    col[np.abs(stripe) < 0.35] = 0.95
    size = 0.06
    quat = np.stack([np.zeros(n), np.zeros(n), np.zeros(n), np.ones(n)], 1)
    scales = np.stack([np.full(n, size), np.full(n, size), np.full(n, 0.3 * size)], 1)
    anchors = LocalAnchors(face, bary, np.zeros(n), quat, scales, "affine")
    return _anchored(mesh, anchors, col, np.full(n, 0.95), name)


def _axis_angle_matrix(axis, degrees: float) -> np.ndarray:
    a = np.asarray(axis, np.float64)
    a = a / np.linalg.norm(a)
    t = math.radians(degrees)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(t) * k + (1 - math.cos(t)) * (k @ k)


def _node_case() -> RenderCase:
    cid = "render-node-transforms"
    rng = case_rng(cid)
    prim = _tube_prim(rng, "tube", center=(0.0, -0.5, 0.0))
    mesh = prim.anchoring.mesh  # type: ignore[union-attr]
    v = mesh.vertices.astype(np.float64)
    rot = _axis_angle_matrix((1.0, 0.4, 0.2), 55.0)
    scale, trans = 1.3, np.array([0.35, -0.15, 0.2])
    matrix = np.eye(4)
    matrix[:3, :3] = rot * scale
    matrix[:3, 3] = trans
    q = from_matrix(rot)

    def edit(doc: dict, blob: bytes) -> tuple[dict, bytes]:
        node = next(n for n in doc["nodes"] if n.get("mesh") == 0)
        node.update(translation=trans.tolist(), rotation=[float(x) for x in q],
                    scale=[scale, scale, scale])
        anchor_mesh = doc["meshes"][0]["primitives"][0]["extensions"]["KHR_gaussian_splatting"][
            "extensions"]["GSVERSE_gaussian_splatting_mesh_anchor"]["mesh"]
        doc["nodes"].append({"name": "anchor mesh node (ignored for anchoring)", "mesh": anchor_mesh,
                             "translation": [2.0, 0.5, -1.0], "rotation": [0.0, 0.7071068, 0.0, 0.7071068]})
        doc["scenes"][doc.get("scene", 0)]["nodes"].append(len(doc["nodes"]) - 1)
        return doc, blob

    centre = trans
    cam = _front_camera(centre, 3.2, azimuth=15.0, elevation=10.0)
    frames = [RenderFrame("rest", {"kind": "rest"}, cam),
              RenderFrame("twisted 120 degrees about the tube axis",
                          _vertices(twist(v, 120.0, (0.0, -0.5, 0.0), -0.5, 0.5)), cam),
              RenderFrame("bent 90 degrees", _vertices(bend(v, 90.0, (0.0, -0.5, 0.0), -0.5, 0.5)), cam)]
    return RenderCase(cid, "A tube on a splat node with a translation, a rotation and a uniform "
                      "scale 1.3; another node instantiates the anchor mesh elsewhere (ignored for "
                      "anchoring, not drawn).",
                      "the splat node's transform ignored or applied twice; the anchor mesh drawn",
                      ["render", "render:node-transforms"],
                      SplatAsset([prim], "gsverse-conformance"), frames, edit, [matrix])


def _plain_case() -> RenderCase:
    cid = "render-plain-and-anchored"
    rng = case_rng(cid)
    prim = _tube_prim(rng, "tube", center=(0.0, -0.5, 0.0))
    v = prim.anchoring.mesh.vertices.astype(np.float64)  # type: ignore[union-attr]
    n_back, n_front = 500, 60
    back = np.stack([rng.uniform(-0.9, 0.9, n_back), rng.uniform(-0.8, 0.8, n_back),
                     np.full(n_back, -0.5)], 1)
    front = np.stack([rng.uniform(-0.6, 0.6, n_front), rng.uniform(-0.6, 0.6, n_front),
                      np.full(n_front, 0.45)], 1)
    means = np.concatenate([back, front])
    n = len(means)
    rots = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    scales = np.concatenate([np.tile([0.07, 0.07, 0.01], (n_back, 1)), np.tile([0.04, 0.04, 0.04], (n_front, 1))])
    col = np.concatenate([np.tile([0.15, 0.75, 0.2], (n_back, 1)), np.tile([0.95, 0.9, 0.15], (n_front, 1))])
    col = np.clip(col + rng.normal(0, 0.04, col.shape), 0, 1)
    opac = np.concatenate([np.full(n_back, 0.9), np.full(n_front, 0.95)]).astype(np.float32)
    plain = SplatPrimitive(SplatCloud(means, rots, scales, opac, _rgb_sh(col)), None, name="plain")
    cam = _front_camera((0, 0, 0), 3.0)
    frames = [RenderFrame("rest", {"kind": "rest"}, cam),
              RenderFrame("tube stretched 1.4x along y", _vertices(stretch(v, (1.0, 1.4, 1.0), (0.0, 0.0, 0.0))), cam),
              RenderFrame("tube bent 100 degrees", _vertices(bend(v, 100.0, (0.0, -0.5, 0.0), -0.5, 0.5)), cam)]
    return RenderCase(cid, "An anchored tube between plain splats: a green wall behind it and "
                      "yellow splats in front of it.",
                      "plain splats moved, or anchored and plain splats blended out of depth order",
                      ["render", "render:plain-and-anchored"],
                      SplatAsset([prim, plain], "gsverse-conformance"), frames)


def _skinned_case() -> RenderCase:
    cid = "render-skinned"
    rng = case_rng(cid)
    glb, _, _, duration = skinned_tube(rings=7, segments=10, radius=0.2, height=1.2)
    from ..io.mesh import read_mesh

    with tempfile.TemporaryDirectory(prefix="gsverse-render-case-") as tmp:
        path = Path(tmp) / "skinned.glb"
        path.write_bytes(glb)
        mesh = read_mesh(path)
    if mesh.rig is None:
        raise RuntimeError("the skinned test asset lost its rig")
    prim = _tube_prim(rng, "skinned tube", mesh=mesh, per_face=5)
    cam = _front_camera((0.0, 0.6, 0.0), 3.0, azimuth=10.0, elevation=5.0)
    frames = [RenderFrame("rest (no animation)", {"kind": "rest"}, cam),
              RenderFrame("animation 0 at 0.35 s", {"kind": "animation", "animation": 0, "time": 0.35}, cam),
              RenderFrame(f"animation 0 at {0.85 * duration:g} s",
                          {"kind": "animation", "animation": 0, "time": 0.85 * duration}, cam)]
    return RenderCase(cid, "A tube whose anchor mesh carries a three-joint skin and an animation "
                      "in the file, rendered at two animation times.",
                      "the file's animation not played (or played differently) on the anchor mesh",
                      ["render", "render:skinned"], SplatAsset([prim], "gsverse-conformance"), frames)


def _sliver_case() -> RenderCase:
    cid = "render-sliver-stretched"
    rng = case_rng(cid)
    # a strip of two slivers: 0.6 long along x, 1/40 of that across
    xs = np.linspace(-0.6, 0.6, 3)
    half = 0.6 / 80
    v = np.concatenate([np.stack([xs, np.full(3, -half), np.zeros(3)], 1),
                        np.stack([xs, np.full(3, half), np.zeros(3)], 1)])
    faces = []
    for i in range(2):   # bottom row 0..2, top row 3..5, counter-clockwise seen from +z
        faces += [(i, i + 1, 3 + i + 1), (i, 3 + i + 1, 3 + i)]
    mesh = TriangleMesh(v.astype(np.float32), np.array(faces, np.uint32))
    prim = _needles(mesh, rng, 70, 0.06, "sliver needles")
    vv = mesh.vertices.astype(np.float64)
    cam = _front_camera((0, 0, 0), 1.9)
    frames = [RenderFrame("rest", {"kind": "rest"}, cam),
              RenderFrame("stretched 3x across the slivers (y)", _vertices(stretch(vv, (1.0, 3.0, 1.0), (0, 0, 0))), cam),
              RenderFrame("compressed to 0.6x along x", _vertices(stretch(vv, (0.6, 1.0, 1.0), (0, 0, 0))), cam)]
    return RenderCase(cid, "Needles on sliver triangles (height 1/40 of their length), stretched "
                      "3x across the slivers and compressed along them.",
                      "the affine law's decomposition into rotation and scales on thin triangles",
                      ["render", "render:sliver"], SplatAsset([prim], "gsverse-conformance"), frames)


def render_cases() -> list[RenderCase]:
    """Every render case of the suite, in a fixed order."""
    return [_turn_case(), _fold_case(), _packing_case(), _node_case(), _plain_case(),
            _skinned_case(), _sliver_case(), _spz_turn_case()]
