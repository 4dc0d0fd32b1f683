// glTF-Transform support for GSVERSE_gaussian_splatting_mesh_anchor (spec/README.md), nested in
// a splat primitive's KHR_gaussian_splatting object. The MeshAnchor property holds references to
// the anchor accessors and to the anchor Mesh, so dedup and prune keep and renumber them and the
// anchor mesh (which no node instantiates) survives prune.
//
// Transforms that rewrite vertex data know nothing of the anchoring. What they may break is
// checked when writing: the anchor mesh's vertex positions and triangles, and the splat
// primitive's positions, rotations and scales, must be exactly what was read; every per-splat
// anchor accessor must have one element per splat, every faceIndex must name a triangle, and
// faceCounts (extension 1.2) must hold one count per triangle adding up to the splat count.
// Derived `local` anchors (1.2: no barycentrics) are computed from the rest pose and the anchor
// mesh, which the first check keeps as read. Otherwise write() throws an MeshAnchorError with a
// one-line message and nothing is written.

import { Extension, ExtensionProperty, MathUtils, PropertyType } from '@gltf-transform/core';
import { GSVERSE_MESH_ANCHOR, KHR_GAUSSIAN_SPLATTING } from './khr-gaussian-splatting.js';

/** @typedef {import('@gltf-transform/core').Accessor} Accessor */
/** @typedef {import('@gltf-transform/core').Mesh} Mesh */
/** @typedef {import('@gltf-transform/core').Primitive} Primitive */
/** @typedef {import('@gltf-transform/core').Property} Property */
/** @typedef {import('@gltf-transform/core').ReaderContext} ReaderContext */
/** @typedef {import('@gltf-transform/core').WriterContext} WriterContext */
/** @typedef {import('@gltf-transform/core').PropertyResolver<Property>} PropertyResolver */

const POINTS = 0;
const TRIANGLES = 4;
const FLOAT = 5126;
/** Buffer view grouping of the anchor accessors: no target (spec: SHOULD NOT set target). */
const USAGE = { usage: 'OTHER' };
/** Compression extensions whose output GS-Verse readers refuse (and Draco re-orders points and vertices). */
const COMPRESSION = ['KHR_draco_mesh_compression', 'EXT_meshopt_compression', 'KHR_meshopt_compression'];

/** @typedef {'faceIndex' | 'faceCounts' | 'barycentrics' | 'normalOffset' | 'localRotation' | 'localScale' | 'rho'} AnchorAccessorKey */

/**
 * The per-splat anchor accessors of each profile besides the face (faceIndex, or faceCounts
 * per triangle), with their accessor type. `local` anchors without barycentrics are derived
 * (extension 1.2): then none of these is present.
 */
export const PROFILE_ACCESSORS = /** @type {const} */ ({
    local: [['barycentrics', 'VEC2'], ['normalOffset', 'SCALAR'], ['localRotation', 'VEC4'], ['localScale', 'VEC3']],
    games: [['barycentrics', 'VEC2'], ['rho', 'SCALAR']],
});
/** @type {AnchorAccessorKey[]} */
const ACCESSOR_KEYS = ['faceIndex', 'faceCounts', 'barycentrics', 'normalOffset', 'localRotation', 'localScale', 'rho'];
/** The rest-pose attributes of the splat primitive whose values the anchoring depends on. */
const SPLAT_ATTRIBUTES = ['POSITION', 'KHR_gaussian_splatting:ROTATION', 'KHR_gaussian_splatting:SCALE'];

/** An anchored asset that cannot be read or written consistently; `message` is one line. */
export class MeshAnchorError extends Error {
    /** @param {string} message */
    constructor(message) {
        super(message);
        this.name = 'MeshAnchorError';
    }
}

/**
 * What the anchoring depends on, as read: compared when writing.
 * @typedef {Object} ReadState
 * @property {Float32Array} anchorPositions anchor vertex positions
 * @property {Uint32Array | null} anchorIndices anchor indices (null: not indexed)
 * @property {number} anchorMode
 * @property {Map<string, Float32Array>} splat the SPLAT_ATTRIBUTES of the splat primitive (dequantized)
 * @property {boolean} splatIndexed
 */

/**
 * @typedef {Object} IMeshAnchor
 * @property {string} name
 * @property {Record<string, unknown>} extras
 * @property {Mesh} mesh
 * @property {number} primitive
 * @property {string} profile
 * @property {string | null} deformation
 * @property {Accessor} faceIndex
 * @property {Accessor} faceCounts
 * @property {Accessor} barycentrics
 * @property {Accessor} normalOffset
 * @property {Accessor} localRotation
 * @property {Accessor} localScale
 * @property {Accessor} rho
 */

/**
 * The `GSVERSE_gaussian_splatting_mesh_anchor` object of one anchored splat primitive: the anchor
 * mesh (a reference, so that prune keeps it), the anchor primitive's index in it, the profile
 * and the per-splat anchor accessors.
 * @extends {ExtensionProperty<IMeshAnchor>}
 */
export class MeshAnchor extends ExtensionProperty {
    static EXTENSION_NAME = GSVERSE_MESH_ANCHOR;

    /** @returns {typeof GSVERSE_MESH_ANCHOR} */
    get extensionName() { return GSVERSE_MESH_ANCHOR; }
    /** @returns {'MeshAnchor'} */
    get propertyType() { return 'MeshAnchor'; }
    // the precise types below keep these members in the generated declarations (types/), where
    // ExtensionProperty's abstract members must be implemented
    /** @returns {['Primitive']} */
    get parentTypes() { return [PropertyType.PRIMITIVE]; }

    /**
     * @protected
     * @returns {undefined}
     */
    init() {
        /** @type {ReadState | null} what was read (null for an anchor made with the API) */
        this.readState = null;
    }

    /**
     * @protected
     * @returns {import('@gltf-transform/core').Nullable<IMeshAnchor>}
     */
    getDefaults() {
        return Object.assign(super.getDefaults(), {
            mesh: null, primitive: 0, profile: 'local', deformation: null,
            faceIndex: null, faceCounts: null, barycentrics: null, normalOffset: null, localRotation: null, localScale: null, rho: null,
        });
    }

    /**
     * @param {this} other
     * @param {PropertyResolver} [resolve]
     * @returns {this}
     */
    copy(other, resolve) {
        super.copy(other, resolve);
        this.readState = other.readState;
        return this;
    }

    /** The mesh holding the anchor triangles. @returns {Mesh | null} */
    getMesh() { return this.getRef('mesh'); }
    /** @param {Mesh | null} mesh */
    setMesh(mesh) { return this.setRef('mesh', mesh); }
    /** Index of the anchor primitive in the anchor mesh. @returns {number} */
    getPrimitive() { return this.get('primitive'); }
    /** @param {number} index */
    setPrimitive(index) { return this.set('primitive', index); }
    /** The anchor primitive, or null. @returns {Primitive | null} */
    getAnchorPrimitive() { return this.getMesh()?.listPrimitives()[this.getPrimitive()] ?? null; }
    /** `"local"` or `"games"`. @returns {string} */
    getProfile() { return this.get('profile'); }
    /** @param {string} profile */
    setProfile(profile) { return this.set('profile', profile); }
    /** `"affine"`, `"rigid"`, or null (absent: affine for `local`). @returns {string | null} */
    getDeformation() { return this.get('deformation'); }
    /** @param {string | null} deformation */
    setDeformation(deformation) { return this.set('deformation', deformation); }

    /**
     * An anchor accessor.
     * @param {AnchorAccessorKey} key
     * @returns {Accessor | null}
     */
    getAccessor(key) { return this.getRef(key); }
    /**
     * @param {AnchorAccessorKey} key
     * @param {Accessor | null} accessor
     */
    setAccessor(key, accessor) { return this.setRef(key, accessor, USAGE); }
    /** The anchor accessors that are set. @returns {Accessor[]} */
    listAccessors() {
        return ACCESSOR_KEYS.map((key) => this.getRef(key)).filter((a) => a !== null);
    }
}

/**
 * [`GSVERSE_gaussian_splatting_mesh_anchor`](../../spec/README.md) for glTF-Transform: keeps
 * mesh-anchored splats anchored through read, transform and write, and refuses to write an
 * asset a transform made inconsistent (see the module comment). Register it together with
 * {@link KHRGaussianSplatting}.
 */
export class GSVERSEMeshAnchor extends Extension {
    static EXTENSION_NAME = GSVERSE_MESH_ANCHOR;
    extensionName = GSVERSE_MESH_ANCHOR;
    /** @type {import('@gltf-transform/core').PropertyType[]} */
    prewriteTypes = [PropertyType.ACCESSOR];

    /** Creates an anchor object for a splat {@link Primitive} (set it on the primitive's extensions). */
    createMeshAnchor() {
        return new MeshAnchor(this.document.getGraph());
    }

    /**
     * @param {ReaderContext} context
     * @returns {this}
     */
    read(context) {
        const json = context.jsonDoc.json;
        (json.meshes || []).forEach((meshDef, m) => {
            (meshDef.primitives || []).forEach((primDef, p) => {
                const khr = /** @type {Record<string, any> | undefined} */ (primDef.extensions?.[KHR_GAUSSIAN_SPLATTING]);
                const def = /** @type {Record<string, any> | undefined} */ (khr?.extensions?.[GSVERSE_MESH_ANCHOR]);
                if (!def || typeof def !== 'object') return;
                const where = `${GSVERSE_MESH_ANCHOR}: meshes[${m}].primitives[${p}]`;
                const anchor = this.createMeshAnchor();
                const mesh = Number.isInteger(def.mesh) ? context.meshes[def.mesh] : undefined;
                if (!mesh) throw new MeshAnchorError(`${where}: mesh ${JSON.stringify(def.mesh)} does not exist`);
                anchor.setMesh(mesh)
                    .setPrimitive(def.primitive === undefined ? 0 : def.primitive)
                    .setProfile(def.profile)
                    .setDeformation(def.deformation === undefined ? null : def.deformation);
                for (const key of ACCESSOR_KEYS) {
                    if (def[key] === undefined) continue;
                    const accessor = Number.isInteger(def[key]) ? context.accessors[def[key]] : undefined;
                    if (!accessor) throw new MeshAnchorError(`${where}: ${key} accessor ${JSON.stringify(def[key])} does not exist`);
                    anchor.setAccessor(key, accessor);
                }
                if (def.extras && typeof def.extras === 'object') anchor.setExtras(def.extras);
                const prim = context.meshes[m].listPrimitives()[p];
                prim.setExtension(GSVERSE_MESH_ANCHOR, anchor);
                anchor.readState = readState(anchor, prim);
            });
        });
        return this;
    }

    /**
     * Anchor accessors are never written sparse (spec: MUST NOT be sparse).
     * @param {WriterContext} _context
     * @returns {this}
     */
    prewrite(_context) {
        for (const prop of this.properties) {
            if (!(prop instanceof MeshAnchor)) continue;
            for (const accessor of prop.listAccessors()) accessor.setSparse(false);
        }
        return this;
    }

    /**
     * @param {WriterContext} context
     * @returns {this}
     */
    write(context) {
        const root = this.document.getRoot();
        const meshDefs = context.jsonDoc.json.meshes || [];
        const registered = new Set(context.options.extensions.map((ext) => ext.EXTENSION_NAME));
        /** @type {Set<MeshAnchor>} */
        const written = new Set();
        for (const mesh of root.listMeshes()) {
            const meshIndex = context.meshIndexMap.get(mesh);
            if (meshIndex === undefined) continue;
            mesh.listPrimitives().forEach((prim, p) => {
                const anchor = prim.getExtension(GSVERSE_MESH_ANCHOR);
                if (!(anchor instanceof MeshAnchor)) return;
                const name = mesh.getName() ? ` ("${mesh.getName()}")` : '';
                const refuse = (/** @type {string} */ why) => new MeshAnchorError(
                    `${GSVERSE_MESH_ANCHOR}: refusing to write meshes[${meshIndex}].primitives[${p}]${name}: ${why}`);
                if (!registered.has(KHR_GAUSSIAN_SPLATTING)) {
                    throw refuse(`${KHR_GAUSSIAN_SPLATTING} is not registered for writing (register both gsverseExtensions)`);
                }
                const def = checkAnchor(anchor, prim, context, refuse);
                const compression = root.listExtensionsUsed().map((ext) => ext.extensionName)
                    .find((extName) => COMPRESSION.includes(extName) && registered.has(extName));
                if (compression) {
                    throw refuse(`${compression} is enabled; GS-Verse readers do not decode compressed geometry `
                        + '(and Draco re-orders points and vertices); write without compression');
                }
                const primDef = meshDefs[meshIndex].primitives[p];
                primDef.extensions = primDef.extensions || {};
                const khr = /** @type {Record<string, any>} */ (primDef.extensions[KHR_GAUSSIAN_SPLATTING] ||= {});
                khr.extensions = khr.extensions || {};
                khr.extensions[GSVERSE_MESH_ANCHOR] = def;
                written.add(anchor);
            });
        }
        for (const prop of this.properties) {
            if (prop instanceof MeshAnchor && prop.readState && !written.has(prop)) {
                throw new MeshAnchorError(`${GSVERSE_MESH_ANCHOR}: refusing to write: an anchored splat primitive `
                    + 'read from the input is no longer in the output (a transform such as join, simplify or prune '
                    + 'replaced or removed it); its splats would lose their anchoring. Dispose its MeshAnchor to drop it on purpose');
            }
        }
        return this;
    }
}

/**
 * The values of an accessor as float32 (normalized integers dequantized).
 * @param {Accessor} accessor
 * @returns {Float32Array}
 */
function values(accessor) {
    const array = accessor.getArray();
    if (!array) return new Float32Array(0);
    if (array instanceof Float32Array) return array.slice();
    const out = new Float32Array(array.length);
    const type = accessor.getComponentType();
    const normalized = accessor.getNormalized();
    for (let i = 0; i < array.length; ++i) out[i] = normalized ? MathUtils.decodeNormalizedInt(array[i], type) : array[i];
    return out;
}

/**
 * @param {Accessor | null} indices
 * @returns {Uint32Array | null}
 */
function indexValues(indices) {
    const array = indices?.getArray();
    return array ? Uint32Array.from(array) : null;
}

/**
 * @param {MeshAnchor} anchor
 * @param {Primitive} prim the splat primitive
 * @returns {ReadState | null}
 */
function readState(anchor, prim) {
    const anchorPrim = anchor.getAnchorPrimitive();
    const position = anchorPrim?.getAttribute('POSITION');
    if (!anchorPrim || !position) return null; // an invalid input: write() refuses it
    /** @type {Map<string, Float32Array>} */
    const splat = new Map();
    for (const semantic of SPLAT_ATTRIBUTES) {
        const accessor = prim.getAttribute(semantic);
        // a placeholder without data (an SPZ-compressed rest pose): spz-compression.js checks it
        if (accessor && accessor.getArray()) splat.set(semantic, values(accessor));
    }
    return {
        anchorPositions: values(position), anchorIndices: indexValues(anchorPrim.getIndices()),
        anchorMode: anchorPrim.getMode(), splat, splatIndexed: prim.getIndices() !== null,
    };
}

/**
 * Where two arrays first differ ("642 → 600 vertices", "vertex 3"), or null when they are equal.
 * @param {ArrayLike<number>} before
 * @param {ArrayLike<number>} after
 * @param {number} size values per item
 * @param {string} item what an item is, e.g. "vertex"
 * @returns {string | null}
 */
function difference(before, after, size, item) {
    if (before.length !== after.length) {
        return `${before.length / size} → ${after.length / size} ${item === 'vertex' ? 'vertices' : `${item}s`}`;
    }
    for (let i = 0; i < before.length; ++i) {
        if (before[i] !== after[i] && !(Number.isNaN(before[i]) && Number.isNaN(after[i]))) {
            return `${item} ${Math.floor(i / size)} differs`;
        }
    }
    return null;
}

/**
 * Checks one anchored primitive before writing; returns its extension object (JSON).
 * @param {MeshAnchor} anchor
 * @param {Primitive} prim the splat primitive
 * @param {WriterContext} context
 * @param {(why: string) => MeshAnchorError} refuse
 * @returns {Record<string, unknown>}
 */
function checkAnchor(anchor, prim, context, refuse) {
    const profile = anchor.getProfile();
    if (profile !== 'local' && profile !== 'games') throw refuse(`unknown profile ${JSON.stringify(profile)}`);
    const deformation = anchor.getDeformation();
    if (profile === 'games' ? deformation !== null : deformation !== null && deformation !== 'affine' && deformation !== 'rigid') {
        throw refuse(`deformation ${JSON.stringify(deformation)} is not allowed with profile "${profile}"`);
    }

    // The anchor mesh: present, unchanged since it was read, the triangles every faceIndex names.
    const mesh = anchor.getMesh();
    const meshIndex = mesh ? context.meshIndexMap.get(mesh) : undefined;
    if (!mesh || meshIndex === undefined) throw refuse('the anchor mesh was removed by a transform');
    const anchorPrim = anchor.getAnchorPrimitive();
    if (!anchorPrim) throw refuse(`the anchor mesh has no primitive ${anchor.getPrimitive()} (a transform removed or joined primitives)`);
    const position = anchorPrim.getAttribute('POSITION');
    if (anchorPrim.getMode() !== TRIANGLES || !position) throw refuse('the anchor primitive is no longer a TRIANGLES primitive with POSITION');
    const state = anchor.readState;
    const changed = 'a transform (weld, quantize, reorder, simplify, meshopt, ...) rewrote the anchor mesh; '
        + 'splats would follow other vertices and faceIndex would name other triangles. Leave the anchor mesh as it is';
    if (state) {
        const moved = difference(state.anchorPositions, values(position), 3, 'vertex');
        if (moved) throw refuse(`the anchor mesh's vertex positions changed (${moved}): ${changed}`);
        const indices = indexValues(anchorPrim.getIndices());
        if ((state.anchorIndices === null) !== (indices === null)) {
            throw refuse(`the anchor mesh was ${indices ? 'indexed' : 'de-indexed'}: ${changed}`);
        }
        const renumbered = state.anchorIndices && indices && difference(state.anchorIndices, indices, 3, 'triangle');
        if (renumbered) throw refuse(`the anchor mesh's triangles changed (${renumbered}): ${changed}`);
    }
    if (position.getComponentType() !== FLOAT || position.getNormalized()) {
        throw refuse(`the anchor mesh's POSITION is no longer FLOAT: ${changed}`);
    }
    const instances = mesh.listParents().filter((p) => p.propertyType === PropertyType.NODE).length;
    if (instances > 1) throw refuse(`the anchor mesh is instantiated by ${instances} nodes (at most one is allowed)`);
    const indices = anchorPrim.getIndices();
    const faces = Math.floor((indices ? indices.getCount() : position.getCount()) / 3);

    // The splat primitive: the same splats, in the same order, one anchor element per splat.
    const splatPosition = prim.getAttribute('POSITION');
    if (prim.getMode() !== POINTS || !splatPosition) throw refuse('the splat primitive is no longer a POINTS primitive with POSITION');
    if (!prim.getExtension(KHR_GAUSSIAN_SPLATTING)) throw refuse(`the splat primitive has no ${KHR_GAUSSIAN_SPLATTING} object`);
    const n = splatPosition.getCount();
    /** @type {Record<string, unknown>} */
    const def = { mesh: meshIndex, primitive: anchor.getPrimitive(), profile };
    if (deformation !== null) def.deformation = deformation;
    /** @param {AnchorAccessorKey} key @param {string} type @param {number} count @param {string} per */
    const put = (key, type, count, per) => {
        const accessor = anchor.getAccessor(key);
        if (!accessor) throw refuse(`its ${key} accessor was removed by a transform`);
        if (accessor.getType() !== type) throw refuse(`its ${key} accessor is ${accessor.getType()}, not ${type}`);
        if (accessor.getCount() !== count) {
            throw refuse(`its ${key} accessor has ${accessor.getCount()} elements for ${count} ${per} `
                + '(a transform added, removed or merged splats or triangles; the anchors would belong to others)');
        }
        const index = context.accessorIndexMap.get(accessor);
        if (index === undefined) throw refuse(`its ${key} accessor was not written (no buffer)`);
        def[key] = index;
        return accessor;
    };
    const hasCounts = anchor.getAccessor('faceCounts') !== null;
    if (hasCounts && anchor.getAccessor('faceIndex')) throw refuse('it has both faceIndex and faceCounts (exactly one is allowed)');
    const face = hasCounts ? put('faceCounts', 'SCALAR', faces, 'triangles') : put('faceIndex', 'SCALAR', n, 'splats');
    const derived = profile === 'local' && anchor.getAccessor('barycentrics') === null;
    for (const [key, type] of PROFILE_ACCESSORS[profile]) {
        if (derived) {
            if (anchor.getAccessor(key)) throw refuse(`it has ${key} but no barycentrics (derived local anchors store neither)`);
        } else {
            put(key, type, n, 'splats');
        }
    }
    if (state) {
        if (!state.splatIndexed && prim.getIndices()) throw refuse('the splat primitive was indexed by a transform');
        for (const [semantic, before] of state.splat) {
            const accessor = prim.getAttribute(semantic);
            const size = accessor ? accessor.getElementSize() : 1;
            const moved = accessor ? difference(before, values(accessor), size, 'splat') : 'removed';
            if (moved) {
                throw refuse(`the splats' ${semantic} changed (${moved}): a transform (quantize, reorder, simplify, `
                    + '...) moved, re-ordered or dropped splats, which their anchors no longer describe');
            }
        }
    }
    const faceArray = face.getArray() || [];
    if (hasCounts) {
        // stops at the first overrun: the sum stays an exact integer in binary64
        let sum = 0;
        for (let f = 0; f < faceArray.length && sum <= n; ++f) sum += faceArray[f];
        if (sum !== n) throw refuse(`its faceCounts add up to ${sum > n ? `more than ${n}` : sum}, not the ${n} splats`);
    } else {
        for (let i = 0; i < faceArray.length; ++i) {
            if (!(faceArray[i] < faces)) throw refuse(`faceIndex[${i}] = ${faceArray[i]} but the anchor mesh has ${faces} triangles`);
        }
    }
    if (Object.keys(anchor.getExtras()).length) def.extras = anchor.getExtras();
    return def;
}
