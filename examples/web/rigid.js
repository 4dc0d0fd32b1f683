// Rigid physics objects of a scene (the file's KHR_physics_rigid_bodies records, read by the
// plugin's readPhysics): each a Jolt body in the demo's PhysicsWorld, beside the soft bodies.
//
//   rigid     -> a dynamic body, a ConvexHullShape from the collider hull (a kinematic one that
//                nothing moves when its mass is 0, infinite in the draft);
//   kinematic -> a kinematic body (it stays: the demo plays no node animation);
//   static    -> a static body.
// The hull is in the splat node's local space; the body's shape is the hull scaled by the node's
// global scale, its position and rotation the node's. The body drives the splat node's world
// transform, so the splats move rigidly with it and need no remap.
//
// A grabbed rigid body (RigidDrag) is pulled towards the pointer: every step its velocity is set
// so that the grabbed point reaches the pointer's point within a few steps, and on release it
// keeps the pointer's velocity over its last moves (a throw). That velocity is measured on the
// pointer's own clock (the moves' times), not in physics steps: on a slow machine a frame runs
// fewer steps than its time, and a pointer that moved fast must still throw fast.
//
// Like physics.js, the module takes its Jolt module from the PhysicsWorld and runs in the browser
// and in Node alike.

import { LAYER_MOVING, LAYER_STATIC, bounds } from './physics.js';

/** How many steps a grabbed point takes to reach the pointer (1: at once; more: softer). */
const GRAB_STEPS = 4;
/** The pointer's moves of this last stretch of time (ms) make the throw's velocity; a pointer
 * that has not moved for 1.5 times that long throws nothing (it only lets go). */
const THROW_WINDOW_MS = 200;
/** The fastest a grabbed or thrown body moves, in scene sizes per second (the world's unit). */
const MAX_SPEED = 6;
/** Angular damping of a grabbed body per step (it swings, but does not spin up). */
const GRAB_SPIN_DAMPING = 0.8;

/**
 * Split a column-major affine 4x4 into translation, rotation (unit quaternion x, y, z, w) and
 * scale (column lengths; a mirrored matrix is not a rotation and is refused).
 * @param {ArrayLike<number>} m
 */
export function decomposeAffine(m) {
    const s = [0, 1, 2].map((c) => Math.hypot(m[4 * c], m[4 * c + 1], m[4 * c + 2]));
    if (s.some((v) => !(v > 0))) throw new Error('a physics object node has a zero scale');
    const r = [0, 1, 2].map((c) => [m[4 * c] / s[c], m[4 * c + 1] / s[c], m[4 * c + 2] / s[c]]);   // columns
    const det = r[0][0] * (r[1][1] * r[2][2] - r[2][1] * r[1][2]) - r[1][0] * (r[0][1] * r[2][2] - r[2][1] * r[0][2])
        + r[2][0] * (r[0][1] * r[1][2] - r[1][1] * r[0][2]);
    if (det < 0) throw new Error('a physics object node is mirrored (negative scale): a rigid body cannot follow it');
    // rotation matrix R[row][col] = r[col][row] -> quaternion (Shepperd)
    const R = (/** @type {number} */ i, /** @type {number} */ j) => r[j][i];
    const tr = R(0, 0) + R(1, 1) + R(2, 2);
    let x, y, z, w;
    if (tr > 0) {
        const k = 0.5 / Math.sqrt(tr + 1);
        w = 0.25 / k; x = (R(2, 1) - R(1, 2)) * k; y = (R(0, 2) - R(2, 0)) * k; z = (R(1, 0) - R(0, 1)) * k;
    } else if (R(0, 0) > R(1, 1) && R(0, 0) > R(2, 2)) {
        const k = 2 * Math.sqrt(1 + R(0, 0) - R(1, 1) - R(2, 2));
        w = (R(2, 1) - R(1, 2)) / k; x = 0.25 * k; y = (R(0, 1) + R(1, 0)) / k; z = (R(0, 2) + R(2, 0)) / k;
    } else if (R(1, 1) > R(2, 2)) {
        const k = 2 * Math.sqrt(1 + R(1, 1) - R(0, 0) - R(2, 2));
        w = (R(0, 2) - R(2, 0)) / k; x = (R(0, 1) + R(1, 0)) / k; y = 0.25 * k; z = (R(1, 2) + R(2, 1)) / k;
    } else {
        const k = 2 * Math.sqrt(1 + R(2, 2) - R(0, 0) - R(1, 1));
        w = (R(1, 0) - R(0, 1)) / k; x = (R(0, 2) + R(2, 0)) / k; y = (R(1, 2) + R(2, 1)) / k; z = 0.25 * k;
    }
    const n = Math.hypot(x, y, z, w);
    return { translation: [m[12], m[13], m[14]], rotation: [x / n, y / n, z / n, w / n], scale: s };
}

/**
 * Rotate v by the unit quaternion q (x, y, z, w).
 * @param {number[]} q @param {number[]} v
 */
export function rotate(q, v) {
    const [x, y, z, w] = q;
    const tx = 2 * (y * v[2] - z * v[1]), ty = 2 * (z * v[0] - x * v[2]), tz = 2 * (x * v[1] - y * v[0]);
    return [v[0] + w * tx + (y * tz - z * ty), v[1] + w * ty + (z * tx - x * tz), v[2] + w * tz + (x * ty - y * tx)];
}

/** One rigid physics object of a scene: a Jolt body driving a splat node. */
export class RigidObject {
    /**
     * @param {import('./physics.js').PhysicsWorld} world
     * @param {import('@gsverse/web').PhysicsObject} object its record (kind rigid, kinematic or static)
     * @param {Float64Array|number[]} matrix the splat node's world matrix now (column-major)
     */
    constructor(world, object, matrix) {
        const Jolt = world.Jolt;
        this.world = world;
        this.object = object;
        this.kind = object.kind;
        const { translation, rotation, scale } = decomposeAffine(matrix);
        /** where the node starts (world): reset puts it back */
        this.start = { translation, rotation };
        this.scale = scale;
        const u = world.unit, o = world.origin;
        const hull = object.collider.vertices;
        /** the hull scaled by the node's scale (node space without scale, world units): grab points */
        this.points = new Float32Array(hull.length);
        for (let i = 0; i < hull.length; i++) this.points[i] = hull[i] * scale[i % 3];
        const settings = new Jolt.ConvexHullShapeSettings();
        const v = new Jolt.Vec3(0, 0, 0);
        for (let i = 0; i < hull.length; i += 3) {
            v.Set(this.points[i] * u, this.points[i + 1] * u, this.points[i + 2] * u);
            settings.mPoints.push_back(v);
        }
        Jolt.destroy(v);
        const result = settings.Create();
        if (result.HasError()) {
            const why = result.GetError().c_str();
            Jolt.destroy(settings);
            throw new Error(`${object.name}: its collider hull is not a convex hull Jolt accepts (${why})`);
        }
        const shape = result.Get();
        Jolt.destroy(settings);
        /** a rigid body of mass 0 (infinite in KHR_physics_rigid_bodies): nothing moves it */
        this.immovable = this.kind === 'rigid' && object.motion?.mass === 0;
        const motion = this.kind === 'rigid' && !this.immovable ? Jolt.EMotionType_Dynamic
            : this.kind === 'static' ? Jolt.EMotionType_Static : Jolt.EMotionType_Kinematic;
        const pos = new Jolt.RVec3((translation[0] - o[0]) * u, (translation[1] - o[1]) * u, (translation[2] - o[2]) * u);
        const rot = new Jolt.Quat(rotation[0], rotation[1], rotation[2], rotation[3]);
        const cs = new Jolt.BodyCreationSettings(shape, pos, rot, motion, this.kind === 'static' ? LAYER_STATIC : LAYER_MOVING);
        Jolt.destroy(pos);
        Jolt.destroy(rot);
        cs.mFriction = 0.6;
        cs.mRestitution = 0.1;
        cs.mLinearDamping = 0.1;
        cs.mAngularDamping = 0.2;
        cs.mMaxLinearVelocity = 4 * MAX_SPEED;
        if (this.kind === 'rigid' && !this.immovable && object.motion?.mass) {
            cs.mOverrideMassProperties = Jolt.EOverrideMassProperties_CalculateInertia;
            cs.mMassPropertiesOverride.mMass = object.motion.mass;
        }
        if (this.kind === 'rigid' && object.motion) cs.mGravityFactor = object.motion.gravityFactor;
        this.body = world.bodies.CreateBody(cs);
        Jolt.destroy(cs);
        this.id = this.body.GetID();
        world.bodies.AddBody(this.id, this.kind === 'static' ? Jolt.EActivation_DontActivate : Jolt.EActivation_Activate);
        /** @type {RigidDrag|null} the hand holding it */
        this.drag = null;
        this.setInitialVelocity();
    }

    /** The file's initial velocities (node space, rotated into world). @private */
    setInitialVelocity() {
        const m = this.object.motion;
        if (this.kind !== 'rigid' || this.immovable || !m) return;
        const u = this.world.unit;
        const lin = rotate(this.start.rotation, m.linearVelocity), ang = rotate(this.start.rotation, m.angularVelocity);
        this.setVelocity(lin.map((x) => x * u), ang);
    }

    /**
     * Set the body's velocities (simulation frame: linear in sim units per second).
     * @param {number[]} linear @param {number[]} [angular]
     */
    setVelocity(linear, angular) {
        const Jolt = this.world.Jolt;
        const v = new Jolt.Vec3(linear[0], linear[1], linear[2]);
        this.world.bodies.SetLinearVelocity(this.id, v);
        if (angular) {
            v.Set(angular[0], angular[1], angular[2]);
            this.world.bodies.SetAngularVelocity(this.id, v);
        }
        Jolt.destroy(v);
    }

    /** The body's linear velocity, world units per second. */
    velocity() {
        const v = this.world.bodies.GetLinearVelocity(this.id), k = 1 / this.world.unit;
        return [v.GetX() * k, v.GetY() * k, v.GetZ() * k];
    }

    /** The body's world position (the node's origin) and rotation (x, y, z, w). */
    transform() {
        const p = this.world.bodies.GetPosition(this.id), q = this.world.bodies.GetRotation(this.id);
        const o = this.world.origin, k = 1 / this.world.unit;
        return {
            translation: [p.GetX() * k + o[0], p.GetY() * k + o[1], p.GetZ() * k + o[2]],
            rotation: [q.GetX(), q.GetY(), q.GetZ(), q.GetW()],
        };
    }

    /**
     * The hull's points in world space now (3H), or one of them.
     * @param {Float32Array} [out]
     */
    worldPoints(out = new Float32Array(this.points.length)) {
        const { translation: t, rotation: q } = this.transform();
        for (let i = 0; i < this.points.length; i += 3) {
            const p = rotate(q, [this.points[i], this.points[i + 1], this.points[i + 2]]);
            out[i] = p[0] + t[0]; out[i + 1] = p[1] + t[1]; out[i + 2] = p[2] + t[2];
        }
        return out;
    }

    /** World bounds of the hull now. */
    bounds() {
        return bounds(this.worldPoints());
    }

    /** Before a world step: a held body is moved towards the hand. @param {number} dt */
    prepare(dt) {
        this.drag?.step(dt);
    }

    /**
     * Back where the file puts it (moved by `offset`, world), at rest (then the file's initial
     * velocity).
     * @param {number[]} [offset]
     */
    reset(offset = [0, 0, 0]) {
        this.drag = null;
        const Jolt = this.world.Jolt, o = this.world.origin, u = this.world.unit;
        const t = this.start.translation.map((v, k) => v + offset[k]), r = this.start.rotation;
        const pos = new Jolt.RVec3((t[0] - o[0]) * u, (t[1] - o[1]) * u, (t[2] - o[2]) * u);
        const rot = new Jolt.Quat(r[0], r[1], r[2], r[3]);
        this.world.bodies.SetPositionAndRotation(this.id, pos, rot, this.kind === 'static' ? Jolt.EActivation_DontActivate : Jolt.EActivation_Activate);
        Jolt.destroy(pos);
        Jolt.destroy(rot);
        if (this.kind !== 'static') this.setVelocity([0, 0, 0], [0, 0, 0]);
        this.setInitialVelocity();
    }

    /** Remove the body from the world. */
    destroy() {
        this.world.bodies.RemoveBody(this.id);
        this.world.bodies.DestroyBody(this.id);
    }
}

/**
 * A hand holding a dynamic rigid body at one point: the point follows the hand's target
 * (world), and letting go leaves the body with the hand's recent velocity.
 */
export class RigidDrag {
    /**
     * @param {RigidObject} rigid
     * @param {number[]} grabbed the grabbed point, world
     * @param {() => number} [clock] the pointer's clock (ms; default performance.now)
     */
    constructor(rigid, grabbed, clock = () => performance.now()) {
        this.rigid = rigid;
        const { translation: t, rotation: q } = rigid.transform();
        const inv = [-q[0], -q[1], -q[2], q[3]];
        /** the grabbed point in the body's frame (world units, unscaled node space) */
        this.local = rotate(inv, [grabbed[0] - t[0], grabbed[1] - t[1], grabbed[2] - t[2]]);
        this.origin = grabbed.slice();
        this.target = grabbed.slice();
        this.clock = clock;
        /** @type {{t: number, target: number[]}[]} the last moves, for the throw velocity */
        this.trail = [{ t: clock(), target: grabbed.slice() }];
        this.released = false;
        if (rigid.kind === 'rigid' && !rigid.immovable) rigid.drag = this;
    }

    /**
     * Move the hand to `origin + d` (world), at time `t` of the pointer's clock (the pointer
     * event's timeStamp: events a busy page handles together keep their own times).
     * @param {number[]} d @param {number} [t]
     */
    move(d, t = this.clock()) {
        this.target = [this.origin[0] + d[0], this.origin[1] + d[1], this.origin[2] + d[2]];
        this.trail.push({ t, target: this.target.slice() });
        if (this.trail.length > 64) this.trail.shift();
    }

    /** Where the grabbed point is now (world). */
    point() {
        const { translation: t, rotation: q } = this.rigid.transform();
        const p = rotate(q, this.local);
        return [p[0] + t[0], p[1] + t[1], p[2] + t[2]];
    }

    /**
     * The hand's velocity at `now` (world units per second): over its moves of the last
     * THROW_WINDOW_MS before its last move, or over its last two moves where the page handles
     * them further apart (a busy page); zero when it has not moved for longer than that.
     * @param {number} [now]
     */
    handVelocity(now = this.clock()) {
        const tr = this.trail, n = tr.length;
        if (n < 2) return [0, 0, 0];
        const last = tr[n - 1], window = Math.max(THROW_WINDOW_MS, last.t - tr[n - 2].t);
        if (now - last.t > 1.5 * window) return [0, 0, 0];
        let first = n - 2;
        while (first > 0 && tr[first - 1].t >= last.t - window) first--;
        const span = (last.t - tr[first].t) / 1000;
        if (!(span > 0)) return [0, 0, 0];
        return [0, 1, 2].map((k) => (last.target[k] - tr[first].target[k]) / span);
    }

    /** One step held: a velocity that takes the grabbed point to the hand. @param {number} dt */
    step(dt) {
        if (this.released) return;
        const p = this.point(), u = this.rigid.world.unit;
        const v = [0, 1, 2].map((k) => (this.target[k] - p[k]) / (GRAB_STEPS * dt));
        const speed = Math.hypot(...v), cap = MAX_SPEED / u;
        const f = speed > cap ? cap / speed : 1;
        const w = this.rigid.world.bodies.GetAngularVelocity(this.rigid.id);
        this.rigid.setVelocity(v.map((x) => x * f * u), [w.GetX() * GRAB_SPIN_DAMPING, w.GetY() * GRAB_SPIN_DAMPING, w.GetZ() * GRAB_SPIN_DAMPING]);
        this.rigid.world.bodies.ActivateBody(this.rigid.id);
    }

    /**
     * Let go at time `t` (the pointer's clock): the body keeps the hand's velocity over its last
     * moves (a throw).
     * @param {number} [t]
     */
    release(t = this.clock()) {
        if (this.released) return;
        this.released = true;
        if (this.rigid.drag !== this) return;
        this.rigid.drag = null;
        const v = this.handVelocity(t), u = this.rigid.world.unit;
        const speed = Math.hypot(...v), cap = MAX_SPEED / u;
        const f = speed > cap ? cap / speed : 1;
        this.rigid.setVelocity(v.map((x) => x * f * u));
        this.rigid.world.bodies.ActivateBody(this.rigid.id);
    }
}
