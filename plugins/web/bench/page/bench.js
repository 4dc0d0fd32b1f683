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
import { deform, summarize, synthetic } from './synthetic.js';

/** @type {pc.Application|null} */
let app = null;

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

/** @param {{backend?: 'webgl2'|'webgpu', width?: number, height?: number}} [options] */
async function init(options = {}) {
    const canvas = /** @type {HTMLCanvasElement} */ (document.getElementById('canvas'));
    app = await startApp(canvas, { backend: options.backend, width: options.width, height: options.height });
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
 * The synthetic splats `prim` in the rendered scene (the bench camera added and the app started
 * the first time), anchored, with the engine's sorts counted in `sorting` ('gsplat:sorted':
 * how many, and the last one's time); `close()` takes them out again.
 * @param {any} prim
 */
function sceneSplats(prim) {
    const a = /** @type {any} */ (app);
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
    const sorting = { sorts: 0, lastSortTime: 0 };
    const onSorted = (/** @type {number} */ t) => { sorting.sorts++; sorting.lastSortTime = t; };
    a.scene.on('gsplat:sorted', onSorted);
    const close = () => {
        a.scene.off('gsplat:sorted', onSorted);
        splat.destroy();
        entity.destroy();
        resource.destroy();
    };
    return { splat, sorting, close };
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
    const { splat, sorting, close } = sceneSplats(prim);
    const frame = () => new Promise((resolve) => { a.once('frameend', () => resolve(undefined)); a.renderNextFrame = true; });
    const rest = prim.anchorMesh.vertices;
    const verts = new Float32Array(rest.length);
    /** @type {{centresMs: number, sortMs: number, latencyMs: number, uploadMs: number}[]} */
    const rows = [];
    const count = opts.frames ?? 6;
    for (let i = 0; i < count + 1; ++i) {
        deform(rest, verts, 0.7 * i);
        const before = sorting.sorts;
        const t0 = performance.now();
        splat.setVertices(verts);
        const centresMs = splat.lastSortMs;
        const t1 = performance.now();
        while (sorting.sorts === before && performance.now() - t1 < 30000) await frame();
        const latencyMs = performance.now() - t0;
        splat.sortDeformed = false;
        splat.setVertices(verts);
        const uploadMs = splat.lastRemapMs;
        splat.sortDeformed = true;
        if (i > 0) rows.push({ centresMs, sortMs: sorting.lastSortTime, latencyMs, uploadMs });   // frame 0 warms up
    }
    close();
    const med = (/** @type {number[]} */ x) => x.slice().sort((p, q) => p - q)[Math.floor(x.length / 2)];
    return {
        n, law, frames: rows.length,
        centresMs: med(rows.map((r) => r.centresMs)), sortMs: med(rows.map((r) => r.sortMs)),
        latencyMs: med(rows.map((r) => r.latencyMs)), uploadMs: med(rows.map((r) => r.uploadMs)),
    };
}

/**
 * The remap and the deformed sort against the engine's own splat pass, interleaved in one
 * rendered scene (bench/engines.mjs). Each round draws three kinds of frame, in turn:
 *   static:   one rendered frame of the splats as they are (no setVertices): the engine's own
 *             per-frame work (its update and the draw of every splat; nothing to sort, the
 *             camera stands still);
 *   remapped: setVertices (a new pose, sortDeformed off) then one rendered frame: the vertex
 *             upload and the engine's work-buffer copy of every splat through the remap chunk,
 *             then the same draw; remapMs = this frame minus the static frame of its round;
 *   sorted:   setVertices with sortDeformed on: the deformed means computed into the engine's
 *             sort centres (CPU) and the engine's sort of them in its worker ('gsplat:sorted'
 *             reports its time); sortMs = the two together, the order arriving some frames later.
 * A frame is timed from the engine's 'update' (the tick's start, after requestAnimationFrame
 * handed it over, so the wait for the display's refresh is not counted) to a 1-pixel readback
 * of the canvas after 'frameend', which waits for the GPU (SwiftShader: the CPU) to finish it.
 * @param {number} n @param {{rounds?: number}} [opts]
 */
async function engineFrames(n, opts = {}) {
    const a = /** @type {any} */ (app);
    const device = a.graphicsDevice;
    const gl = device.gl;
    const prim = synthetic(n, 'affine');
    const { splat, sorting, close } = sceneSplats(prim);
    const pixel = new Uint8Array(4);
    /** one rendered frame, `before` run at its start; resolves to its time in ms @param {() => void} [before] */
    const frame = (before) => new Promise((resolve) => {
        let t0 = 0;
        a.once('update', () => { t0 = performance.now(); if (before) before(); });
        a.once('frameend', () => {
            device.setFramebuffer(null);
            gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
            resolve(performance.now() - t0);
        });
        a.renderNextFrame = true;
    });
    const rest = prim.anchorMesh.vertices;
    const verts = new Float32Array(rest.length);
    /** wait for the engine's sort of the centres handed over (at most 30 s of frames) @param {number} before */
    const sorted = async (before) => {
        const t = performance.now();
        while (sorting.sorts === before && performance.now() - t < 30000) await frame();
        return sorting.sorts !== before;
    };
    // warm-up: shaders, the first sort, the first remapped copy
    splat.sortDeformed = true;
    for (let i = 0; i < 2; ++i) {
        deform(rest, verts, 0.7 * i);
        const before = sorting.sorts;
        await frame(() => splat.setVertices(verts));
        await sorted(before);
    }
    /** @type {{baseMs: number, remapFrameMs: number, remapMs: number, centresMs: number, workerSortMs: number, sortMs: number}[]} */
    const rows = [];
    const rounds = opts.rounds ?? 5;
    for (let i = 0; i < rounds; ++i) {
        const baseMs = await frame();
        deform(rest, verts, 0.37 * i + 0.1);
        splat.sortDeformed = false;
        const remapFrameMs = await frame(() => splat.setVertices(verts));
        splat.sortDeformed = true;
        deform(rest, verts, 0.37 * i + 0.2);
        const before = sorting.sorts;
        let centresMs = NaN;
        await frame(() => { splat.setVertices(verts); centresMs = splat.lastSortMs; });
        if (!await sorted(before)) throw new Error(`no sort reported within 30 s (${n} splats)`);
        rows.push({ baseMs, remapFrameMs, remapMs: remapFrameMs - baseMs, centresMs, workerSortMs: sorting.lastSortTime, sortMs: centresMs + sorting.lastSortTime });
    }
    close();
    return summarize('PlayCanvas', n, rows);
}

/** @type {any} */ (window).gsvBench = { init, run, sort, engineFrames };
/** @type {any} */ (window).gsvReady = true;
