"""Generate the small examples the README converts: splats on a bumpy capsule + its mesh, and
a room of three objects for physics.

``python -m gsverse_format.examples FOLDER`` writes ``FOLDER/splats.ply`` (3DGS PLY, SH degree 1,
in the 3DGS frame like a trained capture) and ``FOLDER/mesh.obj`` (the anchor mesh, same frame).
``python -m gsverse_format.examples --physics-scene FOLDER`` writes ``FOLDER/room.ply`` (splats
on a box ``chair``, a squashed sphere ``pillow`` and a cylinder ``lamp``, and a floor of plain
splats under them) and the three meshes ``chair.obj``, ``pillow.obj``, ``lamp.obj``;
:func:`physics_scene_arguments` is the ``gsverse-convert`` command that makes them a scene with
physics (:data:`PHYSICS_SCENE_KINDS`, a ground). The output is deterministic (fixed seeds).
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

from . import quaternion as quat
from .atomic import atomic_write
from .frames import local_frames
from .model import SplatCloud, TriangleMesh
from .sh import SH_C0
from .transform import PLY_TO_GLTF, rotate_mesh, rotate_splats


def example_mesh(subdivisions: int = 3, seed: int = 0) -> TriangleMesh:
    """A bumpy capsule-like closed mesh, +Y up, about 1 unit wide and 1.6 tall."""
    import trimesh

    ico = trimesh.creation.icosphere(subdivisions=subdivisions)
    v = ico.vertices * [0.5, 0.8, 0.5]
    rng = np.random.default_rng(seed)
    bumps = 1.0 + 0.06 * np.sin(7 * v[:, 0:1]) * np.cos(5 * v[:, 1:2]) + 0.01 * rng.standard_normal((len(v), 1))
    return TriangleMesh(v * bumps, ico.faces)


def example_splats(mesh: TriangleMesh, count: int = 3000, seed: int = 1) -> SplatCloud:
    """Flat splats lying on ``mesh`` (small normal offsets), coloured by height, SH degree 1."""
    rng = np.random.default_rng(seed)
    tri = mesh.triangles()
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    face = rng.choice(mesh.face_count, size=count, p=area / area.sum())
    bary = rng.dirichlet([2, 2, 2], count)
    frames = local_frames(tri[face])
    normal = frames.rotation[:, :, 2]
    means = np.einsum("nm,nmx->nx", bary, tri[face]) + normal * rng.normal(0, 0.004, (count, 1))
    spin = rng.uniform(0, np.pi, count)
    in_plane = np.stack([np.zeros(count), np.zeros(count), np.sin(spin / 2), np.cos(spin / 2)], -1)
    rotations = quat.multiply(quat.from_matrix(frames.rotation), in_plane)
    scales = np.stack([rng.uniform(0.02, 0.04, count), rng.uniform(0.01, 0.02, count),
                       np.full(count, 0.002)], -1)
    height = (means[:, 1] - means[:, 1].min()) / np.ptp(means[:, 1])
    rgb = np.stack([0.9 - 0.6 * height, 0.3 + 0.5 * height, 0.2 + 0.6 * height], -1)
    sh = np.zeros((count, 4, 3))
    sh[:, 0] = (rgb - 0.5) / SH_C0
    sh[:, 1:] = rng.normal(0, 0.05, (count, 3, 3))
    opacities = rng.uniform(0.6, 0.99, count)
    return SplatCloud(means, rotations, scales, opacities, sh)


def write_obj(mesh: TriangleMesh, path: str) -> None:
    """Write ``mesh`` as a minimal Wavefront OBJ (v and f lines only), atomically."""
    lines = [f"v {x:.7g} {y:.7g} {z:.7g}\n" for x, y, z in mesh.vertices.astype(np.float64)]
    lines += [f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in mesh.faces.astype(np.int64)]
    with atomic_write(path, "w") as handle:
        handle.write("# gsverse-format example anchor mesh\n")
        handle.writelines(lines)


def make_example(folder: str) -> tuple[str, str]:
    """Write the example PLY and OBJ into ``folder`` (created if missing); returns their paths."""
    from .io.ply import write_splat_ply

    os.makedirs(folder, exist_ok=True)
    mesh = example_mesh()
    splats = example_splats(mesh)
    # Store both in the 3DGS capture frame (+Y down), like a trained scene.
    ply_path = os.path.join(folder, "splats.ply")
    obj_path = os.path.join(folder, "mesh.obj")
    write_splat_ply(rotate_splats(splats, PLY_TO_GLTF), ply_path)
    write_obj(rotate_mesh(mesh, PLY_TO_GLTF), obj_path)
    return ply_path, obj_path


#: The physics scene's objects (mesh file stems) and their ``--physics`` kinds.
PHYSICS_SCENE_KINDS: dict[str, str] = {"chair": "rigid", "pillow": "soft", "lamp": "kinematic"}
#: The floor splats' height (glTF frame, +Y up): below every object by more than
#: ``--max-distance`` (:data:`PHYSICS_SCENE_MAX_DISTANCE` of each object's diagonal, at most
#: 0.051), so that they stay plain static splats.
PHYSICS_SCENE_FLOOR = -0.06
PHYSICS_SCENE_MAX_DISTANCE = 0.04


def physics_scene_meshes() -> dict[str, TriangleMesh]:
    """The physics scene's anchor meshes in the glTF frame (+Y up), standing on y = 0: a box
    ``chair``, a squashed sphere ``pillow`` (a closed mesh, for a soft body) and a cylinder
    ``lamp``; keys in :data:`PHYSICS_SCENE_KINDS` order."""
    import trimesh

    box = trimesh.creation.box(extents=[0.5, 0.8, 0.5])
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.35)
    can = trimesh.creation.cylinder(radius=0.15, height=1.2, sections=16)
    can.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    meshes = {"chair": (box.vertices + [-1.2, 0.4, 0.0], box.faces),
              "pillow": (ball.vertices * [1.0, 0.6, 1.0] + [0.0, 0.21, 0.0], ball.faces),
              "lamp": (can.vertices + [1.2, 0.6, 0.0], can.faces)}
    return {name: TriangleMesh(np.asarray(v, np.float64), np.asarray(f, np.int64))
            for name, (v, f) in meshes.items()}


def physics_scene_splats(meshes: dict[str, TriangleMesh], seed: int = 7) -> SplatCloud:
    """Splats on each of ``meshes`` (:func:`example_splats`) and a flat floor of 600 plain
    splats at y = :data:`PHYSICS_SCENE_FLOOR`, SH degree 1, glTF frame."""
    counts = {"chair": 1200, "pillow": 1500, "lamp": 800}
    clouds = [example_splats(mesh, counts.get(name, 1000), seed=seed + k)
              for k, (name, mesh) in enumerate(meshes.items())]
    rng = np.random.default_rng(seed + 100)
    n = 600
    means = np.stack([rng.uniform(-2.0, 2.0, n), np.full(n, PHYSICS_SCENE_FLOOR),
                      rng.uniform(-1.2, 1.2, n)], -1)
    spin = rng.uniform(0, np.pi, n)
    flat = quat.multiply(np.tile([-np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)], (n, 1)),
                         np.stack([np.zeros(n), np.zeros(n), np.sin(spin / 2),
                                   np.cos(spin / 2)], -1))
    scales = np.stack([rng.uniform(0.06, 0.1, n), rng.uniform(0.04, 0.08, n),
                       np.full(n, 0.003)], -1)
    sh = np.zeros((n, 4, 3))
    sh[:, 0] = (np.array([0.45, 0.42, 0.38]) + rng.normal(0, 0.03, (n, 3)) - 0.5) / SH_C0
    clouds.append(SplatCloud(means, flat, scales, rng.uniform(0.7, 0.95, n), sh))
    return SplatCloud.concatenate(clouds)


def make_physics_scene(folder: str) -> list[str]:
    """Write the physics scene into ``folder`` (created if missing), in the 3DGS capture frame
    like :func:`make_example`: ``room.ply`` and one OBJ per object; returns their paths."""
    from .io.ply import write_splat_ply

    os.makedirs(folder, exist_ok=True)
    meshes = physics_scene_meshes()
    ply_path = os.path.join(folder, "room.ply")
    write_splat_ply(rotate_splats(physics_scene_splats(meshes), PLY_TO_GLTF), ply_path)
    paths = [ply_path]
    for name, mesh in meshes.items():
        paths.append(os.path.join(folder, f"{name}.obj"))
        write_obj(rotate_mesh(mesh, PLY_TO_GLTF), paths[-1])
    return paths


def physics_scene_arguments(folder: str, output: str) -> list[str]:
    """The ``gsverse-convert`` arguments that turn the physics scene in ``folder``
    (:func:`make_physics_scene`) into ``output``: each object anchored with its kind of
    :data:`PHYSICS_SCENE_KINDS`, the floor static, a ground under it, compact anchors."""
    args = [os.path.join(folder, "room.ply"), output]
    for name in PHYSICS_SCENE_KINDS:
        args += ["--mesh", os.path.join(folder, f"{name}.obj")]
    return args + ["--max-distance", f"{PHYSICS_SCENE_MAX_DISTANCE:g}", "--physics",
                   ",".join(f"{k}={v}" for k, v in PHYSICS_SCENE_KINDS.items()), "--ground",
                   "--anchors", "compact"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m gsverse_format.examples", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("folder", help="where to write splats.ply and mesh.obj (with "
                                       "--physics-scene: room.ply, chair.obj, pillow.obj, "
                                       "lamp.obj)")
    parser.add_argument("--physics-scene", action="store_true",
                        help="write the physics scene instead of the capsule")
    args = parser.parse_args(argv)
    paths = make_physics_scene(args.folder) if args.physics_scene else make_example(args.folder)
    for path in paths:
        print(path)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
