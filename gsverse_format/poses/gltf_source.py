"""glTF animations as a deformation source for an anchor mesh.

:func:`open_gltf_source` opens a skinned and/or morphed glTF file with the package's hardened
glTF reader (bounds-checked accessors, no URI outside the file's folder) and returns a
:class:`GltfSource` posing the file's triangle primitives (:mod:`.gltf_animation`).

Which vertices: when the file is an anchored asset whose anchor mesh carries a skin or morph
targets, the anchor primitive(s) of its anchor extension; otherwise every TRIANGLES primitive
of the default scene concatenated in the order in which ``gsverse-convert --mesh FILE.glb``
reads them (:func:`gsverse_format.io.mesh.read_mesh`), so an asset converted with
``--mesh character.glb`` is posed by ``--source character.glb``.

An anchored asset's own anchor mesh is posed as spec/README.md §Animated anchor meshes says
(:meth:`GltfAnimation.anchor_pose`): morphed and skinned, the anchor node's transform ignored,
skinned vertices brought into the splat primitive's local space by M⁻¹ (M the global matrix of
the node that instantiates the splat mesh anchored to it).

Matching (:meth:`GltfSource.match`): the anchor mesh must have as many vertices, and its rest
positions must be the source's rest positions (what glTF draws with the nodes' own values and
the default morph weights: a skinned primitive skinned, not placed by its node's transform;
what ``gsverse-convert --mesh`` stores as the anchor mesh), up to one of the frame rotations the converter applies (glTF, 3DGS, Z-up), within
10⁻⁴ of the mesh's bounding-box diagonal. The posed vertices get the same rotation.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from ..errors import FormatError, GsverseError
from .gltf_animation import GltfAnimation, Instance

__all__ = ["GltfSource", "open_gltf_source", "anchor_instances", "anchor_primitives",
           "splat_nodes", "MATCH_TOLERANCE"]

#: Rest positions match when no vertex differs by more than this × the bounding-box diagonal.
MATCH_TOLERANCE = 1e-4

_KHR = "KHR_gaussian_splatting"
_ANCHOR = "GSVERSE_gaussian_splatting_mesh_anchor"
_GTYPES = ("SCALAR", "VEC2", "VEC3", "VEC4", "MAT4")


def anchor_primitives(doc: dict) -> list[tuple[int, int]]:
    """(mesh, primitive) of every anchor primitive the anchor extensions of ``doc`` name."""
    wanted: list[tuple[int, int]] = []
    for mesh in doc.get("meshes") or []:
        for prim in mesh.get("primitives", []):
            ext = (prim.get("extensions") or {}).get(_KHR, {}).get("extensions", {}).get(_ANCHOR)
            if isinstance(ext, dict) and isinstance(ext.get("mesh"), int):
                key = (ext["mesh"], int(ext.get("primitive", 0)))
                if key not in wanted:
                    wanted.append(key)
    return wanted


def anchor_instances(anim: GltfAnimation) -> list[Instance]:
    """The instances of the anchor primitives an anchored asset's extension points at (the
    node with a skin drawing them, else the first node drawing them), in file order; [] for
    none."""
    wanted = anchor_primitives(anim.doc)
    out = []
    nodes = anim.nodes
    for m, p in wanted:
        users = [i for i, n in enumerate(nodes) if n.get("mesh") == m]
        skinned = [i for i in users if nodes[i].get("skin") is not None]
        chosen = skinned or users
        if chosen:
            out.append(Instance(chosen[0], m, p))
    return out


def splat_nodes(doc: dict, instances: list[Instance]) -> list[int | None]:
    """Per anchor instance, the node instantiating the first splat mesh anchored to its mesh
    (None when no node does: the splat-local space is then the scene's)."""
    out: list[int | None] = []
    nodes = doc.get("nodes") or []
    for inst in instances:
        found = None
        for m, mesh in enumerate(doc.get("meshes") or []):
            for prim in mesh.get("primitives", []):
                ext = (prim.get("extensions") or {}).get(_KHR, {}).get("extensions", {}).get(
                    _ANCHOR)
                if isinstance(ext, dict) and ext.get("mesh") == inst.mesh and found is None:
                    users = [i for i, n in enumerate(nodes) if n.get("mesh") == m]
                    found = users[0] if users else None
        out.append(found)
    return out


@dataclass
class GltfSource:
    """Poses of a glTF file's triangle primitives: ``at(t)`` (V, 3) in the file's space."""

    path: str
    animation: GltfAnimation
    instances: list[Instance]
    #: rotation into the anchor mesh's frame, set by :meth:`match`
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    #: an anchored asset's own anchor meshes: the splat node of each instance (spec steps
    #: 1–3, :meth:`GltfAnimation.anchor_pose`); None for a plain glTF file's meshes
    splat_nodes: list[int | None] | None = None

    def _vertices(self, t: float | None) -> np.ndarray:
        if self.splat_nodes is None:
            return self.animation.vertices(t, self.instances)
        return np.concatenate([self.animation.anchor_pose(t, inst, node)[1]
                               for inst, node in zip(self.instances, self.splat_nodes)])

    @property
    def vertex_count(self) -> int:
        return len(self.rest_pose())

    def duration(self) -> float:
        return self.animation.duration()

    def rest_pose(self) -> np.ndarray:
        return self._vertices(None)

    def match(self, rest: np.ndarray, label: str = "the anchor mesh") -> None:
        """Check that ``rest`` (V, 3) is this source's rest pose (see the module docstring)
        and remember the frame rotation; :class:`FormatError` naming the source otherwise."""
        from ..io.registry import FRAMES

        rest = np.asarray(rest, dtype=np.float64)
        mine = self.rest_pose()
        if len(mine) != len(rest):
            raise FormatError(f"its mesh has {len(mine)} vertices but {label} has {len(rest)}: "
                              f"not the mesh the asset is anchored to (or it was decimated "
                              f"with --faces)", self.path)
        diag = float(np.linalg.norm(np.ptp(rest, axis=0))) or 1.0
        best = np.inf
        for frame in FRAMES.values():
            r = np.asarray(frame.to_gltf, dtype=np.float64)
            err = float(np.abs(mine @ r.T - rest).max())
            best = min(best, err)
            if err <= MATCH_TOLERANCE * diag:
                self.rotation = r
                return
        raise FormatError(f"its mesh's rest positions differ from {label}'s by up to "
                          f"{best:.3g} ({best / diag:.2g} of the mesh's size; vertex order and "
                          f"positions must be the same)", self.path)

    def at(self, t: float) -> np.ndarray:
        """Posed vertices (V, 3) float64 at time ``t`` (s), in the anchor mesh's frame."""
        try:
            return self._vertices(t) @ self.rotation.T
        except GsverseError as err:
            raise FormatError(err.cause, self.path) from None
        except (KeyError, IndexError, TypeError, ValueError) as err:
            raise FormatError(f"malformed skin, morph target or animation data "
                              f"({type(err).__name__}: {' '.join(str(err).split())})",
                              self.path) from None


def open_gltf_source(path: str | os.PathLike, animation: int | str | None = 0, *,
                     prefer_anchor: bool = True) -> GltfSource:
    """Open ``path`` (``.glb``/``.gltf``) as a deformation source (see the module docstring).
    ``animation``: index or name (default the first). :class:`FormatError` naming the file
    when it cannot be read or holds neither a skin nor morph targets nor an animation."""
    from ..io.gltf import dequantize, open_document
    from ..io.gltf.scene import check_instancing

    spath = os.fspath(path)
    try:
        document = open_document(spath)
        check_instancing(document.doc)  # node cycles and instancing limits, before expanding
        reader = document.reader

        def accessor(i: int) -> np.ndarray:
            arr, ctype, normalized = reader.raw(i, f"accessor {i}", _GTYPES)
            return dequantize(arr, ctype, normalized)

        anim = GltfAnimation(document.doc, accessor, animation)
        anchored = bool(anchor_primitives(anim.doc)) and prefer_anchor
        instances = anchor_instances(anim) if anchored else anim.instances()
        if anchored and not (instances and anim.animates(instances)):
            raise FormatError("its anchor mesh has no skin and no morph targets (or no node "
                              "draws it)")
        if not instances:
            raise FormatError("the file has no triangle primitives in its scene")
        if not anim.animates(instances) and anim.animation is None:
            raise FormatError("its meshes have no skin, no morph targets and no animation")
        source = GltfSource(spath, anim, instances,
                            splat_nodes=splat_nodes(anim.doc, instances) if anchored else None)
        source.rest_pose()   # reads and checks every accessor now, not at the first pose
        anim.check_key_times()
        return source
    except GsverseError as err:
        raise FormatError(err.cause, spath) from None
    except (KeyError, IndexError, TypeError, ValueError) as err:
        raise FormatError(f"malformed skin, morph target or animation data "
                          f"({type(err).__name__}: {' '.join(str(err).split())})",
                          spath) from None
    except OSError as err:
        raise FormatError(f"cannot read: {err.strerror or err}", spath) from None
