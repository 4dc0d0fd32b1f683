"""The editing flags of ``gsverse-convert`` (:mod:`gsverse_format.edit`): their parser group,
help and the ``ConvertOptions`` fields they fill."""
from __future__ import annotations

import argparse
from collections.abc import Callable

from ..edit import EDIT_FLAGS, parse_numbers
from ..errors import UsageError

__all__ = ["EDIT_OPTIONS", "EDIT_EPILOG", "add_edit_flags"]

#: The ``ConvertOptions`` fields the flags fill (``args.<field>``).
EDIT_OPTIONS = (*EDIT_FLAGS, "drop_nonfinite", "edit_frame")

EDIT_EPILOG = """\
editing splats while converting:
  after reading and before binding, in the input file's frame (the coordinates it holds: a
  3DGS PLY's +Y-down frame, a GLB's +Y-up one), before the frame change; with --edit-frame
  output in the output's frame, after it (glTF's +Y up; the frame splat-transform's actions
  and the mesh-fit warning's numbers use: on a 3DGS PLY its -t X,Y,Z and -r A,B,C are
  --translate=-X,-Y,Z and --rotate=-A,-B,C in the input frame). In order:
  --drop-nonfinite, then --scale, --rotate, --translate (in that order, whatever the order
  of the flags; --mesh-scale, --mesh-rotate, --mesh-translate the same for every --mesh),
  then --crop-box / --crop-sphere (on the moved means), then --min-opacity. --rotate X,Y,Z
  is Euler degrees as splat-transform and PlayCanvas take them: R = Rz(Z) Ry(Y) Rx(X), a
  turn about X first, then Y, then Z (fixed axes). Scales are uniform (> 0). Write a first
  negative number with '=': --translate=-1,0,0. The summary ("edits", --json "edits") counts
  the splats each step dropped; none left is an error (exit 1, nothing written).
  gsverse-convert splats.ply out.glb --mesh body.obj --mesh-scale 100
  gsverse-convert splats.ply out.glb --plain --drop-nonfinite --crop-sphere 0,0,0,2
"""


def _numbers(flag: str, count: int) -> Callable[[str], tuple[float, ...]]:
    def parse(text: str) -> tuple[float, ...]:
        try:
            return parse_numbers(flag, text, count)
        except UsageError as exc:
            raise argparse.ArgumentTypeError(exc.cause.removeprefix(flag + " ")
                                             .removeprefix(flag + ": ")) from None
    return parse


def _one(flag: str) -> Callable[[str], float]:
    numbers = _numbers(flag, 1)
    return lambda text: numbers(text)[0]


def add_edit_flags(p: argparse.ArgumentParser) -> None:
    """The "editing" group of ``gsverse-convert``'s parser."""
    g = p.add_argument_group("editing (in the input file's frame; see 'editing splats while converting' below)")
    g.add_argument("--translate", type=_numbers("--translate", 3), metavar="X,Y,Z",
                   help="move the splats by X,Y,Z (after --scale and --rotate)")
    g.add_argument("--rotate", type=_numbers("--rotate", 3), metavar="X,Y,Z",
                   help="rotate the splats about the origin by Euler angles in degrees: "
                        "about X, then Y, then Z (fixed axes); SH rotated exactly")
    g.add_argument("--scale", type=_one("--scale"), metavar="S",
                   help="scale the splats uniformly about the origin by S > 0 (means and "
                        "splat sizes)")
    g.add_argument("--mesh-translate", type=_numbers("--mesh-translate", 3), metavar="X,Y,Z",
                   help="move every --mesh by X,Y,Z (after --mesh-scale, --mesh-rotate)")
    g.add_argument("--mesh-rotate", type=_numbers("--mesh-rotate", 3), metavar="X,Y,Z",
                   help="rotate every --mesh like --rotate")
    g.add_argument("--mesh-scale", type=_one("--mesh-scale"), metavar="S",
                   help="scale every --mesh uniformly by S > 0 (e.g. 100 for a mesh in metres "
                        "beside splats in centimetres)")
    g.add_argument("--edit-frame", choices=("input", "output"), default="input",
                   help="the frame the edits act in: the input file's (default; a 3DGS PLY's "
                        "+Y down) or the output's (glTF's +Y up, as in splat-transform)")
    g.add_argument("--drop-nonfinite", action="store_true",
                   help="drop splats with NaN or infinite values (or a zero rotation "
                        "quaternion) instead of refusing the file (3DGS and TRELLIS PLY "
                        "inputs; values any source passes on)")
    g.add_argument("--crop-box", type=_numbers("--crop-box", 6),
                   metavar="XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX",
                   help="keep only splats whose centre is inside this box (bounds included)")
    g.add_argument("--crop-sphere", type=_numbers("--crop-sphere", 4), metavar="X,Y,Z,R",
                   help="keep only splats whose centre is within R of X,Y,Z")
    g.add_argument("--min-opacity", type=_one("--min-opacity"), metavar="A",
                   help="drop splats whose opacity (0..1, after the sigmoid) is below A")
