// readAnchorAnimation: skinning (with a splat node that is not the identity), morph targets
// and their weights channels, STEP / LINEAR / CUBICSPLINE keys, time clamping, node.matrix,
// several JOINTS_n/WEIGHTS_n sets, quantized accessors, a 10,000-deep node chain, and every
// refusal with its code. The expected vertices are worked out here from the spec's formulas
// with plain matrices (column-major 4x4 as number arrays).
import test from 'node:test';
import assert from 'node:assert/strict';

import { AnchorError, readAnchoredGlb } from '../src/anchor.js';
import { readAnchorAnimation } from '../src/animation.js';
import { parseGltf } from '../src/glb.js';
import { anchoredGlb, matrixAccessor } from './glb-writer.mjs';

/** @typedef {import('../src/glb.js').GltfDocument} GltfDocument */
/** @typedef {import('./glb-writer.mjs').GltfBuilder} GltfBuilder */

// ---------------------------------------------------------------------- matrices (column-major)

/** @param {number[]} a @param {number[]} b @returns {number[]} a · b */
function mul(a, b) {
    const out = new Array(16).fill(0);
    for (let c = 0; c < 4; ++c) for (let r = 0; r < 4; ++r) for (let k = 0; k < 4; ++k) out[4 * c + r] += a[4 * k + r] * b[4 * c + k];
    return out;
}
/** @param {...number[]} ms */
const chain = (...ms) => ms.reduce(mul);
/** @param {number} x @param {number} y @param {number} z */
const translate = (x, y, z) => [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, x, y, z, 1];
/** @param {number} x @param {number} y @param {number} z */
const scale = (x, y, z) => [x, 0, 0, 0, 0, y, 0, 0, 0, 0, z, 0, 0, 0, 0, 1];
/** @param {number} deg */
function rotZ(deg) {
    const a = (deg * Math.PI) / 180;
    return [Math.cos(a), Math.sin(a), 0, 0, -Math.sin(a), Math.cos(a), 0, 0, 0, 0, 1, 0, 0, 0, 0, 1];
}
/** @param {number} deg */
function rotX(deg) {
    const a = (deg * Math.PI) / 180;
    return [1, 0, 0, 0, 0, Math.cos(a), Math.sin(a), 0, 0, -Math.sin(a), Math.cos(a), 0, 0, 0, 0, 1];
}
/** quaternion (x, y, z, w) of a rotation about Z @param {number} deg */
const quatZ = (deg) => [0, 0, Math.sin((deg * Math.PI) / 360), Math.cos((deg * Math.PI) / 360)];
const IDENTITY = translate(0, 0, 0);

/**
 * Apply a matrix to every point of a flat xyz list.
 * @param {number[]} m
 * @param {ArrayLike<number>} pts
 * @returns {number[]}
 */
function apply(m, pts) {
    const out = [];
    for (let i = 0; i < pts.length; i += 3) {
        const [x, y, z] = [pts[i], pts[i + 1], pts[i + 2]];
        out.push(m[0] * x + m[4] * y + m[8] * z + m[12], m[1] * x + m[5] * y + m[9] * z + m[13], m[2] * x + m[6] * y + m[10] * z + m[14]);
    }
    return out;
}

/**
 * @param {ArrayLike<number>} actual
 * @param {ArrayLike<number>} expected
 * @param {number} tol
 * @param {string} [what]
 */
function close(actual, expected, tol, what = '') {
    assert.equal(actual.length, expected.length, `${what}: length`);
    for (let i = 0; i < expected.length; ++i) {
        assert.ok(Math.abs(actual[i] - expected[i]) <= tol, `${what}[${i}]: ${actual[i]} vs ${expected[i]} (tol ${tol})`);
    }
}

/** @param {ArrayLike<number>} a @param {ArrayLike<number>} b */
function maxDiff(a, b) {
    let m = 0;
    for (let i = 0; i < a.length; ++i) m = Math.max(m, Math.abs(a[i] - b[i]));
    return m;
}

// ---------------------------------------------------------------------- assets

/** A strip of 6 vertices in rows y = 0, 1, 2 (two per row), 4 triangles. */
const STRIP = [0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 2, 0, 1, 2, 0];
const STRIP_FACES = [0, 1, 3, 0, 3, 2, 2, 3, 5, 2, 5, 4];
const V = 6;
/** @param {number} i vertex index @returns {number[]} */
const vertex = (i) => STRIP.slice(3 * i, 3 * i + 3);

/**
 * @typedef {object} SkinSpec
 * @property {any[]} nodes         joint (and other) nodes; `children` index into this list
 * @property {number[]} joints     indices into `nodes`
 * @property {number[]|null} ibm   16 numbers per joint, or null for no inverseBindMatrices
 * @property {number[][]} influences  per vertex [joint, weight, joint, weight, …] (≤ 4 pairs)
 */

/**
 * @typedef {object} ChannelSpec
 * @property {number|string} node   a node index, or 'anchor' / 'splat'
 * @property {string} path
 * @property {number[]} times
 * @property {number[]|import('./glb-writer.mjs').Typed} values
 * @property {string} [interpolation]
 * @property {boolean} [normalized]
 */

/**
 * @typedef {object} RigSpec
 * @property {number[]} [splatMatrix]  the splat node's matrix
 * @property {any} [anchorNode]        extra properties of the anchor node (node 1)
 * @property {SkinSpec} [skin]
 * @property {{deltas: number[][], meshWeights?: number[]}} [morph]
 * @property {{name?: string, channels: ChannelSpec[]}[]} [animations]
 * @property {(json: any, b: GltfBuilder, base: number) => void} [patch]  base: index of nodes[0] of the skin
 */

/**
 * An anchored asset on STRIP whose anchor mesh is instantiated by node 1 (the anchor node),
 * with a skin, morph targets and animations as given. Node 0 is the splat node.
 * @param {RigSpec} r
 * @returns {Uint8Array}
 */
function riggedGlb(r) {
    return anchoredGlb({
        vertices: STRIP, indices: STRIP_FACES, profile: 'local', deformation: 'affine',
        face: [0, 3], bary: [0.25, 0.25, 0.2, 0.3], nodeMatrix: r.splatMatrix,
        patch: (json, b) => {
            json.nodes.push({ name: 'anchor', mesh: 1, ...(r.anchorNode || {}) });
            json.scenes[0].nodes.push(1);
            const aprim = json.meshes[1].primitives[0];
            const base = json.nodes.length;
            if (r.skin) {
                const s = r.skin;
                /** @type {Set<number>} */
                const children = new Set();
                for (const n of s.nodes) {
                    const copy = { ...n };
                    if (n.children) copy.children = n.children.map((/** @type {number} */ c) => { children.add(c); return c + base; });
                    json.nodes.push(copy);
                }
                s.nodes.forEach((_, k) => { if (!children.has(k)) json.scenes[0].nodes.push(base + k); });
                /** @type {any} */
                const skin = { joints: s.joints.map((j) => j + base) };
                if (s.ibm) skin.inverseBindMatrices = matrixAccessor(b, s.ibm);
                json.skins = [skin];
                json.nodes[1].skin = 0;
                const joints = new Uint8Array(4 * V);
                const weights = new Float32Array(4 * V);
                s.influences.forEach((list, v) => {
                    for (let k = 0; 2 * k < list.length; ++k) { joints[4 * v + k] = list[2 * k]; weights[4 * v + k] = list[2 * k + 1]; }
                });
                aprim.attributes.JOINTS_0 = b.accessor(joints, 'VEC4');
                aprim.attributes.WEIGHTS_0 = b.accessor(weights, 'VEC4');
            }
            if (r.morph) {
                aprim.targets = r.morph.deltas.map((d) => ({ POSITION: b.accessor(Float32Array.from(d), 'VEC3') }));
                if (r.morph.meshWeights) json.meshes[1].weights = r.morph.meshWeights;
            }
            json.animations = (r.animations || []).map((anim) => {
                /** @type {any[]} */
                const samplers = [];
                const channels = anim.channels.map((ch, k) => {
                    const type = ch.path === 'rotation' ? 'VEC4' : ch.path === 'weights' ? 'SCALAR' : 'VEC3';
                    const values = ArrayBuffer.isView(ch.values) ? ch.values : Float32Array.from(ch.values);
                    samplers.push({
                        input: b.accessor(Float32Array.from(ch.times), 'SCALAR'),
                        output: b.accessor(/** @type {any} */ (values), type, { normalized: ch.normalized }),
                        interpolation: ch.interpolation || 'LINEAR',
                    });
                    const node = ch.node === 'anchor' ? 1 : ch.node === 'splat' ? 0 : base + /** @type {number} */ (ch.node);
                    return { sampler: k, target: { node, path: ch.path } };
                });
                return { name: anim.name, samplers, channels };
            });
            if (r.patch) r.patch(json, b, base);
        },
    });
}

/**
 * @param {Uint8Array} bytes
 */
function load(bytes) {
    const prim = readAnchoredGlb(bytes, { name: 'case.glb' }).anchored[0];
    const anim = readAnchorAnimation(bytes, prim, { name: 'case.glb' });
    assert.ok(anim, 'the anchor mesh is animated');
    return { prim, anim };
}

/**
 * @param {Uint8Array} bytes
 * @param {string} code
 * @param {RegExp} [pattern]  the message must match
 */
function refuses(bytes, code, pattern) {
    const prim = readAnchoredGlb(bytes, { name: 'case.glb' }).anchored[0];
    assert.throws(() => readAnchorAnimation(bytes, prim, { name: 'case.glb' }), (/** @type {any} */ err) => {
        assert.ok(err instanceof AnchorError, `an AnchorError, got ${err}`);
        assert.equal(err.code, code, err.message);
        assert.ok(err.message.startsWith('case.glb: '), `message names the file: ${err.message}`);
        assert.ok(!err.message.includes('\n'), 'one line');
        if (pattern) assert.match(err.message, pattern);
        return true;
    });
}

/**
 * Two joints: A at the origin (a scene root), B its child at (0, 1, 0). Rows y = 0, 1, 2 of the
 * strip follow A, half and half, and B. Inverse bind matrices G_rest(j)⁻¹ · M, so that the rest
 * skin reproduces POSITION in the splat node's space M.
 * @param {number[]} M  the splat node's matrix
 * @returns {SkinSpec}
 */
function twoJoints(M) {
    return {
        nodes: [{ name: 'A', children: [1] }, { name: 'B', translation: [0, 1, 0] }],
        joints: [0, 1],
        ibm: [...M, ...mul(translate(0, -1, 0), M)],
        influences: [[0, 1], [0, 1], [0, 0.5, 1, 0.5], [0, 0.5, 1, 0.5], [1, 1], [1, 1]],
    };
}

// M = T · Rx(90°) · S(2, 2, 2) and its inverse, by hand
const M = chain(translate(5, -1, 3), rotX(90), scale(2, 2, 2));
const M_INV = chain(scale(0.5, 0.5, 0.5), rotX(-90), translate(-5, 1, -3));

// ---------------------------------------------------------------------- tests

test('the M⁻¹ of the hand-built matrices is their inverse', () => {
    close(mul(M, M_INV), IDENTITY, 1e-12, 'M·M⁻¹');
});

test('two-joint skin under a splat node that is not the identity: rest, LINEAR slerp, blending, M⁻¹', () => {
    const bytes = riggedGlb({
        splatMatrix: M,
        skin: twoJoints(M),
        animations: [{ name: 'bend', channels: [{ node: 1, path: 'rotation', times: [0, 1], values: [...quatZ(0), ...quatZ(90)] }] }],
    });
    const { prim, anim } = load(bytes);
    assert.equal(anim.skinned, true);
    assert.equal(anim.morphed, false);
    assert.equal(anim.vertexCount, V);
    assert.equal(anim.jointCount, 2);
    assert.deepEqual(anim.animations, [{ index: 0, name: 'bend', duration: 1 }]);
    close(prim.nodeMatrix || [], M, 1e-12, 'the splat node matrix');
    // rest: the stored POSITION
    close(anim.rest(), STRIP, 2e-6, 'rest');
    close(anim.sample(0, 0), STRIP, 2e-6, 't = 0');
    // t = 0.5: B turned 45° about Z around its origin (0, 1, 0) in the scene's space
    const pivot = chain(translate(0, 1, 0), rotZ(45), translate(0, -1, 0));
    const moved = chain(M_INV, pivot, M);   // a vertex that follows B, in splat-local space
    /** @type {number[]} */
    const expected = [];
    for (let i = 0; i < V; ++i) {
        const p = vertex(i);
        const q = apply(moved, p);
        const wB = i < 2 ? 0 : i < 4 ? 0.5 : 1;
        for (let c = 0; c < 3; ++c) expected.push((1 - wB) * p[c] + wB * q[c]);
    }
    const got = anim.sample(0, 0.5);
    close(got, expected, 2e-6, 't = 0.5');
    // without M⁻¹ (skinned vertices left in the scene's space) the result is far off
    const unplaced = [];
    for (let i = 0; i < V; ++i) {
        const wB = i < 2 ? 0 : i < 4 ? 0.5 : 1;
        const p = apply(M, vertex(i));
        const q = apply(chain(pivot, M), vertex(i));
        for (let c = 0; c < 3; ++c) unplaced.push((1 - wB) * p[c] + wB * q[c]);
    }
    assert.ok(maxDiff(got, unplaced) > 1, 'M⁻¹ changes the result');
    // the anchor node's transform is ignored
    const shifted = load(riggedGlb({
        splatMatrix: M, skin: twoJoints(M), anchorNode: { translation: [7, 8, 9], rotation: quatZ(30) },
        animations: [{ name: 'bend', channels: [{ node: 1, path: 'rotation', times: [0, 1], values: [...quatZ(0), ...quatZ(90)] }] }],
    })).anim;
    assert.deepEqual(shifted.sample(0, 0.5), got);
});

test('sample writes into `out` and returns it; bad arguments are RangeErrors', () => {
    const { anim } = load(riggedGlb({
        skin: twoJoints(IDENTITY),
        animations: [{ channels: [{ node: 1, path: 'rotation', times: [0, 1], values: [...quatZ(0), ...quatZ(90)] }] }],
    }));
    assert.equal(anim.animations[0].name, 'animation 0');
    const out = new Float32Array(3 * V);
    assert.equal(anim.sample(0, 0.25, out), out);
    assert.deepEqual(out, anim.sample(0, 0.25));
    assert.equal(anim.rest(out), out);
    assert.throws(() => anim.sample(1, 0), RangeError);
    assert.throws(() => anim.sample(0, NaN), RangeError);
    assert.throws(() => anim.sample(0, 0, new Float32Array(3)), RangeError);
});

/**
 * One joint J at the origin carrying every vertex (IBM identity, splat node identity): the
 * posed vertices are G_J(t) · POSITION.
 * @param {ChannelSpec[]} channels  on node 0 (the joint)
 * @param {any} [joint]  the joint node
 */
function oneJoint(channels, joint = { name: 'J' }) {
    return load(riggedGlb({
        skin: { nodes: [joint], joints: [0], ibm: IDENTITY, influences: new Array(V).fill([0, 1]) },
        animations: [{ name: 'move', channels }],
    })).anim;
}

/** @param {number} x @param {number} y @param {number} z */
const moved = (x, y, z) => apply(translate(x, y, z), STRIP);

test('STEP takes the previous key, LINEAR interpolates, both clamp outside the keys', () => {
    const step = oneJoint([{ node: 0, path: 'translation', interpolation: 'STEP', times: [0, 1, 2], values: [0, 0, 0, 1, 0, 0, 3, 0, 0] }]);
    for (const [t, x] of [[-1, 0], [0, 0], [0.5, 0], [1, 1], [1.99, 1], [2, 3], [5, 3]]) close(step.sample(0, t), moved(x, 0, 0), 1e-6, `STEP t=${t}`);
    const linear = oneJoint([{ node: 0, path: 'translation', times: [1, 2, 4], values: [2, 0, 0, 4, 0, 0, 0, 0, 8] }]);
    assert.equal(linear.animations[0].duration, 4);
    /** @type {[number, number[]][]} */
    const keys = [[0, [2, 0, 0]], [1, [2, 0, 0]], [1.25, [2.5, 0, 0]], [3, [2, 0, 4]], [4, [0, 0, 8]], [10, [0, 0, 8]]];
    for (const [t, [x, y, z]] of keys) close(linear.sample(0, t), moved(x, y, z), 1e-6, `LINEAR t=${t}`);
});

test('CUBICSPLINE: Hermite with tangents scaled by the key interval', () => {
    // keys at 0 and 2: value 0 with out-tangent 1, value 1 with in-tangent 0 (the other tangents
    // are never used); x(s) = h10·2·1 + h01·1
    const cubic = oneJoint([{
        node: 0, path: 'translation', interpolation: 'CUBICSPLINE', times: [0, 2],
        values: [9, 9, 9, 0, 0, 0, 1, 0, 0, /* key 1 */ 0, 0, 0, 1, 0, 0, 9, 9, 9],
    }]);
    for (const [t, x] of [[-1, 0], [0, 0], [0.5, 0.4375], [1, 0.75], [2, 1], [3, 1]]) close(cubic.sample(0, t), moved(x, 0, 0), 1e-6, `t=${t}`);
});

test('rotations: slerp along the shortest arc, CUBICSPLINE normalized', () => {
    const qz = quatZ(90);
    const expected = apply(rotZ(45), STRIP);
    // the second key is −q: the same rotation, reached along the short arc
    const slerp = oneJoint([{ node: 0, path: 'rotation', times: [0, 1], values: [0, 0, 0, 1, ...qz.map((c) => -c)] }]);
    close(slerp.sample(0, 0.5), expected, 1e-6, 'slerp');
    close(slerp.sample(0, 2), apply(rotZ(90), STRIP), 1e-6, 'slerp clamped');
    // zero tangents: the Hermite value halfway is (q0 + q1)/2, not unit: normalized to 45°
    const cubic = oneJoint([{
        node: 0, path: 'rotation', interpolation: 'CUBICSPLINE', times: [0, 1],
        values: [0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, /* key 1 */ 0, 0, 0, 0, ...qz, 0, 0, 0, 0],
    }]);
    close(cubic.sample(0, 0.5), expected, 1e-6, 'cubic');
    // STEP rotations and scales
    const step = oneJoint([
        { node: 0, path: 'rotation', interpolation: 'STEP', times: [0, 1], values: [0, 0, 0, 1, ...qz] },
        { node: 0, path: 'scale', interpolation: 'STEP', times: [0, 1], values: [1, 1, 1, 2, 3, 4] },
    ]);
    close(step.sample(0, 0.9), STRIP, 1e-6, 'STEP before the second key');
    close(step.sample(0, 1), apply(chain(rotZ(90), scale(2, 3, 4)), STRIP), 1e-6, 'STEP at the second key');
    // normalized SHORT rotation keys dequantize (32767 → 1)
    const q16 = Int16Array.from([0, 0, 0, 32767, 0, 0, 32767, 0]);
    const quantized = oneJoint([{ node: 0, path: 'rotation', times: [0, 1], values: q16, normalized: true }]);
    close(quantized.sample(0, 1), apply(rotZ(180), STRIP), 1e-6, 'normalized SHORT rotation');
});

test('node.matrix: a fixed local transform that animation channels do not move', () => {
    const anim = load(riggedGlb({
        skin: {
            nodes: [{ name: 'R', matrix: chain(translate(0, 0, 5), rotZ(90)), children: [1] }, { name: 'J' }],
            joints: [1], ibm: IDENTITY, influences: new Array(V).fill([0, 1]),
        },
        animations: [{
            channels: [
                { node: 0, path: 'translation', times: [0, 1], values: [0, 0, 0, 100, 100, 100] },
                { node: 1, path: 'translation', times: [0, 1], values: [0, 0, 0, 2, 0, 0] },
            ],
        }],
    })).anim;
    close(anim.rest(), apply(chain(translate(0, 0, 5), rotZ(90)), STRIP), 1e-6, 'rest');
    close(anim.sample(0, 1), apply(chain(translate(0, 0, 5), rotZ(90), translate(2, 0, 0)), STRIP), 1e-6, 't = 1');
});

test('the splat node is taken at the sampled time; a singular one is refused', () => {
    const { anim } = load(riggedGlb({
        skin: { nodes: [{ name: 'J' }], joints: [0], ibm: IDENTITY, influences: new Array(V).fill([0, 1]) },
        animations: [{ channels: [{ node: 'splat', path: 'scale', times: [0, 1], values: [1, 1, 1, 0, 0, 0] }] }],
    }));
    close(anim.sample(0, 0.5), STRIP.map((x) => 2 * x), 1e-6, 'M(0.5) = S(0.5)');
    assert.throws(() => anim.sample(0, 1), (/** @type {any} */ err) => err instanceof AnchorError && err.code === 'ANCHOR_SPLAT_NODE_SINGULAR' && err.message.startsWith('case.glb: '));
});

test('every JOINTS_n/WEIGHTS_n set, normalized weights and interleaved (byteStride) attributes', () => {
    const channels = [{ node: 1, path: 'rotation', times: [0, 1], values: [...quatZ(0), ...quatZ(90)] }];
    const skin = twoJoints(IDENTITY);
    const reference = load(riggedGlb({ skin, animations: [{ channels }] })).anim.sample(0, 0.7);
    // vertices 2, 3 (half A, half B) split over JOINTS_0/WEIGHTS_0 and JOINTS_1/WEIGHTS_1
    const split = load(riggedGlb({
        skin: { ...skin, influences: skin.influences.map((l, v) => (v === 2 || v === 3 ? [0, 0.5] : l)) },
        animations: [{ channels }],
        patch: (json, b) => {
            const attrs = json.meshes[1].primitives[0].attributes;
            const j1 = new Uint16Array(4 * V);
            const w1 = new Float32Array(4 * V);
            for (const v of [2, 3]) { j1[4 * v] = 1; w1[4 * v] = 0.5; }
            [attrs.JOINTS_1, attrs.WEIGHTS_1] = b.interleaved([{ data: j1, type: 'VEC4' }, { data: w1, type: 'VEC4' }]);
        },
    })).anim;
    close(split.sample(0, 0.7), reference, 1e-6, 'two sets');
    // the same weights as normalized UNSIGNED_BYTE (255 = 1, 128/255 + 127/255 on rows 2, 3)
    const quantized = load(riggedGlb({
        skin, animations: [{ channels }],
        patch: (json, b) => {
            const attrs = json.meshes[1].primitives[0].attributes;
            const w = new Uint8Array(4 * V);
            w[0] = w[4] = 255; w[8] = w[12] = 128; w[9] = w[13] = 127; w[16] = w[20] = 255;
            attrs.WEIGHTS_0 = b.accessor(w, 'VEC4', { normalized: true });
        },
    })).anim;
    const got = quantized.sample(0, 0.7);
    const rest = STRIP;
    const full = load(riggedGlb({ skin: { ...skin, influences: new Array(V).fill([1, 1]) }, animations: [{ channels }] })).anim.sample(0, 0.7);
    for (const v of [2, 3]) {
        for (let c = 0; c < 3; ++c) {
            const want = (128 / 255) * rest[3 * v + c] + (127 / 255) * full[3 * v + c];
            assert.ok(Math.abs(got[3 * v + c] - want) < 1e-6, `vertex ${v}: ${got[3 * v + c]} vs ${want}`);
        }
    }
    close(got.subarray(0, 6), reference.subarray(0, 6), 1e-6, 'rows on A');
    close(got.subarray(12), reference.subarray(12), 1e-6, 'rows on B');
});

test('morph targets: default weights (node over mesh), an animated weights channel, no placement', () => {
    const d0 = new Array(3 * V).fill(0).map((_, i) => (i % 3 === 2 ? 1 : 0));     // +z for every vertex
    const d1 = new Array(3 * V).fill(0).map((_, i) => (i % 3 === 0 ? i / 3 : 0)); // +x by vertex index
    /** @param {number} w0 @param {number} w1 */
    const morphed = (w0, w1) => STRIP.map((x, i) => x + w0 * d0[i] + w1 * d1[i]);
    const channel = { node: 'anchor', path: 'weights', times: [0, 2], values: [0, 0, 1, 0.5] };
    const spec = {
        splatMatrix: M,                                           // not applied: no skin
        anchorNode: { translation: [100, 0, 0] },                 // ignored
        morph: { deltas: [d0, d1], meshWeights: [0.5, 0] },
        animations: [{ name: 'linear', channels: [channel] },
            { name: 'step', channels: [{ ...channel, interpolation: 'STEP' }] },
            { name: 'cubic', channels: [{ ...channel, interpolation: 'CUBICSPLINE', values: [0, 0, 0, 0, 2, 0, /* key 1 */ 0, 0, 1, 0.5, 0, 0] }] }],
    };
    const { anim } = load(riggedGlb(spec));
    assert.equal(anim.skinned, false);
    assert.equal(anim.morphed, true);
    assert.equal(anim.targetCount, 2);
    assert.deepEqual(anim.animations.map((a) => a.name), ['linear', 'step', 'cubic']);
    close(anim.rest(), morphed(0.5, 0), 1e-6, 'rest: mesh weights');
    close(anim.sample(0, 1), morphed(0.5, 0.25), 1e-6, 'LINEAR t = 1');
    close(anim.sample(0, -3), morphed(0, 0), 1e-6, 'LINEAR clamped before');
    close(anim.sample(0, 9), morphed(1, 0.5), 1e-6, 'LINEAR clamped after');
    close(anim.sample(1, 1.5), morphed(0, 0), 1e-6, 'STEP');
    // cubic, s = 0.5, dt = 2: w0 = h10·2·2 + h01·1 = 0.5 + 0.5, w1 = h01·0.5
    close(anim.sample(2, 1), morphed(1, 0.25), 1e-6, 'CUBICSPLINE');
    const nodeWeights = load(riggedGlb({ ...spec, anchorNode: { weights: [0, 0.25] } })).anim;
    close(nodeWeights.rest(), morphed(0, 0.25), 1e-6, 'rest: node weights win');
});

test('skin and morph targets together: morphed first, then skinned', () => {
    const d0 = new Array(3 * V).fill(0).map((_, i) => (i % 3 === 1 ? 0.5 : 0));
    const { anim } = load(riggedGlb({
        skin: { nodes: [{ name: 'J' }], joints: [0], ibm: IDENTITY, influences: new Array(V).fill([0, 1]) },
        morph: { deltas: [d0] },
        animations: [{
            channels: [
                { node: 0, path: 'rotation', times: [0, 1], values: [...quatZ(0), ...quatZ(90)] },
                { node: 'anchor', path: 'weights', times: [0, 1], values: [0, 1] },
            ],
        }],
    }));
    close(anim.rest(), STRIP, 0, 'rest');
    close(anim.sample(0, 1), apply(rotZ(90), STRIP.map((x, i) => x + d0[i])), 1e-6, 't = 1');
});

test('a 10,000-deep node chain: no recursion, in readAnchoredGlb and in the sampler', () => {
    // listed deepest first (node k's child is node k - 1), so that solving a node before its
    // ancestors would recurse 10,000 deep; every link moves 0.001 up
    const DEPTH = 10000;
    const nodes = [];
    for (let k = 0; k < DEPTH; ++k) nodes.push({ translation: [0, 0.001, 0], ...(k > 0 ? { children: [k - 1] } : {}) });
    /** @param {number} y height of a chain node @returns {number} its index */
    const at = (y) => Math.round(DEPTH - y / 0.001);
    const bytes = riggedGlb({
        // the joint is the deepest node (y = 10); the splat node (node 0, read first) hangs
        // below the node at y = 9.999
        skin: { nodes, joints: [at(10)], ibm: translate(0, -0.001, 0), influences: new Array(V).fill([0, 1]) },
        // the joint moves, the splat node does not
        animations: [{ channels: [{ node: at(10), path: 'translation', times: [0, 1], values: [0, 0.001, 0, 1, 0.001, 0] }] }],
        patch: (json, _b, base) => {
            json.scenes[0].nodes = json.scenes[0].nodes.filter((/** @type {number} */ n) => n !== 0);
            json.nodes[base + at(9.999)].children.push(0);
        },
    });
    const { prim, anim } = load(bytes);
    close(prim.nodeMatrix || [], translate(0, 9.999, 0), 1e-9, 'splat node matrix');
    close(anim.rest(), STRIP, 1e-6, 'rest');
    close(anim.sample(0, 1), moved(1, 0, 0), 1e-6, 't = 1');
});

test('not animated: no node draws the anchor mesh, or it has neither skin nor morph targets', () => {
    const bare = anchoredGlb({ vertices: STRIP, indices: STRIP_FACES, profile: 'local', face: [0], bary: [0.25, 0.25] });
    assert.equal(readAnchorAnimation(bare, readAnchoredGlb(bare).anchored[0]), null);
    const plainNode = riggedGlb({});
    assert.equal(readAnchorAnimation(plainNode, readAnchoredGlb(plainNode).anchored[0]), null);
    // the parsed document works as well as the bytes
    const bytes = riggedGlb({ skin: twoJoints(IDENTITY) });
    const anim = readAnchorAnimation(parseGltf(bytes), readAnchoredGlb(bytes).anchored[0]);
    assert.ok(anim);
    assert.deepEqual(anim.animations, []);
    close(anim.rest(), STRIP, 1e-6, 'rest');
});

// ---------------------------------------------------------------------- refusals

const BEND = [{ channels: [/** @type {ChannelSpec} */ ({ node: 1, path: 'rotation', times: [0, 1], values: [...quatZ(0), ...quatZ(90)] })] }];

/** @param {(json: any, b: GltfBuilder, base: number) => void} patch @param {Partial<RigSpec>} [extra] */
const broken = (patch, extra = {}) => riggedGlb({ skin: twoJoints(IDENTITY), animations: BEND, patch, ...extra });

test('refused: malformed animation channels and samplers', () => {
    refuses(broken((json) => { json.animations[0].channels[0].target.node = 99; }), 'ANCHOR_ANIMATION_TARGET_INVALID', /node 99/);
    refuses(broken((json) => { json.animations[0].channels.push({ sampler: 0, target: { node: 1, path: 'weights' } }); }), 'ANCHOR_ANIMATION_TARGET_INVALID', /no morph targets/);
    refuses(broken((json) => { json.animations[0].channels[0].sampler = 3; }), 'UNRESOLVED_REFERENCE', /sampler 3/);
    refuses(broken((json) => { json.animations[0].samplers[0].interpolation = 'SMOOTH'; }), 'ANCHOR_ANIMATION_SAMPLER_INVALID', /SMOOTH/);
    // two key times, three output values
    refuses(broken((json, b) => { json.animations[0].samplers[0].output = b.accessor(new Float32Array(12), 'VEC4'); }), 'ANCHOR_ANIMATION_SAMPLER_INVALID', /3 values/);
    // CUBICSPLINE needs three values per key
    refuses(broken((json) => { json.animations[0].samplers[0].interpolation = 'CUBICSPLINE'; }), 'ANCHOR_ANIMATION_SAMPLER_INVALID', /needs 6/);
    refuses(broken((json, b) => { json.animations[0].samplers[0].input = b.accessor(Float32Array.from([1, 0]), 'SCALAR'); }), 'ANCHOR_ANIMATION_SAMPLER_INVALID', /increase/);
    refuses(broken((json, b) => { json.animations[0].samplers[0].input = b.accessor(new Float32Array(0), 'SCALAR'); }), 'ANCHOR_ANIMATION_SAMPLER_INVALID', /no key times/);
    refuses(broken((json, b) => { json.animations[0].samplers[0].input = b.accessor(Float32Array.from([0, NaN]), 'SCALAR'); }), 'NON_FINITE_VALUE', /input/);
    refuses(broken((json, b) => { json.animations[0].samplers[0].output = b.accessor(Float32Array.from([0, 0, 0, 1, 0, NaN, 0, 1]), 'VEC4'); }), 'NON_FINITE_VALUE', /output/);
    refuses(broken((json, b) => { json.animations[0].samplers[0].output = b.accessor(new Float32Array(6), 'VEC3'); }), 'ANCHOR_ANIMATION_SAMPLER_INVALID', /expected VEC4/);
});

test('refused: malformed skins and skin attributes', () => {
    refuses(broken((json) => { json.nodes[1].skin = 4; }), 'ANCHOR_SKIN_INVALID', /skin 4/);
    refuses(broken((json) => { json.skins[0].joints = [2, 500]; }), 'ANCHOR_SKIN_INVALID', /joints/);
    refuses(broken((json, b) => { json.skins[0].inverseBindMatrices = matrixAccessor(b, IDENTITY); }), 'ANCHOR_SKIN_INVALID', /1 matrices for 2 joints/);
    refuses(broken((json, b) => { json.skins[0].inverseBindMatrices = b.accessor(new Float32Array(8), 'VEC4'); }), 'ANCHOR_SKIN_INVALID', /MAT4/);
    refuses(broken((json, b) => { json.skins[0].inverseBindMatrices = matrixAccessor(b, [...IDENTITY, ...IDENTITY.map((x, i) => (i === 13 ? NaN : x))]); }), 'NON_FINITE_VALUE');
    refuses(broken((json, b) => {
        const j = new Uint8Array(4 * V); j[9] = 2;
        json.meshes[1].primitives[0].attributes.JOINTS_0 = b.accessor(j, 'VEC4');
    }), 'ANCHOR_SKIN_ATTRIBUTES_INVALID', /vertex 2 refers to joint 2 of a skin with 2 joints/);
    refuses(broken((json) => { delete json.meshes[1].primitives[0].attributes.WEIGHTS_0; }), 'ANCHOR_SKIN_ATTRIBUTES_INVALID', /JOINTS_0\/WEIGHTS_0/);
    refuses(broken((json, b) => { json.meshes[1].primitives[0].attributes.WEIGHTS_0 = b.accessor(new Float32Array(4 * (V - 1)), 'VEC4'); }), 'ANCHOR_SKIN_ATTRIBUTES_INVALID', /5 elements but POSITION has 6/);
    refuses(broken((json, b) => { json.meshes[1].primitives[0].attributes.JOINTS_0 = b.accessor(new Float32Array(4 * V), 'VEC4'); }), 'ANCHOR_SKIN_ATTRIBUTES_INVALID', /UNSIGNED_BYTE or UNSIGNED_SHORT/);
    refuses(broken((json, b) => { json.meshes[1].primitives[0].attributes.WEIGHTS_0 = b.accessor(new Uint8Array(4 * V), 'VEC4'); }), 'ANCHOR_SKIN_ATTRIBUTES_INVALID', /normalized/);
});

test('refused: morph targets and weights whose counts do not match', () => {
    const deltas = [new Array(3 * V).fill(0.1)];
    refuses(broken((json, b) => { json.meshes[1].primitives[0].targets[0].POSITION = b.accessor(new Float32Array(3 * (V - 1)), 'VEC3'); }, { morph: { deltas } }),
        'ANCHOR_MORPH_TARGETS_INVALID', /5 deltas/);
    refuses(broken(() => {}, { morph: { deltas, meshWeights: [0, 0] } }), 'ANCHOR_MORPH_TARGETS_INVALID', /2 default weights for 1 morph targets/);
    refuses(broken(() => {}, { morph: { deltas }, anchorNode: { weights: [] } }), 'ANCHOR_MORPH_TARGETS_INVALID', /0 default weights/);
    // a weights channel with two numbers per key for one target
    refuses(broken(() => {}, { morph: { deltas }, animations: [{ channels: [{ node: 'anchor', path: 'weights', times: [0, 1], values: [0, 0, 1, 1] }] }] }),
        'ANCHOR_ANIMATION_SAMPLER_INVALID', /4 values but 2 keys of 1 morph weights need 2/);
});

test('refused: a cycle in the node hierarchy above a joint', () => {
    const bytes = riggedGlb({ skin: twoJoints(IDENTITY), animations: BEND });
    const prim = readAnchoredGlb(bytes).anchored[0];
    const doc = parseGltf(bytes);
    doc.json.nodes[3].children = [2];   // A → B → A
    assert.throws(() => readAnchorAnimation(doc, prim, { name: 'case.glb' }), (/** @type {any} */ err) => err instanceof AnchorError && err.code === 'NODE_GRAPH_INVALID' && /cycle/.test(err.message));
});
