// Render check of the PlayCanvas plugin: loads an anchored GLB with loadAnchoredAsset, renders
// it through the engine's unified gsplat pipeline (the remap runs in the work-buffer copy pass),
// and measures the rendered extent of the splats in pixels, at rest and after a deformation
// of the anchor mesh. Driven by test/gpu-render.test.mjs.

import * as pc from 'playcanvas';
import { loadAnchoredAsset } from '../../src/playcanvas/index.js';
import { canvasPixels, settleFrames, startApp } from './engine-page.js';

/** @type {pc.Application|null} */
let app = null;
/** @type {any} */
let loaded = null;

/** Render until the picture stops changing (the engine sorts asynchronously). */
const settle = () => settleFrames(/** @type {pc.Application} */ (app), { identical: 1 });

/** @returns {Uint8Array} the canvas pixels (RGBA, rows top to bottom) */
const pixels = () => canvasPixels(/** @type {pc.Application} */ (app));

/**
 * At rest, the remapped splats must render like the engine's own rest pose: compare the
 * frame with the remap installed to the frame without it (largest channel difference and
 * the number of pixels differing by more than 8 of 255).
 */
async function compareToEngine() {
    const s = loaded.anchored[0];
    s.reset();
    await settle();
    const withRemap = pixels();
    s.enabled = false;
    await settle();
    const plain = pixels();
    s.enabled = true;
    await settle();
    let maxDiff = 0, differing = 0, lit = 0;
    for (let i = 0; i < plain.length; i += 4) {
        let d = 0;
        for (let k = 0; k < 3; ++k) d = Math.max(d, Math.abs(plain[i + k] - withRemap[i + k]));
        maxDiff = Math.max(maxDiff, d);
        if (d > 8) differing++;
        if (plain[i] + plain[i + 1] + plain[i + 2] > 24) lit++;
    }
    return { maxDiff, differing, lit };
}

/**
 * Pixel bounding box of everything brighter than the background.
 * @returns {{x0: number, x1: number, y0: number, y1: number, lit: number}}
 */
function extent() {
    const canvas = /** @type {HTMLCanvasElement} */ (document.getElementById('canvas'));
    const w = canvas.width, h = canvas.height;
    const px = pixels();
    let x0 = w, x1 = -1, y0 = h, y1 = -1, lit = 0;
    for (let y = 0; y < h; ++y) {
        for (let x = 0; x < w; ++x) {
            const o = 4 * (y * w + x);
            if (px[o] + px[o + 1] + px[o + 2] > 24) {
                lit++;
                if (x < x0) x0 = x;
                if (x > x1) x1 = x;
                if (y < y0) y0 = y;
                if (y > y1) y1 = y;
            }
        }
    }
    return { x0, x1, y0, y1, lit };
}

/**
 * Load the asset and frame it.
 * @param {string} url
 * @param {{fault?: string|null, backend?: 'webgl2'|'webgpu'}} [options]
 */
async function load(url, options = {}) {
    const canvas = /** @type {HTMLCanvasElement} */ (document.getElementById('canvas'));
    app = await startApp(canvas, { backend: options.backend, readback: true, width: 256, height: 256 });
    const camera = new pc.Entity('camera');
    camera.addComponent('camera', { clearColor: new pc.Color(0, 0, 0), fov: 40 });
    camera.setPosition(0, 0, 6);
    app.root.addChild(camera);
    app.start();
    loaded = await loadAnchoredAsset(app, url, { fault: options.fault ?? null });
    await settle();
    return {
        splats: loaded.anchored.map((/** @type {any} */ s) => s.prim.count), plain: loaded.plain.length,
        plainModified: loaded.plain.some((/** @type {any} */ e) => e.gsplat?._workBufferModifier),
    };
}

/**
 * Stretch the anchor mesh about its centroid along an axis (0, 1, 2), render, measure.
 * @param {number} axis
 * @param {number} factor
 */
async function stretch(axis, factor) {
    const s = loaded.anchored[0];
    const rest = s.prim.anchorMesh.vertices;
    const V = rest.length / 3;
    let c = 0;
    for (let v = 0; v < V; ++v) c += rest[3 * v + axis];
    c /= V;
    const out = new Float32Array(rest);
    for (let v = 0; v < V; ++v) out[3 * v + axis] = c + (rest[3 * v + axis] - c) * factor;
    s.setVertices(out);
    await settle();
    return { ...extent(), lastRemapMs: s.lastRemapMs };
}

/** Brightness summed per pixel column (left to right), after the picture settles. */
async function columns() {
    await settle();
    const canvas = /** @type {HTMLCanvasElement} */ (document.getElementById('canvas'));
    const w = canvas.width, h = canvas.height;
    const px = pixels();
    const sums = new Array(w).fill(0);
    for (let y = 0; y < h; ++y) for (let x = 0; x < w; ++x) { const o = 4 * (y * w + x); sums[x] += px[o] + px[o + 1] + px[o + 2]; }
    return sums;
}

async function measure() {
    await settle();
    return extent();
}

/** @type {any} */ (window).gsvRender = { load, stretch, measure, columns, compareToEngine };
/** @type {any} */ (window).gsvReady = true;
