// decompose.js: covariance -> rotation + scale round trips (Σ = R diag(s)² Rᵀ), repeated
// eigenvalues, near-singular matrices and scales from 1e-6 to 1e6.
import test from 'node:test';
import assert from 'node:assert/strict';

import {
    covToRotationScale, eigenSymmetric3, matrixToQuat, quatToMatrix, rotationScaleToCov,
} from '../src/decompose.js';

/** @param {number} seed */
function rng(seed) {
    let s = seed >>> 0;
    return () => {
        s = (s * 1664525 + 1013904223) >>> 0;
        return s / 4294967296;
    };
}

/** @param {() => number} r @returns {number[]} */
function randomQuat(r) {
    const q = [r() - 0.5, r() - 0.5, r() - 0.5, r() - 0.5];
    const n = Math.hypot(...q);
    return q.map((x) => x / n);
}

/** Frobenius norm of the difference of two cov6 (off-diagonals counted twice).
 * @param {ArrayLike<number>} a @param {ArrayLike<number>} b */
function frob(a, b) {
    const d = [0, 1, 2, 3, 4, 5].map((i) => a[i] - b[i]);
    return Math.sqrt(d[0] ** 2 + d[3] ** 2 + d[5] ** 2 + 2 * (d[1] ** 2 + d[2] ** 2 + d[4] ** 2));
}

/** @param {ArrayLike<number>} a */
const norm6 = (a) => frob(a, [0, 0, 0, 0, 0, 0]);

/**
 * Decompose Σ and check the round trip, a unit quaternion and non-negative scales.
 * @param {number[]} cov
 * @param {number} rtol relative to ‖Σ‖_F
 * @param {string} what
 */
function roundTrip(cov, rtol, what) {
    const { rotation, scale } = covToRotationScale(cov);
    assert.ok(Math.abs(Math.hypot(...rotation) - 1) < 1e-12, `${what}: unit quaternion`);
    assert.ok(rotation[3] >= 0, `${what}: w >= 0`);
    for (const s of scale) assert.ok(s >= 0 && Number.isFinite(s), `${what}: scale ${s}`);
    const back = rotationScaleToCov(rotation, scale);
    const err = frob(back, cov);
    assert.ok(err <= rtol * norm6(cov), `${what}: ‖ΔΣ‖ = ${err} > ${rtol} ‖Σ‖ = ${rtol * norm6(cov)}`);
    return { rotation, scale };
}

test('random covariances round-trip: Σ = R diag(s)² Rᵀ', () => {
    const r = rng(1);
    for (let k = 0; k < 500; ++k) {
        const s = [r() + 0.01, r() + 0.01, r() + 0.01];
        roundTrip(rotationScaleToCov(randomQuat(r), s), 1e-13, `case ${k}`);
    }
});

test('recovered scales equal the true ones (up to order)', () => {
    const r = rng(2);
    for (let k = 0; k < 100; ++k) {
        const s = [0.1 + r(), 0.1 + r(), 0.1 + r()];
        const { scale } = roundTrip(rotationScaleToCov(randomQuat(r), s), 1e-13, `case ${k}`);
        const a = [...scale].sort(), b = [...s].sort();
        for (let i = 0; i < 3; ++i) assert.ok(Math.abs(a[i] - b[i]) < 1e-12, `scale ${a[i]} vs ${b[i]}`);
    }
});

test('repeated eigenvalues (two equal, three equal) and diagonal input', () => {
    const r = rng(3);
    for (let k = 0; k < 100; ++k) {
        roundTrip(rotationScaleToCov(randomQuat(r), [0.5, 0.5, 0.2]), 1e-13, `double ${k}`);
        roundTrip(rotationScaleToCov(randomQuat(r), [0.3, 0.3, 0.3]), 1e-13, `triple ${k}`);
    }
    const d = roundTrip([4, 0, 0, 9, 0, 1], 0, 'diagonal');
    assert.deepEqual(d.rotation, [0, 0, 0, 1]);
    assert.deepEqual(d.scale, [2, 3, 1]);
});

test('near-singular and singular covariances (flat and needle splats)', () => {
    const r = rng(4);
    for (let k = 0; k < 100; ++k) {
        roundTrip(rotationScaleToCov(randomQuat(r), [1, 0.5, 1e-9]), 1e-13, `flat ${k}`);
        roundTrip(rotationScaleToCov(randomQuat(r), [1, 0, 0]), 1e-13, `needle ${k}`);
        roundTrip(rotationScaleToCov(randomQuat(r), [1, 1, 0]), 1e-13, `disc ${k}`);
    }
    const zero = covToRotationScale([0, 0, 0, 0, 0, 0]);
    assert.deepEqual(zero.scale, [0, 0, 0]);
    assert.deepEqual(zero.rotation, [0, 0, 0, 1]);
});

test('scales from 1e-6 to 1e6, within one splat and across splats', () => {
    const r = rng(5);
    for (const e of [-6, -3, 0, 3, 6]) {
        for (let k = 0; k < 50; ++k) {
            const c = 10 ** e;
            roundTrip(rotationScaleToCov(randomQuat(r), [c * (0.5 + r()), c * (0.5 + r()), c * (0.5 + r())]), 1e-13, `scale 1e${e} ${k}`);
        }
    }
    for (let k = 0; k < 100; ++k) {
        // 1e-6 and 1e6 in one splat: the small axis is below the rounding of the large one
        const s = [1e6, 1e-6, 1];
        const { scale } = roundTrip(rotationScaleToCov(randomQuat(r), s), 1e-13, `mixed ${k}`);
        const sorted = [...scale].sort((a, b) => a - b);
        assert.ok(Math.abs(sorted[2] - 1e6) < 1e-6, `largest ${sorted[2]}`);
        assert.ok(Math.abs(sorted[1] - 1) < 1e-3, `middle ${sorted[1]}`);
    }
});

test('eigenvectors form a right-handed orthonormal basis', () => {
    const r = rng(6);
    for (let k = 0; k < 200; ++k) {
        const cov = rotationScaleToCov(randomQuat(r), [r(), r(), r() * 1e-4]);
        const { values, vectors: v } = eigenSymmetric3(cov);
        const det = v[0] * (v[4] * v[8] - v[5] * v[7]) - v[1] * (v[3] * v[8] - v[5] * v[6]) + v[2] * (v[3] * v[7] - v[4] * v[6]);
        assert.ok(Math.abs(det - 1) < 1e-12, `det ${det}`);
        for (let i = 0; i < 3; ++i) {
            for (let j = 0; j < 3; ++j) {
                const dot = v[i] * v[j] + v[3 + i] * v[3 + j] + v[6 + i] * v[6 + j];
                assert.ok(Math.abs(dot - (i === j ? 1 : 0)) < 1e-12, `VᵀV[${i}][${j}] = ${dot}`);
            }
        }
        for (const x of values) assert.ok(Number.isFinite(x));
    }
});

test('quaternion <-> matrix round trip covers every Shepperd branch', () => {
    const quats = [[0, 0, 0, 1], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0.5, 0.5, 0.5, 0.5], [0.7071067811865476, 0, 0, -0.7071067811865476]];
    const r = rng(7);
    for (let k = 0; k < 200; ++k) quats.push(randomQuat(r));
    for (const q of quats) {
        const back = matrixToQuat(quatToMatrix(q));
        const sign = q[3] < 0 || (q[3] === 0 && back[3] === 0 && Math.sign(back[0] || back[1] || back[2]) !== Math.sign(q[0] || q[1] || q[2])) ? -1 : 1;
        for (let i = 0; i < 4; ++i) assert.ok(Math.abs(back[i] - sign * q[i]) < 1e-12, `${q} -> ${back}`);
    }
});
