// The glTF-Transform extensions (src/gltf-transform): round trips through NodeIO keep the
// anchoring (checked with readAnchoredGlb and the CPU remap), prune and dedup keep the anchor
// mesh and accessors, and writes refuse what a transform made inconsistent.
import test from 'node:test';
import assert from 'node:assert/strict';

import { Document, NodeIO, Primitive } from '@gltf-transform/core';
import { ALL_EXTENSIONS } from '@gltf-transform/extensions';
import { dedup, prune, weld } from '@gltf-transform/functions';

import { readAnchoredGlb } from '../src/anchor.js';
import { computeRest } from '../src/rest.js';
import { remapCpu } from '../src/remap-cpu.js';
import {
    GSVERSEMeshAnchor, GaussianSplatting, KHRGaussianSplatting, MeshAnchor, MeshAnchorError, gsverseExtensions,
} from '../src/gltf-transform/index.js';
import { anchoredGlb, KHR, EXT } from './glb-writer.mjs';

/** @typedef {import('./glb-writer.mjs').AnchoredSpec} AnchoredSpec */
/** @typedef {import('../src/types.js').AnchoredPrimitive} AnchoredPrimitive */

/**
 * Four triangles of a unit square fan (vertex 2 in the middle, vertices numbered in order of first
 * use, as weld numbers them), two local splats on each.
 * @returns {AnchoredSpec}
 */
function localSpec() {
    const face = [0, 0, 1, 1, 2, 2, 3, 3];
    return {
        vertices: [0, 0, 0, 1, 0, 0, 0.5, 0.5, 0.1, 1, 1, 0, 0, 1, 0],
        indices: [0, 1, 2, 1, 3, 2, 3, 4, 2, 4, 0, 2],
        profile: 'local', deformation: 'rigid', face,
        bary: face.flatMap((_, i) => [0.2 + 0.05 * i, 0.3]),
        offset: face.map((_, i) => 0.01 * (i - 4)),
        rotation: face.flatMap((_, i) => { const a = 0.2 * i; return [0, Math.sin(a), 0, Math.cos(a)]; }),
        scale: face.flatMap((_, i) => [0.1, 0.05 + 0.01 * i, 0.01]),
        means: face.flatMap((_, i) => [0.1 * i, 0.2, 0.05]),
    };
}

/** @returns {AnchoredSpec} */
function gamesSpec() {
    return { ...localSpec(), profile: 'games', deformation: undefined, rho: [1, 2, 0.5, 1.5, 1, 1, 2, 0.25] };
}

const io = () => new NodeIO().registerExtensions([...ALL_EXTENSIONS, ...gsverseExtensions]);

/** A pose of the anchor mesh: every vertex moved differently. @param {Float32Array} v */
function pose(v) {
    const out = new Float32Array(v.length);
    for (let i = 0; i < v.length; i += 3) {
        out[i] = 1.3 * v[i] + 0.2 * v[i + 1];
        out[i + 1] = v[i + 1] - 0.4 * v[i] * v[i];
        out[i + 2] = v[i + 2] + 0.3 * v[i] + 0.1 * i;
    }
    return out;
}

/**
 * The remap of an anchored primitive at rest and at pose().
 * @param {AnchoredPrimitive} prim
 */
function remaps(prim) {
    const rest = computeRest(prim);
    return [remapCpu(prim, rest, prim.anchorMesh.vertices), remapCpu(prim, rest, pose(prim.anchorMesh.vertices))];
}

/**
 * The written asset anchors the same splats to the same triangles as the original.
 * @param {Uint8Array} original
 * @param {Uint8Array} written
 */
function assertSameAnchoring(original, written) {
    const a = readAnchoredGlb(original, { name: 'original.glb' });
    const b = readAnchoredGlb(written, { name: 'written.glb' });
    assert.equal(b.anchored.length, a.anchored.length);
    assert.equal(b.plain.length, a.plain.length);
    a.anchored.forEach((pa, k) => {
        const pb = b.anchored[k];
        assert.equal(pb.profile, pa.profile);
        assert.equal(pb.deformation, pa.deformation);
        assert.deepEqual(pb.anchorMesh.vertices, pa.anchorMesh.vertices);
        assert.deepEqual(pb.anchorMesh.indices, pa.anchorMesh.indices);
        assert.equal(pb.anchorMesh.node, null, 'the anchor mesh stays un-instantiated');
        for (const key of /** @type {const} */ (['faceIndex', 'barycentrics', 'normalOffset', 'localRotation', 'localScale', 'rho'])) {
            assert.deepEqual(pb[key], pa[key], key);
        }
        assert.deepEqual(pb.rest, pa.rest);
        const [restA, posedA] = remaps(pa);
        const [restB, posedB] = remaps(pb);
        assert.deepEqual(restB, restA);
        assert.deepEqual(posedB, posedA);
    });
}

for (const [name, spec] of /** @type {[string, () => AnchoredSpec][]} */ ([['local', localSpec], ['games', gamesSpec]])) {
    test(`NodeIO round trip keeps the ${name} anchoring`, async () => {
        const original = anchoredGlb(spec());
        const doc = await io().readBinary(original);
        const splatPrim = doc.getRoot().listMeshes()[0].listPrimitives()[0];
        const anchor = splatPrim.getExtension(EXT);
        assert.ok(anchor instanceof MeshAnchor);
        assert.equal(anchor.getProfile(), name);
        assert.equal(anchor.getMesh(), doc.getRoot().listMeshes()[1]);
        const splat = splatPrim.getExtension(KHR);
        assert.ok(splat instanceof GaussianSplatting);
        assert.equal(splat.getKernel(), 'ellipse');
        assertSameAnchoring(original, await io().writeBinary(doc));
    });
}

test('interleaved and quantized anchor accessors round trip', async () => {
    const spec = localSpec();
    spec.bary = Uint16Array.from(/** @type {number[]} */ (spec.bary), (x) => Math.round(x * 65535));
    spec.rotation = Int16Array.from(/** @type {number[]} */ (spec.rotation), (x) => Math.round(x * 32767));
    spec.normalized = { bary: true, rotation: true };
    spec.interleave = true;
    const original = anchoredGlb(spec);
    const written = await io().writeBinary(await io().readBinary(original));
    assertSameAnchoring(original, written);
    const b = readAnchoredGlb(written, { name: 'written.glb' });
    assert.equal(b.anchored[0].componentTypes.barycentrics, 'UNSIGNED_SHORT normalized');
});

test('prune and dedup keep the anchor mesh no node uses, and the anchor accessors', async () => {
    const original = anchoredGlb(localSpec());
    const doc = await io().readBinary(original);
    await doc.transform(prune(), dedup());
    assert.equal(doc.getRoot().listMeshes().length, 2);
    assertSameAnchoring(original, await io().writeBinary(doc));
});

test('without the extensions the anchoring is lost (why they must be registered)', async () => {
    const original = anchoredGlb(localSpec());
    const plainIO = new NodeIO().registerExtensions(ALL_EXTENSIONS);
    const doc = await plainIO.readBinary(original);
    await doc.transform(prune());
    const written = await plainIO.writeBinary(doc);
    const b = readAnchoredGlb(written, { name: 'written.glb' });
    assert.equal(b.anchored.length, 0);
    assert.equal(doc.getRoot().listMeshes().length, 1, 'prune dropped the anchor mesh');
});

/**
 * @param {Document} doc
 * @param {RegExp} pattern
 */
async function refuses(doc, pattern) {
    await assert.rejects(io().writeBinary(doc), (/** @type {any} */ err) => {
        assert.ok(err instanceof MeshAnchorError, `a MeshAnchorError, got ${err}`);
        assert.match(err.message, pattern);
        assert.ok(!err.message.includes('\n'), 'one line');
        return true;
    });
}

test('a transform that renumbers the anchor vertices is refused (weld)', async () => {
    const spec = localSpec();
    // Vertex 2 first in the index list: weld numbers vertices by first use, so it renumbers them.
    spec.indices = [2, 0, 1, 2, 1, 3, 2, 3, 4, 2, 4, 0];
    const doc = await io().readBinary(anchoredGlb(spec));
    await doc.transform(weld());
    await refuses(doc, /refusing to write meshes\[0\]\.primitives\[0\] \("splats"\): the anchor mesh's vertex positions changed \(vertex 0 differs\)/);
});

test('weld of an anchor mesh already in weld order writes it unchanged', async () => {
    const original = anchoredGlb(localSpec());
    const doc = await io().readBinary(original);
    await doc.transform(weld());
    assertSameAnchoring(original, await io().writeBinary(doc));
});

test('changed anchor triangles, vertices or splats are refused', async () => {
    const original = anchoredGlb(localSpec());
    /** @param {(doc: Document) => void} edit */
    const edited = async (edit) => { const doc = await io().readBinary(original); edit(doc); return doc; };
    const anchorPrim = (/** @type {Document} */ doc) => doc.getRoot().listMeshes()[1].listPrimitives()[0];
    const splatPrim = (/** @type {Document} */ doc) => doc.getRoot().listMeshes()[0].listPrimitives()[0];

    await refuses(await edited((doc) => {
        const indices = /** @type {import('@gltf-transform/core').Accessor} */ (anchorPrim(doc).getIndices());
        const a = /** @type {Uint32Array} */ (indices.getArray()).slice();
        a.set([a[3], a[4], a[5], a[0], a[1], a[2]]); // swap triangles 0 and 1
        indices.setArray(a);
    }), /triangles changed \(triangle 0 differs\).*faceIndex would name other triangles/);
    await refuses(await edited((doc) => {
        const position = /** @type {import('@gltf-transform/core').Accessor} */ (anchorPrim(doc).getAttribute('POSITION'));
        position.setArray(/** @type {Float32Array} */ (position.getArray()).subarray(0, 12).slice());
    }), /5 → 4 vertices/);
    await refuses(await edited((doc) => {
        const position = /** @type {import('@gltf-transform/core').Accessor} */ (splatPrim(doc).getAttribute('POSITION'));
        position.setArray(/** @type {Float32Array} */ (position.getArray()).subarray(0, 21).slice());
    }), /has 8 elements for 7 splats/);
    await refuses(await edited((doc) => {
        const position = /** @type {import('@gltf-transform/core').Accessor} */ (splatPrim(doc).getAttribute('POSITION'));
        const a = /** @type {Float32Array} */ (position.getArray()).slice();
        a.set([a[3], a[4], a[5], a[0], a[1], a[2]]); // splats 0 and 1 swapped
        position.setArray(a);
    }), /the splats' POSITION changed \(splat 0 differs\)/);
    await refuses(await edited((doc) => {
        doc.getRoot().listMeshes()[0].listPrimitives()[0].dispose();
    }), /no longer in the output/);
    await refuses(await edited((doc) => {
        doc.createNode('a').setMesh(doc.getRoot().listMeshes()[1]);
        doc.createNode('b').setMesh(doc.getRoot().listMeshes()[1]);
    }), /instantiated by 2 nodes/);
});

test('anchor accessors are never written sparse', async () => {
    const spec = localSpec();
    spec.face = spec.face.map(() => 0);
    const doc = await io().readBinary(anchoredGlb(spec));
    const anchor = /** @type {MeshAnchor} */ (doc.getRoot().listMeshes()[0].listPrimitives()[0].getExtension(EXT));
    for (const accessor of anchor.listAccessors()) accessor.setSparse(true);
    const written = await io().writeBinary(doc);
    const b = readAnchoredGlb(written, { name: 'written.glb' });
    assert.equal(b.anchored.length, 1);
    assert.ok(b.json.accessors.every((/** @type {any} */ a) => a.sparse === undefined));
});

test('an anchored asset made with the API', async () => {
    const doc = new Document();
    const buffer = doc.createBuffer();
    const khr = doc.createExtension(KHRGaussianSplatting);
    const ext = doc.createExtension(GSVERSEMeshAnchor);
    const acc = (/** @type {string} */ type, /** @type {any} */ array) => doc.createAccessor().setType(/** @type {any} */ (type)).setArray(array).setBuffer(buffer);
    const anchorMesh = doc.createMesh('anchor mesh').addPrimitive(doc.createPrimitive()
        .setAttribute('POSITION', acc('VEC3', new Float32Array([0, 0, 0, 1, 0, 0, 0, 1, 0])))
        .setIndices(acc('SCALAR', new Uint16Array([0, 1, 2]))));
    const scale = acc('VEC3', new Float32Array([0.1, 0.1, 0.01]));
    const prim = doc.createPrimitive().setMode(Primitive.Mode.POINTS)
        .setAttribute('POSITION', acc('VEC3', new Float32Array([0.25, 0.25, 0])))
        .setAttribute(`${KHR}:ROTATION`, acc('VEC4', new Float32Array([0, 0, 0, 1])))
        .setAttribute(`${KHR}:SCALE`, scale)
        .setAttribute(`${KHR}:OPACITY`, acc('SCALAR', new Float32Array([1])))
        .setAttribute(`${KHR}:SH_DEGREE_0_COEF_0`, acc('VEC3', new Float32Array([0.5, 0.5, 0.5])));
    prim.setExtension(KHR, khr.createGaussianSplatting().setKernel('ellipse').setColorSpace('srgb_rec709_display')
        .setProjection('perspective').setSortingMethod('cameraDistance'));
    const anchor = ext.createMeshAnchor().setMesh(anchorMesh).setProfile('local')
        .setAccessor('faceIndex', acc('SCALAR', new Uint8Array([0])))
        .setAccessor('barycentrics', acc('VEC2', new Float32Array([0.25, 0.25])))
        .setAccessor('normalOffset', acc('SCALAR', new Float32Array([0])))
        .setAccessor('localRotation', acc('VEC4', new Float32Array([0, 0, 0, 1])))
        .setAccessor('localScale', scale);
    prim.setExtension(EXT, anchor);
    doc.createScene().addChild(doc.createNode('splats').setMesh(doc.createMesh('splats').addPrimitive(prim)));
    const b = readAnchoredGlb(await io().writeBinary(doc), { name: 'api.glb' });
    assert.equal(b.anchored.length, 1);
    assert.deepEqual(Array.from(b.anchored[0].rest.means), [0.25, 0.25, 0]);
    const [restPose] = remaps(b.anchored[0]);
    assert.deepEqual(Array.from(restPose.means), [0.25, 0.25, 0]);

    anchor.setAccessor('faceIndex', acc('SCALAR', new Uint8Array([1])));
    await refuses(doc, /faceIndex\[0\] = 1 but the anchor mesh has 1 triangles/);
});

test('KHR properties this class does not model are kept; unregistered nested extensions are reported', async () => {
    const spec = localSpec();
    spec.patch = (json) => {
        const khr = json.meshes[0].primitives[0].extensions[KHR];
        khr.kernel = 'customShape';
        khr.futureProperty = { a: 1 };
        khr.extensions.VENDOR_other = { x: 1 };
    };
    /** @type {string[]} */
    const warnings = [];
    const logger = { debug() {}, info() {}, error() {}, warn: (/** @type {string} */ m) => warnings.push(m) };
    const doc = await io().setLogger(/** @type {any} */ (logger)).readBinary(anchoredGlb(spec));
    assert.ok(warnings.some((m) => m.includes('"VENDOR_other" is not registered')), warnings.join('; '));
    const out = readAnchoredGlb(await io().writeBinary(doc), { name: 'w.glb' });
    const khr = out.json.meshes[0].primitives[0].extensions[KHR];
    assert.equal(khr.kernel, 'customShape');
    assert.deepEqual(khr.futureProperty, { a: 1 });
    assert.deepEqual(Object.keys(khr.extensions), [EXT]);
    assert.deepEqual(out.json.extensionsUsed.sort(), [EXT, KHR]);
});

test('compact anchors (faceCounts, derived local anchors) round trip; broken counts are refused', async () => {
    const counts = [2, 2, 2, 2];
    const compact = { ...localSpec(), faceCounts: Uint8Array.from(counts), derived: true };
    const original = anchoredGlb(compact);
    const doc = await io().readBinary(original);
    await doc.transform(prune(), dedup());
    const written = await io().writeBinary(doc);
    assertSameAnchoring(original, written);
    const b = readAnchoredGlb(written, { name: 'written.glb' });
    assert.equal(b.anchored[0].faceEncoding, 'faceCounts');
    assert.equal(b.anchored[0].derived, true);
    const ext = b.json.meshes[0].primitives[0].extensions[KHR].extensions[EXT];
    assert.deepEqual(Object.keys(ext).sort(), ['deformation', 'faceCounts', 'mesh', 'primitive', 'profile']);
    const games = anchoredGlb({ ...gamesSpec(), faceCounts: Uint16Array.from(counts) });
    assertSameAnchoring(games, await io().writeBinary(await io().readBinary(games)));

    /** @param {(anchor: MeshAnchor, doc: Document) => void} edit */
    const edited = async (edit) => {
        const d = await io().readBinary(original);
        edit(/** @type {MeshAnchor} */ (d.getRoot().listMeshes()[0].listPrimitives()[0].getExtension(EXT)), d);
        return d;
    };
    const counted = (/** @type {MeshAnchor} */ a) => /** @type {import('@gltf-transform/core').Accessor} */ (a.getAccessor('faceCounts'));
    await refuses(await edited((a) => counted(a).setArray(Uint8Array.from([2, 2, 2, 1]))), /faceCounts add up to 7, not the 8 splats/);
    await refuses(await edited((a) => counted(a).setArray(Uint8Array.from([2, 2, 2, 2, 0]))), /faceCounts accessor has 5 elements for 4 triangles/);
    await refuses(await edited((a, d) => a.setAccessor('faceIndex', d.createAccessor().setType('SCALAR').setArray(new Uint8Array(8)))), /both faceIndex and faceCounts/);
    await refuses(await edited((a, d) => a.setAccessor('normalOffset', d.createAccessor().setType('SCALAR').setArray(new Float32Array(8)))), /normalOffset but no barycentrics/);
});
