// What every browser page of the package's harnesses does with the engine, once: start a
// PlayCanvas application on the page's canvas (WebGL2 or WebGPU), describe the device, render a
// frame on demand, read the canvas back, wait until the picture stops changing, and move bytes
// in and out (fetchBytes, toBase64 of bytes.js, re-exported). Used by the
// conformance pages (numbers and render levels), the render check and the repository's
// cross-check of gsverse-render (tests/render_js).

import * as pc from 'playcanvas';

export { fetchBytes, toBase64 } from './bytes.js';

/**
 * A PlayCanvas application on `canvas`, rendering only when asked (autoRender off).
 * @param {HTMLCanvasElement} canvas
 * @param {{backend?: 'webgl2'|'webgpu', readback?: boolean, width?: number, height?: number}} [options]
 *   readback: keep the drawing buffer so the canvas can be read after a frame; width/height: a
 *   fixed canvas size (else the canvas's own)
 * @returns {Promise<pc.Application>}
 */
export async function startApp(canvas, options = {}) {
    const backend = options.backend || 'webgl2';
    if (options.width && options.height) {
        canvas.width = options.width;
        canvas.height = options.height;
    }
    const graphicsDevice = await pc.createGraphicsDevice(canvas, /** @type {any} */ ({
        deviceTypes: [backend], antialias: false, alpha: false, preserveDrawingBuffer: !!options.readback,
    }));
    if (graphicsDevice.deviceType !== backend) throw new Error(`no ${backend} device (got ${graphicsDevice.deviceType})`);
    const app = new pc.Application(canvas, { graphicsDevice });
    app.setCanvasFillMode(pc.FILLMODE_NONE);
    app.setCanvasResolution(pc.RESOLUTION_FIXED, canvas.width, canvas.height);
    app.autoRender = false;
    return app;
}

/**
 * The engine and device of `app`, as the harnesses report them (harness.json).
 * @param {pc.Application} app
 */
export function describeBackend(app) {
    const device = /** @type {any} */ (app.graphicsDevice);
    if (device.isWebGPU) {
        const info = device.gpuAdapter?.info || {};
        return {
            engine: 'PlayCanvas', engine_version: pc.version, device: device.deviceType,
            renderer: `WebGPU adapter: ${[info.vendor, info.architecture, info.device, info.description].filter(Boolean).join(' ') || 'unknown'}`,
            vendor: info.vendor || '', version: 'WebGPU', shading_language: 'WGSL', float_precision: 'f32',
            user_agent: navigator.userAgent,
        };
    }
    const gl = device.gl;
    const info = gl.getExtension('WEBGL_debug_renderer_info');
    const p = gl.getShaderPrecisionFormat(gl.FRAGMENT_SHADER, gl.HIGH_FLOAT);
    return {
        engine: 'PlayCanvas', engine_version: pc.version, device: device.deviceType,
        renderer: info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER),
        vendor: info ? gl.getParameter(info.UNMASKED_VENDOR_WEBGL) : gl.getParameter(gl.VENDOR),
        version: gl.getParameter(gl.VERSION), shading_language: gl.getParameter(gl.SHADING_LANGUAGE_VERSION),
        float_precision: `highp float: precision ${p.precision} bits, range 2^${p.rangeMin}..2^${p.rangeMax}`,
        user_agent: navigator.userAgent,
    };
}

/**
 * Render one frame and wait for it.
 * @param {pc.Application} app
 * @returns {Promise<void>}
 */
export function frame(app) {
    return new Promise((resolve) => {
        app.once('frameend', () => resolve(undefined));
        app.renderNextFrame = true;
    });
}

/**
 * The canvas's pixels, RGBA8, rows top to bottom (needs `readback` on WebGL2).
 * @param {pc.Application} app
 * @returns {Uint8Array}
 */
export function canvasPixels(app) {
    const device = /** @type {any} */ (app.graphicsDevice);
    const canvas = /** @type {HTMLCanvasElement} */ (device.canvas);
    const w = canvas.width, h = canvas.height;
    if (device.isWebGPU) {
        const copy = document.createElement('canvas');
        copy.width = w;
        copy.height = h;
        const ctx = /** @type {CanvasRenderingContext2D} */ (copy.getContext('2d'));
        ctx.drawImage(canvas, 0, 0);
        return new Uint8Array(ctx.getImageData(0, 0, w, h).data.buffer);
    }
    const gl = device.gl;
    const px = new Uint8Array(w * h * 4);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    const out = new Uint8Array(w * h * 4);
    for (let y = 0; y < h; ++y) out.set(px.subarray((h - 1 - y) * w * 4, (h - y) * w * 4), y * w * 4);
    return out;
}

/**
 * Render until `identical` consecutive frames are the same and something is drawn (the engine
 * sorts splats asynchronously, so a change shows a frame or two later); at most `maxFrames`.
 * Returns the last picture.
 * @param {pc.Application} app
 * @param {{identical?: number, maxFrames?: number}} [options]
 */
export async function settleFrames(app, options = {}) {
    const identical = options.identical ?? 1, maxFrames = options.maxFrames ?? 60;
    let previous = null, same = 0;
    let px = canvasPixels(app);
    for (let i = 0; i < maxFrames; ++i) {
        await frame(app);
        px = canvasPixels(app);
        let lit = false;
        for (let k = 0; k < px.length && !lit; k += 4) lit = px[k] + px[k + 1] + px[k + 2] > 24;
        const p = previous;
        same = lit && p && p.every((v, k) => v === px[k]) ? same + 1 : 0;
        if (same >= identical) break;
        previous = px;
    }
    return px;
}
