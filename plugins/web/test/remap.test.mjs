// The CPU remap against the worked examples of spec/README.md (numbers by hand), rigid-motion
// and scale invariance, the rest pose, and float input arrays.
import test from 'node:test';
import assert from 'node:assert/strict';

import { readAnchoredGlb } from '../src/anchor.js';
import { computeRest } from '../src/rest.js';
import { remapCpu, remapCpuRotationScale, remapMeansInto } from '../src/remap-cpu.js';
import { quatToMatrix, rotationScaleToCov } from '../src/decompose.js';
import { anchoredGlb } from './glb-writer.mjs';

/** @typedef {import('../src/types.js').AnchoredPrimitive} AnchoredPrimitive */

/**
 * An anchored primitive read back from a GLB written by the test writer.
 * @param {import('./glb-writer.mjs').AnchoredSpec} spec
 * @returns {AnchoredPrimitive}
 */
function prim(spec) {
    return readAnchoredGlb(anchoredGlb(spec), { name: 'test.glb' }).anchored[0];
}

/**
 * @param {ArrayLike<number>} actual
 * @param {ArrayLike<number>} expected
 * @param {number} tol  absolute tolerance
 * @param {string} [what]
 */
function close(actual, expected, tol, what = '') {
    assert.equal(actual.length, expected.length, `${what}: length`);
    for (let i = 0; i < expected.length; ++i) {
        assert.ok(Math.abs(actual[i] - expected[i]) <= tol, `${what}[${i}]: ${actual[i]} vs ${expected[i]} (tol ${tol})`);
    }
}

/** cov6 of a diagonal matrix @param {number} a @param {number} b @param {number} c */
const diag6 = (a, b, c) => [a, 0, 0, b, 0, c];

const EX1 = {
    vertices: [0, 0, 0, 2, 0, 0, 0, 1, 0],
    indices: [0, 1, 2],
    face: [0], bary: [0.25, 0.5], offset: [0.125], rotation: [0, 0, 0, 1], scale: [0.125, 0.375, 0.0625],
};
const EX1_POSE = Float32Array.from([0, 0, 0, 0, 4, 0, -1, 0, 0]);

test('worked example 1: local affine, stretch and rotation', () => {
    const p = prim({ ...EX1, profile: 'local', deformation: 'affine' });
    const out = remapCpu(p, computeRest(p), EX1_POSE);
    close(out.means, [-0.5, 1, 0.1767766953], 1e-7, 'mean');
    close(out.cov, diag6(0.140625, 0.0625, 0.0078125), 1e-8, 'cov');
    const rs = remapCpuRotationScale(p, computeRest(p), EX1_POSE);
    close(rotationScaleToCov(rs.rotations, rs.scales), diag6(0.140625, 0.0625, 0.0078125), 1e-8, 'cov of rotation+scale');
    const sorted = Array.from(rs.scales).sort((a, b) => a - b);
    close(sorted, [0.0883883476, 0.25, 0.375], 1e-7, 'scales');
});

test('worked example 1: local rigid', () => {
    const p = prim({ ...EX1, profile: 'local', deformation: 'rigid' });
    const out = remapCpu(p, computeRest(p), EX1_POSE);
    close(out.means, [-0.5, 1, 0.1767766953], 1e-7, 'mean');
    close(out.cov, diag6(0.28125, 0.03125, 0.0078125), 1e-8, 'cov');
    const rs = remapCpuRotationScale(p, null, EX1_POSE);
    close(rs.rotations, [0, 0, 0.7071067812, 0.7071067812], 1e-7, 'rotation R_c R_l');
    close(rs.scales, [0.1767766953, 0.5303300859, 0.0883883476], 1e-7, 'scales k s_l');
});

test('worked example 1: the default deformation is affine', () => {
    const p = prim({ ...EX1, profile: 'local' });
    assert.equal(p.deformation, 'affine');
    close(remapCpu(p, null, EX1_POSE).cov, diag6(0.140625, 0.0625, 0.0078125), 1e-8, 'cov');
});

test('worked example 2: local, general pose (reference values)', () => {
    const spec = { ...EX1, rotation: [0.102597833, 0.205195665, 0.307793498, 0.923380494] };
    const pose = [0.5, 0.25, 0.125, 2.25, 1, 0.5, -0.25, 1.5, 1];
    const affine = prim({ ...spec, profile: 'local', deformation: 'affine' });
    const rigid = prim({ ...spec, profile: 'local', deformation: 'rigid' });
    const a = remapCpu(affine, null, pose);
    const r = remapCpu(rigid, null, pose);
    const mean = [0.5716245404, 0.9742961090, 0.7900765932];
    close(a.means, mean, 1e-7, 'affine mean');
    close(r.means, mean, 1e-7, 'rigid mean');
    close(a.cov, [0.1504155097, -0.0800643672, -0.1319521019, 0.0710522307, 0.0785591657, 0.1271967727], 2e-7, 'affine cov');
    close(r.cov, [0.1516519468, -0.0306877600, -0.1007813439, 0.0320743478, 0.0301091211, 0.0804442972], 2e-7, 'rigid cov');
});

test('worked example 3: games, regular triangle', () => {
    const p = prim({ vertices: [0, 0, 0, 3, 0, 0, 0, 3, 0], indices: [0, 1, 2], profile: 'games', face: [0], bary: [0.3, 0.5], rho: [2] });
    const v = p.anchorMesh.vertices;
    const out = remapCpu(p, null, v);
    close(out.means, [0.9, 1.5, 0], 1e-7, 'mean');
    const rs = remapCpuRotationScale(p, null, v);
    close(rs.scales, [3e-8, 2.2360679975, 1.3416407965], 1e-7, 'scales');
    assert.ok(Math.abs(rs.scales[0] - 3e-8) < 1e-14, `normal scale ${rs.scales[0]}`);
    const R = quatToMatrix(rs.rotations);
    close(R, [0, 0.8944271910, 0.4472135955, 0, -0.4472135955, 0.8944271910, 1, 0, 0], 1e-7, 'R = [n | b1 | b2]');
    const s2 = [9e-16, 5, 1.8];
    // Σ = R diag(s²) Rᵀ with R above
    const expected = [
        0.8 * s2[1] + 0.2 * s2[2], -0.4 * s2[1] + 0.4 * s2[2], 0,
        0.2 * s2[1] + 0.8 * s2[2], 0, s2[0],
    ];
    close(out.cov, expected, 2e-6, 'cov');
});

test('worked example 4: local, a face degenerate at rest (both laws)', () => {
    const spec = {
        vertices: [0, 0, 0, 2, 0, 0, 1, 0, 0], indices: [0, 1, 2], face: [0], bary: [0.25, 0.25], offset: [0.125],
        rotation: [0, 0, 0, 1], scale: [0.125, 0.375, 0.0625],
    };
    const pose = Float32Array.from([0, 0, 0, 0, 2, 0, 0, 1, 0]);
    for (const deformation of ['affine', 'rigid']) {
        const p = prim({ ...spec, profile: 'local', deformation });
        const rest = computeRest(p);
        assert.equal(rest.regular[0], 0, 'degenerate at rest');
        const out = remapCpu(p, rest, pose);
        close(out.means, [0, 0.75, -0.125], 1e-7, `${deformation} mean`);
        close(out.cov, diag6(0.140625, 0.015625, 0.00390625), 1e-8, `${deformation} cov`);
        const rs = remapCpuRotationScale(p, rest, pose);
        close(rotationScaleToCov(rs.rotations, rs.scales), diag6(0.140625, 0.015625, 0.00390625), 1e-8, `${deformation} rotation+scale`);
        const atRest = remapCpu(p, rest, p.anchorMesh.vertices);
        close(atRest.means, [0.75, 0, 0.125], 1e-7, `${deformation} rest mean`);
        close(atRest.cov, diag6(0.015625, 0.140625, 0.00390625), 1e-8, `${deformation} rest cov`);
    }
    const rigid = remapCpuRotationScale(prim({ ...spec, profile: 'local', deformation: 'rigid' }), null, pose);
    close(rigid.rotations, [0.7071067812, 0.7071067812, 0, 0], 1e-7, 'rotation R_c');
    close(rigid.scales, [0.125, 0.375, 0.0625], 1e-8, 'scales s_l');
});

test('worked example 5: games, v1 at the midpoint of v0 v2', () => {
    const p = prim({ vertices: [0, 0, 0, 1, 0, 0, 2, 0, 0], indices: [0, 1, 2], profile: 'games', face: [0], bary: [0.3, 0.5], rho: [2] });
    const out = remapCpu(p, null, p.anchorMesh.vertices);
    close(out.means, [1.300000012, 0, 0], 1e-7, 'mean');
    close(out.cov, diag6(1.00000002, 9e-16, 4e-16), 1e-7, 'cov');
    assert.ok(Math.abs(out.cov[3] - 9e-16) < 1e-21 && Math.abs(out.cov[5] - 4e-16) < 1e-21, `tiny axes ${out.cov[3]} ${out.cov[5]}`);
    const rs = remapCpuRotationScale(p, null, p.anchorMesh.vertices);
    close(rs.scales, [3e-8, 2e-8, 1.00000001], 1e-7, 'scales');
    close(quatToMatrix(rs.rotations), [0, 0, 1, 1, 0, 0, 0, 1, 0], 1e-7, 'R = [n | b1 | b2]');
});

/** A deterministic pseudo-random generator. @param {number} seed */
function rng(seed) {
    let s = seed >>> 0;
    return () => {
        s = (s * 1664525 + 1013904223) >>> 0;
        return s / 4294967296;
    };
}

/** A small bumpy strip of triangles with splats on every face. @param {'local'|'games'} profile @param {string} [deformation] */
function randomAsset(profile, deformation) {
    const r = rng(7);
    const vertices = [];
    for (let j = 0; j < 2; ++j) for (let i = 0; i < 5; ++i) vertices.push(i, j, 0.3 * Math.sin(i + 2 * j));
    const indices = [];
    for (let i = 0; i < 4; ++i) indices.push(i, i + 1, i + 5, i + 1, i + 6, i + 5);
    const face = [], bary = [], offset = [], rotation = [], scale = [], rho = [];
    for (let f = 0; f < 8; ++f) {
        for (let k = 0; k < 3; ++k) {
            face.push(f);
            const b1 = r() * 0.6, b2 = r() * 0.4;
            bary.push(b1, b2);
            offset.push((r() - 0.5) * 0.2);
            const q = [r() - 0.5, r() - 0.5, r() - 0.5, r() - 0.5];
            const n = Math.hypot(...q);
            rotation.push(...q.map((x) => x / n));
            scale.push(0.01 + r() * 0.1, 0.01 + r() * 0.1, 0.001 + r() * 0.02);
            rho.push(0.5 + r());
        }
    }
    return prim({ vertices, indices, profile, deformation, face, bary, offset, rotation, scale, rho });
}

/** @param {number[]} m row-major 3x3 @param {ArrayLike<number>} c cov6 @param {number} o */
function rotateCov(m, c, o) {
    const S = [c[o], c[o + 1], c[o + 2], c[o + 1], c[o + 3], c[o + 4], c[o + 2], c[o + 4], c[o + 5]];
    const MS = new Array(9).fill(0);
    for (let i = 0; i < 3; ++i) for (let j = 0; j < 3; ++j) for (let k = 0; k < 3; ++k) MS[3 * i + j] += m[3 * i + k] * S[3 * k + j];
    const out = new Array(9).fill(0);
    for (let i = 0; i < 3; ++i) for (let j = 0; j < 3; ++j) for (let k = 0; k < 3; ++k) out[3 * i + j] += MS[3 * i + k] * m[3 * j + k];
    return [out[0], out[1], out[2], out[4], out[5], out[8]];
}

for (const [profile, deformation] of [['local', 'affine'], ['local', 'rigid'], ['games', undefined]]) {
    const label = deformation ? `${profile} ${deformation}` : profile;
    test(`rigid motion of the mesh moves every splat rigidly (${label})`, () => {
        const p = randomAsset(/** @type {'local'|'games'} */ (profile), deformation);
        const rest = computeRest(p);
        // a deformed pose, then that pose rotated and translated
        const base = Array.from(p.anchorMesh.vertices, (x, i) => x * (i % 3 === 0 ? 1.3 : 1) + (i % 3 === 2 ? 0.1 * Math.cos(i) : 0));
        const Q = Array.from(quatToMatrix([0.3, -0.5, 0.2, 0.7]));
        const t = [10, -4, 2.5];
        const moved = new Float64Array(base.length);
        for (let v = 0; v < base.length; v += 3) {
            for (let i = 0; i < 3; ++i) moved[v + i] = Q[3 * i] * base[v] + Q[3 * i + 1] * base[v + 1] + Q[3 * i + 2] * base[v + 2] + t[i];
        }
        const a = remapCpu(p, rest, base);
        const b = remapCpu(p, rest, moved);
        for (let s = 0; s < p.count; ++s) {
            const mu = [0, 1, 2].map((i) => Q[3 * i] * a.means[3 * s] + Q[3 * i + 1] * a.means[3 * s + 1] + Q[3 * i + 2] * a.means[3 * s + 2] + t[i]);
            close(b.means.subarray(3 * s, 3 * s + 3), mu, 1e-5, `mean ${s}`);
            const want = rotateCov(Q, a.cov, 6 * s);
            const scale = Math.max(...want.map(Math.abs));
            close(b.cov.subarray(6 * s, 6 * s + 6), want, 1e-5 * scale, `cov ${s}`);
        }
    });

    test(`the remap at the rest mesh returns a consistent rest pose; uniform scaling (${label})`, () => {
        const p = randomAsset(/** @type {'local'|'games'} */ (profile), deformation);
        const rest = computeRest(p);
        const r0 = remapCpu(p, rest, p.anchorMesh.vertices);
        if (profile === 'local') {
            // at rest A = R_r: Σ = R_r R_l S² R_lᵀ R_rᵀ
            for (let s = 0; s < p.count; ++s) {
                const f = p.faceIndex[s];
                const Rr = Array.from(rest.restFrame.subarray(9 * f, 9 * f + 9));
                const local = rotationScaleToCov(/** @type {Float32Array} */ (p.localRotation), /** @type {Float32Array} */ (p.localScale), 4 * s, 3 * s);
                const want = rotateCov(Rr, local, 0);
                close(r0.cov.subarray(6 * s, 6 * s + 6), want, 1e-6 * Math.max(...want.map(Math.abs)), `rest cov ${s}`);
            }
            // scaling the current mesh by c scales means by c and covariances by c²
            const c = 3;
            const scaled = remapCpu(p, rest, Array.from(p.anchorMesh.vertices, (x) => x * c));
            for (let i = 0; i < r0.means.length; ++i) assert.ok(Math.abs(scaled.means[i] - c * r0.means[i]) < 1e-5, `scaled mean ${i}`);
            for (let i = 0; i < r0.cov.length; ++i) assert.ok(Math.abs(scaled.cov[i] - c * c * r0.cov[i]) <= 1e-5 * Math.abs(c * c * r0.cov[i]) + 1e-12, `scaled cov ${i}`);
        }
        for (const x of r0.means) assert.ok(Number.isFinite(x));
    });
}

test('vertices as Float32Array, Float64Array or plain numbers give the same result', () => {
    const p = randomAsset('local', 'affine');
    const v32 = Float32Array.from(p.anchorMesh.vertices, (x, i) => x + 0.01 * i);
    const a = remapCpu(p, null, v32);
    const b = remapCpu(p, null, Float64Array.from(v32));
    const c = remapCpu(p, null, Array.from(v32));
    assert.deepEqual(a.means, b.means);
    assert.deepEqual(a.cov, c.cov);
    // preallocated outputs are filled in place
    const out = { means: new Float32Array(3 * p.count), cov: new Float32Array(6 * p.count) };
    const d = remapCpu(p, null, v32, out);
    assert.equal(d.means, out.means);
    assert.deepEqual(out.cov, a.cov);
    assert.throws(() => remapCpu(p, null, new Float32Array(3)), RangeError);
});

test('rotation + scale outputs reproduce the covariances (all laws)', () => {
    for (const [profile, deformation] of [['local', 'affine'], ['local', 'rigid'], ['games', undefined]]) {
        const p = randomAsset(/** @type {'local'|'games'} */ (profile), deformation);
        const pose = Float32Array.from(p.anchorMesh.vertices, (x, i) => x * (1 + 0.2 * Math.sin(i)));
        const cov = remapCpu(p, null, pose).cov;
        const rs = remapCpuRotationScale(p, null, pose);
        for (let s = 0; s < p.count; ++s) {
            const q = rs.rotations.subarray(4 * s, 4 * s + 4);
            assert.ok(Math.abs(Math.hypot(...q) - 1) < 1e-6, 'unit quaternion');
            const want = Array.from(cov.subarray(6 * s, 6 * s + 6));
            close(rotationScaleToCov(rs.rotations, rs.scales, 4 * s, 3 * s), want, 1e-5 * Math.max(...want.map(Math.abs)), `${profile} ${deformation} splat ${s}`);
        }
    }
});

test('a collapsed current triangle gives finite output; m = 0 when a_c = 0', () => {
    const p = prim({ ...EX1, profile: 'local', deformation: 'affine' });
    const out = remapCpu(p, null, [0, 0, 0, 0, 0, 0, 0, 0, 0]);
    close(out.means, [0, 0, 0], 0, 'mean on a point');
    close(out.cov, [0, 0, 0, 0, 0, 0], 0, 'cov on a point');
    const seg = remapCpu(p, null, [0, 0, 0, 2, 0, 0, 1, 0, 0]);
    close(seg.means, [0.25 * 2 + 0.5 * 1, 0, 0], 1e-7, 'mean on a segment: no normal offset');
    for (const x of seg.cov) assert.ok(Number.isFinite(x));
});

test('means-only remap (the depth-sort centres) equals the full remap, in any row order', () => {
    for (const [profile, deformation] of [['local', 'affine'], ['local', 'rigid'], ['games', undefined]]) {
        const p = randomAsset(/** @type {'local'|'games'} */ (profile), deformation);
        const pose = Float32Array.from(p.anchorMesh.vertices, (x, i) => x * (1 + 0.3 * Math.sin(i)) - 0.1 * Math.cos(i));
        const full = remapCpu(p, null, pose).means;
        assert.deepEqual(remapMeansInto(p, null, pose), full, `${profile} ${deformation}`);
        const order = Uint32Array.from({ length: p.count }, (_, r) => (r * 7 + 3) % p.count);
        const rows = remapMeansInto(p, computeRest(p), pose, new Float32Array(3 * p.count), order);
        for (let r = 0; r < p.count; ++r) {
            for (let k = 0; k < 3; ++k) assert.equal(rows[3 * r + k], full[3 * order[r] + k], `${profile} row ${r}`);
        }
    }
    // a face degenerate at rest: m is the current frame normal (worked example 4)
    const deg = prim({ vertices: [0, 0, 0, 2, 0, 0, 1, 0, 0], indices: [0, 1, 2], face: [0], bary: [0.25, 0.25], offset: [0.125],
        rotation: [0, 0, 0, 1], scale: [0.125, 0.375, 0.0625], profile: 'local', deformation: 'affine' });
    close(remapMeansInto(deg, null, [0, 0, 0, 0, 2, 0, 0, 1, 0]), [0, 0.75, -0.125], 1e-7, 'degenerate at rest');
});
