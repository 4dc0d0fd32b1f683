"""``gsverse-render ASSET OUT``: pictures of an asset at rest or posed (PNG or OpenEXR).

``OUT`` may also be given as ``-o OUT``; the flags shared by every command (``-o``, ``-w``,
``-q``, ``--json``, ``--version``) are those of :mod:`gsverse_format.cli.grammar`.

Exit codes: 0 success, 1 bad input (a missing or unreadable asset or pose file), 2 usage error
(bad options, an existing output without -w), 70 internal error, 130 interrupted (143 SIGTERM,
129 SIGHUP; see :mod:`.boundary`). Errors are one line on stderr (``gsverse-render: error:
<file>: <cause>``).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import sys
import time

import numpy as np

from ..errors import FormatError, GsverseError, UsageError
from ..limits import MAX_RENDER_PIXELS, MAX_RENDER_SIDE
from ..progress import Progress
from .boundary import parse_args, run_command
from .grammar import Parser, add_json, add_output, add_overwrite, add_quiet, add_version, one_output

PROG = "gsverse-render"

EPILOG = """\
examples:
  gsverse-render anchored.glb rest.png
  gsverse-render anchored.glb -o rest.png                    # the same
  gsverse-render anchored.glb sheet.png --deform twist=90 --sheet
  gsverse-render anchored.glb posed.exr --pose pose.npy --camera "eye=0,1,4 target=0,0,0 fov=40"
  gsverse-render anchored.glb spin.png --turntable 36 --size 256x256   # spin_000.png ...

poses:
  --pose FILE   anchor vertices (V, 3): .npy, .npz (the array 'vertices', or its only array)
                or .f32 (raw little-endian float32); with several anchored primitives, all
                their vertices concatenated in file order
  --deform      analytic quick looks along the vertical (+Y) extent of the anchor meshes:
                stretch=FACTOR, twist=DEGREES, bend=DEGREES
  --time T      the asset's own animation at T seconds (a glTF asset whose anchor mesh has
                a skin or morph targets)

output:
  .png: 8-bit RGBA, sRGB-encoded (the splats' colours as blended; transparent background
  unless --background); .exr: linear premultiplied R, G, B (half), A, and Z (float32 camera
  depth). --sheet puts rest | posed | posed anchor-mesh wireframe side by side (PNG only),
  seen by one camera that frames the rest and the posed asset together.
"""


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog=PROG, description="Render a splat asset at rest or posed (CPU reference "
               "renderer).", epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
               usage=f"{PROG} ASSET OUT [options]\n       {PROG} ASSET -o OUT [options]")
    p.add_argument("asset", metavar="ASSET", help="a .glb/.gltf, 3DGS .ply or USD file")
    p.add_argument("out", nargs="?", metavar="OUT",
                   help="OUT.png or OUT.exr (with --turntable N: OUT_000.png ...)")
    add_output(p, "OUT")
    pose = p.add_mutually_exclusive_group()
    pose.add_argument("--time", type=float, metavar="T", help="sample the asset's own animation")
    pose.add_argument("--pose", metavar="FILE", help="anchor vertices (V, 3) .npy/.npz/.f32")
    pose.add_argument("--deform", metavar="NAME=AMOUNT",
                      help="stretch=FACTOR, twist=DEGREES or bend=DEGREES")
    p.add_argument("--camera", metavar="SPEC",
                   help='"eye=x,y,z target=x,y,z [fov=deg] [up=x,y,z] [near=n] [far=f]" '
                        "(default: framed automatically; missing fields come from the framing)")
    p.add_argument("--size", default="512x512", metavar="WxH", help="image size (default 512x512)")
    p.add_argument("--fov", type=float, default=40.0, help="vertical field of view of the "
                   "automatic framing, degrees (default 40)")
    p.add_argument("--turntable", type=int, metavar="N",
                   help="N frames around the vertical axis: OUT_000.png ...")
    p.add_argument("--sheet", action="store_true", help="rest | posed | wireframe (PNG), one "
                   "camera framing rest and posed")
    p.add_argument("--background", metavar="R,G,B", help="background colour 0..1 (sRGB); "
                   "PNG default transparent (sheets: black)")
    add_overwrite(p)
    add_json(p)
    add_quiet(p)
    add_version(p, PROG)
    return p


def _size(text: str) -> tuple[int, int]:
    m = re.fullmatch(r"\s*(\d{1,9})\s*[xX]\s*(\d{1,9})\s*", text)
    side = MAX_RENDER_SIDE
    if not m or not (1 <= int(m.group(1)) <= side and 1 <= int(m.group(2)) <= side):
        raise UsageError(f"--size {text!r}: expected WxH with 1..{side} pixels each")
    width, height = int(m.group(1)), int(m.group(2))
    if width * height > MAX_RENDER_PIXELS:
        raise UsageError(f"--size {text!r}: {width * height} pixels; at most "
                         f"{MAX_RENDER_PIXELS} (4096x4096) per picture")
    return width, height


def _background(text: str | None):
    if text is None:
        return None
    try:
        v = tuple(float(x) for x in text.split(","))
    except ValueError:
        v = ()
    if len(v) != 3 or not all(0.0 <= x <= 1.0 for x in v):
        raise UsageError(f"--background {text!r}: expected R,G,B in 0..1")
    return v


def load_pose_file(path: str) -> np.ndarray:
    """A (V, 3) array from .npy, .npz or raw little-endian float32 .f32."""
    low = path.lower()
    try:
        if low.endswith(".f32"):
            raw = np.fromfile(path, dtype="<f4")
            if raw.size % 3:
                raise FormatError(f"{raw.size} floats is not a whole number of vertices", path)
            return raw.reshape(-1, 3).astype(np.float64)
        data = np.load(path, allow_pickle=False)
        if isinstance(data, np.lib.npyio.NpzFile):
            with data:
                names = list(data.files)
                key = "vertices" if "vertices" in names else names[0] if len(names) == 1 else None
                if key is None:
                    raise FormatError(f"holds arrays {names}; name the pose 'vertices'", path)
                return np.asarray(data[key], np.float64)
        return np.asarray(data, np.float64)
    except GsverseError:
        raise
    except (OSError, ValueError, EOFError) as exc:
        raise FormatError(f"cannot read a pose: {exc}", path) from None


def _poses(args, asset):
    from ..render.scene import DEFORMATIONS, deform_vertices, pose_vertices, split_pose

    if args.time is not None:
        return pose_vertices(asset, args.time, args.asset), f"time {args.time:g}"
    if args.pose is not None:
        v = load_pose_file(args.pose)
        try:
            return split_pose(asset, v), f"pose {os.path.basename(args.pose)}"
        except UsageError as exc:
            raise FormatError(exc.cause, args.pose) from None
    if args.deform is not None:
        name, _, amount = args.deform.partition("=")
        try:
            value = float(amount)
        except ValueError:
            value = float("nan")
        if name not in DEFORMATIONS or not np.isfinite(value):
            raise UsageError(f"--deform {args.deform!r}: expected stretch=FACTOR, twist=DEGREES "
                             "or bend=DEGREES")
        from ..poses.analytic import MAX_STRETCH
        if name == "stretch" and not 1.0 / MAX_STRETCH <= value <= MAX_STRETCH:
            raise UsageError(f"--deform {args.deform!r}: a stretch factor must lie in "
                             f"{1.0 / MAX_STRETCH:g}..{MAX_STRETCH:g}")
        return deform_vertices(asset, name, value), f"{name} {value:g}"
    return None, "rest"


def _outputs(args, frames: int) -> list[str]:
    out = one_output(args.out, args.output, "the picture")
    if out is None:
        raise UsageError("give the picture to write: ASSET OUT.png (or OUT.exr, or -o OUT)")
    base, ext = os.path.splitext(out)
    if ext.lower() not in (".png", ".exr"):
        raise UsageError("the output must end in .png or .exr", out)
    if args.sheet and ext.lower() != ".png":
        raise UsageError("--sheet writes a PNG", out)
    paths = [out] if frames == 1 else [f"{base}_{k:03d}{ext}" for k in range(frames)]
    if not args.overwrite:
        for path in paths:
            if os.path.lexists(path):
                raise UsageError("output exists; use -w/--overwrite to replace it", path)
    return paths


def run(args, progress: Progress) -> dict:
    from ..pipeline import read_input
    from ..render.camera import CameraSpecError, parse_camera, turntable
    from ..render.output import write_image, write_png
    from ..render.scene import auto_camera, gaussians, render_asset, sheet, sheet_camera

    t0 = time.perf_counter()
    width, height = _size(args.size)
    background = _background(args.background)
    if args.turntable is not None and not 1 <= args.turntable <= 3600:
        raise UsageError("--turntable N needs 1 <= N <= 3600")
    if args.sheet and args.turntable:
        raise UsageError("--sheet and --turntable cannot be combined")
    if not 0.0 < args.fov < 180.0:
        raise UsageError("--fov must be between 0 and 180 degrees")
    frames = args.turntable or 1
    paths = _outputs(args, frames)
    if not os.path.exists(args.asset):
        raise FormatError("file not found", args.asset)
    progress.stage("reading")
    try:
        asset = read_input(args.asset)  # USD in a child process
    except GsverseError as exc:
        raise (exc if exc.path else exc.with_path(args.asset)) from None
    except OSError as exc:
        raise FormatError(exc.strerror or str(exc), args.asset) from None
    if asset.splat_count() == 0:
        raise FormatError("holds no splats", args.asset)
    poses, pose_name = _poses(args, asset)
    g = gaussians(asset, poses)
    # a sheet shows rest and posed side by side: one camera that frames both
    cam = sheet_camera(asset, poses, width, height, fov=args.fov) if args.sheet \
        else auto_camera(g, width, height, fov=args.fov)
    if args.camera:
        try:
            cam = parse_camera(args.camera, width=width, height=height, default=cam)
        except CameraSpecError as exc:
            raise UsageError(f"--camera: {exc}") from None
    if args.sheet:
        progress.stage("rendering sheet")
        pixels = sheet(asset, poses, cam, background=background or (0.0, 0.0, 0.0),
                       progress=progress)
        write_png(pixels, paths[0])
    else:
        cams = turntable(cam, frames) if frames > 1 else [cam]
        progress.stage("rendering")
        for k, (c, path) in enumerate(zip(cams, paths)):
            write_image(render_asset(g, c), path, background)
            progress.update(k + 1, frames)
    progress.close()
    return {"asset": args.asset, "outputs": paths, "pose": pose_name, "splats": int(len(g.means)),
            "width": width * (3 if args.sheet else 1), "height": height,
            "camera": {"eye": list(cam.eye), "target": list(cam.target), "fov": cam.fov,
                       "near": cam.near, "far": cam.far},
            "seconds": round(time.perf_counter() - t0, 3)}


def main(argv: list[str] | None = None) -> int:
    args = parse_args(build_parser(), argv)
    progress = Progress(enabled=None if not (args.quiet or args.json) else False)

    def work() -> int:
        summary = run(args, progress)
        if args.json:
            print(json.dumps(summary, indent=2))
        elif not args.quiet:
            outputs = summary["outputs"]
            print(f"{', '.join(outputs[:3])}{' ...' if len(outputs) > 3 else ''}: "
                  f"{summary['splats']} splats, {summary['pose']}, {summary['seconds']:.2f} s")
        return 0

    return run_command(PROG, args.asset, progress, work, quiet=args.quiet,
                       json_errors=args.json)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
