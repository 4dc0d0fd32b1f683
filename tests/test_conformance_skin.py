"""The skinned test asset of the conformance suite and its linear-blend-skinning sampler."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from gsverse_format.conformance.glb import accessor_bytes, unpack_glb
from gsverse_format.conformance.skin import sample_skin, skinned_tube, tube


def test_tube_winds_outward():
    v, f = tube(4, 6, 0.5, 2.0)
    tri = v[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    radial = tri.mean(axis=1) * np.array([1, 0, 1])
    assert np.all(np.einsum("ij,ij->i", n, radial) > 0)


def test_bind_pose_is_the_rest_pose():
    glb, rest, faces, duration = skinned_tube()
    np.testing.assert_allclose(sample_skin(glb, 0.0), rest, atol=1e-6)
    doc, blob = unpack_glb(glb)
    w = accessor_bytes(doc, blob, doc["meshes"][0]["primitives"][0]["attributes"]["WEIGHTS_0"])
    np.testing.assert_allclose(w.astype(np.float64).sum(axis=1), 1.0, atol=1e-7)
    assert duration == 1.0 and len(faces) == 96


def _channel(doc, blob, node, path):
    anim = doc["animations"][0]
    ch = next(c for c in anim["channels"] if c["target"] == {"node": node, "path": path})
    s = anim["samplers"][ch["sampler"]]
    return (accessor_bytes(doc, blob, s["input"])[:, 0].astype(np.float64),
            accessor_bytes(doc, blob, s["output"]).astype(np.float64))


def test_sampler_matches_an_independent_evaluation():
    """Joint chain evaluated with scipy's Slerp and explicit matrices, skinned by hand."""
    glb, rest, _, _ = skinned_tube()
    doc, blob = unpack_glb(glb)
    t = 0.3
    times, trans = _channel(doc, blob, 1, "translation")
    root_t = np.array([np.interp(t, times, trans[:, k]) for k in range(3)])

    def rot(node):
        ts, q = _channel(doc, blob, node, "rotation")
        return Slerp(ts, Rotation.from_quat(q))([t]).as_matrix()[0]

    ts, sc = _channel(doc, blob, 3, "scale")
    tip_s = np.array([np.interp(t, ts, sc[:, k]) for k in range(3)])
    step = doc["nodes"][2]["translation"][1]

    def trs(tr, r, s=(1, 1, 1)):
        m = np.eye(4)
        m[:3, :3] = r * np.asarray(s)[None, :]
        m[:3, 3] = tr
        return m

    g0 = trs(root_t, rot(1))
    g1 = g0 @ trs([0, step, 0], rot(2))
    g2 = g1 @ trs([0, step, 0], rot(3), tip_s)
    joint = [g @ np.diag([1.0, 1.0, 1.0, 1.0]) for g in (g0, g1, g2)]
    for j, y in enumerate((0.0, step, 2 * step)):      # inverse bind matrices: translate by -y
        ibm = np.eye(4)
        ibm[1, 3] = -y
        joint[j] = joint[j] @ ibm
    prim = doc["meshes"][0]["primitives"][0]["attributes"]
    jn = accessor_bytes(doc, blob, prim["JOINTS_0"]).astype(int)
    wt = accessor_bytes(doc, blob, prim["WEIGHTS_0"]).astype(np.float64)
    homo = np.concatenate([rest.astype(np.float64), np.ones((len(rest), 1))], axis=1)
    want = np.zeros((len(rest), 4))
    for i in range(len(rest)):
        for k in range(4):
            want[i] += wt[i, k] * (joint[jn[i, k]] @ homo[i])
    np.testing.assert_allclose(sample_skin(glb, t), want[:, :3], atol=1e-7)
    # the animation really deforms the tube (not only moves it)
    posed = sample_skin(glb, 1.0)
    assert np.max(np.abs(posed - rest)) > 0.2
    edge = lambda v: np.linalg.norm(v[8] - v[0])  # noqa: E731  a vertical edge
    assert abs(edge(posed) - edge(rest)) > 1e-3 or abs(np.linalg.norm(posed[-1] - posed[-5])
                                                        - np.linalg.norm(rest[-1] - rest[-5])) > 1e-3


def test_times_outside_the_keys_clamp():
    glb, _, _, _ = skinned_tube()
    np.testing.assert_array_equal(sample_skin(glb, -1.0), sample_skin(glb, 0.0))
    np.testing.assert_array_equal(sample_skin(glb, 5.0), sample_skin(glb, 1.0))
