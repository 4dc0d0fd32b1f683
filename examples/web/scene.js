// One loaded asset of the demo: its anchored splats (GPU remap, by the engine adapter:
// engine-playcanvas.js or engine-three.js), one
// Jolt soft body per anchor mesh (physics.js), and the per-frame link between them.
//
// The soft bodies live in world space. Each frame the anchor vertices are read back through each
// body's embedding (physmesh.js), taken to the splat's local space with the inverse of the splat
// node's world matrix, and handed to AnchoredSplat.setVertices; the remap pass moves the splats
// on the next frame. Plain (unanchored) splats of the asset are never touched.
//
// A scene with physics records (the plugin's readPhysics: KHR_physics_rigid_bodies) builds its
// objects by kind in the same world: soft -> the soft body above (with gravity), rigid, kinematic
// and static -> a Jolt rigid body (rigid.js) that drives the splat node's transform (no remap);
// its ground box replaces the demo's own ground. An asset without records is all soft bodies.

import { invertInto, readPhysics } from '@gsverse/web';
import { SoftBodyMesh, bounds } from './physics.js';
import { RigidObject, decomposeAffine } from './rigid.js';

/**
 * Column-major 4x4 times points (3N), into `out`.
 * @param {ArrayLike<number>} m @param {ArrayLike<number>} p @param {Float32Array} out
 */
export function transformPoints(m, p, out) {
    for (let i = 0; i < p.length; i += 3) {
        const x = p[i], y = p[i + 1], z = p[i + 2];
        out[i] = m[0] * x + m[4] * y + m[8] * z + m[12];
        out[i + 1] = m[1] * x + m[5] * y + m[9] * z + m[13];
        out[i + 2] = m[2] * x + m[6] * y + m[10] * z + m[14];
    }
    return out;
}


/**
 * Unique edges of a triangle list.
 * @param {Uint32Array} faces
 * @returns {Uint32Array} pairs
 */
function uniqueEdges(faces) {
    const seen = new Set();
    const out = [];
    for (let f = 0; f < faces.length; f += 3) {
        for (let e = 0; e < 3; e++) {
            const a = faces[f + e], b = faces[f + (e + 1) % 3];
            const key = a < b ? a * 4294967296 + b : b * 4294967296 + a;
            if (seen.has(key)) continue;
            seen.add(key);
            out.push(a, b);
        }
    }
    return new Uint32Array(out);
}

/**
 * @typedef {object} Body
 * @property {any} splat  the plugin's anchored splat
 * @property {import('./engine-playcanvas.js').SplatNode} node  its node
 * @property {SoftBodyMesh} soft
 * @property {Float64Array} toWorld  splat node world matrix (column-major)
 * @property {Float64Array} toLocal  its inverse
 * @property {Float32Array} world    current anchor vertices, world space (3V)
 * @property {Float32Array} local    current anchor vertices, splat-local space (3V)
 * @property {Float32Array} posed    scratch: the animated pose plus the physics displacement (3V)
 * @property {Uint32Array} edges     physics-mesh edges for the wireframe
 * @property {Float32Array} lines    wireframe line buffer
 * @property {Float32Array} wire     physics vertex positions scratch for the wireframe
 */

/**
 * m⁻¹ (column-major 4x4, binary64), for a splat node's matrix.
 * @param {ArrayLike<number>} m
 * @returns {Float64Array}
 */
function inverse(m) {
    const out = new Float64Array(16);
    if (!invertInto(Float64Array.from(m), 0, out)) throw new Error('the splat node matrix is singular');
    return out;
}

/** @typedef {import('./engine-playcanvas.js').Engine} Engine */

export class DemoAsset {
    /**
     * Load an asset (URL or bytes) and build one soft body per anchored primitive.
     * Refused assets throw AnchorError before anything is added to the scene.
     * @param {Engine} engine the engine adapter
     * @param {import('./physics.js').PhysicsWorld} world
     * @param {string|Uint8Array} source
     * @param {string} name
     * @param {import('./physics.js').SoftBodyOptions} [physics] soft-body options (physics mesh kind, budget, ...)
     */
    static async load(engine, world, source, name, physics = {}) {
        let bytes = source;
        if (typeof source === 'string') {
            const response = await fetch(source);
            if (!response.ok) throw new Error(`${source}: HTTP ${response.status}`);
            bytes = new Uint8Array(await response.arrayBuffer());
        }
        const records = readPhysics(/** @type {Uint8Array} */ (bytes), { name });     // refusals throw here
        const loaded = await engine.load(/** @type {Uint8Array} */ (bytes), name);
        try {
            return new DemoAsset(engine, world, loaded, name, physics, records);
        } catch (err) {
            for (const s of loaded.anchored) s.destroy();
            loaded.dispose();
            throw err;
        }
    }

    /**
     * @param {Engine} engine
     * @param {import('./physics.js').PhysicsWorld} world
     * @param {import('./engine-playcanvas.js').Loaded} loaded
     * @param {string} name
     * @param {import('./physics.js').SoftBodyOptions} [physics]
     * @param {import('@gsverse/web').PhysicsScene} [records] the file's physics records
     */
    constructor(engine, world, loaded, name, physics = {}, records = { objects: [], shapes: [] }) {
        this.engine = engine;
        this.world = world;
        this.name = name;
        this.loaded = loaded;
        this.plain = loaded.plain;
        /** the file's animations of its animated anchor meshes ([] when none) */
        this.animations = loaded.animations ?? [];
        /** @type {Body[]} the soft bodies */
        this.bodies = [];
        /** @type {{splat: any, node: import('./engine-playcanvas.js').SplatNode, rigid: RigidObject}[]} the rigid, kinematic and static objects */
        this.rigids = [];
        /** whether the file has physics records: a scene (gravity on, its own ground) */
        this.isScene = records.objects.length > 0 || records.shapes.length > 0;
        /** the file's static ground boxes */
        this.grounds = records.shapes.filter((g) => g.type === 'box' && g.kind === 'static');
        // one simulation frame for the whole asset: about one unit large, centred
        const all = [], before = { origin: world.origin, unit: world.unit };
        for (const splat of loaded.anchored) {
            const m = engine.node(splat).matrix();
            all.push(...transformPoints(m, splat.prim.anchorMesh.vertices, new Float32Array(splat.prim.anchorMesh.vertices.length)));
        }
        if (all.length) {
            const b = bounds(all);
            world.setFrame(b.center, 1 / (Math.max(...b.size) || 1));
        }
        try {
            this.build(world, loaded.anchored, physics, records);
        } catch (err) {
            for (const b of this.bodies) b.soft.destroy();
            for (const r of this.rigids) r.rigid.destroy();
            this.bodies = [];
            this.rigids = [];
            world.setFrame(before.origin, before.unit);     // the current asset's bodies live in it
            throw err;
        }
    }

    /**
     * One soft body per anchored splat.
     * @param {import('./physics.js').PhysicsWorld} world
     * @param {any[]} anchored AnchoredSplat[]
     * @param {import('./physics.js').SoftBodyOptions} physics
     * @param {import('@gsverse/web').PhysicsScene} records
     * @private
     */
    build(world, anchored, physics, records) {
        for (const splat of anchored) {
            const node = this.engine.node(splat);
            const toWorld = node.matrix();
            const object = records.objects.find((o) => o.node === splat.prim.node);
            if (object && object.kind !== 'soft') {
                this.rigids.push({ splat, node, rigid: new RigidObject(world, object, toWorld) });
                continue;
            }
            const mesh = splat.prim.anchorMesh;
            const worldVerts = transformPoints(toWorld, mesh.vertices, new Float32Array(mesh.vertices.length));
            const soft = new SoftBodyMesh(world, { vertices: worldVerts, indices: mesh.indices }, physics);
            const edges = uniqueEdges(soft.faces);
            if (this.isScene) soft.setGravity(1);
            this.bodies.push({
                splat, node, soft, toWorld, toLocal: inverse(toWorld),
                world: worldVerts, local: new Float32Array(mesh.vertices.length), posed: new Float32Array(mesh.vertices.length),
                edges, lines: new Float32Array(edges.length * 3), wire: new Float32Array(3 * soft.count),
            });
        }
    }

    /** Number of splats: anchored (deformed) and plain (left alone). */
    counts() {
        let anchored = 0, plain = 0;
        for (const b of this.bodies) anchored += b.splat.prim.count;
        for (const r of this.rigids) anchored += r.splat.prim.count;
        for (const e of this.plain) plain += e.gsplat?.resource?.numSplats ?? e.gsplat?.asset?.resource?.numSplats ?? e.packedSplats?.numSplats ?? 0;
        return { anchored, plain };
    }

    /** World bounds of the anchor meshes at rest. */
    restBounds() {
        const all = [];
        for (const b of this.bodies) all.push(...transformPoints(b.toWorld, b.splat.prim.anchorMesh.vertices, new Float32Array(b.world.length)));
        return bounds(all);
    }

    /** World bounds of every physics object at rest (soft anchor meshes and rigid hulls). */
    sceneRestBounds() {
        const all = [];
        for (const b of this.bodies) all.push(...transformPoints(b.toWorld, b.splat.prim.anchorMesh.vertices, new Float32Array(b.world.length)));
        for (const { rigid } of this.rigids) {
            const m = rigid.object.matrix;
            all.push(...transformPoints(m, rigid.object.collider.vertices, new Float32Array(rigid.object.collider.vertices.length)));
        }
        return bounds(all);
    }

    /**
     * The file's first static ground box in world space: centre, half extents, rotation
     * (x, y, z, w), and the height of its top face; null when the file has none.
     */
    groundBox() {
        const g = this.grounds[0];
        if (!g) return null;
        const { translation, rotation, scale } = decomposeAffine(g.matrix);
        const size = /** @type {number[]} */ (g.size);
        const half = size.map((v, k) => 0.5 * v * scale[k]);
        return { center: translation, half, rotation, top: translation[1] + half[1] };
    }

    /** Current world bounds of the anchor meshes (through the embedding: the mesh the splats follow). */
    bounds() {
        for (const b of this.bodies) b.soft.readAnchorVertices(b.world);
        return this.syncedBounds();
    }

    /** World bounds of the anchor meshes as last handed to the splats (`sync`). */
    syncedBounds() {
        const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
        for (const b of this.bodies) {
            const r = bounds(b.world);
            for (let k = 0; k < 3; k++) {
                lo[k] = Math.min(lo[k], r.min[k]);
                hi[k] = Math.max(hi[k], r.max[k]);
            }
        }
        return bounds([...lo, ...hi]);
    }

    /**
     * Soft bodies -> splats: read the anchor vertices, to splat-local space, setVertices (the
     * plugin paces the deformed sort centres by the engine's sorts). With an animation `pose`,
     * an animated anchor mesh shows the file's animation at that time plus the soft body's
     * displacement from its rest pose (player.js).
     * @param {{index: number, time: number}|null} [pose]
     */
    sync(pose = null) {
        for (const { node, rigid } of this.rigids) {
            if (rigid.kind === 'static') continue;
            const { translation: t, rotation: q } = rigid.transform();
            node.setPose(t, q);
        }
        for (const b of this.bodies) {
            b.soft.readAnchorVertices(b.world);
            transformPoints(b.toLocal, b.world, b.local);
            if (pose && b.splat.animation) {
                const animated = b.splat.animation.sample(pose.index, pose.time, b.posed);
                const rest = b.splat.prim.anchorMesh.vertices;
                for (let i = 0; i < animated.length; i++) animated[i] += b.local[i] - rest[i];
                b.splat.setVertices(animated);
            } else {
                b.splat.setVertices(b.local);
            }
        }
    }

    /**
     * CPU times of the bodies' last setVertices, ms: the whole call (vertex upload and sort
     * centres) and the part spent on the deformed sort centres.
     */
    remapCpuMs() {
        let total = 0, sort = 0;
        for (const b of this.bodies) {
            total += b.splat.lastRemapMs || 0;
            sort += b.splat.lastSortMs || 0;
        }
        return { total, sort };
    }

    /** Times the guard had to put a body back to rest. */
    guardTrips() {
        return this.bodies.reduce((n, b) => n + b.soft.guardTrips, 0);
    }

    /**
     * Advance the physics one fixed step (pins driven, the world stepped, blown-up bodies put back).
     * @param {number} dt
     */
    step(dt) {
        for (const r of this.rigids) r.rigid.prepare(dt);
        for (const b of this.bodies) b.soft.prepare(dt);
        this.world.step(dt);
        for (const b of this.bodies) b.soft.guard();
    }

    /**
     * Draw the physics meshes as wireframes (immediate lines, current physics positions).
     * @param {number[]} color RGB, 0..1
     */
    drawWireframe(color) {
        for (const b of this.bodies) {
            const p = b.soft.positions(b.wire);
            const e = b.edges, l = b.lines;
            for (let i = 0; i < e.length; i++) {
                const v = e[i];
                l[3 * i] = p[3 * v]; l[3 * i + 1] = p[3 * v + 1]; l[3 * i + 2] = p[3 * v + 2];
            }
            this.engine.drawLines(l, color);
        }
    }

    /**
     * Lift every moving object of a scene by `dy` (world, up) from where the file puts it, at
     * rest: dynamic rigid bodies and soft bodies (kinematic and static ones stay).
     * @param {number} dy
     */
    lift(dy) {
        for (const { rigid } of this.rigids) if (rigid.kind === 'rigid') rigid.reset([0, dy, 0]);
        for (const b of this.bodies) b.soft.placeAt([0, dy, 0]);
    }

    /**
     * Drop: lift what moves and let it fall (gravity on). A scene lifts its dynamic rigid and soft
     * bodies by half its height; an asset without records its soft bodies by half theirs.
     * @returns {boolean} whether this is a scene (the camera stays; otherwise it follows the body)
     */
    drop() {
        const rb = this.isScene ? this.sceneRestBounds() : this.restBounds();
        this.lift(0.5 * rb.size[1]);
        for (const b of this.bodies) b.soft.setGravity(1);
        return this.isScene;
    }

    /**
     * Place the physics ground and the visible `plane` (the engine's ground, or null): the file's ground box
     * when it has one (the plane on its top face), else a wide box a little below `rb` (bounds).
     * @param {import('./physics.js').PhysicsWorld} world @param {any} plane
     * @param {{center: number[], size: number[], min: number[]}} rb
     */
    placeGround(world, plane, rb) {
        const box = this.groundBox();
        if (box) {
            world.setGroundBox(box.center, box.half, box.rotation);
            plane?.place(box.center[0], box.top, box.center[2], 2 * box.half[0], 2 * box.half[2]);
            return;
        }
        const size = Math.max(...rb.size) || 1, y = rb.min[1] - 0.2 * rb.size[1];
        world.setGround(y, 20 * size, [rb.center[0], rb.center[2]]);
        plane?.place(rb.center[0], y, rb.center[2], 20 * size, 20 * size);
    }

    /**
     * The physics objects of a scene now (null for an asset without records): name, kind, the
     * splat node's world position and rotation, the world bounds of its collider hull (rigid
     * kinds) or anchor mesh (soft), the velocity of rigid ones; and the ground's top.
     */
    describe() {
        if (!this.isScene) return null;
        const out = [];
        for (const { node, rigid } of this.rigids) {
            const b = rigid.bounds();
            out.push({ name: rigid.object.name, kind: rigid.kind, node: rigid.object.node, position: node.position(),
                rotation: node.rotation(), min: b.min, max: b.max, velocity: rigid.velocity() });
        }
        for (const b of this.bodies) {
            const r = bounds(b.soft.readAnchorVertices());
            out.push({ name: b.node.name, kind: 'soft', node: b.splat.prim.node, position: b.node.position(),
                rotation: null, min: r.min, max: r.max, velocity: null });
        }
        return { objects: out, groundTop: this.groundBox()?.top ?? null };
    }

    /** Back to the rest pose (physics and splats). */
    reset() {
        for (const b of this.bodies) {
            b.soft.reset();
            if (this.isScene) b.soft.setGravity(1);
            b.splat.reset();
        }
        for (const r of this.rigids) r.rigid.reset();
    }

    /** Remove everything this asset added. */
    destroy() {
        for (const b of this.bodies) {
            b.soft.destroy();
            b.splat.destroy();
        }
        for (const r of this.rigids) {
            r.rigid.destroy();
            r.splat.destroy();
        }
        this.bodies = [];
        this.rigids = [];
        this.loaded.dispose();
    }
}
