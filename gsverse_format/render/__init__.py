"""A CPU reference renderer of Gaussian splats (the 3DGS rasterizer's rules) for previews.

* :mod:`~gsverse_format.render.camera`: look-at cameras, automatic framing, turntables;
* :mod:`~gsverse_format.render.project_reference` (numpy) beside
  :mod:`~gsverse_format.render.project_compiled` (numba): EWA projection of each Gaussian,
  SH colour, and the tile kernels;
* :mod:`~gsverse_format.render.raster`: depth-sorted front-to-back compositing on 16×16 tiles;
* :mod:`~gsverse_format.render.scene`: asset → posed Gaussians, wireframes, before/after sheet;
* :mod:`~gsverse_format.render.output`: PNG (sRGB-encoded) and OpenEXR (linear, A, Z).

``gsverse-render`` (:mod:`gsverse_format.cli.render`) is the command line.
"""
from __future__ import annotations

from .camera import Camera, frame_bounds, look_at, parse_camera, turntable
from .project_reference import Settings
from .raster import Image, render_gaussians
from .scene import Gaussians, gaussians, pose_vertices, render_asset

__all__ = ["Camera", "frame_bounds", "look_at", "parse_camera", "turntable", "Settings", "Image",
           "render_gaussians", "Gaussians", "gaussians", "pose_vertices", "render_asset"]
