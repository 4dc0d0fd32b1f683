// The anchor mesh as a Jolt soft body (npm `jolt-physics`, the physics engine Godot 4 also uses).
//
// Each anchor mesh gets a physics mesh (physmesh.js: by default a lattice of tetrahedra around
// it, within a node budget), turned into a Jolt soft body and simulated in world space next to a
// static ground box. Each frame the anchor vertices are read back through the embedding
// (`readAnchorVertices`), so the caller can convert them to splat-local space and hand them to
// the remap; the anchor mesh itself is never changed.
//
// Manipulations are done the way a hand does them: a set of physics vertices is pinned (made
// kinematic, inverse mass 0) and driven towards target positions while the rest of the body
// follows under its constraints. Pinned vertices move towards their targets at a bounded speed
// (`pinSpeed`), never in one jump; vertex speeds are capped (`maxVelocity`), and a body that
// blows up anyway is put back to its rest shape (`guard`, counted in `guardTrips`). The scripted
// manipulations (`pose`) are deterministic: they set the pins and the free vertices to an initial
// guess, zero all velocities, switch gravity off and step the solver a fixed number of times with
// a fixed time step.
//
// The module takes the initialised Jolt module as an argument, so it runs in the browser and in
// Node alike.

import { bounds, buildPhysicsMesh, applyEmbedding } from './physmesh.js';

export { bounds, weldVertices, weldFaces, isClosed, coreVertices, buildPhysicsMesh, DEFAULT_BUDGET } from './physmesh.js';

/** Jolt object layers: static bodies (the ground) collide with moving ones (soft bodies, rigid
 * and kinematic bodies), moving ones with each other. */
export const LAYER_STATIC = 0;
export const LAYER_MOVING = 1;
/** Stability defaults, in rest diagonals of the body (per second): how fast pinned vertices move
 * towards their targets, the speed cap of every vertex, and the extent at which the guard puts a
 * body back to rest (see README, "Stability"). */
const PIN_SPEED = 1.5;
const MAX_VELOCITY = 6;
const GUARD = 3;

/** @typedef {0|1|2} Axis */

/**
 * @typedef {{mass?: number, edgeCompliance?: number, bendCompliance?: number, pressure?: number,
 *            iterations?: number, damping?: number, friction?: number, vertexRadius?: number,
 *            bendType?: number, shearCompliance?: number, spokeCompliance?: number, coreCount?: number,
 *            kind?: 'lattice'|'surface', budget?: number, latticeCompliance?: number, diagonalCompliance?: number,
 *            volumeCompliance?: number, pinSpeed?: number, maxVelocity?: number, guard?: number}} SoftBodyOptions
 *   kind, budget and the compliances of the physics mesh: see physmesh.js. pinSpeed: fastest speed
 *   of pinned vertices towards their targets, maxVelocity: of any vertex (both in rest diagonals
 *   per second); guard: extent (in rest diagonals) beyond which the body is put back to its rest
 *   shape (0: never)
 */

/**
 * Normalise an axis argument ('x' | 'y' | 'z' | 0 | 1 | 2).
 * @param {string|number} axis
 * @returns {Axis}
 */
export function axisIndex(axis) {
    const i = typeof axis === 'number' ? axis : 'xyz'.indexOf(String(axis).toLowerCase());
    if (i !== 0 && i !== 1 && i !== 2) throw new Error(`axis must be x, y, z, 0, 1 or 2 (got ${axis})`);
    return /** @type {Axis} */ (i);
}

/** A Jolt physics system with a static ground box. */
export class PhysicsWorld {
    /**
     * @param {any} Jolt the initialised jolt-physics module
     * @param {{groundY?: number}} [options]
     */
    constructor(Jolt, options = {}) {
        this.Jolt = Jolt;
        const settings = new Jolt.JoltSettings();
        const pairs = new Jolt.ObjectLayerPairFilterTable(2);
        pairs.EnableCollision(LAYER_STATIC, LAYER_MOVING);
        pairs.EnableCollision(LAYER_MOVING, LAYER_MOVING);
        const bp = new Jolt.BroadPhaseLayerInterfaceTable(2, 2);
        bp.MapObjectToBroadPhaseLayer(LAYER_STATIC, new Jolt.BroadPhaseLayer(0));
        bp.MapObjectToBroadPhaseLayer(LAYER_MOVING, new Jolt.BroadPhaseLayer(1));
        settings.mObjectLayerPairFilter = pairs;
        settings.mBroadPhaseLayerInterface = bp;
        settings.mObjectVsBroadPhaseLayerFilter = new Jolt.ObjectVsBroadPhaseLayerFilterTable(bp, 2, pairs, 2);
        this.jolt = new Jolt.JoltInterface(settings);
        Jolt.destroy(settings);
        this.system = this.jolt.GetPhysicsSystem();
        this.bodies = this.system.GetBodyInterface();
        this.system.SetGravity(new Jolt.Vec3(0, -9.81, 0));
        /** Simulation frame: sim = (world - origin) * unit (see setFrame). */
        this.origin = [0, 0, 0];
        this.unit = 1;
        this.groundY = options.groundY ?? -1;
        this.ground = null;
        this.setGround(this.groundY);
    }

    /**
     * Simulate in a frame where the asset is about one unit large, so that the constraint
     * compliances, gravity and collision margins behave the same for an asset of any size or
     * position: sim = (world - origin) * unit. Every method of this module takes and returns world
     * coordinates. Set it before creating bodies (bodies created in another frame are invalid).
     * @param {number[]} origin @param {number} unit
     */
    setFrame(origin, unit) {
        this.origin = origin.slice(0, 3);
        this.unit = unit > 0 && Number.isFinite(unit) ? unit : 1;
    }

    /**
     * Place the static ground box with its top face at `y`.
     * @param {number} y
     * @param {number} [halfWidth] half the box's width and depth
     * @param {number[]} [center] x and z of the box's centre
     */
    setGround(y, halfWidth = 50, center = [0, 0]) {
        const h = Math.max(halfWidth * this.unit, 1e-3) / this.unit;
        this.setGroundBox([center[0], y - 0.5 * h, center[1]], [h, 0.5 * h, h]);
        this.groundY = y;
    }

    /**
     * Place the static ground box: its centre, half extents along its axes and rotation
     * (x, y, z, w), all in world space (a scene's `ground` node: KHR_implicit_shapes box).
     * @param {number[]} center @param {number[]} half @param {number[]} [rotation]
     */
    setGroundBox(center, half, rotation = [0, 0, 0, 1]) {
        const Jolt = this.Jolt;
        if (this.ground) {
            this.bodies.RemoveBody(this.ground.GetID());
            this.bodies.DestroyBody(this.ground.GetID());
        }
        const u = this.unit, o = this.origin;
        const hx = Math.max(half[0] * u, 1e-3), hy = Math.max(half[1] * u, 1e-3), hz = Math.max(half[2] * u, 1e-3);
        this.groundY = center[1] + half[1];
        const shape = new Jolt.BoxShape(new Jolt.Vec3(hx, hy, hz), Math.min(0.05, 0.1 * Math.min(hx, hy, hz)), null);
        const cs = new Jolt.BodyCreationSettings(shape, new Jolt.RVec3((center[0] - o[0]) * u, (center[1] - o[1]) * u, (center[2] - o[2]) * u),
            new Jolt.Quat(rotation[0], rotation[1], rotation[2], rotation[3]),
            Jolt.EMotionType_Static, LAYER_STATIC);
        cs.mFriction = 0.8;
        this.ground = this.bodies.CreateBody(cs);
        Jolt.destroy(cs);
        this.bodies.AddBody(this.ground.GetID(), Jolt.EActivation_DontActivate);
    }

    /** @param {number} dt */
    step(dt) {
        this.jolt.Step(dt, 1);
    }

    /** Free the Jolt system (bodies first: SoftBodyMesh.destroy). */
    destroy() {
        if (this.ground) {
            this.bodies.RemoveBody(this.ground.GetID());
            this.bodies.DestroyBody(this.ground.GetID());
            this.ground = null;
        }
        this.Jolt.destroy(this.jolt);
    }
}

/**
 * The anchor mesh of one anchored primitive as a soft body, in world space: a Jolt soft body on
 * its physics mesh (physmesh.js), and the embedding that moves the anchor vertices with it.
 */
export class SoftBodyMesh {
    /**
     * @param {PhysicsWorld} world
     * @param {{vertices: Float32Array, indices: Uint32Array}} mesh world-space anchor vertices (3V) and faces (3F)
     * @param {SoftBodyOptions} [options]
     */
    constructor(world, mesh, options = {}) {
        const Jolt = world.Jolt;
        this.world = world;
        this.Jolt = Jolt;
        const restBox = bounds(mesh.vertices);
        const diag = Math.hypot(...restBox.size) || 1;
        const o = world.origin, u = world.unit;
        this.origin = o;
        this.unit = u;
        const pm = buildPhysicsMesh(mesh.vertices, mesh.indices, options);
        /** the physics mesh: surface (the welded anchor mesh) or lattice */
        this.physics = pm;
        this.kind = pm.kind;
        this.anchorCount = mesh.vertices.length / 3;
        /** rest anchor vertices (world), the base of the embedding */
        this.restAnchor = Float32Array.from(mesh.vertices);
        /** vertices that are pinned, picked and drawn (welded surface vertices or lattice nodes) */
        this.count = pm.count;
        this.simCount = pm.positions.length / 3;
        this.restAll = pm.positions;
        this.rest = pm.positions.slice(0, 3 * pm.count);
        this.faces = pm.faces;
        this.closed = pm.closed;
        /** anchor vertex -> welded vertex (surface kind), else null */
        this.map = pm.kind === 'surface' ? pm.embedding.nodes : null;

        const shared = new Jolt.SoftBodySharedSettings();
        const mass = options.mass ?? 1;
        const invMass = this.simCount / mass;
        const v = new Jolt.SoftBodySharedSettingsVertex();
        const all = pm.positions;
        for (let i = 0; i < this.simCount; i++) {
            const p = new Jolt.Float3((all[3 * i] - o[0]) * u, (all[3 * i + 1] - o[1]) * u, (all[3 * i + 2] - o[2]) * u);
            v.mPosition = p;
            Jolt.destroy(p);
            v.mInvMass = invMass;
            shared.mVertices.push_back(v);
        }
        Jolt.destroy(v);
        const face = new Jolt.SoftBodySharedSettingsFace(0, 0, 0, 0);
        for (let f = 0; f < pm.faces.length; f += 3) {
            face.set_mVertex(0, pm.faces[f]);
            face.set_mVertex(1, pm.faces[f + 1]);
            face.set_mVertex(2, pm.faces[f + 2]);
            shared.mFaces.push_back(face);
        }
        Jolt.destroy(face);
        if (pm.kind === 'surface') {
            // edge, shear and bend constraints from the faces; the core's spokes and spine below
            const attr = new Jolt.SoftBodySharedSettingsVertexAttributes();
            attr.mCompliance = options.edgeCompliance ?? 1e-3;
            attr.mShearCompliance = options.shearCompliance ?? 1e-3;
            attr.mBendCompliance = options.bendCompliance ?? 0.02;
            shared.CreateConstraints(attr, 1, options.bendType ?? Jolt.SoftBodySharedSettings_EBendType_Dihedral);
            Jolt.destroy(attr);
        }
        for (let e = 0; e < pm.edgeCompliance.length; e++) {
            const edge = new Jolt.SoftBodySharedSettingsEdge(pm.edges[2 * e], pm.edges[2 * e + 1], pm.edgeCompliance[e]);
            shared.mEdgeConstraints.push_back(edge);
            Jolt.destroy(edge);
        }
        if (pm.edgeCompliance.length) shared.CalculateEdgeLengths();
        const volC = options.volumeCompliance ?? 1e-6;
        for (let t = 0; t < pm.volumes.length; t += 4) {
            const vol = new Jolt.SoftBodySharedSettingsVolume(pm.volumes[t], pm.volumes[t + 1], pm.volumes[t + 2], pm.volumes[t + 3], volC);
            shared.mVolumeConstraints.push_back(vol);
            Jolt.destroy(vol);
        }
        if (pm.volumes.length) shared.CalculateVolumeConstraintVolumes();
        shared.Optimize();

        const cs = new Jolt.SoftBodyCreationSettings(shared, new Jolt.RVec3(0, 0, 0), new Jolt.Quat(0, 0, 0, 1), LAYER_MOVING);
        cs.mNumIterations = options.iterations ?? 10;
        cs.mLinearDamping = options.damping ?? 0.5;
        cs.mPressure = pm.kind === 'surface' && this.closed ? (options.pressure ?? 0) : 0;
        cs.mMaxLinearVelocity = (options.maxVelocity ?? MAX_VELOCITY) * diag * u;
        cs.mUpdatePosition = false;
        cs.mMakeRotationIdentity = false;
        cs.mAllowSleeping = false;
        cs.mFriction = options.friction ?? 0.8;
        cs.mRestitution = 0.1;
        cs.mVertexRadius = (options.vertexRadius ?? 0.01) * diag * u;
        this.body = world.bodies.CreateSoftBody(cs);
        Jolt.destroy(cs);
        world.bodies.AddBody(this.body.GetID(), Jolt.EActivation_Activate);
        this.motion = Jolt.castObject(this.body.GetMotionProperties(), Jolt.SoftBodyMotionProperties);
        const arr = this.motion.GetVertices();
        /** @type {any[]} Jolt SoftBodyVertex views, physics vertex order */
        this.verts = [];
        for (let i = 0; i < this.simCount; i++) this.verts.push(arr.at(i));
        /** rest positions in the simulation frame, as Jolt holds them (the embedding's X) */
        this.simRest = new Float32Array(3 * this.simCount);
        this.readSim(this.simRest);
        this.invMass = invMass;
        /** @type {Float32Array|null} targets (3W, world) of pinned vertices, NaN where free */
        this.targets = null;
        /** where pinned vertices are driven this step (simulation frame), moving towards the targets */
        this.drive = new Float32Array(3 * this.simCount);
        /** rest size in the simulation frame: speeds and the guard are relative to it */
        this.simDiag = diag * u;
        this.pinSpeed = options.pinSpeed ?? PIN_SPEED;
        this.guardLimit = options.guard ?? GUARD;
        /** times the guard put an exploded body back to its rest shape */
        this.guardTrips = 0;
        this.gravity = 0;
        this.motion.SetGravityFactor(0);
        this._disp = new Float32Array(3 * this.simCount);
        this._sim = new Float32Array(3 * this.simCount);
    }

    /** Simulation-frame positions of every simulated vertex (3 * simCount). @param {Float32Array} out */
    readSim(out) {
        for (let i = 0; i < this.simCount; i++) {
            const p = this.verts[i].mPosition;
            out[3 * i] = p.GetX(); out[3 * i + 1] = p.GetY(); out[3 * i + 2] = p.GetZ();
        }
        return out;
    }

    /** Current positions of the physics vertices (3 * count, world space). @param {Float32Array} [out] */
    positions(out = new Float32Array(3 * this.count)) {
        for (let i = 0; i < this.count; i++) {
            const p = this.verts[i].mPosition, o = this.origin, k = 1 / this.unit;
            out[3 * i] = p.GetX() * k + o[0]; out[3 * i + 1] = p.GetY() * k + o[1]; out[3 * i + 2] = p.GetZ() * k + o[2];
        }
        return out;
    }

    /**
     * Current anchor vertices (3V, world space, anchor vertex order) through the embedding: each
     * is its rest position plus the weighted displacement of its physics vertices, so at rest
     * it is exactly the rest anchor vertex.
     * @param {Float32Array} [out]
     */
    readAnchorVertices(out = new Float32Array(3 * this.anchorCount)) {
        const d = this._disp, k = 1 / this.unit;
        for (let i = 0; i < this.count; i++) {
            const p = this.verts[i].mPosition, r = this.simRest;
            d[3 * i] = (p.GetX() - r[3 * i]) * k; d[3 * i + 1] = (p.GetY() - r[3 * i + 1]) * k; d[3 * i + 2] = (p.GetZ() - r[3 * i + 2]) * k;
        }
        return applyEmbedding(this.physics.embedding, this.restAnchor, d, out);
    }

    /** Current world-space bounds of the anchor mesh (through the embedding). */
    bounds() {
        return bounds(this.readAnchorVertices());
    }

    /** Gravity on (1) or off (0). @param {number} factor */
    setGravity(factor) {
        this.gravity = factor;
        this.motion.SetGravityFactor(factor);
    }

    /**
     * Pin vertices (kinematic, driven to targets) or free them. A pinned vertex starts where it
     * is and moves towards its target at most `pinSpeed` rest diagonals per second, so a target
     * that jumps (a slider clicked far away, a fast drag) never teleports it.
     * @param {Map<number, number[]>|null} pins physics vertex -> world target; null frees all
     */
    setPins(pins) {
        if (!pins || pins.size === 0) {
            if (this.targets) for (let i = 0; i < this.simCount; i++) this.verts[i].mInvMass = this.invMass;
            this.targets = null;
            return;
        }
        this.targets = new Float32Array(3 * this.simCount).fill(NaN);
        for (let i = 0; i < this.simCount; i++) {
            const t = pins.get(i);
            const v = this.verts[i];
            v.mInvMass = t ? 0 : this.invMass;
            if (!t) continue;
            this.targets.set(t, 3 * i);
            const p = v.mPosition;
            this.drive[3 * i] = p.GetX(); this.drive[3 * i + 1] = p.GetY(); this.drive[3 * i + 2] = p.GetZ();
        }
    }

    /** Move the target of pinned vertex `i`. @param {number} i @param {number[]} t */
    setTarget(i, t) {
        if (this.targets && !Number.isNaN(this.targets[3 * i])) this.targets.set(t, 3 * i);
    }

    /**
     * Advance the world one fixed step (this body alone).
     * @param {number} dt
     */
    step(dt) {
        this.prepare(dt);
        this.world.step(dt);
        this.guard();
    }

    /**
     * Before a world step of `dt`: move the pinned vertices' drive positions towards their targets
     * (all by the same fraction of the way, at most `pinSpeed` rest diagonals per second for the
     * farthest, so a pinned cap moves as a whole) and give each the velocity that takes it there
     * within the step (Jolt moves kinematic vertices with their velocity). Call for every body,
     * then `PhysicsWorld.step` once, then `guard` for every body.
     * @param {number} dt
     */
    prepare(dt) {
        const t = this.targets;
        if (!t) return;
        const o = this.origin, u = this.unit, d = this.drive;
        let far = 0;
        for (let i = 0; i < this.simCount; i++) {
            if (Number.isNaN(t[3 * i])) continue;
            const dx = (t[3 * i] - o[0]) * u - d[3 * i], dy = (t[3 * i + 1] - o[1]) * u - d[3 * i + 1], dz = (t[3 * i + 2] - o[2]) * u - d[3 * i + 2];
            far = Math.max(far, dx * dx + dy * dy + dz * dz);
        }
        far = Math.sqrt(far);
        const reach = this.pinSpeed * this.simDiag * dt;
        const f = far > reach ? reach / far : 1;
        for (let i = 0; i < this.simCount; i++) {
            if (Number.isNaN(t[3 * i])) continue;
            for (let k = 0; k < 3; k++) d[3 * i + k] += f * ((t[3 * i + k] - o[k]) * u - d[3 * i + k]);
            const v = this.verts[i], p = v.mPosition;
            v.mVelocity.Set((d[3 * i] - p.GetX()) / dt, (d[3 * i + 1] - p.GetY()) / dt, (d[3 * i + 2] - p.GetZ()) / dt);
        }
    }

    /** Whether pinned vertices are still on their way to their targets. */
    get pinsMoving() {
        const t = this.targets;
        if (!t) return false;
        const o = this.origin, u = this.unit, eps = 1e-6 * this.simDiag;
        for (let i = 0; i < 3 * this.simCount; i++) {
            if (!Number.isNaN(t[i]) && Math.abs((t[i] - o[i % 3]) * u - this.drive[i]) > eps) return true;
        }
        return false;
    }

    /**
     * After a world step: if the body has blown up (a non-finite position, or an extent beyond
     * `guard` rest diagonals), put it back to its rest shape where its centre is, at rest; pinned
     * vertices then move to their targets again at the bounded speed. Counted in `guardTrips`.
     * @returns {boolean} whether it had to
     */
    guard() {
        if (!(this.guardLimit > 0)) return false;
        const p = this.readSim(this._sim);
        const b = bounds(p);
        const limit = this.guardLimit * this.simDiag;
        const ok = b.size.every((s) => Number.isFinite(s) && s <= limit);
        if (ok) return false;
        this.guardTrips++;
        const r = bounds(this.simRest);
        const shift = b.center.map((c, k) => (Number.isFinite(c) && Math.abs(c - r.center[k]) < 100 * this.simDiag ? c - r.center[k] : 0));
        const q = this.simRest.map((x, i) => x + shift[i % 3]);
        this.teleportSim(q);
        return true;
    }

    /**
     * Teleport every simulated vertex (simulation frame) and zero all velocities; pinned vertices
     * are driven from there.
     * @param {ArrayLike<number>} q 3 * simCount
     */
    teleportSim(q) {
        for (let i = 0; i < this.simCount; i++) {
            const v = this.verts[i];
            const x = q[3 * i], y = q[3 * i + 1], z = q[3 * i + 2];
            v.mPosition.Set(x, y, z);
            v.mPreviousPosition.Set(x, y, z);
            v.mVelocity.Set(0, 0, 0);
            this.drive[3 * i] = x; this.drive[3 * i + 1] = y; this.drive[3 * i + 2] = z;
        }
        this.world.bodies.ActivateBody(this.body.GetID());
    }

    /**
     * Teleport every simulated vertex (3 * simCount world positions: the physics vertices, then
     * the core vertices) and zero all velocities.
     * @param {ArrayLike<number>} p
     */
    teleport(p) {
        const o = this.origin, u = this.unit;
        const q = new Float64Array(3 * this.simCount);
        for (let i = 0; i < 3 * this.simCount; i++) q[i] = (p[i] - o[i % 3]) * u;
        this.teleportSim(q);
    }

    /** Add a velocity (world units per second) to every vertex. @param {number[]} vel */
    kick(vel) {
        const u = this.unit;
        for (let i = 0; i < this.simCount; i++) {
            const v = this.verts[i].mVelocity;
            v.Set(v.GetX() + vel[0] * u, v.GetY() + vel[1] * u, v.GetZ() + vel[2] * u);
        }
    }

    /** Back to the rest shape, unpinned, at rest, without gravity. */
    reset() {
        this.setPins(null);
        this.teleportSim(this.simRest);
        this.setGravity(0);
    }

    /** Rest shape moved by `offset`, unpinned, at rest. @param {number[]} offset */
    placeAt(offset) {
        this.setPins(null);
        this.teleport(this.restAll.map((v, i) => v + offset[i % 3]));
    }

    /**
     * Physics vertices within a fraction `frac` of the rest extent from the low (-1) or high (+1)
     * end along `axis`.
     * @param {Axis} axis @param {-1|1} end @param {number} frac
     * @returns {number[]}
     */
    endCap(axis, end, frac) {
        const b = bounds(this.rest);
        const lim = frac * b.size[axis];
        const out = [];
        for (let i = 0; i < this.count; i++) {
            const s = this.rest[3 * i + axis];
            if (end < 0 ? s <= b.min[axis] + lim : s >= b.max[axis] - lim) out.push(i);
        }
        return out;
    }

    /**
     * Deterministic scripted pose: pin the two end caps along `axis` at the positions `target`
     * gives them, start the free vertices at `target` too, and let the soft body settle
     * (gravity off, fixed steps). The pins stay until `reset` or the next pose.
     * @param {Axis} axis
     * @param {(p: number[], i: number) => number[]} target rest position -> world target
     * @param {{cap?: number, steps?: number, dt?: number}} [options]
     */
    pose(axis, target, options = {}) {
        const cap = options.cap ?? 0.12, steps = options.steps ?? 60, dt = options.dt ?? 1 / 60;
        this.setGravity(0);
        const r = this.restAll;
        const start = new Float32Array(3 * this.simCount);
        for (let i = 0; i < this.simCount; i++) start.set(target([r[3 * i], r[3 * i + 1], r[3 * i + 2]], i), 3 * i);
        /** @type {Map<number, number[]>} */
        const pins = new Map();
        for (const i of [...this.endCap(axis, -1, cap), ...this.endCap(axis, 1, cap)]) {
            pins.set(i, [start[3 * i], start[3 * i + 1], start[3 * i + 2]]);
        }
        this.setPins(pins);
        this.teleport(start);
        for (let s = 0; s < steps; s++) this.step(dt);
    }

    /**
     * Interactive hold: pin the two end caps along `axis` at `target(rest position)` and let the
     * running simulation follow (no teleport, gravity unchanged).
     * @param {Axis} axis
     * @param {(p: number[], i: number) => number[]} target
     * @param {number} [cap]
     */
    hold(axis, target, cap = 0.12) {
        /** @type {Map<number, number[]>} */
        const pins = new Map();
        for (const i of [...this.endCap(axis, -1, cap), ...this.endCap(axis, 1, cap)]) {
            pins.set(i, target([this.rest[3 * i], this.rest[3 * i + 1], this.rest[3 * i + 2]], i));
        }
        this.setPins(pins);
    }

    /**
     * Target function of a stretch by `factor` along `axis` about the rest centre.
     * @param {Axis} axis @param {number} factor
     * @returns {(p: number[]) => number[]}
     */
    stretchMap(axis, factor) {
        const c = bounds(this.rest).center[axis];
        return (p) => {
            const q = p.slice();
            q[axis] = c + factor * (p[axis] - c);
            return q;
        };
    }

    /**
     * Target function of a twist by `deg` about the line through the rest centre along `axis`
     * (0 at the low end cap, `deg` at the high end cap, linear in between).
     * @param {Axis} axis @param {number} deg @param {number} [cap]
     * @returns {(p: number[]) => number[]}
     */
    twistMap(axis, deg, cap = 0.12) {
        const b = bounds(this.rest);
        const lo = b.min[axis] + cap * b.size[axis], hi = b.max[axis] - cap * b.size[axis];
        const u = (axis + 1) % 3, w = (axis + 2) % 3;
        return (p) => {
            const t = Math.min(1, Math.max(0, (p[axis] - lo) / (hi - lo)));
            const a = t * deg * Math.PI / 180, ca = Math.cos(a), sa = Math.sin(a);
            const du = p[u] - b.center[u], dw = p[w] - b.center[w];
            const q = p.slice();
            q[u] = b.center[u] + ca * du - sa * dw;
            q[w] = b.center[w] + sa * du + ca * dw;
            return q;
        };
    }

    /**
     * Stretch by `factor` along `axis` (the pinned end caps are moved apart so that the rest
     * extent along `axis` becomes `factor` times longer, symmetric about the centre).
     * @param {Axis} axis @param {number} factor @param {{cap?: number, steps?: number}} [options]
     */
    pull(axis, factor, options) {
        this.pose(axis, this.stretchMap(axis, factor), options);
    }

    /**
     * Twist by `deg` about the line through the rest centre along `axis`: the low end cap stays,
     * the high end cap turns by `deg`, the body in between follows.
     * @param {Axis} axis @param {number} deg @param {{cap?: number, steps?: number}} [options]
     */
    twist(axis, deg, options) {
        this.pose(axis, this.twistMap(axis, deg, options?.cap), options);
    }

    /** Remove the body from the world. */
    destroy() {
        const id = this.body.GetID();
        this.world.bodies.RemoveBody(id);
        this.world.bodies.DestroyBody(id);
        this.verts = [];
    }
}
