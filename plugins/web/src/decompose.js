// Symmetric 3x3 eigen-decomposition by cyclic Jacobi, and the conversions between a
// covariance and a rotation + scale pair. This is the JavaScript mirror of the GLSL
// decomposition used by the GPU remap:
//
//   1. normalize: A' = A / s with s = max |A_ij| (s = 0: zero scales, identity rotation), so
//      that float32 shaders neither overflow nor underflow for scales of 1e-6..1e6;
//   2. cyclic Jacobi, a fixed number of sweeps (JACOBI_SWEEPS) over the pairs (0,1), (0,2),
//      (1,2); each rotation annihilates A'_pq with the stable formula
//      θ = (a_qq − a_pp) / (2 a_pq), t = sign(θ) / (|θ| + √(θ² + 1)), c = 1/√(t² + 1), s = t c;
//      a pair whose off-diagonal entry is exactly zero is skipped (no division by zero);
//   3. eigenvalues λ_j = s · A'_jj, scales √max(λ_j, 0); the eigenvector matrix V (columns) is
//      made right-handed (the third column negated when det V < 0);
//   4. quaternion of V by the largest-diagonal (Shepperd) branch, w ≥ 0.
//
// Stability: Jacobi rotations are orthogonal, so V stays orthonormal to rounding whatever the
// input (repeated eigenvalues need no special case: any basis of the eigenspace is correct);
// the eigenvalues are accurate to about u·‖A‖ (u the unit roundoff): eigenvalues much smaller
// than the largest have absolute, not relative, accuracy, which is what the covariance needs.
// Six sweeps converge quadratically to full double precision for 3x3 matrices; the shader
// uses the same count in float32.

/** Number of cyclic Jacobi sweeps (shared with the shader). */
export const JACOBI_SWEEPS = 6;

/**
 * Cyclic Jacobi on a symmetric 3x3 matrix, in place and without allocation.
 * @param {Float64Array} a  the matrix, row-major; on return its diagonal holds the eigenvalues
 * @param {Float64Array} v  receives V, row-major, eigenvector j in column j, det V = +1
 */
export function jacobi3(a, v) {
    v.fill(0);
    v[0] = 1; v[4] = 1; v[8] = 1;
    let scale = 0;
    for (let i = 0; i < 9; ++i) scale = Math.max(scale, Math.abs(a[i]));
    if (!(scale > 0) || !Number.isFinite(scale)) {
        const z = Number.isFinite(scale) ? 0 : NaN;
        a.fill(0);
        a[0] = z; a[4] = z; a[8] = z;
        return;
    }
    for (let i = 0; i < 9; ++i) a[i] /= scale;
    for (let sweep = 0; sweep < JACOBI_SWEEPS; ++sweep) {
        for (let p = 0; p < 2; ++p) {
            for (let q = p + 1; q < 3; ++q) {
                const apq = a[3 * p + q];
                if (apq === 0) continue;
                const theta = (a[3 * q + q] - a[3 * p + p]) / (2 * apq);
                const t = (theta >= 0 ? 1 : -1) / (Math.abs(theta) + Math.sqrt(theta * theta + 1));
                const cs = 1 / Math.sqrt(t * t + 1);
                const sn = t * cs;
                for (let k = 0; k < 3; ++k) {           // A <- A J
                    const akp = a[3 * k + p], akq = a[3 * k + q];
                    a[3 * k + p] = cs * akp - sn * akq;
                    a[3 * k + q] = sn * akp + cs * akq;
                }
                for (let k = 0; k < 3; ++k) {           // A <- J^T A
                    const apk = a[3 * p + k], aqk = a[3 * q + k];
                    a[3 * p + k] = cs * apk - sn * aqk;
                    a[3 * q + k] = sn * apk + cs * aqk;
                }
                a[3 * p + q] = 0;                       // annihilated exactly
                a[3 * q + p] = 0;
                for (let k = 0; k < 3; ++k) {           // V <- V J
                    const vkp = v[3 * k + p], vkq = v[3 * k + q];
                    v[3 * k + p] = cs * vkp - sn * vkq;
                    v[3 * k + q] = sn * vkp + cs * vkq;
                }
            }
        }
    }
    const det = v[0] * (v[4] * v[8] - v[5] * v[7]) - v[1] * (v[3] * v[8] - v[5] * v[6]) + v[2] * (v[3] * v[7] - v[4] * v[6]);
    if (det < 0) { v[2] = -v[2]; v[5] = -v[5]; v[8] = -v[8]; }
    a[0] *= scale; a[4] *= scale; a[8] *= scale;
}

/**
 * @param {ArrayLike<number>} c  cov6
 * @param {number} o
 * @param {Float64Array} a  receives the full symmetric matrix, row-major
 */
function unpack6(c, o, a) {
    a[0] = c[o]; a[1] = c[o + 1]; a[2] = c[o + 2];
    a[3] = c[o + 1]; a[4] = c[o + 3]; a[5] = c[o + 4];
    a[6] = c[o + 2]; a[7] = c[o + 4]; a[8] = c[o + 5];
}

/**
 * Eigen-decomposition of a symmetric 3x3 matrix given as cov6 = (xx, xy, xz, yy, yz, zz).
 * @param {ArrayLike<number>} c  six numbers
 * @param {number} [o]  offset into c
 * @returns {{values: [number, number, number], vectors: Float64Array}} vectors: V row-major,
 *   eigenvector j in column j, det V = +1
 */
export function eigenSymmetric3(c, o = 0) {
    const a = new Float64Array(9);
    const v = new Float64Array(9);
    unpack6(c, o, a);
    jacobi3(a, v);
    return { values: [a[0], a[4], a[8]], vectors: v };
}

/**
 * Unit quaternion (x, y, z, w), w ≥ 0, of a rotation matrix (row-major), by the branch of the
 * largest of 4w², 4x², 4y², 4z² (Shepperd), written to out[oo..oo+3].
 * @param {ArrayLike<number>} m  nine numbers, row-major
 * @param {number} o
 * @param {Float32Array|Float64Array|number[]} out
 * @param {number} oo
 */
export function matrixToQuatInto(m, o, out, oo) {
    const m0 = m[o], m1 = m[o + 1], m2 = m[o + 2], m3 = m[o + 3], m4 = m[o + 4], m5 = m[o + 5];
    const m6 = m[o + 6], m7 = m[o + 7], m8 = m[o + 8];
    const tr = m0 + m4 + m8;
    const c0 = 1 + 2 * m0 - tr, c1 = 1 + 2 * m4 - tr, c2 = 1 + 2 * m8 - tr, c3 = 1 + tr;
    let k = 0, best = c0;
    if (c1 > best) { k = 1; best = c1; }
    if (c2 > best) { k = 2; best = c2; }
    if (c3 > best) { k = 3; best = c3; }
    const s = 2 * Math.sqrt(best > 0 ? best : 0);
    let x, y, z, w;
    if (!(s > 0)) { x = 0; y = 0; z = 0; w = 1; }
    else if (k === 3) { x = (m7 - m5) / s; y = (m2 - m6) / s; z = (m3 - m1) / s; w = s / 4; }
    else if (k === 0) { x = s / 4; y = (m1 + m3) / s; z = (m2 + m6) / s; w = (m7 - m5) / s; }
    else if (k === 1) { x = (m1 + m3) / s; y = s / 4; z = (m5 + m7) / s; w = (m2 - m6) / s; }
    else { x = (m2 + m6) / s; y = (m5 + m7) / s; z = s / 4; w = (m3 - m1) / s; }
    let len = Math.sqrt(x * x + y * y + z * z + w * w);
    if (w < 0) len = -len;
    out[oo] = x / len; out[oo + 1] = y / len; out[oo + 2] = z / len; out[oo + 3] = w / len;
}

/**
 * Unit quaternion (x, y, z, w), w ≥ 0, of a rotation matrix (row-major) (see matrixToQuatInto).
 * @param {ArrayLike<number>} m  nine numbers, row-major
 * @param {number} [o]
 * @returns {[number, number, number, number]}
 */
export function matrixToQuat(m, o = 0) {
    /** @type {[number, number, number, number]} */
    const q = [0, 0, 0, 1];
    matrixToQuatInto(m, o, q, 0);
    return q;
}

/**
 * Rotation matrix (row-major) of a quaternion (x, y, z, w), normalized first; a zero
 * quaternion gives the identity.
 * @param {ArrayLike<number>} q
 * @param {number} [o]
 * @param {Float64Array|number[]} [out]
 * @returns {Float64Array|number[]}
 */
export function quatToMatrix(q, o = 0, out = new Float64Array(9)) {
    const len = Math.sqrt(q[o] * q[o] + q[o + 1] * q[o + 1] + q[o + 2] * q[o + 2] + q[o + 3] * q[o + 3]);
    let x = 0, y = 0, z = 0, w = 1;
    if (len > 0) { x = q[o] / len; y = q[o + 1] / len; z = q[o + 2] / len; w = q[o + 3] / len; }
    out[0] = 1 - 2 * (y * y + z * z); out[1] = 2 * (x * y - w * z); out[2] = 2 * (x * z + w * y);
    out[3] = 2 * (x * y + w * z); out[4] = 1 - 2 * (x * x + z * z); out[5] = 2 * (y * z - w * x);
    out[6] = 2 * (x * z - w * y); out[7] = 2 * (y * z + w * x); out[8] = 1 - 2 * (x * x + y * y);
    return out;
}

const SCRATCH_A = new Float64Array(9);
const SCRATCH_V = new Float64Array(9);

/**
 * Rotation + scale of a covariance without allocation: any pair with R diag(s)² Rᵀ = Σ.
 * @param {ArrayLike<number>} cov6  xx, xy, xz, yy, yz, zz
 * @param {number} o
 * @param {Float32Array|Float64Array|number[]} rotation  receives x, y, z, w at ro
 * @param {number} ro
 * @param {Float32Array|Float64Array|number[]} scale  receives the linear scales at so
 * @param {number} so
 */
export function covToRotationScaleInto(cov6, o, rotation, ro, scale, so) {
    unpack6(cov6, o, SCRATCH_A);
    jacobi3(SCRATCH_A, SCRATCH_V);
    matrixToQuatInto(SCRATCH_V, 0, rotation, ro);
    scale[so] = Math.sqrt(Math.max(SCRATCH_A[0], 0));
    scale[so + 1] = Math.sqrt(Math.max(SCRATCH_A[4], 0));
    scale[so + 2] = Math.sqrt(Math.max(SCRATCH_A[8], 0));
}

/**
 * Rotation + scale of a covariance: any pair with R diag(s)² Rᵀ = Σ.
 * @param {ArrayLike<number>} cov6  xx, xy, xz, yy, yz, zz
 * @param {number} [o]
 * @returns {{rotation: [number, number, number, number], scale: [number, number, number]}}
 */
export function covToRotationScale(cov6, o = 0) {
    /** @type {[number, number, number, number]} */
    const rotation = [0, 0, 0, 1];
    /** @type {[number, number, number]} */
    const scale = [0, 0, 0];
    covToRotationScaleInto(cov6, o, rotation, 0, scale, 0);
    return { rotation, scale };
}

/**
 * Covariance R diag(s)² Rᵀ of a rotation (x, y, z, w) and linear scales.
 * @param {ArrayLike<number>} q
 * @param {ArrayLike<number>} s
 * @param {number} [qo]
 * @param {number} [so]
 * @returns {[number, number, number, number, number, number]}  xx, xy, xz, yy, yz, zz
 */
export function rotationScaleToCov(q, s, qo = 0, so = 0) {
    const r = quatToMatrix(q, qo);
    const m = new Float64Array(9);
    for (let i = 0; i < 3; ++i) for (let j = 0; j < 3; ++j) m[3 * i + j] = r[3 * i + j] * s[so + j];
    /** @param {number} i @param {number} j */
    const dot = (i, j) => m[3 * i] * m[3 * j] + m[3 * i + 1] * m[3 * j + 1] + m[3 * i + 2] * m[3 * j + 2];
    return [dot(0, 0), dot(0, 1), dot(0, 2), dot(1, 1), dot(1, 2), dot(2, 2)];
}
