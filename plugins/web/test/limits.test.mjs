// The reader's limits on hostile inputs, every input built here: a node chain deeper than any
// call stack, node cycles, a data: URI past MAX_DATA_URI_BYTES (refused on the length of its
// text, before decoding), arrays past MAX_GLTF_ARRAY_ITEMS, and base64 decoding in one pass.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { AnchorError, readAnchoredGlb } from '../src/anchor.js';
import { MAX_DATA_URI_BYTES, MAX_GLTF_ARRAY_ITEMS, globalMatrices, parseGltf } from '../src/glb.js';
import { readPhysics } from '../src/physics.js';
import { anchoredBuilder, anchoredGlb } from './glb-writer.mjs';

/** @type {import('./glb-writer.mjs').AnchoredSpec} */
const TRIANGLE = { profile: 'local', face: [0], bary: [0.25, 0.25], vertices: [0, 0, 0, 1, 0, 0, 0, 1, 0], indices: [0, 1, 2] };

/**
 * The triangle asset with its splat node at the bottom of a chain of `depth` nodes, each
 * moving by 1 along x.
 * @param {number} depth
 */
function deepChain(depth) {
    return anchoredGlb({
        ...TRIANGLE,
        patch(json) {
            const first = json.nodes.length;
            for (let i = 0; i < depth; ++i) json.nodes.push({ children: [first + i + 1], translation: [1, 0, 0] });
            json.nodes.push({ mesh: 0 });
            json.nodes[0] = { name: 'unused' };
            json.scenes[0].nodes = [first];
        },
    });
}

/**
 * @param {() => unknown} fn
 * @param {string} code
 * @param {RegExp} message
 */
function refuses(fn, code, message) {
    assert.throws(fn, (/** @type {any} */ err) => {
        assert.ok(err instanceof AnchorError, `an AnchorError, not ${err && err.name}: ${err && err.message}`);
        assert.equal(err.code, code);
        assert.match(err.message, message);
        assert.doesNotMatch(err.message, /\n/);
        return true;
    });
}

test('a 90,000-deep node chain is read without recursion: the splat node\'s matrix composes every level', () => {
    const depth = 90000;
    const glb = deepChain(depth);
    const { anchored } = readAnchoredGlb(glb, { name: 'deep.glb' });
    assert.equal(anchored.length, 1);
    assert.equal(anchored[0].nodeMatrix?.[12], depth);
    const physics = readPhysics(glb, { name: 'deep.glb' });
    assert.ok(physics);
    const matrices = globalMatrices(parseGltf(glb).json);
    assert.equal(matrices[matrices.length - 1][12], depth);
});

test('node cycles and shared children are NODE_GRAPH_INVALID, one line naming the file', () => {
    const cycle = anchoredGlb({
        ...TRIANGLE,
        patch(json) {
            json.nodes.push({ children: [0] });   // 0 → 1 → 0: the splat node in a cycle
            json.nodes[0].children = [1];
        },
    });
    refuses(() => readAnchoredGlb(cycle, { name: 'cycle.glb' }), 'NODE_GRAPH_INVALID', /^cycle\.glb: the node hierarchy has a cycle/);
    const shared = anchoredGlb({
        ...TRIANGLE,
        patch(json) {
            json.nodes.push({ children: [0] }, { children: [0] });
        },
    });
    refuses(() => readAnchoredGlb(shared, { name: 'shared.glb' }), 'NODE_GRAPH_INVALID', /^shared\.glb: node 0 has more than one parent/);
});

/**
 * A .gltf document whose only buffer is a data: URI of `text`, as bytes.
 * @param {string} text
 */
function gltfWithUri(text) {
    return new TextEncoder().encode(`{"asset":{"version":"2.0"},"buffers":[{"byteLength":1,"uri":"data:application/octet-stream;base64,${text}"}]}`);
}

test('a data: URI past MAX_DATA_URI_BYTES is refused on its length, before it is decoded', () => {
    assert.equal(MAX_DATA_URI_BYTES, 2 ** 28);
    // 4/3 of the limit plus a block: about 341 MiB of text, one character repeated. Decoding
    // it would take a 256 MiB array; the refusal comes from the length alone.
    const text = 'A'.repeat((MAX_DATA_URI_BYTES / 3 + 1) * 4);
    const before = process.memoryUsage().arrayBuffers;
    const bytes = gltfWithUri(text);
    refuses(() => readAnchoredGlb(bytes, { name: 'big.gltf' }), 'DATA_URI_TOO_LARGE', /^big\.gltf: buffers\[0\]: data: URI holds about 26843545\d bytes, more than the limit of 268435456/);
    // the document's bytes themselves, and nothing of the decoded size on top
    assert.ok(process.memoryUsage().arrayBuffers - before < bytes.byteLength + MAX_DATA_URI_BYTES / 2);
});

test('base64 data: URIs decode in one pass; padding, whitespace and bad characters', () => {
    const decode = (/** @type {string} */ text) => parseGltf(gltfWithUri(text)).buffers[0];
    assert.deepEqual(Array.from(decode('AQ==')), [1]);
    assert.deepEqual(Array.from(decode('AQID')), [1]);
    assert.deepEqual(Array.from(decode('AQ ID\\n')), [1]);
    for (const bad of ['AQ=I', 'A', 'AQ===', 'AQ*D', 'AQ\u00e9D']) {
        refuses(() => readAnchoredGlb(gltfWithUri(bad), { name: 'b.gltf' }), 'URI_INVALID', /not valid base64/);
    }
    // 48 MiB of base64 (36 MiB of bytes) decodes in linear time: the same bytes come back
    const n = 36 * 2 ** 20;
    const raw = new Uint8Array(n);
    for (let i = 0; i < n; ++i) raw[i] = (i * 2654435761) >>> 24;
    const text = Buffer.from(raw).toString('base64');
    const back = new TextEncoder().encode(`{"asset":{"version":"2.0"},"buffers":[{"byteLength":${n},"uri":"data:;base64,${text}"}]}`);
    assert.deepEqual(Buffer.compare(Buffer.from(parseGltf(back).buffers[0]), Buffer.from(raw)), 0);
});

test('arrays past MAX_GLTF_ARRAY_ITEMS are SIZE_LIMIT_EXCEEDED before any member is read', () => {
    const b = anchoredBuilder(TRIANGLE);
    b.json.accessors = b.json.accessors.concat(new Array(MAX_GLTF_ARRAY_ITEMS).fill(0));
    refuses(() => readAnchoredGlb(b.glb(), { name: 'many.glb' }), 'SIZE_LIMIT_EXCEEDED', /^many\.glb: the document has 1000\d\d accessors, more than the limit of 100000/);
    const p = anchoredBuilder(TRIANGLE);
    p.json.meshes[1].primitives = new Array(MAX_GLTF_ARRAY_ITEMS + 1).fill(p.json.meshes[1].primitives[0]);
    refuses(() => readAnchoredGlb(p.glb(), { name: 'prims.glb' }), 'SIZE_LIMIT_EXCEEDED', /^prims\.glb: meshes\[1\] has 100001 primitives/);
});

test('splat primitives sharing one accessor past MAX_READ_AMPLIFICATION are SIZE_LIMIT_EXCEEDED before any is read', () => {
    // 4,000 splat primitives sharing the accessors of one 20,000-splat primitive: about
    // about 2 MB of buffer read 4,000 times over (8 GB), refused on the declared sizes
    const N = 20000;
    const b = anchoredBuilder({ ...TRIANGLE, face: new Array(N).fill(0), bary: new Array(2 * N).fill(0.25) });
    const prim = b.json.meshes[0].primitives[0];
    b.json.meshes[0].primitives = new Array(4000).fill(prim);
    const glb = b.glb();
    assert.ok(glb.byteLength < 2 ** 22);
    refuses(() => readAnchoredGlb(glb, { name: 'shared.glb' }), 'SIZE_LIMIT_EXCEEDED', /^shared\.glb: the splat primitives up to meshes\[0\]\.primitives\[\d+\] would read \d+ bytes of accessors, more than 4 times the \d+ bytes/);
    // within the limit: two primitives sharing them are read
    b.json.meshes[0].primitives = [prim, prim];
    assert.equal(readAnchoredGlb(b.glb()).anchored.length, 2);
});
