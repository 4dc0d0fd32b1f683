// Browser side of the render level of the conformance suite for the three.js plugin
// (conformance/run-browser.mjs --engine three drives it): each render case's asset is loaded
// with the plugin's loadAnchoredAsset into a three.js scene with Spark's renderer, and for every
// frame of the manifest the anchor meshes are posed (rest, the frame's vertex file, or the
// file's own animation at a time), the camera is placed, Spark remaps (its object modifier),
// sorts and draws, and the canvas pixels go back to Node, which writes them as PNG for
// `gsverse-conformance check`. The twin of render-cases.js.

import * as THREE from 'three';
import { loadAnchoredAsset } from '../../src/three/index.js';
import { fetchBytes, toBase64 } from './bytes.js';
import { describeThree, startThree } from './three-engine.js';

/** @type {ReturnType<typeof startThree>|null} */
let engine = null;
const camera = new THREE.PerspectiveCamera();

/**
 * Start the renderer (WebGL2 only); returns the backend description.
 * @param {{backend?: string}} [options]
 */
async function init(options = {}) {
    if (options.backend && options.backend !== 'webgl2') throw new Error(`the three.js plugin runs on WebGL2 only (asked for ${options.backend})`);
    const canvas = /** @type {HTMLCanvasElement} */ (document.getElementById('canvas'));
    engine = startThree(canvas);
    engine.scene.background = new THREE.Color(0, 0, 0);
    return describeThree(engine.renderer);
}

/** The canvas's pixels, RGBA8, rows top to bottom. */
function canvasPixels() {
    const { renderer } = /** @type {ReturnType<typeof startThree>} */ (engine);
    const gl = renderer.getContext();
    const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
    const px = new Uint8Array(w * h * 4);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    const out = new Uint8Array(w * h * 4);
    for (let y = 0; y < h; ++y) out.set(px.subarray((h - 1 - y) * w * 4, (h - y) * w * 4), y * w * 4);
    return out;
}

/**
 * Is Spark done with the current scene: the splats generated for the meshes' current versions,
 * sorted, and that sorted set the one on display?
 * @param {any} spark  the SparkRenderer
 */
function sparkIdle(spark) {
    return !spark.sorting && !spark.sortDirty && spark.display === spark.current;
}

/**
 * Render until Spark is idle (sparkIdle: it regenerates and sorts the splats asynchronously,
 * so a change shows a few frames later) and `identical` consecutive pictures are the same with
 * something drawn; at least `maxFrames` frames, and for as long as `waitMs` allows (a busy
 * machine is slower, not failing). Returns the last picture.
 * @param {{identical: number, maxFrames: number, waitMs: number}} limits
 */
async function settle(limits) {
    const { renderer, scene, spark } = /** @type {ReturnType<typeof startThree>} */ (engine);
    let previous = null, same = 0, px = canvasPixels();
    const t0 = performance.now();
    for (let i = 0; i < limits.maxFrames || performance.now() - t0 < limits.waitMs; ++i) {
        renderer.render(scene, camera);
        await new Promise((r) => requestAnimationFrame(() => r(undefined)));
        px = canvasPixels();
        let lit = false;
        for (let k = 0; k < px.length && !lit; k += 4) lit = px[k] + px[k + 1] + px[k + 2] > 24;
        const p = previous;
        same = lit && sparkIdle(spark) && p && p.every((v, k) => v === px[k]) ? same + 1 : 0;
        if (same >= limits.identical) break;
        previous = px;
    }
    return px;
}

/**
 * Place the camera of a frame (manifest `camera`).
 * @param {any} cam
 */
function placeCamera(cam) {
    const { renderer } = /** @type {ReturnType<typeof startThree>} */ (engine);
    const canvas = renderer.domElement;
    if (canvas.width !== cam.width || canvas.height !== cam.height) renderer.setSize(cam.width, cam.height, false);
    camera.fov = cam.fov_y_degrees;
    camera.aspect = cam.width / cam.height;
    camera.near = cam.near;
    camera.far = cam.far;
    camera.position.set(cam.eye[0], cam.eye[1], cam.eye[2]);
    camera.up.set(cam.up[0], cam.up[1], cam.up[2]);
    camera.lookAt(cam.target[0], cam.target[1], cam.target[2]);
    camera.updateProjectionMatrix();
    camera.updateMatrixWorld();
}

/**
 * Render every frame of one render case.
 * @param {string} path  the case folder relative to the suite
 * @param {{fault?: string|null, sortWaitMs?: number, maxFrames?: number}} options  sortWaitMs: how
 *   long a pose may take to be regenerated, sorted and shown (the runner scales it with the load)
 * @returns {Promise<{frames?: {name: string, rgba: string, width: number, height: number}[], refused?: string, code?: string}>}
 */
async function renderCase(path, options) {
    if (!engine) throw new Error('init() first');
    const limits = { identical: 2, maxFrames: options.maxFrames ?? 60, waitMs: options.sortWaitMs ?? 3000 };
    const base = `/suite/${path}/`;
    const manifest = await (await fetch(`${base}case.json`)).json();
    const bytes = await fetchBytes(base + manifest.files.asset);
    let loaded;
    try {
        loaded = await loadAnchoredAsset(bytes, { name: manifest.files.asset, fault: options.fault ?? null });
    } catch (err) {
        const e = /** @type {any} */ (err);
        if (e && e.name === 'AnchorError') return { refused: `${e.code}: ${e.message}`, code: e.code };
        throw err;
    }
    const { root, anchored, plain } = loaded;
    engine.scene.add(root);
    const out = [];
    try {
        for (const f of manifest.frames) {
            placeCamera(f.camera);
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
            const px = await settle(limits);
            out.push({ name: f.result, rgba: toBase64(px), width: f.camera.width, height: f.camera.height });
        }
    } finally {
        root.removeFromParent();
        for (const s of anchored) s.destroy();
        for (const m of plain) m.dispose();
    }
    return { frames: out };
}

/** @type {any} */ (window).gsvRenderCases = { init, renderCase };
/** @type {any} */ (window).gsvReady = true;
