"""The conversion pipeline behind ``gsverse-convert``: one input, top to bottom.

:func:`convert` runs these steps in order:

1. check the options;
2. format conversion only (``plain``, or a glTF/USD input or a PLY output without a mesh):
   read the file into the glTF frame (:func:`gsverse_format.io.registry.read_asset`; anchoring
   a glTF or USD file holds is kept), truncate SH, and go to 7;
3. otherwise load the source (``--from``, or detected: the table of
   :mod:`gsverse_format.converters.registry`) — splats, mesh, maybe exact anchors, in the
   source's own frame — and make the edits asked for (:mod:`gsverse_format.edit`: drop
   non-finite splats, move splats and meshes, crop, minimum opacity), in that frame (a
   format-only conversion makes them in step 2, in the file's frame);
4. rotate that into the glTF frame (:func:`to_gltf`): the one place where a source's
   coordinates change frame (the frames are :data:`gsverse_format.io.registry.FRAMES`);
   without the frame change (``frame_change=False``) they stay in the source's frame, which
   the asset's ``frame`` names and a glTF or USD output records (``asset.extras.gsverse``);
5. reconstruct an anchor mesh from the splats when the source has none
   (:func:`gsverse_format.converters.reconstruct.reconstruct_mesh`, about
   ``reconstruct_faces`` faces);
6. truncate SH → decimate the mesh to ``faces`` → bind splats that have no exact anchors to
   their nearest triangle → keep only what the scene requires (splats farther than
   ``max_distance`` from the mesh stay plain, or are dropped) → sort anchored splats by face;
7. write atomically (:func:`gsverse_format.io.registry.write_asset`, from the glTF frame into
   the output file's).

Steps 3–5 are :func:`load_source`. Library users call :func:`convert`; the command line
(:mod:`gsverse_format.cli.convert`) only parses options and prints the returned
:class:`ConvertSummary`. The options, the summary and the checks of step 1 are in
:mod:`gsverse_format.convert_options` (re-exported here: ``pipeline.ConvertOptions``).
"""
from __future__ import annotations

import os
import time
import warnings
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from .convert_options import ConvertOptions, ConvertSummary, check_options, source_options
from .edit import EditCounts, SplatEdit, edit_splats, transform_mesh
from .errors import FormatError, GsverseError, NonFiniteError, UsageError
from .io.registry import (FORMATS, FRAMES, find_format, khr_loss, read_asset, rotate_asset,
                          write_asset)
from .model import (Anchoring, KhrProperties, LocalAnchors, SplatAsset, SplatCloud, face_order,
                    SplatPrimitive, prim_label, splat_problem)
from .progress import Progress
from .transform import rotate_mesh, rotate_splats

if TYPE_CHECKING:
    from .converters.base import SourceOptions, SourceResult

# The sources, binding, nearest-triangle search and scene modules are imported where they are
# used: a format-only conversion (``plain``) never loads them.

__all__ = ["ConvertOptions", "ConvertSummary", "convert", "load_source", "read_input", "to_gltf"]

#: Formats whose files can hold anchoring (kept by a format-only conversion).
_ANCHORING_FORMATS = ("gltf", "usd")
#: Why a format-only conversion's input has no splats, by input format.
_NO_SPLATS = {"gltf": "the file has no KHR_gaussian_splatting POINTS primitive",
              "ply": "the PLY has no vertices", "usd": "the stage has no splat prim with points"}
#: The ``source`` a summary names for a format-only conversion, by input format.
_FORMAT_SOURCE = {"gltf": "khr", "ply": "3dgs"}
#: Sources whose loaders keep non-finite splats for ``drop_nonfinite`` to drop
#: (``SourceOptions.keep_nonfinite``), and the input format that does in a format-only
#: conversion; other readers refuse such files.
_KEEP_NONFINITE_SOURCES = ("3dgs", "trellis")
_KEEP_NONFINITE_FORMAT = "ply"
#: What a refusal of non-finite splats adds where ``--drop-nonfinite`` would help.
_DROP_HINT = "; --drop-nonfinite drops those splats instead"


def _format_only(input_path: str, output_path: str, options: ConvertOptions) -> bool:
    """Whether this is a format conversion only: no binding involved (PLY <-> GLB <-> USD,
    GLB -> GLB, PLY -> PLY); anchoring already present in a glTF or USD input is kept."""
    if options.plain:
        return True
    if options.mesh is not None or options.source not in ("auto", "khr"):
        return False
    in_format = FORMATS.get(os.path.splitext(input_path)[1].lower())
    return (in_format is not None and in_format.name in _ANCHORING_FORMATS) \
        or find_format(output_path, "write").name == "ply"


def convert(input_path: str | os.PathLike[str], output_path: str | os.PathLike[str],
            options: ConvertOptions | None = None,
            progress: Progress | None = None) -> ConvertSummary:
    """Convert ``input_path`` (any supported source) to ``output_path`` (any writable format)."""
    options = options or ConvertOptions()
    if options.meshes is not None:   # several objects; one is a plain --mesh
        if options.mesh is not None and options.mesh not in options.meshes:
            raise UsageError("give the anchor meshes either as mesh or as meshes, not both")
        options = replace(options, mesh=options.meshes[0] if options.meshes else None,
                          meshes=list(options.meshes) if len(options.meshes) > 1 else None)
    progress = progress or Progress(enabled=False)
    start = time.perf_counter()
    input_path, output_path = os.fspath(input_path), os.fspath(output_path)
    summary = ConvertSummary(input_path, output_path)
    check_options(input_path, output_path, options)
    protect = tuple(p for p in (input_path, options.mesh, options.pt_path, options.bake_poses,
                                *(options.meshes or ())) if p is not None)

    if _format_only(input_path, output_path, options):
        if options.mesh is not None:
            raise UsageError("--plain writes splats without anchoring: drop --mesh or --plain")
        if options.watertight or options.collider is not None or options.physics \
                or options.ground:
            raise UsageError("--watertight, --collider, --physics and --ground act on the "
                             "anchor mesh the splats are bound to: give --mesh (or a source "
                             "that has or reconstructs one)")
        progress.stage(f"reading {os.path.basename(input_path)}")
        in_format = find_format(input_path, "read")
        summary.source = _FORMAT_SOURCE.get(in_format.name, in_format.name)
        edit = SplatEdit.from_options(options)
        asset = _read_noting_usd_warnings(input_path, options, summary, edit,
                                          in_format.name == _KEEP_NONFINITE_FORMAT)
        if not asset.splat_count():
            raise FormatError(f"no splats to convert ("
                              f"{_NO_SPLATS.get(in_format.name, 'the file holds none')})",
                              input_path)
        if not edit.is_identity:
            asset = _edit_asset(asset, edit, options, summary, input_path)
            if edit.frame == "input" and options.frame_change and in_format.frame != "gltf":
                asset = rotate_asset(asset, FRAMES[in_format.frame].to_gltf)
        for i, prim in enumerate(asset.primitives):
            _require_valid_splats(prim.splats, input_path, prim_label(i, prim))
        from .converters.khr import require_valid_primitives
        require_valid_primitives(asset, input_path)  # anchors too: the input's problem
        _require_writable_khr([(prim_label(i, p), p.khr) for i, p in enumerate(asset.primitives)],
                              input_path, output_path)
        if options.sh_degree is not None:
            for prim in asset.primitives:
                if prim.splats.sh_degree > options.sh_degree:
                    prim.splats = prim.splats.with_sh_degree(options.sh_degree)
        if options.plain:
            asset = SplatAsset([SplatPrimitive(p.splats, None, p.name, p.khr)
                                for p in asset.primitives], asset.generator, frame=asset.frame)
        bodies = [p.name or "?" for p in asset.primitives if p.physics is not None] + \
            (["ground"] if asset.ground is not None else [])
        if bodies and find_format(output_path, "write").name != "gltf":
            summary.notes.append(f"the input's physics ({', '.join(bodies)}) is not written: "
                                 f"only glTF output holds it")
        return _finish(asset, output_path, options, protect, summary, progress, start)

    from .io.mesh import read_meshes_once
    from .scene import (anchor_scene, finish_physics, normalize_skin_weights,
                        read_scene_meshes)

    with read_meshes_once():   # auto-detection and the loader read a --mesh file once
        source = options.source
        if source == "auto":
            from .converters import detect_source

            source, reason = detect_source(input_path, options.mesh)
            summary.notes.append(f"detected source {source}: {reason}")
        summary.source = source
        progress.stage(f"reading {source} input")
        src_options, notes = source_options(source, options)
        summary.notes.extend(notes)
        reconstruct_faces = options.reconstruct_faces if options.reconstruct_faces is not None \
            else options.faces
        edit = SplatEdit.from_options(options)
        if not edit.is_identity:
            summary.edits = vars(EditCounts())
        if options.meshes:
            before, after = edit.split()
            result = load_source(source, input_path, options.mesh, src_options, frame_change=False,
                                 edit=before, summary=summary)
            more = read_scene_meshes(options.meshes[1:], result.frame, options.frame_change,
                                     lambda m: transform_mesh(m, before.mesh))
            result = to_gltf(result) if options.frame_change else result
            if after is not None and not after.is_identity:   # in the output's frame
                result = _edit_source(result, after, summary, input_path)
                more = [transform_mesh(m, after.mesh) for m in more]
            read = list(zip([result.mesh, *more], options.meshes))
        else:
            result = load_source(source, input_path, options.mesh, src_options,
                                 frame_change=options.frame_change,
                                 reconstruct_faces=reconstruct_faces, progress=progress,
                                 edit=edit, summary=summary)
            read = [(result.mesh, options.mesh or input_path)]
    for mesh, mesh_path in read:   # a rig's skin weights as readers use them
        if mesh is not None:
            normalize_skin_weights(mesh, mesh_path, options, summary)
    summary.notes.extend(result.notes)
    summary.check = dict(result.check)
    if result.inputs:  # the files a source folder's loader read, in place of the whole folder
        protect = (*(p for p in protect if p != input_path or not os.path.isdir(p)),
                   *result.inputs)
    _require_writable_khr([("the splats", result.khr)], input_path, output_path)
    if options.meshes:
        if result.mesh is None:
            raise UsageError(f"the {source} source took no mesh from --mesh; several --mesh "
                             f"need a source of free splats (3dgs, khr)", input_path)
        asset = anchor_scene(result, [result.mesh, *more], options.meshes, options, progress,
                             summary)
    else:
        asset = _anchor(result, options, progress, summary)
    asset.frame = result.frame   # the source's, without the frame change: the output records it
    del result   # the source's splats: the asset holds its own (sorted) copies
    reports = finish_physics(asset, options, summary)   # computed while the output is written
    return _finish(asset, output_path, options, protect, summary, progress, start, reports)


def load_source(source: str, input_path: str | os.PathLike[str], mesh_path: str | None = None,
                options: SourceOptions | None = None, *, frame_change: bool = True,
                reconstruct_faces: int | None = None,
                progress: Progress | None = None, edit: SplatEdit | None = None,
                summary: ConvertSummary | None = None) -> SourceResult:
    """Load ``source``'s output (steps 3–5 of :func:`convert`): the loader's result edited
    by ``edit`` (in the source's frame, or in the glTF frame after the rotation for
    ``edit.frame == "output"``; what it dropped is counted in ``summary.edits``),
    rotated into the glTF frame (unless ``frame_change`` is off), with an anchor mesh of about
    ``reconstruct_faces`` faces reconstructed from the splats when the source has none.
    (TRELLIS's PLY-to-GLB frame is ``options.trellis_frame``; :func:`convert` sets it to
    ``"none"`` with ``frame_change`` off.) ``progress`` shows each step as it starts."""
    from .converters import get_source
    from .converters.base import SourceOptions, require_splats
    from .converters.reconstruct import reconstruct_mesh

    path = os.fspath(input_path)
    hint = source in _KEEP_NONFINITE_SOURCES
    try:
        result = get_source(source).load(path, mesh_path, options or SourceOptions())
    except NonFiniteError as exc:
        raise type(exc)(exc.cause + (_DROP_HINT if hint else ""), exc.path) from None
    require_splats(result.splats, path, f"the {source} input holds none")
    before, after = edit.split() if edit is not None else (None, None)
    if before is not None and not before.is_identity:
        result = _edit_source(result, before, summary, path)
    _require_valid_splats(result.splats, path)
    if frame_change:
        result = to_gltf(result)
    if after is not None and not after.is_identity:
        result = _edit_source(result, after, summary, path)
    if result.mesh is None:
        result = reconstruct_mesh(result, reconstruct_faces, path,
                                  stage=progress.stage if progress is not None else None)
    return result


def _require_valid_splats(splats: SplatCloud, input_path: str, label: str = "") -> None:
    """Refuse input splats that are not valid ``KHR_gaussian_splatting`` data (non-finite
    values, negative scales, opacities outside [0, 1], zero rotation quaternions, as the PLY
    reader does) as a :class:`FormatError` naming the input: checked when they are read, so
    that the problem is the input's, not the output's. Checked after the edits: non-finite
    values and zero quaternions that reach here are what ``--drop-nonfinite`` drops, and the
    message says so."""
    problem = splat_problem(splats)
    zero = int(np.count_nonzero(~np.any(splats.rotations != 0, axis=1)))
    if problem is None and zero:
        problem = (f"zero rotation quaternions in {zero} of {len(splats)} splats (rotations "
                   f"are unit quaternions)")
        problem += _DROP_HINT
    elif problem is not None and problem.startswith("non-finite"):
        problem += _DROP_HINT
    if problem is not None:
        raise FormatError(f"{label + ': ' if label else ''}{problem}", input_path)


def _edited(cloud: SplatCloud, edit: SplatEdit,
            summary: ConvertSummary | None) -> tuple[SplatCloud, np.ndarray | None]:
    """:func:`gsverse_format.edit.edit_splats`, counted into ``summary.edits``."""
    counts = EditCounts(**(summary.edits if summary is not None and summary.edits else {}))
    cloud, keep = edit_splats(cloud, edit, counts)
    if summary is not None:
        summary.edits = vars(counts)
    return cloud, keep


def _no_splats_left(summary: ConvertSummary | None, input_path: str) -> FormatError:
    e = summary.edits if summary is not None else {}
    return FormatError(f"no splats left after the edits (dropped {e.get('nonfinite', 0)} "
                       f"non-finite, {e.get('cropped', 0)} outside the crop, "
                       f"{e.get('below_opacity', 0)} below the minimum opacity): nothing "
                       f"written", input_path)


def _edit_source(result: SourceResult, edit: SplatEdit, summary: ConvertSummary | None,
                 input_path: str) -> SourceResult:
    """A loaded source edited in its own frame (:mod:`gsverse_format.edit`): splats, mesh,
    and the source's exact anchors, which follow the splats kept; moving splats or mesh
    replaces them by nearest-triangle binding."""
    splats, keep = _edited(result.splats, edit, summary)
    if not len(splats):
        raise _no_splats_left(summary, input_path)
    mesh = transform_mesh(result.mesh, edit.mesh) if result.mesh is not None else None
    anchors, notes = result.anchors, list(result.notes)
    if anchors is not None:
        if not (edit.splats.is_identity and edit.mesh.is_identity):
            notes.append("the source's exact binding was replaced by nearest-triangle binding "
                         "(local profile): the edits moved the splats or the mesh")
            anchors = None
        elif keep is not None:
            anchors = anchors.subset(keep)
    return replace(result, splats=splats, mesh=mesh, anchors=anchors, notes=notes)


def _edit_asset(asset: SplatAsset, edit: SplatEdit, options: ConvertOptions,
                summary: ConvertSummary, input_path: str) -> SplatAsset:
    """A format-only conversion's asset edited in the file's frame: each primitive's splats
    (and the anchors that follow those kept); primitives left without splats are dropped.
    Anchored splats are not moved (their anchors would no longer place them): a
    :class:`UsageError` says to add ``--plain``."""
    summary.edits = vars(EditCounts())
    primitives = []
    for prim in asset.primitives:
        anchoring = None if options.plain else prim.anchoring
        if anchoring is not None and not edit.splats.is_identity:
            raise UsageError("--translate, --rotate and --scale would move anchored splats "
                             "off their anchors: add --plain (the anchoring is not written), "
                             "or convert the splats' source with --mesh", input_path)
        splats, keep = _edited(prim.splats, edit, summary)
        if not len(splats):
            continue
        if anchoring is not None and keep is not None:
            anchoring = Anchoring(anchoring.mesh, anchoring.anchors.subset(keep))
        primitives.append(SplatPrimitive(splats, anchoring, prim.name, prim.khr))
    if not primitives:
        raise _no_splats_left(summary, input_path)
    return replace(asset, primitives=primitives)


def _require_writable_khr(labelled: list[tuple[str, KhrProperties]], input_path: str,
                          output_path: str) -> None:
    """Refuse what the output cannot keep of the input's ``KHR_gaussian_splatting``
    properties (an unknown kernel, projection or sorting method, a nested extension) rather
    than rewrite or drop it: a :class:`FormatError` naming the input, the value and why.
    ``labelled``: (how to name the primitive, its properties)."""
    out_format = find_format(output_path, "write")
    for label, props in labelled:
        problem = khr_loss(props, out_format, label)
        carry = props.carry_problem()
        if problem is None and carry is not None:
            problem = f"{label}: {carry}"
        if problem is not None:
            raise FormatError(problem, input_path)


def to_gltf(result: SourceResult) -> SourceResult:
    """``result`` rotated from its frame into the glTF frame: splats and mesh; the anchors are
    relative to their triangles and stay as they are. ``result`` is given up: its SH may be
    rotated in place (:func:`gsverse_format.transform.rotate_splats`)."""
    frame = FRAMES[result.frame]
    if frame.name == "gltf":
        return result
    mesh = rotate_mesh(result.mesh, frame.to_gltf) if result.mesh is not None else None
    return replace(result, splats=rotate_splats(result.splats, frame.to_gltf, consume=True),
                   mesh=mesh, notes=result.notes + [frame.note], frame="gltf")


def _read_noting_usd_warnings(input_path: str, options: ConvertOptions,
                              summary: ConvertSummary, edit: SplatEdit,
                              keeps_nonfinite: bool) -> SplatAsset:
    """``read_asset``; what the USD reader replaced in foreign data goes to the summary notes.
    With edits, the asset stays in the file's frame (the edits are made there), and a reader
    that can (``keeps_nonfinite``) keeps non-finite splats for ``edit`` to drop."""
    from .io.usd import UsdReadWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UsdReadWarning)
        try:
            asset = read_input(input_path, frame_change=options.frame_change
                               and (edit.is_identity or edit.frame == "output"),
                               keep_nonfinite=edit.drop_nonfinite and keeps_nonfinite)
        except NonFiniteError as exc:
            raise type(exc)(exc.cause + (_DROP_HINT if keeps_nonfinite else ""),
                            exc.path) from None
    for w in caught:
        if issubclass(w.category, UsdReadWarning):
            summary.notes.append(str(w.message))
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return asset


def read_input(path: str | os.PathLike[str], *, frame_change: bool = True,
               keep_nonfinite: bool = False) -> SplatAsset:
    """:func:`~gsverse_format.io.registry.read_asset` for files from anywhere: a USD file is
    parsed in a child process (:func:`gsverse_format.io.usd.read_usd` with ``isolate``), so
    that a file that crashes the USD library (a stack overflow on deeply nested prims, an
    abort on corrupt ``.usdc`` data) is a :class:`FormatError` naming it, not the end of this
    process. ``keep_nonfinite``: a 3DGS PLY's non-finite splats are kept, not refused
    (:func:`gsverse_format.io.ply.read_ply_asset`)."""
    fmt = find_format(path, "read")
    if keep_nonfinite and fmt.name == "ply":
        from .io.ply import read_ply_asset

        asset = read_ply_asset(path, keep_nonfinite=True)
        if frame_change:
            return rotate_asset(asset, FRAMES[fmt.frame].to_gltf, consume=True)
        asset.frame = fmt.frame
        return asset
    if fmt.name != "usd":
        return read_asset(path, frame_change=frame_change)
    from .io.usd import read_usd

    asset = read_usd(path, isolate=True)
    if frame_change and fmt.frame != "gltf":
        asset = rotate_asset(asset, FRAMES[fmt.frame].to_gltf, consume=True)
    return asset


def _finish(asset: SplatAsset, output_path: str, options: ConvertOptions,
            protect: tuple[str, ...], summary: ConvertSummary, progress: Progress,
            start: float, reports: Callable[[], None] | None = None) -> ConvertSummary:
    """Step 7: fill the summary and write ``asset``; then ``reports()``, which completes the
    anchor meshes' manifold reports (:func:`gsverse_format.scene.finish_physics`)."""
    summary.splats = asset.splat_count()
    summary.anchored = sum(len(p.splats) for p in asset.anchored)
    summary.static = sum(len(p.splats) for p in asset.static)
    summary.sh_degree = max((p.splats.sh_degree for p in asset.primitives), default=0)
    if asset.anchored and summary.profile is None:
        anchoring = asset.anchored[0].anchoring
        assert anchoring is not None
        summary.profile = anchoring.anchors.profile
        summary.deformation = getattr(anchoring.anchors, "deformation", None)
        summary.mesh_faces = anchoring.mesh.face_count
    kept = sorted({d for p in asset.primitives for d in p.khr.differences()})
    if kept:
        summary.notes.append(f"kept the input's KHR_gaussian_splatting {', '.join(kept)}")
    if find_format(output_path, "write").name == "ply" and asset.anchored:
        # PLY holds plain splats: what the summary counts is what the file holds
        summary.plain_output = True
        summary.static += summary.anchored
        summary.anchored = 0
    poses = None
    if options.bake_poses is not None:
        from .io.usd import load_poses

        poses = load_poses(options.bake_poses)
        _require_poses_fit(asset, poses, options.bake_poses, summary.input)
        summary.notes.append(f"baked {len(poses.times)} anchor-mesh poses into USD time samples")
    encoding: dict[str, Any] = {}
    if find_format(output_path, "write").name == "gltf":
        from .io.gltf.writer import QUANTIZE_BITS, compress_notes, compress_problem, quantize_notes

        quantize = QUANTIZE_BITS[options.quantize] if options.quantize is not None else None
        layout = _anchor_layout(asset, options, summary)
        encoding = {"quantize": quantize, "anchors": layout, "compress": options.compress}
        summary.notes.extend(quantize_notes(asset, quantize, layout))
        if options.compress is not None:
            problem = compress_problem(asset, layout)
            if problem is not None:
                raise UsageError(f"--compress {options.compress}: {problem}", summary.input)
            summary.notes.extend(compress_notes(asset))
            summary.compression = options.compress
    progress.stage(f"writing {os.path.basename(output_path)}")
    write_asset(asset, output_path, frame_change=options.frame_change, protect=protect,
                bake_poses=poses, **encoding)
    if reports is not None:
        reports()
    progress.close()
    summary.output_bytes = os.path.getsize(output_path)
    summary.seconds = time.perf_counter() - start
    return summary


def _anchor_layout(asset: SplatAsset, options: ConvertOptions, summary: ConvertSummary) -> str:
    """How glTF output stores the anchors: ``options.anchors`` when given, else compact, or
    explicit (with a note) where compact cannot be written; recorded in the summary."""
    from .io.gltf.writer import compact_problem

    layout = options.anchors or "compact"
    if options.anchors is None and asset.anchored:
        reason = ("--keep-order keeps the input's splat order, compact anchors group the "
                  "splats by face" if options.keep_order else compact_problem(asset))
        if reason is not None and options.compress is not None:
            raise UsageError(f"--compress {options.compress} needs compact anchors: {reason}")
        if reason is not None:
            layout = "explicit"
            summary.notes.append(f"wrote explicit anchors (extension 1.1 layout), not the "
                                 f"default compact ones: {reason}")
    summary.anchors = layout if asset.anchored else None
    return layout


def _require_poses_fit(asset: SplatAsset, poses: Any, poses_path: str, input_path: str) -> None:
    """``--bake-poses`` needs splats anchored to one mesh (else a :class:`UsageError` naming
    the input: the flag does not apply to it) and poses of that mesh's vertices (else a
    :class:`FormatError` naming the poses file)."""
    meshes = {id(p.anchoring.mesh): p.anchoring.mesh for p in asset.anchored
              if p.anchoring is not None}
    if len(meshes) != 1:
        raise UsageError(f"--bake-poses needs splats anchored to exactly one mesh, this input "
                         f"has {len(meshes)} anchor meshes"
                         + ("" if meshes else " (convert with --mesh first)"), input_path)
    (mesh,) = meshes.values()
    if poses.vertices.shape[1] != len(mesh.vertices):
        raise FormatError(f"poses have {poses.vertices.shape[1]} vertices but the anchor mesh "
                          f"has {len(mesh.vertices)}: give every vertex of the written anchor "
                          f"mesh, in its order (without --faces decimation)", poses_path)


def _anchor(result: SourceResult, options: ConvertOptions, progress: Progress,
            summary: ConvertSummary) -> SplatAsset:
    """Step 6: SH, decimation, binding, what the scene requires, order."""
    from .binding import bind_local
    from .scene import (distance_stats, face_distances, input_stem, judge_fit, object_name,
                        prepare_mesh, with_static_rest)

    splats, mesh, anchors = result.splats, result.mesh, result.anchors
    assert mesh is not None  # load_source reconstructs a missing mesh
    if options.sh_degree is not None and splats.sh_degree > options.sh_degree:
        splats = splats.with_sh_degree(options.sh_degree)
    rigged = mesh.rig is not None
    if mesh.rig is not None:
        summary.notes.extend(f"{object_name(options.mesh or summary.input)}: {note}"
                             for note in mesh.rig.notes)
    if options.faces is not None and mesh.face_count > options.faces:
        from .meshops import decimate, decimation_shortfall

        progress.stage(f"decimating {mesh.face_count} -> {options.faces} faces")
        try:
            mesh = decimate(mesh, options.faces)
        except FormatError as exc:   # the mesh's fault: name the file it came from
            raise exc.with_path(options.mesh or summary.input) from None
        shortfall = decimation_shortfall(mesh, options.faces)
        if shortfall is not None:
            summary.notes.append(shortfall)
        if anchors is not None:
            summary.notes.append("--faces: the source's exact binding was replaced by nearest-"
                                 "triangle binding to the decimated mesh (local profile)")
            anchors = None
    repaired = prepare_mesh(mesh, options, summary, options.mesh or summary.input, progress)
    if repaired is not mesh:
        mesh = repaired
    if rigged and mesh.rig is None:
        summary.notes.append("the anchor mesh's skin, morph targets and animations were dropped: "
                             "decimating or repairing it changed its vertices")
        if anchors is not None:
            summary.notes.append("--watertight: the source's exact binding was replaced by "
                                 "nearest-triangle binding to the repaired mesh (local profile)")
            anchors = None
    sorted_order = None       # when set: the anchors are already in this (face) order
    if anchors is None:
        progress.stage("binding to the nearest triangles")
        # a compact glTF stores no derived anchor value: derived only if something reads one
        compact = (options.anchors in (None, "compact") and not options.keep_order
                   and find_format(summary.output, "write").name == "gltf")
        try:
            bound = bind_local(splats, mesh, deformation=options.deformation, derive=not compact,
                               progress=progress.update, in_face_order=not options.keep_order)
        except GsverseError as exc:
            raise exc.with_path(options.mesh or summary.input)
        anchors, distance, sorted_order = bound.anchors, bound.distance, bound.order
        summary.degenerate_faces = bound.degenerate_faces
    else:
        if isinstance(anchors, LocalAnchors) and anchors.deformation != options.deformation:
            anchors = replace(anchors, deformation=options.deformation)
        distance = face_distances(splats, mesh, anchors.face_index)

    lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    diagonal = float(np.linalg.norm(hi.astype(np.float64) - lo))
    summary.distance = distance_stats(distance, diagonal)
    judge_fit(splats.means, mesh, distance, "the anchor mesh" if options.mesh is None
              else object_name(options.mesh), options.mesh or summary.input, options, summary)
    summary.mesh_faces = mesh.face_count
    summary.profile = anchors.profile
    summary.deformation = getattr(anchors, "deformation", None)

    keep = np.ones(len(splats), bool)
    if options.max_distance is not None:
        limit = options.max_distance if options.absolute_distance else options.max_distance * diagonal
        summary.max_distance = float(limit)
        keep = distance <= limit
    # keep_idx: the splats kept, in their written order; anchor_idx: their anchors' rows
    # (None: all of them, as they are)
    anchor_idx: np.ndarray | None
    if sorted_order is not None:                # the anchors are in face order already
        if options.max_distance is None:
            keep_idx, anchor_idx = sorted_order, None
        else:
            anchor_idx = np.flatnonzero(keep[sorted_order])
            keep_idx = sorted_order[anchor_idx]
    elif not options.keep_order:
        order = face_order(anchors.face_index)
        keep_idx = anchor_idx = order[keep[order]]
    else:
        keep_idx = anchor_idx = np.flatnonzero(keep)
    primitives = []
    if keep_idx.size:
        if keep_idx.size == len(splats):
            # all kept: the source's splats are reordered in place (no second copy of them;
            # nothing reads them in the old order after this) or, kept in order, used as is
            if not options.keep_order:
                splats.permute(keep_idx)
            kept = splats
        else:
            kept = splats.subset(keep_idx)
        kept_anchors = anchors if anchor_idx is None else anchors.subset(anchor_idx)
        primitives.append(SplatPrimitive(kept, Anchoring(mesh, kept_anchors),
                                         input_stem(summary), result.khr))
    return with_static_rest(primitives, splats, result.khr, np.flatnonzero(~keep), options,
                            summary, f"the mesh{' ' + repr(options.mesh) if options.mesh else ''}",
                            "is the mesh")
