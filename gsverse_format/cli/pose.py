"""``gsverse-pose``: posed splats of an anchored asset from any deformation source.

    gsverse-pose ASSET OUT [--times T... | --fps F [--duration D]] [--source FILE]
                 [--animation NAME|INDEX] [--deform KIND=AMOUNT ...]
                 [--to ply|glb|usda|usdc|usd|usdz] [--vat OUT.exr [--vat-mode position|offset]
                 [--vat-half] [--vat-width N] [--vat-normalize]] [--no-frame-change]
                 [-w] [--json] [-q]

The anchor mesh is posed at every time by the source (:mod:`gsverse_format.poses`): the
asset's own skin/morph targets/animations by default, or ``--source`` (a skinned/morphed glTF
with the anchor mesh's vertices, an ``.npz`` vertex cache, an OBJ/PLY sequence, an EXR VAT),
then by the ``--deform`` quick looks in order (alone, they deform the rest pose). Each anchored
primitive is remapped (:func:`gsverse_format.api.remap`) onto its posed anchor mesh; static
primitives stay.

``OUT`` (or ``-o OUT``; :mod:`gsverse_format.cli.grammar`) says what is written, by its name:

* a ``.usda``, ``.usdc`` (binary crate), ``.usd`` (crate) or ``.usdz`` file: one USD file with
  time samples (time codes = seconds × ``--fps``, default 24 per second);
* a ``.ply`` (3DGS PLY) or ``.glb`` (plain ``KHR_gaussian_splatting``) file: that file for one
  time; for several, ``OUT_fNNNN.ply`` … beside it;
* a folder (``--output-dir DIR``, or an existing folder, a path ending in ``/`` or a name
  without a suffix): ``<asset>_fNNNN.<ext>`` per time in it, or one ``<asset>.<ext>`` for USD,
  the format from ``--to`` (default ``ply``; ``--format ply|glb|usd`` is the older spelling,
  ``usd`` meaning ``usda``).

and with ``--vat`` an EXR vertex-animation texture of the anchor mesh over the sampled times.

Frames. Posed files are written in the frame the asset was converted in: an asset converted
with the frame change (the default) is in glTF's frame and a posed PLY is rotated into the
3DGS frame (180° about Z), as ``gsverse-convert`` writes PLY; an asset converted with
``--no-frame-change`` records the source's frame (glTF ``asset.extras.gsverse.frame``, USD
``customLayerData``) and its posed files keep the values as they are, so a posed PLY at rest
gives back the input's positions. ``--no-frame-change`` does the same for an asset that records
nothing (written by another tool without the frame change).

Times. Quick looks alone (``--deform`` without ``--source``) are one pose: they take one time,
t = 0, by default; several times are refused unless a look changes with time (``shake``), so no
two written frames are the same. An animated source needs ``--times`` or ``--fps``. A time
given twice is refused for the same reason.

Exit codes: 0 success, 1 bad input (a missing or unreadable asset or source), 2 usage error
(existing outputs without ``-w`` included), 70 internal error, 130 interrupted (143 SIGTERM,
129 SIGHUP; see :mod:`.boundary`). Errors are one line on stderr naming the file and the cause.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time as _time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..textsafe import safe_line
from ..atomic import make_folder
from ..errors import FormatError, UsageError
from ..limits import MAX_POSES, MAX_VAT_WIDTH
from ..progress import Progress
from .boundary import parse_args, run_command
from .grammar import (Parser, add_json, add_output, add_overwrite, add_quiet, add_version,
                      one_output, output_kind)

PROG = "gsverse-pose"
#: ``--to`` choices: posed files per time (ply, glb) or one USD file with time samples.
TO_FORMATS = ("ply", "glb", "usda", "usdc", "usd", "usdz")
USD_FORMATS = ("usda", "usdc", "usd", "usdz")
#: ``--format`` (the older spelling of ``--to``) -> ``--to``.
FORMATS = {"ply": "ply", "glb": "glb", "usd": "usda"}

EPILOG = """\
output (OUT or -o OUT, by its name):
  posed.usda | .usdc | .usd | .usdz   one USD file with time samples (.usdc, .usd: binary crate)
  posed.ply | posed.glb               that file for one time; several: posed_f0000.ply ...
  DIR/ (or --output-dir DIR)          <asset>_f0000.ply ... per time, or <asset>.usda (--to
                                      picks the format: ply, glb, usda, usdc, usd, usdz)

sources (--source; default: the asset's own skinned/morphed anchor mesh and its animations):
  FILE.glb/.gltf   a skinned and/or morph-target glTF whose mesh has the anchor mesh's
                   vertices (same count and order, same rest positions), e.g. the file given to
                   gsverse-convert --mesh; --animation picks one of its animations
  FILE.npz         vertex cache: vertices (T, V, 3), optional times (T,) in seconds or fps
  DIR or 'GLOB'    one .obj/.ply per frame, sorted by name (numbers compared as numbers)
  FILE.exr         vertex-animation texture (rows = frames, columns = vertices; see
                   gsverse_format.poses.vat)
  frames without times are 1/--source-fps apart (default 24). Times outside a source's
  range clamp to its first or last pose. An animated source needs --times or --fps.

quick looks (--deform, several allowed, applied in order after the source):
  stretch=F (factor along +Y), twist=DEG, bend=DEG, shake=A (fraction of the bounding-box
  diagonal); placed on the anchor mesh's bounding box. Without --source they are one pose,
  written once (t = 0; several times only with shake, which differs at every time).

examples:
  gsverse-pose capsule.glb look.ply --deform twist=90 --deform stretch=1.3
  gsverse-pose fox.glb posed/ --source Fox.glb --animation Walk --fps 24
  gsverse-pose fox.glb posed/ --source Fox.glb --times 0.5 1.0 --to glb
  gsverse-pose fox.glb out/fox.usdc --source sim.npz --fps 30 --vat out/fox_vat.exr
"""


def build_parser() -> argparse.ArgumentParser:
    p = Parser(
        prog=PROG, description="Pose the splats of an anchored asset by a deformation source "
                               "and write the posed splats: a file per time, or one USD file "
                               "with time samples.",
        usage=f"{PROG} ASSET OUT [options]\n       {PROG} ASSET -o OUT [options]\n"
              f"       {PROG} ASSET --output-dir DIR [options]",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("asset", metavar="ASSET", help="an anchored asset (.glb, .gltf, .usda, ...)")
    p.add_argument("out", nargs="?", metavar="OUT",
                   help="what to write: a .usda/.usdc/.usd/.usdz file (time samples), a "
                        ".ply/.glb file (one time; several: OUT_f0000.ply ...), or a folder")
    add_output(p, "OUT")
    p.add_argument("--output-dir", metavar="DIR",
                   help="the folder for the posed files (created if missing)")
    when = p.add_mutually_exclusive_group()
    when.add_argument("--times", type=float, nargs="+", metavar="T",
                      help="the times to pose at, in seconds (quick looks alone: default 0)")
    when.add_argument("--fps", type=float, metavar="F",
                      help="pose at F frames per second from 0 to --duration (default: the "
                           "source's length)")
    p.add_argument("--duration", type=float, metavar="D",
                   help="with --fps: the last time, in seconds")
    p.add_argument("--source", metavar="FILE",
                   help="where the poses come from (see below); default: the asset's own "
                        "animated anchor mesh")
    p.add_argument("--animation", metavar="NAME|INDEX", default="0",
                   help="which glTF animation (default: the first)")
    p.add_argument("--source-fps", type=float, default=24.0, metavar="F",
                   help="frame rate of source frames that carry no times (default 24)")
    p.add_argument("--deform", action="append", metavar="KIND=AMOUNT",
                   help="a quick-look deformation: stretch=F, twist=DEG, bend=DEG, shake=A")
    p.add_argument("--to", choices=TO_FORMATS,
                   help="the output format when OUT is a folder (default ply: 3DGS PLY per "
                        "time; glb: plain KHR_gaussian_splatting GLB per time; usda, usdc, "
                        "usd, usdz: one USD file with time samples); with a file OUT, its "
                        "suffix, which --to must match")
    p.add_argument("--format", choices=tuple(FORMATS),
                   help="the older spelling of --to: ply, glb, or usd (= usda)")
    p.add_argument("--compress", choices=("spz",), default=None,
                   help="spz: GLB frames store their splats as SPZ streams "
                        "(KHR_gaussian_splatting_compression_spz_2; spec/README.md "
                        "§SPZ-compressed rest pose); glb and gltf output only")
    p.add_argument("--no-frame-change", action="store_true",
                   help="write the posed values as they are, in the asset's frame (default: "
                        "as the asset records; an asset converted with the frame change is "
                        "rotated into the 3DGS frame for PLY output)")
    vat = p.add_argument_group("vertex-animation texture")
    vat.add_argument("--vat", metavar="OUT.exr",
                     help="also write the anchor mesh's poses as an OpenEXR VAT")
    vat.add_argument("--vat-mode", choices=("position", "offset"), default="position",
                     help="store positions (default) or offsets from the rest pose")
    vat.add_argument("--vat-half", action="store_true", help="16-bit HALF texels (default "
                                                             "32-bit FLOAT)")
    vat.add_argument("--vat-width", type=int, metavar="N",
                     help="texture width, 1..16384 (default: the vertex count, at most 8192; "
                          "larger meshes wrap onto more rows per frame)")
    vat.add_argument("--vat-normalize", action="store_true",
                     help="store values scaled into [0, 1], the bounds in the header")
    add_overwrite(p)
    add_json(p)
    add_quiet(p)
    add_version(p, PROG)
    return p


@dataclass
class PoseSummary:
    asset: str
    source: str
    format: str
    times: list[float]
    outputs: list[str] = field(default_factory=list)
    #: ``"spz"`` when the GLB frames are SPZ-compressed
    compression: str | None = None
    vat: str | None = None
    anchor_meshes: int = 0
    splats: int = 0
    max_displacement: float = 0.0
    seconds: float = 0.0

    def as_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)

    def lines(self) -> list[str]:
        out = [f"{PROG}: {self.asset}: {len(self.times)} pose(s) from {self.source}",
               f"  splats      {self.splats} on {self.anchor_meshes} anchor mesh(es); anchor "
               f"vertices moved up to {self.max_displacement:.4g}"]
        if self.outputs:
            out.append(f"  wrote       {len(self.outputs)} {self.format} file(s) in "
                       f"{os.path.dirname(self.outputs[0]) or '.'}"
                       + (f" ({self.compression.upper()}-compressed)" if self.compression
                          else ""))
        if self.vat:
            out.append(f"  VAT         {self.vat}")
        out.append(f"  time        {self.seconds:.2f} s")
        return out


def _times(args: argparse.Namespace, duration: float, *, one_pose: bool) -> np.ndarray:
    """The times to pose at. ``one_pose``: quick looks alone that do not change with time
    (default one time, t = 0; several are refused: they would be identical frames)."""
    if args.times is None and args.fps is None:     # quick looks alone (checked by run)
        if args.duration is not None:
            raise UsageError("--duration goes with --fps")
        return np.zeros(1)
    if args.times is not None:
        if args.duration is not None:
            raise UsageError("--duration goes with --fps, not --times")
        times = np.asarray(args.times, dtype=np.float64)
    else:
        fps = float(args.fps)
        if not (math.isfinite(fps) and fps > 0):
            raise UsageError(f"--fps must be > 0, got {args.fps}")
        end = duration if args.duration is None else float(args.duration)
        if not (math.isfinite(end) and end >= 0):
            raise UsageError(f"--duration must be >= 0, got {args.duration}")
        count = int(math.floor(end * fps + 1e-9)) + 1
        if count > MAX_POSES:
            whence = f"--duration {args.duration}" if args.duration is not None else \
                f"the source's duration {end:g} s"
            raise UsageError(f"--fps {args.fps} over {whence} asks for {count} poses; at most "
                             f"{MAX_POSES} per command: lower --fps, give a shorter --duration, "
                             f"or pick --times")
        times = np.arange(count, dtype=np.float64) / fps
    if not np.all(np.isfinite(times)):
        raise UsageError("--times must be finite numbers")
    if len(times) > MAX_POSES:
        raise UsageError(f"--times gives {len(times)} poses; at most {MAX_POSES} per command")
    values, counts = np.unique(times, return_counts=True)
    if np.any(counts > 1):
        raise UsageError(f"--times gives t={values[counts > 1][0]:g} more than once: the "
                         "frames would be identical")
    if one_pose and len(times) > 1:
        raise UsageError(f"the quick looks {', '.join(args.deform)} are the same at every time: "
                         f"{len(times)} times would write {len(times)} identical frames; give "
                         "one time (or none: t = 0), a --source that moves, or add shake=A")
    return times


def _quick_looks_only(args: argparse.Namespace) -> bool:
    return bool(args.deform) and args.source is None


def _out_format(args: argparse.Namespace) -> str | None:
    """``--to``, or ``--format`` in its terms, or None."""
    if args.to is not None and args.format is not None and FORMATS[args.format] != args.to \
            and not (args.format == "usd" and args.to in USD_FORMATS):
        raise UsageError(f"--to {args.to} and --format {args.format} disagree; give --to only")
    return args.to or (FORMATS[args.format] if args.format else None)


def _outputs(args: argparse.Namespace, stem: str, count: int) -> tuple[list[str], str | None]:
    """The paths to write (none without OUT) and their format (``ply``, ``glb`` or a USD
    suffix), from OUT's name (:func:`gsverse_format.cli.grammar.output_kind`)."""
    out = one_output(args.out, args.output, "the output")
    if out is not None and args.output_dir is not None:
        raise UsageError("give OUT (or -o OUT) or --output-dir DIR, not both")
    wanted = _out_format(args)
    folder = args.output_dir
    if out is not None:
        if out == "-":
            raise UsageError("posed splats go to files, not to standard output: give a file "
                             "or folder name", out)
        kind = output_kind(out, ["." + t for t in TO_FORMATS])
        if kind is None:
            raise UsageError(f"neither an output file name (.{', .'.join(TO_FORMATS)}) nor a "
                             f"folder (one that exists, a path ending in '/', or a name without "
                             f"a suffix); for a folder of that name write --output-dir {out}",
                             out)
        if kind == "folder":
            folder = out
        else:
            fmt = os.path.splitext(out)[1].lower()[1:]
            if wanted is not None and wanted != fmt and \
                    not (args.to is None and args.format == "usd" and fmt in USD_FORMATS):
                flag = f"--to {args.to}" if args.to else f"--format {args.format}"
                raise UsageError(f"{flag} does not match the output's suffix", out)
            if fmt in USD_FORMATS or count == 1:
                return [out], fmt
            base = os.path.splitext(out)[0]
            return [f"{base}_f{i:04d}.{fmt}" for i in range(count)], fmt
    if folder is None:
        return [], None
    fmt = wanted or "ply"
    if fmt in USD_FORMATS:
        return [os.path.join(folder, f"{stem}.{fmt}")], fmt
    return [os.path.join(folder, f"{stem}_f{i:04d}.{fmt}") for i in range(count)], fmt


def _posed_asset(asset, posed_meshes: dict[int, np.ndarray]):
    """A plain asset: every anchored primitive remapped onto its posed mesh."""
    from ..api import remap
    from ..model import SplatAsset, SplatCloud, SplatPrimitive

    prims = []
    for prim in asset.primitives:
        c = prim.splats
        if prim.anchoring is not None and id(prim.anchoring.mesh) in posed_meshes:
            r = remap(prim.anchoring, posed_meshes[id(prim.anchoring.mesh)])
            c = SplatCloud(r.means, r.rotations, r.scales, c.opacities, c.sh, c.color_space,
                           dict(c.extra))
        prims.append(SplatPrimitive(c, None, prim.name, prim.khr))
    return SplatAsset(prims, asset.generator, frame=asset.frame)


def run(args: argparse.Namespace, progress: Progress) -> PoseSummary:
    from ..api import write
    from ..pipeline import read_input
    from ..poses import open_source, parse_deformations
    from ..poses.gltf_source import open_gltf_source

    started = _time.monotonic()
    if args.out is None and args.output is None and args.output_dir is None and args.vat is None:
        raise UsageError("nothing to write: give OUT (a .ply/.glb/.usda/.usdc/.usd/.usdz file, "
                         "or a folder) and/or --vat OUT.exr")
    if args.vat is not None and os.path.splitext(args.vat)[1].lower() != ".exr":
        raise UsageError("--vat writes OpenEXR: give a .exr file name", args.vat)
    if args.vat_width is not None and not 1 <= args.vat_width <= MAX_VAT_WIDTH:
        raise UsageError(f"--vat-width must be 1..{MAX_VAT_WIDTH}, got {args.vat_width}")
    if not (math.isfinite(args.source_fps) and args.source_fps > 0):
        raise UsageError(f"--source-fps must be > 0, got {args.source_fps}")
    looks = parse_deformations(args.deform)
    one_pose = _quick_looks_only(args) and not any(q.timed for q in looks)
    if args.times is None and args.fps is None and not _quick_looks_only(args):
        raise UsageError("give --times T... or --fps F: the times of the animation to pose "
                         "(or --deform alone for a quick look)")
    _out_format(args)
    asset_path = args.asset
    if not os.path.isfile(asset_path):
        raise FormatError("file not found", asset_path)
    asset = read_input(asset_path)  # USD in a child process: a crash there is bad input
    meshes = {id(p.anchoring.mesh): p.anchoring.mesh for p in asset.anchored
              if p.anchoring is not None}
    if not meshes:
        raise FormatError("has no anchored splats (convert it with gsverse-convert --mesh "
                          "first)", asset_path)
    # the asset's frame: kept (no rotation) when it records one or --no-frame-change says so
    frame_change = not args.no_frame_change and asset.frame == "gltf"
    animation: int | str = int(args.animation) if args.animation.isdigit() else args.animation

    source = None
    source_label = "the quick looks" if looks else "the asset's animation"
    if args.source is not None:
        source = open_source(args.source, animation=animation, fps=args.source_fps)
        source_label = args.source
    elif not looks:
        if os.path.splitext(asset_path)[1].lower() not in (".glb", ".gltf"):
            raise UsageError("the asset is not glTF, so it carries no animation: give "
                             "--source FILE or --deform", asset_path)
        try:
            source = open_gltf_source(asset_path, animation)
        except FormatError as err:
            raise FormatError(f"{err.cause}; give --source FILE (a skinned glTF, a vertex "
                              f"cache, a VAT) or --deform", asset_path) from None
        source_label = f"{asset_path} (its own animation)"

    # which anchor meshes the source drives
    driven: dict[int, Any] = {}
    if source is not None:
        problems = []
        for key, mesh in meshes.items():
            try:
                source.match(mesh.vertices)
                driven[key] = mesh
                break   # one source poses one mesh
            except FormatError as err:
                problems.append(err)
        if not driven:
            raise problems[0]
    else:
        driven = dict(meshes)

    duration = source.duration() if source is not None else 0.0
    times = _times(args, duration, one_pose=one_pose)
    stem = os.path.splitext(os.path.basename(asset_path))[0]
    outputs, fmt = _outputs(args, stem, len(times))
    usd = fmt in USD_FORMATS
    if args.compress is not None and fmt not in ("glb", "gltf"):
        raise UsageError(f"--compress applies to glb and gltf frames, not {fmt or 'a VAT only'}")
    encoding = {"compress": args.compress} if args.compress is not None else {}
    if (usd or args.vat) and np.any(np.diff(times) <= 0):
        raise UsageError(f"{'a VAT' if args.vat else 'USD time samples'} needs strictly "
                         f"increasing --times")
    if usd and len(meshes) != 1:
        raise UsageError("USD time samples need an asset with exactly one anchor mesh",
                         asset_path)
    targets = outputs + ([args.vat] if args.vat else [])
    if not args.overwrite:
        for path in targets:
            if os.path.lexists(path):
                raise UsageError("output exists; use -w/--overwrite to replace it", path)
    for path in targets:
        if os.path.exists(path) and os.path.samefile(path, asset_path):
            raise UsageError("output would overwrite the input asset", path)
    folders = {os.path.dirname(path) for path in outputs}
    for folder in sorted(f for f in folders if f):
        make_folder(folder)

    summary = PoseSummary(asset_path, source_label, fmt or "vat", [float(t) for t in times],
                          anchor_meshes=len(driven), splats=asset.splat_count(),
                          compression=args.compress)
    vat_mesh_key = next(iter(driven))
    progress.stage(f"posing {len(times)} time(s)")
    frames: list[dict[int, np.ndarray]] = []   # every pose first: a bad one writes nothing
    for i, t in enumerate(times):
        posed: dict[int, np.ndarray] = {}
        for key, mesh in driven.items():
            rest = mesh.vertices.astype(np.float64)
            v = source.at(float(t)) if source is not None else rest.copy()
            for look in looks:
                v = look.apply(v, rest, float(t))
            if not np.all(np.isfinite(v)):
                raise FormatError(f"the pose at t={t:g} s has non-finite vertices",
                                  source.path if source is not None else asset_path)
            posed[key] = v
            summary.max_displacement = max(summary.max_displacement,
                                           float(np.linalg.norm(v - rest, axis=1).max()))
        frames.append(posed)
        progress.update(i + 1, len(times), f"t={t:g}s")
    if outputs and not usd:
        progress.stage(f"writing {len(times)} {fmt} file(s)")
        for i, posed in enumerate(frames):
            write(_posed_asset(asset, posed), outputs[i], protect=(asset_path,),
                  frame_change=frame_change, **encoding)
            summary.outputs.append(outputs[i])
            progress.update(i + 1, len(times))
    progress.close()
    if usd:
        from ..io.usd import BakedPoses

        rate = float(args.fps) if args.fps is not None else 24.0
        poses = BakedPoses(times * rate, np.stack([f[vat_mesh_key] for f in frames]), rate)
        write(asset, outputs[0], protect=(asset_path,), bake_poses=poses,
              frame_change=frame_change)
        summary.outputs.append(outputs[0])
    if args.vat:
        from ..poses import write_vat

        write_vat(args.vat, times, np.stack([f[vat_mesh_key] for f in frames]),
                  rest=driven[vat_mesh_key].vertices, mode=args.vat_mode, half=args.vat_half,
                  width=args.vat_width, normalized=args.vat_normalize, protect=(asset_path,))
        summary.vat = args.vat
    summary.seconds = _time.monotonic() - started
    return summary


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parse_args(parser, argv)
    progress = Progress(enabled=None if not (args.quiet or args.json) else False)

    def work() -> int:
        summary = run(args, progress)
        if args.json:
            print(json.dumps(summary.as_dict(), indent=2))
        elif not args.quiet:
            print("\n".join(map(safe_line, summary.lines())))
        return 0

    return run_command(PROG, args.asset, progress, work, quiet=args.quiet,
                       json_errors=args.json)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
