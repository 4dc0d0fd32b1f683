// The physics scene of the demo in Node (no browser): the shipped scene.glb's records read by the
// plugin (readPhysics), its rigid, kinematic and soft objects and its ground box in one Jolt world
// (rigid.js beside physics.js), stepped a fixed number of fixed steps.
//
//   node --test examples/web/test/rigid.test.mjs

import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { haveJolt, jolt } from './jolt.mjs';
import { PhysicsWorld, SoftBodyMesh, bounds } from '../physics.js';
import { RigidObject, RigidDrag, decomposeAffine, rotate } from '../rigid.js';

const HERE = path.dirname(fileURLToPath(import.meta.url));
const REPO = path.resolve(HERE, '..', '..', '..');
const SCENE = path.join(REPO, 'examples', 'web', 'scene.glb');
const skip = !haveJolt ? 'jolt-physics is not installed (npm ci in plugins/web)' : !fs.existsSync(SCENE) ? 'examples/web/scene.glb is missing' : false;
const DT = 1 / 60;
/** how high the test lifts the objects before they fall (world units) */
const LIFT = 0.6;

/** The scene's objects in one world, as the demo builds them. */
async function buildScene() {
    const { readPhysics } = await import('../../../plugins/web/src/index.js');
    const { readAnchoredGlb } = await import('../../../plugins/web/src/anchor.js');
    const bytes = new Uint8Array(fs.readFileSync(SCENE));
    const records = readPhysics(bytes, { name: 'scene.glb' });
    const { anchored } = readAnchoredGlb(bytes, { name: 'scene.glb' });
    const world = new PhysicsWorld(await jolt());
    const all = records.objects.flatMap((o) => Array.from(o.collider.vertices));
    const b = bounds(all);
    world.setFrame(b.center, 1 / Math.max(...b.size));
    const g = records.shapes[0], d = decomposeAffine(g.matrix);
    world.setGroundBox(d.translation, /** @type {number[]} */ (g.size).map((v) => 0.5 * v), d.rotation);
    /** @type {{[name: string]: any}} */
    const objects = {};
    for (const o of records.objects) {
        if (o.kind === 'soft') {
            const prim = /** @type {any} */ (anchored.find((p) => p.node === o.node));
            const soft = new SoftBodyMesh(world, { vertices: prim.anchorMesh.vertices, indices: prim.anchorMesh.indices });
            soft.setGravity(1);
            objects[o.name] = soft;
        } else {
            objects[o.name] = new RigidObject(world, o, o.matrix);
        }
    }
    const step = (/** @type {number} */ n) => {
        for (let i = 0; i < n; i++) {
            for (const r of Object.values(objects)) r.prepare(DT);
            world.step(DT);
        }
    };
    return { world, objects, step, groundTop: world.groundY, slop: 0.02 / world.unit };
}

test('decomposeAffine and rotate: a turned, scaled, moved node', () => {
    const c = Math.cos(0.5), s = Math.sin(0.5);
    // rotation of 1 rad about y, scale (2, 3, 4), translation (1, 2, 3), column-major
    const m = [c * 2, 0, -s * 2, 0, 0, 3, 0, 0, s * 4, 0, c * 4, 0, 1, 2, 3, 1];
    const d = decomposeAffine(m);
    assert.deepEqual(d.translation, [1, 2, 3]);
    d.scale.forEach((v, k) => assert.ok(Math.abs(v - [2, 3, 4][k]) < 1e-12));
    const r = rotate(d.rotation, [1, 0, 0]);
    [c, 0, -s].forEach((v, k) => assert.ok(Math.abs(r[k] - v) < 1e-12, `${r}`));
    assert.throws(() => decomposeAffine([-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]), /mirrored/);
});

test('the scene, dropped: the rigid chair falls onto the ground and rests, the kinematic lamp stays, the soft pillow lands', { skip }, async () => {
    const { objects, step, groundTop, slop } = await buildScene();
    const chair = objects.chair, lamp = objects.lamp, pillow = objects.pillow;
    assert.equal(chair.kind, 'rigid');
    assert.equal(lamp.kind, 'kinematic');
    // the file stands them on the floor: lift them (as the demo's drop does)
    chair.reset([0, LIFT, 0]);
    pillow.placeAt([0, LIFT, 0]);
    const chair0 = chair.bounds(), lamp0 = lamp.transform(), pillow0 = pillow.bounds();
    step(240);
    const chair1 = chair.bounds();
    const fell = chair0.min[1] - chair1.min[1];
    assert.ok(fell > LIFT, `the chair fell ${fell.toFixed(3)} (from ${chair0.min[1].toFixed(3)} to ${chair1.min[1].toFixed(3)})`);
    assert.ok(chair1.min[1] >= groundTop - slop, `the chair rests on the ground: lowest ${chair1.min[1].toFixed(4)}, ground top ${groundTop.toFixed(4)}, slop ${slop.toFixed(4)}`);
    assert.ok(Math.hypot(...chair.velocity()) < 0.05, `the chair is at rest: ${chair.velocity()}`);
    assert.deepEqual(lamp.transform().translation, lamp0.translation);
    const pillow1 = pillow.bounds();
    assert.ok(pillow1.min[1] < pillow0.min[1] - 0.1 && pillow1.min[1] >= groundTop - slop,
        `the pillow fell onto the ground: lowest ${pillow0.min[1].toFixed(3)} -> ${pillow1.min[1].toFixed(3)}`);
    assert.equal(pillow.guardTrips, 0);
});

test('a grabbed rigid body follows the hand and, let go, keeps the hand velocity (a throw)', { skip }, async () => {
    const { objects, step } = await buildScene();
    const chair = objects.chair;
    step(120);
    const c0 = chair.bounds().center;
    let ms = 0;                                   // the pointer's clock: one move per step
    const drag = new RigidDrag(chair, c0, () => ms);
    const v = [-1.2, 0.6, 0];                     // world units per second, away from the pillow
    for (let i = 1; i <= 20; i++) {
        ms += 1000 * DT;
        drag.move(v.map((x) => x * i * DT));
        step(1);
    }
    const held = drag.point();
    assert.ok(Math.hypot(held[0] - (c0[0] + 20 * v[0] * DT), held[1] - (c0[1] + 20 * v[1] * DT)) < 0.1, `the grabbed point follows the hand: ${held}`);
    drag.release();
    const thrown = chair.velocity();
    assert.ok(Math.abs(thrown[0] - v[0]) < 1e-3 && Math.abs(thrown[1] - v[1]) < 1e-3, `the thrown body has the hand velocity: ${thrown}`);
    step(10);
    const c1 = chair.bounds().center;
    // a hand that stopped moving well before letting go (0.4 s; 1.5 x 0.2 s) throws nothing
    const again = new RigidDrag(chair, c1, () => ms);
    ms += 1000 * DT;
    again.move([-0.1, 0, 0]);
    ms += 400;
    again.release();
    assert.deepEqual(chair.velocity().map((x) => Math.abs(x) < 1e-6), [true, true, true], `${chair.velocity()}`);
    // a busy page handles the moves 0.6 s apart: the last two moves make the velocity
    const busy = new RigidDrag(chair, chair.bounds().center, () => ms);
    for (const x of [-0.1, -0.2]) {
        ms += 600;
        busy.move([x, 0, 0]);
    }
    ms += 100;
    busy.release();
    assert.ok(Math.abs(chair.velocity()[0] + 0.1 / 0.6) < 1e-3, `${chair.velocity()}`);
    // in the air for these 10 steps, it covers at least half the distance at the hand's speed
    assert.ok(c1[0] < held[0] + 0.5 * 10 * DT * v[0], `it flies on after the release: x ${held[0].toFixed(3)} -> ${c1[0].toFixed(3)}`);
});

test('a rigid body of mass 0 (infinite) does not move', { skip }, async () => {
    const { readPhysics } = await import('../../../plugins/web/src/index.js');
    const { world, step } = await buildScene();
    const chairRecord = readPhysics(new Uint8Array(fs.readFileSync(SCENE))).objects.find((o) => o.name === 'chair');
    const record = /** @type {any} */ ({ ...chairRecord, motion: { ...chairRecord?.motion, mass: 0 } });
    const heavy = new RigidObject(world, record, record.matrix);
    heavy.reset([0, 2, 0]);                       // in the air, above the scene
    const y0 = heavy.transform().translation[1];
    step(60);
    assert.equal(heavy.immovable, true);
    assert.equal(heavy.transform().translation[1], y0);
    heavy.destroy();
});
