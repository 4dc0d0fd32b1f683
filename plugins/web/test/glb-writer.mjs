// A small glTF/GLB writer for the tests: accessors from typed arrays (the typed array's class
// gives the component type), interleaved buffer views with byteStride, and a builder of
// anchored splat assets whose JSON a test may patch before packing (to make invalid assets).

/** @type {Map<Function, number>} */
const COMPONENT = new Map(/** @type {[Function, number][]} */ ([
    [Int8Array, 5120], [Uint8Array, 5121], [Int16Array, 5122], [Uint16Array, 5123], [Uint32Array, 5125], [Float32Array, 5126],
]));
/** @type {{[type: string]: number}} */
const NCOMP = { SCALAR: 1, VEC2: 2, VEC3: 3, VEC4: 4 };

/** @typedef {Int8Array|Uint8Array|Int16Array|Uint16Array|Uint32Array|Float32Array} Typed */

export const KHR = 'KHR_gaussian_splatting';
export const EXT = 'GSVERSE_gaussian_splatting_mesh_anchor';

export class GltfBuilder {
    constructor() {
        /** @type {any} */
        this.json = {
            asset: { version: '2.0', generator: 'gsverse web tests' },
            extensionsUsed: [KHR, EXT],
            buffers: [], bufferViews: [], accessors: [], meshes: [], nodes: [], scenes: [{ nodes: [] }], scene: 0,
        };
        /** @type {Uint8Array[]} */
        this.parts = [];
        this.length = 0;
    }

    /**
     * @param {Uint8Array} bytes
     * @param {number} [byteStride]
     * @returns {number} bufferView index
     */
    view(bytes, byteStride) {
        const pad = (4 - (this.length % 4)) % 4;
        if (pad) { this.parts.push(new Uint8Array(pad)); this.length += pad; }
        /** @type {any} */
        const v = { buffer: 0, byteOffset: this.length, byteLength: bytes.byteLength };
        if (byteStride) v.byteStride = byteStride;
        this.parts.push(bytes);
        this.length += bytes.byteLength;
        this.json.bufferViews.push(v);
        return this.json.bufferViews.length - 1;
    }

    /**
     * @param {Typed} data
     * @param {string} type SCALAR, VEC2, VEC3, VEC4
     * @param {{normalized?: boolean}} [options]
     * @returns {number} accessor index
     */
    accessor(data, type, options = {}) {
        const ctype = COMPONENT.get(/** @type {any} */ (data.constructor));
        if (!ctype) throw new Error('unsupported typed array');
        const bytes = new Uint8Array(data.buffer.slice(data.byteOffset, data.byteOffset + data.byteLength));
        const bufferView = this.view(bytes);
        /** @type {any} */
        const acc = { bufferView, componentType: ctype, count: data.length / NCOMP[type], type };
        if (options.normalized) acc.normalized = true;
        if (type === 'VEC3' && ctype === 5126 && acc.count) {
            const min = [Infinity, Infinity, Infinity], max = [-Infinity, -Infinity, -Infinity];
            for (let i = 0; i < data.length; ++i) { min[i % 3] = Math.min(min[i % 3], data[i]); max[i % 3] = Math.max(max[i % 3], data[i]); }
            if (min.every(Number.isFinite) && max.every(Number.isFinite)) { acc.min = min; acc.max = max; }
        }
        this.json.accessors.push(acc);
        return this.json.accessors.length - 1;
    }

    /**
     * Several accessors of the same count interleaved in one buffer view with byteStride.
     * @param {{data: Typed, type: string, normalized?: boolean}[]} list
     * @returns {number[]} accessor indices
     */
    interleaved(list) {
        const count = list[0].data.length / NCOMP[list[0].type];
        /** @type {number[]} */
        const offsets = [];
        let stride = 0;
        for (const item of list) {
            offsets.push(stride);
            stride += item.data.BYTES_PER_ELEMENT * NCOMP[item.type];
            stride += (4 - (stride % 4)) % 4;
        }
        const bytes = new Uint8Array(stride * count);
        const dv = new DataView(bytes.buffer);
        list.forEach((item, k) => {
            const n = NCOMP[item.type];
            const size = item.data.BYTES_PER_ELEMENT;
            for (let e = 0; e < count; ++e) {
                for (let c = 0; c < n; ++c) {
                    const p = e * stride + offsets[k] + c * size;
                    const v = item.data[e * n + c];
                    if (item.data instanceof Float32Array) dv.setFloat32(p, v, true);
                    else if (item.data instanceof Int8Array) dv.setInt8(p, v);
                    else if (item.data instanceof Uint8Array) dv.setUint8(p, v);
                    else if (item.data instanceof Int16Array) dv.setInt16(p, v, true);
                    else if (item.data instanceof Uint16Array) dv.setUint16(p, v, true);
                    else dv.setUint32(p, v, true);
                }
            }
        });
        const bufferView = this.view(bytes, stride);
        return list.map((item, k) => {
            /** @type {any} */
            const acc = { bufferView, byteOffset: offsets[k], componentType: COMPONENT.get(/** @type {any} */ (item.data.constructor)), count, type: item.type };
            if (item.normalized) acc.normalized = true;
            this.json.accessors.push(acc);
            return this.json.accessors.length - 1;
        });
    }

    /** @returns {Uint8Array} the binary buffer */
    bin() {
        const out = new Uint8Array(this.length + ((4 - (this.length % 4)) % 4));
        let o = 0;
        for (const p of this.parts) { out.set(p, o); o += p.byteLength; }
        return out;
    }

    /** @returns {Uint8Array} a GLB container */
    glb() {
        const bin = this.bin();
        this.json.buffers = [{ byteLength: bin.byteLength }];
        let text = new TextEncoder().encode(JSON.stringify(this.json));
        const jpad = (4 - (text.byteLength % 4)) % 4;
        const jsonChunk = new Uint8Array(text.byteLength + jpad).fill(0x20);
        jsonChunk.set(text);
        const total = 12 + 8 + jsonChunk.byteLength + 8 + bin.byteLength;
        const out = new Uint8Array(total);
        const dv = new DataView(out.buffer);
        dv.setUint32(0, 0x46546c67, true); dv.setUint32(4, 2, true); dv.setUint32(8, total, true);
        dv.setUint32(12, jsonChunk.byteLength, true); dv.setUint32(16, 0x4e4f534a, true);
        out.set(jsonChunk, 20);
        const b = 20 + jsonChunk.byteLength;
        dv.setUint32(b, bin.byteLength, true); dv.setUint32(b + 4, 0x004e4942, true);
        out.set(bin, b + 8);
        return out;
    }

    /** @returns {Uint8Array} a .gltf JSON document with the buffer as a base64 data: URI */
    gltf() {
        const bin = this.bin();
        this.json.buffers = [{ byteLength: bin.byteLength, uri: `data:application/octet-stream;base64,${Buffer.from(bin).toString('base64')}` }];
        return new TextEncoder().encode(JSON.stringify(this.json));
    }
}

/**
 * @typedef {object} AnchoredSpec
 * @property {number[]} vertices         anchor rest vertices (3V)
 * @property {number[]|null} [indices]   triangle corner indices; null or omitted: a non-indexed mesh
 * @property {'local'|'games'} profile
 * @property {string} [deformation]      omitted: none in the JSON
 * @property {number[]} face
 * @property {Typed|number[]} bary       barycentrics (Float32Array by default; pass a typed array to quantize)
 * @property {Typed|number[]} [offset]
 * @property {Typed|number[]} [rotation]
 * @property {Typed|number[]} [scale]
 * @property {Typed|number[]} [rho]
 * @property {{bary?: boolean, rotation?: boolean, scale?: boolean}} [normalized]
 * @property {number[]} [means]  rest POSITION (default: zeros)
 * @property {number[]} [rotations]  rest ROTATION x, y, z, w (default: identity)
 * @property {number[]} [scales]     rest SCALE (default: 0.01)
 * @property {Typed|number[]} [faceCounts]  write these per-face counts (UNSIGNED_INT unless typed)
 *   instead of faceIndex; `face` still gives the splat count
 * @property {boolean} [derived]  write no barycentrics, normalOffset, localRotation, localScale
 * @property {number} [shDegree]
 * @property {boolean} [interleave]  interleave the anchor accessors with byteStride
 * @property {number[]} [nodeMatrix]  splat node matrix (column-major)
 * @property {(json: any, b: GltfBuilder) => void} [patch]  edit the JSON before packing
 */

/** @param {Typed|number[]} a @returns {Typed} */
function typed(a) {
    return ArrayBuffer.isView(a) ? a : Float32Array.from(a);
}

/**
 * An anchored splat asset (one splat mesh with one node, one anchor mesh no node uses).
 * @param {AnchoredSpec} s
 * @returns {GltfBuilder}
 */
export function anchoredBuilder(s) {
    const b = new GltfBuilder();
    const N = s.face.length;
    const means = Float32Array.from(s.means || new Array(3 * N).fill(0));
    const rot = new Float32Array(4 * N);
    for (let i = 0; i < N; ++i) rot[4 * i + 3] = 1;
    if (s.rotations) rot.set(s.rotations);
    const scl = s.scales ? Float32Array.from(s.scales) : new Float32Array(3 * N).fill(0.01);
    /** @type {any} */
    const attributes = {
        POSITION: b.accessor(means, 'VEC3'),
        [`${KHR}:ROTATION`]: b.accessor(rot, 'VEC4'),
        [`${KHR}:SCALE`]: b.accessor(scl, 'VEC3'),
        [`${KHR}:OPACITY`]: b.accessor(new Float32Array(N).fill(0.5), 'SCALAR'),
    };
    const degree = s.shDegree || 0;
    for (let l = 0; l <= degree; ++l) {
        for (let n = 0; n <= 2 * l; ++n) {
            const sh = new Float32Array(3 * N);
            for (let i = 0; i < 3 * N; ++i) sh[i] = (l * l + n) + i / 1000;
            attributes[`${KHR}:SH_DEGREE_${l}_COEF_${n}`] = b.accessor(sh, 'VEC3');
        }
    }
    const meshAttrs = { POSITION: b.accessor(Float32Array.from(s.vertices), 'VEC3') };
    /** @type {any} */
    const anchorPrim = { mode: 4, attributes: meshAttrs };
    if (s.indices) anchorPrim.indices = b.accessor(Uint32Array.from(s.indices), 'SCALAR');
    const nz = s.normalized || {};
    /** @type {{key: string, data: Typed, type: string, normalized?: boolean}[]} */
    const items = s.faceCounts
        ? [{ key: 'faceCounts', data: ArrayBuffer.isView(s.faceCounts) ? s.faceCounts : Uint32Array.from(s.faceCounts), type: 'SCALAR' }]
        : [{ key: 'faceIndex', data: N <= 255 ? Uint8Array.from(s.face) : Uint32Array.from(s.face), type: 'SCALAR' }];
    if (s.derived) {
        // derived local anchors: the face only
    } else if (s.profile === 'local') {
        items.push({ key: 'barycentrics', data: typed(s.bary), type: 'VEC2', normalized: nz.bary });
        items.push({ key: 'normalOffset', data: typed(s.offset || new Array(N).fill(0)), type: 'SCALAR' });
        items.push({ key: 'localRotation', data: typed(s.rotation || Array.from(rot)), type: 'VEC4', normalized: nz.rotation });
        items.push({ key: 'localScale', data: typed(s.scale || Array.from(scl)), type: 'VEC3', normalized: nz.scale });
    } else {
        items.push({ key: 'barycentrics', data: typed(s.bary), type: 'VEC2', normalized: nz.bary });
        items.push({ key: 'rho', data: typed(s.rho || new Array(N).fill(1)), type: 'SCALAR' });
    }
    /** @type {any} */
    const ext = { mesh: 1, primitive: 0, profile: s.profile };
    if (s.deformation !== undefined) ext.deformation = s.deformation;
    const ids = s.interleave ? b.interleaved(items) : items.map((it) => b.accessor(it.data, it.type, { normalized: it.normalized }));
    items.forEach((it, k) => { ext[it.key] = ids[k]; });
    b.json.meshes.push({
        name: 'splats',
        primitives: [{
            mode: 0, attributes,
            extensions: { [KHR]: { kernel: 'ellipse', colorSpace: 'srgb_rec709_display', projection: 'perspective', sortingMethod: 'cameraDistance', extensions: { [EXT]: ext } } },
        }],
    });
    b.json.meshes.push({ name: 'anchor mesh', primitives: [anchorPrim] });
    /** @type {any} */
    const node = { mesh: 0, name: 'splats' };
    if (s.nodeMatrix) node.matrix = s.nodeMatrix;
    b.json.nodes.push(node);
    b.json.scenes[0].nodes.push(0);
    if (s.patch) s.patch(b.json, b);
    return b;
}

/**
 * The GLB bytes of an anchored asset.
 * @param {AnchoredSpec} s
 */
export function anchoredGlb(s) {
    return anchoredBuilder(s).glb();
}

/**
 * A FLOAT MAT4 accessor of column-major 4x4 matrices (16 numbers each), in its own buffer view.
 * @param {GltfBuilder} b
 * @param {ArrayLike<number>} matrices  16 numbers per matrix
 * @returns {number} accessor index
 */
export function matrixAccessor(b, matrices) {
    const data = Float32Array.from(matrices);
    const bufferView = b.view(new Uint8Array(data.buffer));
    b.json.accessors.push({ bufferView, componentType: 5126, count: data.length / 16, type: 'MAT4' });
    return b.json.accessors.length - 1;
}
