// Animated anchor meshes (spec/README.md §Animated anchor meshes): the skin, morph targets and
// animations an anchored asset carries for its anchor mesh, sampled at any time into the
// current anchor vertices in the splat primitive's local space, in the anchor mesh's file
// vertex order (what AnchoredSplat.setVertices takes). Engine-free: typed arrays only.
//
// At time t, anchor vertex i is
//   1. morphed: p = POSITION_i + Σ_k w_k(t) · targets[k].POSITION_i, with the weights of the
//      anchor node's `weights` channel, else the node's `weights`, else the mesh's, else 0;
//   2. skinned (glTF 2.0 linear blend skinning) when the anchor node has a skin:
//      p' = Σ_j WEIGHTS_ij · G(joints[JOINTS_ij]) · IBM_j · p over every JOINTS_n/WEIGHTS_n set,
//      each vertex's weights normalized (divided by their sum; all zero: 1 on the first one),
//      G the global transform of the joint node at t (the anchor node's own transform is ignored);
//   3. for a skinned mesh, brought into the splat primitive's local space: M(t)⁻¹ · p', M the
//      global matrix at t of the node instantiating the splat mesh (the identity without one).
//      An unskinned, morph-only mesh is already in that space.
// Global transforms are products of local ones (`matrix`, or T·R·S with the node's values
// replaced by animated ones; a node with `matrix` is not animated) over the node hierarchy.
// Everything that does not depend on t is read, checked and laid out once per asset.

import { AnchorError } from './anchor.js';
import { FLOAT, GltfDocument, GltfError, UNSIGNED_BYTE, UNSIGNED_SHORT, dequantize, isIndex, nodeParents, parseGltf } from './glb.js';
import { INTERPOLATIONS, composeTrs, invertInto, multiplyInto, normalizeQuaternion, sampleKeyframes } from './keyframes.js';

/** @typedef {import('./types.js').AnchoredPrimitive} AnchoredPrimitive */
/** @typedef {import('./glb.js').RawAccessor} RawAccessor */
/** @typedef {import('./keyframes.js').Keyframes} Keyframes */

// gsverse-validate codes (spec/validation.md, validators/rig.py)
const SKIN = 'ANCHOR_SKIN_INVALID';
const SKIN_ATTRIBUTES = 'ANCHOR_SKIN_ATTRIBUTES_INVALID';
const MORPH = 'ANCHOR_MORPH_TARGETS_INVALID';
const TARGET = 'ANCHOR_ANIMATION_TARGET_INVALID';
const NON_FINITE = 'NON_FINITE_VALUE';
/** an animation sampler whose keys cannot be sampled: no keys, key times that decrease, an
 * unknown interpolation, an output count that does not match the key count */
const SAMPLER = 'ANCHOR_ANIMATION_SAMPLER_INVALID';
/** the splat node's global matrix is singular at the sampled time (no splat-local space) */
const SPLAT_NODE_SINGULAR = 'ANCHOR_SPLAT_NODE_SINGULAR';

const TRANSLATION = 0;
const ROTATION = 1;
const SCALE = 2;
const WEIGHTS = 3;
/** @type {{[path: string]: number}} */
const PATHS = { translation: TRANSLATION, rotation: ROTATION, scale: SCALE, weights: WEIGHTS };

/**
 * One animation of the asset.
 * @typedef {object} AnimationInfo
 * @property {number} index     its index in the file's `animations`
 * @property {string} name      its name, or `animation <index>`
 * @property {number} duration  the last key time of all its samplers, s (0 without keys)
 */

/**
 * A sampler bound to what it drives: `slot` is the node slot of a translation, rotation or
 * scale channel (-1 for the anchor node's morph weights).
 * @typedef {Keyframes & {path: number, slot: number}} Channel
 */

/** @param {string} code @param {string} message */
const fail = (code, message) => new AnchorError(code, message);

/**
 * @param {ArrayLike<number>} values
 * @param {string} what
 */
function requireFinite(values, what) {
    for (let i = 0; i < values.length; ++i) {
        if (!Number.isFinite(values[i])) throw fail(NON_FINITE, `${what} holds NaN or infinity (number ${i})`);
    }
}

/**
 * A node's `translation`, `rotation` or `scale`, or its default.
 * @param {any} node
 * @param {string} key
 * @param {number[]} fallback
 * @param {number} i  node index
 * @returns {number[]}
 */
function nodeVector(node, key, fallback, i) {
    const v = node[key];
    if (v === undefined) return fallback;
    if (!Array.isArray(v) || v.length !== fallback.length || !v.every((x) => typeof x === 'number')) {
        throw fail('GLTF_SCHEMA_VIOLATION', `nodes[${i}].${key} must be an array of ${fallback.length} numbers`);
    }
    requireFinite(v, `nodes[${i}].${key}`);
    return v;
}

/**
 * The morph weights (one per target) in `owner.weights`, or null when it has none.
 * @param {any} owner
 * @param {string} what
 * @param {number} targets
 * @returns {number[]|null}
 */
function defaultWeights(owner, what, targets) {
    const w = owner.weights;
    if (w === undefined) return null;
    if (!Array.isArray(w) || !w.every((x) => typeof x === 'number')) throw fail(MORPH, `${what}.weights must be an array of numbers`);
    if (w.length !== targets) throw fail(MORPH, `${what} has ${w.length} default weights for ${targets} morph targets`);
    requireFinite(w, `${what}.weights`);
    return w;
}

/** @param {Float64Array} m 4x4 @returns {boolean} m is exactly the identity */
function isIdentity(m) {
    for (let i = 0; i < 16; ++i) if (m[i] !== (i % 5 === 0 ? 1 : 0)) return false;
    return true;
}

/**
 * The animation of one anchor mesh, made by readAnchorAnimation. Public: `animations`,
 * `skinned`, `morphed`, `vertexCount`, `targetCount`, `jointCount`, `node`, `splatNode`,
 * `sample()` and `rest()`; the other fields are the precomputed state `sample` works on.
 */
/**
 * Deliberately broken variants (testing only: the conformance suite's rig cases must catch
 * them): `skip-inverse-node` leaves skinned vertices in the scene's global space (no M⁻¹),
 * `raw-weights` skins with the weights as stored (no normalization).
 */
export const ANIMATION_FAULTS = Object.freeze(['skip-inverse-node', 'raw-weights']);

export class AnchorAnimation {
    /**
     * @param {GltfDocument} doc @param {AnchoredPrimitive} prim @param {string} name
     * @param {string|null} [fault]  one of ANIMATION_FAULTS (testing only)
     */
    constructor(doc, prim, name, fault = null) {
        if (fault !== null && !ANIMATION_FAULTS.includes(fault)) {
            throw new Error(`unknown animation fault '${fault}' (known: ${ANIMATION_FAULTS.join(', ')})`);
        }
        /** @type {string|null} */
        this.fault = fault;
        const json = doc.json;
        const anchor = prim.anchorMesh;
        const nodes = Array.isArray(json.nodes) ? json.nodes : [];
        const anchorNode = /** @type {number} */ (anchor.node);
        const node = doc.item('nodes', anchorNode, 'the anchor node');
        const mesh = doc.item('meshes', anchor.mesh, `nodes[${anchorNode}].mesh`);
        const aprim = mesh.primitives[anchor.primitive];
        const where = `anchor mesh meshes[${anchor.mesh}].primitives[${anchor.primitive}]`;
        /** @type {string} file name used in messages */
        this.name = name;
        /** @type {number} the node instantiating the anchor mesh (its transform is ignored) */
        this.node = anchorNode;
        /** @type {number} V */
        this.vertexCount = anchor.vertexCount;
        const V = anchor.vertexCount;
        /** rest POSITION, binary64 */
        this.base = Float64Array.from(anchor.vertices);

        // ---- morph targets: deltas target-major, default weights
        const targets = Array.isArray(aprim.targets) ? aprim.targets : [];
        /** @type {number} morph targets of the anchor primitive */
        this.targetCount = targets.length;
        /** @type {boolean} */
        this.morphed = targets.length > 0;
        /** (T·3V) POSITION deltas; a target without POSITION moves nothing */
        this.deltas = new Float64Array(targets.length * 3 * V);
        targets.forEach((/** @type {any} */ target, /** @type {number} */ k) => {
            if (typeof target !== 'object' || target === null) throw fail(MORPH, `${where}.targets[${k}] must be an object`);
            if (target.POSITION === undefined) return;
            const what = `${where}.targets[${k}].POSITION`;
            const raw = doc.raw(target.POSITION, what, ['VEC3'], MORPH);
            if (raw.count !== V) throw fail(MORPH, `${what} has ${raw.count} deltas but the anchor mesh has ${V} vertices`);
            const d = dequantize(raw);
            requireFinite(d, what);
            this.deltas.set(d, k * 3 * V);
        });
        const nodeW = defaultWeights(node, `nodes[${anchorNode}]`, targets.length);
        const meshW = defaultWeights(mesh, `meshes[${anchor.mesh}]`, targets.length);
        this.defaultWeights = Float64Array.from(nodeW || meshW || new Array(targets.length).fill(0));
        this.weights = new Float64Array(targets.length);
        this.activeTargets = new Int32Array(targets.length);

        // ---- skin: joints, inverse bind matrices, per-vertex influences
        /** @type {boolean} */
        this.skinned = node.skin !== undefined && node.skin !== null;
        /** @type {number[]} node of each joint */
        let joints = [];
        this.ibm = new Float64Array(0);
        this.offsets = new Uint32Array(V + 1);
        this.influenceJoint = new Uint32Array(0);
        this.influenceWeight = new Float64Array(0);
        if (this.skinned) {
            const skins = Array.isArray(json.skins) ? json.skins : [];
            const s = node.skin;
            if (!isIndex(s) || s >= skins.length || typeof skins[s] !== 'object' || skins[s] === null) {
                throw fail(SKIN, `nodes[${anchorNode}].skin ${JSON.stringify(s)} does not index a skin (${skins.length} skins)`);
            }
            const skin = skins[s];
            joints = skin.joints;
            if (!Array.isArray(joints) || !joints.length || !joints.every((j) => isIndex(j) && j < nodes.length)) {
                throw fail(SKIN, `skins[${s}].joints must be a non-empty list of existing nodes (${nodes.length} nodes)`);
            }
            const J = joints.length;
            this.ibm = new Float64Array(16 * J);
            if (skin.inverseBindMatrices === undefined) {
                for (let j = 0; j < J; ++j) for (let c = 0; c < 4; ++c) this.ibm[16 * j + 5 * c] = 1;
            } else {
                const what = `skins[${s}].inverseBindMatrices`;
                const m = doc.matrices(skin.inverseBindMatrices, what, SKIN);
                if (m.count !== J) throw fail(SKIN, `${what} holds ${m.count} matrices for ${J} joints`);
                requireFinite(m.values, what);
                this.ibm = m.values;
            }
            this.readInfluences(doc, aprim.attributes || {}, where, J);
        }
        /** @type {number} joints of the skin (0 without one) */
        this.jointCount = joints.length;

        // ---- the nodes whose global transform is needed: joints, the splat node, ancestors
        const parent = nodeParents(json);
        /** @type {number|null} the node instantiating the splat mesh, when it places a skinned mesh */
        this.splatNode = this.skinned && prim.node !== null && prim.node !== undefined ? prim.node : null;
        const seeds = this.splatNode === null ? joints : [...joints, this.splatNode];
        const slotOf = new Int32Array(nodes.length).fill(-1);
        /** @type {number[]} */
        const order = [];   // parents before children
        /** @type {number[]} */
        const chain = [];
        for (const seed of seeds) {
            chain.length = 0;
            for (let j = seed; j >= 0 && slotOf[j] < 0; j = parent[j]) {
                if (chain.length >= nodes.length) throw fail('NODE_GRAPH_INVALID', `the node hierarchy has a cycle through node ${seed}`);
                chain.push(j);
            }
            for (let k = chain.length - 1; k >= 0; --k) {
                slotOf[chain[k]] = order.length;
                order.push(chain[k]);
            }
        }
        const R = order.length;
        this.slotOf = slotOf;
        this.slotNode = Int32Array.from(order);
        this.parentSlot = Int32Array.from(order, (n) => (parent[n] < 0 ? -1 : slotOf[parent[n]]));
        this.jointSlot = Int32Array.from(joints, (n) => slotOf[n]);
        this.splatSlot = this.splatNode === null ? -1 : slotOf[this.splatNode];
        /** 1 for a node with `matrix` (fixed local matrix, not animated) */
        this.fixed = new Uint8Array(R);
        this.fixedLocal = new Float64Array(16 * R);
        this.restT = new Float64Array(3 * R);
        this.restR = new Float64Array(4 * R);
        this.restS = new Float64Array(3 * R);
        order.forEach((n, k) => {
            const nd = nodes[n];
            if (typeof nd !== 'object' || nd === null) throw fail('GLTF_SCHEMA_VIOLATION', `nodes[${n}] must be an object`);
            if (nd.matrix !== undefined) {
                this.fixed[k] = 1;
                this.fixedLocal.set(nodeVector(nd, 'matrix', new Array(16).fill(0), n), 16 * k);
            }
            this.restT.set(nodeVector(nd, 'translation', [0, 0, 0], n), 3 * k);
            this.restR.set(nodeVector(nd, 'rotation', [0, 0, 0, 1], n), 4 * k);
            this.restS.set(nodeVector(nd, 'scale', [1, 1, 1], n), 3 * k);
            normalizeQuaternion(this.restR, 4 * k);
        });
        this.curT = new Float64Array(3 * R);
        this.curR = new Float64Array(4 * R);
        this.curS = new Float64Array(3 * R);
        this.globals = new Float64Array(16 * R);
        this.local = new Float64Array(16);
        this.jointTmp = new Float64Array(16);
        /** (12J) rows 0..2 of G(joint_j) · IBM_j, column by column */
        this.jointMatrices = new Float64Array(12 * joints.length);
        this.splatInverse = new Float64Array(16);

        // ---- animations
        /** @type {AnimationInfo[]} */
        this.animations = [];
        /** @type {Channel[][]} the channels of each animation that move this anchor mesh */
        this.channels = [];
        this.readAnimations(doc, json, nodes.length);
    }

    /**
     * JOINTS_n/WEIGHTS_n sets (n = 0, 1, … while both are present) as per-vertex lists of
     * (joint, weight) with non-zero weight, set by set.
     * @param {GltfDocument} doc
     * @param {any} attrs
     * @param {string} where
     * @param {number} J
     */
    readInfluences(doc, attrs, where, J) {
        const V = this.vertexCount;
        /** @type {{joints: Float64Array, weights: Float64Array}[]} */
        const sets = [];
        for (let n = 0; `JOINTS_${n}` in attrs && `WEIGHTS_${n}` in attrs; ++n) {
            const jw = `${where} JOINTS_${n}`;
            const ww = `${where} WEIGHTS_${n}`;
            const jraw = doc.raw(attrs[`JOINTS_${n}`], jw, ['VEC4'], SKIN_ATTRIBUTES);
            const wraw = doc.raw(attrs[`WEIGHTS_${n}`], ww, ['VEC4'], SKIN_ATTRIBUTES);
            if (!(jraw.componentType === UNSIGNED_BYTE || jraw.componentType === UNSIGNED_SHORT) || jraw.normalized) {
                throw fail(SKIN_ATTRIBUTES, `${jw} (accessor ${jraw.index}) must be UNSIGNED_BYTE or UNSIGNED_SHORT, not normalized`);
            }
            if (!(wraw.componentType === FLOAT ? !wraw.normalized : wraw.normalized && (wraw.componentType === UNSIGNED_BYTE || wraw.componentType === UNSIGNED_SHORT))) {
                throw fail(SKIN_ATTRIBUTES, `${ww} (accessor ${wraw.index}) must be FLOAT, or UNSIGNED_BYTE or UNSIGNED_SHORT normalized`);
            }
            for (const [raw, what] of /** @type {[RawAccessor, string][]} */ ([[jraw, jw], [wraw, ww]])) {
                if (raw.count !== V) throw fail(SKIN_ATTRIBUTES, `${what} has ${raw.count} elements but POSITION has ${V}`);
            }
            const joints = dequantize(jraw);
            for (let i = 0; i < joints.length; ++i) {
                if (joints[i] >= J) throw fail(SKIN_ATTRIBUTES, `${jw} of vertex ${Math.floor(i / 4)} refers to joint ${joints[i]} of a skin with ${J} joints`);
            }
            const weights = dequantize(wraw);
            requireFinite(weights, ww);
            sets.push({ joints, weights });
        }
        if (!sets.length) throw fail(SKIN_ATTRIBUTES, `${where} is skinned but has no JOINTS_0/WEIGHTS_0 pair`);
        // Each vertex's weights normalized (spec/README.md §Animated anchor meshes, as three.js's
        // SkinnedMesh.normalizeSkinWeights): divided by their sum over every set; all zero:
        // weight 1 on the first influence (JOINTS_0 component 0).
        const sums = new Float64Array(V);
        let count = 0;
        for (const { weights } of sets) {
            for (let i = 0; i < weights.length; ++i) {
                sums[Math.floor(i / 4)] += weights[i];
                if (weights[i] !== 0) ++count;
            }
        }
        for (let v = 0; v < V; ++v) if (!(sums[v] > 0)) ++count;
        this.influenceJoint = new Uint32Array(count);
        this.influenceWeight = new Float64Array(count);
        let e = 0;
        const raw = this.fault === 'raw-weights';
        for (let v = 0; v < V; ++v) {
            this.offsets[v] = e;
            if (!(sums[v] > 0)) {
                if (raw) continue;
                this.influenceJoint[e] = sets[0].joints[4 * v];
                this.influenceWeight[e++] = 1;
                continue;
            }
            for (const { joints, weights } of sets) {
                for (let c = 4 * v; c < 4 * v + 4; ++c) {
                    if (weights[c] === 0) continue;
                    this.influenceJoint[e] = joints[c];
                    this.influenceWeight[e++] = raw ? weights[c] : weights[c] / sums[v];
                }
            }
        }
        this.offsets[V] = e;
    }

    /**
     * Every animation: its duration (all samplers' key times are read and checked) and the
     * channels that move this mesh (their outputs are read and checked).
     * @param {GltfDocument} doc
     * @param {any} json
     * @param {number} nodeCount
     */
    readAnimations(doc, json, nodeCount) {
        if (json.animations !== undefined && !Array.isArray(json.animations)) throw fail('GLTF_SCHEMA_VIOLATION', 'animations must be an array');
        const anims = json.animations || [];
        /** @type {Map<number, Float64Array>} key times by accessor */
        const inputs = new Map();
        /** @param {unknown} index @param {string} what @returns {Float64Array} */
        const keyTimes = (index, what) => {
            const done = inputs.get(/** @type {number} */ (index));
            if (done) return done;
            const times = dequantize(doc.raw(index, what, ['SCALAR'], SAMPLER));
            if (!times.length) throw fail(SAMPLER, `${what} has no key times`);
            requireFinite(times, what);
            for (let k = 1; k < times.length; ++k) {
                if (times[k] < times[k - 1]) throw fail(SAMPLER, `${what}: key time ${k} (${times[k]} s) is before key time ${k - 1} (${times[k - 1]} s); key times must increase`);
            }
            inputs.set(/** @type {number} */ (index), times);
            return times;
        };
        anims.forEach((/** @type {any} */ anim, /** @type {number} */ a) => {
            const w = `animations[${a}]`;
            if (typeof anim !== 'object' || anim === null) throw fail('GLTF_SCHEMA_VIOLATION', `${w} must be an object`);
            const samplers = anim.samplers === undefined ? [] : anim.samplers;
            const channels = anim.channels === undefined ? [] : anim.channels;
            if (!Array.isArray(samplers) || !Array.isArray(channels)) throw fail('GLTF_SCHEMA_VIOLATION', `${w}.samplers and ${w}.channels must be arrays`);
            let duration = 0;
            /** @type {{times: Float64Array, mode: number}[]} */
            const keyed = samplers.map((/** @type {any} */ s, /** @type {number} */ k) => {
                const sw = `${w}.samplers[${k}]`;
                if (typeof s !== 'object' || s === null) throw fail('GLTF_SCHEMA_VIOLATION', `${sw} must be an object`);
                const name = s.interpolation === undefined ? 'LINEAR' : s.interpolation;
                if (!Object.prototype.hasOwnProperty.call(INTERPOLATIONS, name)) {
                    throw fail(SAMPLER, `${sw}.interpolation ${JSON.stringify(name)} is not one of ${Object.keys(INTERPOLATIONS).join(', ')}`);
                }
                const times = keyTimes(s.input, `${sw}.input`);
                duration = Math.max(duration, times[times.length - 1]);
                return { times, mode: INTERPOLATIONS[name] };
            });
            /** @type {Channel[]} */
            const used = [];
            channels.forEach((/** @type {any} */ ch, /** @type {number} */ c) => {
                const cw = `${w}.channels[${c}]`;
                if (typeof ch !== 'object' || ch === null) throw fail('GLTF_SCHEMA_VIOLATION', `${cw} must be an object`);
                if (!isIndex(ch.sampler) || ch.sampler >= samplers.length) {
                    throw fail('UNRESOLVED_REFERENCE', `${cw}.sampler ${JSON.stringify(ch.sampler)} does not index a sampler of the animation (${samplers.length} samplers)`);
                }
                const target = ch.target;
                if (typeof target !== 'object' || target === null || target.node === undefined) return;   // other extensions' targets
                const n = target.node;
                if (!isIndex(n) || n >= nodeCount) throw fail(TARGET, `${cw} targets node ${JSON.stringify(n)}, which does not exist (${nodeCount} nodes)`);
                if (!Object.prototype.hasOwnProperty.call(PATHS, target.path)) return;   // e.g. KHR_animation_pointer's 'pointer'
                const path = PATHS[target.path];
                if (path === WEIGHTS && n === this.node && !this.morphed) {
                    throw fail(TARGET, `${cw} animates the morph weights of the anchor node ${n}, whose mesh has no morph targets`);
                }
                const slot = this.slotOf[n];
                const moves = path === WEIGHTS ? n === this.node : slot >= 0 && !this.fixed[slot];
                if (!moves) return;
                const { times, mode } = keyed[ch.sampler];
                const width = path === WEIGHTS ? this.targetCount : path === ROTATION ? 4 : 3;
                const ow = `${w}.samplers[${ch.sampler}].output`;
                const raw = doc.raw(samplers[ch.sampler].output, ow, [path === WEIGHTS ? 'SCALAR' : width === 4 ? 'VEC4' : 'VEC3'], SAMPLER);
                const keys = (mode === INTERPOLATIONS.CUBICSPLINE ? 3 : 1) * times.length;
                if (raw.count !== keys * (path === WEIGHTS ? width : 1)) {
                    throw fail(SAMPLER, path === WEIGHTS
                        ? `${ow} has ${raw.count} values but ${keys} keys of ${width} morph weights need ${keys * width} (${target.path}, ${Object.keys(INTERPOLATIONS)[mode]})`
                        : `${ow} has ${raw.count} values but the input has ${times.length} key times (${target.path}, ${Object.keys(INTERPOLATIONS)[mode]} needs ${keys})`);
                }
                const values = dequantize(raw);
                requireFinite(values, ow);
                used.push({ times, values, width, mode, rotation: path === ROTATION, path, slot: path === WEIGHTS ? -1 : slot });
            });
            this.animations.push({ index: a, name: typeof anim.name === 'string' ? anim.name : `animation ${a}`, duration });
            this.channels.push(used);
        });
    }

    /**
     * The current anchor vertices at time `time` (s) of animation `animation` (an index into
     * `animations`), in the splat primitive's local space, file vertex order. Times outside
     * the keys clamp to the first or last key.
     * @param {number} animation
     * @param {number} time
     * @param {Float32Array} [out]  (3V) written and returned; nothing is allocated when given
     * @returns {Float32Array}
     */
    sample(animation, time, out) {
        if (!(Number.isInteger(animation) && animation >= 0 && animation < this.channels.length)) {
            throw new RangeError(`animation ${animation} does not exist; the asset has ${this.channels.length}`);
        }
        if (!Number.isFinite(time)) throw new RangeError(`time must be a finite number of seconds, got ${time}`);
        return this.pose(this.channels[animation], time, out);
    }

    /**
     * The anchor vertices with no animation applied (the nodes' own values, default morph
     * weights), in the splat primitive's local space. For the writer's layout (splat node at
     * the identity, inverse bind matrices of the rest skeleton) these are the stored POSITION.
     * @param {Float32Array} [out]  (3V)
     * @returns {Float32Array}
     */
    rest(out) {
        return this.pose([], 0, out);
    }

    /**
     * @param {Channel[]} channels
     * @param {number} t
     * @param {Float32Array} [out]
     * @returns {Float32Array}
     */
    pose(channels, t, out) {
        const V = this.vertexCount;
        if (out === undefined) out = new Float32Array(3 * V);
        else if (!(out instanceof Float32Array) || out.length !== 3 * V) throw new RangeError(`out must be a Float32Array of ${3 * V} numbers`);
        const { curT, curR, curS, weights } = this;
        curT.set(this.restT);
        curR.set(this.restR);
        curS.set(this.restS);
        weights.set(this.defaultWeights);
        for (let c = 0; c < channels.length; ++c) {
            const ch = channels[c];
            const dst = ch.path === TRANSLATION ? curT : ch.path === ROTATION ? curR : ch.path === SCALE ? curS : weights;
            sampleKeyframes(ch, t, dst, ch.path === WEIGHTS ? 0 : ch.width * ch.slot);
        }
        if (this.skinned) this.updateJoints();

        const base = this.base;
        const deltas = this.deltas;
        const active = this.activeTargets;
        let nActive = 0;
        for (let k = 0; k < weights.length; ++k) if (weights[k] !== 0) active[nActive++] = k;
        const skinned = this.skinned;
        const offsets = this.offsets;
        const ij = this.influenceJoint;
        const iw = this.influenceWeight;
        const J = this.jointMatrices;
        const M = this.splatInverse;
        // M⁻¹ = I (the writer's layout) changes nothing
        const placed = skinned && !isIdentity(M) && this.fault !== 'skip-inverse-node';
        for (let v = 0, p = 0; v < V; ++v, p += 3) {
            let x = base[p], y = base[p + 1], z = base[p + 2];
            for (let a = 0; a < nActive; ++a) {
                const k = active[a];
                const w = weights[k];
                const d = k * 3 * V + p;
                x += w * deltas[d];
                y += w * deltas[d + 1];
                z += w * deltas[d + 2];
            }
            if (skinned) {
                let sx = 0, sy = 0, sz = 0;
                for (let e = offsets[v], end = offsets[v + 1]; e < end; ++e) {
                    const m = 12 * ij[e];
                    const w = iw[e];
                    sx += w * (J[m] * x + J[m + 3] * y + J[m + 6] * z + J[m + 9]);
                    sy += w * (J[m + 1] * x + J[m + 4] * y + J[m + 7] * z + J[m + 10]);
                    sz += w * (J[m + 2] * x + J[m + 5] * y + J[m + 8] * z + J[m + 11]);
                }
                if (placed) {
                    x = M[0] * sx + M[4] * sy + M[8] * sz + M[12];
                    y = M[1] * sx + M[5] * sy + M[9] * sz + M[13];
                    z = M[2] * sx + M[6] * sy + M[10] * sz + M[14];
                } else {
                    x = sx; y = sy; z = sz;
                }
            }
            out[p] = x;
            out[p + 1] = y;
            out[p + 2] = z;
        }
        return out;
    }

    /** Global matrices of the needed nodes (parents first), joint matrices and M⁻¹. */
    updateJoints() {
        const G = this.globals;
        const L = this.local;
        const R = this.slotNode.length;
        for (let k = 0; k < R; ++k) {
            const src = this.fixed[k] ? this.fixedLocal : L;
            const so = this.fixed[k] ? 16 * k : 0;
            if (!this.fixed[k]) composeTrs(this.curT, this.curR, this.curS, k, L, 0);
            const ps = this.parentSlot[k];
            if (ps < 0) {
                for (let c = 0; c < 16; ++c) G[16 * k + c] = src[so + c];
            } else {
                multiplyInto(G, 16 * ps, src, so, G, 16 * k);
            }
        }
        const tmp = this.jointTmp;
        const JM = this.jointMatrices;
        for (let j = 0; j < this.jointSlot.length; ++j) {
            multiplyInto(G, 16 * this.jointSlot[j], this.ibm, 16 * j, tmp, 0);
            for (let c = 0; c < 4; ++c) {
                JM[12 * j + 3 * c] = tmp[4 * c];
                JM[12 * j + 3 * c + 1] = tmp[4 * c + 1];
                JM[12 * j + 3 * c + 2] = tmp[4 * c + 2];
            }
        }
        const Mi = this.splatInverse;
        if (this.splatSlot < 0) {
            Mi.fill(0);
            Mi[0] = Mi[5] = Mi[10] = Mi[15] = 1;
        } else if (!invertInto(G, 16 * this.splatSlot, Mi)) {
            throw fail(SPLAT_NODE_SINGULAR, `${this.name}: the global matrix of the splat node ${this.splatNode} is singular or not finite at this time; the skinned anchor vertices have no splat-local position`);
        }
    }
}

/**
 * The animation of the anchor mesh of anchored primitive `prim` (from readAnchoredGlb of the
 * same file): null when nothing deforms it (no node instantiates it, or it has neither a skin
 * nor morph targets). Everything per asset is read and checked here; malformed skin, morph
 * or animation data throws AnchorError (`.code` the gsverse-validate code, a one-line message
 * naming the file).
 * @param {Uint8Array|ArrayBuffer|GltfDocument} input  the file's bytes, or parseGltf of them
 * @param {AnchoredPrimitive} prim
 * @param {{name?: string, fault?: string|null}} [options]  name: the file name used in
 *   messages; fault: one of ANIMATION_FAULTS (testing only)
 * @returns {AnchorAnimation|null}
 */
export function readAnchorAnimation(input, prim, options = {}) {
    const name = options.name || 'asset';
    try {
        const doc = input instanceof GltfDocument ? input : parseGltf(input);
        const anchor = prim.anchorMesh;
        if (anchor.node === null || anchor.node === undefined) return null;
        const node = doc.item('nodes', anchor.node, 'the anchor node');
        const prims = doc.item('meshes', anchor.mesh, 'the anchor mesh').primitives;
        const aprim = Array.isArray(prims) ? prims[anchor.primitive] : undefined;
        if (typeof aprim !== 'object' || aprim === null) {
            throw new GltfError('UNRESOLVED_REFERENCE', `the anchor mesh meshes[${anchor.mesh}] has no primitive ${anchor.primitive}`);
        }
        const skinned = node.skin !== undefined && node.skin !== null;
        if (!skinned && !(Array.isArray(aprim.targets) && aprim.targets.length)) return null;
        return new AnchorAnimation(doc, prim, name, options.fault ?? null);
    } catch (err) {
        if (err instanceof AnchorError || err instanceof GltfError) throw new AnchorError(err.code, `${name}: ${err.message}`);
        throw err;
    }
}
