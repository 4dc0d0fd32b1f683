"""Build the demo's physics scene, ``examples/web/scene.glb``.

    python examples/web/make_scene.py examples/web/scene.glb

Generates the inputs (deterministic: fixed seeds) into a temporary folder — a box-ish chair, a
round pillow and a lamp cylinder as OBJ anchor meshes, splats on each of them and background
splats (a floor and a back wall) in one 3DGS PLY — and converts them as a user does:

    gsverse-convert scene.ply scene.glb --mesh chair.obj --mesh pillow.obj --mesh lamp.obj \\
        --collider hull --max-distance 0.02 --absolute-distance --anchors compact --sh-degree 0

then adds the physics records (``physics_records.py``: chair rigid, pillow soft, lamp kinematic,
a ground box under the scene). ``tests/test_web_demo_physics.py`` checks that the shipped file is
what this command writes.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from physics_records import add_physics_records  # noqa: E402

#: the physics kind of each object (the OBJ file stems)
KINDS = {"chair": "rigid", "pillow": "soft", "lamp": "kinematic"}
#: the base colour of each object's splats, and of the background's floor and wall
COLOURS = {"chair": (0.75, 0.45, 0.2), "pillow": (0.85, 0.3, 0.55), "lamp": (0.9, 0.85, 0.3),
           "floor": (0.35, 0.45, 0.35), "wall": (0.3, 0.4, 0.6)}
COUNTS = {"chair": 1200, "pillow": 1000, "lamp": 500}
#: splats closer than this (scene units) to an object's mesh are anchored to it
MAX_DISTANCE = 0.02


def scene_meshes() -> dict:
    """The three anchor meshes, +Y up (glTF frame), placed in the scene: the chair floats above
    the floor (it falls when the physics runs), the pillow lies a little above it, the lamp
    stands on it."""
    import trimesh

    from gsverse_format.model import TriangleMesh

    def fine(mesh: "trimesh.Trimesh", size: float) -> "trimesh.Trimesh":
        return trimesh.Trimesh(*trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, size))

    seat = trimesh.creation.box([0.5, 0.1, 0.5])
    back = trimesh.creation.box([0.5, 0.5, 0.08])
    back.apply_translation([0.0, 0.3, -0.21])
    chair = fine(trimesh.util.concatenate([seat, back]), 0.1)
    pillow = trimesh.creation.icosphere(3)
    pillow.vertices *= [0.25, 0.1, 0.2]
    lamp = trimesh.creation.cylinder(0.07, 0.8, sections=16)
    lamp.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    lamp = fine(lamp, 0.15)
    place = {"chair": (chair, [-0.55, 0.9, 0.0]), "pillow": (pillow, [0.15, 0.3, 0.1]),
             "lamp": (lamp, [0.7, 0.43, -0.2])}
    return {name: TriangleMesh(np.asarray(m.vertices, dtype=np.float64) + shift, np.asarray(m.faces))
            for name, (m, shift) in place.items()}


def _coloured(cloud, rgb) -> None:
    from gsverse_format.sh import SH_C0

    shade = 0.85 + 0.15 * np.sin(7 * cloud.means[:, :1]) * np.cos(5 * cloud.means[:, 2:3])
    cloud.sh[:, 0] = (np.asarray(rgb) * shade - 0.5) / SH_C0


def background_splats(seed: int = 7):
    """Flat splats on a floor (y = 0, 2.6 x 1.4) and a back wall (z = -0.7), SH degree 1."""
    from gsverse_format.examples import example_splats
    from gsverse_format.model import SplatCloud, TriangleMesh

    parts = []
    for name, corners, count in (
            ("floor", [[-1.3, 0, -0.7], [1.3, 0, -0.7], [1.3, 0, 0.7], [-1.3, 0, 0.7]], 1400),
            ("wall", [[-1.3, 0, -0.7], [-1.3, 1.3, -0.7], [1.3, 1.3, -0.7], [1.3, 0, -0.7]], 900)):
        quad = TriangleMesh(np.asarray(corners, dtype=np.float64), np.array([[0, 2, 1], [0, 3, 2]]))
        cloud = example_splats(quad, count, seed=seed + len(parts))
        cloud.scales = cloud.scales * 1.6
        _coloured(cloud, COLOURS[name])
        parts.append(cloud)
    return SplatCloud.concatenate(parts)


def write_inputs(folder: str) -> tuple[str, list[str]]:
    """Write scene.ply (every splat, 3DGS frame) and one OBJ per object (same frame) into
    ``folder``; returns the PLY and the OBJ paths."""
    from gsverse_format.examples import example_splats, write_obj
    from gsverse_format.io.ply import write_splat_ply
    from gsverse_format.model import SplatCloud
    from gsverse_format.transform import PLY_TO_GLTF, rotate_mesh, rotate_splats

    meshes = scene_meshes()
    clouds, objs = [], []
    for i, (name, mesh) in enumerate(meshes.items()):
        cloud = example_splats(mesh, COUNTS[name], seed=11 + i)
        _coloured(cloud, COLOURS[name])
        clouds.append(cloud)
        objs.append(os.path.join(folder, f"{name}.obj"))
        write_obj(rotate_mesh(mesh, PLY_TO_GLTF), objs[-1])
    clouds.append(background_splats())
    ply = os.path.join(folder, "scene.ply")
    write_splat_ply(rotate_splats(SplatCloud.concatenate(clouds), PLY_TO_GLTF), ply)
    return ply, objs


def build(output: str) -> None:
    """Write the demo scene to ``output`` (atomically: the converter writes it, the physics
    records are added in place through an atomic rewrite)."""
    import gsverse_format as gv

    with tempfile.TemporaryDirectory(prefix="gsverse-scene-") as folder:
        ply, objs = write_inputs(folder)
        gv.convert(ply, output, meshes=objs, collider="hull", max_distance=MAX_DISTANCE,
                   absolute_distance=True, anchors="compact", sh_degree=0)
    add_physics_records(output, KINDS, ground=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="make_scene.py", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("output", help="the .glb to write (examples/web/scene.glb)")
    build(parser.parse_args(argv).output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
