"""Pinhole cameras for the reference renderer: look-at cameras, automatic framing, turntables.

Convention: world space is the asset's (glTF, +Y up, metres). The camera looks from ``eye`` at
``target``; camera space has x to the right, y *down* and z forward (depth), so a point at
camera coordinates (x, y, z) lands on pixel ``(fx x / z + cx, fy y / z + cy)`` with pixel
*centres* at half-integers (pixel (i, j) covers [i, i+1) × [j, j+1)). ``fov`` is the vertical
field of view in degrees (as in glTF and PlayCanvas); the horizontal one follows from the aspect
ratio of square pixels.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

__all__ = ["Camera", "look_at", "frame_bounds", "turntable", "parse_camera", "CameraSpecError"]


#: The largest |coordinate| of a ``--camera`` eye, target or up (metres): squared lengths stay
#: far from float64 overflow (about 1e154; NumPy warned of it on stderr), and a camera farther
#: than this sees any float32 asset as less than a pixel.
MAX_CAMERA_COORDINATE = 1e12


class CameraSpecError(ValueError):
    """A ``--camera`` specification that cannot be parsed."""


@dataclass(frozen=True)
class Camera:
    """A perspective pinhole camera.

    ``eye``, ``target``, ``up``: world positions and up direction; ``fov``: vertical field of
    view (degrees); ``width``/``height``: image size in pixels; ``near``/``far``: Gaussians whose
    mean has a camera depth outside (near, far) are not drawn."""

    eye: tuple[float, float, float]
    target: tuple[float, float, float]
    fov: float = 40.0
    width: int = 512
    height: int = 512
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    near: float = 0.01
    far: float = 1000.0

    def rotation(self) -> np.ndarray:
        """World → camera rotation (3, 3): rows are the camera's right, down and forward axes."""
        eye = np.asarray(self.eye, np.float64)
        fwd = np.asarray(self.target, np.float64) - eye
        n = np.linalg.norm(fwd)
        if not n > 0:
            raise CameraSpecError("camera eye and target coincide")
        fwd /= n
        up = np.asarray(self.up, np.float64)
        right = np.cross(fwd, up)
        if float(np.linalg.norm(right)) < 1e-9 * max(float(np.linalg.norm(up)), 1e-30):
            # looking along up: pick any perpendicular up
            alt = np.array([0.0, 0.0, 1.0]) if abs(fwd[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
            right = np.cross(fwd, alt)
        right /= np.linalg.norm(right)
        down = np.cross(fwd, right)
        return np.stack([right, down, fwd])

    @property
    def focal(self) -> tuple[float, float]:
        """(fx, fy) in pixels."""
        f = 0.5 * self.height / math.tan(math.radians(self.fov) / 2.0)
        return f, f

    @property
    def center(self) -> tuple[float, float]:
        return 0.5 * self.width, 0.5 * self.height

    @property
    def tan_half_fov(self) -> tuple[float, float]:
        """tan of half the horizontal and vertical fields of view."""
        ty = math.tan(math.radians(self.fov) / 2.0)
        return ty * self.width / self.height, ty

    def with_size(self, width: int, height: int) -> "Camera":
        return replace(self, width=int(width), height=int(height))

    def project_points(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates (N, 2) and depths (N,) of world ``points`` (N, 3)."""
        cam = (np.asarray(points, np.float64) - np.asarray(self.eye, np.float64)) @ self.rotation().T
        z = cam[:, 2]
        fx, fy = self.focal
        cx, cy = self.center
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = np.stack([fx * cam[:, 0] / z + cx, fy * cam[:, 1] / z + cy], axis=1)
        return uv, z


def look_at(eye, target, *, fov: float = 40.0, width: int = 512, height: int = 512,
            up=(0.0, 1.0, 0.0), near: float | None = None, far: float | None = None) -> Camera:
    """A camera at ``eye`` looking at ``target``; near/far default to 1/1000 and 100× the distance."""
    d = float(np.linalg.norm(np.asarray(target, float) - np.asarray(eye, float)))
    return Camera(tuple(map(float, eye)), tuple(map(float, target)), float(fov), int(width),  # type: ignore[arg-type]
                  int(height), tuple(map(float, up)), near if near is not None else max(d * 1e-3, 1e-6),  # type: ignore[arg-type]
                  far if far is not None else max(d * 100.0, 1.0))


def frame_bounds(lo, hi, *, fov: float = 40.0, width: int = 512, height: int = 512,
                 azimuth: float = 30.0, elevation: float = 20.0, margin: float = 1.1) -> Camera:
    """A camera that frames the box [lo, hi]: it looks at the box centre from the direction
    (``azimuth`` about +Y from +Z, ``elevation`` above the horizon) at the distance where the
    box's bounding sphere (times ``margin``) fills the narrower field of view."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    centre = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-6) * margin
    ty = math.tan(math.radians(fov) / 2.0)
    half = math.atan(min(ty, ty * width / height))
    dist = radius / math.sin(half)
    az, el = math.radians(azimuth), math.radians(elevation)
    direction = np.array([math.sin(az) * math.cos(el), math.sin(el), math.cos(az) * math.cos(el)])
    return look_at(centre + dist * direction, centre, fov=fov, width=width, height=height,
                   near=max(dist - 2 * radius, dist * 1e-3), far=dist + 2 * radius)


def turntable(camera: Camera, frames: int) -> list[Camera]:
    """``frames`` cameras on the circle about the vertical (+Y) axis through the target that
    passes through ``camera.eye``, evenly spaced, starting at ``camera``."""
    eye = np.asarray(camera.eye, np.float64)
    target = np.asarray(camera.target, np.float64)
    rel = eye - target
    out = []
    for k in range(frames):
        a = 2.0 * math.pi * k / frames
        c, s = math.cos(a), math.sin(a)
        r = np.array([c * rel[0] + s * rel[2], rel[1], -s * rel[0] + c * rel[2]])
        p = target + r
        out.append(replace(camera, eye=(float(p[0]), float(p[1]), float(p[2]))))
    return out


def _vec(text: str, key: str) -> tuple[float, float, float]:
    try:
        parts = [float(p) for p in text.split(",")]
    except ValueError:
        raise CameraSpecError(f"{key}={text!r}: expected three comma-separated numbers") from None
    if len(parts) != 3 or not all(math.isfinite(p) for p in parts):
        raise CameraSpecError(f"{key}={text!r}: expected three finite comma-separated numbers")
    if max(abs(p) for p in parts) > MAX_CAMERA_COORDINATE:
        raise CameraSpecError(f"{key}={text!r}: coordinates must lie within "
                              f"±{MAX_CAMERA_COORDINATE:g}")
    return parts[0], parts[1], parts[2]


def parse_camera(spec: str, *, width: int, height: int, default: Camera | None = None) -> Camera:
    """Parse ``eye=x,y,z target=x,y,z [fov=deg] [up=x,y,z] [near=n] [far=f]`` (spaces or
    semicolons between fields). Missing ``eye``/``target`` come from ``default`` (the automatic
    framing) when given."""
    fields: dict[str, str] = {}
    for token in spec.replace(";", " ").split():
        if "=" not in token:
            raise CameraSpecError(f"camera field {token!r}: expected key=value")
        key, value = token.split("=", 1)
        if key not in ("eye", "target", "fov", "up", "near", "far"):
            raise CameraSpecError(f"unknown camera field {key!r} (eye, target, fov, up, near, far)")
        fields[key] = value
    if default is None and not {"eye", "target"} <= fields.keys():
        raise CameraSpecError("a camera needs eye=x,y,z and target=x,y,z")
    eye = _vec(fields["eye"], "eye") if "eye" in fields else default.eye  # type: ignore[union-attr]
    target = _vec(fields["target"], "target") if "target" in fields else default.target  # type: ignore[union-attr]
    fov = default.fov if default is not None else 40.0
    if "fov" in fields:
        try:
            fov = float(fields["fov"])
        except ValueError:
            raise CameraSpecError(f"fov={fields['fov']!r} is not a number") from None
        if not 0.0 < fov < 180.0:
            raise CameraSpecError(f"fov={fov:g} must be between 0 and 180 degrees")
    up = _vec(fields["up"], "up") if "up" in fields else (0.0, 1.0, 0.0)
    near = far = None
    for key in ("near", "far"):
        if key in fields:
            try:
                v = float(fields[key])
            except ValueError:
                raise CameraSpecError(f"{key}={fields[key]!r} is not a number") from None
            if not (v > 0 and math.isfinite(v)):
                raise CameraSpecError(f"{key}={fields[key]} must be positive")
            near, far = (v, far) if key == "near" else (near, v)
    if np.allclose(eye, target):
        raise CameraSpecError("camera eye and target coincide")
    cam = look_at(eye, target, fov=fov, width=width, height=height, up=up, near=near, far=far)
    if cam.near >= cam.far:
        raise CameraSpecError(f"near ({cam.near:g}) must be less than far ({cam.far:g})")
    return cam
