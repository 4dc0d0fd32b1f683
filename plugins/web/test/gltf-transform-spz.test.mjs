// The glTF-Transform SPZ extension (src/gltf-transform/spz-compression.js) on the demo's shipped
// compressed capsule (examples/web/capsule-spz.glb): a round trip through NodeIO, prune and dedup
// keep the stream byte for byte and the placeholders as they were, so the asset decodes to the
// same splats and derived anchors; writes refuse what a transform made inconsistent.
import test from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';

import { NodeIO } from '@gltf-transform/core';
import { ALL_EXTENSIONS } from '@gltf-transform/extensions';
import { dedup, prune } from '@gltf-transform/functions';

import { readAnchoredGlb, SPZ_EXTENSION } from '../src/anchor.js';
import { parseGltf } from '../src/glb.js';
import { expandCompressed } from '../src/spz.js';
import { SpzCompression, SpzCompressionError, gsverseExtensions } from '../src/gltf-transform/index.js';
import { KHR } from './glb-writer.mjs';

const CAPSULE = new Uint8Array(readFileSync(new URL('../../../examples/web/capsule-spz.glb', import.meta.url)));
const io = () => new NodeIO().registerExtensions([...ALL_EXTENSIONS, ...gsverseExtensions]);

/** The primitive's SPZ stream and its placeholders (JSON) of a GLB. @param {Uint8Array} bytes */
function compressed(bytes) {
    const doc = parseGltf(bytes);
    const json = doc.json;
    const prim = json.meshes[0].primitives[0];
    const view = json.bufferViews[prim.extensions[KHR].extensions[SPZ_EXTENSION].bufferView];
    const start = view.byteOffset || 0;
    const stream = doc.buffers[view.buffer].slice(start, start + view.byteLength);
    /** @type {Record<string, any>} */
    const placeholders = {};
    for (const [name, index] of Object.entries(prim.attributes)) {
        const { bufferView, byteOffset, name: _n, ...rest } = json.accessors[index];
        assert.equal(bufferView, undefined, `${name} stays a placeholder`);
        placeholders[name] = rest;
    }
    return { stream, placeholders, json };
}

/** @param {Uint8Array} out */
async function sameAsCapsule(out) {
    const a = compressed(CAPSULE);
    const b = compressed(out);
    assert.deepEqual(b.stream, a.stream);
    assert.deepEqual(b.placeholders, a.placeholders);
    assert.ok(b.json.extensionsUsed.includes(SPZ_EXTENSION));
    assert.deepEqual(b.json.extensionsRequired, [SPZ_EXTENSION]);
    const ra = readAnchoredGlb(await expandCompressed(CAPSULE)).anchored[0];
    const rb = readAnchoredGlb(await expandCompressed(out)).anchored[0];
    assert.deepEqual(rb.rest, ra.rest);
    assert.deepEqual(rb.faceIndex, ra.faceIndex);
    assert.deepEqual(rb.barycentrics, ra.barycentrics);
    assert.deepEqual(rb.localRotation, ra.localRotation);
}

test('a compressed asset survives a NodeIO round trip, prune and dedup', async () => {
    const doc = await io().readBinary(CAPSULE);
    const prim = doc.getRoot().listMeshes()[0].listPrimitives()[0];
    assert.ok(prim.getExtension(SPZ_EXTENSION) instanceof SpzCompression);
    await sameAsCapsule(await io().writeBinary(doc));
    await doc.transform(prune(), dedup());
    await sameAsCapsule(await io().writeBinary(doc));
});

test('what a transform made inconsistent with the stream is refused', async () => {
    /** @param {(doc: import('@gltf-transform/core').Document) => void} edit @param {RegExp} message */
    const refuses = async (edit, message) => {
        const doc = await io().readBinary(CAPSULE);
        edit(doc);
        await assert.rejects(io().writeBinary(doc), (/** @type {any} */ err) => {
            assert.ok(err instanceof SpzCompressionError, String(err));
            assert.match(err.message, message);
            assert.ok(!err.message.includes('\n'));
            return true;
        });
    };
    const prim = (/** @type {any} */ doc) => doc.getRoot().listMeshes()[0].listPrimitives()[0];
    await refuses((doc) => {
        const opacity = prim(doc).getAttribute(`${KHR}:OPACITY`);
        opacity.setArray(new Float32Array(opacity.getCount()).fill(0.5));
    }, /wrote values into its KHR_gaussian_splatting:OPACITY placeholder/);
    await refuses((doc) => {
        const color = prim(doc).getAttribute('COLOR_0');
        color.setArray(new Uint8Array(4 * 2999));
    }, /COLOR_0 has 2999 elements, the SPZ stream 3000 splats/);
    await refuses((doc) => { prim(doc).setAttribute('COLOR_0', null); }, /changed its attributes/);
});
