// The hands of the demo: what the sliders, a drag and the shake button do to the soft bodies,
// with the limits that keep them stable. No rendering here, so it runs in Node as well.
//
// - SliderDrive: the stretch and twist sliders hold both end caps along the longest axis. The pose
//   they hold moves towards the sliders' values at a bounded rate (`stretchRate` per second,
//   `twistRate` degrees per second), so a slider clicked far from its value turns the caps
//   through the angles in between instead of pulling them across in a straight line (a 180-degree
//   jump would otherwise squeeze the caps through the axis).
// - Drag: pins the grabbed vertex's neighbourhood and, unless the whole body is moved, the far
//   end; the pull is clamped to `maxPull` rest diagonals from where it started.
// - Shake: holds one end, shakes it sideways, brings it back to rest and holds it still for a
//   moment before letting go, so the body does not fly off with the last swing.
// Pinned vertices move towards their targets at a bounded speed in any case (SoftBodyMesh).

import { bounds } from './physmesh.js';

/** @typedef {import('./physics.js').SoftBodyMesh} SoftBodyMesh */
/** @typedef {0|1|2} Axis */

/** Fraction of the rest extent held at each end by the sliders. */
export const CAP = 0.12;

/**
 * `value` moved towards `target` by at most `step`.
 * @param {number} value @param {number} target @param {number} step
 */
function approach(value, target, step) {
    return Math.abs(target - value) <= step ? target : value + Math.sign(target - value) * step;
}

export class SliderDrive {
    /** @param {{stretchRate?: number, twistRate?: number, cap?: number}} [options] */
    constructor(options = {}) {
        this.stretchRate = options.stretchRate ?? 1.5;
        this.twistRate = options.twistRate ?? 180;
        this.cap = options.cap ?? CAP;
        /** @type {Axis} */
        this.axis = 1;
        /** the sliders' values */
        this.target = { stretch: 1, twist: 0 };
        /** the pose held now */
        this.applied = { stretch: 1, twist: 0 };
        /** whether the caps are held */
        this.active = false;
        this._held = false;
    }

    /**
     * The sliders moved: hold the caps and move towards these values.
     * @param {Axis} axis @param {number} stretch @param {number} twist degrees
     */
    set(axis, stretch, twist) {
        if (axis !== this.axis) this._held = false;
        this.axis = axis;
        this.target = { stretch, twist };
        if (!this.active) this._held = false;
        this.active = true;
    }

    /**
     * The caps are already held at this pose (a scripted pose): hold it without moving.
     * @param {Axis} axis @param {number} stretch @param {number} twist
     */
    snap(axis, stretch, twist) {
        this.axis = axis;
        this.target = { stretch, twist };
        this.applied = { stretch, twist };
        this.active = true;
        this._held = true;
    }

    /** Let go (the bodies' pins are freed by the caller) and forget the pose. */
    release() {
        this.active = false;
        this._held = false;
        this.target = { stretch: 1, twist: 0 };
        this.applied = { stretch: 1, twist: 0 };
    }

    /** Whether the held pose has reached the sliders' values. */
    get settled() {
        return this.applied.stretch === this.target.stretch && this.applied.twist === this.target.twist;
    }

    /**
     * Before a physics step of `dt`: move the held pose towards the sliders and pin the caps of
     * every body at it.
     * @param {number} dt @param {SoftBodyMesh[]} softs
     */
    step(dt, softs) {
        if (!this.active) return;
        if (this._held && this.settled) return;
        this.applied = {
            stretch: approach(this.applied.stretch, this.target.stretch, this.stretchRate * dt),
            twist: approach(this.applied.twist, this.target.twist, this.twistRate * dt),
        };
        for (const s of softs) {
            const st = s.stretchMap(this.axis, this.applied.stretch);
            const tw = s.twistMap(this.axis, this.applied.twist, this.cap);
            s.hold(this.axis, (p) => st(tw(p)), this.cap);
        }
        this._held = true;
    }
}

/**
 * Grab-and-pull of one soft body at one of its physics vertices.
 */
export class Drag {
    /**
     * @param {SoftBodyMesh} soft
     * @param {number} index the grabbed physics vertex
     * @param {{moveWhole?: boolean, radius?: number, maxPull?: number}} [options]
     *   moveWhole: pin only the grabbed neighbourhood (the body follows) instead of also holding
     *   the far end; radius: of the neighbourhood, maxPull: largest pull (both in rest diagonals)
     */
    constructor(soft, index, options = {}) {
        this.soft = soft;
        const p = soft.positions();
        const diag = Math.hypot(...bounds(soft.rest).size) || 1;
        this.maxPull = options.moveWhole ? Infinity : (options.maxPull ?? 0.6) * diag;
        const radius = (options.radius ?? 0.15) * diag;
        const near = (/** @type {number} */ c) => {
            const out = [];
            for (let i = 0; i < soft.count; i++) {
                if (Math.hypot(p[3 * i] - p[3 * c], p[3 * i + 1] - p[3 * c + 1], p[3 * i + 2] - p[3 * c + 2]) <= radius) out.push(i);
            }
            return out;
        };
        /** the pinned vertices that follow the pointer */
        this.grab = near(index);
        /** @type {Map<number, number[]>} */
        const pins = new Map();
        for (const i of this.grab) pins.set(i, [p[3 * i], p[3 * i + 1], p[3 * i + 2]]);
        if (!options.moveWhole) {
            // hold the far end: the vertex farthest from the grabbed one, and its neighbourhood
            let far = 0, farD = -1;
            for (let i = 0; i < soft.count; i++) {
                const d = (p[3 * i] - p[3 * index]) ** 2 + (p[3 * i + 1] - p[3 * index + 1]) ** 2 + (p[3 * i + 2] - p[3 * index + 2]) ** 2;
                if (d > farD) { farD = d; far = i; }
            }
            for (const i of near(far)) if (!pins.has(i)) pins.set(i, [p[3 * i], p[3 * i + 1], p[3 * i + 2]]);
        }
        soft.setPins(pins);
        this.start = p;
        /** the grabbed vertex's position when grabbed (world) */
        this.origin = [p[3 * index], p[3 * index + 1], p[3 * index + 2]];
    }

    /**
     * Move the grabbed neighbourhood by `d` (world units, from where it was grabbed), clamped to
     * `maxPull`. Returns the offset used.
     * @param {number[]} d
     */
    move(d) {
        const len = Math.hypot(d[0], d[1], d[2]);
        const k = len > this.maxPull ? this.maxPull / len : 1;
        const o = [d[0] * k, d[1] * k, d[2] * k];
        const s = this.start;
        for (const i of this.grab) this.soft.setTarget(i, [s[3 * i] + o[0], s[3 * i + 1] + o[1], s[3 * i + 2] + o[2]]);
        return o;
    }

    release() {
        this.soft.setPins(null);
    }
}

/**
 * Hold one end of every body and shake it sideways.
 */
export class Shake {
    /**
     * @param {SoftBodyMesh[]} softs
     * @param {Axis} axis the long axis (the low end along it is held)
     * @param {{amplitude?: number, duration?: number, settle?: number, frequency?: number, cap?: number}} [options]
     *   amplitude: world units (default 0.12 of the longest rest extent); duration and settle:
     *   seconds of shaking and of holding still afterwards; frequency: Hz; cap: held fraction
     */
    constructor(softs, axis, options = {}) {
        this.softs = softs;
        this.axis = axis;
        this.side = axis === 0 ? 2 : 0;
        const size = Math.max(...softs.flatMap((s) => bounds(s.rest).size), 0);
        this.amplitude = options.amplitude ?? 0.12 * size;
        this.duration = options.duration ?? 2;
        this.settle = options.settle ?? 0.75;
        this.frequency = options.frequency ?? 3;
        this.t = 0;
        this.done = false;
        for (const s of softs) {
            /** @type {Map<number, number[]>} */
            const pins = new Map();
            for (const i of s.endCap(axis, -1, options.cap ?? 0.2)) pins.set(i, [s.rest[3 * i], s.rest[3 * i + 1], s.rest[3 * i + 2]]);
            s.setPins(pins);
        }
    }

    /**
     * Before a physics step of `dt`: move the held end; after `duration + settle`, let go.
     * @param {number} dt
     * @returns {boolean} whether it is still going
     */
    step(dt) {
        if (this.done) return false;
        this.t += dt;
        if (this.t >= this.duration + this.settle) {
            for (const s of this.softs) s.setPins(null);
            this.done = true;
            return false;
        }
        const t = Math.min(this.t, this.duration);
        const amp = this.amplitude * Math.sin(2 * Math.PI * this.frequency * t) * Math.min(1, 4 * (this.duration - t));
        for (const s of this.softs) {
            if (!s.targets) continue;
            for (let i = 0; i < s.count; i++) {
                if (Number.isNaN(s.targets[3 * i])) continue;
                const q = [s.rest[3 * i], s.rest[3 * i + 1], s.rest[3 * i + 2]];
                q[this.side] += amp;
                s.targets.set(q, 3 * i);
            }
        }
        return true;
    }

    /** Stop now and let go. */
    stop() {
        if (!this.done) for (const s of this.softs) s.setPins(null);
        this.done = true;
    }
}
