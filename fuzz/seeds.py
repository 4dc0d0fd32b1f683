"""Seeds of the fuzz harness (:mod:`fuzz.fuzz_readers`): small valid files of every kind the
readers accept, built from the data model."""
from __future__ import annotations

import os
import struct
import tempfile

__all__ = ["seeds", "usd_seeds"]


def seeds() -> list[tuple[str, bytes]]:
    """(suffix, bytes) of small valid files of every kind the readers accept."""
    import numpy as np

    from gsverse_format.binding import bind_local
    from gsverse_format.examples import example_mesh, example_splats
    from gsverse_format.io.gltf import asset_to_gltf, gltf_to_bytes
    from gsverse_format.io.ply import write_splat_ply
    from gsverse_format.model import (Anchoring, GamesAnchors, SplatAsset, SplatPrimitive)
    from gsverse_format.remapping.reference import remap

    mesh = example_mesh(subdivisions=0)
    cloud = example_splats(mesh, 12, seed=3)
    local = bind_local(cloud, mesh).anchors
    rng = np.random.default_rng(4)
    games = GamesAnchors(np.sort(rng.integers(0, mesh.face_count, 10)),
                         rng.dirichlet([2, 2, 2], 10)[:, 1:], rng.uniform(0.3, 1.0, 10))
    g = remap(Anchoring(mesh, games))
    from gsverse_format.model import SplatCloud

    gcloud = SplatCloud(g.means, g.rotations, g.scales, rng.uniform(0.2, 1, 10),
                        rng.normal(0, 0.2, (10, 1, 3)))
    anchored = SplatAsset([SplatPrimitive(cloud, Anchoring(mesh, local), "body"),
                           SplatPrimitive(cloud.subset([0, 1, 2]), None, "static")])
    out: list[tuple[str, bytes]] = []
    for asset, kw in ((anchored, {}),
                      (anchored, {"quantize": {"barycentrics": "unsigned_short",
                                               "localRotation": "byte"}}),
                      (anchored, {"anchors": "compact", "compress": "spz"}),
                      (SplatAsset([SplatPrimitive(gcloud, Anchoring(mesh, games), "g")]), {})):
        gltf = asset_to_gltf(asset, **kw)
        out.append((".glb", gltf_to_bytes(gltf, binary=True)))
    out.append((".gltf", gltf_to_bytes(asset_to_gltf(SplatAsset(
        [SplatPrimitive(gcloud, Anchoring(mesh, games), "g")])), binary=False)))
    with tempfile.TemporaryDirectory() as tmp:
        for name, kw in (("le.ply", {}), ("be.ply", {"byte_order": ">"}),
                         ("ascii.ply", {"binary": False}), ("n.ply", {"normals": True})):
            path = os.path.join(tmp, name)
            write_splat_ply(cloud.subset(range(6)), path, **kw)
            with open(path, "rb") as handle:
                out.append((".ply", handle.read()))
    v = mesh.vertices
    header = (f"ply\nformat ascii 1.0\nelement vertex {len(v)}\nproperty float x\n"
              f"property float y\nproperty float z\nelement face {mesh.face_count}\n"
              f"property list uchar int vertex_indices\nend_header\n")
    body = "".join(f"{a:.6g} {b:.6g} {c:.6g}\n" for a, b, c in v.tolist())
    body += "".join(f"3 {a} {b} {c}\n" for a, b, c in mesh.faces.tolist())
    out.append((".ply", (header + body).encode()))
    binary = (header.replace("ascii", "binary_little_endian").encode()
              + v.astype("<f4").tobytes()
              + b"".join(b"\x03" + struct.pack("<3i", *f) for f in mesh.faces.tolist()))
    out.append((".ply", binary))
    out.extend(usd_seeds(anchored, SplatAsset([SplatPrimitive(gcloud, Anchoring(mesh, games),
                                                              "g")])))
    return out


def usd_seeds(*assets) -> list[tuple[str, bytes]]:
    """``.usda`` and ``.usdc`` files of ``assets`` (none without usd-core)."""
    try:
        import pxr  # noqa: F401
    except ImportError:
        return []
    from gsverse_format.io.usd import write_usd

    out: list[tuple[str, bytes]] = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, asset in enumerate(assets):
            for suffix in (".usda", ".usdc"):
                path = os.path.join(tmp, f"seed{i}{suffix}")
                write_usd(asset, path)
                with open(path, "rb") as handle:
                    out.append((suffix, handle.read()))
    return out
