// Browser side of the GPU conformance run of the three.js plugin (conformance/run-browser.mjs
// --engine three drives it): every case is imported with the plugin's loadAnchoredAsset (our
// reader, Spark's splats), each pose is remapped on the GPU by the same Spark modifier that
// renders (RemapProbe: Spark's Readback over the mesh's splats) and read back as float32.
// The poses of a rig case are the asset's own animation sampled in the page, as in harness.js.

import { loadAnchoredAsset } from '../../src/three/index.js';
import { RemapProbe } from '../../src/three/probe.js';
import { ANIMATION_FAULTS, readAnchorAnimation } from '../../src/animation.js';
import { rigPose } from '../rig-pose.js';
import { fetchBytes, toBase64 } from './bytes.js';
import { describeThree, startThree } from './three-engine.js';

/** @type {import('three').WebGLRenderer|null} */
let renderer = null;

/**
 * Start the renderer (WebGL2 only: Spark renders through three.js's WebGLRenderer).
 * @param {{backend?: string}} [options]
 */
async function init(options = {}) {
    if (options.backend && options.backend !== 'webgl2') throw new Error(`the three.js plugin runs on WebGL2 only (asked for ${options.backend})`);
    const canvas = /** @type {HTMLCanvasElement} */ (document.getElementById('canvas'));
    ({ renderer } = startThree(canvas));
    return describeThree(renderer);
}

/**
 * Import one case, remap every pose on the GPU, read back.
 * @param {string} path  the case folder relative to the suite
 * @param {{fault?: string|null}} options  a plugin fault (src/three/shader.js FAULTS) or an
 *   animation fault (ANIMATION_FAULTS of src/animation.js)
 */
async function runCase(path, options) {
    if (!renderer) throw new Error('init() first');
    const base = `/suite/${path}/`;
    const manifest = await (await fetch(`${base}case.json`)).json();
    const bytes = await fetchBytes(base + manifest.files.asset);
    const fault = options.fault ?? null;
    const animationFault = fault !== null && ANIMATION_FAULTS.includes(fault) ? fault : null;
    const shaderFault = animationFault ? null : fault;
    const rig = manifest.kind === 'rig';
    let loaded;
    try {
        loaded = await loadAnchoredAsset(bytes, { name: manifest.files.asset, fault: shaderFault });
    } catch (err) {
        const e = /** @type {any} */ (err);
        if (e && e.name === 'AnchorError') return { refused: `${e.code}: ${e.message}`, code: e.code };
        throw err;
    }
    const { anchored, plain } = loaded;
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
        probe = new RemapProbe(renderer, splat, { fault: shaderFault });
        const animation = !rig ? null : animationFault
            ? readAnchorAnimation(bytes, prim, { name: manifest.files.asset, fault: animationFault }) : splat.animation;
        out.poses = [];
        const count = rig ? manifest.poses.length : manifest.files.poses.length;
        for (let p = 0; p < count; ++p) {
            const vertices = rig ? rigPose(animation, manifest.poses[p].source)
                : new Float32Array((await fetchBytes(base + manifest.files.poses[p])).buffer);
            const r = await probe.run(vertices);
            out.poses.push({ means: toBase64(r.means), rotation: toBase64(r.rotations), scale: toBase64(r.scales) });
        }
        // opacity and SH pass through the remap (the modifier never touches them)
        out.posed = { opacity: out.rest.opacity, sh: out.rest.sh };
    } finally {
        probe?.destroy();
        for (const s of anchored) s.destroy();
        for (const m of plain) m.dispose();
    }
    return out;
}

/** @type {any} */ (window).gsvConformance = { init, runCase };
/** @type {any} */ (window).gsvReady = true;
