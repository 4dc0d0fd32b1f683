// Browser side of the render level of the conformance suite (conformance/run-browser.mjs drives
// it): each render case's asset is loaded with loadAnchoredAsset into a PlayCanvas scene, and
// for every frame of the manifest the anchor meshes are posed (rest, the frame's vertex file,
// or the file's own animation at a time), the camera is placed, the engine renders (remap in
// the work-buffer pass, splats sorted by the engine), and the canvas pixels go back to Node,
// which writes them as PNG for `gsverse-conformance check`.

import * as pc from 'playcanvas';
import { loadAnchoredAsset } from '../../src/playcanvas/index.js';

/** @type {pc.Application|null} */
let app = null;
/** @type {pc.Entity|null} */
let camera = null;
let sorts = 0;

/** @param {Uint8Array} bytes */
function toBase64(bytes) {
    let s = '';
    for (let i = 0; i < bytes.length; i += 0x8000) s += String.fromCharCode.apply(null, /** @type {any} */ (bytes.subarray(i, i + 0x8000)));
    return btoa(s);
}

/** @param {string} url */
async function fetchBytes(url) {
    const response = await fetch(url);
    if (!response.ok) throw new Error(`${url}: HTTP ${response.status}`);
    return new Uint8Array(await response.arrayBuffer());
}

/**
 * Start the application (WebGL2 or WebGPU) with a camera; returns the backend description.
 * @param {{backend?: 'webgl2'|'webgpu'}} [options]
 */
async function init(options = {}) {
    const canvas = /** @type {HTMLCanvasElement} */ (document.getElementById('canvas'));
    const backend = options.backend || 'webgl2';
    const graphicsDevice = await pc.createGraphicsDevice(canvas, /** @type {any} */ ({
        deviceTypes: [backend], antialias: false, alpha: false, preserveDrawingBuffer: true,
    }));
    if (graphicsDevice.deviceType !== backend) throw new Error(`no ${backend} device (got ${graphicsDevice.deviceType})`);
    app = new pc.Application(canvas, { graphicsDevice });
    app.setCanvasFillMode(pc.FILLMODE_NONE);
    app.autoRender = false;
    camera = new pc.Entity('camera');
    camera.addComponent('camera', {
        clearColor: new pc.Color(0, 0, 0, 1),
        // the splats' colours are sRGB display values: blend them as the engine does for its own
        // splats and write them sRGB-encoded, no tone mapping
        toneMapping: pc.TONEMAP_LINEAR, gammaCorrection: pc.GAMMA_SRGB,
    });
    app.root.addChild(camera);
    app.scene.on('gsplat:sorted', () => { sorts++; });
    app.start();
    const device = /** @type {any} */ (app.graphicsDevice);
    const gl = device.gl;
    const info = gl?.getExtension('WEBGL_debug_renderer_info');
    return {
        engine: 'PlayCanvas', engine_version: pc.version, device: device.deviceType,
        renderer: gl ? (info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER)) : 'WebGPU',
    };
}

function frame() {
    return new Promise((resolve) => {
        const a = /** @type {pc.Application} */ (app);
        a.once('frameend', () => resolve(undefined));
        a.renderNextFrame = true;
    });
}

/** @returns {Uint8Array} top-down RGBA8 pixels of the canvas */
function pixels() {
    const device = /** @type {any} */ ((/** @type {pc.Application} */ (app)).graphicsDevice);
    const canvas = /** @type {HTMLCanvasElement} */ (document.getElementById('canvas'));
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
 * The picture once the engine has sorted the current pose and drawn it: wait (up to
 * `sortWaitMs`) for a sort that finished after the change and until no anchored primitive has
 * its pose's sort pending, then until three consecutive frames are identical (at most
 * `maxFrames`).
 * @param {number} sortsBefore
 * @param {any[]} anchored  AnchoredSplat[]
 * @param {{sortWaitMs: number, maxFrames: number}} limits
 */
async function settle(sortsBefore, anchored, limits) {
    const t0 = performance.now();
    while ((sorts === sortsBefore || anchored.some((s) => s.sortPending)) && performance.now() - t0 < limits.sortWaitMs) await frame();
    let previous = null, same = 0, px = pixels();
    for (let i = 0; i < limits.maxFrames && same < 2; ++i) {
        await frame();
        px = pixels();
        same = previous && previous.every((v, k) => v === px[k]) ? same + 1 : 0;
        previous = px;
    }
    return px;
}

/**
 * Place the camera of a frame (manifest `camera`).
 * @param {any} cam
 */
function placeCamera(cam) {
    const a = /** @type {pc.Application} */ (app);
    const c = /** @type {pc.Entity} */ (camera);
    const canvas = /** @type {HTMLCanvasElement} */ (document.getElementById('canvas'));
    if (canvas.width !== cam.width || canvas.height !== cam.height) {
        a.setCanvasResolution(pc.RESOLUTION_FIXED, cam.width, cam.height);
        a.resizeCanvas(cam.width, cam.height);
    }
    const cc = /** @type {any} */ (c.camera);
    cc.fov = cam.fov_y_degrees;
    cc.nearClip = cam.near;
    cc.farClip = cam.far;
    cc.horizontalFov = false;
    c.setPosition(cam.eye[0], cam.eye[1], cam.eye[2]);
    c.lookAt(new pc.Vec3(cam.target[0], cam.target[1], cam.target[2]), new pc.Vec3(cam.up[0], cam.up[1], cam.up[2]));
}

/**
 * Render every frame of one render case.
 * @param {string} path  the case folder relative to the suite
 * @param {{fault?: string|null, sortWaitMs?: number, maxFrames?: number}} options
 * @returns {Promise<{frames?: {name: string, rgba: string, width: number, height: number}[], refused?: string, code?: string}>}
 */
async function renderCase(path, options) {
    if (!app) throw new Error('init() first');
    const limits = { sortWaitMs: options.sortWaitMs ?? 3000, maxFrames: options.maxFrames ?? 120 };
    const base = `/suite/${path}/`;
    const manifest = await (await fetch(`${base}case.json`)).json();
    const bytes = await fetchBytes(base + manifest.files.asset);
    let loaded;
    try {
        loaded = await loadAnchoredAsset(app, bytes, { name: manifest.files.asset, fault: options.fault ?? null });
    } catch (err) {
        const e = /** @type {any} */ (err);
        if (e && e.name === 'AnchorError') return { refused: `${e.code}: ${e.message}`, code: e.code };
        throw err;
    }
    const { root, anchored, asset } = loaded;
    const out = [];
    try {
        for (const f of manifest.frames) {
            placeCamera(f.camera);
            const before = sorts;
            const d = f.deformation;
            if (d.kind === 'rest') {
                for (const s of anchored) s.reset();
            } else if (d.kind === 'vertices') {
                const all = new Float32Array((await fetchBytes(base + d.file)).buffer);
                let at = 0;
                for (const s of anchored) {
                    const n = 3 * s.prim.anchorMesh.vertexCount;
                    s.setVertices(all.subarray(at, at + n));
                    at += n;
                }
                if (at !== all.length) throw new Error(`${d.file}: ${all.length / 3} vertices, the anchor meshes have ${at / 3}`);
            } else if (d.kind === 'animation') {
                for (const s of anchored) {
                    if (!s.animation) throw new Error(`frame ${f.index}: the asset's anchor mesh carries no animation the plugin can play`);
                    s.setAnimationTime(d.animation, d.time);
                }
            } else {
                throw new Error(`frame ${f.index}: unknown deformation kind ${d.kind}`);
            }
            const px = await settle(before, anchored, limits);
            out.push({ name: f.result, rgba: toBase64(px), width: f.camera.width, height: f.camera.height });
        }
    } finally {
        for (const s of anchored) s.destroy();
        root.destroy();
        /** @type {pc.Application} */ (app).assets.remove(asset);
        asset.unload();
    }
    return { frames: out };
}

/** @type {any} */ (window).gsvRenderCases = { init, renderCase };
/** @type {any} */ (window).gsvReady = true;
