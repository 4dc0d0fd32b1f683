// Renders an anchored GLB in PlayCanvas (through @gsverse/web's loadAnchoredAsset, so posed
// anchor vertices go through the GPU remap) with an explicit camera, and returns the pixels.
// Driven by render-playcanvas.mjs; compared with gsverse-render by tests/test_render.py.

import * as pc from '/pkg/node_modules/playcanvas/build/playcanvas.mjs';
import { loadAnchoredAsset } from '/pkg/src/playcanvas/index.js';
import { settleFrames, startApp } from '/pkg/conformance/page/engine-page.js';

/** @type {any} */
let app = null;
/** @type {any} */
let loaded = null;

/** Render until two consecutive frames are identical (the engine sorts asynchronously). */
const settle = () => settleFrames(app, { identical: 1 });

/**
 * @param {{url: string, width: number, height: number, eye: number[], target: number[], fov: number,
 *          near: number, far: number, vertices?: number[]|null, gamma: string}} o
 */
async function render(o) {
    const canvas = /** @type {HTMLCanvasElement} */ (document.getElementById('canvas'));
    app = await startApp(canvas, { readback: true, width: o.width, height: o.height });
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
