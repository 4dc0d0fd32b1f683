// The GS-Verse web demo: loads an anchored GLB with @gsverse/web/playcanvas or, with
// ?engine=three, @gsverse/web/three (splats remapped on the GPU; the engine adapters
// engine-playcanvas.js and engine-three.js), turns each anchor mesh into a Jolt soft body, and lets
// the user stretch, twist, shake and drop it. `window.gsverseDemo` is a scripted API for tests.
//
// URL parameters: ?asset=URL (default: the asset the server names in /config.json; the shipped
// physics scene is ?asset=scene.glb),
// ?test (fixed front camera, plain background, no panel or ground, physics paused: for
// deterministic screenshots), ?physics=surface and ?budget=N (the physics mesh, see physmesh.js),
// ?engine=three (three.js + Spark instead of PlayCanvas).

import initJolt from 'jolt-physics';
import { PhysicsWorld, axisIndex, DEFAULT_BUDGET } from './physics.js';
import { DemoAsset } from './scene.js';
import { OrbitCamera, Grabber } from './input.js';
import { SliderDrive, Shake, CAP } from './controls.js';
import { FrameWatch, physicsLabel, statsText, showErrorIn, hideErrorIn } from './report.js';
import { AnimationPlayer, bindAnimationUi, showAnimationUi } from './player.js';

const params = new URLSearchParams(location.search);
const TEST = params.has('test');
/** The engine: 'playcanvas' (default) or 'three' (three.js + Spark). */
const ENGINE = params.get('engine') === 'three' ? 'three' : 'playcanvas';
const DT = 1 / 60;
/** At most this many physics steps per frame, and no new step once a frame's steps took this
 * long (ms): on a slow machine the simulation runs slower than real time instead of stalling the
 * page. */
const MAX_STEPS = 6;
const FRAME_PHYSICS_MS = 12;
/** Soft-body options from the URL: ?physics=surface (the anchor mesh itself, within the budget)
 * or lattice (default); ?budget=N physics vertices. */
/** @type {import('./physics.js').SoftBodyOptions} */
const PHYSICS = {
    kind: params.get('physics') === 'surface' ? 'surface' : 'lattice',
    budget: Number(params.get('budget')) > 0 ? Number(params.get('budget')) : DEFAULT_BUDGET,
};

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

/** @type {import('./engine-playcanvas.js').Engine|null} */ let engine = null;
/** @type {PhysicsWorld|null} */ let world = null;
/** @type {DemoAsset|null} */ let current = null;
/** @type {OrbitCamera|null} */ let orbit = null;
/** @type {import('./gputimer.js').RemapTimer|null} */ let timer = null;
/** @type {Grabber|null} */ let grabber = null;
let paused = TEST;
let dirty = true;
let accumulator = 0;
let stepMs = 0;
const sliders = new SliderDrive({ cap: CAP });
/** @type {Shake|null} */
let shake = null;
/** the camera follows the body while it falls and rolls (after drop) */
let follow = false;
let backend = '';
let software = false;
let assetLabel = 'no asset';

const state = { axis: /** @type {0|1|2} */ (1), stretch: 1, twist: 0 };

/** What the page saw since the last `monitor()` call. */
const watch = new FrameWatch();
/** The asset's own animations (player.js). */
const player = new AnimationPlayer();
const animUi = () => ({
    row: $('anim-row'), select: /** @type {HTMLSelectElement} */ ($('anim')),
    play: /** @type {HTMLButtonElement} */ ($('anim-play')), time: input('anim-time'), label: $('anim-val'),
});

/** Show an error (an AnchorError as a refusal) on the page. @param {unknown} err */
const showError = (err) => showErrorIn($('error'), err);
const hideError = () => hideErrorIn($('error'));

/** The soft bodies of the current asset. */
const softs = () => (current ? current.bodies.map((b) => b.soft) : []);

/** Put the slider elements (and labels) at the given values. @param {number} stretch @param {number} twist */
function showSliders(stretch, twist) {
    state.stretch = stretch;
    state.twist = twist;
    input('stretch').value = String(stretch);
    input('twist').value = String(twist);
    updateLabels();
}

/** Bring every soft body back to rest, free all pins, reset the sliders. */
function resetAll() {
    shake?.stop();
    shake = null;
    grabber?.release();
    follow = false;
    sliders.release();
    showSliders(1, 0);
    current?.reset();
    if (current && orbit && current.bodies.length) {
        const c = (current.isScene ? current.sceneRestBounds() : current.restBounds()).center;
        orbit.target.set(c[0], c[1], c[2]);
        orbit.apply();
    }
    dirty = true;
}

function updateLabels() {
    $('stretch-val').textContent = `${state.stretch.toFixed(2)}×`;
    $('twist-val').textContent = `${Math.round(state.twist)}°`;
}

/** The sliders moved: hold both end caps and move them towards the sliders' pose. */
function holdSliders() {
    if (!current) return;
    shake?.stop();
    shake = null;
    grabber?.release();
    sliders.set(state.axis, state.stretch, state.twist);
}

/** Let go of everything held (sliders, shake, drag); the sliders go back to rest. */
function releaseAll() {
    shake?.stop();
    shake = null;
    grabber?.release();
    sliders.release();
    for (const s of softs()) s.setPins(null);
    showSliders(1, 0);
}

function startShake() {
    if (!current) return;
    resetAll();
    shake = new Shake(softs(), state.axis);
}

/**
 * Drop: the soft bodies (and, in a physics scene, the dynamic rigid bodies) are lifted by half
 * the height of what they make up and fall onto the ground.
 * @param {boolean} [run] start the physics (default); false leaves it paused (scripted steps)
 */
function drop(run = true) {
    if (!current || !world) return;
    resetAll();
    follow = !current.drop();
    dirty = true;
    if (run) {
        paused = false;
        $('pause').textContent = 'pause';
    }
}

/** One fixed physics step of the current asset, with whatever holds it. */
function physicsStep() {
    if (!current) return;
    sliders.step(DT, softs());
    if (shake && !shake.step(DT)) shake = null;
    current.step(DT);
    watch.steps++;
}

/** Place the camera and the ground for the current asset. */
function frameAsset() {
    if (!current || !orbit || !world) return;
    const scene = current.isScene;
    const rb = scene ? current.sceneRestBounds()
        : current.bodies.length ? current.restBounds() : { center: [0, 0, 0], size: [1, 1, 1], min: [-0.5, -0.5, -0.5] };
    const size = Math.max(...rb.size) || 1;
    state.axis = /** @type {0|1|2} */ (rb.size.indexOf(Math.max(...rb.size)));
    current.placeGround(world, engine?.ground ?? null, rb);
    if (TEST) {
        orbit.yaw = 0;
        orbit.pitch = scene ? -20 : 0;
        orbit.frame(rb.center, (scene ? 1.5 : 1.9) * size);
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
    if (!engine || !world) throw new Error('the demo is not started');
    hideError();
    const splatFile = /^(.*)\.(ply|splat|ksplat|spz|sog|json)$/i.exec(name);
    if (splatFile) {
        const err = new Error(`${name} holds splats, not an anchored asset: convert it first with `
            + `gsverse-convert ${name} ${splatFile[1]}.glb (add --mesh MESH.obj to anchor the splats to your own mesh), then open the .glb`);
        showError(err);
        throw err;
    }
    $('asset').textContent = `loading ${name}…`;
    let next;
    try {
        next = await DemoAsset.load(engine, world, source, name, PHYSICS);
    } catch (err) {
        $('asset').textContent = assetLabel;
        showError(err);
        throw err;
    }
    timer?.clear();
    grabber?.release();
    shake?.stop();
    shake = null;
    current?.destroy();
    current = next;
    player.setAnimations(current.animations);
    showAnimationUi(player, animUi());
    resetAll();
    frameAsset();
    const c = current.counts();
    const meshes = current.bodies.map((b) => `anchor mesh: ${b.soft.anchorCount} vertices, ${b.splat.prim.anchorMesh.indices.length / 3} faces; `
        + `physics: ${physicsLabel(b.soft)}`);
    assetLabel = `${name}: ${c.anchored} anchored splats${c.plain ? `, ${c.plain} plain` : ''}`;
    $('asset').textContent = assetLabel;
    $('asset').title = meshes.join('\n');
    if (current.bodies.length === 0 && current.rigids.length === 0) showError(new Error(`${name}: no anchored splat primitive (plain splats are shown; nothing to deform)`));
    if (current.isScene && !TEST) drop();       // the objects of a physics scene fall when it opens
    dirty = true;
    await frames(3);
    return info();
}

function info() {
    return {
        asset: current?.name ?? null,
        splats: current?.counts() ?? null,
        bodies: current?.bodies.map((b) => ({
            vertices: b.soft.anchorCount, faces: b.splat.prim.anchorMesh.indices.length / 3,
            physics: b.soft.kind, physicsVertices: b.soft.simCount, grid: b.soft.physics.grid?.cells ?? null, why: b.soft.physics.reason,
            guardTrips: b.soft.guardTrips,
        })) ?? [],
        objects: objects(),
        axis: 'xyz'[state.axis],
        engine: ENGINE,
        backend,
        software,
        gpuTimer: !!timer?.available,
        remapGpuMs: timer?.remapMs ?? null,
        workBufferGpuMs: timer?.workBufferMs ?? null,
        setVerticesCpuMs: current?.remapCpuMs() ?? null,
        physicsStepMs: stepMs,
        paused,
    };
}

/** The physics objects of a scene now (DemoAsset.describe), or null. */
const objects = () => current?.describe() ?? null;

/** The stats panel's text. */
function stats() {
    if (!current) return '';
    return statsText({ asset: current, timer, software, backend, stepMs, fps: engine?.fps() ?? 0, paused, engine: ENGINE });
}

function updateStats() {
    if (current) $('stats').textContent = stats();
}

// ---- start-up -------------------------------------------------------------------------------

async function start() {
    const canvas = /** @type {HTMLCanvasElement} */ ($('canvas'));
    if (TEST) document.body.classList.add('test');
    const { createEngine } = ENGINE === 'three' ? await import('./engine-three.js') : await import('./engine-playcanvas.js');
    engine = await createEngine(canvas, { test: TEST });
    software = engine.software;
    backend = engine.backend;
    const camera = engine.camera;

    orbit = new OrbitCamera(camera);
    timer = engine.makeTimer();
    grabber = new Grabber(canvas, camera, orbit, () => current, {
        onGrab: () => {
            shake?.stop();
            shake = null;
            sliders.release();
            showSliders(1, 0);
            paused = false;
            $('pause').textContent = 'pause';
        },
    });
    grabber.enabled = !TEST;

    const Jolt = await initJolt();
    world = new PhysicsWorld(Jolt);

    const wireColor = [0.3, 1, 0.55];
    engine.onUpdate((dt) => {
        // the extent the previous frame showed
        watch.frame(current && current.bodies.length ? current.syncedBounds().size : null);
        timer?.update(current ? current.bodies.map((b) => b.splat) : []);
        if (!current) return;
        if (!paused) {
            accumulator += Math.min(dt, 0.1);
            let n = 0;
            const t0 = performance.now();
            while (accumulator >= DT && n < MAX_STEPS && (n === 0 || performance.now() - t0 < FRAME_PHYSICS_MS)) {
                physicsStep();
                accumulator -= DT;
                n++;
            }
            if (n) {
                stepMs = (performance.now() - t0) / n;
                dirty = true;
            }
            if (accumulator >= DT) accumulator = 0;     // behind: slow down rather than catch up
        }
        if (player.advance(dt)) {
            dirty = true;
            showAnimationUi(player, animUi());
        }
        if (dirty) {
            // the plugin hands the deformed sort centres to the engine as fast as it sorts them
            current.sync(player.pose());
            dirty = false;
        }
        if (follow && !grabber?.grab && orbit && current.bodies.length) {
            const c = current.syncedBounds().center, t = orbit.target, k = Math.min(1, 3 * dt);
            t.set(t.x + k * (c[0] - t.x), t.y + k * (c[1] - t.y), t.z + k * (c[2] - t.z));
            orbit.apply();
        }
        if (input('wire').checked) current.drawWireframe(wireColor);
    });
    setInterval(updateStats, 250);
    engine.onSorted(() => { watch.sorts++; });   // the engine's sorts (deformed poses and camera moves)
    engine.start();
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
    $('release').addEventListener('click', releaseAll);
    $('shake').addEventListener('click', () => { paused = false; startShake(); });
    $('drop-btn').addEventListener('click', drop);
    $('reset').addEventListener('click', resetAll);
    $('pause').addEventListener('click', () => {
        paused = !paused;
        $('pause').textContent = paused ? 'resume' : 'pause';
    });
    $('error').addEventListener('click', hideError);
    for (const [id, file] of [['open-capsule', 'capsule.glb'], ['open-capsule-spz', 'capsule-spz.glb'], ['open-scene', 'scene.glb']]) {
        $(id).addEventListener('click', () => { open(`/${file}`, file).catch(() => {}); });
    }
    bindAnimationUi(player, animUi(), () => { dirty = true; });
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
    shake?.stop();
    shake = null;
    grabber?.release();
    sliders.release();
    for (const b of current.bodies) fn(b);
    current.sync(player.pose());
    dirty = false;
    await frames(4);
    await new Promise((r) => setTimeout(r, 100));
    await frames(2);
    return api.extent();
}

/**
 * Set a slider's value and fire its input event, as a person moving it does.
 * @param {'stretch'|'twist'} id @param {number} value
 */
async function moveSlider(id, value) {
    await ready;
    const el = input(id);
    el.value = String(value);
    el.dispatchEvent(new Event('input', { bubbles: true }));
    return { stretch: state.stretch, twist: state.twist };
}

const api = {
    ready,
    /**
     * Stretch every anchor mesh by `factor` along a world axis (its end caps pinned and moved
     * apart, the rest settled by the solver).
     * @param {string|number} axis @param {number} factor
     */
    pull: async (axis, factor) => {
        const size = await scripted((b) => b.soft.pull(axisIndex(axis), factor, { cap: CAP }));
        if (axisIndex(axis) === state.axis) {
            showSliders(factor, 0);
            sliders.snap(state.axis, factor, 0);
        }
        return size;
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
    /**
     * Run the physics `steps` fixed steps of 1/60 s now (deterministic: no wall clock; the
     * physics is paused afterwards), hand the result to the splats, and return the scene's
     * objects (see `objects`).
     * @param {number} steps
     */
    simulate: async (steps) => {
        await ready;
        if (!current) throw new Error('no asset loaded');
        paused = true;
        $('pause').textContent = 'resume';
        for (let i = 0; i < steps; i++) physicsStep();
        current.sync(player.pose());
        dirty = false;
        await frames(2);
        return objects();
    },
    /** The physics objects of a scene now (null for an asset without physics records). */
    objects,
    /**
     * Where world points land on the canvas (CSS pixels, y down).
     * @param {number[][]} points
     */
    toScreen: (points) => points.map((p) => /** @type {import('./engine-playcanvas.js').Engine} */ (engine).camera.toScreen(p)),
    /** Current world-space size [x, y, z] of the anchor meshes. */
    extent: () => (current && current.bodies.length ? current.bounds().size : null),
    /** Pause (true) or resume (false) the physics. @param {boolean} [on] */
    pause: (on = true) => { paused = !!on; $('pause').textContent = paused ? 'resume' : 'pause'; return paused; },
    /** Open an asset by URL or bytes. @param {string|Uint8Array} source @param {string} [name] */
    load: (source, name) => open(source, name || (typeof source === 'string' ? source.split('/').pop() || 'asset.glb' : 'asset.glb')),
    /** Drop (see drop); `run: false` leaves the physics paused. @param {boolean} [run] */
    drop: (run = true) => drop(run !== false),
    shake: () => { paused = false; startShake(); },
    /**
     * Move the stretch slider to `value` the way a person does (the slider's input event): the
     * physics runs, the caps move towards the new pose at the bounded rate.
     * @param {number} value
     */
    stretchSlider: (value) => moveSlider('stretch', value),
    /** Move the twist slider to `deg` (see stretchSlider). @param {number} deg */
    twistSlider: (deg) => moveSlider('twist', deg),
    /** Press "let go". */
    release: () => { $('release').click(); return true; },
    /**
     * Grab the high end of the body (along its long axis) and pull it outwards by `pixels` on
     * screen within `frames` frames (fast: a few frames), hold it for `hold` frames, let go.
     * @param {{pixels?: number, frames?: number, hold?: number, moveWhole?: boolean}} [options]
     * @returns {Promise<{grabbed: boolean, from: number[], to: number[]}>}
     */
    drag: async (options = {}) => {
        await ready;
        if (!current || !grabber || !current.bodies.length) throw new Error('no asset loaded');
        const { from: s0, to } = grabber.farEnd(current.bodies[0].soft, state.axis, options.pixels ?? 300);
        const n = Math.max(1, options.frames ?? 3);
        paused = false;
        const grabbed = grabber.grabAt(s0[0], s0[1], !!options.moveWhole);
        if (grabbed) {
            for (let f = 1; f <= n; f++) {
                grabber.dragTo(s0[0] + (to[0] - s0[0]) * f / n, s0[1] + (to[1] - s0[1]) * f / n);
                await frames(1);
            }
            await frames(options.hold ?? 60);
            grabber.release();
        }
        return { grabbed, from: s0, to };
    },
    /**
     * What the page saw since the last call (or load): rendered frames, physics steps, refreshes
     * of the splats' sort centres, the longest frame interval (ms) and frames over 250 ms apart,
     * the anchor meshes' smallest and largest world extent per axis and the latest one, their
     * rest extent, the guard's trips.
     * @param {boolean} [reset] start a new record (default true)
     */
    monitor: (reset = true) => ({
        ...watch.take(reset),
        rest: current && current.bodies.length ? current.restBounds().size : null,
        guardTrips: current?.guardTrips() ?? 0, stepMs, paused,
    }),
    /**
     * Run the remap of the current asset alone once (the plugin's RemapProbe) and wait for it
     * (its results read back): wall-clock ms, which on a software rasterizer is the CPU's
     * emulation, not GPU time.
     */
    remapOnce: async () => (timer ? timer.fencedRemapMs(current ? current.bodies.map((b) => b.splat) : []) : null),
    /**
     * The asset's own animations: choose one (`chosen`: its position in the list, -1 the rest
     * pose), set its time (s) and whether it plays; returns the player's state (the list, the
     * chosen animation, time, duration, playing). Without arguments, only the state.
     * @param {{chosen?: number, time?: number, playing?: boolean}} [set]
     */
    animation: async (set = {}) => {
        await ready;
        if (set.chosen !== undefined) player.choose(set.chosen);
        if (set.time !== undefined) player.seek(set.time);
        if (set.playing !== undefined) player.playing = !!set.playing && !!player.current;
        showAnimationUi(player, animUi());
        dirty = true;
        if (set.chosen !== undefined || set.time !== undefined) await frames(2);
        return player.state();
    },
    /** The stats panel's text. */
    stats,
    info,
    frames,
    /**
     * True when the picture shows the current state: no change waits for the next frame and no
     * body waits for the engine to sort its current pose (the plugin's sortPending).
     */
    settled: () => !dirty && !!engine?.idle() && (!current || current.bodies.every((b) => !b.splat.sortPending)),
    /** The error shown on the page, or null. */
    error: () => ($('error').classList.contains('show') ? { text: $('error').textContent, code: $('error').dataset.code || null } : null),
};
/** @type {any} */ (window).gsverseDemo = api;

start().then(resolveReady, (err) => {
    if (!$('error').classList.contains('show')) showError(err);
    rejectReady(err);
});
