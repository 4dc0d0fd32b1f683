// readAnchoredGlb: the container, accessors (byteStride, byteOffset, bounds, dequantization),
// .gltf with data: URIs, and every refusal of spec/conformance.md with its code.
import test from 'node:test';
import assert from 'node:assert/strict';

import { AnchorError, readAnchoredGlb } from '../src/anchor.js';
import { dequantize, parseGltf } from '../src/glb.js';
import { remapCpu } from '../src/remap-cpu.js';
import { GltfBuilder, anchoredBuilder, anchoredGlb, KHR, EXT } from './glb-writer.mjs';

/** @typedef {import('./glb-writer.mjs').AnchoredSpec} AnchoredSpec */

/** Two triangles of a unit square, one local splat on each. @returns {AnchoredSpec} */
function localSpec() {
    return {
        vertices: [0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0],
        indices: [0, 1, 2, 0, 2, 3],
        profile: 'local', deformation: 'affine',
        face: [0, 1], bary: [0.25, 0.25, 0.5, 0.25], offset: [0.1, -0.1],
        rotation: [0, 0, 0, 2, 0, 0.6, 0, 0.8], scale: [0.1, 0.2, 0.01, 0.3, 0.1, 0.01],
        means: [0.5, 0.25, 0.1, 0.75, 0.75, -0.1],
    };
}

/** @returns {AnchoredSpec} */
function gamesSpec() {
    return { ...localSpec(), profile: 'games', deformation: undefined, rho: [1, 2] };
}

/** @param {Uint8Array} bytes */
const read = (bytes) => readAnchoredGlb(bytes, { name: 'case.glb' });

/**
 * @param {Uint8Array} bytes
 * @param {string} code
 */
function refuses(bytes, code) {
    assert.throws(() => read(bytes), (/** @type {any} */ err) => {
        assert.ok(err instanceof AnchorError, `an AnchorError, got ${err}`);
        assert.equal(err.code, code, err.message);
        assert.ok(err.message.startsWith('case.glb: '), `message names the file: ${err.message}`);
        assert.ok(!err.message.includes('\n'), 'one line');
        return true;
    });
}

/** @param {(json: any, b: GltfBuilder) => void} patch @param {AnchoredSpec} [spec] */
const patched = (patch, spec = localSpec()) => anchoredGlb({ ...spec, patch });
/** @param {any} json */
const anchorExt = (json) => json.meshes[0].primitives[0].extensions[KHR].extensions[EXT];

test('reads a local asset: rest pose, anchor mesh, anchors, normalized quaternions', () => {
    const { anchored, plain } = read(anchoredGlb({ ...localSpec(), shDegree: 1 }));
    assert.equal(anchored.length, 1);
    assert.deepEqual(plain, []);
    const p = anchored[0];
    assert.equal(p.count, 2);
    assert.equal(p.profile, 'local');
    assert.equal(p.deformation, 'affine');
    assert.equal(p.shDegree, 1);
    assert.equal(p.shCoefficients, 4);
    assert.equal(p.rest.sh.length, 2 * 4 * 3);
    // coefficient-major: sh[(i*K + k)*3 + c] = k + (3i + c)/1000 as written
    assert.ok(Math.abs(p.rest.sh[(1 * 4 + 2) * 3 + 1] - (2 + 4 / 1000)) < 1e-6);
    assert.deepEqual(Array.from(p.anchorMesh.indices), [0, 1, 2, 0, 2, 3]);
    assert.equal(p.anchorMesh.faceCount, 2);
    assert.equal(p.anchorMesh.indexed, true);
    assert.equal(p.anchorMesh.node, null);
    assert.deepEqual(Array.from(p.faceIndex), [0, 1]);
    assert.deepEqual(Array.from(/** @type {Float32Array} */ (p.localRotation)), [0, 0, 0, 1, 0, 0.6000000238418579, 0, 0.800000011920929]);
    assert.equal(p.node, 0);
    assert.deepEqual(Array.from(/** @type {Float64Array} */ (p.nodeMatrix)), [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]);
    assert.deepEqual(p.componentTypes, { faceIndex: 'UNSIGNED_BYTE', barycentrics: 'FLOAT', normalOffset: 'FLOAT', localRotation: 'FLOAT', localScale: 'FLOAT' });
});

test('reads a games asset; a plain KHR primitive is listed as plain', () => {
    const bytes = anchoredGlb({
        ...gamesSpec(),
        patch: (json) => {
            const copy = JSON.parse(JSON.stringify(json.meshes[0]));
            delete copy.primitives[0].extensions[KHR].extensions;
            json.meshes.push(copy);
        },
    });
    const { anchored, plain } = read(bytes);
    assert.equal(anchored[0].profile, 'games');
    assert.equal(anchored[0].deformation, null);
    assert.deepEqual(Array.from(/** @type {Float32Array} */ (anchored[0].rho)), [1, 2]);
    assert.equal(anchored[0].localRotation, null);
    assert.deepEqual(plain, [{ mesh: 2, primitive: 0 }]);
});

test('the same asset as .gltf with a base64 data: URI; other URIs are refused', () => {
    const b = anchoredBuilder(localSpec());
    const glb = read(b.glb()).anchored[0];
    const gltf = read(b.gltf()).anchored[0];
    assert.deepEqual(gltf.rest.means, glb.rest.means);
    assert.deepEqual(gltf.barycentrics, glb.barycentrics);
    const json = JSON.parse(new TextDecoder().decode(b.gltf()));
    json.buffers[0].uri = 'splats.bin';
    refuses(new TextEncoder().encode(JSON.stringify(json)), 'URI_SCHEME_REJECTED');
    json.buffers[0].uri = 'https://example.com/splats.bin';
    refuses(new TextEncoder().encode(JSON.stringify(json)), 'URI_SCHEME_REJECTED');
});

test('quantized anchors: normalized barycentrics, rotations and local scales dequantize per glTF §3.11', () => {
    const spec = {
        ...localSpec(),
        bary: Uint16Array.from([16384, 16384, 32768, 16384]),
        rotation: Int8Array.from([0, 0, 0, 127, 0, -128, 0, 127]),
        scale: Uint8Array.from([255, 51, 0, 10, 20, 30]),
        normalized: { bary: true, rotation: true, scale: true },
    };
    const p = read(anchoredGlb(spec)).anchored[0];
    assert.deepEqual(Array.from(p.barycentrics), Array.from([16384, 16384, 32768, 16384], (c) => Math.fround(c / 65535)));
    // -128/127 clamps to -1, then (0, -1, 0, 1) normalizes to (0, -0.7071, 0, 0.7071)
    const q = /** @type {Float32Array} */ (p.localRotation);
    assert.ok(Math.abs(q[5] + Math.SQRT1_2) < 1e-7 && Math.abs(q[7] - Math.SQRT1_2) < 1e-7, `${q}`);
    assert.deepEqual(Array.from(/** @type {Float32Array} */ (p.localScale)), [1, 0.2, 0, 10 / 255, 20 / 255, 30 / 255].map(Math.fround));
    assert.equal(p.componentTypes.barycentrics, 'UNSIGNED_SHORT normalized');
    assert.equal(p.componentTypes.localRotation, 'BYTE normalized');
    // b0 = 1 - b1 - b2 from the dequantized values: the mean uses them
    const out = remapCpu(p, null, p.anchorMesh.vertices);
    const b1 = 16384 / 65535, b2 = 16384 / 65535;
    assert.ok(Math.abs(out.means[0] - (b1 * 1 + b2 * 1)) < 1e-7, `mean x ${out.means[0]}`);
    // integer, not normalized local scales are used as they are
    const raw = read(anchoredGlb({ ...localSpec(), scale: Uint16Array.from([1, 2, 3, 4, 5, 6]) })).anchored[0];
    assert.deepEqual(Array.from(/** @type {Float32Array} */ (raw.localScale)), [1, 2, 3, 4, 5, 6]);
    const u8 = read(anchoredGlb({ ...gamesSpec(), bary: Uint8Array.from([51, 102, 0, 255]), normalized: { bary: true } })).anchored[0];
    assert.deepEqual(Array.from(u8.barycentrics), [0.2, 0.4, 0, 1].map(Math.fround));
});

test('FLOAT localRotation is normalized too', () => {
    const p = read(anchoredGlb({ ...localSpec(), rotation: [0, 0, 0, 1.00001, 0, 0, 0, 0.5] })).anchored[0];
    assert.deepEqual(Array.from(/** @type {Float32Array} */ (p.localRotation)), [0, 0, 0, 1, 0, 0, 0, 1]);
});

test('interleaved anchor accessors with byteStride read the same values', () => {
    const a = read(anchoredGlb(localSpec())).anchored[0];
    const b = read(anchoredGlb({ ...localSpec(), interleave: true })).anchored[0];
    const json = read(anchoredGlb({ ...localSpec(), interleave: true })).json;
    assert.ok(json.bufferViews.some((/** @type {any} */ v) => v.byteStride), 'a strided view');
    for (const key of /** @type {const} */ (['faceIndex', 'barycentrics', 'normalOffset', 'localRotation', 'localScale'])) {
        assert.deepEqual(b[key], a[key], key);
    }
});

test('a non-indexed anchor mesh synthesizes indices 0..3F-1', () => {
    const spec = { ...localSpec(), vertices: [0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 0, 0, 1, 1, 0, 0, 1, 0], indices: null };
    const p = read(anchoredGlb(spec)).anchored[0];
    assert.equal(p.anchorMesh.indexed, false);
    assert.deepEqual(Array.from(p.anchorMesh.indices), [0, 1, 2, 3, 4, 5]);
    const indexed = read(anchoredGlb(localSpec())).anchored[0];
    assert.deepEqual(remapCpu(p, null, p.anchorMesh.vertices), remapCpu(indexed, null, indexed.anchorMesh.vertices));
    refuses(anchoredGlb({ ...spec, vertices: spec.vertices.slice(0, 15) }), 'ANCHOR_MESH_INDICES_INVALID');
});

test('the splat node global matrix composes parents; the anchor node transform is recorded, not applied', () => {
    const bytes = patched((json) => {
        json.nodes[0].translation = [1, 2, 3];
        json.nodes.push({ children: [0], scale: [2, 2, 2] });
        json.nodes.push({ mesh: 1, translation: [100, 0, 0] });
    });
    const p = read(bytes).anchored[0];
    assert.deepEqual(Array.from(/** @type {Float64Array} */ (p.nodeMatrix)), [2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 2, 4, 6, 1]);
    assert.equal(p.anchorMesh.node, 2);
    assert.deepEqual(Array.from(p.anchorMesh.vertices.subarray(0, 3)), [0, 0, 0]);
});

test('dequantize: every normalized type, clamping of the most negative code', () => {
    /** @param {any} values @param {number} componentType */
    const raw = (values, componentType) => ({ index: 0, type: 'SCALAR', componentType, normalized: true, count: values.length, ncomp: 1, values });
    assert.deepEqual(Array.from(dequantize(raw(Int8Array.from([-128, -127, 0, 127]), 5120))), [-1, -1, 0, 1]);
    assert.deepEqual(Array.from(dequantize(raw(Int16Array.from([-32768, 32767]), 5122))), [-1, 1]);
    assert.deepEqual(Array.from(dequantize(raw(Uint8Array.from([0, 255]), 5121))), [0, 1]);
    assert.deepEqual(Array.from(dequantize(raw(Uint16Array.from([65535]), 5123))), [1]);
});

test('container errors: bad magic, truncation, length mismatch, unsupported version', () => {
    const good = anchoredGlb(localSpec());
    const bad = good.slice();
    bad[0] = 0x78;
    refuses(bad, 'FILE_TYPE_UNSUPPORTED');
    refuses(good.slice(0, good.length - 8), 'GLB_TRUNCATED');
    const longer = new Uint8Array(good.length + 4);
    longer.set(good);
    refuses(longer, 'GLB_LENGTH_MISMATCH');
    const v3 = good.slice();
    v3[4] = 3;
    refuses(v3, 'GLB_UNSUPPORTED_VERSION');
    assert.throws(() => parseGltf(new Uint8Array([0x67, 0x6c, 0x54, 0x46])), /GLB/);
});

// Every refusal of spec/conformance.md §What a plugin must implement, with its code.
/** @type {[string, string, (json: any, b: GltfBuilder) => void, AnchoredSpec?][]} */
const REFUSALS = [
    ['splat primitive not POINTS', 'KHR_PRIMITIVE_NOT_POINTS', (j) => { j.meshes[0].primitives[0].mode = 4; }],
    ['anchor mesh index out of range', 'UNRESOLVED_REFERENCE', (j) => { anchorExt(j).mesh = 7; }],
    ['anchor primitive index out of range', 'UNRESOLVED_REFERENCE', (j) => { anchorExt(j).primitive = 1; }],
    ['anchor mesh not TRIANGLES', 'ANCHOR_MESH_NOT_TRIANGLES', (j) => { j.meshes[1].primitives[0].mode = 5; }],
    ['anchor mesh instantiated twice', 'ANCHOR_MESH_MULTIPLE_INSTANCES', (j) => { j.nodes.push({ mesh: 1 }, { mesh: 1 }); }],
    ['anchor POSITION not FLOAT', 'ANCHOR_MESH_POSITION_INVALID', (j, b) => { j.meshes[1].primitives[0].attributes.POSITION = b.accessor(new Uint16Array(12), 'VEC3'); }],
    ['anchor POSITION missing', 'ANCHOR_MESH_POSITION_INVALID', (j) => { j.meshes[1].primitives[0].attributes = {}; }],
    ['index count not a multiple of 3', 'ANCHOR_MESH_INDICES_INVALID', (j, b) => { j.meshes[1].primitives[0].indices = b.accessor(Uint16Array.from([0, 1, 2, 3]), 'SCALAR'); }],
    ['index out of range', 'ANCHOR_MESH_INDICES_INVALID', (j, b) => { j.meshes[1].primitives[0].indices = b.accessor(Uint16Array.from([0, 1, 2, 0, 2, 4]), 'SCALAR'); }],
    ['signed indices', 'ANCHOR_MESH_INDICES_INVALID', (j, b) => { j.meshes[1].primitives[0].indices = b.accessor(Int16Array.from([0, 1, 2, 0, 2, 3]), 'SCALAR'); }],
    ['unknown profile', 'ANCHOR_SCHEMA_VIOLATION', (j) => { anchorExt(j).profile = 'global'; }],
    ['unknown deformation', 'ANCHOR_SCHEMA_VIOLATION', (j) => { anchorExt(j).deformation = 'elastic'; }],
    ['games with deformation', 'ANCHOR_SCHEMA_VIOLATION', (j) => { anchorExt(j).deformation = 'affine'; }, gamesSpec()],
    ['local without localRotation', 'ANCHOR_SCHEMA_VIOLATION', (j) => { delete anchorExt(j).localRotation; }],
    ['games without rho', 'ANCHOR_SCHEMA_VIOLATION', (j) => { delete anchorExt(j).rho; }, gamesSpec()],
    ['extension not an object', 'ANCHOR_SCHEMA_VIOLATION', (j) => { j.meshes[0].primitives[0].extensions[KHR].extensions[EXT] = 3; }],
    ['barycentrics signed byte', 'ANCHOR_ACCESSOR_FORMAT', (j, b) => { anchorExt(j).barycentrics = b.accessor(new Int8Array(4), 'VEC2', { normalized: true }); }],
    ['faceIndex float', 'ANCHOR_ACCESSOR_FORMAT', (j, b) => { anchorExt(j).faceIndex = b.accessor(new Float32Array(2), 'SCALAR'); }],
    ['faceIndex normalized', 'ANCHOR_ACCESSOR_FORMAT', (j, b) => { anchorExt(j).faceIndex = b.accessor(new Uint8Array(2), 'SCALAR', { normalized: true }); }],
    ['normalOffset quantized', 'ANCHOR_ACCESSOR_FORMAT', (j, b) => { anchorExt(j).normalOffset = b.accessor(new Int16Array(2), 'SCALAR', { normalized: true }); }],
    ['rho quantized', 'ANCHOR_ACCESSOR_FORMAT', (j, b) => { anchorExt(j).rho = b.accessor(new Uint8Array(2), 'SCALAR', { normalized: true }); }, gamesSpec()],
    ['localRotation VEC3', 'ANCHOR_ACCESSOR_FORMAT', (j, b) => { anchorExt(j).localRotation = b.accessor(new Float32Array(6), 'VEC3'); }],
    ['barycentrics unnormalized UNSIGNED_SHORT', 'ANCHOR_ACCESSOR_FORMAT', (j, b) => { anchorExt(j).barycentrics = b.accessor(new Uint16Array(4), 'VEC2'); }],
    ['anchor count mismatch', 'ANCHOR_ACCESSOR_COUNT', (j, b) => { anchorExt(j).normalOffset = b.accessor(new Float32Array(3), 'SCALAR'); }],
    ['sparse anchor accessor', 'ACCESSOR_UNSUPPORTED', (j) => { j.accessors[anchorExt(j).barycentrics].sparse = { count: 1, indices: { bufferView: 0, componentType: 5121 }, values: { bufferView: 0 } }; }],
    ['accessor out of bounds', 'ACCESSOR_OUT_OF_BOUNDS', (j) => { j.accessors[anchorExt(j).barycentrics].byteOffset = 8; }],
    ['accessor misaligned', 'ACCESSOR_MISALIGNED', (j) => { j.accessors[anchorExt(j).barycentrics].byteOffset = 2; }],
    ['byteStride smaller than the element', 'BUFFER_VIEW_STRIDE_INVALID', (j) => { j.bufferViews[j.accessors[anchorExt(j).barycentrics].bufferView].byteStride = 4; }],
    ['faceIndex out of range', 'ANCHOR_FACE_OUT_OF_RANGE', (j, b) => { anchorExt(j).faceIndex = b.accessor(Uint8Array.from([0, 2]), 'SCALAR'); }],
    ['zero localRotation', 'ROTATION_NOT_UNIT', (j, b) => { anchorExt(j).localRotation = b.accessor(Float32Array.from([0, 0, 0, 1, 0, 0, 0, 0]), 'VEC4'); }],
    ['zero quantized localRotation', 'ROTATION_NOT_UNIT', (j, b) => { anchorExt(j).localRotation = b.accessor(Int16Array.from([0, 0, 0, 0, 0, 0, 0, 9]), 'VEC4', { normalized: true }); }],
    ['negative localScale', 'SCALE_NEGATIVE', (j, b) => { anchorExt(j).localScale = b.accessor(Float32Array.from([0.1, 0.1, 0.1, 0.1, -0.001, 0.1]), 'VEC3'); }],
    ['non-finite normal offset', 'NON_FINITE_VALUE', (j, b) => { anchorExt(j).normalOffset = b.accessor(Float32Array.from([0, NaN]), 'SCALAR'); }],
    ['non-finite rho', 'NON_FINITE_VALUE', (j, b) => { anchorExt(j).rho = b.accessor(Float32Array.from([Infinity, 1]), 'SCALAR'); }, gamesSpec()],
    ['non-finite anchor vertex', 'NON_FINITE_VALUE', (j, b) => { j.meshes[1].primitives[0].attributes.POSITION = b.accessor(Float32Array.from([0, 0, 0, 1, 0, 0, 1, 1, 0, 0, -Infinity, 0]), 'VEC3'); }],
    ['non-finite rest POSITION', 'NON_FINITE_VALUE', (j, b) => { j.meshes[0].primitives[0].attributes.POSITION = b.accessor(Float32Array.from([0, 0, 0, NaN, 0, 0]), 'VEC3'); }],
    ['non-finite rest ROTATION', 'NON_FINITE_VALUE', (j, b) => { j.meshes[0].primitives[0].attributes[`${KHR}:ROTATION`] = b.accessor(Float32Array.from([0, 0, 0, 1, 0, 0, NaN, 1]), 'VEC4'); }],
    ['non-finite rest SCALE', 'NON_FINITE_VALUE', (j, b) => { j.meshes[0].primitives[0].attributes[`${KHR}:SCALE`] = b.accessor(Float32Array.from([0, 0, 0, 1, Infinity, 1]), 'VEC3'); }],
    ['rest attribute missing', 'KHR_ATTRIBUTE_MISSING', (j) => { delete j.meshes[0].primitives[0].attributes[`${KHR}:OPACITY`]; }],
    ['rest attribute count mismatch', 'ATTRIBUTE_COUNT_MISMATCH', (j, b) => { j.meshes[0].primitives[0].attributes[`${KHR}:OPACITY`] = b.accessor(new Float32Array(3), 'SCALAR'); }],
    ['partial SH degree', 'KHR_SH_INCOMPLETE', (j, b) => { j.meshes[0].primitives[0].attributes[`${KHR}:SH_DEGREE_1_COEF_0`] = b.accessor(new Float32Array(6), 'VEC3'); }],
];

for (const [label, code, patch, spec] of REFUSALS) {
    test(`refuses: ${label} (${code})`, () => refuses(patched(patch, spec), code));
}

test('faces degenerate at rest are not refused', () => {
    const spec = { ...localSpec(), vertices: [0, 0, 0, 1, 0, 0, 2, 0, 0, 0, 1, 0] };
    const p = read(anchoredGlb(spec)).anchored[0];
    assert.equal(p.anchorMesh.faceCount, 2);
});

test('an asset without anchors gives no anchored primitives', () => {
    const bytes = patched((json) => { delete json.meshes[0].primitives[0].extensions[KHR].extensions; });
    const { anchored, plain } = read(bytes);
    assert.equal(anchored.length, 0);
    assert.deepEqual(plain, [{ mesh: 0, primitive: 0 }]);
});
