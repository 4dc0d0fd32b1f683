// Render check of the PlayCanvas plugin: loads an anchored GLB with loadAnchoredAsset, renders
// it through the engine's unified gsplat pipeline (the remap runs in the work-buffer copy pass),
// and measures the rendered extent of the splats in pixels, at rest and after a deformation
// of the anchor mesh. Driven by test/gpu-render.test.mjs.

import * as pc from 'playcanvas';
import { loadAnchoredAsset } from '../../src/playcanvas/index.js';

/** @type {pc.Application|null} */
let app = null;
/** @type {any} */
let loaded = null;

/** Render one frame and wait for it. */
function frame() {
    return new Promise((resolve) => {
        const a = /** @type {pc.Application} */ (app);
        a.once('frameend', () => resolve(undefined));
        a.renderNextFrame = true;
    });
}

/**
 * Render until two consecutive frames are identical and not blank (the engine sorts splats
 * asynchronously, so a change shows a frame or two later); at most 60 frames.
 */
async function settle() {
    let previous = null;
    for (let i = 0; i < 60; ++i) {
        await frame();
        const px = pixels();
        let lit = false;
        for (let k = 0; k < px.length && !lit; k += 4) lit = px[k] + px[k + 1] + px[k + 2] > 24;
        if (lit && previous && previous.every((v, k) => v === px[k])) return;
        previous = px;
    }
}

/** @returns {Uint8Array} the canvas pixels (RGBA; rows bottom-up on WebGL2, top-down on WebGPU) */
function pixels() {
    const device = /** @type {any} */ ((/** @type {pc.Application} */ (app)).graphicsDevice);
    if (device.isWebGPU) {
        const canvas = /** @type {HTMLCanvasElement} */ (document.getElementById('canvas'));
        const copy = document.createElement('canvas');
        copy.width = canvas.width;
        copy.height = canvas.height;
        const ctx = /** @type {CanvasRenderingContext2D} */ (copy.getContext('2d'));
        ctx.drawImage(canvas, 0, 0);
        return new Uint8Array(ctx.getImageData(0, 0, copy.width, copy.height).data.buffer);
    }
    const gl = device.gl;
    const px = new Uint8Array(gl.drawingBufferWidth * gl.drawingBufferHeight * 4);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.readPixels(0, 0, gl.drawingBufferWidth, gl.drawingBufferHeight, gl.RGBA, gl.UNSIGNED_BYTE, px);
    return px;
}

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
    const backend = options.backend || 'webgl2';
    const graphicsDevice = await pc.createGraphicsDevice(canvas, /** @type {any} */ ({ deviceTypes: [backend], antialias: false, preserveDrawingBuffer: true }));
    if (graphicsDevice.deviceType !== backend) throw new Error(`no ${backend} device (got ${graphicsDevice.deviceType})`);
    app = new pc.Application(canvas, { graphicsDevice });
    app.setCanvasFillMode(pc.FILLMODE_NONE);
    app.setCanvasResolution(pc.RESOLUTION_FIXED, 256, 256);
    app.autoRender = false;
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
