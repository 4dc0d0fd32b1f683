"""Shared generators for tests: random meshes, splats, anchors."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

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


def gltf_accessor(g, i: int) -> np.ndarray:
    """Accessor ``i`` of a pygltflib GLB as float64 (count, components), byteStride honoured."""
    a = g.accessors[i]
    view = g.bufferViews[a.bufferView]
    n = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}[a.type]
    dt = np.dtype({5126: "<f4", 5123: "<u2", 5121: "<u1"}[a.componentType])
    blob = g.binary_blob()
    start = (view.byteOffset or 0) + (a.byteOffset or 0)
    stride = view.byteStride or dt.itemsize * n
    return np.ndarray((a.count, n), dt, blob, start, (stride, dt.itemsize)).astype(np.float64)


def numpy_skinning(g, node_i: int, t: float, animation: int | None = 0,
                   primitive: int = 0) -> np.ndarray:
    """glTF morph + linear blend skinning of ``primitive`` of the mesh of node ``node_i`` at
    time ``t`` (LINEAR channels; ``animation=None``: the rest pose, the nodes' own values),
    written from the glTF spec in plain numpy and scipy: the tests' own reference, independent
    of :mod:`gsverse_format.poses`."""
    nodes = g.nodes
    trs = {i: [np.array(n.translation or [0, 0, 0], float),
               Rotation.from_quat(n.rotation or [0, 0, 0, 1]),
               np.array(n.scale or [1, 1, 1], float)] for i, n in enumerate(nodes)}
    mesh = g.meshes[nodes[node_i].mesh]
    morph = np.array(getattr(nodes[node_i], "weights", None) or mesh.weights or [], float)
    for ch in [] if animation is None else g.animations[animation].channels:
        anim = g.animations[animation]
        s = anim.samplers[ch.sampler]
        keys, vals = gltf_accessor(g, s.input)[:, 0], gltf_accessor(g, s.output)
        tc = float(np.clip(t, keys[0], keys[-1]))
        n, path = ch.target.node, ch.target.path
        if path == "weights" and n == node_i:
            vals = vals.reshape(len(keys), -1)
            morph = np.array([np.interp(tc, keys, vals[:, k]) for k in range(vals.shape[1])])
        elif path == "rotation":
            trs[n][1] = Slerp(keys, Rotation.from_quat(vals))([tc])[0]
        elif path in ("translation", "scale"):
            trs[n][0 if path == "translation" else 2] = np.array(
                [np.interp(tc, keys, vals[:, k]) for k in range(3)])
    parents = {c: i for i, n in enumerate(nodes) for c in (n.children or [])}

    def local(i: int) -> np.ndarray:
        if nodes[i].matrix:
            return np.array(nodes[i].matrix, float).reshape(4, 4).T
        m = np.eye(4)
        m[:3, :3] = trs[i][1].as_matrix() @ np.diag(trs[i][2])
        m[:3, 3] = trs[i][0]
        return m

    def world(i: int) -> np.ndarray:
        return local(i) if i not in parents else world(parents[i]) @ local(i)

    node = nodes[node_i]
    attrs = g.meshes[node.mesh].primitives[primitive].attributes
    pos = gltf_accessor(g, attrs.POSITION)
    for w, target in zip(morph, mesh.primitives[primitive].targets or []):
        pos = pos + w * gltf_accessor(g, target["POSITION"])
    if node.skin is None:   # not skinned: placed by its node
        m = world(node_i)
        return pos @ m[:3, :3].T + m[:3, 3]
    skin = g.skins[node.skin]
    ibm = gltf_accessor(g, skin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1)
    jn, wt = gltf_accessor(g, attrs.JOINTS_0).astype(int), gltf_accessor(g, attrs.WEIGHTS_0)
    mats = np.stack([world(j) @ ibm[k] for k, j in enumerate(skin.joints)])
    homo = np.c_[pos, np.ones(len(pos))]
    v = sum(wt[:, k, None] * np.einsum("nij,nj->ni", mats[jn[:, k]], homo) for k in range(4))
    return v[:, :3]


def anchor_foot_points(prim, vertices: np.ndarray) -> np.ndarray:
    """The barycentric anchor point of every splat on the posed triangles (float64)."""
    a = prim.anchoring.anchors
    tri = np.asarray(vertices, np.float64)[prim.anchoring.mesh.faces.astype(np.intp)]
    tri = tri[a.face_index.astype(np.intp)]
    b = a.barycentrics.astype(np.float64)
    return (1 - b[:, :1] - b[:, 1:]) * tri[:, 0] + b[:, :1] * tri[:, 1] + b[:, 1:] * tri[:, 2]


def fuzz_module(name: str):
    """The module ``fuzz.<name>`` of this checkout's fuzz harness (``fuzz/`` is run as
    ``python -m fuzz.fuzz_readers`` from the checkout and installed nowhere), imported from
    its file: the package is registered under its own name, ``sys.path`` stays as it is (so
    that no test sees the checkout's ``converters``/``validators`` folders as top-level
    packages)."""
    import importlib
    import importlib.util
    import pathlib
    import sys

    folder = pathlib.Path(__file__).resolve().parents[1] / "fuzz"
    package = sys.modules.get("fuzz")
    if package is None:
        spec = importlib.util.spec_from_file_location(
            "fuzz", folder / "__init__.py", submodule_search_locations=[str(folder)])
        assert spec is not None and spec.loader is not None
        package = importlib.util.module_from_spec(spec)
        sys.modules["fuzz"] = package
        spec.loader.exec_module(package)
    if [pathlib.Path(p).resolve() for p in getattr(package, "__path__", [])] != [folder]:
        raise ImportError(f"another package named fuzz is loaded: {package!r}")
    return importlib.import_module(f"fuzz.{name}")
