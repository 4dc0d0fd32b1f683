// Soft-body physics of the demo, in Node (no browser): welding, the lattice physics mesh and its
// embedding, the stability measures, and the deterministic scripted pull / twist on the shipped
// example's anchor mesh. Step times are reported (test diagnostics), never asserted.
//
//   node --test examples/web/test/physics.test.mjs
//   GSVERSE_DEMO_ASSETS=a.glb:b.glb node --test examples/web/test/physics.test.mjs   # also these assets

import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { haveJolt, jolt } from './jolt.mjs';
import { weldVertices, weldFaces, isClosed, bounds, PhysicsWorld, SoftBodyMesh, DEFAULT_BUDGET } from '../physics.js';
import { buildPhysicsMesh, triangleOverlapsBox, applyEmbedding } from '../physmesh.js';
import { SliderDrive, Drag, Shake } from '../controls.js';

const HERE = path.dirname(fileURLToPath(import.meta.url));
const REPO = path.resolve(HERE, '..', '..', '..');
const EXAMPLE = path.join(REPO, 'examples', 'web', 'capsule.glb');
const haveAssets = fs.existsSync(EXAMPLE) && haveJolt;
const EXTRA = (process.env.GSVERSE_DEMO_ASSETS || '').split(path.delimiter).filter(Boolean);

/** @param {string} file */
async function anchorMeshOf(file) {
    const { readAnchoredGlb } = await import('../../../plugins/web/src/anchor.js');
    const { anchored } = readAnchoredGlb(new Uint8Array(fs.readFileSync(file)), { name: path.basename(file) });
    return anchored[0].anchorMesh;
}

/** A small deterministic PRNG (mulberry32). @param {number} seed */
function random(seed) {
    return () => {
        seed = (seed + 0x6d2b79f5) | 0;
        let t = Math.imul(seed ^ (seed >>> 15), 1 | seed);
        t = (t + Math.imul(t ^ (t >>> 7), 61 | t)) ^ t;
        return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
    };
}

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

/**
 * A torus standing in the x-y plane like the donut capture: `around` x `tube` vertices,
 * 2 * around * tube faces (100 x 100: 10,000 vertices, 20,000 faces), its vertices jittered and,
 * with `holes`, a few patches of faces cut out so that it is open like a reconstructed mesh.
 * @param {{around?: number, tube?: number, holes?: number, jitter?: number}} [o]
 */
function torus(o = {}) {
    const n = o.around ?? 100, m = o.tube ?? 100, R = 0.075, r = 0.03;
    const rnd = random(7);
    const v = new Float32Array(3 * n * m);
    for (let i = 0; i < n; i++) {
        for (let j = 0; j < m; j++) {
            const a = 2 * Math.PI * i / n, b = 2 * Math.PI * j / m, k = 3 * (i * m + j);
            const rr = r * (1 + (o.jitter ?? 0.02) * (rnd() - 0.5));
            v[k] = (R + rr * Math.cos(b)) * Math.cos(a);
            v[k + 1] = (R + rr * Math.cos(b)) * Math.sin(a);
            v[k + 2] = rr * Math.sin(b);
        }
    }
    const holes = [];
    for (let h = 0; h < (o.holes ?? 0); h++) holes.push([Math.floor(rnd() * n), Math.floor(rnd() * m)]);
    const f = [];
    for (let i = 0; i < n; i++) {
        for (let j = 0; j < m; j++) {
            if (holes.some(([hi, hj]) => Math.abs(hi - i) <= 1 && Math.abs(hj - j) <= 1)) continue;
            const a = i * m + j, b = ((i + 1) % n) * m + j, c = ((i + 1) % n) * m + (j + 1) % m, d = i * m + (j + 1) % m;
            f.push(a, b, c, a, c, d);
        }
    }
    return { vertices: v, indices: new Uint32Array(f) };
}

/** A world framed on a mesh (about one unit large) with the ground below it. @param {any} Jolt @param {Float32Array} v */
function worldFor(Jolt, v) {
    const b = bounds(v);
    const world = new PhysicsWorld(Jolt, {});
    world.setFrame(b.center, 1 / Math.max(...b.size));
    world.setGround(b.min[1] - 0.2 * b.size[1], 20 * Math.max(...b.size), [b.center[0], b.center[2]]);
    return world;
}

/** Mean step time of `n` steps, ms. @param {SoftBodyMesh} soft @param {number} n */
function stepTime(soft, n) {
    for (let i = 0; i < 3; i++) soft.step(1 / 60);
    const t0 = performance.now();
    for (let i = 0; i < n; i++) soft.step(1 / 60);
    return (performance.now() - t0) / n;
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

test('triangle / box overlap', () => {
    const c = [0, 0, 0], h = [0.5, 0.5, 0.5];
    assert.equal(triangleOverlapsBox(c, h, [-2, 0, 0], [2, 0.1, 0], [0, 2, 0.1]), true);        // cuts through
    assert.equal(triangleOverlapsBox(c, h, [0.6, 0, 0], [2, 0, 0], [2, 1, 0]), false);          // beside it
    assert.equal(triangleOverlapsBox(c, h, [1.2, 0, -1], [0, 1.2, -1], [0.6, 0.6, 1]), false);   // across a corner, outside
    assert.equal(triangleOverlapsBox(c, h, [0.9, 0, -1], [0, 0.9, -1], [0.45, 0.45, 1]), true);  // across a corner, inside
});

test('the lattice is a solid: a closed cube is filled, a torus keeps its hole', () => {
    const cube = buildPhysicsMesh(splitCube().vertices, splitCube().indices, { budget: 200 });
    assert.equal(cube.kind, 'lattice');
    const [a, b, c] = /** @type {{cells: number[]}} */ (cube.grid).cells;
    assert.equal(cube.count, (a + 1) * (b + 1) * (c + 1), 'every cell of the cube, the inside too');
    assert.ok(cube.count <= 200 && cube.count > 50, `${cube.count} nodes`);
    assert.equal(cube.volumes.length / 4, 5 * a * b * c);

    const t = torus({ around: 48, tube: 24 });
    const pm = buildPhysicsMesh(t.vertices, t.indices, { budget: 600 });
    assert.ok(pm.count <= 600, `${pm.count} nodes`);
    // the hole (radius 0.045 about the axis) stays empty but for the cells its wall touches, and
    // there are nodes all around the ring
    const h = /** @type {{cellSize: number[]}} */ (pm.grid).cellSize;
    const wall = 0.045 - Math.hypot(h[0], h[1]) * 1.01;
    assert.ok(wall > 0.01, `cells of ${h.map((x) => x.toFixed(4))}`);
    let inHole = 0;
    for (let i = 0; i < pm.count; i++) if (Math.hypot(pm.positions[3 * i], pm.positions[3 * i + 1]) < wall) inHole++;
    assert.equal(inHole, 0, 'the hole stays empty');
    const sectors = new Set();
    for (let i = 0; i < pm.count; i++) sectors.add(Math.floor((Math.atan2(pm.positions[3 * i + 1], pm.positions[3 * i]) + Math.PI) / (Math.PI / 8)));
    assert.equal(sectors.size, 16);
    // every tetrahedron positively oriented (Jolt keeps |volume|, so the sign must be right)
    for (let q = 0; q < pm.volumes.length; q += 4) {
        const p = [0, 1, 2, 3].map((j) => [0, 1, 2].map((k) => pm.positions[3 * pm.volumes[q + j] + k]));
        const e = [1, 2, 3].map((j) => [0, 1, 2].map((k) => p[j][k] - p[0][k]));
        const six = e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) - e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) + e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
        assert.ok(six > 0, `tetrahedron ${q / 4} has volume ${six}`);
    }
});

test('the embedding: trilinear weights that reproduce the anchor mesh and any affine motion', () => {
    const t = torus({ holes: 6 });
    const pm = buildPhysicsMesh(t.vertices, t.indices);
    const { k, nodes, weights } = pm.embedding;
    assert.equal(k, 8);
    const A = t.vertices.length / 3;
    const size = Math.max(...bounds(t.vertices).size);
    let sumErr = 0, posErr = 0;
    for (let a = 0; a < A; a++) {
        let s = 0;
        const p = [0, 0, 0];
        for (let q = 8 * a; q < 8 * a + 8; q++) {
            assert.ok(weights[q] >= 0 && nodes[q] < pm.count);
            s += weights[q];
            for (let c = 0; c < 3; c++) p[c] += weights[q] * pm.positions[3 * nodes[q] + c];
        }
        sumErr = Math.max(sumErr, Math.abs(s - 1));
        for (let c = 0; c < 3; c++) posErr = Math.max(posErr, Math.abs(p[c] - t.vertices[3 * a + c]));
    }
    assert.ok(sumErr < 1e-6, `weights sum to 1 within ${sumErr}`);
    assert.ok(posErr < 1e-6 * size, `the weighted rest nodes give the anchor vertices within ${posErr}`);
    // an affine map of the nodes moves the anchor vertices by the same map (float32 rounding)
    const M = [[1.3, 0.2, -0.1], [-0.25, 0.8, 0.3], [0.1, -0.2, 1.1]], T = [0.05, -0.02, 0.3];
    const map = (/** @type {ArrayLike<number>} */ x, /** @type {number} */ o) => [0, 1, 2].map((r) => M[r][0] * x[o] + M[r][1] * x[o + 1] + M[r][2] * x[o + 2] + T[r]);
    const disp = new Float32Array(3 * pm.count);
    for (let i = 0; i < pm.count; i++) {
        const y = map(pm.positions, 3 * i);
        for (let c = 0; c < 3; c++) disp[3 * i + c] = y[c] - pm.positions[3 * i + c];
    }
    const out = applyEmbedding(pm.embedding, t.vertices, disp, new Float32Array(t.vertices.length));
    let affErr = 0;
    for (let a = 0; a < A; a++) {
        const y = map(t.vertices, 3 * a);
        for (let c = 0; c < 3; c++) affErr = Math.max(affErr, Math.abs(out[3 * a + c] - y[c]));
    }
    assert.ok(affErr < 4e-6 * size, `affine motion reproduced within ${affErr}`);
});

test('a 20,000-face mesh: reduced to the budget, exact at rest, rigid motions followed', { skip: !haveJolt && 'jolt-physics missing' }, async (t) => {
    const Jolt = await jolt();
    const mesh = torus({ holes: 6 });
    const F = mesh.indices.length / 3;
    assert.ok(F > 19000 && !isClosed(mesh.indices), `${F} faces, open`);
    const world = worldFor(Jolt, mesh.vertices);

    // before: the anchor mesh itself as the soft body
    const direct = new SoftBodyMesh(world, mesh, { kind: 'surface', budget: Infinity });
    assert.equal(direct.kind, 'surface');
    assert.equal(direct.count, mesh.vertices.length / 3);
    const before = stepTime(direct, 10);
    direct.destroy();

    // after: the lattice within the budget
    let t0 = performance.now();
    const soft = new SoftBodyMesh(world, mesh);
    const build = performance.now() - t0;
    assert.equal(soft.kind, 'lattice');
    assert.ok(soft.simCount <= DEFAULT_BUDGET && soft.simCount > DEFAULT_BUDGET / 4, `${soft.simCount} physics vertices`);
    const out = soft.readAnchorVertices();
    assert.deepEqual(out, mesh.vertices, 'at rest the anchor mesh is reproduced exactly');
    const after = stepTime(soft, 60);
    t0 = performance.now();
    for (let i = 0; i < 20; i++) soft.readAnchorVertices(out);
    const embedMs = (performance.now() - t0) / 20;
    t.diagnostic(`20,000-face mesh (${mesh.vertices.length / 3} vertices): ${before.toFixed(2)} ms/step stepped as it is; `
        + `lattice of ${soft.simCount} nodes (${soft.physics.grid?.cells.join('x')} cells, built in ${build.toFixed(0)} ms): ${after.toFixed(2)} ms/step, `
        + `embedding ${embedMs.toFixed(2)} ms per frame`);

    // without gravity nothing moves
    soft.reset();
    for (let i = 0; i < 60; i++) soft.step(1 / 60);
    const size = Math.max(...bounds(mesh.vertices).size);
    let drift = 0;
    soft.readAnchorVertices(out);
    for (let i = 0; i < out.length; i++) drift = Math.max(drift, Math.abs(out[i] - mesh.vertices[i]));
    assert.ok(drift < 1e-4 * size, `rest drift ${drift}`);

    // a rigid motion of the lattice moves the anchor mesh rigidly
    const ang = 0.7, ca = Math.cos(ang), sa = Math.sin(ang), tr = [0.01, 0.02, -0.03];
    const rot = (/** @type {ArrayLike<number>} */ p, /** @type {number} */ o) => [ca * p[o] - sa * p[o + 2] + tr[0], p[o + 1] + tr[1], sa * p[o] + ca * p[o + 2] + tr[2]];
    const moved = new Float32Array(3 * soft.simCount);
    for (let i = 0; i < soft.simCount; i++) moved.set(rot(soft.restAll, 3 * i), 3 * i);
    soft.teleport(moved);
    soft.readAnchorVertices(out);
    let rigidErr = 0;
    for (let a = 0; a < out.length / 3; a++) {
        const y = rot(mesh.vertices, 3 * a);
        for (let c = 0; c < 3; c++) rigidErr = Math.max(rigidErr, Math.abs(out[3 * a + c] - y[c]));
    }
    assert.ok(rigidErr < 1e-5 * size, `rigid motion followed within ${rigidErr}`);
    soft.destroy();
    world.destroy();
});

test('pinned vertices move towards their targets at the bounded speed', { skip: !haveAssets && 'example asset or jolt-physics missing' }, async () => {
    const Jolt = await jolt();
    const mesh = await anchorMeshOf(EXAMPLE);
    const world = worldFor(Jolt, mesh.vertices);
    const soft = new SoftBodyMesh(world, mesh);
    const diag = Math.hypot(...bounds(soft.rest).size);
    const cap = soft.endCap(1, 1, 0.12);
    /** @type {Map<number, number[]>} */
    const pins = new Map();
    for (const i of cap) pins.set(i, [soft.rest[3 * i], soft.rest[3 * i + 1] + diag, soft.rest[3 * i + 2]]);   // a jump of one diagonal
    soft.setPins(pins);
    const dt = 1 / 60;
    soft.step(dt);
    let moved = 0;
    const p = soft.positions();
    for (const i of cap) moved = Math.max(moved, Math.hypot(p[3 * i] - soft.rest[3 * i], p[3 * i + 1] - soft.rest[3 * i + 1], p[3 * i + 2] - soft.rest[3 * i + 2]));
    assert.ok(moved <= soft.pinSpeed * diag * dt * 1.001 && moved > 0.5 * soft.pinSpeed * diag * dt, `moved ${moved / diag} diagonals in one step`);
    for (let s = 0; s < 60 && soft.pinsMoving; s++) soft.step(dt);
    assert.equal(soft.pinsMoving, false, 'arrived');
    soft.positions(p);
    for (const i of cap) assert.ok(Math.abs(p[3 * i + 1] - soft.rest[3 * i + 1] - diag) < 1e-4 * diag);
    soft.destroy();
    world.destroy();
});

test('the guard puts a blown-up body back to its rest shape', { skip: !haveAssets && 'example asset or jolt-physics missing' }, async () => {
    const Jolt = await jolt();
    const mesh = await anchorMeshOf(EXAMPLE);
    const world = worldFor(Jolt, mesh.vertices);
    const rest = bounds(mesh.vertices);
    const diag = Math.hypot(...rest.size);
    for (const guard of [3, 0]) {
        const soft = new SoftBodyMesh(world, mesh, { guard });
        // scatter the vertices over ten diagonals, as an explosion would
        const rnd = random(3);
        soft.teleport(soft.restAll.map((x) => x + 10 * diag * (rnd() - 0.5)));
        const tripped = soft.guard();
        const size = Math.max(...soft.bounds().size);
        if (guard) {
            assert.equal(tripped, true);
            assert.equal(soft.guardTrips, 1);
            assert.ok(Math.abs(size - Math.max(...rest.size)) < 1e-4 * diag, `back to the rest shape: ${size}`);
            assert.equal(soft.guard(), false, 'and no further trip');
        } else {
            assert.equal(tripped, false);
            assert.ok(size > 3 * diag, 'without the guard it stays blown up');
        }
        soft.destroy();
    }
    world.destroy();
});

/**
 * The demo's slider jump 1.0 -> 1.7 -> 0.6, let go, a fast drag, drop and shake, stepped at 60 Hz
 * like the page; per phase the anchor mesh's extent range relative to rest.
 * @param {any} Jolt @param {{vertices: Float32Array, indices: Uint32Array}} mesh
 */
function scenario(Jolt, mesh) {
    const world = worldFor(Jolt, mesh.vertices);
    const soft = new SoftBodyMesh(world, mesh);
    const rest = bounds(mesh.vertices).size;
    const axis = /** @type {0|1|2} */ (rest.indexOf(Math.max(...rest)));
    const out = new Float32Array(mesh.vertices.length);
    const sliders = new SliderDrive();
    /** @type {Record<string, {lo: number[], hi: number[], last: number[], ms: number}>} */
    const phases = {};
    /** @param {string} name @param {number} steps @param {() => void} [each] */
    const run = (name, steps, each) => {
        const lo = [Infinity, Infinity, Infinity], hi = [0, 0, 0];
        let last = [0, 0, 0], ms = 0;
        for (let s = 0; s < steps; s++) {
            each?.();
            sliders.step(1 / 60, [soft]);
            const t0 = performance.now();
            soft.step(1 / 60);
            ms += performance.now() - t0;
            last = bounds(soft.readAnchorVertices(out)).size.map((v, k) => v / rest[k]);
            for (let k = 0; k < 3; k++) { lo[k] = Math.min(lo[k], last[k]); hi[k] = Math.max(hi[k], last[k]); }
        }
        phases[name] = { lo, hi, last, ms: ms / steps };
    };
    sliders.set(axis, 1.7, 0);
    run('stretch-1.7', 90);
    sliders.set(axis, 0.6, 0);
    run('squeeze-0.6', 120);
    sliders.release();
    soft.setPins(null);
    run('let-go', 120);
    soft.reset();
    // a fast drag: the high end grabbed and pulled two diagonals away within one step
    const p = soft.positions();
    let end = 0;
    for (let i = 0; i < soft.count; i++) if (p[3 * i + axis] > p[3 * end + axis]) end = i;
    const drag = new Drag(soft, end);
    const d = [0, 0, 0];
    d[axis] = 2 * Math.hypot(...rest);
    drag.move(d);
    run('drag', 60);
    drag.release();
    run('drag-let-go', 60);
    soft.reset();
    soft.placeAt([0, 0.5 * rest[1], 0]);
    soft.setGravity(1);
    run('drop', 180);
    soft.reset();
    const shake = new Shake([soft], axis);
    run('shake', 200, () => { shake.step(1 / 60); });
    const trips = soft.guardTrips, kind = soft.kind, nodes = soft.simCount;
    soft.destroy();
    world.destroy();
    return { phases, trips, axis, kind, nodes, rest };
}

/** @param {ReturnType<typeof scenario>} r @param {string} label */
function checkScenario(r, label) {
    const fmt = (/** @type {number[]} */ a) => a.map((v) => v.toFixed(2)).join(' ');
    const longest = Math.max(...r.rest);
    for (const [name, ph] of Object.entries(r.phases)) {
        if (['drag', 'drag-let-go', 'drop', 'shake'].includes(name)) {
            // the body may turn: no axis beyond 2.2x the rest's longest extent, none collapsed
            const hi = Math.max(...ph.hi.map((v, k) => v * r.rest[k])) / longest;
            assert.ok(hi <= 2.2, `${label} ${name}: largest extent ${hi.toFixed(2)}x the rest's longest`);
            assert.ok(Math.max(...ph.lo.map((v, k) => v * r.rest[k])) / longest >= 0.4, `${label} ${name}: collapsed`);
        } else {
            assert.ok(ph.lo.every((v) => v >= 0.4) && ph.hi.every((v) => v <= 2.2), `${label} ${name}: extent ${fmt(ph.lo)} .. ${fmt(ph.hi)} of rest`);
        }
    }
    assert.ok(Math.abs(r.phases['stretch-1.7'].last[r.axis] - 1.7) < 0.05, `${label}: stretched to ${r.phases['stretch-1.7'].last[r.axis]}`);
    assert.ok(r.phases['squeeze-0.6'].last[r.axis] < 0.85, `${label}: squeezed to ${r.phases['squeeze-0.6'].last[r.axis]}`);
    assert.ok(r.phases['let-go'].last[r.axis] > 0.85, `${label}: springs back when let go (${r.phases['let-go'].last[r.axis]})`);
    assert.ok(r.phases.drag.hi[r.axis] < 2.2, `${label}: the drag's pull is limited`);
    assert.equal(r.trips, 0, `${label}: the guard had to step in`);
}

/** @param {ReturnType<typeof scenario>} r */
function describe(r) {
    const fmt = (/** @type {number[]} */ a) => a.map((v) => v.toFixed(2)).join('/');
    return `${r.kind} of ${r.nodes} vertices; ` + Object.entries(r.phases)
        .map(([name, ph]) => `${name} ${fmt(ph.lo)}..${fmt(ph.hi)} (${ph.ms.toFixed(2)} ms/step)`).join('; ');
}

test('slider jumps, a fast drag, drop and shake keep the body bounded (capsule, 20,000-face torus)', { skip: !haveAssets && 'example asset or jolt-physics missing' }, async (t) => {
    const Jolt = await jolt();
    for (const [label, mesh] of /** @type {[string, any][]} */ ([['capsule', await anchorMeshOf(EXAMPLE)], ['torus', torus({ holes: 6 })]])) {
        const r = scenario(Jolt, mesh);
        t.diagnostic(`${label}: ${describe(r)}`);
        checkScenario(r, label);
    }
});

test('the same on the assets in GSVERSE_DEMO_ASSETS', { skip: (!EXTRA.length || !haveJolt) && 'GSVERSE_DEMO_ASSETS not set' }, async (t) => {
    const Jolt = await jolt();
    for (const file of EXTRA) {
        const mesh = await anchorMeshOf(file);
        const world = worldFor(Jolt, mesh.vertices);
        const direct = new SoftBodyMesh(world, mesh, { kind: 'surface', budget: Infinity });
        const before = stepTime(direct, 10);
        const welded = direct.count;
        direct.destroy();
        world.destroy();
        const r = scenario(Jolt, mesh);
        t.diagnostic(`${path.basename(file)}: anchor mesh ${mesh.vertices.length / 3} vertices (${welded} welded), ${mesh.indices.length / 3} faces: `
            + `${before.toFixed(2)} ms/step stepped as it is; ${describe(r)}`);
        assert.ok(r.nodes <= DEFAULT_BUDGET);
        checkScenario(r, path.basename(file));
    }
});

test('scripted pull and twist of the example anchor mesh', { skip: !haveAssets && 'example asset or jolt-physics missing' }, async () => {
    const Jolt = await jolt();
    const mesh = await anchorMeshOf(EXAMPLE);
    const world = new PhysicsWorld(Jolt, { groundY: -2 });
    const soft = new SoftBodyMesh(world, { vertices: mesh.vertices, indices: mesh.indices });
    const rest = bounds(mesh.vertices);

    // at rest, without gravity, nothing moves
    for (let i = 0; i < 60; i++) soft.step(1 / 60);
    const still = soft.readAnchorVertices();
    let drift = 0;
    for (let i = 0; i < still.length; i++) drift = Math.max(drift, Math.abs(still[i] - mesh.vertices[i]));
    assert.ok(drift < 1e-3, `rest drift ${drift}`);

    // pull 1.5x along y: the pinned caps set the extent, the sides narrow a little (the volume is kept)
    soft.pull(1, 1.5);
    const pulled = soft.bounds();
    assert.ok(Math.abs(pulled.size[1] / rest.size[1] - 1.5) < 0.01, `y ${pulled.size[1] / rest.size[1]}`);
    for (const k of [0, 2]) assert.ok(pulled.size[k] / rest.size[k] > 0.6 && pulled.size[k] / rest.size[k] < 1.0, `axis ${k}: ${pulled.size[k] / rest.size[k]}`);
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

    // back at rest, the anchor mesh is exactly the rest mesh again
    soft.reset();
    assert.deepEqual(soft.readAnchorVertices(), mesh.vertices);

    // dropped onto the ground, it lands and stays above it
    world.setGround(rest.min[1] - 0.2 * rest.size[1]);
    soft.placeAt([0, 0.5 * rest.size[1], 0]);
    soft.setGravity(1);
    for (let i = 0; i < 240; i++) soft.step(1 / 60);
    const landed = soft.bounds();
    assert.ok(landed.min[1] > world.groundY - 0.05 * rest.size[1], `fell through: ${landed.min[1]} < ${world.groundY}`);
    assert.ok(landed.min[1] < world.groundY + 0.05 * rest.size[1], 'resting on the ground');
    soft.destroy();
    world.destroy();
});

test('the welded anchor mesh itself (surface kind) still maps back to the anchor order', { skip: !haveAssets && 'example asset or jolt-physics missing' }, async () => {
    const Jolt = await jolt();
    const mesh = await anchorMeshOf(EXAMPLE);
    const world = worldFor(Jolt, mesh.vertices);
    const soft = new SoftBodyMesh(world, mesh, { kind: 'surface' });
    assert.equal(soft.kind, 'surface');
    assert.ok(soft.simCount > soft.count, 'a closed mesh gets its core');
    soft.pull(1, 1.3);
    const out = soft.readAnchorVertices();
    const w = soft.positions();
    const map = /** @type {Uint32Array} */ (soft.map);
    for (let i = 0; i < soft.anchorCount; i++) {
        for (let k = 0; k < 3; k++) assert.ok(Math.abs(out[3 * i + k] - w[3 * map[i] + k]) < 1e-6, 'each anchor vertex follows its welded vertex');
    }
    soft.destroy();
    world.destroy();
});
