// Browser side of the render level of the conformance suite (conformance/run-browser.mjs drives
// it): each render case's asset is loaded with loadAnchoredAsset into a PlayCanvas scene, and
// for every frame of the manifest the anchor meshes are posed (rest, the frame's vertex file,
// or the file's own animation at a time), the camera is placed, the engine renders (remap in
// the work-buffer pass, splats sorted by the engine), and the canvas pixels go back to Node,
// which writes them as PNG for `gsverse-conformance check`.

import * as pc from 'playcanvas';
import { loadAnchoredAsset } from '../../src/playcanvas/index.js';
import { describeBackend, fetchBytes, frame, settleFrames, startApp, toBase64 } from './engine-page.js';

/** @type {pc.Application|null} */
let app = null;
/** @type {pc.Entity|null} */
let camera = null;
let sorts = 0;

/**
 * Start the application (WebGL2 or WebGPU) with a camera; returns the backend description.
 * @param {{backend?: 'webgl2'|'webgpu'}} [options]
 */
async function init(options = {}) {
    const canvas = /** @type {HTMLCanvasElement} */ (document.getElementById('canvas'));
    app = await startApp(canvas, { backend: options.backend, readback: true });
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
    return describeBackend(app);
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
    const a = /** @type {pc.Application} */ (app);
    const t0 = performance.now();
    while ((sorts === sortsBefore || anchored.some((s) => s.sortPending)) && performance.now() - t0 < limits.sortWaitMs) await frame(a);
    return settleFrames(a, { identical: 2, maxFrames: limits.maxFrames });
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
