// Browser side of the GPU conformance run (conformance/run-browser.mjs drives it): a
// PlayCanvas application on WebGL2; every case is imported with loadAnchoredAsset (engine
// container loading + our reader), each pose is remapped on the GPU by the same remap chunk
// as the render (RemapProbe: the engine's GSplatProcessor over the splat streams), and the
// float32 results are read back from the GPU. Arrays go back to Node as base64. The poses of
// a rig case are the asset's own animation sampled in the page (src/animation.js: morph,
// skin, M⁻¹; conformance/rig-pose.js) at each pose's time.

import * as pc from 'playcanvas';
import { loadAnchoredAsset } from '../../src/playcanvas/index.js';
import { RemapProbe } from '../../src/playcanvas/probe.js';
import { ANIMATION_FAULTS, readAnchorAnimation } from '../../src/animation.js';
import { rigPose } from '../rig-pose.js';
import { describeBackend, fetchBytes, startApp, toBase64 } from './engine-page.js';

/** @type {pc.Application|null} */
let app = null;

/**
 * Start the application on a WebGL2 or WebGPU device; returns the backend description.
 * @param {{backend?: 'webgl2'|'webgpu'}} [options]
 */
async function init(options = {}) {
    const canvas = /** @type {HTMLCanvasElement} */ (document.getElementById('canvas'));
    app = await startApp(canvas, { backend: options.backend });
    return describeBackend(app);
}

/**
 * Import one case, remap every pose on the GPU, read back.
 * @param {string} path  the case folder relative to the suite, e.g. cases/local-affine-stretch
 * @param {{fault?: string|null}} options  fault: a shader fault (src/playcanvas/shader.js) or
 *   an animation fault (ANIMATION_FAULTS of src/animation.js)
 */
async function runCase(path, options) {
    if (!app) throw new Error('init() first');
    const base = `/suite/${path}/`;
    const manifest = await (await fetch(`${base}case.json`)).json();
    const bytes = await fetchBytes(base + manifest.files.asset);
    const fault = options.fault ?? null;
    const animationFault = fault !== null && ANIMATION_FAULTS.includes(fault) ? fault : null;
    const shaderFault = animationFault ? null : fault;
    const rig = manifest.kind === 'rig';
    const t0 = performance.now();
    let loaded;
    try {
        loaded = await loadAnchoredAsset(app, bytes, { name: manifest.files.asset, parent: null, fault: shaderFault });
    } catch (err) {
        const e = /** @type {any} */ (err);
        if (e && e.name === 'AnchorError') return { refused: `${e.code}: ${e.message}`, code: e.code };
        throw err;
    }
    const { root, anchored, asset } = loaded;
    /** @type {any} */
    const out = {};
    let probe = null;
    try {
        if (anchored.length !== 1) throw new Error(`expected one anchored splat primitive, found ${anchored.length}`);
        const splat = anchored[0];
        const prim = splat.prim;
        out.rest = {
            means: toBase64(prim.rest.means), rotation: toBase64(prim.rest.rotations), scale: toBase64(prim.rest.scales),
            opacity: toBase64(prim.rest.opacity), sh: toBase64(prim.rest.sh),
        };
        probe = new RemapProbe(splat.gpu, { fault: shaderFault });
        const animation = !rig ? null : animationFault
            ? readAnchorAnimation(bytes, prim, { name: manifest.files.asset, fault: animationFault }) : splat.animation;
        out.poses = [];
        let gpuMs = 0;
        const count = rig ? manifest.poses.length : manifest.files.poses.length;
        for (let p = 0; p < count; ++p) {
            const vertices = rig ? rigPose(animation, manifest.poses[p].source)
                : new Float32Array((await fetchBytes(base + manifest.files.poses[p])).buffer);
            const t1 = performance.now();
            probe.run(vertices);
            const r = await probe.read();
            gpuMs += performance.now() - t1;
            out.poses.push({ means: toBase64(r.means), rotation: toBase64(r.rotations), scale: toBase64(r.scales) });
        }
        // opacity and SH pass through the remap (the shader never touches them)
        out.posed = { opacity: out.rest.opacity, sh: out.rest.sh };
        out.stats = { splats: prim.count, faces: splat.rest.faceCount, loadMs: t0, gpuMs };
    } finally {
        probe?.destroy();
        for (const s of anchored) s.destroy();
        root.destroy();
        app.assets.remove(asset);
        asset.unload();
    }
    out.stats.loadMs = performance.now() - out.stats.loadMs - out.stats.gpuMs;
    return out;
}

/** @type {any} */ (window).gsvConformance = { init, runCase };
/** @type {any} */ (window).gsvReady = true;
