// glTF 2.0 keyframe sampling (§3.11 Animations) and the small 4x4 matrix kernels of the anchor
// animation (animation.js), on typed arrays, allocating nothing per call.
//
// STEP takes the previous key; LINEAR interpolates linearly (rotations: spherical linear
// interpolation along the shortest arc); CUBICSPLINE is the cubic Hermite spline of glTF (in-
// tangent, value, out-tangent per key, tangents scaled by the key interval). Rotations are
// normalized after every mode (a zero quaternion becomes the identity). Times before the first
// key or after the last clamp to the first or last value. Matrices are column-major.

export const STEP = 0;
export const LINEAR = 1;
export const CUBICSPLINE = 2;

/** Interpolation modes by their glTF names. */
/** @type {{[name: string]: number}} */
export const INTERPOLATIONS = { STEP, LINEAR, CUBICSPLINE };

/**
 * One animation sampler bound to its target.
 * @typedef {object} Keyframes
 * @property {Float64Array} times   (K) key times, non-decreasing
 * @property {Float64Array} values  (K·n), or (3K·n) for CUBICSPLINE: in-tangent, value, out-tangent per key
 * @property {number} width         n, numbers per value (3 translation/scale, 4 rotation, targets for weights)
 * @property {number} mode          STEP, LINEAR or CUBICSPLINE
 * @property {boolean} rotation     a unit quaternion (slerp, normalized)
 */

/**
 * The key interval [k, k + 1] holding `t`, with times[0] < t < times[K − 1]: the largest k
 * with times[k] <= t (so times[k + 1] > t even with repeated key times).
 * @param {Float64Array} times
 * @param {number} t
 */
function interval(times, t) {
    let lo = 0;
    let hi = times.length - 1;
    while (hi - lo > 1) {
        const mid = (lo + hi) >>> 1;
        if (times[mid] <= t) lo = mid; else hi = mid;
    }
    return lo;
}

/**
 * Write the value of `kf` at time `t` (s) to dst[o .. o + width).
 * @param {Keyframes} kf
 * @param {number} t
 * @param {Float64Array} dst
 * @param {number} o
 */
export function sampleKeyframes(kf, t, dst, o) {
    const { times, values, width: n, mode } = kf;
    const K = times.length;
    const cubic = mode === CUBICSPLINE;
    const stride = cubic ? 3 * n : n;   // numbers per key
    const at = cubic ? n : 0;           // where the value lies within a key
    if (t <= times[0] || t >= times[K - 1]) {
        const src = (t <= times[0] ? 0 : (K - 1) * stride) + at;
        for (let c = 0; c < n; ++c) dst[o + c] = values[src + c];
    } else {
        const k = interval(times, t);
        const dt = times[k + 1] - times[k];
        const s = (t - times[k]) / dt;
        const a = k * stride + at;
        const b = a + stride;
        if (mode === STEP) {
            for (let c = 0; c < n; ++c) dst[o + c] = values[a + c];
        } else if (cubic) {
            const s2 = s * s;
            const s3 = s2 * s;
            const h00 = 2 * s3 - 3 * s2 + 1;
            const h10 = (s3 - 2 * s2 + s) * dt;
            const h01 = -2 * s3 + 3 * s2;
            const h11 = (s3 - s2) * dt;
            // value k, out-tangent of k, value k + 1, in-tangent of k + 1
            for (let c = 0; c < n; ++c) {
                dst[o + c] = h00 * values[a + c] + h10 * values[a + n + c] + h01 * values[b + c] + h11 * values[b - n + c];
            }
        } else if (kf.rotation) {
            slerp(values, a, values, b, s, dst, o);
        } else {
            for (let c = 0; c < n; ++c) dst[o + c] = (1 - s) * values[a + c] + s * values[b + c];
        }
    }
    if (kf.rotation) normalizeQuaternion(dst, o);
}

/**
 * Spherical linear interpolation of quaternions (x, y, z, w) along the shortest arc; nearly
 * parallel ones (dot > 0.9995) are interpolated linearly and normalized.
 * @param {Float64Array} qa
 * @param {number} a
 * @param {Float64Array} qb
 * @param {number} b
 * @param {number} s
 * @param {Float64Array} dst
 * @param {number} o
 */
export function slerp(qa, a, qb, b, s, dst, o) {
    let dot = qa[a] * qb[b] + qa[a + 1] * qb[b + 1] + qa[a + 2] * qb[b + 2] + qa[a + 3] * qb[b + 3];
    const sign = dot < 0 ? -1 : 1;
    dot *= sign;
    if (dot > 0.9995) {
        for (let c = 0; c < 4; ++c) dst[o + c] = qa[a + c] + s * (sign * qb[b + c] - qa[a + c]);
        normalizeQuaternion(dst, o);
        return;
    }
    const theta = Math.acos(dot);
    const sin = Math.sin(theta);
    const wa = Math.sin((1 - s) * theta);
    const wb = Math.sin(s * theta) * sign;
    for (let c = 0; c < 4; ++c) dst[o + c] = (wa * qa[a + c] + wb * qb[b + c]) / sin;
}

/**
 * Normalize the quaternion at q[o .. o + 4) in place; a zero one becomes the identity.
 * @param {Float64Array} q
 * @param {number} o
 */
export function normalizeQuaternion(q, o) {
    const len = Math.sqrt(q[o] * q[o] + q[o + 1] * q[o + 1] + q[o + 2] * q[o + 2] + q[o + 3] * q[o + 3]);
    if (len > 0) {
        q[o] /= len; q[o + 1] /= len; q[o + 2] /= len; q[o + 3] /= len;
    } else {
        q[o] = 0; q[o + 1] = 0; q[o + 2] = 0; q[o + 3] = 1;
    }
}

/**
 * m[mo .. mo + 16) = T · R · S from a translation, a unit quaternion (x, y, z, w) and a scale.
 * @param {Float64Array} t
 * @param {Float64Array} r
 * @param {Float64Array} s
 * @param {number} i  the node slot: t[3i], r[4i], s[3i]
 * @param {Float64Array} m
 * @param {number} mo
 */
export function composeTrs(t, r, s, i, m, mo) {
    const x = r[4 * i], y = r[4 * i + 1], z = r[4 * i + 2], w = r[4 * i + 3];
    const sx = s[3 * i], sy = s[3 * i + 1], sz = s[3 * i + 2];
    m[mo] = (1 - 2 * (y * y + z * z)) * sx;
    m[mo + 1] = 2 * (x * y + w * z) * sx;
    m[mo + 2] = 2 * (x * z - w * y) * sx;
    m[mo + 3] = 0;
    m[mo + 4] = 2 * (x * y - w * z) * sy;
    m[mo + 5] = (1 - 2 * (x * x + z * z)) * sy;
    m[mo + 6] = 2 * (y * z + w * x) * sy;
    m[mo + 7] = 0;
    m[mo + 8] = 2 * (x * z + w * y) * sz;
    m[mo + 9] = 2 * (y * z - w * x) * sz;
    m[mo + 10] = (1 - 2 * (x * x + y * y)) * sz;
    m[mo + 11] = 0;
    m[mo + 12] = t[3 * i];
    m[mo + 13] = t[3 * i + 1];
    m[mo + 14] = t[3 * i + 2];
    m[mo + 15] = 1;
}

/**
 * out[oo .. oo + 16) = a[ao ..] · b[bo ..] (4x4, column-major); `out` must not overlap a or b.
 * @param {Float64Array} a
 * @param {number} ao
 * @param {Float64Array} b
 * @param {number} bo
 * @param {Float64Array} out
 * @param {number} oo
 */
export function multiplyInto(a, ao, b, bo, out, oo) {
    for (let c = 0; c < 4; ++c) {
        const b0 = b[bo + 4 * c], b1 = b[bo + 4 * c + 1], b2 = b[bo + 4 * c + 2], b3 = b[bo + 4 * c + 3];
        for (let r = 0; r < 4; ++r) {
            out[oo + 4 * c + r] = a[ao + r] * b0 + a[ao + 4 + r] * b1 + a[ao + 8 + r] * b2 + a[ao + 12 + r] * b3;
        }
    }
}

/**
 * out = m⁻¹ (4x4, column-major, cofactors).
 * @param {Float64Array} m
 * @param {number} mo
 * @param {Float64Array} out
 * @returns {boolean} false when m is singular or not finite (out is then unspecified)
 */
export function invertInto(m, mo, out) {
    const a00 = m[mo], a01 = m[mo + 1], a02 = m[mo + 2], a03 = m[mo + 3];
    const a10 = m[mo + 4], a11 = m[mo + 5], a12 = m[mo + 6], a13 = m[mo + 7];
    const a20 = m[mo + 8], a21 = m[mo + 9], a22 = m[mo + 10], a23 = m[mo + 11];
    const a30 = m[mo + 12], a31 = m[mo + 13], a32 = m[mo + 14], a33 = m[mo + 15];
    const b00 = a00 * a11 - a01 * a10, b01 = a00 * a12 - a02 * a10, b02 = a00 * a13 - a03 * a10;
    const b03 = a01 * a12 - a02 * a11, b04 = a01 * a13 - a03 * a11, b05 = a02 * a13 - a03 * a12;
    const b06 = a20 * a31 - a21 * a30, b07 = a20 * a32 - a22 * a30, b08 = a20 * a33 - a23 * a30;
    const b09 = a21 * a32 - a22 * a31, b10 = a21 * a33 - a23 * a31, b11 = a22 * a33 - a23 * a32;
    const det = b00 * b11 - b01 * b10 + b02 * b09 + b03 * b08 - b04 * b07 + b05 * b06;
    if (!(det !== 0 && Number.isFinite(det))) return false;
    const d = 1 / det;
    out[0] = (a11 * b11 - a12 * b10 + a13 * b09) * d;
    out[1] = (a02 * b10 - a01 * b11 - a03 * b09) * d;
    out[2] = (a31 * b05 - a32 * b04 + a33 * b03) * d;
    out[3] = (a22 * b04 - a21 * b05 - a23 * b03) * d;
    out[4] = (a12 * b08 - a10 * b11 - a13 * b07) * d;
    out[5] = (a00 * b11 - a02 * b08 + a03 * b07) * d;
    out[6] = (a32 * b02 - a30 * b05 - a33 * b01) * d;
    out[7] = (a20 * b05 - a22 * b02 + a23 * b01) * d;
    out[8] = (a10 * b10 - a11 * b08 + a13 * b06) * d;
    out[9] = (a01 * b08 - a00 * b10 - a03 * b06) * d;
    out[10] = (a30 * b04 - a31 * b02 + a33 * b00) * d;
    out[11] = (a21 * b02 - a20 * b04 - a23 * b00) * d;
    out[12] = (a11 * b07 - a10 * b09 - a12 * b06) * d;
    out[13] = (a00 * b09 - a01 * b07 + a02 * b06) * d;
    out[14] = (a31 * b01 - a30 * b03 - a32 * b00) * d;
    out[15] = (a20 * b03 - a21 * b01 + a22 * b00) * d;
    return true;
}
