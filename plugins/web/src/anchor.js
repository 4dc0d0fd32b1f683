// Reading GSVERSE_gaussian_splatting_mesh_anchor (spec/README.md, version 1.2): the anchored
// KHR_gaussian_splatting primitives of a GLB (or .gltf with data: URIs), their rest pose, their
// anchor mesh and anchors, dequantized, with every refusal of spec/conformance.md
// §What a plugin must implement (item 4). A refusal throws AnchorError with the
// gsverse-validate code. The compact encodings (`faceCounts`, derived `local` anchors) are
// expanded to per-splat anchors here (compact.js), so every consumer sees explicit anchors.

import {
    BYTE, COMPONENT_TYPES, FLOAT, GltfError, SHORT, UNSIGNED_BYTE, UNSIGNED_INT, UNSIGNED_SHORT,
    READ_AMPLIFICATION_SLACK, MAX_READ_AMPLIFICATION, declaredAccessorBytes, dequantize, globalMatrices, isIndex, parseGltf,
} from './glb.js';
import { deriveLocalAnchors, expandFaceCounts } from './compact.js';
import { EPS_DEGENERATE } from './rest.js';

/** @typedef {import('./types.js').AnchoredPrimitive} AnchoredPrimitive */
/** @typedef {import('./types.js').AnchoredGlb} AnchoredGlb */
/** @typedef {import('./types.js').RestPose} RestPose */
/** @typedef {import('./types.js').AnchorMesh} AnchorMesh */
/** @typedef {import('./glb.js').GltfDocument} GltfDocument */
/** @typedef {import('./glb.js').RawAccessor} RawAccessor */

export const KHR = 'KHR_gaussian_splatting';
export const EXTENSION = 'GSVERSE_gaussian_splatting_mesh_anchor';
/** The SPZ-compressed rest pose (spec §SPZ-compressed rest pose; decoded by spz.js). */
export const SPZ_EXTENSION = 'KHR_gaussian_splatting_compression_spz_2';
const POINTS = 0;
const TRIANGLES = 4;

/** An asset this reader refuses; `code` is the gsverse-validate code (spec/conformance.md). */
export class AnchorError extends Error {
    /**
     * @param {string} code
     * @param {string} message
     */
    constructor(code, message) {
        super(message);
        this.name = 'AnchorError';
        /** @type {string} */
        this.code = code;
    }
}

/**
 * (componentType, normalized) pairs allowed per anchor property and its accessor type
 * (spec/README.md §Accessor component types and dequantization).
 * @type {{[key: string]: {type: string, formats: [number, boolean][]}}}
 */
export const ANCHOR_ACCESSORS = {
    faceIndex: { type: 'SCALAR', formats: [[UNSIGNED_BYTE, false], [UNSIGNED_SHORT, false], [UNSIGNED_INT, false]] },
    faceCounts: { type: 'SCALAR', formats: [[UNSIGNED_BYTE, false], [UNSIGNED_SHORT, false], [UNSIGNED_INT, false]] },
    barycentrics: { type: 'VEC2', formats: [[FLOAT, false], [UNSIGNED_BYTE, true], [UNSIGNED_SHORT, true]] },
    normalOffset: { type: 'SCALAR', formats: [[FLOAT, false]] },
    localRotation: { type: 'VEC4', formats: [[FLOAT, false], [BYTE, true], [SHORT, true]] },
    localScale: {
        type: 'VEC3',
        formats: [[FLOAT, false], [UNSIGNED_BYTE, false], [UNSIGNED_BYTE, true], [UNSIGNED_SHORT, false], [UNSIGNED_SHORT, true]],
    },
    rho: { type: 'SCALAR', formats: [[FLOAT, false]] },
};

/** Per-splat anchor properties each profile requires besides the face (explicit anchors). */
/** @type {{[profile: string]: string[]}} */
const REQUIRED = {
    local: ['barycentrics', 'normalOffset', 'localRotation', 'localScale'],
    games: ['barycentrics', 'rho'],
};
/** `local` properties that are all absent together when the anchors are derived. */
const DERIVED = ['normalOffset', 'localRotation', 'localScale'];

// gsverse-validate codes of the compact encodings (spec/validation.md); both or neither of
// faceIndex and faceCounts, and derived anchors with some of normalOffset, localRotation,
// localScale, are schema violations (ANCHOR_SCHEMA_VIOLATION)
/** faceCounts count != the anchor primitive's triangle count */
const CODE_FACE_COUNTS_COUNT = 'ANCHOR_FACE_COUNTS_COUNT';
/** sum of faceCounts != POSITION count */
const CODE_FACE_COUNTS_SUM = 'ANCHOR_FACE_COUNTS_SUM';
/** a derived splat on a face degenerate at rest */
const CODE_DERIVED_DEGENERATE = 'ANCHOR_DERIVED_ON_DEGENERATE';

/** @param {RawAccessor} raw */
function formatName(raw) {
    return COMPONENT_TYPES[raw.componentType].name + (raw.normalized ? ' normalized' : '');
}

/** @param {ArrayLike<number>} values @returns {number} index of the first non-finite value, or -1 */
function firstNonFinite(values) {
    for (let i = 0; i < values.length; ++i) if (!Number.isFinite(values[i])) return i;
    return -1;
}

/**
 * @param {RawAccessor} raw
 * @param {string} what
 */
function requireFinite(raw, what) {
    if (raw.componentType !== FLOAT) return;
    const bad = firstNonFinite(raw.values);
    if (bad >= 0) {
        throw new AnchorError('NON_FINITE_VALUE', `${what} (accessor ${raw.index}) holds NaN or infinity (element ${Math.floor(bad / raw.ncomp)})`);
    }
}

/**
 * Normalize quaternions (x, y, z, w) in binary64 and store as float32. Zero ones become the
 * identity (callers refuse a zero localRotation before).
 * @param {Float64Array} q
 * @returns {Float32Array}
 */
function normalizeQuaternions(q) {
    const out = new Float32Array(q.length);
    for (let i = 0; i < q.length; i += 4) {
        const len = Math.sqrt(q[i] * q[i] + q[i + 1] * q[i + 1] + q[i + 2] * q[i + 2] + q[i + 3] * q[i + 3]);
        if (len > 0) {
            out[i] = q[i] / len; out[i + 1] = q[i + 1] / len; out[i + 2] = q[i + 2] / len; out[i + 3] = q[i + 3] / len;
        } else {
            out[i + 3] = 1;
        }
    }
    return out;
}

/** Highest complete SH degree of a KHR primitive's attributes (−1 when there is no SH).
 * @param {{[name: string]: unknown}} attrs
 * @param {string} where
 */
export function shDegree(attrs, where) {
    const re = new RegExp(`^${KHR}:SH_DEGREE_(\\d+)_COEF_(\\d+)$`);
    const present = new Set();
    for (const name of Object.keys(attrs)) {
        const m = re.exec(name);
        if (!m) continue;
        const degree = Number(m[1]);
        const coef = Number(m[2]);
        if (degree > 3) throw new AnchorError('KHR_UNKNOWN_SEMANTIC', `${where}: SH degree ${degree} is not supported (0..3)`);
        if (coef > 2 * degree) throw new AnchorError('KHR_UNKNOWN_SEMANTIC', `${where}: attribute ${name} does not exist in degree ${degree}`);
        present.add(`${degree}_${coef}`);
    }
    let degree = -1;
    for (let level = 0; level < 4; ++level) {
        let have = 0;
        for (let n = 0; n <= 2 * level; ++n) if (present.has(`${level}_${n}`)) ++have;
        if (have === 2 * level + 1) {
            if (degree !== level - 1) throw new AnchorError('KHR_SH_INCOMPLETE', `${where}: SH degree ${level} is present but degree ${level - 1} is missing`);
            degree = level;
        } else if (have) {
            throw new AnchorError('KHR_SH_INCOMPLETE', `${where}: SH degree ${level} is partially defined`);
        }
    }
    return degree;
}

/** @param {number} c linear in [0, 1] */
function linearToSrgb(c) {
    const v = Math.min(Math.max(c, 0), 1);
    return v <= 0.0031308 ? v * 12.92 : 1.055 * v ** (1 / 2.4) - 0.055;
}

/** The SH degree-0 basis constant Y_0^0: a colour is 0.5 + SH_C0 * DC. */
export const SH_C0 = 0.28209479177387814;

/**
 * The rest pose of a KHR splat primitive (its JSON object `prim`); also how an engine plugin
 * that builds its own splats reads the plain (unanchored) ones (src/three/).
 * @param {GltfDocument} doc
 * @param {any} prim
 * @param {string} where
 * @returns {{rest: RestPose, pose64: {means: Float64Array, rotations: Float64Array, scales: Float64Array},
 *   count: number, shDegree: number}}  pose64: POSITION, ROTATION (not normalized) and SCALE
 *   dequantized in binary64, for deriving anchors
 */
export function readRestPose(doc, prim, where) {
    const attrs = (prim.attributes && typeof prim.attributes === 'object') ? prim.attributes : {};
    const names = ['POSITION', `${KHR}:ROTATION`, `${KHR}:SCALE`, `${KHR}:OPACITY`];
    const missing = names.filter((n) => !(n in attrs));
    if (missing.length) throw new AnchorError('KHR_ATTRIBUTE_MISSING', `${where}: required ${KHR} attribute(s) missing: ${missing.join(', ')}`);
    const fmt = 'KHR_ATTRIBUTE_FORMAT';
    const position = doc.raw(attrs.POSITION, `${where} POSITION`, ['VEC3'], fmt);
    const count = position.count;
    /** @param {string} name @param {string[]} types @returns {RawAccessor} */
    const attr = (name, types) => {
        const raw = doc.raw(attrs[name], `${where} ${name}`, types, fmt);
        if (raw.componentType === UNSIGNED_INT) throw new AnchorError(fmt, `${where} ${name} (accessor ${raw.index}) has unsupported component type UNSIGNED_INT`);
        if (raw.count !== count) {
            throw new AnchorError('ATTRIBUTE_COUNT_MISMATCH', `${where}: ${name} has ${raw.count} elements, POSITION has ${count} (accessor count mismatch)`);
        }
        return raw;
    };
    if (position.componentType === UNSIGNED_INT) throw new AnchorError(fmt, `${where} POSITION has unsupported component type UNSIGNED_INT`);
    const rotation = attr(`${KHR}:ROTATION`, ['VEC4']);
    const scale = attr(`${KHR}:SCALE`, ['VEC3']);
    const opacity = attr(`${KHR}:OPACITY`, ['SCALAR']);
    requireFinite(position, `${where} POSITION`);
    requireFinite(rotation, `${where} ${KHR}:ROTATION`);
    requireFinite(scale, `${where} ${KHR}:SCALE`);
    const degree = shDegree(attrs, where);
    /** @type {Float32Array} */
    let sh;
    if (degree >= 0) {
        const K = (degree + 1) ** 2;
        sh = new Float32Array(count * K * 3);
        for (let k = 0; k < K; ++k) {
            const level = Math.floor(Math.sqrt(k));
            const name = `${KHR}:SH_DEGREE_${level}_COEF_${k - level * level}`;
            const v = dequantize(attr(name, ['VEC3']));
            for (let i = 0; i < count; ++i) for (let c = 0; c < 3; ++c) sh[(i * K + k) * 3 + c] = v[3 * i + c];
        }
    } else if ('COLOR_0' in attrs) {
        // No SH at all (not valid KHR_gaussian_splatting): the DC term from the fallback colour.
        const color = attr('COLOR_0', ['VEC3', 'VEC4']);
        const v = dequantize(color);
        const srgb = prim.extensions[KHR].colorSpace === 'srgb_rec709_display';
        sh = new Float32Array(count * 3);
        for (let i = 0; i < count; ++i) {
            for (let c = 0; c < 3; ++c) {
                let x = Math.min(Math.max(v[color.ncomp * i + c], 0), 1);
                if (srgb) x = linearToSrgb(x);
                sh[3 * i + c] = (x - 0.5) / SH_C0;
            }
        }
    } else {
        throw new AnchorError('KHR_ATTRIBUTE_MISSING', `${where}: required ${KHR} attribute missing: ${KHR}:SH_DEGREE_0_COEF_0`);
    }
    const pose64 = { means: dequantize(position), rotations: dequantize(rotation), scales: dequantize(scale) };
    const rest = {
        means: Float32Array.from(pose64.means),
        rotations: normalizeQuaternions(pose64.rotations),
        scales: Float32Array.from(pose64.scales),
        opacity: Float32Array.from(dequantize(opacity)),
        sh,
    };
    return { rest, pose64, count, shDegree: Math.max(degree, 0) };
}

/**
 * The anchor triangle primitive.
 * @param {GltfDocument} doc
 * @param {number} m
 * @param {number} p
 * @returns {AnchorMesh}
 */
function readAnchorMesh(doc, m, p) {
    const where = `anchor mesh meshes[${m}].primitives[${p}]`;
    const prim = doc.json.meshes[m].primitives[p];
    const mode = prim.mode === undefined ? TRIANGLES : prim.mode;
    if (mode !== TRIANGLES) throw new AnchorError('ANCHOR_MESH_NOT_TRIANGLES', `${where} has mode ${JSON.stringify(mode)}; anchor primitives must be TRIANGLES (4)`);
    const attrs = (prim.attributes && typeof prim.attributes === 'object') ? prim.attributes : {};
    if (!('POSITION' in attrs)) throw new AnchorError('ANCHOR_MESH_POSITION_INVALID', `${where} has no POSITION attribute`);
    const pos = doc.raw(attrs.POSITION, `${where} POSITION`, ['VEC3'], 'ANCHOR_MESH_POSITION_INVALID');
    if (pos.componentType !== FLOAT || pos.normalized) {
        throw new AnchorError('ANCHOR_MESH_POSITION_INVALID', `${where} POSITION (accessor ${pos.index}) is ${formatName(pos)}; it must be FLOAT VEC3`);
    }
    requireFinite(pos, `${where} POSITION`);
    const V = pos.count;
    /** @type {Uint32Array} */
    let indices;
    const indexed = prim.indices !== undefined && prim.indices !== null;
    const bad = 'ANCHOR_MESH_INDICES_INVALID';
    if (indexed) {
        const idx = doc.raw(prim.indices, `${where} indices`, ['SCALAR'], bad);
        if (![UNSIGNED_BYTE, UNSIGNED_SHORT, UNSIGNED_INT].includes(idx.componentType) || idx.normalized) {
            throw new AnchorError(bad, `${where} indices (accessor ${idx.index}) are ${formatName(idx)}; they must be UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT, not normalized`);
        }
        if (idx.count % 3) throw new AnchorError(bad, `${where} has ${idx.count} indices, not a multiple of 3`);
        indices = Uint32Array.from(idx.values);
        let max = -1;
        for (let i = 0; i < indices.length; ++i) if (indices[i] > max) max = indices[i];
        if (max >= V) throw new AnchorError(bad, `${where}: index ${max} out of range for ${V} vertices`);
    } else {
        if (V % 3) throw new AnchorError(bad, `${where} is not indexed and has ${V} vertices, not a multiple of 3`);
        indices = new Uint32Array(V);
        for (let i = 0; i < V; ++i) indices[i] = i;
    }
    return {
        mesh: m, primitive: p, node: null, vertexCount: V, faceCount: indices.length / 3, indexed,
        vertices: /** @type {Float32Array} */ (pos.values), indices,
    };
}

/**
 * The `faceCounts` accessor (one count per triangle of the anchor primitive), expanded to a
 * face index per splat; its own count and the sum of the counts are checked.
 * @param {GltfDocument} doc
 * @param {unknown} index  the accessor index
 * @param {string} what
 * @param {number} faces  T, triangles of the anchor primitive
 * @param {number} splats  N, the POSITION count
 * @param {{[key: string]: string}} componentTypes  receives faceCounts' component type
 * @returns {Uint32Array}
 */
function readFaceCounts(doc, index, what, faces, splats, componentTypes) {
    const spec = ANCHOR_ACCESSORS.faceCounts;
    const raw = doc.raw(index, what, [spec.type], 'ANCHOR_ACCESSOR_FORMAT');
    if (!spec.formats.some(([ct, nz]) => ct === raw.componentType && nz === raw.normalized)) {
        throw new AnchorError('ANCHOR_ACCESSOR_FORMAT', `${what} (accessor ${raw.index}) has component type ${formatName(raw)}, which the spec does not allow for faceCounts`);
    }
    if (raw.count !== faces) {
        throw new AnchorError(CODE_FACE_COUNTS_COUNT, `${what} has ${raw.count} elements but the anchor primitive has ${faces} triangles (one count per triangle)`);
    }
    componentTypes.faceCounts = formatName(raw);
    const { faceIndex, sum, exceeded } = expandFaceCounts(raw.values, splats);
    if (!faceIndex) {
        throw new AnchorError(CODE_FACE_COUNTS_SUM, exceeded
            ? `${what} add up to more than the ${splats} splats of the primitive (POSITION count)`
            : `${what} add up to ${sum} but the primitive has ${splats} splats (POSITION count)`);
    }
    return faceIndex;
}

/**
 * One anchored primitive: rest pose, anchor mesh, anchors, every refusal checked.
 * @param {GltfDocument} doc
 * @param {number} m
 * @param {number} p
 * @param {() => Float64Array[]} matrices
 * @returns {AnchoredPrimitive}
 */
function readAnchored(doc, m, p, matrices) {
    const json = doc.json;
    const where = `meshes[${m}].primitives[${p}]`;
    const prim = json.meshes[m].primitives[p];
    const khr = prim.extensions[KHR];
    const { rest, pose64, count, shDegree: B } = readRestPose(doc, prim, where);
    const ext = khr.extensions[EXTENSION];
    const w = `${where} ${EXTENSION}`;
    const schema = 'ANCHOR_SCHEMA_VIOLATION';
    if (typeof ext !== 'object' || ext === null || Array.isArray(ext)) throw new AnchorError(schema, `${w} must be an object`);
    const meshes = json.meshes;
    if (!isIndex(ext.mesh) || ext.mesh >= meshes.length || typeof meshes[ext.mesh] !== 'object' || meshes[ext.mesh] === null) {
        throw new AnchorError('UNRESOLVED_REFERENCE', `${w}.mesh ${JSON.stringify(ext.mesh)} does not index a mesh (${meshes.length} meshes)`);
    }
    const aprims = Array.isArray(meshes[ext.mesh].primitives) ? meshes[ext.mesh].primitives : [];
    const ap = ext.primitive === undefined ? 0 : ext.primitive;
    if (!isIndex(ap) || ap >= aprims.length || typeof aprims[ap] !== 'object' || aprims[ap] === null) {
        throw new AnchorError('UNRESOLVED_REFERENCE', `${w}.primitive ${JSON.stringify(ap)} does not index a primitive of mesh ${ext.mesh} (${aprims.length} primitives)`);
    }
    const anchorMesh = readAnchorMesh(doc, ext.mesh, ap);
    const nodes = Array.isArray(json.nodes) ? json.nodes : [];
    /** @type {number[]} */
    const users = [];
    nodes.forEach((/** @type {any} */ node, /** @type {number} */ i) => { if (node && node.mesh === ext.mesh) users.push(i); });
    if (users.length > 1) {
        throw new AnchorError('ANCHOR_MESH_MULTIPLE_INSTANCES', `${w}: the anchor mesh ${ext.mesh} is instantiated by ${users.length} nodes (${users.join(', ')}); at most one may instantiate it (which instance deforms the splats is ambiguous)`);
    }
    anchorMesh.node = users.length ? users[0] : null;
    const profile = ext.profile;
    if (profile !== 'local' && profile !== 'games') throw new AnchorError(schema, `${w}.profile must be 'local' or 'games', got ${JSON.stringify(profile)}`);
    const hasIndex = ext.faceIndex !== undefined;
    const hasCounts = ext.faceCounts !== undefined;
    if (hasIndex === hasCounts) {
        throw new AnchorError(schema, hasIndex
            ? `${w} has both faceIndex and faceCounts; exactly one of them must be present`
            : `${w} has neither faceIndex nor faceCounts; exactly one of them must be present`);
    }
    // derived local anchors: no barycentrics, and then none of normalOffset, localRotation, localScale
    const derived = profile === 'local' && ext.barycentrics === undefined;
    if (derived) {
        const stray = DERIVED.filter((key) => ext[key] !== undefined);
        if (stray.length) {
            throw new AnchorError(schema, `${w} has no barycentrics (derived local anchors) but has ${stray.join(', ')}; derived anchors store none of normalOffset, localRotation, localScale`);
        }
    } else {
        const missing = REQUIRED[profile].filter((key) => ext[key] === undefined);
        if (missing.length) throw new AnchorError(schema, `${w} (${profile} profile) lacks ${missing.join(', ')}`);
    }
    /** @type {{[key: string]: string}} */
    const componentTypes = {};
    /** @param {string} key @returns {RawAccessor} */
    const anchor = (key) => {
        const spec = ANCHOR_ACCESSORS[key];
        const raw = doc.raw(ext[key], `${w}.${key}`, [spec.type], 'ANCHOR_ACCESSOR_FORMAT');
        if (!spec.formats.some(([ct, nz]) => ct === raw.componentType && nz === raw.normalized)) {
            throw new AnchorError('ANCHOR_ACCESSOR_FORMAT', `${w}.${key} (accessor ${raw.index}) has component type ${formatName(raw)}, which the spec does not allow for ${key}`);
        }
        if (raw.count !== count) {
            throw new AnchorError('ANCHOR_ACCESSOR_COUNT', `${w}.${key} has ${raw.count} elements but the primitive has ${count} splats (accessor count mismatch)`);
        }
        requireFinite(raw, `${w}.${key}`);
        componentTypes[key] = formatName(raw);
        return raw;
    };
    const F = anchorMesh.faceCount;
    /** @type {Uint32Array} */
    let faceIndex;
    if (hasIndex) {
        faceIndex = Uint32Array.from(anchor('faceIndex').values);
        for (let i = 0; i < count; ++i) {
            if (faceIndex[i] >= F) {
                throw new AnchorError('ANCHOR_FACE_OUT_OF_RANGE', `${w}.faceIndex value ${faceIndex[i]} (splat ${i}) out of range for an anchor mesh with ${F} triangles`);
            }
        }
    } else {
        faceIndex = readFaceCounts(doc, ext.faceCounts, `${w}.faceCounts`, F, count, componentTypes);
    }
    /** @type {AnchoredPrimitive} */
    const out = {
        splatMesh: m, splatPrimitive: p, node: null, nodeMatrix: null,
        count, shDegree: B, shCoefficients: (B + 1) ** 2, rest, anchorMesh,
        profile, deformation: null, faceEncoding: hasIndex ? 'faceIndex' : 'faceCounts', derived,
        faceIndex, barycentrics: new Float32Array(0),
        normalOffset: null, localRotation: null, localScale: null, rho: null, componentTypes,
    };
    if (profile === 'games') {
        if (ext.deformation !== undefined) throw new AnchorError(schema, `${w}: 'deformation' must not be present with the games profile`);
        out.barycentrics = Float32Array.from(dequantize(anchor('barycentrics')));
        out.rho = Float32Array.from(dequantize(anchor('rho')));
    } else {
        const deformation = ext.deformation === undefined ? 'affine' : ext.deformation;
        if (deformation !== 'affine' && deformation !== 'rigid') {
            throw new AnchorError(schema, `${w}.deformation must be 'affine' or 'rigid', got ${JSON.stringify(deformation)}`);
        }
        out.deformation = deformation;
    }
    if (derived) {
        // derived anchors are used as stored ones: the refusals of localRotation and
        // localScale apply to the rest ROTATION (before normalizing) and SCALE they come from
        const q = pose64.rotations;
        for (let i = 0; i < count; ++i) {
            if (q[4 * i] === 0 && q[4 * i + 1] === 0 && q[4 * i + 2] === 0 && q[4 * i + 3] === 0) {
                throw new AnchorError('ROTATION_NOT_UNIT', `${where} ${KHR}:ROTATION of splat ${i} has length zero; derived local anchors need a rotation of non-zero length`);
            }
        }
        const s = pose64.scales;
        for (let i = 0; i < s.length; ++i) {
            if (s[i] < 0) throw new AnchorError('SCALE_NEGATIVE', `${where} ${KHR}:SCALE of splat ${Math.floor(i / 3)} is negative; derived local anchors need scales >= 0`);
        }
        const { anchors, degenerateSplat } = deriveLocalAnchors(anchorMesh, faceIndex, pose64.means, pose64.rotations, pose64.scales);
        if (!anchors) {
            throw new AnchorError(CODE_DERIVED_DEGENERATE, `${w}: splat ${degenerateSplat} has derived anchors on face ${faceIndex[degenerateSplat]}, which is degenerate at rest (a <= ${EPS_DEGENERATE} l^2); derived anchors need a regular face`);
        }
        out.barycentrics = anchors.barycentrics;
        out.normalOffset = anchors.normalOffset;
        out.localRotation = anchors.localRotation;
        out.localScale = anchors.localScale;
    } else if (profile === 'local') {
        out.barycentrics = Float32Array.from(dequantize(anchor('barycentrics')));
        out.normalOffset = Float32Array.from(dequantize(anchor('normalOffset')));
        const q = dequantize(anchor('localRotation'));
        for (let i = 0; i < count; ++i) {
            if (q[4 * i] === 0 && q[4 * i + 1] === 0 && q[4 * i + 2] === 0 && q[4 * i + 3] === 0) {
                throw new AnchorError('ROTATION_NOT_UNIT', `${w}.localRotation of splat ${i} has length zero; a rotation must have non-zero length`);
            }
        }
        out.localRotation = normalizeQuaternions(q);
        const s = dequantize(anchor('localScale'));
        for (let i = 0; i < s.length; ++i) {
            if (s[i] < 0) throw new AnchorError('SCALE_NEGATIVE', `${w}.localScale of splat ${Math.floor(i / 3)} is negative; scales are linear, >= 0`);
        }
        out.localScale = Float32Array.from(s);
    }
    const node = nodes.findIndex((/** @type {any} */ n) => n && n.mesh === m);
    if (node >= 0) {
        out.node = node;
        out.nodeMatrix = matrices()[node];
    }
    return out;
}

/**
 * SIZE_LIMIT_EXCEEDED when reading every splat primitive would copy far more bytes than the
 * buffers hold (primitives sharing accessors, legal glTF, would make a small file expand into
 * gigabytes): the Python reader's rule, on the declared sizes, before anything is read.
 * @param {any} json
 */
function checkReadAmplification(json) {
    const meshes = Array.isArray(json.meshes) ? json.meshes : [];
    const buffers = Array.isArray(json.buffers) ? json.buffers : [];
    let held = 0;
    for (const b of buffers) if (b && isIndex(b.byteLength)) held += b.byteLength;
    const allowed = MAX_READ_AMPLIFICATION * held + READ_AMPLIFICATION_SLACK;
    let total = 0;
    meshes.forEach((/** @type {any} */ mesh, /** @type {number} */ m) => {
        const prims = mesh && Array.isArray(mesh.primitives) ? mesh.primitives : [];
        prims.forEach((/** @type {any} */ prim, /** @type {number} */ p) => {
            const khr = prim && prim.extensions && prim.extensions[KHR];
            if (typeof khr !== 'object' || khr === null) return;
            const attrs = typeof prim.attributes === 'object' && prim.attributes !== null ? prim.attributes : {};
            const refs = Object.values(attrs);
            const anchor = khr.extensions && khr.extensions[EXTENSION];
            if (typeof anchor === 'object' && anchor !== null) {
                for (const [k, v] of Object.entries(anchor)) if (k !== 'mesh' && k !== 'primitive') refs.push(v);
            }
            for (const r of refs) total += declaredAccessorBytes(json, r);
            if (total > allowed) {
                throw new GltfError('SIZE_LIMIT_EXCEEDED', `the splat primitives up to meshes[${m}].primitives[${p}] would read ${total} bytes of accessors, more than ${MAX_READ_AMPLIFICATION} times the ${held} bytes of the buffers (accessors shared by many primitives)`);
            }
        });
    });
}

/**
 * Read every anchored splat primitive of a GLB (or .gltf JSON with data: URIs only).
 * Throws AnchorError (message naming the file and the cause, `.code` the gsverse-validate
 * code) when the asset must be refused.
 * @param {Uint8Array|ArrayBuffer} bytes
 * @param {{name?: string}} [options]  name: the file name used in messages
 * @returns {AnchoredGlb}
 */
export function readAnchoredGlb(bytes, options = {}) {
    const name = options.name || 'asset';
    try {
        const doc = parseGltf(bytes);
        const json = doc.json;
        checkReadAmplification(json);
        const meshes = Array.isArray(json.meshes) ? json.meshes : [];
        /** @type {AnchoredPrimitive[]} */
        const anchored = [];
        /** @type {{mesh: number, primitive: number}[]} */
        const plain = [];
        /** @type {Float64Array[]|null} */
        let matrices = null;
        const getMatrices = () => (matrices = matrices || globalMatrices(json));
        meshes.forEach((/** @type {any} */ mesh, /** @type {number} */ m) => {
            const prims = mesh && Array.isArray(mesh.primitives) ? mesh.primitives : [];
            prims.forEach((/** @type {any} */ prim, /** @type {number} */ p) => {
                const khr = prim && prim.extensions && prim.extensions[KHR];
                if (khr === undefined || khr === null) return;
                if (typeof khr !== 'object') throw new AnchorError('KHR_PROPERTY_INVALID', `meshes[${m}].primitives[${p}]: ${KHR} extension must be an object`);
                const nested = khr.extensions;
                if (nested && typeof nested === 'object' && nested[SPZ_EXTENSION] !== undefined) {
                    throw new AnchorError('UNSUPPORTED_REQUIRED_EXTENSION', `meshes[${m}].primitives[${p}] stores its rest pose through ${SPZ_EXTENSION}; expand the asset first (expandCompressed, asynchronous) or load it with an engine's loadAnchoredAsset`);
                }
                const isAnchored = nested && typeof nested === 'object' && nested[EXTENSION] !== undefined;
                const mode = prim.mode === undefined ? TRIANGLES : prim.mode;
                if (isAnchored) {
                    if (mode !== POINTS) {
                        throw new AnchorError('KHR_PRIMITIVE_NOT_POINTS', `meshes[${m}].primitives[${p}]: an anchored splat primitive must have mode POINTS (0), not ${JSON.stringify(mode)}`);
                    }
                    anchored.push(readAnchored(doc, m, p, getMatrices));
                } else if (mode === POINTS) {
                    plain.push({ mesh: m, primitive: p });
                }
            });
        });
        return { anchored, plain, json };
    } catch (err) {
        if (err instanceof AnchorError || err instanceof GltfError) {
            throw new AnchorError(err.code, `${name}: ${err.message}`);
        }
        throw err;
    }
}
