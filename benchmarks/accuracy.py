"""Accuracy of the remap against analytic deformations, and the stretch comparison with a cage.

Object
    A bumpy bar (a capsule along +Y, length 2.6, radius 0.3, with smooth radial bumps), meshed
    finely; surface splats sampled on it: area-weighted positions, normal offsets uniform in
    ±0.25 mean edge, flat splats (in-plane standard deviations 0.3–0.8 mean edge, normal 0.1 mean
    edge) with a random in-plane orientation and up to 10° of tilt.

Deformations φ (magnitude m ∈ {2, 5, 10}; t ∈ [0, 1] is the position along the bar)
    * ``stretch``: the middle half of the bar is stretched along Y, locally by up to m×
      (dy'/dy = 1 + (m − 1) sin²(π (t − ¼)/½) on t ∈ [¼, ¾], 1 elsewhere); X and Z unchanged.
    * ``twist``: rotation about Y by θ = (m π / 5)(t − ½) (m = 10: one full turn end to end).
    * ``bend``: the bar's axis bent onto a circular arc of total angle m π / 10 (m = 10: 180°).

Truth and candidate
    Truth: μ' = φ(μ), Σ' = J Σ Jᵀ with J the analytic Jacobian of φ at μ. Candidate: the remap
    of the anchors onto φ(anchor vertices), computed by
    :class:`gsverse_format.remapping.fast.FastRemapper` (the float32 path an engine runs; it
    matches the float64 reference to ~1e-7, far below every error reported here). For the
    ``games`` profile the splats are GaMeS splats of the anchor mesh itself (flat, on the
    triangles, sized like the surface splats), since GaMeS cannot represent arbitrary splats;
    their truth is φ applied to their rest pose.

Errors per splat (reported as median and 99th percentile)
    * position error relative to splat size: |μ_c − μ_t| / σ_t with σ_t = √(tr Σ_t / 3);
    * covariance error: ‖Σ_c − Σ_t‖_F / ‖Σ_t‖_F;
    * 2-Wasserstein distance between the two Gaussians, relative to σ_t:
      W₂² = |Δμ|² + tr Σ_c + tr Σ_t − 2 tr (Σ_t^½ Σ_c Σ_t^½)^½.

Axes: profile and law (games, local/affine, local/rigid); anchor-mesh resolution (decimation of
the fine mesh by ``gsverse_format.meshops.decimate``); anchor quantization (float32, float16
— which glTF cannot store; an upper bound for half-precision GPU buffers — and normalized 16-bit
integers as glTF stores them); SH degree (size only: SH pass through the remap unchanged).
Cost of each point: remap time per frame (fast path, this object), anchor bytes per splat
(anchor accessors + the anchor mesh amortized over the splats), face count.

Stretch comparison (the GS-Verse claim): at 2×, 5× and 10× stretch, the fraction of splats whose
mean is farther than τ = 0.5 % of the rest bounding-box diagonal (and than one mean edge of the
fine mesh) from the deformed surface (φ of the fine mesh), the 99th percentile of that distance,
and the splat extent (√λ_max(Σ)) relative to the longest edge of its deformed fine-mesh triangle
(99th percentile and largest), for our profiles and for a VR-GS-style cage: the splats embedded
in a coarse tetrahedral lattice (6 tetrahedra per cell) around the object, moved by barycentric
interpolation of φ at the lattice vertices and deformed by each tetrahedron's gradient F
(Σ' = F Σ Fᵀ).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from gsverse_format import quaternion as quat
from gsverse_format.binding import bind_local
from gsverse_format.model import (Anchoring, GamesAnchors, LocalAnchors, SplatAsset, SplatCloud,
                                  SplatPrimitive, TriangleMesh)
from gsverse_format.remapping.reference import remap as reference_remap
from gsverse_format.remapping.fast import FastRemapper

from .timing import measure

MAGNITUDES = (2, 5, 10)
DEFORMATIONS = ("stretch", "twist", "bend")
PROFILES = (("games", None), ("local", "affine"), ("local", "rigid"))
QUANTIZATIONS = ("float32", "float16", "norm16")
PARETO_MAGNITUDE = 5


def profile_name(profile: str, law: str | None) -> str:
    return "games" if profile == "games" else f"local/{law}"


# --------------------------------------------------------------------------- object

def bar_mesh(n_around: int, n_rows: int, *, length: float = 2.0, radius: float = 0.3) -> TriangleMesh:
    """Closed bumpy capsule along +Y: rings of ``n_around`` vertices on ``n_rows − 1`` rows
    (arclength-uniform along the profile), two pole vertices, faces oriented outward."""
    cap = np.pi * radius / 2.0
    total = 2 * cap + length
    s = total * np.arange(1, n_rows) / n_rows
    rho = np.where(s < cap, radius * np.sin(s / radius),
                   np.where(s > cap + length, radius * np.sin((total - s) / radius), radius))
    y = np.where(s < cap, -length / 2 - radius * np.cos(s / radius),
                 np.where(s > cap + length, length / 2 + radius * np.cos((total - s) / radius),
                          -length / 2 + (s - cap)))
    rows = len(s)
    theta = 2 * np.pi * (np.arange(n_around)[None, :] + 0.5 * (np.arange(rows)[:, None] % 2)) / n_around
    bump = 1.0 + 0.04 * np.sin(5 * theta) * np.sin(6 * y[:, None]) + 0.02 * np.sin(11 * theta + 3 * y[:, None])
    r = rho[:, None] * bump
    ring = np.stack([r * np.cos(theta), np.broadcast_to(y[:, None], r.shape), r * np.sin(theta)], -1)
    v = np.concatenate([ring.reshape(-1, 3), [[0, -length / 2 - radius, 0], [0, length / 2 + radius, 0]]])
    idx = np.arange(rows * n_around).reshape(rows, n_around)
    nxt = np.roll(idx, -1, axis=1)
    faces = []
    for k in range(rows - 1):
        a, b, c, d = idx[k], nxt[k], idx[k + 1], nxt[k + 1]
        if k % 2 == 0:   # row k+1 is shifted by half a step
            faces += [np.stack([a, b, c], 1), np.stack([b, d, c], 1)]
        else:
            faces += [np.stack([a, d, c], 1), np.stack([a, b, d], 1)]
    south, north = rows * n_around, rows * n_around + 1
    faces.append(np.stack([np.full(n_around, south), nxt[0], idx[0]], 1))
    faces.append(np.stack([np.full(n_around, north), idx[-1], nxt[-1]], 1))
    f = np.concatenate(faces)
    # Orient every face outward (the shape is star-shaped about its axis segment).
    tri = v[f]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    cen = tri.mean(1)
    axis = np.stack([np.zeros(len(f)), np.clip(cen[:, 1], -length / 2, length / 2), np.zeros(len(f))], 1)
    flip = np.einsum("ij,ij->i", normal, cen - axis) < 0
    f[flip] = f[flip][:, [0, 2, 1]]
    return TriangleMesh(v, f)


def mean_edge(mesh: TriangleMesh) -> float:
    tri = mesh.triangles()
    return float(np.mean(np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2)))


def face_normals(tri: np.ndarray) -> np.ndarray:
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def surface_object(mesh: TriangleMesh, n: int, seed: int = 0) -> SplatCloud:
    """Flat surface splats on ``mesh`` (see the module docstring)."""
    rng = np.random.default_rng(seed)
    tri = mesh.triangles()
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    face = rng.choice(len(tri), n, p=area / area.sum())
    b = rng.dirichlet([1, 1, 1], n)
    nrm = face_normals(tri)[face]
    h = mean_edge(mesh)
    mu = np.einsum("nk,nkx->nx", b, tri[face]) + nrm * rng.uniform(-0.25, 0.25, (n, 1)) * h
    t1 = np.cross(nrm, rng.normal(size=(n, 3)))
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(nrm, t1)
    rot = np.stack([t1, t2, nrm], axis=-1)
    tilt = rng.normal(size=(n, 3))
    tilt *= np.radians(10.0) * rng.uniform(0, 1, (n, 1)) / np.linalg.norm(tilt, axis=1, keepdims=True)
    from scipy.spatial.transform import Rotation

    rot = Rotation.from_rotvec(tilt).as_matrix() @ rot
    scales = np.column_stack([rng.uniform(0.3, 0.8, n) * h, rng.uniform(0.3, 0.8, n) * h,
                              np.full(n, 0.1 * h)])
    return SplatCloud(mu, quat.from_matrix(rot), scales, np.ones(n), np.zeros((n, 1, 3)))


def games_object(mesh: TriangleMesh, n: int, size: float, seed: int = 0) -> GamesAnchors:
    """GaMeS splats on ``mesh``: area-weighted faces, α ~ Dirichlet(1, 1, 1), ρ such that the
    in-plane scale (ρ |v1 − c| / 2) is ``size``·U(0.6, 1.6)."""
    from gsverse_format.frames import games_frames

    rng = np.random.default_rng(seed)
    tri = mesh.triangles()
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    face = rng.choice(len(tri), n, p=area / area.sum())
    _, base, _ = games_frames(tri)
    rho = size * rng.uniform(0.6, 1.6, n) / base[face, 1]
    alpha = rng.dirichlet([1, 1, 1], n)
    return GamesAnchors(face, alpha[:, 1:], rho)


# --------------------------------------------------------------------------- deformations

@dataclass
class Bar:
    y0: float
    y1: float

    @property
    def length(self) -> float:
        return self.y1 - self.y0


def _bump_integral(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """w(t) = sin²(π (t − ¼)/½) on [¼, ¾] (0 elsewhere) and its integral W(t) from 0."""
    a, w = 0.25, 0.5
    u = np.clip((t - a) / w, 0.0, 1.0)
    inside = (t > a) & (t < a + w)
    dens = np.where(inside, np.sin(np.pi * u) ** 2, 0.0)
    integ = w * (u / 2.0 - np.sin(2 * np.pi * u) / (4 * np.pi))
    return dens, integ


def deform(name: str, m: float, bar: Bar, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """φ(x) (N, 3) and its Jacobian J(x) (N, 3, 3) for deformation ``name`` of magnitude ``m``."""
    x = np.asarray(x, dtype=np.float64)
    L = bar.length
    t = (x[:, 1] - bar.y0) / L
    out = x.copy()
    jac = np.zeros((len(x), 3, 3))
    jac[:, 0, 0] = jac[:, 1, 1] = jac[:, 2, 2] = 1.0
    if name == "stretch":
        dens, integ = _bump_integral(t)
        out[:, 1] = bar.y0 + L * (t + (m - 1.0) * integ)
        jac[:, 1, 1] = 1.0 + (m - 1.0) * dens
    elif name == "twist":
        big = m * np.pi / 5.0
        th = big * (t - 0.5)
        c, s = np.cos(th), np.sin(th)
        px, pz = x[:, 0], x[:, 2]
        out[:, 0] = c * px - s * pz
        out[:, 2] = s * px + c * pz
        dth = big / L
        jac[:, 0, 0], jac[:, 0, 2], jac[:, 0, 1] = c, -s, (-s * px - c * pz) * dth
        jac[:, 2, 0], jac[:, 2, 2], jac[:, 2, 1] = s, c, (c * px - s * pz) * dth
    elif name == "bend":
        big = m * np.pi / 10.0
        radius = L / big
        phi = big * (t - 0.5)
        c, s = np.cos(phi), np.sin(phi)
        arm = radius - x[:, 0]
        yc = 0.5 * (bar.y0 + bar.y1)
        out[:, 0] = radius - arm * c
        out[:, 1] = yc + arm * s
        jac[:, 0, 0], jac[:, 1, 0] = c, -s
        jac[:, 0, 1], jac[:, 1, 1] = arm * s / radius, arm * c / radius
    elif name != "rest":
        raise ValueError(name)
    return out, jac


# --------------------------------------------------------------------------- metrics

def _sqrtm_psd(a: np.ndarray) -> np.ndarray:
    lam, vec = np.linalg.eigh(a)
    return (vec * np.sqrt(np.clip(lam, 0.0, None))[:, None, :]) @ np.swapaxes(vec, 1, 2)


def errors(mu_c, cov_c, mu_t, cov_t) -> dict[str, np.ndarray]:
    """Per-splat position/size, relative Frobenius covariance error, W₂/size."""
    size = np.sqrt(np.trace(cov_t, axis1=1, axis2=2) / 3.0)
    dmu2 = np.sum((mu_c - mu_t) ** 2, axis=1)
    st = _sqrtm_psd(cov_t)
    inner = np.linalg.eigvalsh(st @ cov_c @ st)
    bures2 = (np.trace(cov_c, axis1=1, axis2=2) + np.trace(cov_t, axis1=1, axis2=2)
              - 2.0 * np.sum(np.sqrt(np.clip(inner, 0.0, None)), axis=1))
    return {"pos": np.sqrt(dmu2) / size,
            "cov": np.linalg.norm(cov_c - cov_t, axis=(1, 2)) / np.linalg.norm(cov_t, axis=(1, 2)),
            "w2": np.sqrt(dmu2 + np.clip(bures2, 0.0, None)) / size}


def summarize(err: dict[str, np.ndarray]) -> dict[str, float]:
    out = {}
    for k, v in err.items():
        out[f"{k}_p50"] = float(np.median(v))
        out[f"{k}_p99"] = float(np.percentile(v, 99))
    return out


# --------------------------------------------------------------------------- quantization

def _f16(a):
    return np.asarray(a, np.float32).astype(np.float16).astype(np.float32)


def quantize(anchors, mode: str):
    """Anchors as a file stores them in ``mode``; returns (anchors, note)."""
    if mode == "float32":
        return anchors, ""
    if isinstance(anchors, GamesAnchors):
        if mode == "float16":
            return GamesAnchors(anchors.face_index, _f16(anchors.barycentrics), _f16(anchors.rho)), ""
        bary = np.round(anchors.barycentrics.astype(np.float64) * 65535) / 65535
        return GamesAnchors(anchors.face_index, bary, anchors.rho), ""
    if mode == "float16":
        return LocalAnchors(anchors.face_index, _f16(anchors.barycentrics), _f16(anchors.normal_offset),
                            _f16(anchors.local_rotation), anchors.local_scale, anchors.deformation), ""
    q = np.clip(np.round(quat.normalize(anchors.local_rotation) * 32767), -32767, 32767)
    q = np.maximum(q / 32767.0, -1.0)
    bary = anchors.barycentrics
    note = ""
    if np.all((bary >= 0) & (bary <= 1)):
        bary = np.round(bary.astype(np.float64) * 65535) / 65535
    else:
        note = "barycentrics stay FLOAT (some lie outside [0, 1])"
    return LocalAnchors(anchors.face_index, bary, anchors.normal_offset, q, anchors.local_scale,
                        anchors.deformation), note


def anchor_bytes(anchors, mode: str, mesh: TriangleMesh, note: str = "") -> float:
    """Anchor bytes per splat as the glTF writer stores them (float16: hypothetical 2-byte
    floats), plus the anchor mesh (float32 positions + indices) amortized over the splats."""
    n = len(anchors)
    f = mesh.face_count
    face = 1 if f <= 256 else 2 if f <= 65536 else 4
    if isinstance(anchors, GamesAnchors):
        per = face + (4 if mode != "float32" else 8) + (2 if mode == "float16" else 4)
    else:
        bary = 8 if mode == "float32" or note else 4
        per = face + bary + (2 if mode == "float16" else 4) + (16 if mode == "float32" else 8)
    index = 2 if len(mesh.vertices) < 65535 else 4
    return per + (12 * len(mesh.vertices) + index * 3 * f) / n


def glb_bytes_per_splat(splats: SplatCloud, anchoring: Anchoring | None, quant: dict | None) -> float:
    from gsverse_format.io.gltf import asset_to_gltf, gltf_to_bytes

    asset = SplatAsset([SplatPrimitive(splats, anchoring)])
    return len(gltf_to_bytes(asset_to_gltf(asset, quantize=quant))) / len(splats)


# --------------------------------------------------------------------------- cage (VR-GS style)

_KUHN = [(0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)]


class Cage:
    """Regular lattice of ``cells`` around the points, each cell split into 6 tetrahedra
    sharing its main diagonal (Kuhn); splats embedded barycentrically."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray, cell: float):
        pad = 0.05 * cell
        self.lo = lo - pad
        self.n = np.maximum(1, np.ceil((hi + pad - self.lo) / cell).astype(int))
        self.h = (hi + pad - self.lo) / self.n
        self.tets = int(6 * np.prod(self.n))

    def vertices(self) -> np.ndarray:
        g = [self.lo[k] + self.h[k] * np.arange(self.n[k] + 1) for k in range(3)]
        return np.stack(np.meshgrid(*g, indexing="ij"), -1).reshape(-1, 3)

    def embed(self, x: np.ndarray):
        """Per point: the 4 lattice-vertex ids of its tetrahedron, barycentrics, and the
        tetrahedron's rest edge matrix inverse D⁻¹ (for F = D' D⁻¹)."""
        rel = (x - self.lo) / self.h
        cell = np.clip(np.floor(rel).astype(int), 0, self.n - 1)
        u = rel - cell
        order = np.argsort(-u, axis=1, kind="stable")            # axes by decreasing coordinate
        us = np.take_along_axis(u, order, axis=1)
        lam = np.column_stack([1 - us[:, 0], us[:, 0] - us[:, 1], us[:, 1] - us[:, 2], us[:, 2]])
        corner = np.zeros((len(x), 4, 3), int)
        for k in range(1, 4):
            corner[:, k] = corner[:, k - 1]
            corner[np.arange(len(x)), k, order[:, k - 1]] += 1
        ijk = cell[:, None, :] + corner
        dims = self.n + 1
        ids = (ijk[..., 0] * dims[1] + ijk[..., 1]) * dims[2] + ijk[..., 2]
        d = (corner[:, 1:] - corner[:, :1]).astype(float) * self.h      # (N, 3 edges, 3)
        d_inv = np.linalg.inv(np.swapaxes(d, 1, 2))
        return ids, lam, d_inv

    @staticmethod
    def deform(vert_cur: np.ndarray, ids, lam, d_inv, cov: np.ndarray):
        p = vert_cur[ids]                                         # (N, 4, 3)
        mu = np.einsum("nk,nkx->nx", lam, p)
        dcur = np.swapaxes(p[:, 1:] - p[:, :1], 1, 2)             # columns = edges
        f = dcur @ d_inv
        return mu, f @ cov @ np.swapaxes(f, 1, 2)


# --------------------------------------------------------------------------- the run

def _levels(fine: TriangleMesh, count: int, notes: list[str]) -> list[TriangleMesh]:
    levels = [fine]
    try:
        from gsverse_format.meshops import decimate
    except Exception as exc:  # pragma: no cover - depends on optional pieces
        decimate = None
        notes.append(f"decimation unavailable ({exc}); coarser levels are coarser bar meshes")
    for i in range(1, count):
        target = max(64, fine.face_count // 4 ** i)
        if decimate is not None:
            levels.append(decimate(fine, target))
        else:
            k = 2 ** i
            levels.append(bar_mesh(max(8, 128 // k), max(8, 160 // k)))
    return levels


class _one_thread:
    """Context: numba runs on one thread inside (no-op without numba)."""

    def __enter__(self):
        try:
            import numba
        except Exception:
            self.numba = None
            return self
        self.numba, self.before = numba, numba.get_num_threads()
        numba.set_num_threads(1)
        return self

    def __exit__(self, *exc):
        if self.numba is not None:
            self.numba.set_num_threads(self.before)


def _local_truth(cloud: SplatCloud):
    return cloud.means.astype(np.float64), cloud.covariances()


def run(quick: bool = False, log=print) -> dict:
    """Run the accuracy study; returns a JSON-serializable dict of tables (see report.py)."""
    t_start = time.perf_counter()
    notes: list[str] = []
    n_splats = 1000 if quick else 20000
    fine = bar_mesh(32, 40) if quick else bar_mesh(128, 160)
    n_levels = 3 if quick else 5
    levels = _levels(fine, n_levels, notes)
    lo, hi = fine.vertices.min(0).astype(float), fine.vertices.max(0).astype(float)
    bar = Bar(float(lo[1]), float(hi[1]))
    diag = float(np.linalg.norm(hi - lo))
    h = mean_edge(fine)
    cloud = surface_object(fine, n_splats, seed=1)
    mu0, cov0 = _local_truth(cloud)
    log(f"accuracy: fine mesh {fine.face_count} faces, levels {[m.face_count for m in levels]}, "
        f"{n_splats} splats")

    cases = [("rest", 1)] + [(d, m) for d in DEFORMATIONS for m in MAGNITUDES]
    rows = []          # one per (profile, level, quant, deformation, magnitude)
    costs = []         # one per (profile, level, quant)
    remappers = {}
    for li, mesh in enumerate(levels):
        bound = bind_local(cloud, mesh).anchors
        games = games_object(mesh, n_splats, size=0.55 * h, seed=2 + li)
        games_ref = reference_remap(Anchoring(mesh, games))
        games_mu0, games_cov0 = games_ref.means, games_ref.covariances
        for profile, law in PROFILES:
            pname = profile_name(profile, law)
            base = games if profile == "games" else LocalAnchors(
                bound.face_index, bound.barycentrics, bound.normal_offset, bound.local_rotation,
                bound.local_scale, law)
            mu_rest, cov_rest = (games_mu0, games_cov0) if profile == "games" else (mu0, cov0)
            for qmode in QUANTIZATIONS:
                if quick and li > 0 and qmode != "float32":
                    continue        # the quick run varies quantization on the finest level only
                anchors, note = quantize(base, qmode)
                anchoring = Anchoring(mesh, anchors)
                fast = FastRemapper(anchoring)
                key = (pname, li)
                if qmode == "float32":
                    remappers[key] = fast
                for dname, m in cases:
                    mu_t, jac = deform(dname, m, bar, mu_rest)
                    cov_t = jac @ cov_rest @ np.swapaxes(jac, 1, 2)
                    cur, _ = deform(dname, m, bar, mesh.vertices)
                    out = fast.remap(cur)
                    err = errors(out.means.astype(np.float64), out.covariances(), mu_t, cov_t)
                    rows.append({"profile": pname, "level": li, "faces": mesh.face_count,
                                 "quant": qmode, "deformation": dname, "magnitude": m,
                                 **summarize(err)})
                costs.append({"profile": pname, "level": li, "faces": mesh.face_count,
                              "quant": qmode, "note": note,
                              "anchor_bytes": anchor_bytes(anchors, qmode, mesh, note)})
    # Remap time per (profile, level): the fast path on this object, on one thread (small
    # problems gain little from a second thread, and one thread is less exposed to other load).
    reps = 10 if quick else 50
    with _one_thread():
        for (pname, li), fast in remappers.items():
            cur, _ = deform("twist", 5, bar, levels[li].vertices)
            t = measure(lambda: fast.remap(cur), repeat=reps, batches=2 if quick else 3,
                        retry_contended=0 if quick else 2)
            for c in costs:
                if c["profile"] == pname and c["level"] == li:
                    c["remap_ms"] = t.median * 1e3
                    c["remap_contended"] = t.contended
                    c["backend"] = fast.backend
    log(f"accuracy: {len(rows)} error rows in {time.perf_counter() - t_start:.1f} s")

    sizes = _sh_sizes(cloud, fine, games_object(fine, n_splats, 0.55 * h, seed=2))
    stretch = _stretch_claim(cloud, fine, levels, bar, diag, quick, log)
    return {"n_splats": n_splats, "fine_faces": fine.face_count,
            "levels": [m.face_count for m in levels], "mean_edge": h, "diag": diag,
            "rows": rows, "costs": costs, "sh_sizes": sizes, "stretch": stretch,
            "notes": notes, "seconds": time.perf_counter() - t_start}


def _sh_sizes(cloud: SplatCloud, mesh: TriangleMesh, games: GamesAnchors) -> list[dict]:
    """Measured GLB bytes per splat by SH degree, profile and quantization (plain KHR too)."""
    bound = bind_local(cloud, mesh).anchors
    out = []
    quant16 = {"barycentrics": "unsigned_short", "localRotation": "short"}
    games_splats = SplatCloud(*[getattr(cloud, k) for k in ("means", "rotations", "scales",
                                                             "opacities", "sh")])
    for degree in range(4):
        k = (degree + 1) ** 2
        c = SplatCloud(cloud.means, cloud.rotations, cloud.scales, cloud.opacities,
                       np.zeros((len(cloud), k, 3), np.float32))
        g = SplatCloud(games_splats.means, games_splats.rotations, games_splats.scales,
                       games_splats.opacities, np.zeros((len(cloud), k, 3), np.float32))
        row = {"sh_degree": degree, "plain": glb_bytes_per_splat(c, None, None)}
        for name, anchors, splats in (("local", bound, c), ("games", games, g)):
            a = Anchoring(mesh, anchors)
            row[f"{name}/float32"] = glb_bytes_per_splat(splats, a, None)
            row[f"{name}/norm16"] = glb_bytes_per_splat(splats, a, quant16)
        out.append(row)
    return out


def _stretch_claim(cloud, fine, levels, bar, diag, quick, log) -> dict:
    from gsverse_format.nearest import nearest_triangles

    tau = 0.005 * diag
    h_fine = mean_edge(fine)
    mu0, cov0 = _local_truth(cloud)
    home = nearest_triangles(mu0, fine.vertices.astype(np.float64), fine.faces.astype(np.int64)).face
    lo, hi = fine.vertices.min(0).astype(float), fine.vertices.max(0).astype(float)
    methods = []
    coarse = levels[min(2, len(levels) - 1)]
    bound_f = bind_local(cloud, fine).anchors
    bound_c = bind_local(cloud, coarse).anchors
    for law in ("affine", "rigid"):
        methods.append((f"local/{law}, {fine.face_count} faces", fine,
                        LocalAnchors(bound_f.face_index, bound_f.barycentrics, bound_f.normal_offset,
                                     bound_f.local_rotation, bound_f.local_scale, law)))
    methods.append((f"local/affine, {coarse.face_count} faces", coarse,
                    LocalAnchors(bound_c.face_index, bound_c.barycentrics, bound_c.normal_offset,
                                 bound_c.local_rotation, bound_c.local_scale, "affine")))
    radius = 0.5 * (hi[0] - lo[0])
    cages = [Cage(lo, hi, radius / 2.0), Cage(lo, hi, radius / 5.0)]
    results = []
    for m in MAGNITUDES:
        cur_fine, _ = deform("stretch", m, bar, fine.vertices)
        tri_c = cur_fine[fine.faces.astype(np.intp)]
        edge = np.max(np.linalg.norm(tri_c - np.roll(tri_c, 1, axis=1), axis=2), axis=1)

        def score(name, mu, cov, faces_or_tets):
            d = nearest_triangles(mu, cur_fine, fine.faces.astype(np.int64)).distance
            lam = np.linalg.eigvalsh(cov)[:, -1]
            ext = np.sqrt(np.clip(lam, 0, None)) / edge[home]
            results.append({"method": name, "stretch": m, "elements": faces_or_tets,
                            "off_surface": float(np.mean(d > tau)),
                            "off_surface_edge": float(np.mean(d > h_fine)),
                            "dist_p99_diag": float(np.percentile(d, 99) / diag),
                            "extent_p99": float(np.percentile(ext, 99)),
                            "extent_max": float(np.max(ext))})

        mu_t, jac = deform("stretch", m, bar, mu0)
        score("truth φ(μ), J Σ Jᵀ", mu_t, jac @ cov0 @ np.swapaxes(jac, 1, 2), 0)
        for name, mesh, anchors in methods:
            cur, _ = deform("stretch", m, bar, mesh.vertices)
            out = FastRemapper(Anchoring(mesh, anchors)).remap(cur)
            score(name, out.means.astype(np.float64), out.covariances(), mesh.face_count)
        # games: GaMeS splats of the fine mesh (their own rest pose; the truth row above is for
        # the surface splats, the games splats lie on the surface at rest)
        games = games_object(fine, len(mu0), 0.55 * mean_edge(fine), seed=2)
        out = FastRemapper(Anchoring(fine, games)).remap(cur_fine)
        gface = games.face_index.astype(np.intp)
        d = nearest_triangles(out.means.astype(np.float64), cur_fine, fine.faces.astype(np.int64)).distance
        lam = np.linalg.eigvalsh(out.covariances())[:, -1]
        ext = np.sqrt(np.clip(lam, 0, None)) / edge[gface]
        results.append({"method": f"games, {fine.face_count} faces", "stretch": m,
                        "elements": fine.face_count, "off_surface": float(np.mean(d > tau)),
                        "off_surface_edge": float(np.mean(d > h_fine)),
                        "dist_p99_diag": float(np.percentile(d, 99) / diag),
                        "extent_p99": float(np.percentile(ext, 99)), "extent_max": float(np.max(ext))})
        for cage in cages:
            ids, lam_b, d_inv = cage.embed(mu0)
            cv, _ = deform("stretch", m, bar, cage.vertices())
            mu_c, cov_c = Cage.deform(cv, ids, lam_b, d_inv, cov0)
            score(f"cage (VR-GS style), {cage.tets} tets", mu_c, cov_c, cage.tets)
    log(f"stretch comparison: {len(results)} rows")
    return {"tau_diag": 0.005, "mean_edge": h_fine, "rows": results,
            "note": "extent = √λ_max(Σ) / longest edge of the splat's deformed fine-mesh triangle"}
