"""Generated inputs that imitate the files SuGaR and GaMeS / GS-Verse write.

The values are computed here from the published formulas of each tool (independently of the
converters under test): SuGaR's slot table, surface frame and flat scales; GaMeS's α
normalization, ε-regularized frame and ρ-scaled base scales, in float32 as the tools compute.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from gsverse_format.io.ply import write_splat_ply
from gsverse_format.model import SplatCloud

from helpers import bumpy_sphere

# SuGaR's slot tables (rows: weights of corners v0, v1, v2), held as float32 by SuGaR.
SUGAR_SLOTS = {
    1: [[1 / 3, 1 / 3, 1 / 3]],
    3: [[1 / 2, 1 / 4, 1 / 4], [1 / 4, 1 / 2, 1 / 4], [1 / 4, 1 / 4, 1 / 2]],
    4: [[1 / 3, 1 / 3, 1 / 3], [2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]],
    6: [[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3],
        [1 / 6, 5 / 12, 5 / 12], [5 / 12, 1 / 6, 5 / 12], [5 / 12, 5 / 12, 1 / 6]],
}
GAMES_EPS = np.float32(1e-8)


def write_obj(path, vertices, faces, *, decimals: int | None = None, uv_per_corner: bool = False):
    """Write an OBJ by hand. ``decimals=6`` imitates pytorch3d's ``save_obj`` default ("%f"),
    which SuGaR uses; ``None`` writes float32 values exactly. ``uv_per_corner`` adds a ``vt``
    per face corner (as SuGaR's texture atlas does), so readers split vertices at the seams."""
    fmt = "%f" if decimals == 6 else ("%.{}f".format(decimals) if decimals else "%.9g")
    lines = ["# generated"]
    lines += ["v " + " ".join(fmt % c for c in v) for v in np.asarray(vertices, np.float32)]
    faces = np.asarray(faces, np.int64)
    if uv_per_corner:
        rng = np.random.default_rng(1)
        lines += ["vt %f %f" % tuple(t) for t in rng.uniform(0, 1, (3 * len(faces), 2))]
        lines += ["f " + " ".join(f"{v + 1}/{3 * i + j + 1}" for j, v in enumerate(f))
                  for i, f in enumerate(faces)]
    else:
        lines += ["f " + " ".join(str(v + 1) for v in f) for f in faces]
    with open(path, "w") as out:
        out.write("\n".join(lines) + "\n")


def write_ply_mesh(path, vertices, faces):
    """A binary PLY mesh (as Open3D writes SuGaR's coarse mesh: float xyz, uchar/int faces)."""
    vertices = np.asarray(vertices, "<f4")
    faces = np.asarray(faces, "<i4")
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(vertices)}\n"
              "property float x\nproperty float y\nproperty float z\n"
              f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
    rows = np.zeros(len(faces), [("n", "u1"), ("v", "<i4", (3,))])
    rows["n"], rows["v"] = 3, faces
    with open(path, "wb") as out:
        out.write(header.encode("ascii") + vertices.tobytes() + rows.tobytes())


def _random_colour(rng, n, degree=3):
    k = (degree + 1) ** 2
    opacity = rng.uniform(0.05, 0.99, n).astype(np.float32)
    return opacity, rng.normal(0, 0.3, (n, k, 3)).astype(np.float32)


def _unit(v, eps=0.0):
    return v / (np.linalg.norm(v, axis=-1, keepdims=True) + eps)


# --------------------------------------------------------------------------------------------
# SuGaR


@dataclass
class SugarScene:
    vertices: np.ndarray      # (V, 3) float32, refined vertices (COLMAP frame)
    faces: np.ndarray         # (F, 3)
    cloud: SplatCloud         # what the refined PLY holds (activated)
    k: int


def sugar_scene(k: int, seed: int = 0, *, faces=None, vertices=None) -> SugarScene:
    """A refined SuGaR model: k splats per face at SuGaR's slots, SuGaR's surface frame."""
    if vertices is None:
        mesh = bumpy_sphere(2, seed)
        vertices = mesh.vertices.astype(np.float64) * 2.5 + (1.5, -0.75, 4.0)
        faces = mesh.faces.astype(np.int64)
    v = np.asarray(vertices, np.float32)
    f = np.asarray(faces, np.int64)
    rng = np.random.default_rng(seed)
    tri = v[f]                                                   # (F, 3, 3) float32
    bary = np.asarray(SUGAR_SLOTS[k], np.float32)                # (k, 3)
    means = (tri[:, None, :, :] * bary[None, :, :, None]).sum(axis=-2).reshape(-1, 3)

    # Surface frame: n = face normal, e = unit(v0 − v1), t = unit(n × e), learned angle per splat.
    n = _unit(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]).astype(np.float64))
    e = _unit((tri[:, 0] - tri[:, 1]).astype(np.float64))
    t = _unit(np.cross(n, e))
    n, e, t = (np.repeat(a, k, axis=0) for a in (n, e, t))
    angle = rng.uniform(-np.pi, np.pi, len(means))
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    r = np.stack([n, c * e + s * t, -s * e + c * t], axis=-1)     # columns [n, R1, R2]
    quats = Rotation.from_matrix(r).as_quat()

    lo, hi = v.min(axis=0), v.max(axis=0)
    thickness = float(np.linalg.norm(hi - lo)) / 1e6
    shortest = np.min(np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=-1), axis=-1)
    base = np.repeat(shortest, k) / (2 * np.sqrt(3))
    scales = np.stack([np.full(len(means), thickness),
                       base * np.exp(rng.normal(0, 0.3, len(means))),
                       base * np.exp(rng.normal(0, 0.3, len(means)))], axis=-1)
    opacity, sh = _random_colour(rng, len(means))
    cloud = SplatCloud(means, quats, scales, opacity, sh)
    return SugarScene(v, f, cloud, k)


def write_sugar(scene: SugarScene, folder, *, ply_name: str | None = None,
                decimals: int | None = 6, uv_per_corner: bool = True) -> tuple[str, str]:
    """Write ``refined_ply/…gaussperface<k>.ply`` and the refined ``.obj``; return both paths."""
    os.makedirs(folder, exist_ok=True)
    ply = os.path.join(folder, ply_name or f"sugarfine_scene_gaussperface{scene.k}.ply")
    obj = os.path.join(folder, "sugarfine_scene.obj")
    write_splat_ply(scene.cloud, ply)
    write_obj(obj, scene.vertices, scene.faces, decimals=decimals, uv_per_corner=uv_per_corner)
    return ply, obj


# --------------------------------------------------------------------------------------------
# GaMeS / GS-Verse

#: GaMeS's NeRF-synthetic reader: mesh.obj (x, y, z) -> (x, −z, y).
def games_blender_transform(v):
    v = np.asarray(v, np.float32)[:, [0, 2, 1]].copy()
    v[:, 1] = -v[:, 1]
    return v


@dataclass
class GamesScene:
    obj_vertices: np.ndarray   # (V, 3) float32 as mesh.obj holds them
    train_vertices: np.ndarray  # after GaMeS's reader (Blender) or the same (COLMAP)
    faces: np.ndarray
    alpha_raw: np.ndarray      # (F, k, 3) float32
    rho: np.ndarray            # (N,) float32
    cloud: SplatCloud          # what point_cloud.ply holds
    k: int


def games_scene(frame: str, k: int = 5, seed: int = 0) -> GamesScene:
    """A trained GaMeS model on a bumpy sphere; ``frame`` is "blender" or "colmap"."""
    mesh = bumpy_sphere(2, seed + 7)
    obj = (mesh.vertices.astype(np.float64) * (1.2, 0.9, 1.5) + (0.4, -0.3, 0.7)).astype(np.float32)
    faces = mesh.faces.astype(np.int64)
    train = games_blender_transform(obj) if frame == "blender" else obj.copy()
    rng = np.random.default_rng(seed)
    f = len(faces)
    alpha_raw = rng.uniform(-0.3, 1.0, (f, k, 3)).astype(np.float32)
    rho = rng.uniform(0.3, 1.6, f * k).astype(np.float32)

    eps = GAMES_EPS
    tri = train[faces]                                           # float32
    alpha = np.maximum(alpha_raw, 0) + eps
    alpha = alpha / alpha.sum(axis=-1, keepdims=True)
    means = np.matmul(alpha, tri).reshape(-1, 3)                 # (F, k, 3) -> (N, 3)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    r0 = normal / (np.linalg.norm(normal, axis=-1, keepdims=True) + eps)
    centre = tri.mean(axis=1)
    r1 = tri[:, 1] - centre
    r1_len = np.linalg.norm(r1, axis=-1, keepdims=True) + eps
    r1 = r1 / r1_len
    w = tri[:, 2] - centre
    r2 = w - (w * r0).sum(-1, keepdims=True) * r0 - (w * r1).sum(-1, keepdims=True) * r1
    r2 = r2 / (np.linalg.norm(r2, axis=-1, keepdims=True) + eps)
    base = np.concatenate([np.full_like(r1_len, eps), r1_len / 2,
                           (w * r2).sum(-1, keepdims=True) / 2], axis=-1)   # (F, 3)
    scales = np.maximum(rho[:, None] * np.repeat(base, k, axis=0), 0) + eps
    rot = np.repeat(np.stack([r0, r1, r2], axis=-1), k, axis=0)             # columns
    quats = Rotation.from_matrix(rot.astype(np.float64)).as_quat()
    opacity, sh = _random_colour(rng, len(means))
    cloud = SplatCloud(means, quats, scales, opacity, sh)
    return GamesScene(obj, train, faces, alpha_raw, rho, cloud, k)


def write_games_json(scene: GamesScene, path):
    """``model_params.json`` as GS-Verse's import_params.py writes it."""
    with open(path, "w") as out:
        json.dump({"_alpha": scene.alpha_raw.tolist(), "_scale": scene.rho[:, None].tolist()}, out)


def write_gsverse_folder(scene: GamesScene, folder, *, mesh: bool = True, params: bool = True):
    """A GS-Verse export folder: point_cloud.ply, model_params.json, mesh.obj."""
    os.makedirs(folder, exist_ok=True)
    write_splat_ply(scene.cloud, os.path.join(folder, "point_cloud.ply"))
    if params:
        write_games_json(scene, os.path.join(folder, "model_params.json"))
    if mesh:
        write_obj(os.path.join(folder, "mesh.obj"), scene.obj_vertices, scene.faces)
    return folder
