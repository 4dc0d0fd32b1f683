// Mouse and touch input of the demo: an orbit camera and grab-and-pull of the soft bodies.
//
// Left button on the object: grab the nearest physics vertex (and its neighbourhood) and pull it
// in the plane facing the camera; the opposite end of the body is held where it is, so the pull
// stretches it, up to a limit (controls.js, Drag); hold Shift to drag the whole body instead.
// In a physics scene, left button on a rigid object grabs it (rigid.js, RigidDrag): it follows
// the pointer and, let go, flies off with the pointer's velocity.
// Left button elsewhere, or right or middle button: orbit. Wheel: zoom.
// The camera is the engine adapter's CameraRig (engine-playcanvas.js), so this is engine-free.

import { Drag } from './controls.js';
import { RigidDrag } from './rigid.js';

/** @typedef {import('./engine-playcanvas.js').CameraRig} CameraRig */

/** A point that can be set in place (the orbit's target). */
class Point {
    constructor() { this.x = 0; this.y = 0; this.z = 0; }
    /** @param {number} x @param {number} y @param {number} z */
    set(x, y, z) { this.x = x; this.y = y; this.z = z; return this; }
}

/** @param {number[]} a @param {number[]} b */
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];

export class OrbitCamera {
    /** @param {CameraRig} camera */
    constructor(camera) {
        this.camera = camera;
        this.target = new Point();
        this.yaw = 0;
        this.pitch = -10;
        this.distance = 5;
    }

    /**
     * Frame a box: look at its centre from a distance that fits `size` (world units).
     * @param {number[]} center @param {number} size
     */
    frame(center, size) {
        this.target.set(center[0], center[1], center[2]);
        const fov = (this.camera.fov ?? 45) * Math.PI / 180;
        this.distance = 0.5 * size / Math.tan(0.5 * fov);
        this.apply();
    }

    apply() {
        const p = this.pitch * Math.PI / 180, y = this.yaw * Math.PI / 180;
        const d = this.distance;
        const t = this.target;
        this.camera.place([
            t.x + d * Math.cos(p) * Math.sin(y),
            t.y - d * Math.sin(p),
            t.z + d * Math.cos(p) * Math.cos(y)], [t.x, t.y, t.z]);
    }

    /** @param {number} dx @param {number} dy  pixels */
    rotate(dx, dy) {
        this.yaw -= dx * 0.3;
        this.pitch = Math.max(-89, Math.min(89, this.pitch - dy * 0.3));
        this.apply();
    }

    /** @param {number} delta wheel delta */
    zoom(delta) {
        this.distance *= Math.exp(delta * 0.001);
        this.apply();
    }
}

/**
 * Grab-and-pull on the soft bodies of the current asset.
 */
export class Grabber {
    /**
     * @param {HTMLCanvasElement} canvas
     * @param {CameraRig} camera
     * @param {OrbitCamera} orbit
     * @param {() => import('./scene.js').DemoAsset|null} current
     * @param {{onGrab?: () => void}} [hooks]
     */
    constructor(canvas, camera, orbit, current, hooks = {}) {
        this.canvas = canvas;
        this.camera = camera;
        this.orbit = orbit;
        this.current = current;
        this.hooks = hooks;
        this.enabled = true;
        /** @type {null | {drag: Drag|RigidDrag, origin: number[], normal: number[]}} */
        this.grab = null;
        /** @type {null | {x: number, y: number}} */
        this.orbiting = null;
        canvas.addEventListener('pointerdown', (e) => this.down(e));
        canvas.addEventListener('pointermove', (e) => this.move(e));
        canvas.addEventListener('pointerup', (e) => this.up(e));
        canvas.addEventListener('pointercancel', (e) => this.up(e));
        canvas.addEventListener('contextmenu', (e) => e.preventDefault());
        canvas.addEventListener('wheel', (e) => { e.preventDefault(); orbit.zoom(e.deltaY); }, { passive: false });
    }

    /**
     * The vertex nearest to a screen point (within 40 px), over every body.
     * @param {number} x @param {number} y
     */
    pick(x, y) {
        const asset = this.current();
        if (!asset) return null;
        const cam = this.camera;
        const fwd = cam.forward(), eye = cam.eye();
        let best = null, bestD = 40 * 40, bestZ = Infinity;
        for (const b of asset.bodies) {
            const p = b.soft.positions();
            for (let i = 0; i < b.soft.count; i++) {
                const v = [p[3 * i], p[3 * i + 1], p[3 * i + 2]];
                const z = (v[0] - eye[0]) * fwd[0] + (v[1] - eye[1]) * fwd[1] + (v[2] - eye[2]) * fwd[2];
                if (z <= 0) continue;
                const s = cam.toScreen(v);
                const d = (s[0] - x) ** 2 + (s[1] - y) ** 2;
                // prefer the front-most of the vertices under the cursor
                if (d < bestD - 64 || (d < bestD + 64 && z < bestZ)) {
                    best = { soft: b.soft, index: i, positions: p };
                    bestD = Math.min(d, bestD);
                    bestZ = z;
                }
            }
        }
        // a dynamic rigid body under the cursor (inside its hull's projected box), grabbed at the
        // depth of its centre, if it is in front of the soft vertex found
        for (const { rigid } of asset.rigids ?? []) {
            if (rigid.kind !== 'rigid' || rigid.immovable) continue;
            const p = rigid.worldPoints();
            let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity, cz = 0, c = [0, 0, 0];
            for (let i = 0; i < p.length; i += 3) {
                const s = cam.toScreen([p[i], p[i + 1], p[i + 2]]);
                x0 = Math.min(x0, s[0]); x1 = Math.max(x1, s[0]); y0 = Math.min(y0, s[1]); y1 = Math.max(y1, s[1]);
                for (let k = 0; k < 3; k++) c[k] += 3 * p[i + k] / p.length;
            }
            cz = (c[0] - eye[0]) * fwd[0] + (c[1] - eye[1]) * fwd[1] + (c[2] - eye[2]) * fwd[2];
            if (cz <= 0 || x < x0 || x > x1 || y < y0 || y > y1 || (best && bestZ < cz)) continue;
            const { origin: a, dir } = cam.ray(x, y), denom = dot(dir, fwd);
            const t = (cz - dot([a[0] - eye[0], a[1] - eye[1], a[2] - eye[2]], fwd)) / denom;
            best = { rigid, point: [a[0] + t * dir[0], a[1] + t * dir[1], a[2] + t * dir[2]] };
            bestZ = cz;
        }
        return best;
    }

    /**
     * Where a scripted drag of `soft` starts and ends on screen: the vertex farthest along `axis`
     * (and nearest the axis through the centre), pulled outwards from the centre by `pixels`.
     * @param {import('./physics.js').SoftBodyMesh} soft @param {number} axis @param {number} pixels
     * @returns {{from: number[], to: number[]}}
     */
    farEnd(soft, axis, pixels) {
        const cam = this.camera;
        const p = soft.positions(), k = axis, c = soft.bounds().center;
        let best = 0, bestScore = -Infinity;
        for (let i = 0; i < soft.count; i++) {
            const off = Math.hypot(...[0, 1, 2].filter((j) => j !== k).map((j) => p[3 * i + j] - c[j]));
            const score = p[3 * i + k] - 0.5 * off;
            if (score > bestScore) { bestScore = score; best = i; }
        }
        const s0 = cam.toScreen([p[3 * best], p[3 * best + 1], p[3 * best + 2]]);
        const sc = cam.toScreen([c[0], c[1], c[2]]);
        const dir = [s0[0] - sc[0], s0[1] - sc[1]], len = Math.hypot(dir[0], dir[1]) || 1;
        return { from: [s0[0], s0[1]], to: [s0[0] + pixels * dir[0] / len, s0[1] + pixels * dir[1] / len] };
    }

    /** @param {PointerEvent} e */
    down(e) {
        this.canvas.setPointerCapture(e.pointerId);
        if (!(e.button === 0 && this.enabled && this.grabAt(e.offsetX, e.offsetY, e.shiftKey))) {
            this.orbiting = { x: e.clientX, y: e.clientY };
        }
    }

    /**
     * Grab the body under a screen point (pixels). Returns whether something was grabbed.
     * @param {number} x @param {number} y @param {boolean} [moveWhole] drag the whole body
     */
    grabAt(x, y, moveWhole = false) {
        const hit = this.pick(x, y);
        if (!hit) return false;
        this.hooks.onGrab?.();
        if ('rigid' in hit) {
            const q = hit.point;
            this.grab = { drag: new RigidDrag(hit.rigid, q), origin: [q[0], q[1], q[2]], normal: this.camera.forward() };
            return true;
        }
        const { soft, index, positions: p } = hit;
        const drag = new Drag(soft, index, { moveWhole });
        const origin = [p[3 * index], p[3 * index + 1], p[3 * index + 2]];
        this.grab = { drag, origin, normal: this.camera.forward() };
        return true;
    }

    /**
     * Pull the grabbed point to a screen point (pixels), in the plane facing the camera, at time
     * `time` (a pointer event's timeStamp; a rigid body's throw is measured on it).
     * @param {number} x @param {number} y @param {number} [time]
     */
    dragTo(x, y, time) {
        const g = this.grab;
        if (!g) return;
        const { origin: a, dir } = this.camera.ray(x, y);
        const denom = dot(dir, g.normal);
        if (Math.abs(denom) < 1e-9) return;
        const o = g.origin;
        const t = dot([o[0] - a[0], o[1] - a[1], o[2] - a[2]], g.normal) / denom;
        g.drag.move([0, 1, 2].map((k) => a[k] + t * dir[k] - o[k]), time);
    }

    /** Let go of the grabbed body (at time `t`, a pointer event's timeStamp). @param {number} [t] */
    release(t) {
        if (this.grab) {
            this.grab.drag.release(t);
            this.grab = null;
        }
    }

    /** @param {PointerEvent} e */
    move(e) {
        if (this.orbiting) {
            this.orbit.rotate(e.clientX - this.orbiting.x, e.clientY - this.orbiting.y);
            this.orbiting = { x: e.clientX, y: e.clientY };
            return;
        }
        this.dragTo(e.offsetX, e.offsetY, e.timeStamp);
    }

    /** @param {PointerEvent} e */
    up(e) {
        if (this.canvas.hasPointerCapture(e.pointerId)) this.canvas.releasePointerCapture(e.pointerId);
        this.orbiting = null;
        this.release(e.timeStamp);
    }
}
