// The demo's engine adapter for PlayCanvas (@gsverse/web/playcanvas, splats remapped on the GPU).
// engine-three.js is its twin for three.js + Spark; main.js, scene.js and input.js only use the
// interface below (see the Engine typedef), so the physics, controls and scenes are the same on
// both engines.

import * as pc from 'playcanvas';
import { loadAnchoredAsset } from '@gsverse/web/playcanvas';
import { RemapProbe } from '@gsverse/web/playcanvas/probe.js';
import { RemapTimer } from './gputimer.js';

/**
 * @typedef {object} CameraRig  the demo's camera, engine-free (world space, CSS pixels, y down)
 * @property {number} fov  vertical field of view, degrees
 * @property {(eye: number[], target: number[]) => void} place  put the camera at `eye`, looking at `target`
 * @property {() => number[]} eye  its position
 * @property {() => number[]} forward  its unit view direction
 * @property {(p: number[]) => number[]} toScreen  a world point on the canvas [x, y]
 * @property {(x: number, y: number) => {origin: number[], dir: number[]}} ray  the ray under a
 *   canvas point, from the near plane (`origin`) to the far plane (`origin + dir`)
 */

/**
 * @typedef {object} SplatNode  the node of one anchored splat primitive, engine-free
 * @property {string} name
 * @property {() => Float64Array} matrix  its world matrix (column-major 4x4)
 * @property {(t: number[], q: number[]) => void} setPose  world translation and rotation (x, y, z, w); scale kept
 * @property {() => number[]} position
 * @property {() => number[]} rotation  (x, y, z, w)
 */

/**
 * @typedef {object} Loaded  an asset loaded into the engine's scene
 * @property {any[]} anchored  the plugin's anchored splats (setVertices, reset, prim, animation, destroy)
 * @property {any[]} plain
 * @property {{index: number, name: string, duration: number}[]} animations
 * @property {() => void} dispose  remove what the load added (after the anchored splats' destroy)
 */

/**
 * @typedef {object} Engine
 * @property {string} name  'playcanvas' or 'three'
 * @property {string} backend  the renderer, as the stats panel shows it
 * @property {boolean} software  a software rasterizer
 * @property {CameraRig} camera
 * @property {{place: (x: number, y: number, z: number, sx: number, sz: number) => void}|null} ground
 *   the visible ground plane (none in test mode)
 * @property {(bytes: Uint8Array, name: string) => Promise<Loaded>} load  refusals throw AnchorError
 * @property {(splat: any) => SplatNode} node
 * @property {(lines: Float32Array, color: number[]) => void} drawLines  segments (pairs of points) for this frame
 * @property {(fn: (dt: number) => void) => void} onUpdate  called every frame before it renders (dt in s)
 * @property {(fn: () => void) => void} onSorted  called on each of the engine's splat sorts
 * @property {() => number} fps
 * @property {() => boolean} idle  the engine has nothing pending for the current state of the splats
 * @property {() => RemapTimer|null} makeTimer  the GPU remap timer (PlayCanvas only)
 * @property {() => void} start
 */

/** @param {any} v @returns {number[]} */
const arr = (v) => [v.x, v.y, v.z];

/**
 * @param {HTMLCanvasElement} canvas
 * @param {{test: boolean}} options  test mode: black background, no ground, a preserved drawing buffer
 * @returns {Promise<Engine>}
 */
export async function createEngine(canvas, { test }) {
    const app = new pc.Application(canvas, {
        graphicsDeviceOptions: { deviceTypes: ['webgl2'], antialias: false, alpha: false, preserveDrawingBuffer: test },
    });
    app.setCanvasFillMode(pc.FILLMODE_FILL_WINDOW);
    app.setCanvasResolution(pc.RESOLUTION_AUTO);
    window.addEventListener('resize', () => app.resizeCanvas());
    const gl = app.graphicsDevice.gl;
    const dbg = gl?.getExtension('WEBGL_debug_renderer_info');
    const renderer = gl ? String(dbg ? gl.getParameter(dbg.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER)) : '';

    const camera = new pc.Entity('camera');
    camera.addComponent('camera', {
        clearColor: test ? new pc.Color(0, 0, 0) : new pc.Color(0.106, 0.114, 0.133),
        fov: 35, nearClip: 0.01, farClip: 1000,
    });
    app.root.addChild(camera);
    const light = new pc.Entity('light');
    light.addComponent('light', { type: 'directional', intensity: 1.2 });
    light.setEulerAngles(50, 30, 0);
    app.root.addChild(light);
    app.scene.ambientLight = new pc.Color(0.35, 0.35, 0.4);
    /** @type {any} */
    let plane = null;
    if (!test) {
        plane = new pc.Entity('ground');
        const material = new pc.StandardMaterial();
        material.diffuse = new pc.Color(0.32, 0.34, 0.38);
        material.update();
        plane.addComponent('render', { type: 'plane', material });
        app.root.addChild(plane);
    }
    const cam = /** @type {pc.CameraComponent} */ (camera.camera);
    const lineColor = new pc.Color();

    return {
        name: 'playcanvas',
        backend: gl ? `WebGL2, ${renderer}` : app.graphicsDevice.deviceType,
        software: /swiftshader|llvmpipe|software/i.test(renderer),
        camera: {
            fov: cam.fov,
            place: (eye, target) => {
                camera.setPosition(eye[0], eye[1], eye[2]);
                camera.lookAt(target[0], target[1], target[2]);
            },
            eye: () => arr(camera.getPosition()),
            forward: () => arr(camera.forward),
            toScreen: (p) => {
                const s = cam.worldToScreen(new pc.Vec3(p[0], p[1], p[2]));
                return [s.x, s.y];
            },
            ray: (x, y) => {
                const a = cam.screenToWorld(x, y, cam.nearClip), b = cam.screenToWorld(x, y, cam.farClip);
                return { origin: arr(a), dir: arr(b.sub(a)) };
            },
        },
        ground: plane && {
            place: (x, y, z, sx, sz) => {
                plane.setPosition(x, y, z);
                plane.setLocalScale(sx, 1, sz);
            },
        },
        load: async (bytes, name) => {
            const loaded = await loadAnchoredAsset(app, bytes, { name });
            return {
                anchored: loaded.anchored, plain: loaded.plain, animations: loaded.animations ?? [],
                dispose: () => {
                    loaded.root.destroy();
                    if (loaded.asset) {
                        app.assets.remove(loaded.asset);
                        loaded.asset.unload();
                    }
                },
            };
        },
        node: (splat) => ({
            name: splat.entity.name,
            matrix: () => Float64Array.from(splat.entity.getWorldTransform().data),
            setPose: (t, q) => {
                splat.entity.setPosition(t[0], t[1], t[2]);
                splat.entity.setRotation(q[0], q[1], q[2], q[3]);
            },
            position: () => arr(splat.entity.getPosition()),
            rotation: () => { const q = splat.entity.getRotation(); return [q.x, q.y, q.z, q.w]; },
        }),
        drawLines: (lines, color) => {
            lineColor.set(color[0], color[1], color[2], 1);
            app.drawLineArrays(/** @type {any} */ (lines), lineColor, false);
        },
        onUpdate: (fn) => { app.on('update', fn); },
        onSorted: (fn) => { app.scene.on('gsplat:sorted', fn); },
        fps: () => /** @type {any} */ (app).stats?.frame?.fps ?? 0,
        idle: () => true,       // the plugin's per-splat sortPending says it (main.js)
        makeTimer: () => new RemapTimer(app, (gpu) => new RemapProbe(gpu)),
        start: () => app.start(),
    };
}
