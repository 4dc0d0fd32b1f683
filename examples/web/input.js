// Mouse and touch input of the demo: an orbit camera and grab-and-pull of the soft bodies.
//
// Left button on the object: grab the nearest physics vertex (and its neighbourhood) and pull it
// in the plane facing the camera; the opposite end of the body is held where it is, so the pull
// stretches it, up to a limit (controls.js, Drag); hold Shift to drag the whole body instead.
// In a physics scene, left button on a rigid object grabs it (rigid.js, RigidDrag): it follows
// the pointer and, let go, flies off with the pointer's velocity.
// Left button elsewhere, or right or middle button: orbit. Wheel: zoom.

import * as pc from 'playcanvas';
import { Drag } from './controls.js';
import { RigidDrag } from './rigid.js';

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
        /** @type {null | {drag: Drag|RigidDrag, origin: pc.Vec3, normal: pc.Vec3}} */
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
        // a dynamic rigid body under the cursor (inside its hull's projected box), grabbed at the
        // depth of its centre, if it is in front of the soft vertex found
        for (const { rigid } of asset.rigids ?? []) {
            if (rigid.kind !== 'rigid' || rigid.immovable) continue;
            const p = rigid.worldPoints();
            let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity, cz = 0, c = [0, 0, 0];
            for (let i = 0; i < p.length; i += 3) {
                v.set(p[i], p[i + 1], p[i + 2]);
                cam.worldToScreen(v, s);
                x0 = Math.min(x0, s.x); x1 = Math.max(x1, s.x); y0 = Math.min(y0, s.y); y1 = Math.max(y1, s.y);
                for (let k = 0; k < 3; k++) c[k] += 3 * p[i + k] / p.length;
            }
            cz = (c[0] - eye.x) * fwd.x + (c[1] - eye.y) * fwd.y + (c[2] - eye.z) * fwd.z;
            if (cz <= 0 || x < x0 || x > x1 || y < y0 || y > y1 || (best && bestZ < cz)) continue;
            const a = cam.screenToWorld(x, y, cam.nearClip), b2 = cam.screenToWorld(x, y, cam.farClip);
            const dir = b2.clone().sub(a), denom = dir.dot(fwd);
            const t = (cz - a.clone().sub(eye).dot(fwd)) / denom;
            const hit = a.add(dir.mulScalar(t));
            best = { rigid, point: [hit.x, hit.y, hit.z] };
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
        const cam = /** @type {pc.CameraComponent} */ (this.camera.camera);
        const p = soft.positions(), k = axis, c = soft.bounds().center;
        let best = 0, bestScore = -Infinity;
        for (let i = 0; i < soft.count; i++) {
            const off = Math.hypot(...[0, 1, 2].filter((j) => j !== k).map((j) => p[3 * i + j] - c[j]));
            const score = p[3 * i + k] - 0.5 * off;
            if (score > bestScore) { bestScore = score; best = i; }
        }
        const s0 = cam.worldToScreen(new pc.Vec3(p[3 * best], p[3 * best + 1], p[3 * best + 2]));
        const sc = cam.worldToScreen(new pc.Vec3(c[0], c[1], c[2]));
        const dir = [s0.x - sc.x, s0.y - sc.y], len = Math.hypot(dir[0], dir[1]) || 1;
        return { from: [s0.x, s0.y], to: [s0.x + pixels * dir[0] / len, s0.y + pixels * dir[1] / len] };
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
            this.grab = { drag: new RigidDrag(hit.rigid, q), origin: new pc.Vec3(q[0], q[1], q[2]), normal: this.camera.forward.clone() };
            return true;
        }
        const { soft, index, positions: p } = hit;
        const drag = new Drag(soft, index, { moveWhole });
        const origin = new pc.Vec3(p[3 * index], p[3 * index + 1], p[3 * index + 2]);
        this.grab = { drag, origin, normal: this.camera.forward.clone() };
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
        const cam = /** @type {pc.CameraComponent} */ (this.camera.camera);
        const a = cam.screenToWorld(x, y, cam.nearClip);
        const b = cam.screenToWorld(x, y, cam.farClip);
        const dir = b.clone().sub(a);
        const denom = dir.dot(g.normal);
        if (Math.abs(denom) < 1e-9) return;
        const t = g.origin.clone().sub(a).dot(g.normal) / denom;
        const hit = a.add(dir.mulScalar(t));
        const d = hit.sub(g.origin);
        g.drag.move([d.x, d.y, d.z], time);
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
