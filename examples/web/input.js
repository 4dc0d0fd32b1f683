// Mouse and touch input of the demo: an orbit camera and grab-and-pull of the soft bodies.
//
// Left button on the object: grab the nearest physics vertex (and its neighbourhood) and pull it
// in the plane facing the camera; the opposite end of the body is held where it is, so the pull
// stretches it, up to a limit (controls.js, Drag); hold Shift to drag the whole body instead.
// Left button elsewhere, or right or middle button: orbit. Wheel: zoom.

import * as pc from 'playcanvas';
import { Drag } from './controls.js';

export class OrbitCamera {
    /** @param {pc.Entity} camera */
    constructor(camera) {
        this.camera = camera;
        this.target = new pc.Vec3();
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
        const fov = (this.camera.camera?.fov ?? 45) * Math.PI / 180;
        this.distance = 0.5 * size / Math.tan(0.5 * fov);
        this.apply();
    }

    apply() {
        const p = this.pitch * Math.PI / 180, y = this.yaw * Math.PI / 180;
        const d = this.distance;
        this.camera.setPosition(
            this.target.x + d * Math.cos(p) * Math.sin(y),
            this.target.y - d * Math.sin(p),
            this.target.z + d * Math.cos(p) * Math.cos(y));
        this.camera.lookAt(this.target);
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
     * @param {pc.Entity} camera
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
        /** @type {null | {drag: Drag, origin: pc.Vec3, normal: pc.Vec3}} */
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
        const cam = /** @type {pc.CameraComponent} */ (this.camera.camera);
        const v = new pc.Vec3(), s = new pc.Vec3();
        const fwd = this.camera.forward, eye = this.camera.getPosition();
        let best = null, bestD = 40 * 40, bestZ = Infinity;
        for (const b of asset.bodies) {
            const p = b.soft.positions();
            for (let i = 0; i < b.soft.count; i++) {
                v.set(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
                const z = (v.x - eye.x) * fwd.x + (v.y - eye.y) * fwd.y + (v.z - eye.z) * fwd.z;
                if (z <= 0) continue;
                cam.worldToScreen(v, s);
                const d = (s.x - x) ** 2 + (s.y - y) ** 2;
                // prefer the front-most of the vertices under the cursor
                if (d < bestD - 64 || (d < bestD + 64 && z < bestZ)) {
                    best = { soft: b.soft, index: i, positions: p };
                    bestD = Math.min(d, bestD);
                    bestZ = z;
                }
            }
        }
        return best;
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
        const { soft, index, positions: p } = hit;
        const drag = new Drag(soft, index, { moveWhole });
        const origin = new pc.Vec3(p[3 * index], p[3 * index + 1], p[3 * index + 2]);
        this.grab = { drag, origin, normal: this.camera.forward.clone() };
        return true;
    }

    /**
     * Pull the grabbed point to a screen point (pixels), in the plane facing the camera.
     * @param {number} x @param {number} y
     */
    dragTo(x, y) {
        const g = this.grab;
        if (!g) return;
        const cam = /** @type {pc.CameraComponent} */ (this.camera.camera);
        const a = cam.screenToWorld(x, y, cam.nearClip);
        const b = cam.screenToWorld(x, y, cam.farClip);
        const dir = b.clone().sub(a);
        const denom = dir.dot(g.normal);
        if (Math.abs(denom) < 1e-9) return;
        const t = g.origin.clone().sub(a).dot(g.normal) / denom;
        const hit = a.add(dir.mulScalar(t));
        const d = hit.sub(g.origin);
        g.drag.move([d.x, d.y, d.z]);
    }

    /** Let go of the grabbed body. */
    release() {
        if (this.grab) {
            this.grab.drag.release();
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
        this.dragTo(e.offsetX, e.offsetY);
    }

    /** @param {PointerEvent} e */
    up(e) {
        if (this.canvas.hasPointerCapture(e.pointerId)) this.canvas.releasePointerCapture(e.pointerId);
        this.orbiting = null;
        this.release();
    }
}
