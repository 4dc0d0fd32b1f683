"""The render case of the SPZ-compressed rest pose (``render-spz-turn``): written compressed,
its reference pictures are those of the decoded rest pose, and a reader that skips the SPZ frame
change (RUB to glTF) draws pictures the render check fails."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from gsverse_format.anchors_derive import derive_local
from gsverse_format.conformance import render_export
from gsverse_format.conformance.render_cases import render_cases
from gsverse_format.conformance.render_check import read_rgb, score_frame
from gsverse_format.io.gltf import read_gltf
from gsverse_format.conformance.glb import unpack_glb
from gsverse_format.model import Anchoring, LocalAnchors, SplatAsset
from gsverse_format.vocabulary import SPZ_EXTENSION

CID = "render-spz-turn"


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    case = next(c for c in render_cases() if c.id == CID)
    case_dir = tmp_path_factory.mktemp("render-spz") / CID
    manifest = render_export._export_case(case, case_dir)
    return case, case_dir, manifest


def _pictures(asset: SplatAsset, case, manifest, case_dir) -> list[np.ndarray]:
    out = []
    for frame, entry in zip(case.frames, manifest["frames"]):
        d = entry["deformation"]
        poses = None
        if d["kind"] == "vertices":
            v = np.fromfile(case_dir / d["file"], "<f4").reshape(-1, 3)
            poses = [v.astype(np.float64)]
        out.append(render_export.render_reference(asset, [np.eye(4)], poses, frame.camera))
    return out


def test_the_case_is_compressed_and_tagged(exported):
    case, case_dir, manifest = exported
    assert "encoding:spz" in manifest["tags"] and "encoding:spz" in case.tags
    doc, _ = unpack_glb((case_dir / "asset.glb").read_bytes())
    assert SPZ_EXTENSION in doc.get("extensionsUsed", [])


def test_references_are_the_decoded_rest_pose_and_a_reader_without_the_frame_change_fails(
        exported):
    case, case_dir, manifest = exported
    asset = read_gltf(str(case_dir / "asset.glb"))
    prim = asset.primitives[0]
    refs = [read_rgb(case_dir / e["reference"]) for e in manifest["frames"]]
    decoded = _pictures(asset, case, manifest, case_dir)
    assert all(np.array_equal(a, b) for a, b in zip(decoded, refs))

    # a reader skipping the frame change: positions and quaternions with x and z negated
    s = prim.splats
    axis = np.array([-1.0, 1.0, -1.0])
    means = (s.means.astype(np.float64) * axis).astype(np.float32)
    rots = (s.rotations.astype(np.float64) * np.array([-1.0, 1.0, -1.0, 1.0])).astype(np.float32)
    a = prim.anchoring.anchors
    mesh = prim.anchoring.mesh
    derived = derive_local(mesh, a.face_index, means, rots, dtype=np.float32)
    anchors = LocalAnchors(a.face_index, derived.barycentrics, derived.normal_offset,
                           derived.local_rotation, a.local_scale, a.deformation)
    cloud = dataclasses.replace(s, means=means, rotations=rots)
    broken = dataclasses.replace(asset, primitives=[
        dataclasses.replace(prim, splats=cloud, anchoring=Anchoring(mesh, anchors))])
    wrong = _pictures(broken, case, manifest, case_dir)
    scores = [score_frame(w, r, manifest["thresholds"], i)
              for i, (w, r) in enumerate(zip(wrong, refs))]
    th = manifest["thresholds"]
    assert all(f.psnr_db < th["psnr_db"] or f.iou < th["iou"] for f in scores), scores
