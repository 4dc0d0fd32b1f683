"""Checks of an animated anchor mesh (spec/README.md §Animated anchor meshes): the skin of the
node that instantiates the anchor mesh, its ``JOINTS_0``/``WEIGHTS_0``, morph targets, and the
animation channels that drive them. Reported by :class:`~gsverse_format.codes.Code`; the
drawn-or-hidden question is :mod:`.anchor`'s ``ANCHOR_MESH_INSTANTIATED``."""
from __future__ import annotations

from typing import Any

import numpy as np

from gsverse_format.codes import Code
from gsverse_format.rig import WEIGHT_SUM_TOLERANCE
from gsverse_format.rig_checks import (is_index, joints_out_of_range, key_times_problem,
                                       non_finite_problem, sampler_count_problem,
                                       weights_count_problem)

from .container import Context

__all__ = ["check_rig", "WEIGHT_SUM_TOLERANCE"]


def check_rig(ctx: Context, m: int, p: int, node_i: int, vertex_count: int) -> None:
    """Check the rig of anchor primitive ``p`` of mesh ``m`` instantiated by node ``node_i``
    (``vertex_count`` vertices)."""
    pointer = f"/meshes/{m}/primitives/{p}"
    mesh = ctx.array("meshes")[m]
    prim = mesh["primitives"][p]
    node = ctx.array("nodes")[node_i]
    nodes = ctx.array("nodes")
    targets = prim.get("targets") or []
    for k, target in enumerate(targets if isinstance(targets, list) else []):
        ref = target.get("POSITION") if isinstance(target, dict) else None
        lay = ctx.accessor(ref, f"{pointer}/targets/{k}/POSITION") if ref is not None else None
        if lay is not None and lay.count != vertex_count:
            ctx.issues.add(Code.ANCHOR_MORPH_TARGETS_INVALID, f"morph target {k} has "
                           f"{lay.count} POSITION deltas but the anchor mesh has {vertex_count} "
                           f"vertices", pointer=f"{pointer}/targets/{k}/POSITION")
        elif lay is not None:
            deltas = ctx.floats(lay, f"morph target {k} POSITION")
            problem = None if deltas is None else non_finite_problem(deltas, "deltas")
            if problem:
                ctx.issues.add(Code.NON_FINITE_VALUE, f"the POSITION deltas of "
                               f"morph target {k} {problem}",
                               pointer=f"{pointer}/targets/{k}/POSITION")
    for where, owner in ((f"/nodes/{node_i}/weights", node), (f"/meshes/{m}/weights", mesh)):
        problem = None if "weights" not in owner else weights_count_problem(
            owner["weights"], len(targets) if isinstance(targets, list) else 0)
        if problem:
            ctx.issues.add(Code.ANCHOR_MORPH_TARGETS_INVALID, f"the default morph weights "
                           f"{problem}", pointer=where)
    _check_animations(ctx, node_i, len(targets) if isinstance(targets, list) else 0)
    if node.get("skin") is None:
        return
    skins = ctx.array("skins")
    s = node["skin"]
    if not is_index(s, len(skins)) or not isinstance(skins[s], dict):
        ctx.issues.add(Code.ANCHOR_SKIN_INVALID, f"the anchor node's skin {s!r} does not "
                       f"exist (there are {len(skins)} skins)", pointer=f"/nodes/{node_i}/skin")
        return
    skin = skins[s]
    joints = skin.get("joints")
    if not isinstance(joints, list) or not joints or not all(
            is_index(j, len(nodes)) for j in joints):
        ctx.issues.add(Code.ANCHOR_SKIN_INVALID, "the skin's joints must be a non-empty list "
                       "of existing nodes", pointer=f"/skins/{s}/joints")
        return
    ibm = skin.get("inverseBindMatrices")
    if ibm is not None:
        lay = ctx.accessor(ibm, f"/skins/{s}/inverseBindMatrices")
        if lay is not None and lay.count != len(joints):
            ctx.issues.add(Code.ANCHOR_SKIN_INVALID, f"{lay.count} inverse bind matrices for "
                           f"{len(joints)} joints", pointer=f"/skins/{s}/inverseBindMatrices")
        elif lay is not None:
            mats = ctx.floats(lay, "inverseBindMatrices")
            problem = None if mats is None else non_finite_problem(mats, "matrices")
            if problem:
                ctx.issues.add(Code.NON_FINITE_VALUE, f"the inverse bind matrices "
                               f"{problem}", pointer=f"/skins/{s}/inverseBindMatrices")
    attrs = prim.get("attributes", {})
    arrays = {}
    for name in ("JOINTS_0", "WEIGHTS_0"):
        where = f"{pointer}/attributes/{name}"
        if name not in attrs:
            ctx.issues.add(Code.ANCHOR_SKIN_ATTRIBUTES_INVALID, f"the skinned anchor primitive "
                           f"has no {name}", pointer=f"{pointer}/attributes")
            continue
        lay = ctx.accessor(attrs[name], where)
        if lay is None:
            continue
        if lay.count != vertex_count:
            ctx.issues.add(Code.ANCHOR_SKIN_ATTRIBUTES_INVALID, f"{name} has {lay.count} "
                           f"elements but POSITION has {vertex_count}", pointer=where)
            continue
        values = ctx.read(lay, name) if name == "JOINTS_0" else ctx.floats(lay, name)
        if values is not None:
            arrays[name] = np.asarray(values, dtype=np.float64)
    if "JOINTS_0" in arrays:
        jn = arrays["JOINTS_0"]
        bad = joints_out_of_range(jn, len(joints))
        if bad.size:
            ctx.issues.add(Code.ANCHOR_SKIN_ATTRIBUTES_INVALID, f"{bad.size} vertices have a "
                           f"JOINTS_0 index not below the skin's {len(joints)} joints",
                           pointer=f"{pointer}/attributes/JOINTS_0", count=int(bad.size))
    if "WEIGHTS_0" in arrays:   # a warning: readers normalize them (spec, as three.js)
        total = arrays["WEIGHTS_0"].sum(axis=1)
        error = np.abs(total - 1.0)
        bad = np.flatnonzero(~(error <= WEIGHT_SUM_TOLERANCE))
        zero = int(np.count_nonzero(total == 0.0))
        if bad.size:
            ctx.issues.add(Code.ANCHOR_SKIN_WEIGHTS_NOT_NORMALIZED, f"{bad.size} vertices have "
                           f"WEIGHTS_0 summing to 1 ± {float(error[bad].max()):.3g}"
                           + (f" ({zero} all zero)" if zero else "") + "; readers normalize "
                           "them, engines that do not pose those vertices elsewhere",
                           pointer=f"{pointer}/attributes/WEIGHTS_0", count=int(bad.size))


_WIDTH = {"translation": 3, "rotation": 4, "scale": 3}


def _check_animations(ctx: Context, node_i: int, target_count: int) -> None:
    nodes = ctx.array("nodes")
    for a, anim in enumerate(ctx.array("animations")):
        channels = anim.get("channels") if isinstance(anim, dict) else None
        for c, ch in enumerate(channels if isinstance(channels, list) else []):
            target = ch.get("target") if isinstance(ch, dict) else None
            if not isinstance(target, dict) or "node" not in target:
                continue   # a target without a node is left to extensions
            where = f"/animations/{a}/channels/{c}/target"
            if not is_index(target["node"], len(nodes)):
                ctx.issues.add(Code.ANCHOR_ANIMATION_TARGET_INVALID, f"the channel targets node "
                               f"{target['node']!r}, which does not exist", pointer=where)
            elif target["node"] == node_i and target.get("path") == "weights" \
                    and not target_count:
                ctx.issues.add(Code.ANCHOR_ANIMATION_TARGET_INVALID, "the channel animates the "
                               "morph weights of the anchor node, whose mesh has no morph "
                               "targets", pointer=where)
            elif target["node"] == node_i and target.get("path") == "weights" \
                    or target.get("path") in _WIDTH:
                width = _WIDTH.get(str(target.get("path")), target_count)
                _check_sampler(ctx, anim, ch.get("sampler"), width, f"/animations/{a}")


def _check_sampler(ctx: Context, anim: dict, s: Any, width: int, pointer: str) -> None:
    """The key times and values of a sampler that moves a node or the anchor node's morph
    weights: NON_FINITE_VALUE for NaN or infinity, ANCHOR_ANIMATION_SAMPLER_INVALID for the
    other rules of :mod:`gsverse_format.rig_checks` (the web reader's codes for the same)."""
    samplers = anim.get("samplers")
    if not isinstance(samplers, list) or not is_index(s, len(samplers)) \
            or not isinstance(samplers[s], dict):
        return   # an unresolved sampler is the glTF schema's finding
    sampler = samplers[s]
    where = f"{pointer}/samplers/{s}"
    layouts = {key: ctx.accessor(sampler.get(key), f"{where}/{key}")
               for key in ("input", "output")}
    if layouts["input"] is None or layouts["output"] is None:
        return
    times = ctx.floats(layouts["input"], "key times")
    values = ctx.floats(layouts["output"], "key values")
    if times is None or values is None:
        return
    for what, key, data in (("key times", "input", times), ("values", "output", values)):
        problem = non_finite_problem(data.reshape(-1, 1), what)
        if problem:
            ctx.issues.add(Code.NON_FINITE_VALUE, f"the sampler's {what} {problem}",
                           pointer=f"{where}/{key}")
            return
    for what, key, problem in (
            ("key times", "input", key_times_problem(times)),
            ("values", "output", sampler_count_problem(
                len(times.reshape(-1)), values.size, width, sampler.get("interpolation",
                                                                        "LINEAR")))):
        if problem:
            ctx.issues.add(Code.ANCHOR_ANIMATION_SAMPLER_INVALID, f"the sampler's {what} "
                           f"{problem}", pointer=f"{where}/{key}")
