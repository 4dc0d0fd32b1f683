// Browser side of bench/engines.mjs for three.js + Spark: the remap (the plugin's object
// modifier, run by Spark when it regenerates the splats) and Spark's sort of the deformed
// splats, against Spark's own splat pass, on the synthetic workload of ./synthetic.js.

import * as THREE from 'three';
import { AnchoredSplatMesh } from '../../src/three/index.js';
import { describeThree, startThree } from '../../conformance/page/three-engine.js';
import { deform, summarize, synthetic } from './synthetic.js';

/** @type {ReturnType<typeof startThree>|null} */
let three = null;
/** @type {THREE.PerspectiveCamera|null} */
let camera = null;

/** @param {{width?: number, height?: number}} [options] */
async function init(options = {}) {
    const canvas = /** @type {HTMLCanvasElement} */ (document.getElementById('canvas'));
    three = startThree(canvas, { width: options.width, height: options.height });
    // Spark regenerates and sorts only when asked (update below), not on every render
    /** @type {any} */ (three.spark).autoUpdate = false;
    camera = new THREE.PerspectiveCamera(50, canvas.width / canvas.height, 0.1, 100);
    camera.position.set(0, 0, 7);
    const b = describeThree(three.renderer);
    return { engine: `${b.engine} (${b.engine_version})`, device: b.device, renderer: b.renderer, userAgent: b.user_agent, cores: navigator.hardwareConcurrency };
}

/**
 * The three frames of a round, as for PlayCanvas (bench.js engineFrames) but for the remap:
 *   static:   renderer.render of the splats as Spark holds them (its draw of every splat; no
 *             regeneration, no sort: the camera stands still and autoUpdate is off);
 *   remapped: setVertices (a new pose) then Spark's update, which regenerates every splat
 *             through its generator with the remap as the mesh's object modifier, fenced by a
 *             1-pixel readback of the canvas (remapMs: the remap timed on its own, as Spark runs
 *             it apart from the draw; a difference of two frames would drown it in the draw's
 *             variance), then the same render (remapFrameMs: both); Spark's sort is held back
 *             meanwhile (its `sorting` flag, read by its driveSort);
 *   sorted:   Spark's driveSort of the deformed splats just generated: its readback of their
 *             depths, the sort in its worker and the upload of the order (sortMs).
 * Every frame ends with a 1-pixel readback of the canvas, which waits for the GPU to finish it.
 * @param {number} n @param {{rounds?: number}} [opts]
 */
async function engineFrames(n, opts = {}) {
    const { renderer, scene, spark } = /** @type {NonNullable<typeof three>} */ (three);
    const cam = /** @type {THREE.PerspectiveCamera} */ (camera);
    const s = /** @type {any} */ (spark);
    const gl = renderer.getContext();
    const prim = synthetic(n, 'affine');
    const splat = new AnchoredSplatMesh(prim);
    scene.add(splat.mesh);
    const pixel = new Uint8Array(4);
    /** a 1-pixel readback of the canvas: waits for every GL command issued before it */
    const fence = () => {
        gl.bindFramebuffer(gl.FRAMEBUFFER, null);
        gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
    };
    const draw = () => {
        renderer.render(scene, cam);
        fence();
    };
    s.minSortIntervalMs = 0;
    const rest = prim.anchorMesh.vertices;
    const verts = new Float32Array(rest);
    const remapped = async () => {
        const t0 = performance.now();
        splat.setVertices(verts);
        const before = s.current;
        s.sorting = true;   // hold Spark's sort back: driveSort returns at once while it is set
        try {
            await spark.update({ scene, camera: cam });
        } finally {
            s.sorting = false;
        }
        if (s.current === before) throw new Error('Spark did not regenerate the splats');
        fence();
        const remapMs = performance.now() - t0;
        draw();
        return { remapMs, remapFrameMs: performance.now() - t0 };
    };
    const sortNow = async () => {
        const t0 = performance.now();
        s.sortDirty = true;
        await s.driveSort();
        return performance.now() - t0;
    };
    // warm-up: Spark's first update (the new mesh's mapping, generated and sorted), shaders
    splat.setVertices(verts);
    await spark.update({ scene, camera: cam });
    for (let i = 0; i < 2; ++i) {
        deform(rest, verts, 0.7 * i);
        await remapped();
        await sortNow();
        draw();
    }
    /** @type {{baseMs: number, remapFrameMs: number, remapMs: number, sortMs: number}[]} */
    const rows = [];
    const rounds = opts.rounds ?? 5;
    for (let i = 0; i < rounds; ++i) {
        const t0 = performance.now();
        draw();
        const baseMs = performance.now() - t0;
        deform(rest, verts, 0.37 * i + 0.1);
        const { remapMs, remapFrameMs } = await remapped();
        const sortMs = await sortNow();
        rows.push({ baseMs, remapFrameMs, remapMs, sortMs });
    }
    splat.destroy();
    return summarize('three.js + Spark', n, rows);
}

/** @type {any} */ (window).gsvBench = { init, engineFrames };
/** @type {any} */ (window).gsvReady = true;
