// Soft-body physics of the demo, in Node (no browser): welding, mapping back to the anchor vertex
// order, and the deterministic scripted pull / twist on the shipped example's anchor mesh.
//
//   node --test examples/web/test/physics.test.mjs

import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { weldVertices, weldFaces, isClosed, bounds, PhysicsWorld, SoftBodyMesh } from '../physics.js';

const HERE = path.dirname(fileURLToPath(import.meta.url));
const REPO = path.resolve(HERE, '..', '..', '..');
const EXAMPLE = path.join(REPO, 'examples', 'capsule', 'anchored.glb');
const JOLT = path.join(REPO, 'plugins', 'web', 'node_modules', 'jolt-physics', 'dist', 'jolt-physics.wasm-compat.js');

/** A unit cube whose faces have their own vertices (24 vertices, like a UV-split mesh). */
function splitCube() {
    const v = [], f = [];
    const quads = [
        [[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 0, 0]], [[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
        [[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]], [[0, 1, 0], [0, 1, 1], [1, 1, 1], [1, 1, 0]],
        [[0, 0, 0], [0, 0, 1], [0, 1, 1], [0, 1, 0]], [[1, 0, 0], [1, 1, 0], [1, 1, 1], [1, 0, 1]],
    ];
    for (const q of quads) {
        const b = v.length / 3;
        for (const p of q) v.push(...p);
        f.push(b, b + 1, b + 2, b, b + 2, b + 3);
    }
    return { vertices: new Float32Array(v), indices: new Uint32Array(f) };
}

test('welding merges duplicate positions and keeps the mesh closed', () => {
    const cube = splitCube();
    const weld = weldVertices(cube.vertices, 1e-6);
    assert.equal(weld.count, 8);
    const faces = weldFaces(cube.indices, weld.map);
    assert.equal(faces.length, 36);
    assert.equal(isClosed(faces), true);
    assert.equal(isClosed(cube.indices), false);        // unwelded, every edge is a border
    for (let i = 0; i < 24; i++) {
        for (let k = 0; k < 3; k++) assert.equal(weld.positions[3 * weld.map[i] + k], cube.vertices[3 * i + k]);
    }
});

test('degenerate and repeated faces are dropped', () => {
    const map = new Uint32Array([0, 1, 2, 2]);
    const faces = weldFaces(new Uint32Array([0, 1, 2, 1, 2, 3, 2, 1, 0]), map);
    assert.deepEqual([...faces], [0, 1, 2]);
});

const haveAssets = fs.existsSync(EXAMPLE) && fs.existsSync(JOLT);

test('scripted pull and twist of the example anchor mesh', { skip: !haveAssets && 'example asset or jolt-physics missing' }, async () => {
    const { readAnchoredGlb } = await import('../../../plugins/web/src/anchor.js');
    const { default: initJolt } = await import(JOLT);
    const Jolt = await initJolt();
    const { anchored } = readAnchoredGlb(new Uint8Array(fs.readFileSync(EXAMPLE)), { name: 'anchored.glb' });
    const mesh = anchored[0].anchorMesh;
    const world = new PhysicsWorld(Jolt, { groundY: -2 });
    const soft = new SoftBodyMesh(world, { vertices: mesh.vertices, indices: mesh.indices });
    const rest = bounds(soft.rest);

    // at rest, without gravity, nothing moves
    for (let i = 0; i < 60; i++) soft.step(1 / 60);
    const still = soft.readAnchorVertices();
    let drift = 0;
    for (let i = 0; i < still.length; i++) drift = Math.max(drift, Math.abs(still[i] - mesh.vertices[i]));
    assert.ok(drift < 1e-3, `rest drift ${drift}`);

    // pull 1.5x along y: the pinned caps set the extent, the sides stay sane
    soft.pull(1, 1.5);
    const pulled = soft.bounds();
    assert.ok(Math.abs(pulled.size[1] / rest.size[1] - 1.5) < 0.01, `y ${pulled.size[1] / rest.size[1]}`);
    for (const k of [0, 2]) assert.ok(pulled.size[k] / rest.size[k] > 0.6 && pulled.size[k] / rest.size[k] < 1.2, `axis ${k}`);
    const first = soft.positions().slice();
    soft.reset();
    soft.pull(1, 1.5);
    assert.deepEqual(soft.positions(), first, 'scripted poses are deterministic');

    // twist 90 degrees about y: length kept, cross-section kept (no collapse, no explosion)
    soft.reset();
    soft.twist(1, 90);
    const twisted = soft.bounds();
    assert.ok(Math.abs(twisted.size[1] / rest.size[1] - 1) < 0.01);
    for (const k of [0, 2]) assert.ok(twisted.size[k] / rest.size[k] > 0.85 && twisted.size[k] / rest.size[k] < 1.2, `axis ${k}`);

    // anchor order: every anchor vertex gets its welded vertex's position
    const out = soft.readAnchorVertices();
    const w = soft.positions();
    for (let i = 0; i < soft.anchorCount; i++) {
        for (let k = 0; k < 3; k++) assert.equal(out[3 * i + k], w[3 * soft.map[i] + k]);
    }

    // dropped onto the ground, it lands and stays above it
    soft.reset();
    world.setGround(rest.min[1] - 0.2 * rest.size[1]);
    soft.placeAt([0, 0.5 * rest.size[1], 0]);
    soft.setGravity(1);
    for (let i = 0; i < 240; i++) soft.step(1 / 60);
    const landed = soft.bounds();
    assert.ok(landed.min[1] > world.groundY - 0.05 * rest.size[1], `fell through: ${landed.min[1]} < ${world.groundY}`);
    assert.ok(landed.min[1] < world.groundY + 0.05 * rest.size[1], 'resting on the ground');
    soft.destroy();
});
