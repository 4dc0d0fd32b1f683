// The GS-Verse web demo: a PlayCanvas app that loads an anchored GLB with @gsverse/web/playcanvas
// (splats remapped on the GPU), turns each anchor mesh into a Jolt soft body, and lets the user
// stretch, twist, shake and drop it. `window.gsverseDemo` is a scripted API for tests.
//
// URL parameters: ?asset=URL (default: the asset the server names in /config.json),
// ?test (fixed front camera, plain background, no panel or ground, physics paused: for
// deterministic screenshots).

import * as pc from 'playcanvas';
import initJolt from 'jolt-physics';
import { PhysicsWorld, axisIndex } from './physics.js';
import { DemoAsset } from './scene.js';
import { OrbitCamera, Grabber } from './input.js';
import { RemapTimer } from './gputimer.js';

const params = new URLSearchParams(location.search);
const TEST = params.has('test');
const DT = 1 / 60;
const CAP = 0.12;

/** @param {string} id */
const $ = (id) => /** @type {HTMLElement} */ (document.getElementById(id));
const input = (/** @type {string} */ id) => /** @type {HTMLInputElement} */ ($(id));

/** @type {(value: any) => void} */
let resolveReady = () => {};
/** @type {(reason: any) => void} */
let rejectReady = () => {};
const ready = new Promise((res, rej) => { resolveReady = res; rejectReady = rej; });
ready.catch(() => {});      // reported on the page; callers that await it still see the error

/** Resolves after `n` rendered frames. @param {number} [n] */
function frames(n = 2) {
    return new Promise((resolve) => {
        const tick = () => (--n <= 0 ? resolve(undefined) : requestAnimationFrame(tick));
        requestAnimationFrame(tick);
    });
}

// ---- page state ------------------------------------------------------------------------------

/** @type {any} */ let app = null;
/** @type {PhysicsWorld|null} */ let world = null;
/** @type {DemoAsset|null} */ let current = null;
/** @type {OrbitCamera|null} */ let orbit = null;
/** @type {RemapTimer|null} */ let timer = null;
/** @type {any} */ let ground = null;
let paused = TEST;
let dirty = true;
let accumulator = 0;
let stepMs = 0;
/** @type {null | {t: number, duration: number, amplitude: number}} */
let shake = null;
/** the camera follows the body while it falls and rolls (after drop) */
let follow = false;
let backend = '';
let software = false;
let assetLabel = 'no asset';

const state = { axis: /** @type {0|1|2} */ (1), stretch: 1, twist: 0 };

/** @param {unknown} err */
function showError(err) {
    const e = /** @type {any} */ (err);
    const text = e?.name === 'AnchorError'
        ? `Refused: ${e.message} [${e.code}]`
        : `Error: ${e?.message ?? String(err)}`;
    const box = $('error');
    box.textContent = text;
    box.dataset.code = e?.code ?? '';
    box.classList.add('show');
    console.error(err);
}

function hideError() {
    $('error').classList.remove('show');
    $('error').textContent = '';
}

/** Bring every soft body back to rest, free all pins, reset the sliders. */
function resetAll() {
    shake = null;
    follow = false;
    state.stretch = 1;
    state.twist = 0;
    input('stretch').value = '1';
    input('twist').value = '0';
    updateLabels();
    current?.reset();
    if (current && orbit && current.bodies.length) {
        const c = current.restBounds().center;
        orbit.target.set(c[0], c[1], c[2]);
        orbit.apply();
    }
    dirty = true;
}

function updateLabels() {
    $('stretch-val').textContent = `${state.stretch.toFixed(2)}×`;
    $('twist-val').textContent = `${Math.round(state.twist)}°`;
}

/** Hold both end caps at the slider pose (stretch, then twist) and let the body follow. */
function holdSliders() {
    if (!current) return;
    shake = null;
    for (const b of current.bodies) {
        const s = b.soft;
        const st = s.stretchMap(state.axis, state.stretch);
        const tw = s.twistMap(state.axis, state.twist, CAP);
        s.hold(state.axis, (p) => st(tw(p)), CAP);
    }
}

function releaseAll() {
    shake = null;
    for (const b of current?.bodies ?? []) b.soft.setPins(null);
}

function startShake() {
    if (!current) return;
    resetAll();
    shake = { t: 0, duration: 2, amplitude: 0.12 * Math.max(...current.restBounds().size) };
    for (const b of current.bodies) {
        /** @type {Map<number, number[]>} */
        const pins = new Map();
        for (const i of b.soft.endCap(state.axis, -1, 0.2)) pins.set(i, [b.soft.rest[3 * i], b.soft.rest[3 * i + 1], b.soft.rest[3 * i + 2]]);
        b.soft.setPins(pins);
    }
}

/** @param {number} dt */
function advanceShake(dt) {
    if (!shake || !current) return;
    shake.t += dt;
    if (shake.t >= shake.duration) {
        releaseAll();
        return;
    }
    const side = state.axis === 0 ? 2 : 0;
    const amp = shake.amplitude * Math.sin(2 * Math.PI * 3 * shake.t) * Math.min(1, 4 * (shake.duration - shake.t));
    for (const b of current.bodies) {
        const s = b.soft;
        if (!s.targets) continue;
        for (let i = 0; i < s.count; i++) {
            if (Number.isNaN(s.targets[3 * i])) continue;
            const t = [s.rest[3 * i], s.rest[3 * i + 1], s.rest[3 * i + 2]];
            t[side] += amp;
            s.targets.set(t, 3 * i);
        }
    }
}

function drop() {
    if (!current || !world) return;
    resetAll();
    const rb = current.restBounds();
    const lift = 0.5 * rb.size[1];
    for (const b of current.bodies) {
        b.soft.placeAt([0, lift, 0]);
        b.soft.setGravity(1);
    }
    paused = false;
    follow = true;
    $('pause').textContent = 'pause';
}

/** Place the camera and the ground for the current asset. */
function frameAsset() {
    if (!current || !orbit || !world) return;
    const rb = current.bodies.length ? current.restBounds() : { center: [0, 0, 0], size: [1, 1, 1], min: [-0.5, -0.5, -0.5] };
    const size = Math.max(...rb.size) || 1;
    state.axis = /** @type {0|1|2} */ (rb.size.indexOf(Math.max(...rb.size)));
    const groundY = rb.min[1] - 0.2 * rb.size[1];
    world.setGround(groundY, 20 * size, [rb.center[0], rb.center[2]]);
    if (ground) {
        ground.setPosition(rb.center[0], groundY, rb.center[2]);
        ground.setLocalScale(20 * size, 1, 20 * size);
    }
    if (TEST) {
        orbit.yaw = 0;
        orbit.pitch = 0;
        orbit.frame(rb.center, 1.9 * size);
    } else {
        orbit.yaw = 25;
        orbit.pitch = -15;
        orbit.frame(rb.center, 1.8 * size);
    }
}

/**
 * Open an asset (URL or bytes). A refused asset leaves the current one in place and shows why.
 * @param {string|Uint8Array} source
 * @param {string} name
 */
async function open(source, name) {
    if (!app || !world) throw new Error('the demo is not started');
    hideError();
    $('asset').textContent = `loading ${name}…`;
    let next;
    try {
        next = await DemoAsset.load(app, world, source, name);
    } catch (err) {
        $('asset').textContent = assetLabel;
        showError(err);
        throw err;
    }
    current?.destroy();
    current = next;
    resetAll();
    frameAsset();
    const c = current.counts();
    const meshes = current.bodies.map((b) => `${b.soft.anchorCount} vertices (${b.soft.count} welded), ${b.soft.faces.length / 3} faces${b.soft.closed ? '' : ', open'}`);
    assetLabel = `${name}: ${c.anchored} anchored splats${c.plain ? `, ${c.plain} plain` : ''}`;
    $('asset').textContent = assetLabel;
    $('asset').title = meshes.join('\n');
    if (current.bodies.length === 0) showError(new Error(`${name}: no anchored splat primitive (plain splats are shown; nothing to deform)`));
    dirty = true;
    await frames(3);
    return info();
}

function info() {
    return {
        asset: current?.name ?? null,
        splats: current?.counts() ?? null,
        bodies: current?.bodies.map((b) => ({ vertices: b.soft.anchorCount, welded: b.soft.count, faces: b.soft.faces.length / 3, closed: b.soft.closed })) ?? [],
        axis: 'xyz'[state.axis],
        backend,
        gpuTimer: !!timer?.available,
        remapGpuMs: timer?.ms ?? null,
        remapCpuMs: current?.remapCpuMs() ?? null,
        paused,
    };
}

function updateStats() {
    if (!current) return;
    const cpu = `${current.remapCpuMs().toFixed(3)} ms CPU (vertex upload + pass scheduling)`;
    let remap;
    if (timer?.available && timer.ms !== null) {
        remap = `remap pass: ${timer.ms.toFixed(3)} ms GPU timer query (work-buffer pass)` +
            (software ? `\n  software rasterizer: the timer counts CPU emulation, not GPU time` : '') + `\n  vertex update: ${cpu}`;
    } else {
        remap = `remap: ${cpu}; ${timer?.available ? 'waiting for a GPU timing' : 'no GPU timer queries on this device'}`;
    }
    const fps = app?.stats?.frame?.fps ?? 0;
    const shortBackend = software ? 'WebGL2 · software rasterizer (SwiftShader)' : backend;
    $('stats').textContent = `${remap}\nphysics: ${stepMs.toFixed(2)} ms/step (Jolt soft body)\n${fps} fps · ${shortBackend}${paused ? ' · paused' : ''}`;
}

// ---- start-up -------------------------------------------------------------------------------

async function start() {
    const canvas = /** @type {HTMLCanvasElement} */ ($('canvas'));
    if (TEST) document.body.classList.add('test');
    app = new pc.Application(canvas, {
        graphicsDeviceOptions: { deviceTypes: ['webgl2'], antialias: false, alpha: false, preserveDrawingBuffer: TEST },
    });
    app.setCanvasFillMode(pc.FILLMODE_FILL_WINDOW);
    app.setCanvasResolution(pc.RESOLUTION_AUTO);
    window.addEventListener('resize', () => app.resizeCanvas());
    const gl = app.graphicsDevice.gl;
    const dbg = gl?.getExtension('WEBGL_debug_renderer_info');
    const renderer = gl ? String(dbg ? gl.getParameter(dbg.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER)) : '';
    software = /swiftshader|llvmpipe|software/i.test(renderer);
    backend = gl ? `WebGL2, ${renderer}` : app.graphicsDevice.deviceType;

    const camera = new pc.Entity('camera');
    camera.addComponent('camera', {
        clearColor: TEST ? new pc.Color(0, 0, 0) : new pc.Color(0.106, 0.114, 0.133),
        fov: 35, nearClip: 0.01, farClip: 1000,
    });
    app.root.addChild(camera);
    const light = new pc.Entity('light');
    light.addComponent('light', { type: 'directional', intensity: 1.2 });
    light.setEulerAngles(50, 30, 0);
    app.root.addChild(light);
    app.scene.ambientLight = new pc.Color(0.35, 0.35, 0.4);
    if (!TEST) {
        ground = new pc.Entity('ground');
        const material = new pc.StandardMaterial();
        material.diffuse = new pc.Color(0.32, 0.34, 0.38);
        material.update();
        ground.addComponent('render', { type: 'plane', material });
        app.root.addChild(ground);
    }
    orbit = new OrbitCamera(camera);
    timer = new RemapTimer(app);
    const grabber = new Grabber(canvas, camera, orbit, () => current, {
        onGrab: () => { shake = null; paused = false; $('pause').textContent = 'pause'; },
    });
    grabber.enabled = !TEST;

    const Jolt = await initJolt();
    world = new PhysicsWorld(Jolt);

    const wireColor = new pc.Color(0.3, 1, 0.55, 1);
    app.on('update', (/** @type {number} */ dt) => {
        timer?.update();
        if (!current) return;
        if (!paused) {
            accumulator += Math.min(dt, 0.1);
            let n = 0;
            const t0 = performance.now();
            while (accumulator >= DT && n < 4) {
                advanceShake(DT);
                current.step(DT);
                accumulator -= DT;
                n++;
            }
            if (n) {
                stepMs = (performance.now() - t0) / n;
                dirty = true;
            }
            if (n === 4) accumulator = 0;
        }
        if (dirty) {
            current.sync();
            dirty = false;
        }
        if (follow && !grabber.grab && orbit && current.bodies.length) {
            const c = current.bounds().center, t = orbit.target, k = Math.min(1, 3 * dt);
            t.set(t.x + k * (c[0] - t.x), t.y + k * (c[1] - t.y), t.z + k * (c[2] - t.z));
            orbit.apply();
        }
        if (input('wire').checked) current.drawWireframe(wireColor);
    });
    setInterval(updateStats, 250);
    app.start();
    bindUi();

    /** @type {{asset?: string|null}} */
    const config = await fetch('/config.json').then((r) => (r.ok ? r.json() : {})).catch(() => ({}));
    const url = params.get('asset') || config.asset;
    if (!url) throw new Error('no asset to open: drop an anchored .glb onto the page');
    const name = decodeURIComponent(url.split('/').pop() || 'asset.glb');
    return open(url, name);
}

function bindUi() {
    input('stretch').addEventListener('input', () => {
        state.stretch = Number(input('stretch').value);
        updateLabels();
        paused = false;
        holdSliders();
    });
    input('twist').addEventListener('input', () => {
        state.twist = Number(input('twist').value);
        updateLabels();
        paused = false;
        holdSliders();
    });
    $('release').addEventListener('click', () => {
        releaseAll();
        state.stretch = 1;
        state.twist = 0;
        input('stretch').value = '1';
        input('twist').value = '0';
        updateLabels();
    });
    $('shake').addEventListener('click', () => { paused = false; startShake(); });
    $('drop-btn').addEventListener('click', drop);
    $('reset').addEventListener('click', resetAll);
    $('pause').addEventListener('click', () => {
        paused = !paused;
        $('pause').textContent = paused ? 'resume' : 'pause';
    });
    $('error').addEventListener('click', hideError);
    const overlay = $('drop');
    window.addEventListener('dragover', (e) => { e.preventDefault(); overlay.classList.add('show'); });
    window.addEventListener('dragleave', (e) => { if (!e.relatedTarget) overlay.classList.remove('show'); });
    window.addEventListener('drop', async (e) => {
        e.preventDefault();
        overlay.classList.remove('show');
        const file = e.dataTransfer?.files?.[0];
        if (!file) return;
        const bytes = new Uint8Array(await file.arrayBuffer());
        open(bytes, file.name).catch(() => {});
    });
}

// ---- scripted API (tests) ---------------------------------------------------------------------

/** Scripted manipulations run deterministically: physics paused, end caps driven kinematically. */
async function scripted(/** @type {(b: import('./scene.js').Body) => void} */ fn) {
    await ready;
    if (!current) throw new Error('no asset loaded');
    paused = true;
    shake = null;
    for (const b of current.bodies) fn(b);
    current.sync();
    dirty = false;
    await frames(4);
    await new Promise((r) => setTimeout(r, 100));
    await frames(2);
    return api.extent();
}

const api = {
    ready,
    /**
     * Stretch every anchor mesh by `factor` along a world axis (its end caps pinned and moved
     * apart, the rest settled by the solver).
     * @param {string|number} axis @param {number} factor
     */
    pull: (axis, factor) => {
        if (axisIndex(axis) === state.axis) {
            state.stretch = factor;
            input('stretch').value = String(factor);
            updateLabels();
        }
        return scripted((b) => b.soft.pull(axisIndex(axis), factor, { cap: CAP }));
    },
    /**
     * Twist every anchor mesh by `deg` about a world axis (default: its longest rest axis).
     * @param {number} deg @param {string|number} [axis]
     */
    twist: (deg, axis) => scripted((b) => b.soft.twist(axis === undefined ? state.axis : axisIndex(axis), deg, { cap: CAP })),
    /** Back to the rest pose. */
    reset: async () => {
        await ready;
        paused = TEST;
        resetAll();
        await frames(4);
        await new Promise((r) => setTimeout(r, 100));
        await frames(2);
        return api.extent();
    },
    /** Current world-space size [x, y, z] of the anchor meshes. */
    extent: () => (current && current.bodies.length ? current.bounds().size : null),
    /** Pause (true) or resume (false) the physics. @param {boolean} [on] */
    pause: (on = true) => { paused = !!on; $('pause').textContent = paused ? 'resume' : 'pause'; return paused; },
    /** Open an asset by URL or bytes. @param {string|Uint8Array} source @param {string} [name] */
    load: (source, name) => open(source, name || (typeof source === 'string' ? source.split('/').pop() || 'asset.glb' : 'asset.glb')),
    drop,
    shake: () => { paused = false; startShake(); },
    info,
    frames,
    /** The error shown on the page, or null. */
    error: () => ($('error').classList.contains('show') ? { text: $('error').textContent, code: $('error').dataset.code || null } : null),
};
/** @type {any} */ (window).gsverseDemo = api;

start().then(resolveReady, (err) => {
    if (!$('error').classList.contains('show')) showError(err);
    rejectReady(err);
});
