// CPU remap of anchored splats (spec/README.md §Remap: the local profile, §Remap: the games
// profile), in binary64 arithmetic with float32 outputs. No dependencies: typed arrays only.
//
// Per frame: per-face quantities once per face (edges relative to v0, the current frame where
// needed, k, m, A), then per splat the mean and covariance.

import { EPS_DEGENERATE, GAMES_EPS, computeRest, perp, triangleFrame } from './rest.js';
import { covToRotationScaleInto, matrixToQuatInto, quatToMatrix } from './decompose.js';

/** @typedef {import('./types.js').AnchoredPrimitive} AnchoredPrimitive */
/** @typedef {import('./types.js').RestQuantities} RestQuantities */
/** @typedef {import('./types.js').RemapOutput} RemapOutput */
/** @typedef {import('./types.js').RotationScaleOutput} RotationScaleOutput */

// Layout of the per-face record of the local profile (binary64):
// o(3) e1(3) e2(3) m(3) A(9, row-major) R(9, row-major) k(1)
const L_O = 0, L_E1 = 3, L_E2 = 6, L_M = 9, L_A = 12, L_R = 21, L_K = 30, L_STRIDE = 31;
// games: o(3) e1(3) e2(3) R(9) base(3)
const G_O = 0, G_E1 = 3, G_E2 = 6, G_R = 9, G_BASE = 18, G_STRIDE = 21;

/**
 * Current per-face quantities of the `local` profile (spec §Remap: the local profile).
 * Faces regular at rest: k = √(a_c/a_r), m = (e1 × e2)/(√a_c √a_r) (0 when a_c = 0),
 * A = [E_c C_r⁻¹ | m]. Faces degenerate at rest: k = 1, m = n_c, A = R_c.
 * @param {AnchoredPrimitive} prim
 * @param {RestQuantities} rest
 * @param {ArrayLike<number>} vertices  (3V) current anchor vertices, splat-local space
 * @returns {Float64Array}  L_STRIDE numbers per face
 */
export function localFaces(prim, rest, vertices) {
    const idx = prim.anchorMesh.indices;
    const F = prim.anchorMesh.faceCount;
    const out = new Float64Array(F * L_STRIDE);
    const v = vertices;
    for (let f = 0; f < F; ++f) {
        const b = f * L_STRIDE;
        const i0 = 3 * idx[3 * f], i1 = 3 * idx[3 * f + 1], i2 = 3 * idx[3 * f + 2];
        const x0 = v[i0], y0 = v[i0 + 1], z0 = v[i0 + 2];
        const e1x = v[i1] - x0, e1y = v[i1 + 1] - y0, e1z = v[i1 + 2] - z0;
        const e2x = v[i2] - x0, e2y = v[i2 + 1] - y0, e2z = v[i2 + 2] - z0;
        out[b + L_O] = x0; out[b + L_O + 1] = y0; out[b + L_O + 2] = z0;
        out[b + L_E1] = e1x; out[b + L_E1 + 1] = e1y; out[b + L_E1 + 2] = e1z;
        out[b + L_E2] = e2x; out[b + L_E2 + 1] = e2y; out[b + L_E2 + 2] = e2z;
        const fr = triangleFrame(e1x, e1y, e1z, e2x, e2y, e2z, out, b + L_R);
        if (rest.regular[f]) {
            const rootC = Math.sqrt(fr.a);
            const inv = rest.invSqrtArea[f];
            out[b + L_K] = rootC * inv;
            const mx = rootC > 0 ? (fr.cx / rootC) * inv : 0;
            const my = rootC > 0 ? (fr.cy / rootC) * inv : 0;
            const mz = rootC > 0 ? (fr.cz / rootC) * inv : 0;
            out[b + L_M] = mx; out[b + L_M + 1] = my; out[b + L_M + 2] = mz;
            const p = rest.cinv[3 * f], q = rest.cinv[3 * f + 1], r = rest.cinv[3 * f + 2];
            // A = [E_c C_r^-1 | m], C_r^-1 = [[p, q], [0, r]]
            const e1 = [e1x, e1y, e1z], e2 = [e2x, e2y, e2z], m = [mx, my, mz];
            for (let i = 0; i < 3; ++i) {
                out[b + L_A + 3 * i] = e1[i] * p;
                out[b + L_A + 3 * i + 1] = e1[i] * q + e2[i] * r;
                out[b + L_A + 3 * i + 2] = m[i];
            }
        } else {
            out[b + L_K] = 1;
            for (let i = 0; i < 3; ++i) out[b + L_M + i] = out[b + L_R + 3 * i + 2];
            for (let i = 0; i < 9; ++i) out[b + L_A + i] = out[b + L_R + i];
        }
    }
    return out;
}

/**
 * The games frame R = [n | b1 | b2] (row-major into r[o..]) and base scales (into base[bo..])
 * of a triangle given by its edges (spec §Remap: the games profile), everything relative to v0.
 * @param {number} e1x @param {number} e1y @param {number} e1z
 * @param {number} e2x @param {number} e2y @param {number} e2z
 * @param {Float64Array} r @param {number} o
 * @param {Float64Array} base @param {number} bo
 */
export function gamesFrame(e1x, e1y, e1z, e2x, e2y, e2z, r, o, base, bo) {
    const gx = (e1x + e2x) / 3, gy = (e1y + e2y) / 3, gz = (e1z + e2z) / 3;
    const ux = e1x - gx, uy = e1y - gy, uz = e1z - gz;
    const wx = e2x - gx, wy = e2y - gy, wz = e2z - gz;
    const e3x = e2x - e1x, e3y = e2y - e1y, e3z = e2z - e1z;
    const cx = e1y * e2z - e1z * e2y, cy = e1z * e2x - e1x * e2z, cz = e1x * e2y - e1y * e2x;
    const a = Math.sqrt(cx * cx + cy * cy + cz * cz);
    const s1 = e1x * e1x + e1y * e1y + e1z * e1z;
    const s2 = e2x * e2x + e2y * e2y + e2z * e2z;
    const s3 = e3x * e3x + e3y * e3y + e3z * e3z;
    let longest2 = s1 > s2 ? s1 : s2;
    if (s3 > longest2) longest2 = s3;
    const tol = EPS_DEGENERATE * Math.sqrt(longest2);
    const lu = Math.sqrt(ux * ux + uy * uy + uz * uz);
    /** @type {number[]} */ let n;
    /** @type {number[]} */ let b1;
    /** @type {number[]} */ let b2;
    /** @param {number[]} p @param {number[]} q */
    const cross = (p, q) => [p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0]];
    if (a > EPS_DEGENERATE * longest2) {
        b1 = [ux / lu, uy / lu, uz / lu];
        n = [cx / a, cy / a, cz / a];
        b2 = cross(n, b1);
    } else if (lu > tol) {
        // degenerate: b2 from w by Gram-Schmidt against b1
        b1 = [ux / lu, uy / lu, uz / lu];
        const wb = wx * b1[0] + wy * b1[1] + wz * b1[2];
        const rx = wx - wb * b1[0], ry = wy - wb * b1[1], rz = wz - wb * b1[2];
        const lr = Math.sqrt(rx * rx + ry * ry + rz * rz);
        b2 = lr > tol ? [rx / lr, ry / lr, rz / lr] : perp(b1[0], b1[1], b1[2]);
        n = cross(b1, b2);
    } else if (longest2 > 0) {
        // v1 at the centroid: the splat lies along w
        const lw = Math.sqrt(wx * wx + wy * wy + wz * wz);
        b2 = [wx / lw, wy / lw, wz / lw];
        b1 = perp(b2[0], b2[1], b2[2]);
        n = cross(b1, b2);
    } else {
        n = [0, 0, 1]; b1 = [1, 0, 0]; b2 = [0, 1, 0];
    }
    base[bo] = GAMES_EPS;
    base[bo + 1] = (lu + GAMES_EPS) / 2;
    base[bo + 2] = (wx * b2[0] + wy * b2[1] + wz * b2[2]) / 2;
    for (let i = 0; i < 3; ++i) {
        r[o + 3 * i] = n[i]; r[o + 3 * i + 1] = b1[i]; r[o + 3 * i + 2] = b2[i];
    }
}

/**
 * Current per-face quantities of the `games` profile.
 * @param {AnchoredPrimitive} prim
 * @param {ArrayLike<number>} vertices
 * @returns {Float64Array}  G_STRIDE numbers per face
 */
export function gamesFaces(prim, vertices) {
    const idx = prim.anchorMesh.indices;
    const F = prim.anchorMesh.faceCount;
    const out = new Float64Array(F * G_STRIDE);
    const v = vertices;
    for (let f = 0; f < F; ++f) {
        const b = f * G_STRIDE;
        const i0 = 3 * idx[3 * f], i1 = 3 * idx[3 * f + 1], i2 = 3 * idx[3 * f + 2];
        const x0 = v[i0], y0 = v[i0 + 1], z0 = v[i0 + 2];
        const e1x = v[i1] - x0, e1y = v[i1 + 1] - y0, e1z = v[i1 + 2] - z0;
        const e2x = v[i2] - x0, e2y = v[i2 + 1] - y0, e2z = v[i2 + 2] - z0;
        out[b + G_O] = x0; out[b + G_O + 1] = y0; out[b + G_O + 2] = z0;
        out[b + G_E1] = e1x; out[b + G_E1 + 1] = e1y; out[b + G_E1 + 2] = e1z;
        out[b + G_E2] = e2x; out[b + G_E2 + 1] = e2y; out[b + G_E2 + 2] = e2z;
        gamesFrame(e1x, e1y, e1z, e2x, e2y, e2z, out, b + G_R, out, b + G_BASE);
    }
    return out;
}

/**
 * @param {AnchoredPrimitive} prim
 * @param {ArrayLike<number>} vertices
 */
function checkVertices(prim, vertices) {
    if (!vertices || vertices.length !== 3 * prim.anchorMesh.vertexCount) {
        throw new RangeError(`expected ${3 * prim.anchorMesh.vertexCount} vertex coordinates (${prim.anchorMesh.vertexCount} anchor vertices), got ${vertices ? vertices.length : 0}`);
    }
}

/**
 * Visit every splat with its mean (written to means) and the factor M of its covariance
 * Σ = M Mᵀ (row-major, binary64).
 * @param {AnchoredPrimitive} prim
 * @param {RestQuantities|null|undefined} rest
 * @param {ArrayLike<number>} vertices
 * @param {Float32Array} means
 * @param {(i: number, m: Float64Array, face: Float64Array, fb: number, rl: Float64Array) => void} visit
 */
function forEachSplat(prim, rest, vertices, means, visit) {
    checkVertices(prim, vertices);
    const N = prim.count;
    const face = prim.faceIndex;
    const bary = prim.barycentrics;
    const m = new Float64Array(9);
    const rl = new Float64Array(9);
    if (prim.profile === 'games') {
        const rho = /** @type {Float32Array} */ (prim.rho);
        const faces = gamesFaces(prim, vertices);
        for (let i = 0; i < N; ++i) {
            const b = face[i] * G_STRIDE;
            const a1 = bary[2 * i], a2 = bary[2 * i + 1];
            for (let j = 0; j < 3; ++j) means[3 * i + j] = faces[b + G_O + j] + (a1 * faces[b + G_E1 + j] + a2 * faces[b + G_E2 + j]);
            for (let c = 0; c < 3; ++c) {
                const s = rho[i] * faces[b + G_BASE + c];
                const sc = (s > 0 ? s : 0) + GAMES_EPS;
                for (let r = 0; r < 3; ++r) m[3 * r + c] = faces[b + G_R + 3 * r + c] * sc;
            }
            visit(i, m, faces, b, rl);
        }
        return;
    }
    const rq = rest || computeRest(prim);
    const faces = localFaces(prim, rq, vertices);
    const d = /** @type {Float32Array} */ (prim.normalOffset);
    const q = /** @type {Float32Array} */ (prim.localRotation);
    const s = /** @type {Float32Array} */ (prim.localScale);
    const rigid = prim.deformation === 'rigid';
    const l = new Float64Array(9);
    for (let i = 0; i < N; ++i) {
        const b = face[i] * L_STRIDE;
        const b1 = bary[2 * i], b2 = bary[2 * i + 1], di = d[i];
        for (let j = 0; j < 3; ++j) {
            const rel = b1 * faces[b + L_E1 + j] + b2 * faces[b + L_E2 + j] + di * faces[b + L_M + j];
            means[3 * i + j] = faces[b + L_O + j] + rel;
        }
        quatToMatrix(q, 4 * i, rl);
        for (let r = 0; r < 3; ++r) for (let c = 0; c < 3; ++c) l[3 * r + c] = rl[3 * r + c] * s[3 * i + c];
        const off = rigid ? L_R : L_A;
        const k = rigid ? faces[b + L_K] : 1;
        for (let r = 0; r < 3; ++r) {
            const a0 = faces[b + off + 3 * r] * k, a1 = faces[b + off + 3 * r + 1] * k, a2 = faces[b + off + 3 * r + 2] * k;
            for (let c = 0; c < 3; ++c) m[3 * r + c] = a0 * l[c] + a1 * l[3 + c] + a2 * l[6 + c];
        }
        visit(i, m, faces, b, rl);
    }
}

/**
 * Means only, for ordering splats by their deformed positions every frame (a renderer's depth
 * sort): per face v0, e1, e2 and the scaled normal m once, then per splat
 * v0 + (b1 e1 + b2 e2 + d m) (`local`) or v0 + (α1 e1 + α2 e2) (`games`), the same arithmetic
 * as the full remap, without covariances. `order` (optional) permutes the output rows:
 * row r receives file splat order[r] (a renderer's own splat order).
 * @param {AnchoredPrimitive} prim
 * @param {RestQuantities|null|undefined} rest  from computeRest(prim) (computed when null; unused by games)
 * @param {ArrayLike<number>} vertices  (3V) current anchor vertices, splat-local space
 * @param {Float32Array} [out]  (3N) receives the means
 * @param {ArrayLike<number>|null} [order]  row r <- file splat order[r]
 * @returns {Float32Array}
 */
export function remapMeansInto(prim, rest, vertices, out = new Float32Array(3 * prim.count), order = null) {
    checkVertices(prim, vertices);
    const idx = prim.anchorMesh.indices;
    const F = prim.anchorMesh.faceCount;
    const N = prim.count;
    const games = prim.profile === 'games';
    const rq = games ? null : (rest || computeRest(prim));
    const v = vertices;
    // per face: v0 (3), e1 (3), e2 (3), m (3)
    const faces = new Float64Array(12 * F);
    const frame = new Float64Array(9);
    for (let f = 0; f < F; ++f) {
        const b = 12 * f;
        const i0 = 3 * idx[3 * f], i1 = 3 * idx[3 * f + 1], i2 = 3 * idx[3 * f + 2];
        const x0 = v[i0], y0 = v[i0 + 1], z0 = v[i0 + 2];
        const e1x = v[i1] - x0, e1y = v[i1 + 1] - y0, e1z = v[i1 + 2] - z0;
        const e2x = v[i2] - x0, e2y = v[i2 + 1] - y0, e2z = v[i2 + 2] - z0;
        faces[b] = x0; faces[b + 1] = y0; faces[b + 2] = z0;
        faces[b + 3] = e1x; faces[b + 4] = e1y; faces[b + 5] = e1z;
        faces[b + 6] = e2x; faces[b + 7] = e2y; faces[b + 8] = e2z;
        if (games || !rq) continue;
        if (rq.regular[f]) {
            const cx = e1y * e2z - e1z * e2y, cy = e1z * e2x - e1x * e2z, cz = e1x * e2y - e1y * e2x;
            const rootC = Math.sqrt(Math.sqrt(cx * cx + cy * cy + cz * cz));
            const k = rootC > 0 ? rq.invSqrtArea[f] / rootC : 0;
            faces[b + 9] = cx * k; faces[b + 10] = cy * k; faces[b + 11] = cz * k;
        } else {
            triangleFrame(e1x, e1y, e1z, e2x, e2y, e2z, frame, 0);
            faces[b + 9] = frame[2]; faces[b + 10] = frame[5]; faces[b + 11] = frame[8];
        }
    }
    const face = prim.faceIndex;
    const bary = prim.barycentrics;
    const d = games ? null : /** @type {Float32Array} */ (prim.normalOffset);
    for (let r = 0; r < N; ++r) {
        const i = order ? order[r] : r;
        const b = 12 * face[i];
        const b1 = bary[2 * i], b2 = bary[2 * i + 1], di = d ? d[i] : 0;
        out[3 * r] = faces[b] + (b1 * faces[b + 3] + b2 * faces[b + 6] + di * faces[b + 9]);
        out[3 * r + 1] = faces[b + 1] + (b1 * faces[b + 4] + b2 * faces[b + 7] + di * faces[b + 10]);
        out[3 * r + 2] = faces[b + 2] + (b1 * faces[b + 5] + b2 * faces[b + 8] + di * faces[b + 11]);
    }
    return out;
}

/**
 * @param {Float64Array} m  row-major 3x3
 * @param {Float64Array|Float32Array} cov
 * @param {number} o
 */
function outer(m, cov, o) {
    cov[o] = m[0] * m[0] + m[1] * m[1] + m[2] * m[2];
    cov[o + 1] = m[0] * m[3] + m[1] * m[4] + m[2] * m[5];
    cov[o + 2] = m[0] * m[6] + m[1] * m[7] + m[2] * m[8];
    cov[o + 3] = m[3] * m[3] + m[4] * m[4] + m[5] * m[5];
    cov[o + 4] = m[3] * m[6] + m[4] * m[7] + m[5] * m[8];
    cov[o + 5] = m[6] * m[6] + m[7] * m[7] + m[8] * m[8];
}

/**
 * CPU remap of every splat onto current anchor vertices (Float32Array 3V, splat-local space).
 * @param {AnchoredPrimitive} prim
 * @param {RestQuantities|null|undefined} rest  from computeRest(prim) (computed when null; unused by games)
 * @param {ArrayLike<number>} vertices
 * @param {{means?: Float32Array, cov?: Float32Array}} [out]  preallocated outputs
 * @returns {RemapOutput}
 */
export function remapCpu(prim, rest, vertices, out = {}) {
    const means = out.means || new Float32Array(3 * prim.count);
    const cov = out.cov || new Float32Array(6 * prim.count);
    forEachSplat(prim, rest, vertices, means, (i, m) => outer(m, cov, 6 * i));
    return { means, cov };
}

/**
 * CPU remap returning rotation (unit x, y, z, w) + linear scales per splat, a pair with
 * R diag(s)² Rᵀ = Σ: rigid: R_c R_l and k s_l; games: [n | b1 | b2] and the games scales;
 * affine: the eigen-decomposition of Σ (decompose.js).
 * @param {AnchoredPrimitive} prim
 * @param {RestQuantities|null|undefined} rest  from computeRest(prim) (computed when null)
 * @param {ArrayLike<number>} vertices
 * @param {{means?: Float32Array, rotations?: Float32Array, scales?: Float32Array}} [out]
 * @returns {RotationScaleOutput}
 */
export function remapCpuRotationScale(prim, rest, vertices, out = {}) {
    const N = prim.count;
    const means = out.means || new Float32Array(3 * N);
    const rotations = out.rotations || new Float32Array(4 * N);
    const scales = out.scales || new Float32Array(3 * N);
    const cov = new Float64Array(6);
    const rot = new Float64Array(9);
    const games = prim.profile === 'games';
    const rigid = prim.deformation === 'rigid';
    forEachSplat(prim, rest, vertices, means, (i, m, faces, b, rl) => {
        if (games || rigid) {
            // the factor M = R' diag(scale): R' = [n | b1 | b2] (games) or R_c R_l (rigid)
            const off = games ? G_R : L_R;
            if (games) {
                for (let j = 0; j < 9; ++j) rot[j] = faces[b + off + j];
            } else {
                for (let r = 0; r < 3; ++r) {
                    for (let c = 0; c < 3; ++c) {
                        rot[3 * r + c] = faces[b + off + 3 * r] * rl[c] + faces[b + off + 3 * r + 1] * rl[3 + c] + faces[b + off + 3 * r + 2] * rl[6 + c];
                    }
                }
            }
            matrixToQuatInto(rot, 0, rotations, 4 * i);
            for (let j = 0; j < 3; ++j) scales[3 * i + j] = Math.sqrt(m[j] * m[j] + m[3 + j] * m[3 + j] + m[6 + j] * m[6 + j]);
        } else {
            outer(m, cov, 0);
            covToRotationScaleInto(cov, 0, rotations, 4 * i, scales, 3 * i);
        }
    });
    return { means, rotations, scales };
}
