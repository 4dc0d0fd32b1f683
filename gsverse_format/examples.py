"""Generate the small example the README converts: splats on a bumpy capsule + its mesh.

``python -m gsverse_format.examples FOLDER`` writes ``FOLDER/splats.ply`` (3DGS PLY, SH degree 1,
in the 3DGS frame like a trained capture) and ``FOLDER/mesh.obj`` (the anchor mesh, same frame).
The output is deterministic (fixed seed).
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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m gsverse_format.examples", description=__doc__)
    parser.add_argument("folder", help="where to write splats.ply and mesh.obj")
    args = parser.parse_args(argv)
    for path in make_example(args.folder):
        print(path)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
