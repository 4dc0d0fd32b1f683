// Browser side of bench/remap-browser.mjs: synthetic anchored splats on a deforming tube, the
// GPU remap pass (the render's remap chunk, run by the engine's GSplatProcessor) timed per
// frame: vertex upload + remap of every splat, GPU work fenced by a readback every frame.
// The CPU path (remap-cpu.js, binary64) is timed on the same data for comparison.

import * as pc from 'playcanvas';
import { AnchorGpuData, AnchoredSplat } from '../../src/playcanvas/index.js';
import { RemapProbe } from '../../src/playcanvas/probe.js';
import { describeBackend, startApp } from '../../conformance/page/engine-page.js';
import { computeRest } from '../../src/rest.js';
import { remapCpuRotationScale } from '../../src/remap-cpu.js';

/** @type {pc.Application|null} */
let app = null;

/** A small deterministic PRNG (mulberry32). @param {number} seed */
function random(seed) {
    return () => {
        seed = (seed + 0x6d2b79f5) | 0;
        let t = Math.imul(seed ^ (seed >>> 15), 1 | seed);
        t = (t + Math.imul(t ^ (t >>> 7), 61 | t)) ^ t;
        return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
    };
}

/**
 * A tube of rings x segments vertices and n splats bound to random faces.
 * @param {number} n @param {'affine'|'rigid'|'games'} law
 */
function synthetic(n, law, rings = 64, segments = 64) {
    const V = rings * segments;
    const vertices = new Float32Array(3 * V);
    for (let r = 0; r < rings; ++r) {
        for (let s = 0; s < segments; ++s) {
            const a = (2 * Math.PI * s) / segments, v = r * segments + s;
            vertices[3 * v] = Math.cos(a);
            vertices[3 * v + 1] = (4 * r) / (rings - 1) - 2;
            vertices[3 * v + 2] = Math.sin(a);
        }
    }
    const F = 2 * (rings - 1) * segments;
    const indices = new Uint32Array(3 * F);
    let f = 0;
    for (let r = 0; r + 1 < rings; ++r) {
        for (let s = 0; s < segments; ++s) {
            const a = r * segments + s, b = r * segments + ((s + 1) % segments);
            indices.set([a, b, a + segments], 3 * f++);
            indices.set([b, b + segments, a + segments], 3 * f++);
        }
    }
    const rnd = random(12345);
    const faceIndex = new Uint32Array(n), barycentrics = new Float32Array(2 * n);
    const normalOffset = new Float32Array(n), rho = new Float32Array(n);
    const localRotation = new Float32Array(4 * n), localScale = new Float32Array(3 * n);
    const means = new Float32Array(3 * n);
    for (let i = 0; i < n; ++i) {
        const face = Math.floor(rnd() * F);
        let b1 = rnd(), b2 = rnd();
        if (b1 + b2 > 1) { b1 = 1 - b1; b2 = 1 - b2; }
        faceIndex[i] = face; barycentrics[2 * i] = b1; barycentrics[2 * i + 1] = b2;
        normalOffset[i] = 0.02 * (rnd() - 0.5); rho[i] = 0.5 + rnd();
        const q = [rnd() - 0.5, rnd() - 0.5, rnd() - 0.5, rnd() - 0.5];
        const len = Math.hypot(...q);
        for (let k = 0; k < 4; ++k) localRotation[4 * i + k] = q[k] / len;
        for (let k = 0; k < 3; ++k) localScale[3 * i + k] = 0.005 + 0.02 * rnd();
        const i0 = indices[3 * face], i1 = indices[3 * face + 1], i2 = indices[3 * face + 2];
        for (let k = 0; k < 3; ++k) {
            const v0 = vertices[3 * i0 + k];
            means[3 * i + k] = v0 + b1 * (vertices[3 * i1 + k] - v0) + b2 * (vertices[3 * i2 + k] - v0);
        }
    }
    const games = law === 'games';
    /** @type {any} */
    const prim = {
        splatMesh: 0, splatPrimitive: 0, node: null, nodeMatrix: null, count: n, shDegree: 0, shCoefficients: 1,
        rest: { means, rotations: new Float32Array(4 * n), scales: new Float32Array(3 * n), opacity: new Float32Array(n), sh: new Float32Array(3 * n) },
        anchorMesh: { mesh: 1, primitive: 0, node: null, vertexCount: V, faceCount: F, indexed: true, vertices, indices },
        profile: games ? 'games' : 'local', deformation: games ? null : law,
        faceIndex, barycentrics, normalOffset: games ? null : normalOffset, localRotation: games ? null : localRotation,
        localScale: games ? null : localScale, rho: games ? rho : null, componentTypes: {},
    };
    return prim;
}

/**
 * The engine's resource for the synthetic splats, rows in the engine's (Morton) order as
 * its KHR loader leaves them.
 * @param {any} prim
 */
function engineResource(prim) {
    const n = prim.count;
    /** @type {[string, Float32Array][]} */
    const props = [];
    const m = prim.rest.means;
    props.push(['x', m.filter((_, i) => i % 3 === 0)], ['y', m.filter((_, i) => i % 3 === 1)], ['z', m.filter((_, i) => i % 3 === 2)]);
    props.push(['rot_0', new Float32Array(n).fill(1)], ['rot_1', new Float32Array(n)], ['rot_2', new Float32Array(n)], ['rot_3', new Float32Array(n)]);
    for (const name of ['scale_0', 'scale_1', 'scale_2']) props.push([name, new Float32Array(n).fill(0.01)]);
    for (const name of ['opacity', 'f_dc_0', 'f_dc_1', 'f_dc_2']) props.push([name, new Float32Array(n).fill(0.5)]);
    const data = new pc.GSplatData([{
        name: 'vertex', count: n,
        properties: /** @type {any} */ (props.map(([name, storage]) => ({ type: 'float', name, storage, byteSize: 4 }))),
    }]);
    /** @type {any} */ (data).activated = true;
    data.reorderData();
    return new pc.GSplatResource(/** @type {any} */ (app).graphicsDevice, data);
}

/**
 * A deformation of the tube at time t (bend + twist + breathing).
 * @param {Float32Array} rest @param {Float32Array} out @param {number} t
 */
function deform(rest, out, t) {
    for (let v = 0; v < rest.length / 3; ++v) {
        const x = rest[3 * v], y = rest[3 * v + 1], z = rest[3 * v + 2];
        const a = 0.3 * Math.sin(t) * y, s = 1 + 0.1 * Math.sin(2 * t + y);
        out[3 * v] = s * (x * Math.cos(a) - z * Math.sin(a)) + 0.1 * Math.sin(t) * y * y;
        out[3 * v + 1] = y * (1 + 0.2 * Math.sin(t));
        out[3 * v + 2] = s * (x * Math.sin(a) + z * Math.cos(a));
    }
}

/** @param {{backend?: 'webgl2'|'webgpu'}} [options] */
async function init(options = {}) {
    const canvas = /** @type {HTMLCanvasElement} */ (document.getElementById('canvas'));
    app = await startApp(canvas, { backend: options.backend });
    const b = describeBackend(app);
    return { engine: `${b.engine} ${b.engine_version}`, device: b.device, renderer: b.renderer, userAgent: b.user_agent, cores: navigator.hardwareConcurrency };
}

/**
 * Time the GPU remap per frame (vertex upload + remap pass, fenced by a 1-texel readback) for
 * one configuration, and the CPU path on a few frames.
 * @param {number} n @param {'affine'|'rigid'|'games'} law @param {{minMs?: number, minFrames?: number, cpuFrames?: number}} [opts]
 */
async function run(n, law, opts = {}) {
    const a = /** @type {any} */ (app);
    const device = a.graphicsDevice;
    const gl = device.isWebGPU ? null : device.gl;
    const prim = synthetic(n, law);
    const resource = engineResource(prim);
    const gpu = new AnchorGpuData(device, resource, prim, 'synthetic');
    const probe = new RemapProbe(gpu);
    const rest = prim.anchorMesh.vertices;
    const verts = new Float32Array(rest.length);
    const texel = new Float32Array(4);
    const fence = async () => {
        if (device.isWebGPU) {
            // WebGPU: an awaited 1-texel readback of the output waits for the submitted pass
            await resource.getTexture('gsvOutMean').read(0, 0, 1, 1, { immediate: true });
            return;
        }
        // WebGL2: a synchronous 1-texel readback of the output waits for the whole pass
        const rt = /** @type {any} */ (probe.processor)._renderTarget;
        device.setFramebuffer(rt.impl._glFrameBuffer);
        gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.FLOAT, texel);
        if (gl.getError() !== gl.NO_ERROR) throw new Error('fence readback failed');
    };
    // warm-up: shader compile, first uploads
    for (let i = 0; i < 2; ++i) { deform(rest, verts, i); probe.run(verts); await fence(); }
    const minMs = opts.minMs ?? 1500, minFrames = opts.minFrames ?? 5;
    /** @type {number[]} */
    const frames = [];
    const t0 = performance.now();
    while (frames.length < minFrames || performance.now() - t0 < minMs) {
        const t = frames.length * 0.1;
        deform(rest, verts, t);
        const f0 = performance.now();
        probe.run(verts);
        await fence();
        frames.push(performance.now() - f0);
        if (frames.length >= 200) break;
    }
    frames.sort((x, y) => x - y);
    const median = frames[Math.floor(frames.length / 2)];
    const mean = frames.reduce((s, x) => s + x, 0) / frames.length;
    // CPU path (binary64, JavaScript) on the same data
    const restQ = computeRest(prim);
    const cpuFrames = opts.cpuFrames ?? 2;
    /** @type {any} */
    const out = {};
    const c0 = performance.now();
    for (let i = 0; i < cpuFrames; ++i) { deform(rest, verts, i); remapCpuRotationScale(prim, restQ, verts, out); }
    const cpuMs = (performance.now() - c0) / cpuFrames;
    const check = await probe.read();
    const finite = check.means.every(Number.isFinite) && check.scales.every(Number.isFinite);
    probe.destroy();
    gpu.destroy();
    resource.destroy();
    return { n, law, faces: prim.anchorMesh.faceCount, vertices: prim.anchorMesh.vertexCount, frames: frames.length, medianMs: median, meanMs: mean, minMs: frames[0], cpuMs, finite };
}

/**
 * The cost of ordering splats by their deformed positions, per frame, in a rendered scene:
 * `setVertices` computes the deformed means into the engine's sort centres (`centresMs`, CPU),
 * the engine sends them to its sort worker and sorts (`sortMs`, the worker's own time from
 * 'gsplat:sorted'), and the sorted order arrives `latencyMs` after setVertices. The same
 * frames with `sortDeformed = false` give the upload alone (`uploadMs`).
 * @param {number} n @param {'affine'|'rigid'|'games'} law @param {{frames?: number}} [opts]
 */
async function sort(n, law, opts = {}) {
    const a = /** @type {any} */ (app);
    const prim = synthetic(n, law);
    const resource = engineResource(prim);
    const gpu = new AnchorGpuData(a.graphicsDevice, resource, prim, 'synthetic');
    const entity = new pc.Entity('splats');
    entity.addComponent('gsplat', { unified: true });
    /** @type {any} */ (entity.gsplat).resource = resource;
    a.root.addChild(entity);
    if (!a.root.findByName('bench camera')) {
        const camera = new pc.Entity('bench camera');
        camera.addComponent('camera', { clearColor: new pc.Color(0, 0, 0), fov: 50 });
        camera.setPosition(0, 0, 7);
        a.root.addChild(camera);
        a.autoRender = false;
        a.start();
    }
    const splat = new AnchoredSplat(gpu, entity, [entity.gsplat], null, null);
    let sorts = 0, lastSortTime = 0;
    const onSorted = (/** @type {number} */ t) => { sorts++; lastSortTime = t; };
    a.scene.on('gsplat:sorted', onSorted);
    const frame = () => new Promise((resolve) => { a.once('frameend', () => resolve(undefined)); a.renderNextFrame = true; });
    const rest = prim.anchorMesh.vertices;
    const verts = new Float32Array(rest.length);
    /** @type {{centresMs: number, sortMs: number, latencyMs: number, uploadMs: number}[]} */
    const rows = [];
    const count = opts.frames ?? 6;
    for (let i = 0; i < count + 1; ++i) {
        deform(rest, verts, 0.7 * i);
        const before = sorts;
        const t0 = performance.now();
        splat.setVertices(verts);
        const centresMs = splat.lastSortMs;
        const t1 = performance.now();
        while (sorts === before && performance.now() - t1 < 30000) await frame();
        const latencyMs = performance.now() - t0;
        splat.sortDeformed = false;
        splat.setVertices(verts);
        const uploadMs = splat.lastRemapMs;
        splat.sortDeformed = true;
        if (i > 0) rows.push({ centresMs, sortMs: lastSortTime, latencyMs, uploadMs });   // frame 0 warms up
    }
    a.scene.off('gsplat:sorted', onSorted);
    splat.destroy();
    entity.destroy();
    resource.destroy();
    const med = (/** @type {number[]} */ x) => x.slice().sort((p, q) => p - q)[Math.floor(x.length / 2)];
    return {
        n, law, frames: rows.length,
        centresMs: med(rows.map((r) => r.centresMs)), sortMs: med(rows.map((r) => r.sortMs)),
        latencyMs: med(rows.map((r) => r.latencyMs)), uploadMs: med(rows.map((r) => r.uploadMs)),
    };
}

/** @type {any} */ (window).gsvBench = { init, run, sort };
/** @type {any} */ (window).gsvReady = true;
