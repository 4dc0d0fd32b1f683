// Renders an anchored GLB in PlayCanvas (through @gsverse/web's loadAnchoredAsset, so posed
// anchor vertices go through the GPU remap) with an explicit camera, and returns the pixels.
// Driven by render-playcanvas.mjs; compared with gsverse-render by tests/test_render.py.

import * as pc from '/pkg/node_modules/playcanvas/build/playcanvas.mjs';
import { loadAnchoredAsset } from '/pkg/src/playcanvas/index.js';

/** @type {any} */
let app = null;
/** @type {any} */
let loaded = null;

function frame() {
    return new Promise((resolve) => { app.once('frameend', () => resolve(undefined)); app.renderNextFrame = true; });
}

function pixels() {
    const gl = app.graphicsDevice.gl;
    const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
    const px = new Uint8Array(w * h * 4);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    const out = new Uint8Array(w * h * 4);   // top-down rows
    for (let y = 0; y < h; ++y) out.set(px.subarray((h - 1 - y) * w * 4, (h - y) * w * 4), y * w * 4);
    return out;
}

/** Render until two consecutive frames are identical (the engine sorts asynchronously). */
async function settle() {
    let previous = null;
    for (let i = 0; i < 60; ++i) {
        await frame();
        const px = pixels();
        let lit = false;
        for (let k = 0; k < px.length && !lit; k += 4) lit = px[k] + px[k + 1] + px[k + 2] > 24;
        if (lit && i > 2 && previous && previous.every((v, k) => v === px[k])) return px;
        previous = px;
    }
    return previous;
}

/**
 * @param {{url: string, width: number, height: number, eye: number[], target: number[], fov: number,
 *          near: number, far: number, vertices?: number[]|null, gamma: string}} o
 */
async function render(o) {
    const canvas = /** @type {HTMLCanvasElement} */ (document.getElementById('canvas'));
    canvas.width = o.width;
    canvas.height = o.height;
    const graphicsDevice = await pc.createGraphicsDevice(canvas, /** @type {any} */ ({ deviceTypes: ['webgl2'], antialias: false, preserveDrawingBuffer: true, alpha: false }));
    app = new pc.Application(canvas, { graphicsDevice });
    app.setCanvasFillMode(pc.FILLMODE_NONE);
    app.setCanvasResolution(pc.RESOLUTION_FIXED, o.width, o.height);
    app.autoRender = false;
    const camera = new pc.Entity('camera');
    camera.addComponent('camera', { clearColor: new pc.Color(0, 0, 0, 1), fov: o.fov, nearClip: o.near, farClip: o.far,
        toneMapping: pc.TONEMAP_LINEAR, gammaCorrection: o.gamma === 'srgb' ? pc.GAMMA_SRGB : pc.GAMMA_NONE });
    camera.setPosition(o.eye[0], o.eye[1], o.eye[2]);
    camera.lookAt(new pc.Vec3(o.target[0], o.target[1], o.target[2]), pc.Vec3.UP);
    app.root.addChild(camera);
    app.start();
    loaded = await loadAnchoredAsset(app, o.url);
    if (o.vertices) loaded.anchored[0].setVertices(new Float32Array(o.vertices));
    const px = await settle();
    let s = '';
    for (let i = 0; i < px.length; i += 0x8000) s += String.fromCharCode.apply(null, Array.from(px.subarray(i, i + 0x8000)));
    return { width: o.width, height: o.height, rgba: btoa(s), renderer: app.graphicsDevice.gl.getParameter(app.graphicsDevice.gl.RENDERER) };
}

/** @type {any} */ (window).gsvCompare = { render };
/** @type {any} */ (window).gsvReady = true;
