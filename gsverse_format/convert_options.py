"""What ``gsverse-convert`` is asked and what it reports, and the checks of the request.

:class:`ConvertOptions` (the command-line flags, one to one) and :class:`ConvertSummary` (what a
conversion did; the ``--json`` output) are the two ends of :func:`gsverse_format.pipeline.convert`;
:func:`check_options` refuses impossible requests (a ``UsageError`` naming the flag or file)
before any work, and :func:`source_options` says what the loaders get of them. The steps
themselves are in :mod:`gsverse_format.pipeline`, which re-exports both classes.
"""
from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any

from .atomic import check_target
from .edit import SplatEdit
from .errors import UsageError
from .io.registry import FORMATS, find_format, suffixes
from .model import DeformationLaw

if TYPE_CHECKING:
    from .converters.base import SourceOptions, TrellisFrame

__all__ = ["ConvertOptions", "ConvertSummary", "check_options", "check_encoding_options",
           "source_options", "object_name", "object_names", "physics_request"]


def object_name(path: str | os.PathLike[str]) -> str:
    """The name of the object a mesh file holds: its file stem."""
    return os.path.splitext(os.path.basename(os.fspath(path).rstrip(os.sep)))[0] or "object"


@dataclass
class ConvertOptions:
    """Options of :func:`gsverse_format.pipeline.convert` (the command-line flags map one to
    one).

    ``faces`` is the face count the anchor mesh is decimated to (the resolution the physics
    needs); ``reconstruct_faces`` the size of a mesh reconstructed from the splats when no
    ``mesh`` is given (default: ``faces``, else 20 000). ``frame_change`` rotates from the
    input's frame into glTF's (and from glTF's into a PLY output's). ``max_distance`` is
    relative to the anchor mesh's bounding-box diagonal unless ``absolute_distance``; ``None``
    anchors every splat. ``plain`` converts formats only (no anchoring is added or kept).
    ``bake_poses`` names a poses file (:func:`gsverse_format.io.usd.load_poses`) baked into
    USD time samples (USD output only). ``meshes``, two or more, makes a scene of several
    objects (:mod:`gsverse_format.scene`; ``max_distance`` is then relative to each object's
    mesh); ``watertight`` makes each anchor mesh a closed 2-manifold before binding;
    ``collider`` (``"hull"``) adds a collision mesh per anchor mesh. ``anchors`` is how glTF
    output stores the anchors (``"explicit"``, the version 1.1 layout, or ``"compact"``:
    ``faceCounts`` and derived ``local`` anchors, extension 1.2); ``None`` (default) is
    compact, or explicit where compact cannot be written (``keep_order``, splats bound to
    faces degenerate at rest), which a note says; ``quantize`` (16 or 8) stores
    what glTF output can quantize as normalized integers of that many bits
    (:data:`gsverse_format.io.gltf.writer.QUANTIZE_BITS`); ``compress`` ``"spz"`` stores the
    rest pose of glTF output as SPZ streams (``KHR_gaussian_splatting_compression_spz_2``,
    spec §SPZ-compressed rest pose; anchored splats need compact ``local`` anchors). An anchor mesh that does not fit
    its splats (:func:`gsverse_format.scene.judge_fit`) is a warning, an error with ``strict``.
    The file options (``mesh``, ``meshes``, ``pt_path``, ``bake_poses``) take str or any
    path-like object (``pathlib.Path``). ``physics`` (the ``--physics`` values, a str for one)
    and ``mass`` (the ``--mass NAME=KG`` values) say how each object moves
    (:func:`gsverse_format.physics.parse_physics`; each such object gets a hull collider);
    ``ground`` adds a static ground box under the scene (glTF output only).

    The edits (:mod:`gsverse_format.edit`, in the input file's frame, before binding):
    ``translate``, ``rotate`` (Euler degrees) and ``scale`` (uniform, > 0) move the splats,
    ``mesh_translate``, ``mesh_rotate`` and ``mesh_scale`` every anchor mesh (``"x,y,z"``
    strings or sequences of numbers; scale, then rotate, then translate);
    ``drop_nonfinite`` drops splats with NaN or infinite values instead of refusing the file;
    ``crop_box`` (xmin, ymin, zmin, xmax, ymax, zmax) and ``crop_sphere`` (x, y, z, r) keep the
    splats whose means lie inside, after the moves; ``min_opacity`` drops splats below it.
    ``edit_frame`` ``"output"`` makes the edits in the output's frame instead (after the
    frame change, as splat-transform does).
    """

    mesh: str | None = None
    source: str = "auto"
    deformation: DeformationLaw = "affine"
    frame_change: bool = True
    keep_order: bool = False
    sh_degree: int | None = None
    max_distance: float | None = None
    absolute_distance: bool = False
    drop_unanchored: bool = False
    faces: int | None = None
    reconstruct_faces: int | None = None
    pt_path: str | None = None
    k: int | None = None
    legacy_trellis_frame: bool = False
    plain: bool = False
    bake_poses: str | None = None
    meshes: list[str] | None = None
    watertight: bool = False
    collider: str | None = None
    anchors: str | None = None
    quantize: int | None = None
    compress: str | None = None
    strict: bool = False
    physics: list[str] | None = None
    mass: list[str] | None = None
    ground: bool = False
    translate: str | tuple[float, ...] | None = None
    rotate: str | tuple[float, ...] | None = None
    scale: str | float | None = None
    mesh_translate: str | tuple[float, ...] | None = None
    mesh_rotate: str | tuple[float, ...] | None = None
    mesh_scale: str | float | None = None
    drop_nonfinite: bool = False
    crop_box: str | tuple[float, ...] | None = None
    crop_sphere: str | tuple[float, ...] | None = None
    min_opacity: str | float | None = None
    edit_frame: str = "input"

    def __post_init__(self) -> None:  # file options given as path-like objects, kept as str
        self.mesh, self.pt_path, self.bake_poses = (
            None if p is None else os.fspath(p) for p in (self.mesh, self.pt_path, self.bake_poses))
        self.meshes = None if self.meshes is None else [os.fspath(p) for p in self.meshes]
        if isinstance(self.physics, str):
            self.physics = [self.physics]
        if isinstance(self.mass, str):
            self.mass = [self.mass]


@dataclass
class ConvertSummary:
    """What a conversion did; ``as_dict()`` is the ``--json`` output."""

    input: str
    output: str
    source: str = ""
    splats: int = 0
    anchored: int = 0
    static: int = 0
    dropped: int = 0
    profile: str | None = None
    deformation: str | None = None
    #: How glTF output stores the anchors: ``"compact"`` (1.2) or ``"explicit"`` (1.1); None
    #: for other outputs and for outputs without anchors.
    anchors: str | None = None
    #: ``"spz"`` when glTF output stores the rest pose SPZ-compressed, else None.
    compression: str | None = None
    sh_degree: int = 0
    mesh_faces: int = 0
    degenerate_faces: int = 0
    distance: dict[str, float] = field(default_factory=dict)
    max_distance: float | None = None
    check: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    objects: list[dict[str, Any]] = field(default_factory=list)
    anchor_meshes: list[dict[str, Any]] = field(default_factory=list)
    fit: list[dict[str, Any]] = field(default_factory=list)
    #: Per object with physics: {name, kind, mass, collider: {kind, faces}}.
    physics: list[dict[str, Any]] = field(default_factory=list)
    #: The ground box: {size: [x, y, z], translation: [x, y, z], top: y}, or None.
    ground: dict[str, Any] | None = None
    #: splats the edits dropped: ``nonfinite``, ``cropped``, ``below_opacity`` (empty: no edit)
    edits: dict[str, int] = field(default_factory=dict)
    output_bytes: int = 0
    seconds: float = 0.0
    #: The splats were bound, but the output format (PLY) holds plain splats only.
    plain_output: bool = False

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    def lines(self) -> list[str]:
        written = ("written as plain splats (anchoring not written to PLY)"
                   if self.plain_output else
                   f"written: anchored {self.anchored}, static {self.static}")
        out = [f"{self.input} -> {self.output}  (source: {self.source})",
               f"  splats     {self.splats} {written}; dropped {self.dropped}; "
               f"SH degree {self.sh_degree}"]
        if self.profile:
            law = f", deformation {self.deformation}" if self.deformation else ""
            layout = {"compact": "; compact anchors (extension 1.2)",
                      "explicit": "; explicit anchors (extension 1.1 layout)"}.get(
                          self.anchors or "", "")
            if self.compression:
                layout += f"; rest pose {self.compression.upper()}-compressed"
            out.append(f"  {'binding    ' if self.plain_output else 'anchoring  '}profile "
                       f"{self.profile}{law}, {self.mesh_faces} faces "
                       f"({self.degenerate_faces} degenerate, never bound)"
                       + ("; not written" if self.plain_output else layout))
        if self.distance:
            d = self.distance
            out.append(f"  distance   to mesh p50 {d['p50']:.3g}, p95 {d['p95']:.3g}, p99 {d['p99']:.3g}, "
                       f"max {d['max']:.3g} (mesh diagonal {d['mesh_diagonal']:.3g})")
        if self.max_distance is not None:
            out.append(f"  static     splats farther than {self.max_distance:.3g} from the mesh "
                       f"{'dropped' if self.dropped else 'kept as plain splats'}")
        if self.edits:
            e = self.edits
            out.append(f"  edits      dropped {e['nonfinite']} non-finite, {e['cropped']} "
                       f"outside the crop, {e['below_opacity']} below the minimum opacity")
        for obj in self.objects:
            d = obj["distance"]
            dist = (f", distance p50 {d['p50']:.3g}, p95 {d['p95']:.3g}, max {d['max']:.3g}"
                    if d else "")
            limit = f", within {obj['max_distance']:.3g}" if obj["max_distance"] is not None \
                else ""
            out.append(f"  object     {obj['name']}: {obj['splats']} splats, {obj['faces']} "
                       f"faces{dist}{limit}")
        for m in self.anchor_meshes:
            state = "a closed 2-manifold" if m["closed_manifold"] else (
                f"not a closed 2-manifold ({m['boundary_edges']} boundary, "
                f"{m['nonmanifold_edges']} non-manifold edges)")
            collider = f"; {m['collider']['kind']} collider, {m['collider']['faces']} faces" \
                if m["collider"] else ""
            out.append(f"  manifold   {m['name']} anchor mesh: {state}{collider}")
        for body in self.physics:
            mass = f", {body['mass']:.6g} kg" if body["mass"] is not None else ""
            out.append(f"  physics    {body['name']}: {body['kind']}{mass}; "
                       f"{body['collider']['kind']} collider, {body['collider']['faces']} faces")
        if self.ground is not None:
            g = self.ground
            out.append(f"  ground     static box {g['size'][0]:.4g} x {g['size'][1]:.4g} x "
                       f"{g['size'][2]:.4g}, top at y = {g['top']:.6g} (the lowest splat), "
                       f"centred at x = {g['translation'][0]:.4g}, z = {g['translation'][2]:.4g}")
        for note in self.notes:
            out.append(f"  note       {note}")
        out.append(f"  wrote      {self.output_bytes} bytes in {self.seconds:.2f} s")
        return out


def check_options(input_path: str, output_path: str, options: ConvertOptions) -> None:
    """Step 1 of :func:`gsverse_format.pipeline.convert`: refuse impossible options, missing
    input files and an unwritable output (:class:`~gsverse_format.errors.UsageError`), before
    any work."""
    SplatEdit.from_options(options)   # bad numbers: a UsageError naming the flag
    if options.deformation not in ("affine", "rigid"):
        raise UsageError(f"--deformation must be affine or rigid, not {options.deformation!r}")
    if options.sh_degree is not None and options.sh_degree not in (0, 1, 2, 3):
        raise UsageError(f"--sh-degree must be 0..3, not {options.sh_degree}")
    if options.max_distance is not None and not (options.max_distance >= 0):
        raise UsageError(f"--max-distance must be >= 0, not {options.max_distance}")
    if options.drop_unanchored and options.max_distance is None:
        raise UsageError("--drop-unanchored needs --max-distance")
    if options.collider is not None and options.collider not in ("hull",):
        raise UsageError(f"--collider must be hull, not {options.collider!r}")
    if options.plain and (options.meshes or options.watertight or options.collider
                          or options.physics or options.ground):
        raise UsageError("--plain writes splats without anchoring: drop --mesh, --watertight, "
                         "--collider, --physics and --ground, or --plain")
    physics_request(input_path, options)
    for flag, value in (("--faces", options.faces),
                        ("--reconstruct-faces", options.reconstruct_faces)):
        if value is not None and value < 4:
            raise UsageError(f"{flag} must be at least 4, not {value}")
    if not os.path.exists(input_path):
        raise UsageError("file not found", input_path)
    for p in (options.mesh, options.pt_path, options.bake_poses, *(options.meshes or ())):
        if p is not None and not os.path.isfile(p):
            raise UsageError("file not found", p)
    check_target(output_path)  # a folder, a path through a file, a missing folder
    out_format = find_format(output_path, "write")
    if options.bake_poses is not None and out_format.name != "usd":
        raise UsageError(f"--bake-poses needs a USD output ({', '.join(suffixes('write', 'usd'))})",
                         output_path)
    check_encoding_options(output_path, options, out_format.name)
    if (options.physics or options.ground) and out_format.name != "gltf":
        raise UsageError(f"--physics and --ground apply to glTF output (.glb, .gltf) only "
                         f"(KHR_physics_rigid_bodies); {out_format.name.upper()} output carries "
                         f"{'colliders only (--collider hull)' if out_format.name == 'usd' else 'plain splats'}",
                         output_path)
    if options.ground and not options.frame_change:
        raise UsageError("--ground is placed below the scene along glTF's +Y (up): drop "
                         "--no-frame-change or --ground")
    in_format = FORMATS.get(os.path.splitext(input_path)[1].lower())
    if "usd" in (out_format.name, in_format.name if in_format is not None else None):
        from .io.usd.schema import import_pxr

        try:   # a missing usd-core is said before any work, not after it
            import_pxr()
        except UsageError as exc:
            raise exc.with_path(output_path if out_format.name == "usd" else input_path) \
                from None


def check_encoding_options(output_path: str, options: ConvertOptions, out_format: str) -> None:
    """``--anchors`` and ``--quantize``: glTF output only; compact anchors group the splats by
    face, which ``--keep-order`` forbids (the default layout then falls back to explicit)."""
    if options.anchors not in (None, "explicit", "compact"):
        raise UsageError(f"--anchors must be explicit or compact, not {options.anchors!r}")
    if options.quantize is not None and options.quantize not in (16, 8):
        raise UsageError(f"--quantize must be 16 or 8, not {options.quantize}")
    changed = [flag for flag, on in (("--anchors compact", options.anchors == "compact"),
                                     ("--quantize", options.quantize is not None)) if on]
    if changed and out_format != "gltf":
        raise UsageError(f"{' and '.join(changed)} {'apply' if len(changed) > 1 else 'applies'} "
                         f"to glTF output (.glb, .gltf) only", output_path)
    if options.anchors == "compact" and options.keep_order:
        raise UsageError("--anchors compact stores the splats grouped by face: drop --keep-order "
                         "or --anchors compact")
    if options.compress not in (None, "spz"):
        raise UsageError(f"--compress must be spz, not {options.compress!r}")
    if options.compress is not None:
        if out_format != "gltf":
            raise UsageError("--compress applies to glTF output (.glb, .gltf) only", output_path)
        if options.anchors == "explicit" and not options.plain:
            raise UsageError("--compress spz needs compact anchors: explicit anchors fix the rest "
                             "pose, and SPZ quantization would move it off their remap; drop "
                             "--anchors explicit")
        if options.keep_order and not options.plain:
            raise UsageError("--compress spz needs compact anchors, which group the splats by "
                             "face: drop --keep-order")


def object_names(input_path: str, options: ConvertOptions) -> list[str]:
    """The names of the objects a conversion makes: the ``--mesh`` file stems, or the input's
    stem for a mesh reconstructed from the splats."""
    meshes = options.meshes or ([options.mesh] if options.mesh else [])
    return [object_name(p) for p in meshes] or [object_name(input_path) or "splats"]


def physics_request(input_path: str, options: ConvertOptions) -> tuple[dict[str, str],
                                                                         dict[str, float]]:
    """(object name -> physics kind, object name -> mass) that ``--physics`` and ``--mass``
    ask for (:func:`gsverse_format.physics.parse_physics`); :class:`UsageError` for a request
    that does not parse or names no object."""
    from .physics import parse_mass, parse_physics

    names = object_names(input_path, options)
    kinds = parse_physics(options.physics, names)
    if options.mass and not kinds:
        raise UsageError("--mass needs --physics (the objects it weighs)")
    return kinds, parse_mass(options.mass, kinds, names)


def source_options(source: str, options: ConvertOptions) -> tuple[SourceOptions, list[str]]:
    """What the loaders get from the command line, and notes on flags that do not apply."""
    from .converters.base import SourceOptions

    notes: list[str] = []
    trellis_frame: TrellisFrame = "legacy" if options.legacy_trellis_frame else "current"
    if not options.frame_change:
        trellis_frame = "none"
        if options.legacy_trellis_frame and source == "trellis":
            notes.append("--legacy-trellis-frame ignored: --no-frame-change keeps the PLY as is")
    return SourceOptions(pt_path=options.pt_path, k=options.k, trellis_frame=trellis_frame,
                         keep_nonfinite=options.drop_nonfinite), notes
