// Reading the physics records of a scene (engine-free): `KHR_physics_rigid_bodies` (the Khronos
// draft, KhronosGroup/glTF PR #2424) on the nodes, `KHR_implicit_shapes` at the top level, and the
// GS-Verse kind `extras.gsverse.physics` ("soft": an engine simulates the anchor mesh as a soft
// body and ignores `motion`). What `gsverse-convert --physics ... --ground` writes:
//   - per object, its splat node: `motion` ({} rigid, {isKinematic: true} kinematic, none static)
//     and `collider.geometry = {node: H, convexHull: true}`, H a node (outside every scene,
//     identity transform) whose mesh is the convex hull in the splat node's local space;
//   - `ground`: a node without a mesh whose collider is `geometry.shape = S`, S a box of
//     `KHR_implicit_shapes` centred at the node's origin.
// Records this reader cannot use are skipped, as the draft allows (triggers, joints, the draft's
// capsule, cylinder and plane shapes); malformed ones are refused with AnchorError and the
// gsverse-validate code (spec/validation.md: PHYSICS_GEOMETRY_INVALID, PHYSICS_SHAPE_INVALID,
// PHYSICS_MOTION_INVALID, PHYSICS_KIND_UNKNOWN, PHYSICS_SOFT_NOT_ANCHORED; GLTF_SCHEMA_VIOLATION
// for a record that is not an object, NON_FINITE_VALUE for a hull vertex).

import { AnchorError, EXTENSION, KHR } from './anchor.js';
import { invertInto } from './keyframes.js';
import { FLOAT, GltfError, globalMatrices, isIndex, mat4Multiply, nodeLocalMatrix, nodeParents, parseGltf } from './glb.js';

export const RIGID_BODIES = 'KHR_physics_rigid_bodies';
export const IMPLICIT_SHAPES = 'KHR_implicit_shapes';
/** The kinds of a physics object (`extras.gsverse.physics`). */
export const PHYSICS_KINDS = /** @type {const} */ (['rigid', 'soft', 'kinematic', 'static']);
const TRIANGLES = 4;
/** The shape types of KHR_implicit_shapes; this reader builds box and sphere and skips the others. */
const SHAPE_TYPES = ['box', 'sphere', 'capsule', 'cylinder', 'plane'];
const MOTION = 'PHYSICS_MOTION_INVALID';
const GEOMETRY = 'PHYSICS_GEOMETRY_INVALID';
const SHAPE = 'PHYSICS_SHAPE_INVALID';

/** @typedef {import('./types.js').PhysicsObject} PhysicsObject */
/** @typedef {import('./types.js').PhysicsShape} PhysicsShape */
/** @typedef {import('./types.js').PhysicsScene} PhysicsScene */
/** @typedef {import('./glb.js').GltfDocument} GltfDocument */

/** @param {unknown} v */
const isObject = (v) => typeof v === 'object' && v !== null && !Array.isArray(v);

/**
 * A list of `n` finite numbers, or `fallback` when absent; else `code`.
 * @param {unknown} v @param {number} n @param {string} what @param {number[]|null} fallback @param {string} code
 * @returns {number[]|null}
 */
function numbers(v, n, what, fallback, code) {
    if (v === undefined) return fallback;
    if (!Array.isArray(v) || v.length !== n || v.some((x) => typeof x !== 'number' || !Number.isFinite(x))) {
        throw new GltfError(code, `${what} must be an array of ${n} finite numbers`);
    }
    return v.slice();
}

/**
 * A finite number (≥ 0 when `nonNegative`), or `fallback` when absent; else `code`.
 * @param {unknown} v @param {string} what @param {number|null} fallback @param {string} code @param {boolean} [nonNegative]
 */
function number(v, what, fallback, code, nonNegative = false) {
    if (v === undefined) return fallback;
    if (typeof v !== 'number' || !Number.isFinite(v) || (nonNegative && v < 0)) {
        throw new GltfError(code, `${what} must be a finite number${nonNegative ? ' >= 0' : ''}`);
    }
    return v;
}

/**
 * The `motion` of a record, or null for a static body.
 * @param {unknown} motion @param {string} what
 * @returns {PhysicsObject['motion']}
 */
function readMotion(motion, what) {
    if (motion === undefined) return null;
    if (!isObject(motion)) throw new GltfError(MOTION, `${what} must be an object`);
    const m = /** @type {any} */ (motion);
    if (m.isKinematic !== undefined && typeof m.isKinematic !== 'boolean') {
        throw new GltfError(MOTION, `${what}.isKinematic must be a boolean`);
    }
    return {
        isKinematic: m.isKinematic === true,
        mass: number(m.mass, `${what}.mass`, null, MOTION, true),
        gravityFactor: /** @type {number} */ (number(m.gravityFactor, `${what}.gravityFactor`, 1, MOTION)),
        linearVelocity: /** @type {number[]} */ (numbers(m.linearVelocity, 3, `${what}.linearVelocity`, [0, 0, 0], MOTION)),
        angularVelocity: /** @type {number[]} */ (numbers(m.angularVelocity, 3, `${what}.angularVelocity`, [0, 0, 0], MOTION)),
    };
}

/**
 * The triangles of the mesh of node `h`, in the space of node `body`: H's own matrix when H is
 * a root outside the body's hierarchy (the converter writes it so, with the identity), else
 * H's global matrix seen from the body.
 * @param {GltfDocument} doc @param {number} body @param {number} h @param {string} what
 * @param {() => Float64Array[]} matrices @param {Int32Array} parents
 */
function readHull(doc, body, h, what, matrices, parents) {
    const nodes = Array.isArray(doc.json.nodes) ? doc.json.nodes : [];
    if (!isIndex(h) || h >= nodes.length || !isObject(nodes[h])) throw new GltfError(GEOMETRY, `${what}.node ${JSON.stringify(h)} does not exist (${nodes.length} nodes)`);
    const node = nodes[h];
    const meshes = Array.isArray(doc.json.meshes) ? doc.json.meshes : [];
    const mesh = isIndex(node.mesh) && node.mesh < meshes.length ? meshes[node.mesh] : null;
    const prims = isObject(mesh) && Array.isArray(mesh.primitives) ? mesh.primitives : [];
    if (!prims.length) throw new GltfError(GEOMETRY, `${what}.node ${h} holds no collider mesh`);
    /** @type {number[]} */
    const vertices = [];
    /** @type {number[]} */
    const indices = [];
    let m = nodeLocalMatrix(node);
    if (parents[h] >= 0) {
        const toBody = new Float64Array(16);
        if (!invertInto(Float64Array.from(matrices()[body]), 0, toBody)) {
            throw new GltfError('GLTF_SCHEMA_VIOLATION', `${what}: the body node's matrix is singular`);
        }
        m = mat4Multiply(toBody, matrices()[h]);
    }
    prims.forEach((/** @type {any} */ prim, /** @type {number} */ p) => {
        const w = `meshes[${node.mesh}].primitives[${p}] (the collider of ${what})`;
        if (!isObject(prim) || !isObject(prim.attributes)) throw new GltfError(GEOMETRY, `${w} has no attributes`);
        const mode = prim.mode === undefined ? TRIANGLES : prim.mode;
        if (mode !== TRIANGLES) throw new GltfError(GEOMETRY, `${w} must be TRIANGLES (4), not ${JSON.stringify(mode)}`);
        const pos = doc.raw(prim.attributes.POSITION, `${w}.POSITION`, ['VEC3'], 'GLTF_SCHEMA_VIOLATION');
        if (pos.componentType !== FLOAT) throw new GltfError('GLTF_SCHEMA_VIOLATION', `${w}.POSITION must be FLOAT`);
        const base = vertices.length / 3;
        for (let i = 0; i < pos.values.length; i += 3) {
            const x = pos.values[i], y = pos.values[i + 1], z = pos.values[i + 2];
            if (!Number.isFinite(x) || !Number.isFinite(y) || !Number.isFinite(z)) {
                throw new GltfError('NON_FINITE_VALUE', `${w}.POSITION ${i / 3} is not finite`);
            }
            vertices.push(m[0] * x + m[4] * y + m[8] * z + m[12], m[1] * x + m[5] * y + m[9] * z + m[13], m[2] * x + m[6] * y + m[10] * z + m[14]);
        }
        const n = pos.count;
        if (prim.indices === undefined) {
            for (let i = 0; i + 2 < n; i += 3) indices.push(base + i, base + i + 1, base + i + 2);
        } else {
            const idx = doc.raw(prim.indices, `${w}.indices`, ['SCALAR'], 'GLTF_SCHEMA_VIOLATION');
            if (idx.values.length % 3) throw new GltfError('GLTF_SCHEMA_VIOLATION', `${w}.indices count ${idx.values.length} is not a multiple of 3`);
            for (const i of idx.values) {
                if (!Number.isInteger(i) || i < 0 || i >= n) throw new GltfError('UNRESOLVED_REFERENCE', `${w}.indices: vertex ${i} out of range (${n} vertices)`);
                indices.push(base + i);
            }
        }
    });
    if (!indices.length) throw new GltfError(GEOMETRY, `${what}: the collider mesh of node ${h} has no triangles`);
    return { vertices: Float32Array.from(vertices), indices: Uint32Array.from(indices) };
}


/**
 * The implicit shape `s` as this reader uses it, or null for a type of the draft it does not build.
 * @param {any} json @param {unknown} s @param {string} what
 * @returns {{type: 'box', size: number[]}|{type: 'sphere', radius: number}|null}
 */
function readShape(json, s, what) {
    const shapes = json.extensions?.[IMPLICIT_SHAPES]?.shapes;
    if (!Array.isArray(shapes) || !isIndex(s) || /** @type {number} */ (s) >= shapes.length) {
        throw new GltfError(GEOMETRY, `${what}.shape ${JSON.stringify(s)} names no shape of ${IMPLICIT_SHAPES}`);
    }
    const shape = shapes[/** @type {number} */ (s)];
    const w = `extensions.${IMPLICIT_SHAPES}.shapes[${s}]`;
    if (!isObject(shape) || !SHAPE_TYPES.includes(shape.type)) {
        throw new GltfError(SHAPE, `${w} has an unknown type ${JSON.stringify(shape?.type)} (${SHAPE_TYPES.join(', ')})`);
    }
    const params = shape[shape.type];
    if (!isObject(params)) throw new GltfError(SHAPE, `${w} has no ${shape.type} object`);
    if (shape.type === 'box') {
        const size = /** @type {number[]} */ (numbers(params.size, 3, `${w}.box.size`, [1, 1, 1], SHAPE));
        if (size.some((v) => v <= 0)) throw new GltfError(SHAPE, `${w}.box.size must be positive (degenerate)`);
        return { type: 'box', size };
    }
    if (shape.type === 'sphere') {
        const radius = /** @type {number} */ (number(params.radius, `${w}.sphere.radius`, 0.5, SHAPE));
        if (radius <= 0) throw new GltfError(SHAPE, `${w}.sphere.radius must be positive (degenerate)`);
        return { type: 'sphere', radius };
    }
    return null;
}

/**
 * The mesh `m` holds a KHR_gaussian_splatting primitive (`anchored`: one with the anchor extension).
 * @param {any} json @param {unknown} m @param {boolean} [anchored]
 */
function holdsSplats(json, m, anchored = false) {
    const mesh = isIndex(m) && Array.isArray(json.meshes) ? json.meshes[/** @type {number} */ (m)] : null;
    return !!mesh && Array.isArray(mesh.primitives) && mesh.primitives.some((/** @type {any} */ p) => {
        const khr = p?.extensions?.[KHR];
        return khr !== undefined && (!anchored || khr?.extensions?.[EXTENSION] !== undefined);
    });
}

/**
 * Read the physics records of a GLB (or .gltf with data: URIs): the splat nodes that are physics
 * objects (their kind, motion and convex-hull collider in the node's local space) and the
 * nodes without splats whose collider is an implicit shape (the ground). Returns empty lists for
 * an asset without physics records. Throws AnchorError (message naming the file and the cause,
 * `.code` the gsverse-validate code) for a malformed record.
 * @param {Uint8Array|ArrayBuffer|GltfDocument} input
 * @param {{name?: string}} [options] name: the file name used in messages
 * @returns {PhysicsScene}
 */
export function readPhysics(input, options = {}) {
    const name = options.name || 'asset';
    try {
        const doc = 'json' in input && 'buffers' in input ? /** @type {GltfDocument} */ (input) : parseGltf(/** @type {Uint8Array|ArrayBuffer} */ (input));
        const json = doc.json;
        const nodes = Array.isArray(json.nodes) ? json.nodes : [];
        /** @type {PhysicsObject[]} */
        const objects = [];
        /** @type {PhysicsShape[]} */
        const shapes = [];
        /** @type {Float64Array[]|null} */
        let global = null;
        const matrices = () => (global = global || globalMatrices(json));
        /** @type {Int32Array|null} */
        let parents = null;
        nodes.forEach((/** @type {any} */ node, /** @type {number} */ i) => {
            const record = node?.extensions?.[RIGID_BODIES];
            if (record === undefined) return;
            const what = `nodes[${i}].extensions.${RIGID_BODIES}`;
            if (!isObject(record)) throw new GltfError('GLTF_SCHEMA_VIOLATION', `${what} must be an object`);
            const motion = readMotion(record.motion, `${what}.motion`);
            const tag = node?.extras?.gsverse?.physics;
            if (tag !== undefined && !PHYSICS_KINDS.includes(tag)) {
                throw new GltfError('PHYSICS_KIND_UNKNOWN', `nodes[${i}].extras.gsverse.physics ${JSON.stringify(tag)} is not one of ${PHYSICS_KINDS.join(', ')}`);
            }
            if (tag === 'soft' && !holdsSplats(json, node.mesh, true)) {
                throw new GltfError('PHYSICS_SOFT_NOT_ANCHORED', `nodes[${i}] is a soft body but holds no anchored splat primitive`);
            }
            const collider = record.collider;
            if (collider === undefined) return;                  // a trigger or a joint only
            const gw = `${what}.collider.geometry`;
            const geometry = isObject(collider) ? collider.geometry : undefined;
            if (!isObject(geometry) || (geometry.node === undefined) === (geometry.shape === undefined)) {
                throw new GltfError(GEOMETRY, `${gw} must name exactly one of node and shape`);
            }
            /** @type {PhysicsObject['kind']} */
            const kind = tag === 'soft' && motion ? 'soft' : !motion ? 'static' : motion.isKinematic ? 'kinematic' : 'rigid';
            const label = typeof node.name === 'string' ? node.name : `node ${i}`;
            if (holdsSplats(json, node.mesh)) {
                if (geometry.node === undefined) return;      // an implicit shape on splats: not read here
                if (geometry.convexHull !== undefined && typeof geometry.convexHull !== 'boolean') {
                    throw new GltfError(GEOMETRY, `${gw}.convexHull must be a boolean`);
                }
                parents = parents || nodeParents(json);
                const hull = readHull(doc, i, /** @type {number} */ (geometry.node), gw, matrices, parents);
                objects.push({
                    node: i, name: label, kind, motion, matrix: matrices()[i],
                    collider: { node: /** @type {number} */ (geometry.node), convexHull: geometry.convexHull === true, ...hull },
                });
            } else if (geometry.shape !== undefined) {
                const shape = readShape(json, geometry.shape, gw);
                if (!shape) return;                           // capsule, cylinder, plane: not built here
                shapes.push({ node: i, name: label, kind, matrix: matrices()[i], shape: /** @type {number} */ (geometry.shape), ...shape });
            }
        });
        return { objects, shapes };
    } catch (err) {
        if (err instanceof AnchorError || err instanceof GltfError) throw new AnchorError(err.code, `${name}: ${err.message}`);
        throw err;
    }
}
