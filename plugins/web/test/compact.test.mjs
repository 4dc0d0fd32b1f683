// The compact anchor encodings (extension 1.2): faceCounts expanded to a face per splat, derived
// local anchors (numbers by hand, the rest pose reproduced, the same remap as stored anchors),
// and every refusal with its gsverse-validate code.
import test from 'node:test';
import assert from 'node:assert/strict';

import { AnchorError, readAnchoredGlb } from '../src/anchor.js';
import { deriveLocalAnchors, expandFaceCounts } from '../src/compact.js';
import { computeRest } from '../src/rest.js';
import { remapCpu, remapCpuRotationScale } from '../src/remap-cpu.js';
import { quatToMatrix } from '../src/decompose.js';
import { anchoredGlb, KHR, EXT } from './glb-writer.mjs';

/** @typedef {import('./glb-writer.mjs').AnchoredSpec} AnchoredSpec */
/** @typedef {import('../src/types.js').AnchoredPrimitive} AnchoredPrimitive */

/** @param {AnchoredSpec} spec @returns {AnchoredPrimitive} */
const read = (spec) => readAnchoredGlb(anchoredGlb(spec), { name: 'case.glb' }).anchored[0];

/** @param {AnchoredSpec} spec @param {string} code */
function refuses(spec, code) {
    assert.throws(() => read(spec), (/** @type {any} */ err) => {
        assert.ok(err instanceof AnchorError, `an AnchorError, got ${err}`);
        assert.equal(err.code, code, err.message);
        assert.ok(err.message.startsWith('case.glb: '), `message names the file: ${err.message}`);
        assert.ok(!err.message.includes('\n'), 'one line');
        return true;
    });
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

/** @param {any} json */
const anchorExt = (json) => json.meshes[0].primitives[0].extensions[KHR].extensions[EXT];

/** A bumpy 3x3-vertex grid (8 triangles) and 3 splats per face near it, sorted by face. @returns {AnchoredSpec} */
function gridSpec() {
    /** @type {number[]} */
    const vertices = [];
    for (let j = 0; j < 3; ++j) for (let i = 0; i < 3; ++i) vertices.push(i * 0.7, j * 0.5, 0.15 * Math.sin(1.3 * i + 2.1 * j));
    /** @type {number[]} */
    const indices = [];
    for (let j = 0; j < 2; ++j) {
        for (let i = 0; i < 2; ++i) {
            const a = 3 * j + i;
            indices.push(a, a + 1, a + 4, a, a + 4, a + 3);
        }
    }
    /** @type {number[]} */ const face = [];
    /** @type {number[]} */ const means = [];
    /** @type {number[]} */ const rotations = [];
    /** @type {number[]} */ const scales = [];
    let seed = 7;
    const rnd = () => ((seed = (seed * 16807) % 2147483647) / 2147483647);
    for (let f = 0; f < 8; ++f) {
        for (let k = 0; k < 3; ++k) {
            const c = [0, 1, 2].map((n) => vertices.slice(3 * indices[3 * f + n], 3 * indices[3 * f + n] + 3));
            const w1 = rnd() * 0.6, w2 = rnd() * 0.6 * (1 - w1);
            for (let d = 0; d < 3; ++d) means.push(c[0][d] + w1 * (c[1][d] - c[0][d]) + w2 * (c[2][d] - c[0][d]) + (d === 2 ? 0.05 * (rnd() - 0.5) : 0));
            const q = [rnd() - 0.5, rnd() - 0.5, rnd() - 0.5, rnd() - 0.5];
            rotations.push(...q);   // not normalized: the reader normalizes
            scales.push(0.01 + 0.05 * rnd(), 0.01 + 0.05 * rnd(), 0.002 + 0.01 * rnd());
            face.push(f);
        }
    }
    return {
        vertices, indices, profile: 'local', deformation: 'affine', face, bary: [], means, rotations, scales,
        faceCounts: new Array(8).fill(3), derived: true,
    };
}

/** A deformation of the grid: a shear, a stretch and a bend. @param {ArrayLike<number>} v */
function deform(v) {
    const out = new Float32Array(v.length);
    for (let i = 0; i < v.length; i += 3) {
        out[i] = 1.3 * v[i] + 0.2 * v[i + 1];
        out[i + 1] = 0.8 * v[i + 1] + 0.1 * v[i + 2];
        out[i + 2] = v[i + 2] + 0.3 * v[i] * v[i];
    }
    return out;
}

/** Rest covariance R diag(s)² Rᵀ of splat i (cov6) from the rest pose as read. @param {AnchoredPrimitive} p @param {number} i */
function restCov(p, i) {
    const r = quatToMatrix(p.rest.rotations, 4 * i);
    const s = p.rest.scales;
    /** @param {number} a @param {number} b */
    const e = (a, b) => r[3 * a] * r[3 * b] * s[3 * i] ** 2 + r[3 * a + 1] * r[3 * b + 1] * s[3 * i + 1] ** 2 + r[3 * a + 2] * r[3 * b + 2] * s[3 * i + 2] ** 2;
    return [e(0, 0), e(0, 1), e(0, 2), e(1, 1), e(1, 2), e(2, 2)];
}

test('expandFaceCounts: splats grouped by face in face order, zero counts skipped', () => {
    const { faceIndex } = expandFaceCounts(Uint8Array.from([2, 0, 3, 1]), 6);
    assert.deepEqual(Array.from(/** @type {Uint32Array} */ (faceIndex)), [0, 0, 2, 2, 2, 3]);
    assert.deepEqual(Array.from(/** @type {Uint32Array} */ (expandFaceCounts([0, 0], 0).faceIndex)), []);
    assert.deepEqual(expandFaceCounts([1, 2], 4), { faceIndex: null, sum: 3, exceeded: false });
    assert.equal(expandFaceCounts([1, 2], 2).exceeded, true);
});

test('expandFaceCounts: a sum that wraps in 32 bits is not taken for the splat count', () => {
    // 2^32 − 1 + 1 + 5 = 2^32 + 5, which is 5 modulo 2^32
    assert.equal(expandFaceCounts(Uint32Array.from([0xffffffff, 1, 5]), 5).faceIndex, null);
    // many huge counts: the sum stops at the first overrun, exact in binary64
    const many = new Uint32Array(1 << 22).fill(0xffffffff);
    const r = expandFaceCounts(many, 2 ** 52);
    assert.equal(r.faceIndex, null);
    assert.equal(r.exceeded, true);
    assert.ok(Number.isSafeInteger(r.sum) && r.sum > 2 ** 52, `${r.sum}`);
});

test('faceCounts with explicit anchors reads the same primitive as faceIndex', () => {
    const spec = gridSpec();
    const counts = [3, 0, 5, 1, 0, 4, 3, 8];
    /** @type {number[]} */
    const face = [];
    counts.forEach((c, f) => { for (let k = 0; k < c; ++k) face.push(f); });
    const N = face.length;
    const explicit = {
        ...spec, derived: false, faceCounts: undefined, face,
        bary: Array.from({ length: 2 * N }, (_, i) => 0.1 + 0.01 * i), offset: Array.from({ length: N }, (_, i) => 0.001 * i),
        rotation: Array.from({ length: 4 * N }, (_, i) => (i % 4 === 3 ? 1 : 0.1)), scale: new Array(3 * N).fill(0.02),
        means: new Array(3 * N).fill(0), rotations: undefined, scales: undefined,
    };
    const a = read(explicit);
    const b = read({ ...explicit, faceCounts: Uint16Array.from(counts) });
    assert.equal(a.faceEncoding, 'faceIndex');
    assert.equal(b.faceEncoding, 'faceCounts');
    assert.equal(b.derived, false);
    assert.deepEqual(Array.from(b.faceIndex), face);
    assert.equal(b.componentTypes.faceCounts, 'UNSIGNED_SHORT');
    assert.equal(b.componentTypes.faceIndex, undefined);
    for (const key of /** @type {const} */ (['barycentrics', 'normalOffset', 'localRotation', 'localScale'])) assert.deepEqual(b[key], a[key], key);
    const pose = deform(a.anchorMesh.vertices);
    assert.deepEqual(remapCpu(b, null, pose), remapCpu(a, null, pose));
    // games: faceCounts allowed, barycentrics and rho stay stored
    const g = read({ ...explicit, profile: 'games', deformation: undefined, faceCounts: Uint8Array.from(counts), rho: new Array(N).fill(1.5) });
    assert.equal(g.faceEncoding, 'faceCounts');
    assert.deepEqual(Array.from(g.faceIndex), face);
    assert.equal(g.componentTypes.faceCounts, 'UNSIGNED_BYTE');
});

test('derived local anchors, by hand: b1, b2, d in the rest frame and q_l = conj(q_r) ⊗ q', () => {
    // worked example 1's triangle: R_r = I, C_r = [[2, 0], [0, 1]]
    const flat = read({
        vertices: [0, 0, 0, 2, 0, 0, 0, 1, 0], indices: [0, 1, 2], profile: 'local', deformation: 'affine',
        face: [0], bary: [], means: [0.5, 0.5, 0.125], rotations: [0, 0, 0.6, 0.8], scales: [0.125, 0.375, 0.0625], derived: true,
    });
    assert.equal(flat.derived, true);
    assert.equal(flat.faceEncoding, 'faceIndex');
    assert.ok(flat.barycentrics instanceof Float32Array, 'derived anchors are rounded once to float32');
    close(flat.barycentrics, [0.25, 0.5], 1e-15, 'b');
    close(/** @type {Float32Array} */ (flat.normalOffset), [0.125], 1e-15, 'd');
    close(/** @type {Float32Array} */ (flat.localRotation), [0, 0, Math.fround(0.6), Math.fround(0.8)], 1e-7, 'q_l = q');
    assert.deepEqual(Array.from(/** @type {Float32Array} */ (flat.localScale)), [0.125, 0.375, 0.0625]);
    // a triangle in the x = 0 plane: t = y, n = x, b = n × t = z; R_r maps x→y→z→x, the rotation
    // by 120° about (1, 1, 1): q_r = (0.5, 0.5, 0.5, 0.5). C_r = [[2, 0], [0, 1]].
    const turned = read({
        vertices: [0, 0, 0, 0, 2, 0, 0, 0, 1], indices: [0, 1, 2], profile: 'local', deformation: 'rigid',
        face: [0], bary: [], means: [0.125, 0.5, 0.25], rotations: [0.5, 0.5, 0.5, 0.5], scales: [0.1, 0.2, 0.3], derived: true,
    });
    close(turned.barycentrics, [0.25, 0.25], 1e-15, 'b');
    close(/** @type {Float32Array} */ (turned.normalOffset), [0.125], 1e-15, 'd');
    close(/** @type {Float32Array} */ (turned.localRotation), [0, 0, 0, 1], 1e-15, 'q_l');
    assert.equal(turned.deformation, 'rigid');
});

for (const deformation of ['affine', 'rigid']) {
    test(`derived ${deformation} anchors reproduce the rest pose and remap as the same anchors stored`, () => {
        const spec = { ...gridSpec(), deformation };
        const p = read(spec);
        assert.equal(p.derived, true);
        assert.equal(p.faceEncoding, 'faceCounts');
        assert.equal(p.count, 24);
        assert.deepEqual(p.componentTypes, { faceCounts: 'UNSIGNED_INT' });
        const rest = computeRest(p);
        // at the rest mesh: the stored means and covariances, up to float32 outputs
        const atRest = remapCpu(p, rest, p.anchorMesh.vertices);
        close(atRest.means, p.rest.means, 2e-7, 'rest means');
        for (let i = 0; i < p.count; ++i) close(atRest.cov.subarray(6 * i, 6 * i + 6), restCov(p, i), 1e-9, `rest cov ${i}`);
        // the same anchors stored explicitly (float32) remap to the same splats
        const stored = read({
            ...spec, derived: false, faceCounts: undefined,
            bary: Array.from(p.barycentrics), offset: Array.from(/** @type {Float32Array} */ (p.normalOffset)),
            rotation: Array.from(/** @type {Float32Array} */ (p.localRotation)), scale: Array.from(/** @type {Float32Array} */ (p.localScale)),
        });
        const pose = deform(p.anchorMesh.vertices);
        const a = remapCpu(p, rest, pose);
        const b = remapCpu(stored, null, pose);
        close(a.means, b.means, 1e-6, 'means');
        close(a.cov, b.cov, 1e-8, 'cov');
        const rs = remapCpuRotationScale(p, rest, pose);
        assert.ok(rs.scales.every(Number.isFinite));
        // and the deformation moved them
        assert.ok(Math.abs(a.means[0] - atRest.means[0]) > 1e-3);
    });
}

test('derived anchors from a normalized (quantized) rest ROTATION reproduce it at rest', () => {
    const spec = gridSpec();
    const p = read(spec);
    const bytes = anchoredGlb({
        ...spec,
        patch: (json, b) => {
            const codes = Int16Array.from(p.rest.rotations, (x) => Math.round(x * 32767));
            json.meshes[0].primitives[0].attributes[`${KHR}:ROTATION`] = b.accessor(codes, 'VEC4', { normalized: true });
        },
    });
    const q = readAnchoredGlb(bytes, { name: 'case.glb' }).anchored[0];
    const atRest = remapCpu(q, null, q.anchorMesh.vertices);
    // the quantized rest rotation is the rest pose: reproduced as well as the float one
    for (let i = 0; i < q.count; ++i) close(atRest.cov.subarray(6 * i, 6 * i + 6), restCov(q, i), 1e-9, `cov ${i}`);
});

test('deriveLocalAnchors reports the first splat on a face degenerate at rest', () => {
    const mesh = { vertices: [0, 0, 0, 1, 0, 0, 2, 0, 0, 0, 1, 0], indices: [0, 1, 3, 0, 1, 2], faceCount: 2 };
    const ok = deriveLocalAnchors(mesh, Uint32Array.from([0, 0]), [0.2, 0.2, 0, 0.1, 0.1, 0], [0, 0, 0, 1, 0, 0, 0, 1], [1, 1, 1, 1, 1, 1]);
    assert.equal(ok.degenerateSplat, -1);
    const bad = deriveLocalAnchors(mesh, Uint32Array.from([0, 1, 1]), new Array(9).fill(0), [0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1], new Array(9).fill(1));
    assert.equal(bad.anchors, null);
    assert.equal(bad.degenerateSplat, 1);
});

/** @type {[string, string, () => AnchoredSpec][]} */
const REFUSALS = [
    ['both faceIndex and faceCounts', 'ANCHOR_SCHEMA_VIOLATION', () => ({
        ...gridSpec(), patch: (j, b) => { anchorExt(j).faceIndex = b.accessor(new Uint8Array(24), 'SCALAR'); },
    })],
    ['neither faceIndex nor faceCounts', 'ANCHOR_SCHEMA_VIOLATION', () => ({ ...gridSpec(), patch: (j) => { delete anchorExt(j).faceCounts; } })],
    ['neither, games', 'ANCHOR_SCHEMA_VIOLATION', () => ({
        ...gridSpec(), profile: 'games', deformation: undefined, derived: false, bary: new Array(48).fill(0.2),
        patch: (j) => { delete anchorExt(j).faceCounts; },
    })],
    ['faceCounts count != triangles (fewer)', 'ANCHOR_FACE_COUNTS_COUNT', () => ({ ...gridSpec(), faceCounts: [3, 3, 3, 3, 3, 3, 6] })],
    ['faceCounts count != triangles (more)', 'ANCHOR_FACE_COUNTS_COUNT', () => ({ ...gridSpec(), faceCounts: [3, 3, 3, 3, 3, 3, 3, 3, 0] })],
    ['faceCounts sum < POSITION count', 'ANCHOR_FACE_COUNTS_SUM', () => ({ ...gridSpec(), faceCounts: [3, 3, 3, 3, 3, 3, 3, 2] })],
    ['faceCounts sum > POSITION count', 'ANCHOR_FACE_COUNTS_SUM', () => ({ ...gridSpec(), faceCounts: [3, 3, 3, 3, 3, 3, 3, 4] })],
    ['faceCounts sum wraps in 32 bits', 'ANCHOR_FACE_COUNTS_SUM', () => ({ ...gridSpec(), faceCounts: [0xffffffff, 1, 3, 3, 3, 3, 3, 3] })],
    ['faceCounts FLOAT', 'ANCHOR_ACCESSOR_FORMAT', () => ({ ...gridSpec(), faceCounts: new Float32Array(8).fill(3) })],
    ['faceCounts signed', 'ANCHOR_ACCESSOR_FORMAT', () => ({ ...gridSpec(), faceCounts: new Int16Array(8).fill(3) })],
    ['faceCounts normalized', 'ANCHOR_ACCESSOR_FORMAT', () => ({
        ...gridSpec(), patch: (j) => { j.accessors[anchorExt(j).faceCounts].normalized = true; j.accessors[anchorExt(j).faceCounts].componentType = 5121; },
    })],
    ['faceCounts VEC2', 'ANCHOR_ACCESSOR_FORMAT', () => ({ ...gridSpec(), patch: (j) => { j.accessors[anchorExt(j).faceCounts].type = 'VEC2'; } })],
    ['faceCounts sparse', 'ACCESSOR_UNSUPPORTED', () => ({
        ...gridSpec(), patch: (j) => { j.accessors[anchorExt(j).faceCounts].sparse = { count: 1, indices: { bufferView: 0, componentType: 5121 }, values: { bufferView: 0 } }; },
    })],
    ['faceCounts not an accessor', 'UNRESOLVED_REFERENCE', () => ({ ...gridSpec(), patch: (j) => { anchorExt(j).faceCounts = 999; } })],
    ['derived with normalOffset', 'ANCHOR_SCHEMA_VIOLATION', () => ({
        ...gridSpec(), patch: (j, b) => { anchorExt(j).normalOffset = b.accessor(new Float32Array(24), 'SCALAR'); },
    })],
    ['derived with localRotation and localScale', 'ANCHOR_SCHEMA_VIOLATION', () => ({
        ...gridSpec(), patch: (j, b) => {
            anchorExt(j).localRotation = b.accessor(new Float32Array(96).fill(0.5), 'VEC4');
            anchorExt(j).localScale = b.accessor(new Float32Array(72).fill(0.5), 'VEC3');
        },
    })],
    ['explicit without localScale', 'ANCHOR_SCHEMA_VIOLATION', () => ({
        ...gridSpec(), derived: false, bary: new Array(48).fill(0.2), patch: (j) => { delete anchorExt(j).localScale; },
    })],
    ['games without barycentrics (no derived form)', 'ANCHOR_SCHEMA_VIOLATION', () => ({
        ...gridSpec(), profile: 'games', deformation: undefined, derived: false, bary: new Array(48).fill(0.2),
        patch: (j) => { delete anchorExt(j).barycentrics; },
    })],
    ['derived anchors from a rest ROTATION of length zero', 'ROTATION_NOT_UNIT', () => {
        const s = gridSpec();
        const q = /** @type {number[]} */ (s.rotations).slice();
        q.splice(4 * 5, 4, 0, 0, 0, 0);
        return { ...s, rotations: q };
    }],
    ['derived anchors from a quantized rest ROTATION of length zero', 'ROTATION_NOT_UNIT', () => ({
        ...gridSpec(), patch: (j, b) => {
            const codes = new Int16Array(96).fill(100);
            codes.fill(0, 8, 12);
            j.meshes[0].primitives[0].attributes[`${KHR}:ROTATION`] = b.accessor(codes, 'VEC4', { normalized: true });
        },
    })],
    ['derived anchors from a negative rest SCALE', 'SCALE_NEGATIVE', () => {
        const s = gridSpec();
        const v = /** @type {number[]} */ (s.scales).slice();
        v[3 * 7 + 2] = -0.001;
        return { ...s, scales: v };
    }],
    ['derived splat on a face degenerate at rest', 'ANCHOR_DERIVED_ON_DEGENERATE', () => {
        const s = gridSpec();
        const v = s.vertices.slice();
        // vertex 3 to the midpoint of vertices 0 (the origin) and 4: face 1 = (0, 4, 3) collapses
        v[9] = 0.5 * v[12]; v[10] = 0.5 * v[13]; v[11] = 0.5 * v[14];
        return { ...s, vertices: v };
    }],
];

for (const [label, code, spec] of REFUSALS) {
    test(`refuses: ${label} (${code})`, () => refuses(spec(), code));
}

test('explicit anchors: a zero or negative rest pose is not refused (the stored anchors are used)', () => {
    const s = gridSpec();
    const N = s.face.length;
    const q = /** @type {number[]} */ (s.rotations).slice();
    q.splice(0, 4, 0, 0, 0, 0);
    const v = /** @type {number[]} */ (s.scales).slice();
    v[0] = -0.01;
    const p = read({
        ...s, rotations: q, scales: v, derived: false, bary: new Array(2 * N).fill(0.25), offset: new Array(N).fill(0),
        rotation: Array.from({ length: 4 * N }, (_, i) => (i % 4 === 3 ? 1 : 0)), scale: new Array(3 * N).fill(0.01),
    });
    assert.equal(p.derived, false);
});

test('explicit anchors may still lie on faces degenerate at rest; derived ones may not', () => {
    const s = gridSpec();
    const v = s.vertices.slice();
    v[9] = 0.5 * v[12]; v[10] = 0.5 * v[13]; v[11] = 0.5 * v[14];
    const rest = computeRest({ anchorMesh: { vertices: v, indices: /** @type {number[]} */ (s.indices) } });
    assert.equal(rest.regular[1], 0, 'face 1 (0, 4, 3) degenerate at rest');
    assert.equal(rest.regular[0], 1);
    const N = s.face.length;
    const p = read({
        ...s, vertices: v, derived: false, bary: new Array(2 * N).fill(0.25), offset: new Array(N).fill(0),
        rotation: Array.from({ length: 4 * N }, (_, i) => (i % 4 === 3 ? 1 : 0)), scale: new Array(3 * N).fill(0.01),
    });
    assert.equal(p.derived, false);
});
