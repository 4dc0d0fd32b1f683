"""Running an implementation over the suite and writing its dumps, as an engine harness does.

A harness, for every case of the suite: loads ``asset.glb`` with the plugin's importer (or
writes ``refused`` when the importer rejects it), dumps the imported rest pose, applies every
pose in ``poses/`` to the anchor mesh and dumps the remapped means and covariances, then dumps
the opacity and SH the splats carry after the last pose. ``spec/conformance.md`` gives the
layout; :func:`run_plugin` is the same loop in Python for implementations callable from here.
The poses of a rig case are the deformed vertices p′ brought into splat-local space by M⁻¹, or
the asset's animation sampled by the implementation (:func:`pose_vertices`).

An implementation is an object with the methods of :class:`Plugin`. Three are provided:

* :class:`ReferencePlugin` — the library as a plugin: :func:`gsverse_format.io.gltf.read_gltf`
  and the float64 reference :func:`gsverse_format.remapping.reference.remap`;
* :class:`FastPlugin` — the same importer and the compiled float32 path
  (:class:`gsverse_format.remapping.fast.FastRemapper`);
* :class:`RawReferencePlugin` — the importer of :mod:`.minimal_reader` (no glTF library) with
  a replaceable dequantization step, and the reference remap.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Callable, Protocol

import numpy as np

from ..errors import FormatError
from ..io.gltf import read_gltf
from ..model import Anchoring, GamesAnchors, LocalAnchors, TriangleMesh
from ..remapping import reference
from .glb import unpack_glb
from .minimal_reader import Raw, Refused, dequantize, derive_local, face_index, read_anchored_glb
from .rig_poses import sample_rig, splat_local

__all__ = ["Plugin", "Refused", "run_plugin", "write_array", "ReferencePlugin", "FastPlugin",
           "RawReferencePlugin", "cov6", "suite_cases", "read_asset", "pose_vertices",
           "RIG_FAULTS"]

_COV6 = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
_KHR = "KHR_gaussian_splatting"
_ANCHOR = "GSVERSE_gaussian_splatting_mesh_anchor"


def cov6(cov: np.ndarray) -> np.ndarray:
    """(N, 3, 3) → (N, 6) unique entries xx, xy, xz, yy, yz, zz."""
    return np.stack([cov[:, r, s] for r, s in _COV6], axis=-1)


class Plugin(Protocol):
    """What :func:`run_plugin` needs from an implementation.

    ``rest`` and ``apply_pose`` return a dict with ``means`` and either ``cov`` (N, 6) or
    ``rotation`` (N, 4, xyzw) and ``scale`` (N, 3); ``rest`` and ``splat_data`` also return
    ``opacity`` (N,) and ``sh`` (N, K, 3). float32 arrays are dumped as ``.f32``, others as
    ``.f64``. An optional ``rig_pose(folder, manifest, p)`` poses a rig case itself (sampled,
    or M⁻¹ of its own); without it :func:`pose_vertices` does M⁻¹ in float64.
    """

    def load(self, asset_path: str) -> None: ...          # raises Refused
    def rest(self) -> dict[str, np.ndarray]: ...
    def apply_pose(self, vertices: np.ndarray) -> dict[str, np.ndarray]: ...
    def splat_data(self) -> dict[str, np.ndarray]: ...


def write_array(stem: Path, array: np.ndarray) -> None:
    """Write ``array`` raw little-endian to ``stem`` + ``.f32`` (float32) or ``.f64``."""
    a = np.asarray(array)
    if a.dtype == np.float32:
        data, ext = np.ascontiguousarray(a, dtype="<f4"), ".f32"
    else:
        data, ext = np.ascontiguousarray(a, dtype="<f8"), ".f64"
    Path(str(stem) + ext).write_bytes(data.tobytes())


def _dump(folder: Path, prefix: str, values: dict[str, np.ndarray]) -> None:
    for key, array in values.items():
        write_array(folder / f"{prefix}.{key}", array)


def suite_cases(suite_dir: str | os.PathLike) -> list[tuple[Path, dict]]:
    """(case folder, manifest) for every case of a suite, in suite order."""
    root = Path(suite_dir)
    index = json.loads((root / "suite.json").read_text(encoding="utf-8"))
    out = []
    for entry in index["cases"]:
        folder = root / entry["path"]
        out.append((folder, json.loads((folder / "case.json").read_text(encoding="utf-8"))))
    return out


def run_plugin(suite_dir: str | os.PathLike, results_dir: str | os.PathLike,
               factory: Callable[[], Plugin], *, info: dict | None = None,
               only: Callable[[dict], bool] | None = None) -> None:
    """Run a fresh ``factory()`` plugin over every case and write its dumps.

    ``info`` is written to ``RESULTS/harness.json``; ``only`` selects cases by manifest.
    """
    results = Path(results_dir)
    results.mkdir(parents=True, exist_ok=True)
    if info is not None:
        (results / "harness.json").write_text(json.dumps(info, indent=1), encoding="utf-8")
    for folder, manifest in suite_cases(suite_dir):
        if only is not None and not only(manifest):
            continue
        out = results / manifest["id"]
        out.mkdir(parents=True, exist_ok=True)
        plugin = factory()
        try:
            plugin.load(str(folder / manifest["files"]["asset"]))
        except Refused as err:
            (out / "refused").write_text(str(err) + "\n", encoding="utf-8")
            continue
        try:
            _dump(out, "rest", plugin.rest())
            for p in range(len(manifest.get("poses", []))):
                _dump(out, f"pose_{p:03d}", plugin.apply_pose(pose_vertices(plugin, folder,
                                                                            manifest, p)))
            _dump(out, "posed", plugin.splat_data())
        except Exception as err:  # the implementation failed on this case: record, go on
            (out / "error").write_text(f"{type(err).__name__}: {err}\n", encoding="utf-8")


def pose_vertices(plugin: object, folder: Path, manifest: dict, p: int) -> np.ndarray:
    """The anchor vertices of pose ``p`` in the splat primitive's local space: the pose file
    of a remap case; for a rig case (spec/conformance.md §Rig cases) the plugin's own
    ``rig_pose(folder, manifest, p)`` when it has one, else the deformed file p′ brought into
    splat-local space by M⁻¹ in float64 (:func:`.rig_poses.splat_local`)."""
    files = manifest.get("files", {})
    if manifest.get("kind") != "rig":
        return np.fromfile(folder / files["poses"][p], dtype="<f4").reshape(-1, 3)
    own = getattr(plugin, "rig_pose", None)
    if own is not None:
        return own(folder, manifest, p)
    deformed = np.fromfile(folder / files["deformed"][p], dtype="<f4").reshape(-1, 3)
    return splat_local(deformed, manifest["rig"])


# --------------------------------------------------------------------------- library plugins

_CACHE: dict[str, object] = {}


def read_asset(path: str):
    """:func:`~gsverse_format.io.gltf.read_gltf` with a per-process cache keyed by the file's
    content (the suite is read by several implementations in one process)."""
    with open(path, "rb") as handle:
        key = hashlib.sha256(handle.read()).hexdigest()
    if key not in _CACHE:
        try:
            _CACHE[key] = read_gltf(path)
        except FormatError as err:
            _CACHE[key] = err
        if len(_CACHE) > 512:
            _CACHE.pop(next(iter(_CACHE)))
    value = _CACHE[key]
    if isinstance(value, FormatError):
        raise value
    return value


def _require_finite(prim) -> None:
    """Refuse non-finite anchor data or rest pose (invalid glTF; the remap would have no finite
    output), a zero localRotation and a negative localScale (spec v1.1 refusals)."""
    anchors = prim.anchoring.anchors
    arrays = [prim.anchoring.mesh.vertices, anchors.barycentrics]
    if isinstance(anchors, LocalAnchors):
        arrays += [anchors.normal_offset, anchors.local_rotation, anchors.local_scale]
    else:
        arrays += [anchors.rho]
    if not all(np.all(np.isfinite(a)) for a in arrays):
        raise Refused("non-finite anchor data (NaN or infinity)")
    splats = prim.splats
    if not all(np.all(np.isfinite(a)) for a in (splats.means, splats.rotations, splats.scales)):
        raise Refused("non-finite rest pose (POSITION, ROTATION or SCALE holds NaN or infinity)")
    if isinstance(anchors, LocalAnchors):
        zero = np.flatnonzero(~np.any(anchors.local_rotation != 0, axis=1))
        if zero.size:
            raise Refused(f"localRotation of splat {int(zero[0])} has length zero")
        negative = np.flatnonzero(np.any(anchors.local_scale < 0, axis=1))
        if negative.size:
            raise Refused(f"localScale of splat {int(negative[0])} is negative")


def _require_document_rules(asset_path: str) -> None:
    """Refuse what the JSON document alone shows (spec v1.1): an anchored splat primitive
    whose mode is not POINTS, and an anchor mesh instantiated by more than one node."""
    try:
        doc, _ = unpack_glb(Path(asset_path).read_bytes())
    except (OSError, ValueError):
        return   # the importer reports unreadable containers
    meshes: list = doc["meshes"] if isinstance(doc.get("meshes"), list) else []
    nodes: list = doc["nodes"] if isinstance(doc.get("nodes"), list) else []
    for m, mesh in enumerate(meshes):
        for p, prim in enumerate(mesh.get("primitives", []) if isinstance(mesh, dict) else []):
            khr = (prim.get("extensions") or {}).get(_KHR) if isinstance(prim, dict) else None
            ext = (khr.get("extensions") or {}).get(_ANCHOR) if isinstance(khr, dict) else None
            if ext is None:
                continue
            if prim.get("mode", 4) != 0:
                raise Refused(f"the anchored splat primitive meshes[{m}].primitives[{p}] has "
                              f"mode {prim.get('mode', 4)!r}, not POINTS (0)")
            anchor_mesh = ext.get("mesh") if isinstance(ext, dict) else None
            users = [n for n, node in enumerate(nodes)
                     if isinstance(node, dict) and node.get("mesh") == anchor_mesh]
            if anchor_mesh is not None and len(users) > 1:
                raise Refused(f"the anchor mesh {anchor_mesh} is instantiated by {len(users)} "
                              f"nodes ({', '.join(map(str, users))}); at most one is allowed")


#: Deliberately broken rig steps (:class:`ReferencePlugin` ``fault``): remap p′ without M⁻¹,
#: skin with the weights as stored (no normalization).
RIG_FAULTS = ("skip-inverse-node", "raw-weights")


class ReferencePlugin:
    """The library as a plugin: ``read_gltf`` and the float64 reference remap.

    ``form="cov"`` dumps covariances, ``"rotscale"`` the reference's rotation/scale pairs.
    Rig cases: ``rig="files"`` reads the deformed vertices p′ and does M⁻¹ in float64,
    ``"sample"`` samples the asset's animation with :mod:`gsverse_format.poses.gltf_animation`
    at the pose's time (spec steps 1–3). ``fault`` (one of :data:`RIG_FAULTS`) breaks a rig
    step on purpose; ``raw-weights`` needs ``rig="sample"``.
    """

    name = "gsverse_format.remapping.reference (numpy, float64)"

    def __init__(self, form: str = "cov", *, rig: str = "files", fault: str | None = None) -> None:
        if rig not in ("files", "sample") or fault not in (None,) + RIG_FAULTS:
            raise ValueError(f"rig {rig!r} / fault {fault!r}")
        if fault == "raw-weights" and rig != "sample":
            raise ValueError("the raw-weights fault samples the animation: use rig='sample'")
        self.form = form
        self.rig_source = rig
        self.fault = fault

    def rig_pose(self, folder: Path, manifest: dict, p: int) -> np.ndarray:
        """Pose ``p`` of a rig case in splat-local space (see the class docstring)."""
        skip = self.fault == "skip-inverse-node"
        if self.rig_source == "sample":
            glb = (folder / manifest["files"]["asset"]).read_bytes()
            raw = (lambda w: np.asarray(w, np.float64)) if self.fault == "raw-weights" else None
            return sample_rig(glb, [manifest["poses"][p]["source"]], weights=raw,
                              inverse=not skip)[0][1]
        deformed = np.fromfile(folder / manifest["files"]["deformed"][p], "<f4").reshape(-1, 3)
        return deformed.astype(np.float64) if skip else splat_local(deformed, manifest["rig"])

    def load(self, asset_path: str) -> None:
        try:
            asset = read_asset(asset_path)
        except FormatError as err:
            raise Refused(str(err)) from None
        _require_document_rules(asset_path)
        anchored = asset.anchored
        if len(anchored) != 1:
            raise Refused(f"expected one anchored splat primitive, found {len(anchored)}")
        self.prim = anchored[0]
        anchors = self.prim.anchoring.anchors
        _require_finite(self.prim)
        self.rest_data = (reference.prepare_rest(self.prim.anchoring.mesh.triangles())
                          if isinstance(anchors, LocalAnchors) else None)

    def rest(self) -> dict[str, np.ndarray]:
        c = self.prim.splats
        return {"means": c.means, "rotation": c.rotations, "scale": c.scales,
                "opacity": c.opacities, "sh": c.sh}

    def apply_pose(self, vertices: np.ndarray) -> dict[str, np.ndarray]:
        r = reference.remap(self.prim.anchoring, vertices, rest=self.rest_data)
        if self.form == "rotscale":
            return {"means": r.means, "rotation": r.rotations, "scale": r.scales}
        return {"means": r.means, "cov": cov6(r.covariances)}

    def splat_data(self) -> dict[str, np.ndarray]:
        return {"opacity": self.prim.splats.opacities, "sh": self.prim.splats.sh}


class FastPlugin(ReferencePlugin):
    """``read_gltf`` and the compiled float32 remap
    (:class:`~gsverse_format.remapping.fast.FastRemapper`)."""

    name = "gsverse_format.remapping.fast (float32)"

    def __init__(self, backend: str = "numba", rotations: bool = False, *, rig: str = "files",
                 fault: str | None = None) -> None:
        super().__init__(rig=rig, fault=fault)
        self.backend = backend
        self.rotations = rotations

    def load(self, asset_path: str) -> None:
        from ..remapping.fast import FastRemapper

        super().load(asset_path)
        self.remapper = FastRemapper(self.prim.anchoring, backend=self.backend,
                                     rotations=self.rotations)

    def apply_pose(self, vertices: np.ndarray) -> dict[str, np.ndarray]:
        out = self.remapper.remap(np.ascontiguousarray(vertices, dtype=np.float32)).copy()
        if out.rotations is not None and out.scales is not None:
            return {"means": out.means, "rotation": out.rotations, "scale": out.scales}
        return {"means": out.means, "cov": out.cov6}


class RawReferencePlugin:
    """:mod:`.minimal_reader` as importer, ``dequantize_fn`` for the anchors, reference remap.

    ``renormalize`` rescales every quaternion (float and integer-quantized) to unit length,
    as the spec requires (turn it off to see what happens when an importer forgets).
    """

    name = "minimal_reader + gsverse_format.remapping.reference"

    def __init__(self, dequantize_fn: Callable[[Raw], np.ndarray] = dequantize,
                 renormalize: bool = True) -> None:
        self.deq = dequantize_fn
        self.renormalize = renormalize

    def _quat(self, raw: Raw) -> np.ndarray:
        q = self.deq(raw)
        if self.renormalize:
            q = q / np.linalg.norm(q, axis=1, keepdims=True)
        return q

    def load(self, asset_path: str) -> None:
        a = read_anchored_glb(asset_path)
        self.raw = a
        mesh = TriangleMesh(a.anchor_vertices, a.anchor_faces)
        face = face_index(a)
        anchors: GamesAnchors | LocalAnchors
        if a.derived:                 # version 1.2: derived from the rest pose
            d = derive_local(a)
            anchors = LocalAnchors(face, d["barycentrics"], d["normalOffset"],
                                   d["localRotation"], d["localScale"],
                                   "rigid" if a.deformation == "rigid" else "affine")
        elif a.profile == "games":
            bary = self.deq(a.anchors["barycentrics"])
            anchors = GamesAnchors(face, bary, self.deq(a.anchors["rho"])[:, 0])
        else:
            bary = self.deq(a.anchors["barycentrics"])
            anchors = LocalAnchors(face, bary, self.deq(a.anchors["normalOffset"])[:, 0],
                                   self._quat(a.anchors["localRotation"]),
                                   self.deq(a.anchors["localScale"]),
                                   "rigid" if a.deformation == "rigid" else "affine")
        self.anchoring = Anchoring(mesh, anchors)
        self.rest_data = reference.prepare_rest(mesh.triangles()) if a.profile == "local" else None

    def rest(self) -> dict[str, np.ndarray]:
        a = self.raw
        return {"means": dequantize(a.positions), "rotation": self._quat(a.rotations),
                "scale": dequantize(a.scales), "opacity": dequantize(a.opacities)[:, 0],
                "sh": np.stack([dequantize(s) for s in a.sh], axis=1)}

    def apply_pose(self, vertices: np.ndarray) -> dict[str, np.ndarray]:
        r = reference.remap(self.anchoring, vertices, rest=self.rest_data)
        return {"means": r.means, "cov": cov6(r.covariances)}

    def splat_data(self) -> dict[str, np.ndarray]:
        rest = self.rest()
        return {"opacity": rest["opacity"], "sh": rest["sh"]}
