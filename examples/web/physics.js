// The anchor mesh as a Jolt soft body (npm `jolt-physics`, the physics engine Godot 4 also uses).
//
// The anchor mesh of an anchored splat primitive is welded (vertices that share a position, e.g.
// along UV seams, become one soft-body vertex), turned into a Jolt soft body (edge, shear and
// dihedral bend constraints from its faces, plus pressure when the mesh is closed), and simulated
// in world space next to a static ground box. Each frame the soft-body vertices are mapped back to
// the anchor vertex order (`readAnchorVertices`), so the caller can convert them to splat-local
// space and hand them to the remap.
//
// Manipulations are done the way a hand does them: a set of vertices is pinned (made kinematic,
// inverse mass 0) and driven to target positions while the rest of the body follows under its
// constraints. The scripted manipulations (`pose`) are deterministic: they set the pins and the
// free vertices to an initial guess, zero all velocities, switch gravity off and step the solver a
// fixed number of times with a fixed time step.
//
// The module takes the initialised Jolt module as an argument, so it runs in the browser and in
// Node alike.

const LAYER_STATIC = 0;
const LAYER_MOVING = 1;

/** @typedef {0|1|2} Axis */

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

/**
 * Weld vertices that share a position (within `tolerance`, absolute units).
 * Positions are snapped to a grid of `tolerance`; exact duplicates always weld.
 * @param {Float32Array} vertices 3V positions
 * @param {number} tolerance
 * @returns {{map: Uint32Array, positions: Float32Array, count: number}} map: anchor vertex -> welded vertex
 */
export function weldVertices(vertices, tolerance) {
    const n = vertices.length / 3;
    const map = new Uint32Array(n);
    /** @type {Map<string, number>} */
    const seen = new Map();
    const out = [];
    const inv = tolerance > 0 ? 1 / tolerance : 0;
    for (let i = 0; i < n; i++) {
        const x = vertices[3 * i], y = vertices[3 * i + 1], z = vertices[3 * i + 2];
        const key = inv ? `${Math.round(x * inv)},${Math.round(y * inv)},${Math.round(z * inv)}` : `${x},${y},${z}`;
        let w = seen.get(key);
        if (w === undefined) {
            w = out.length / 3;
            seen.set(key, w);
            out.push(x, y, z);
        }
        map[i] = w;
    }
    return { map, positions: new Float32Array(out), count: out.length / 3 };
}

/**
 * Faces on welded vertices, without degenerate or repeated faces.
 * @param {Uint32Array} indices 3F anchor-vertex indices
 * @param {Uint32Array} map anchor vertex -> welded vertex
 * @returns {Uint32Array}
 */
export function weldFaces(indices, map) {
    const out = [];
    const seen = new Set();
    for (let f = 0; f < indices.length; f += 3) {
        const a = map[indices[f]], b = map[indices[f + 1]], c = map[indices[f + 2]];
        if (a === b || b === c || a === c) continue;
        const key = [a, b, c].sort((p, q) => p - q).join(',');
        if (seen.has(key)) continue;
        seen.add(key);
        out.push(a, b, c);
    }
    return new Uint32Array(out);
}

/**
 * Whether a triangle mesh is closed (every edge shared by exactly two faces).
 * @param {Uint32Array} faces
 * @returns {boolean}
 */
export function isClosed(faces) {
    /** @type {Map<string, number>} */
    const count = new Map();
    for (let f = 0; f < faces.length; f += 3) {
        for (let e = 0; e < 3; e++) {
            const a = faces[f + e], b = faces[f + (e + 1) % 3];
            const key = a < b ? `${a},${b}` : `${b},${a}`;
            count.set(key, (count.get(key) || 0) + 1);
        }
    }
    if (count.size === 0) return false;
    for (const c of count.values()) if (c !== 2) return false;
    return true;
}

/**
 * Axis-aligned bounds of 3V positions.
 * @param {ArrayLike<number>} p
 * @returns {{min: number[], max: number[], size: number[], center: number[]}}
 */
export function bounds(p) {
    const min = [Infinity, Infinity, Infinity], max = [-Infinity, -Infinity, -Infinity];
    for (let i = 0; i < p.length; i += 3) {
        for (let k = 0; k < 3; k++) {
            const v = p[i + k];
            if (v < min[k]) min[k] = v;
            if (v > max[k]) max[k] = v;
        }
    }
    const size = [0, 1, 2].map((k) => max[k] - min[k]);
    const center = [0, 1, 2].map((k) => 0.5 * (max[k] + min[k]));
    return { min, max, size, center };
}

/**
 * Interior points of a closed mesh: `count` points evenly spread along its longest axis through
 * the centroid (count 1: the centroid; 0: about two per thickness along the axis).
 * @param {Float32Array} p 3W positions
 * @param {number} count
 * @returns {number[]}
 */
export function coreVertices(p, count) {
    const n = p.length / 3;
    const c = [0, 0, 0];
    for (let i = 0; i < n; i++) for (let k = 0; k < 3; k++) c[k] += p[3 * i + k] / n;
    const b = bounds(p);
    const axis = b.size.indexOf(Math.max(...b.size));
    if (count <= 0) {
        const others = b.size.filter((_, k) => k !== axis);
        const thick = Math.max(1e-9, 0.5 * (others[0] + others[1]));
        count = Math.max(1, Math.min(12, Math.round(2 * b.size[axis] / thick)));
    }
    if (count <= 1) return c;
    const out = [];
    for (let j = 0; j < count; j++) {
        const q = c.slice();
        q[axis] = b.min[axis] + b.size[axis] * (j + 0.5) / count;
        out.push(...q);
    }
    return out;
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
        const Jolt = this.Jolt;
        if (this.ground) {
            this.bodies.RemoveBody(this.ground.GetID());
            this.bodies.DestroyBody(this.ground.GetID());
        }
        this.groundY = y;
        const u = this.unit, o = this.origin;
        const h = Math.max(halfWidth * u, 1e-3), t = 0.5 * h;
        const shape = new Jolt.BoxShape(new Jolt.Vec3(h, t, h), Math.min(0.05, 0.1 * t), null);
        const cs = new Jolt.BodyCreationSettings(shape, new Jolt.RVec3((center[0] - o[0]) * u, (y - o[1]) * u - t, (center[1] - o[2]) * u),
            new Jolt.Quat(0, 0, 0, 1),
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
}

/**
 * The anchor mesh of one anchored primitive as a soft body, in world space.
 */
export class SoftBodyMesh {
    /**
     * @param {PhysicsWorld} world
     * @param {{vertices: Float32Array, indices: Uint32Array}} mesh world-space anchor vertices (3V) and faces (3F)
     * @param {{mass?: number, edgeCompliance?: number, bendCompliance?: number, pressure?: number,
     *          iterations?: number, damping?: number, friction?: number, vertexRadius?: number,
     *          bendType?: number, shearCompliance?: number, spokeCompliance?: number, coreCount?: number}} [options]
     */
    constructor(world, mesh, options = {}) {
        const Jolt = world.Jolt;
        this.world = world;
        this.Jolt = Jolt;
        const rest = bounds(mesh.vertices);
        const diag = Math.hypot(...rest.size) || 1;
        const o = world.origin, u = world.unit;
        this.origin = o;
        this.unit = u;
        const weld = weldVertices(mesh.vertices, diag * 1e-6);
        this.map = weld.map;
        this.count = weld.count;
        this.anchorCount = mesh.vertices.length / 3;
        this.rest = weld.positions;
        this.faces = weldFaces(mesh.indices, weld.map);
        this.closed = isClosed(this.faces);
        if (this.faces.length === 0) throw new Error('the anchor mesh has no non-degenerate face');

        // A closed mesh gets interior "core" vertices (a chain of points along its longest axis)
        // tied to the surface by spokes (distance constraints): the body keeps its cross-sections
        // like a solid instead of collapsing like an empty shell when twisted or stretched.
        const core = this.closed && (options.spokeCompliance ?? 0) >= 0 ? coreVertices(this.rest, options.coreCount ?? 0) : [];
        this.simCount = this.count + core.length / 3;
        const shared = new Jolt.SoftBodySharedSettings();
        const mass = options.mass ?? 1;
        const invMass = this.simCount / mass;
        const v = new Jolt.SoftBodySharedSettingsVertex();
        const all = new Float32Array(3 * this.simCount);
        all.set(this.rest);
        all.set(core, 3 * this.count);
        for (let i = 0; i < this.simCount; i++) {
            v.mPosition = new Jolt.Float3((all[3 * i] - o[0]) * u, (all[3 * i + 1] - o[1]) * u, (all[3 * i + 2] - o[2]) * u);
            v.mInvMass = invMass;
            shared.mVertices.push_back(v);
        }
        Jolt.destroy(v);
        this.restAll = all;
        const face = new Jolt.SoftBodySharedSettingsFace(0, 0, 0, 0);
        for (let f = 0; f < this.faces.length; f += 3) {
            face.set_mVertex(0, this.faces[f]);
            face.set_mVertex(1, this.faces[f + 1]);
            face.set_mVertex(2, this.faces[f + 2]);
            shared.mFaces.push_back(face);
        }
        Jolt.destroy(face);
        const attr = new Jolt.SoftBodySharedSettingsVertexAttributes();
        attr.mCompliance = options.edgeCompliance ?? 1e-3;
        attr.mShearCompliance = options.shearCompliance ?? 1e-3;
        attr.mBendCompliance = options.bendCompliance ?? 0.02;
        shared.CreateConstraints(attr, 1, options.bendType ?? Jolt.SoftBodySharedSettings_EBendType_Dihedral);
        if (core.length) {
            // Spokes: every surface vertex to its two nearest core vertices; a spine along the core.
            const nc = core.length / 3;
            const spoke = options.spokeCompliance ?? 1e-4;
            const add = (/** @type {number} */ i, /** @type {number} */ j, /** @type {number} */ c) => {
                const e = new Jolt.SoftBodySharedSettingsEdge(i, j, c);
                shared.mEdgeConstraints.push_back(e);
                Jolt.destroy(e);
            };
            for (let i = 0; i < this.count; i++) {
                const d = [];
                for (let k = 0; k < nc; k++) {
                    let q = 0;
                    for (let j = 0; j < 3; j++) q += (all[3 * i + j] - core[3 * k + j]) ** 2;
                    d.push([q, k]);
                }
                d.sort((x, y) => x[0] - y[0]);
                for (const [, k] of d.slice(0, Math.min(2, nc))) add(i, this.count + k, spoke);
            }
            for (let k = 0; k + 1 < nc; k++) add(this.count + k, this.count + k + 1, attr.mCompliance);
            shared.CalculateEdgeLengths();
        }
        Jolt.destroy(attr);
        shared.Optimize();

        const cs = new Jolt.SoftBodyCreationSettings(shared, new Jolt.RVec3(0, 0, 0), new Jolt.Quat(0, 0, 0, 1), LAYER_MOVING);
        cs.mNumIterations = options.iterations ?? 10;
        cs.mLinearDamping = options.damping ?? 0.5;
        cs.mPressure = this.closed ? (options.pressure ?? 0) : 0;
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
        /** @type {any[]} Jolt SoftBodyVertex views, welded order */
        this.verts = [];
        for (let i = 0; i < this.simCount; i++) this.verts.push(arr.at(i));
        this.invMass = invMass;
        /** @type {Float32Array|null} targets (3W) of pinned vertices, NaN where free */
        this.targets = null;
        this.gravity = 0;
        this.motion.SetGravityFactor(0);
    }

    /** Current welded positions (3W, world space). @param {Float32Array} [out] */
    positions(out = new Float32Array(3 * this.count)) {
        for (let i = 0; i < this.count; i++) {
            const p = this.verts[i].mPosition, o = this.origin, k = 1 / this.unit;
            out[3 * i] = p.GetX() * k + o[0]; out[3 * i + 1] = p.GetY() * k + o[1]; out[3 * i + 2] = p.GetZ() * k + o[2];
        }
        return out;
    }

    /**
     * Current positions in the anchor vertex order (3V, world space): duplicates that were welded
     * get the same position.
     * @param {Float32Array} [out]
     */
    readAnchorVertices(out = new Float32Array(3 * this.anchorCount)) {
        const w = this.positions(this._tmp || (this._tmp = new Float32Array(3 * this.count)));
        for (let i = 0; i < this.anchorCount; i++) {
            const j = this.map[i];
            out[3 * i] = w[3 * j]; out[3 * i + 1] = w[3 * j + 1]; out[3 * i + 2] = w[3 * j + 2];
        }
        return out;
    }

    /** Current world-space bounds of the body. */
    bounds() {
        return bounds(this.positions());
    }

    /** Gravity on (1) or off (0). @param {number} factor */
    setGravity(factor) {
        this.gravity = factor;
        this.motion.SetGravityFactor(factor);
    }

    /**
     * Pin vertices (kinematic, driven to targets) or free them.
     * @param {Map<number, number[]>|null} pins welded vertex -> world target; null frees all
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
            this.verts[i].mInvMass = t ? 0 : this.invMass;
            if (t) this.targets.set(t, 3 * i);
        }
    }

    /** Move the target of pinned vertex `i`. @param {number} i @param {number[]} t */
    setTarget(i, t) {
        if (this.targets && !Number.isNaN(this.targets[3 * i])) this.targets.set(t, 3 * i);
    }

    /**
     * Advance the world one fixed step (this body alone: pinned vertices get the velocity that
     * takes them to their target within the step; Jolt moves kinematic vertices with their
     * velocity).
     * @param {number} dt
     */
    step(dt) {
        this.prepare(dt);
        this.world.step(dt);
    }

    /**
     * Before a world step of `dt`: give pinned vertices the velocity that takes them to their
     * target within the step. Call for every body, then `PhysicsWorld.step` once.
     * @param {number} dt
     */
    prepare(dt) {
        const t = this.targets;
        if (t) {
            for (let i = 0; i < this.simCount; i++) {
                if (Number.isNaN(t[3 * i])) continue;
                const v = this.verts[i], p = v.mPosition, o = this.origin, u = this.unit;
                v.mVelocity.Set(((t[3 * i] - o[0]) * u - p.GetX()) / dt, ((t[3 * i + 1] - o[1]) * u - p.GetY()) / dt,
                    ((t[3 * i + 2] - o[2]) * u - p.GetZ()) / dt);
            }
        }
    }

    /**
     * Teleport every simulated vertex (3 * simCount world positions: the welded surface vertices,
     * then the core vertices) and zero all velocities.
     * @param {ArrayLike<number>} p
     */
    teleport(p) {
        for (let i = 0; i < this.simCount; i++) {
            const v = this.verts[i];
            const o = this.origin, u = this.unit;
            const x = (p[3 * i] - o[0]) * u, y = (p[3 * i + 1] - o[1]) * u, z = (p[3 * i + 2] - o[2]) * u;
            v.mPosition.Set(x, y, z);
            v.mPreviousPosition.Set(x, y, z);
            v.mVelocity.Set(0, 0, 0);
        }
        this.world.bodies.ActivateBody(this.body.GetID());
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
        this.teleport(this.restAll);
        this.setGravity(0);
    }

    /** Rest shape moved by `offset`, unpinned, at rest. @param {number[]} offset */
    placeAt(offset) {
        this.setPins(null);
        this.teleport(this.restAll.map((v, i) => v + offset[i % 3]));
    }

    /**
     * Welded vertices within a fraction `frac` of the rest extent from the low (-1) or high (+1)
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
