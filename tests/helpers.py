"""Shared generators for tests: random meshes, splats, anchors."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from gsverse_format.model import SplatCloud, TriangleMesh


def random_rotation(seed: int) -> np.ndarray:
    return Rotation.random(random_state=seed).as_matrix()


def bumpy_sphere(subdivisions: int = 2, seed: int = 0, bump: float = 0.15) -> TriangleMesh:
    """A closed, irregular triangle mesh (icosphere with radial noise)."""
    import trimesh

    ico = trimesh.creation.icosphere(subdivisions=subdivisions)
    rng = np.random.default_rng(seed)
    v = ico.vertices * (1.0 + bump * rng.uniform(-1, 1, size=(len(ico.vertices), 1)))
    return TriangleMesh(v, ico.faces)


def random_splats(n: int, seed: int = 0, *, sh_degree: int = 1, center=(0, 0, 0),
                  spread: float = 1.2, scale: float = 0.05) -> SplatCloud:
    rng = np.random.default_rng(seed)
    k = (sh_degree + 1) ** 2
    means = np.asarray(center) + rng.uniform(-spread, spread, size=(n, 3))
    return SplatCloud(
        means=means,
        rotations=Rotation.random(n, random_state=seed).as_quat(),
        scales=scale * np.exp(rng.normal(0, 0.7, size=(n, 3))),
        opacities=rng.uniform(0.05, 1.0, n),
        sh=rng.normal(0, 0.3, size=(n, k, 3)),
    )


def surface_splats(mesh: TriangleMesh, n: int, seed: int = 0, *, offset: float = 0.02,
                   sh_degree: int = 1) -> SplatCloud:
    """Splats near the surface of ``mesh`` (random faces, barycentrics, normal offsets)."""
    rng = np.random.default_rng(seed)
    tri = mesh.triangles()
    f = rng.integers(0, mesh.face_count, n)
    b = rng.dirichlet([1, 1, 1], n)
    p = np.einsum("nm,nmx->nx", b, tri[f])
    nrm = np.cross(tri[f, 1] - tri[f, 0], tri[f, 2] - tri[f, 0])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    p += nrm * rng.uniform(-offset, offset, (n, 1))
    cloud = random_splats(n, seed, sh_degree=sh_degree, scale=0.02)
    cloud.means = p.astype(np.float32)
    return cloud


def max_rel_cov_error(a: np.ndarray, b: np.ndarray) -> float:
    """max_i ||A_i − B_i||_F / ||B_i||_F."""
    num = np.linalg.norm(a - b, axis=(1, 2))
    den = np.linalg.norm(b, axis=(1, 2))
    return float(np.max(num / den))


def extension_schema_validator():
    """A jsonschema validator for the shipped extension schema (spec/schema), with a stand-in
    for Khronos' glTFProperty.schema.json (an object with optional "extensions" and "extras")."""
    import json
    import pathlib

    import pytest

    jsonschema = pytest.importorskip("jsonschema")
    referencing = pytest.importorskip("referencing")
    name = "primitive.KHR_gaussian_splatting.GSVERSE_gaussian_splatting_mesh_anchor.schema.json"
    path = pathlib.Path(__file__).resolve().parents[1] / "spec" / "schema" / name
    schema = json.loads(path.read_text())
    gltf_property = {"$schema": "https://json-schema.org/draft/2020-12/schema",
                     "$id": "glTFProperty.schema.json", "type": "object",
                     "properties": {"extensions": {"type": "object",
                                                   "additionalProperties": {"type": "object"}},
                                    "extras": {}}}
    registry = referencing.Registry().with_resources([
        (uri, referencing.Resource.from_contents(s)) for uri, s in
        [(schema["$id"], schema), ("glTFProperty.schema.json", gltf_property)]])
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema, registry=registry)
