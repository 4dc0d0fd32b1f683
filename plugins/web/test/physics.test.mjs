// readPhysics: the physics records of a scene (KHR_physics_rigid_bodies, KHR_implicit_shapes and
// extras.gsverse.physics) as gsverse-convert --physics ... --ground writes them, on assets built
// here (test/glb-writer.mjs) and on the demo's shipped scene; malformed records refused with their
// code, records the reader cannot use skipped.
import test from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import { fileURLToPath } from 'node:url';
import { AnchorError, readPhysics, RIGID_BODIES, IMPLICIT_SHAPES } from '../src/index.js';
import { anchoredBuilder } from './glb-writer.mjs';

const SCENE = fileURLToPath(new URL('../../../examples/web/scene.glb', import.meta.url));

/** a unit tetrahedron: the hull mesh */
const HULL_V = [0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1];
const HULL_I = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3];

/**
 * One anchored splat node (node 0, mesh 0) with a hull node (node 1, outside the scene) and a
 * ground node (node 2); `record` is the splat node's physics record, `patch` changes the JSON.
 * @param {{record?: any, kind?: string, hullNode?: any, patch?: (json: any) => void, gltf?: boolean}} [o]
 */
function scene(o = {}) {
    const b = anchoredBuilder({
        profile: 'local', face: [0], bary: [0.2, 0.3], vertices: [0, 0, 0, 1, 0, 0, 0, 1, 0], indices: [0, 1, 2],
    });
    const hullMesh = b.json.meshes.length;
    b.json.meshes.push({ name: 'hull', primitives: [{ mode: 4, attributes: { POSITION: b.accessor(Float32Array.from(HULL_V), 'VEC3') }, indices: b.accessor(Uint32Array.from(HULL_I), 'SCALAR') }] });
    b.json.nodes.push({ name: 'hull', mesh: hullMesh, ...(o.hullNode || {}) });
    b.json.nodes[0].name = 'chair';
    b.json.nodes[0].translation = [1, 2, 3];
    b.json.nodes[0].extensions = { [RIGID_BODIES]: o.record ?? { motion: {}, collider: { geometry: { node: 1, convexHull: true } } } };
    b.json.nodes[0].extras = { gsverse: { physics: o.kind ?? 'rigid' } };
    b.json.nodes.push({ name: 'ground', translation: [0, -0.5, 0], extensions: { [RIGID_BODIES]: { collider: { geometry: { shape: 0 } } } } });
    b.json.scenes[0].nodes.push(2);
    b.json.extensions = { [IMPLICIT_SHAPES]: { shapes: [{ type: 'box', box: { size: [4, 1, 4] } }] } };
    b.json.extensionsUsed.push(RIGID_BODIES, IMPLICIT_SHAPES);
    if (o.patch) o.patch(b.json);
    return o.gltf ? b.gltf() : b.glb();
}

/** @param {() => unknown} fn @param {string} code @param {RegExp} [message] */
function refuses(fn, code, message) {
    assert.throws(fn, (/** @type {any} */ err) => {
        assert.ok(err instanceof AnchorError, String(err));
        assert.equal(err.code, code, err.message);
        assert.match(err.message, /^scene\.glb: /);
        if (message) assert.match(err.message, message);
        return true;
    });
}

test('a rigid object: kind, motion defaults, the hull in the splat node space, the ground box with its transform', () => {
    const p = readPhysics(scene(), { name: 'scene.glb' });
    assert.equal(p.objects.length, 1);
    const o = p.objects[0];
    assert.equal(o.node, 0);
    assert.equal(o.name, 'chair');
    assert.equal(o.kind, 'rigid');
    assert.deepEqual(o.motion, { isKinematic: false, mass: null, gravityFactor: 1, linearVelocity: [0, 0, 0], angularVelocity: [0, 0, 0] });
    assert.deepEqual([o.matrix[12], o.matrix[13], o.matrix[14]], [1, 2, 3]);
    assert.equal(o.collider.node, 1);
    assert.equal(o.collider.convexHull, true);
    assert.deepEqual(Array.from(o.collider.vertices), HULL_V);     // node-local: the hull node's identity
    assert.deepEqual(Array.from(o.collider.indices), HULL_I);
    assert.equal(p.shapes.length, 1);
    const g = p.shapes[0];
    assert.equal(g.name, 'ground');
    assert.equal(g.kind, 'static');
    assert.equal(g.type, 'box');
    assert.deepEqual(g.size, [4, 1, 4]);
    assert.equal(g.matrix[13], -0.5);
});

test('the kinds: soft (extras), kinematic, static; motion fields read', () => {
    const soft = readPhysics(scene({ kind: 'soft', record: { motion: { mass: 2.5 }, collider: { geometry: { node: 1, convexHull: true } } } }));
    assert.equal(soft.objects[0].kind, 'soft');
    assert.equal(soft.objects[0].motion?.mass, 2.5);
    const kin = readPhysics(scene({ kind: 'kinematic', record: { motion: { isKinematic: true, linearVelocity: [0, 1, 0] }, collider: { geometry: { node: 1, convexHull: true } } } }));
    assert.equal(kin.objects[0].kind, 'kinematic');
    assert.deepEqual(kin.objects[0].motion?.linearVelocity, [0, 1, 0]);
    const stat = readPhysics(scene({ kind: 'static', record: { collider: { geometry: { node: 1, convexHull: true } } } }));
    assert.equal(stat.objects[0].kind, 'static');
    assert.equal(stat.objects[0].motion, null);
    // the extras say soft but there is no motion: a static body (extras never make a body move)
    const soft0 = readPhysics(scene({ kind: 'soft', record: { collider: { geometry: { node: 1 } } } }));
    assert.equal(soft0.objects[0].kind, 'static');
    // the kind follows the record, not the extras, for the Khronos kinds
    const tagged = readPhysics(scene({ kind: 'static' }));
    assert.equal(tagged.objects[0].kind, 'rigid');
});

test('a .gltf with a data: URI reads the same', () => {
    const a = readPhysics(scene({ gltf: true }));
    const b = readPhysics(scene());
    assert.deepEqual(Array.from(a.objects[0].collider.vertices), Array.from(b.objects[0].collider.vertices));
    assert.deepEqual(a.shapes[0].size, b.shapes[0].size);
});

test('a hull node inside the body node is read in the body space', () => {
    const p = readPhysics(scene({ patch: (j) => { j.nodes[0].children = [1]; j.nodes[1].translation = [0, 0, 5]; } }));
    assert.deepEqual(Array.from(p.objects[0].collider.vertices.subarray(0, 3)), [0, 0, 5]);
    // a root hull node with its own transform: that transform, relative to the body
    const q = readPhysics(scene({ hullNode: { scale: [2, 2, 2] } }));
    assert.deepEqual(Array.from(q.objects[0].collider.vertices.subarray(3, 6)), [2, 0, 0]);
});

test('an asset without physics records: empty lists', () => {
    const b = anchoredBuilder({ profile: 'local', face: [0], bary: [0.2, 0.3], vertices: [0, 0, 0, 1, 0, 0, 0, 1, 0] });
    assert.deepEqual(readPhysics(b.glb()), { objects: [], shapes: [] });
});

test('records the reader cannot use are skipped, as the draft allows', () => {
    // a trigger (no collider)
    const trigger = (/** @type {any} */ j) => { j.nodes[0].extensions[RIGID_BODIES] = { trigger: { geometry: { node: 1 } } }; };
    assert.equal(readPhysics(scene({ patch: trigger })).objects.length, 0);
    // a shape type of the draft this reader does not build
    const p = readPhysics(scene({ patch: (j) => { j.extensions[IMPLICIT_SHAPES].shapes[0] = { type: 'capsule', capsule: { radiusTop: 1, radiusBottom: 1, height: 1 } }; } }));
    assert.equal(p.shapes.length, 0);
    assert.equal(p.objects.length, 1);
    // a sphere is read
    const q = readPhysics(scene({ patch: (j) => { j.extensions[IMPLICIT_SHAPES].shapes[0] = { type: 'sphere', sphere: { radius: 2 } }; } }));
    assert.equal(q.shapes[0].type, 'sphere');
    assert.equal(q.shapes[0].radius, 2);
});

test('malformed records are refused with the gsverse-validate code', () => {
    const name = { name: 'scene.glb' };
    const geometry = (/** @type {any} */ g) => ({ motion: {}, collider: { geometry: g } });
    refuses(() => readPhysics(scene({ record: 3 }), name), 'GLTF_SCHEMA_VIOLATION', /must be an object/);
    refuses(() => readPhysics(scene({ record: { motion: { isKinematic: 'yes' }, collider: { geometry: { node: 1 } } } }), name), 'PHYSICS_MOTION_INVALID', /isKinematic/);
    refuses(() => readPhysics(scene({ record: { motion: { mass: -1 }, collider: { geometry: { node: 1 } } } }), name), 'PHYSICS_MOTION_INVALID', /mass/);
    refuses(() => readPhysics(scene({ record: { motion: { linearVelocity: [0, 1] }, collider: { geometry: { node: 1 } } } }), name), 'PHYSICS_MOTION_INVALID', /linearVelocity/);
    refuses(() => readPhysics(scene({ record: { motion: { gravityFactor: 'x' }, collider: { geometry: { node: 1 } } } }), name), 'PHYSICS_MOTION_INVALID', /gravityFactor/);
    refuses(() => readPhysics(scene({ record: geometry({ node: 9 }) }), name), 'PHYSICS_GEOMETRY_INVALID', /node 9 does not exist/);
    refuses(() => readPhysics(scene({ record: geometry({ node: 2 }) }), name), 'PHYSICS_GEOMETRY_INVALID', /holds no collider mesh/);
    refuses(() => readPhysics(scene({ record: geometry({ node: 1, shape: 0 }) }), name), 'PHYSICS_GEOMETRY_INVALID', /exactly one/);
    refuses(() => readPhysics(scene({ record: { motion: {}, collider: {} } }), name), 'PHYSICS_GEOMETRY_INVALID', /exactly one/);
    refuses(() => readPhysics(scene({ patch: (j) => { j.nodes[2].extensions[RIGID_BODIES].collider.geometry.shape = 4; } }), name), 'PHYSICS_GEOMETRY_INVALID', /shape 4/);
    refuses(() => readPhysics(scene({ patch: (j) => { j.extensions[IMPLICIT_SHAPES].shapes[0].box.size = [1, 0, 1]; } }), name), 'PHYSICS_SHAPE_INVALID', /positive/);
    refuses(() => readPhysics(scene({ patch: (j) => { j.extensions[IMPLICIT_SHAPES].shapes[0] = { type: 'pyramid', pyramid: {} }; } }), name), 'PHYSICS_SHAPE_INVALID', /unknown type/);
    refuses(() => readPhysics(scene({ patch: (j) => { j.extensions[IMPLICIT_SHAPES].shapes[0] = { type: 'box' }; } }), name), 'PHYSICS_SHAPE_INVALID', /no box object/);
    refuses(() => readPhysics(scene({ patch: (j) => { j.meshes[2].primitives[0].mode = 0; } }), name), 'PHYSICS_GEOMETRY_INVALID', /TRIANGLES/);
    refuses(() => readPhysics(scene({ patch: (j) => { j.accessors[j.meshes[2].primitives[0].indices].count = 4; } }), name), 'GLTF_SCHEMA_VIOLATION', /multiple of 3/);
    refuses(() => readPhysics(scene({ kind: 'squishy' }), name), 'PHYSICS_KIND_UNKNOWN', /squishy/);
    // soft on a node whose splats are not anchored
    refuses(() => readPhysics(scene({ kind: 'soft', patch: (j) => { delete j.meshes[0].primitives[0].extensions.KHR_gaussian_splatting.extensions; } }), name),
        'PHYSICS_SOFT_NOT_ANCHORED', /soft body/);
});

test('a hull index out of range is refused', () => {
    const bytes = scene({
        patch: (j) => {
            // the hull keeps 2 of its 4 vertices: its triangles name vertices 2 and 3
            j.accessors[j.meshes[2].primitives[0].attributes.POSITION].count = 2;
        },
    });
    refuses(() => readPhysics(bytes, { name: 'scene.glb' }), 'UNRESOLVED_REFERENCE', /out of range/);
});

test('the demo scene: chair rigid, pillow soft, lamp kinematic, a ground box under everything', { skip: !fs.existsSync(SCENE) && 'examples/web/scene.glb not present' }, () => {
    const p = readPhysics(fs.readFileSync(SCENE), { name: 'scene.glb' });
    assert.deepEqual(p.objects.map((o) => [o.name, o.kind]), [['chair', 'rigid'], ['pillow', 'soft'], ['lamp', 'kinematic']]);
    assert.equal(p.shapes.length, 1);
    const g = p.shapes[0];
    assert.equal(g.name, 'ground');
    assert.equal(g.type, 'box');
    const top = g.matrix[13] + 0.5 * /** @type {number[]} */ (g.size)[1];
    for (const o of p.objects) {
        assert.ok(o.collider.vertices.length >= 12 && o.collider.indices.length >= 12, o.name);
        let low = Infinity;
        for (let i = 1; i < o.collider.vertices.length; i += 3) low = Math.min(low, o.collider.vertices[i] + o.matrix[13]);
        assert.ok(low >= top - 1e-6, `${o.name}: its hull (lowest ${low}) is above the ground's top face (${top})`);
    }
});
