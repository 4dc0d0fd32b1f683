// What the page reports: the stats panel's text (each figure with what it measures), the
// per-frame record behind `gsverseDemo.monitor` (frames, physics steps, sort refreshes and the
// anchor meshes' extent), which the stability test reads, and the error box.

/** @typedef {import('./scene.js').DemoAsset} DemoAsset */
/** @typedef {import('./gputimer.js').RemapTimer} RemapTimer */
/** @typedef {import('./physics.js').SoftBodyMesh} SoftBodyMesh */

/** A frame is "slow" when it comes this long after the previous one (ms). */
const SLOW_FRAME_MS = 250;

/** What the page saw since the last `take`: frames, steps, sort refreshes, the anchor meshes' extent. */
export class FrameWatch {
    constructor() {
        this.lastFrame = 0;
        /** @type {number[]|null} the latest extent */
        this.last = null;
        this.clear();
    }

    /** Start a new record. */
    clear() {
        this.frames = 0;
        this.steps = 0;
        this.sorts = 0;
        this.slowFrames = 0;
        this.maxFrameMs = 0;
        this.min = [Infinity, Infinity, Infinity];
        this.max = [0, 0, 0];
    }

    /**
     * A frame began: its interval, and the anchor meshes' extent as the previous frame showed it.
     * @param {number[]|null} size
     */
    frame(size) {
        const now = performance.now();
        if (this.lastFrame) {
            const dt = now - this.lastFrame;
            this.maxFrameMs = Math.max(this.maxFrameMs, dt);
            if (dt > SLOW_FRAME_MS) this.slowFrames++;
        }
        this.lastFrame = now;
        this.frames++;
        if (!size) return;
        this.last = size;
        for (let k = 0; k < 3; k++) {
            this.min[k] = Math.min(this.min[k], size[k]);
            this.max[k] = Math.max(this.max[k], size[k]);
        }
    }

    /** The record so far; `reset` starts a new one. @param {boolean} reset */
    take(reset) {
        const out = {
            frames: this.frames, steps: this.steps, sorts: this.sorts, maxFrameMs: this.maxFrameMs,
            slowFrames: this.slowFrames, min: this.min.slice(), max: this.max.slice(), last: this.last,
        };
        if (reset) this.clear();
        return out;
    }
}

/** @param {SoftBodyMesh} soft */
export function physicsLabel(soft) {
    const g = soft.physics.grid;
    return soft.kind === 'lattice'
        ? `lattice of ${soft.count} nodes (${g ? g.cells.join('×') : '?'} cells)`
        : `the anchor mesh itself, ${soft.count} welded vertices${soft.closed ? '' : ', open'}`;
}

/**
 * The stats panel: what each figure measures is said next to it.
 * @param {{asset: DemoAsset, timer: RemapTimer|null, software: boolean, backend: string,
 *          stepMs: number, fps: number, paused: boolean, engine?: string}} s  `engine` 'three':
 *          no remap timer on that engine (gputimer.js reads PlayCanvas's passes)
 */
export function statsText(s) {
    const { asset, timer, software } = s;
    const cpu = asset.remapCpuMs();
    const splats = asset.counts().anchored;
    const lines = [];
    if (timer?.available) {
        const unit = software ? 'ms' : 'ms GPU';
        lines.push(timer.remapMs !== null
            ? `remap: ${timer.remapMs.toFixed(3)} ${unit} (the remap alone over ${timer.remapSplats.toLocaleString('en')} splats, timer query`
                + `${software ? '; on this software rasterizer the timer counts CPU emulation, not GPU time' : ''})`
            : timer.probeError ? `remap: not timed (${timer.probeError})` : 'remap: waiting for a GPU timing');
        if (timer.workBufferMs !== null) lines.push(`  work-buffer pass: ${timer.workBufferMs.toFixed(3)} ${unit} (engine copy of every splat + remap)`);
    } else if (s.engine === 'three') {
        lines.push(`remap: GPU time n/a (not measurable here: the remap timer is PlayCanvas's); `
            + `${splats.toLocaleString('en')} splats remapped on the GPU each frame they move`);
    } else {
        lines.push(`remap: GPU time not measurable here (no GPU timer queries${software ? ' on the software rasterizer' : ''}); `
            + `${splats.toLocaleString('en')} splats remapped on the GPU each frame they move`);
    }
    lines.push(s.engine === 'three'
        ? 'setVertices: not timed on three.js (a texture upload; Spark regenerates and sorts the splats in its own update)'
        : `setVertices: ${cpu.total.toFixed(2)} ms CPU (of it deformed sort centres ${cpu.sort.toFixed(2)} ms)`);
    const phys = asset.bodies.map((b) => physicsLabel(b.soft)).join('; ');
    lines.push(`physics: ${s.stepMs.toFixed(2)} ms/step, ${phys}`);
    const shortBackend = software ? 'WebGL2 · software rasterizer (SwiftShader)' : s.backend;
    lines.push(`${s.fps} fps · ${shortBackend}${s.paused ? ' · paused' : ''}`);
    return lines.join('\n');
}

/**
 * Show an error in `box`: a refused asset (AnchorError) with its code, anything else as an error.
 * @param {HTMLElement} box @param {unknown} err
 */
export function showErrorIn(box, err) {
    const e = /** @type {any} */ (err);
    box.textContent = e?.name === 'AnchorError' ? `Refused: ${e.message} [${e.code}]` : `Error: ${e?.message ?? String(err)}`;
    box.dataset.code = e?.code ?? '';
    box.classList.add('show');
    console.error(err);
}

/** Hide the error box. @param {HTMLElement} box */
export function hideErrorIn(box) {
    box.classList.remove('show');
    box.textContent = '';
}
