"""The web plugin's anchor animation sampler (``plugins/web/src/animation.js``,
``readAnchorAnimation``) against the package's reference, the path ``gsverse-pose`` follows
without ``--source`` (:func:`gsverse_format.poses.gltf_source.open_gltf_source` on the asset,
``match`` against the anchor mesh's rest vertices, then ``at(t)``), on converted assets that
keep their rig: a skinned tube and a skinned and morphed asset built here, and the Khronos Fox
(three animations) and SimpleSkin from ``../shared/data`` when present.

Both sides read the same float32 values from the file and evaluate in binary64; the plugin
stores its result as float32. So they agree to the float32 rounding of the posed vertices
(about 6·10⁻⁸ of their distance from the origin, a few heights at most) plus the different
summation order of the binary64 products: the bound, 10⁻⁵ of the character's height, is two
orders of magnitude above that and far below anything a wrong key, interval, interpolation,
joint matrix or morph weight would give."""
from __future__ import annotations

import json

import numpy as np
import pytest

import gsverse_format as gv
from gsverse_format.conformance.skin import skinned_tube
from gsverse_format.io.mesh import read_mesh
from gsverse_format.model import SplatAsset, SplatPrimitive, TriangleMesh
from gsverse_format.poses.gltf_source import open_gltf_source

from helpers import surface_splats
from web_tools import require_web_tools, run_node

#: max |JS − reference| allowed, as a fraction of the character's height (see the docstring)
TOLERANCE = 1e-5

# Reads argv: asset path, JSON list of time lists (one per animation), output path. Writes the
# rest pose and then every (animation, time) pose as float32 to the output, and a JSON summary
# to stdout. Runs with cwd = plugins/web.
_SAMPLER = r"""
import { readFileSync, writeFileSync } from 'node:fs';
import { readAnchoredGlb } from './src/anchor.js';
import { readAnchorAnimation } from './src/animation.js';

const [path, timesJson, outPath] = process.argv.slice(1);
const bytes = readFileSync(path);
const prims = readAnchoredGlb(bytes, { name: path }).anchored;
const found = prims.map((p) => readAnchorAnimation(bytes, p, { name: path }));
const k = found.findIndex((a) => a !== null);
if (k < 0) throw new Error(`${path}: no animated anchor mesh`);
const anim = found[k];
const times = JSON.parse(timesJson);
const V = anim.vertexCount;
const out = new Float32Array(3 * V * (1 + times.flat().length));
anim.rest(out.subarray(0, 3 * V));
let at = 3 * V;
times.forEach((list, a) => {
    for (const t of list) {
        anim.sample(a, t, out.subarray(at, at + 3 * V));
        at += 3 * V;
    }
});
writeFileSync(outPath, out);
const summary = {
    primitive: k, vertexCount: V, skinned: anim.skinned, morphed: anim.morphed,
    animations: anim.animations,
    stored: Array.from(prims[k].anchorMesh.vertices),
};
process.stdout.write(JSON.stringify(summary));
"""


def _times(duration: float) -> list[float]:
    """Before the start, the start, inside, the end and beyond it (clamped)."""
    return [-0.25, 0.0, 0.37 * duration, 0.5 * duration, 0.81 * duration, duration,
            duration + 0.5]


def _compare(path, expected_animations: int, *, rest_is_stored: bool = True
             ) -> dict[str, float]:
    """Max |JS − reference| / height of the rest pose and of every animation of ``path``.
    ``rest_is_stored``: the skeleton at its node values is the bind pose, so the rest pose is
    the stored POSITION too."""
    require_web_tools()
    rest = gv.read(path).anchored[0].anchoring.mesh.vertices.astype(np.float64)
    height = float(np.ptp(rest[:, 1]))
    assert height > 0
    reference = open_gltf_source(path, 0)
    reference.match(rest)
    names = reference.animation.animation_names
    assert len(names) == expected_animations
    times = []
    for a in range(len(names)):
        times.append(_times(open_gltf_source(path, a).duration()))

    out = path.parent / f"{path.stem}_js.f32"
    proc = run_node(["--input-type=module", "-e", _SAMPLER, path, json.dumps(times), out],
                    timeout=120)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert summary["primitive"] == 0
    V = summary["vertexCount"]
    assert V == len(rest)
    assert [a["name"] for a in summary["animations"]] == names
    js = np.fromfile(out, dtype="<f4").astype(np.float64).reshape(-1, V, 3)
    assert len(js) == 1 + sum(len(t) for t in times)

    errors = {}
    # the plugin reads the anchor mesh the package reads
    np.testing.assert_array_equal(np.asarray(summary["stored"]).reshape(-1, 3),
                                  rest.astype(np.float32))
    errors["rest"] = float(np.abs(js[0] - reference.rest_pose()).max()) / height
    if rest_is_stored:
        errors["rest vs POSITION"] = float(np.abs(js[0] - rest).max()) / height
    at = 1
    for a, name in enumerate(names):
        source = open_gltf_source(path, a)
        source.match(rest)
        assert summary["animations"][a]["duration"] == pytest.approx(source.duration(),
                                                                     rel=1e-12)
        worst, motion = 0.0, 0.0
        for t in times[a]:
            expected = source.at(float(t))
            worst = max(worst, float(np.abs(js[at] - expected).max()))
            motion = max(motion, float(np.abs(expected - rest).max()))
            at += 1
        errors[name] = worst / height
        # the animation moves the mesh, so agreement is not agreement on the rest pose
        assert motion > 0.01 * height, (name, motion)
    bad = {k: v for k, v in errors.items() if not v <= TOLERANCE}
    assert not bad, (bad, errors)
    return errors


def _splat(mesh: TriangleMesh, n: int, seed: int, tmp_path, name: str):
    cloud = surface_splats(mesh, n, seed, offset=0.0)
    path = tmp_path / f"{name}_splats.glb"
    gv.write(SplatAsset([SplatPrimitive(cloud, None, name)]), path)
    return path


def test_skinned_tube(tmp_path):
    """A three-joint chain that moves, twists, bends and scales (gsverse_format.conformance)."""
    glb, rest, faces, _ = skinned_tube()
    src = tmp_path / "tube_mesh.glb"
    src.write_bytes(glb)
    splats = _splat(TriangleMesh(rest.astype(np.float64), faces), 300, 5, tmp_path, "tube")
    out = tmp_path / "tube.glb"
    gv.convert(splats, out, mesh=str(src))
    errors = _compare(out, 1)
    print("tube", errors)


def test_skinned_and_morphed(tmp_path):
    """Two joints and a morph target animated together (the writer's own rig)."""
    from validation_assets import rigged_asset

    out = tmp_path / "rigged.glb"
    gv.write(rigged_asset(), out)
    errors = _compare(out, 1)
    print("rigged", errors)


def test_fox(shared_data, tmp_path):
    """Khronos Fox: 1,728 vertices, 24 joints, Survey, Walk and Run."""
    fox = shared_data / "meshes" / "Fox.glb"
    splats = _splat(read_mesh(fox), 400, 3, tmp_path, "fox")
    out = tmp_path / "fox.glb"
    gv.convert(splats, out, mesh=str(fox))
    errors = _compare(out, 3)
    print("fox", errors)


def test_simple_skin(shared_data, tmp_path):
    """Khronos SimpleSkin: the mesh node parents the skeleton. Its inverse bind matrices hold
    a translation of −0.5 along X that its skeleton's node values do not, so its skinned rest
    pose is its POSITION moved by −0.5 along X (in any glTF viewer): the rest pose is compared
    with the reference's only."""
    src = shared_data / "meshes" / "SimpleSkin.gltf"
    splats = _splat(read_mesh(src), 200, 4, tmp_path, "simple")
    out = tmp_path / "simple.glb"
    gv.convert(splats, out, mesh=str(src))
    errors = _compare(out, 1, rest_is_stored=False)
    print("simple skin", errors)


def test_unnormalized_weights_are_normalized(tmp_path):
    """WEIGHTS_0 that another tool left unnormalized (sums of 1.76, a vertex all zero): the
    plugin uses them as the reference does (spec *Skin weights*: divided by their sum; all
    zero, weight 1 on the first influence), not as they are."""
    from validation_assets import _rigged

    d = _rigged()
    w = d.values(d.anchor_prim()["attributes"]["WEIGHTS_0"])
    w[::2] *= 1.76
    w[1] = 0.0
    out = d.write(tmp_path, "unnormalized.glb")
    errors = _compare(out, 1)
    print("unnormalized", errors)
