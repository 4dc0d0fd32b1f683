// glTF 2.0 container and accessor reading: GLB or .gltf JSON with base64 data: URIs only.
// Knows nothing of splats or anchors. Every problem is a GltfError whose code is the
// gsverse-validate code (spec/validation.md).

/** glTF component types. */
export const BYTE = 5120;
export const UNSIGNED_BYTE = 5121;
export const SHORT = 5122;
export const UNSIGNED_SHORT = 5123;
export const UNSIGNED_INT = 5125;
export const FLOAT = 5126;

/** @type {{[type: number]: {name: string, size: number}}} */
export const COMPONENT_TYPES = {
    [BYTE]: { name: 'BYTE', size: 1 },
    [UNSIGNED_BYTE]: { name: 'UNSIGNED_BYTE', size: 1 },
    [SHORT]: { name: 'SHORT', size: 2 },
    [UNSIGNED_SHORT]: { name: 'UNSIGNED_SHORT', size: 2 },
    [UNSIGNED_INT]: { name: 'UNSIGNED_INT', size: 4 },
    [FLOAT]: { name: 'FLOAT', size: 4 },
};

/** Components per element of each accessor type (matrices are refused by this reader). */
/** @type {{[type: string]: number}} */
export const TYPE_COMPONENTS = { SCALAR: 1, VEC2: 2, VEC3: 3, VEC4: 4 };

/** TYPE_COMPONENTS and 4x4 matrices (read as FLOAT only, by GltfDocument.matrices). */
/** @type {{[type: string]: number}} */
const MATRIX_COMPONENTS = { ...TYPE_COMPONENTS, MAT4: 16 };

/** Largest code of each normalized integer type (glTF 2.0 §3.11). */
/** @type {{[type: number]: number}} */
const NORMALIZED_TOP = { [BYTE]: 127, [UNSIGNED_BYTE]: 255, [SHORT]: 32767, [UNSIGNED_SHORT]: 65535 };

const GLB_MAGIC = 0x46546c67; // 'glTF'
const LITTLE_ENDIAN = new Uint8Array(new Uint16Array([1]).buffer)[0] === 1;
const CHUNK_JSON = 0x4e4f534a;
const CHUNK_BIN = 0x004e4942;

/** A problem with a glTF file; `code` is the gsverse-validate code. */
export class GltfError extends Error {
    /**
     * @param {string} code
     * @param {string} message
     */
    constructor(code, message) {
        super(message);
        this.name = 'GltfError';
        /** @type {string} */
        this.code = code;
    }
}

/**
 * @param {Uint8Array|ArrayBuffer} bytes
 * @returns {Uint8Array}
 */
export function asBytes(bytes) {
    if (bytes instanceof Uint8Array) return bytes;
    if (bytes instanceof ArrayBuffer) return new Uint8Array(bytes);
    if (ArrayBuffer.isView(bytes)) {
        const v = /** @type {ArrayBufferView} */ (bytes);
        return new Uint8Array(v.buffer, v.byteOffset, v.byteLength);
    }
    throw new GltfError('FILE_TYPE_UNSUPPORTED', 'expected the bytes of a .glb or .gltf file');
}

/**
 * The JSON chunk and the BIN chunk (or null) of a GLB container, every length checked.
 * @param {Uint8Array} data
 * @returns {{json: Uint8Array, bin: Uint8Array|null}}
 */
export function parseGlb(data) {
    if (data.byteLength < 12) {
        throw new GltfError('GLB_TRUNCATED', `truncated GLB: ${data.byteLength} bytes, shorter than the 12-byte header`);
    }
    const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
    if (view.getUint32(0, true) !== GLB_MAGIC) throw new GltfError('GLB_BAD_MAGIC', "not a GLB file: bad magic (expected 'glTF')");
    const version = view.getUint32(4, true);
    if (version !== 2) throw new GltfError('GLB_UNSUPPORTED_VERSION', `unsupported GLB container version ${version} (only 2)`);
    const length = view.getUint32(8, true);
    if (length > data.byteLength) {
        throw new GltfError('GLB_TRUNCATED', `truncated GLB: header says ${length} bytes, file has ${data.byteLength}`);
    }
    if (length < data.byteLength) {
        throw new GltfError('GLB_LENGTH_MISMATCH', `GLB length field ${length} does not match the file size ${data.byteLength}`);
    }
    /** @type {{kind: number, data: Uint8Array}[]} */
    const chunks = [];
    let pos = 12;
    while (pos < length) {
        if (pos + 8 > length) throw new GltfError('GLB_TRUNCATED', `truncated GLB: chunk header at byte ${pos} runs past the end`);
        const size = view.getUint32(pos, true);
        const kind = view.getUint32(pos + 4, true);
        if (size > length - pos - 8) {
            throw new GltfError('GLB_CHUNK_TOO_LONG', `GLB chunk ${chunks.length} is ${size} bytes long but only ${length - pos - 8} bytes follow it`);
        }
        pos += 8;
        chunks.push({ kind, data: data.subarray(pos, pos + size) });
        pos += size;
    }
    if (!chunks.length || chunks[0].kind !== CHUNK_JSON) throw new GltfError('GLB_FIRST_CHUNK_NOT_JSON', 'GLB does not start with a JSON chunk');
    const bin = chunks.length > 1 && chunks[1].kind === CHUNK_BIN ? chunks[1].data : null;
    return { json: chunks[0].data, bin };
}

/**
 * Decoded bytes one base64 `data:` URI may hold (256 MiB), the Python reader's
 * `gsverse_format.limits.MAX_DATA_URI_BYTES`: checked on the length of the text before
 * anything is decoded. GLB binary chunks suit larger buffers.
 */
export const MAX_DATA_URI_BYTES = 2 ** 28;

/**
 * Elements of one top-level glTF array (`accessors`, `nodes`, ...) and primitives of one mesh,
 * the Python reader's `MAX_GLTF_ARRAY_ITEMS`: checked right after the JSON is parsed.
 */
export const MAX_GLTF_ARRAY_ITEMS = 100000;

/**
 * Accessor bytes all splat primitives read together (an accessor shared by several primitives
 * counted once per use) may be at most this many times the buffers' declared bytes plus
 * READ_AMPLIFICATION_SLACK: the Python reader's `MAX_READ_AMPLIFICATION` and
 * `READ_AMPLIFICATION_SLACK` (readAnchoredGlb checks them before reading any primitive).
 */
export const MAX_READ_AMPLIFICATION = 4;
export const READ_AMPLIFICATION_SLACK = 2 ** 26;

/**
 * The bytes an accessor declares (count x components x component size; 0 when malformed:
 * its reading refuses it).
 * @param {any} json
 * @param {unknown} index
 * @returns {number}
 */
export function declaredAccessorBytes(json, index) {
    const accessors = Array.isArray(json.accessors) ? json.accessors : [];
    const acc = isIndex(index) && index < accessors.length ? accessors[index] : null;
    if (typeof acc !== 'object' || acc === null || !isIndex(acc.count)) return 0;
    const comp = COMPONENT_TYPES[acc.componentType];
    const n = Object.prototype.hasOwnProperty.call(MATRIX_COMPONENTS, acc.type) ? MATRIX_COMPONENTS[acc.type] : 0;
    return comp ? acc.count * n * comp.size : 0;
}

/** Value of each base64 character code; -1 for ASCII whitespace (skipped), -2 otherwise. */
const BASE64_VALUE = (() => {
    const table = new Int8Array(128).fill(-2);
    const alphabet = 'ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/';
    for (let i = 0; i < 64; ++i) table[alphabet.charCodeAt(i)] = i;
    for (const c of ' \t\n\r\f') table[c.charCodeAt(0)] = -1;
    return table;
})();

/**
 * Decode base64 text from `start` (no external dependency; works in Node and browsers): one
 * pass over the characters into one output array, no copy of the text.
 * @param {string} text
 * @param {number} [start]
 * @returns {Uint8Array|null} null when the text is not valid base64
 */
function decodeBase64(text, start = 0) {
    const out = new Uint8Array(Math.floor(((text.length - start) * 3) / 4));
    let acc = 0;
    let bits = 0;
    let o = 0;
    let chars = 0;
    let pad = 0;
    for (let i = start; i < text.length; ++i) {
        const c = text.charCodeAt(i);
        const v = c < 128 ? BASE64_VALUE[c] : -2;
        if (v === -1) continue;
        if (c === 0x3d) { ++pad; ++chars; continue; }       // '=': only at the end
        if (v < 0 || pad) return null;
        ++chars;
        acc = ((acc << 6) | v) & 0xffffff;
        bits += 6;
        if (bits >= 8) {
            bits -= 8;
            out[o++] = (acc >> bits) & 0xff;
        }
    }
    if (pad > 2 || chars % 4 === 1 || (pad && chars % 4)) return null;
    return out.subarray(0, o);
}

/**
 * The bytes of a `data:` URI. Any other URI (relative paths included) is refused: this
 * reader fetches nothing. The decoded size is checked against MAX_DATA_URI_BYTES on the
 * length of the text, before anything is decoded.
 * @param {string} uri
 * @param {string} what
 * @returns {Uint8Array}
 */
function dataUri(uri, what) {
    if (uri.slice(0, 5).toLowerCase() !== 'data:') {
        throw new GltfError('URI_SCHEME_REJECTED', `${what}: URI ${JSON.stringify(uri.slice(0, 60))} is not a data: URI; only data in the GLB binary chunk or in base64 data: URIs is read`);
    }
    const comma = uri.indexOf(',');
    if (comma < 0 || comma > 1024) throw new GltfError('URI_INVALID', `${what}: malformed data: URI (no comma)`);
    if (!/;base64$/i.test(uri.slice(0, comma))) throw new GltfError('URI_INVALID', `${what}: only base64 data: URIs are supported`);
    const size = Math.floor(((uri.length - comma - 1) * 3) / 4);
    if (size > MAX_DATA_URI_BYTES) {
        throw new GltfError('DATA_URI_TOO_LARGE', `${what}: data: URI holds about ${size} bytes, more than the limit of ${MAX_DATA_URI_BYTES} bytes per data: URI`);
    }
    const bytes = decodeBase64(uri, comma + 1);
    if (!bytes) throw new GltfError('URI_INVALID', `${what}: data: URI is not valid base64`);
    return bytes;
}

/** @param {unknown} v @returns {v is number} */
export function isIndex(v) {
    return typeof v === 'number' && Number.isInteger(v) && v >= 0;
}

/**
 * Raw elements of an accessor, tightly packed, in the stored component type.
 * @typedef {object} RawAccessor
 * @property {number} index          accessor index
 * @property {string} type           SCALAR, VEC2, VEC3 or VEC4
 * @property {number} componentType  glTF component type
 * @property {boolean} normalized
 * @property {number} count
 * @property {number} ncomp          components per element
 * @property {Int8Array|Uint8Array|Int16Array|Uint16Array|Uint32Array|Float32Array} values
 */

/** A parsed glTF document with bounds-checked accessor reading. */
export class GltfDocument {
    /**
     * @param {any} json       the parsed JSON document
     * @param {Uint8Array[]} buffers  the bytes of each buffer
     */
    constructor(json, buffers) {
        /** @type {any} */
        this.json = json;
        /** @type {Uint8Array[]} */
        this.buffers = buffers;
    }

    /**
     * Item `index` of the top-level array `key`, or an UNRESOLVED_REFERENCE error.
     * @param {string} key
     * @param {unknown} index
     * @param {string} what
     * @returns {any}
     */
    item(key, index, what) {
        const items = Array.isArray(this.json[key]) ? this.json[key] : [];
        if (!isIndex(index) || index >= items.length || typeof items[index] !== 'object' || items[index] === null) {
            throw new GltfError('UNRESOLVED_REFERENCE', `${what}: ${key} index ${JSON.stringify(index)} out of range (${items.length} ${key})`);
        }
        return items[index];
    }

    /**
     * Where the elements of accessor `index` lie, checked against its buffer view and buffer.
     * Nothing is read.
     * @param {unknown} index
     * @param {string} what
     * @param {{[type: string]: number}} [components]  the accessor types read and their
     *   components per element (default TYPE_COMPONENTS: no matrices)
     * @returns {{index: number, type: string, componentType: number, normalized: boolean,
     *   count: number, ncomp: number, size: number, stride: number, start: number, buffer: Uint8Array}}
     */
    layout(index, what, components = TYPE_COMPONENTS) {
        const acc = this.item('accessors', index, what);
        const i = /** @type {number} */ (index);
        const where = `${what} (accessor ${i})`;
        const type = acc.type;
        if (!(type in components)) throw new GltfError('ACCESSOR_INVALID', `${where} has unsupported type ${JSON.stringify(type)}`);
        const ct = acc.componentType;
        if (!(ct in COMPONENT_TYPES)) throw new GltfError('ACCESSOR_INVALID', `${where} has unknown componentType ${JSON.stringify(ct)}`);
        const normalized = acc.normalized === undefined ? false : acc.normalized;
        if (typeof normalized !== 'boolean') throw new GltfError('GLTF_SCHEMA_VIOLATION', `${where}.normalized must be a boolean`);
        if (normalized && (ct === FLOAT || ct === UNSIGNED_INT)) {
            throw new GltfError('ACCESSOR_INVALID', `${where}: ${COMPONENT_TYPES[ct].name} accessors cannot be normalized`);
        }
        const count = acc.count;
        if (!isIndex(count)) throw new GltfError('ACCESSOR_INVALID', `${where}.count must be a non-negative integer`);
        if (acc.sparse !== undefined) throw new GltfError('ACCESSOR_UNSUPPORTED', `${where}: sparse accessors are not supported`);
        if (acc.bufferView === undefined) throw new GltfError('ACCESSOR_UNSUPPORTED', `${where} has no bufferView (compressed or placeholder data is not supported)`);
        const view = this.item('bufferViews', acc.bufferView, `${where}.bufferView`);
        const size = COMPONENT_TYPES[ct].size;
        const ncomp = components[type];
        const elem = size * ncomp;
        const offset = acc.byteOffset === undefined ? 0 : acc.byteOffset;
        if (!isIndex(offset)) throw new GltfError('ACCESSOR_INVALID', `${where}.byteOffset must be a non-negative integer`);
        if (offset % size) throw new GltfError('ACCESSOR_MISALIGNED', `${where}.byteOffset ${offset} is not a multiple of the component size ${size}`);
        const v = acc.bufferView;
        const buffer = this.buffer(view.buffer, `bufferViews[${v}].buffer`);
        const vOffset = view.byteOffset === undefined ? 0 : view.byteOffset;
        const vLength = view.byteLength;
        if (!isIndex(vOffset) || !isIndex(vLength)) throw new GltfError('GLTF_SCHEMA_VIOLATION', `bufferViews[${v}]: byteOffset and byteLength must be non-negative integers`);
        if (vOffset + vLength > buffer.byteLength) {
            throw new GltfError('BUFFER_VIEW_OUT_OF_BOUNDS', `bufferViews[${v}] (bytes ${vOffset}..${vOffset + vLength}) runs past the end of its buffer (${buffer.byteLength} bytes)`);
        }
        let stride = elem;
        if (view.byteStride !== undefined) {
            stride = view.byteStride;
            if (!isIndex(stride) || stride < 1) throw new GltfError('BUFFER_VIEW_STRIDE_INVALID', `bufferViews[${v}].byteStride must be a positive integer`);
            if (stride < elem) throw new GltfError('BUFFER_VIEW_STRIDE_INVALID', `bufferViews[${v}].byteStride ${stride} is smaller than the ${elem}-byte elements of ${where}`);
            if (stride % size) throw new GltfError('BUFFER_VIEW_STRIDE_INVALID', `bufferViews[${v}].byteStride ${stride} is not a multiple of the component size of ${where}`);
        }
        if (count) {
            const need = offset + stride * (count - 1) + elem;
            if (need > vLength) throw new GltfError('ACCESSOR_OUT_OF_BOUNDS', `${where} out of bounds: needs ${need} bytes of bufferViews[${v}] which has ${vLength}`);
        }
        return { index: i, type, componentType: ct, normalized, count, ncomp, size, stride, start: vOffset + offset, buffer };
    }

    /**
     * @param {unknown} index
     * @param {string} what
     * @returns {Uint8Array}
     */
    buffer(index, what) {
        this.item('buffers', index, what);
        return this.buffers[/** @type {number} */ (index)];
    }

    /**
     * The elements of accessor `index` in their stored component type, tightly packed
     * (byteStride and byteOffset honoured, little-endian).
     * @param {unknown} index
     * @param {string} what
     * @param {string[]} [types]  allowed accessor types; another is reported under `code`
     * @param {string} [code]
     * @returns {RawAccessor}
     */
    raw(index, what, types, code = 'ACCESSOR_INVALID') {
        if (types) {
            const acc = this.item('accessors', index, what);
            if (!types.includes(acc.type)) {
                throw new GltfError(code, `${what} (accessor ${index}) has type ${JSON.stringify(acc.type)}, expected ${types.join(' or ')}`);
            }
        }
        const L = this.layout(index, what);
        const n = L.count * L.ncomp;
        const at = L.buffer.byteOffset + L.start;
        if (LITTLE_ENDIAN && L.stride === L.size * L.ncomp && at % L.size === 0) {
            // tightly packed and aligned: one copy of the bytes
            const bytes = L.buffer.buffer.slice(at, at + n * L.size);
            /** @type {RawAccessor['values']} */
            let packed;
            switch (L.componentType) {
                case BYTE: packed = new Int8Array(bytes); break;
                case UNSIGNED_BYTE: packed = new Uint8Array(bytes); break;
                case SHORT: packed = new Int16Array(bytes); break;
                case UNSIGNED_SHORT: packed = new Uint16Array(bytes); break;
                case UNSIGNED_INT: packed = new Uint32Array(bytes); break;
                default: packed = new Float32Array(bytes); break;
            }
            return { index: L.index, type: L.type, componentType: L.componentType, normalized: L.normalized, count: L.count, ncomp: L.ncomp, values: packed };
        }
        const dv = new DataView(L.buffer.buffer, L.buffer.byteOffset, L.buffer.byteLength);
        /** @type {RawAccessor['values']} */
        let values;
        /** @type {(p: number) => number} */
        let get;
        switch (L.componentType) {
            case BYTE: values = new Int8Array(n); get = (p) => dv.getInt8(p); break;
            case UNSIGNED_BYTE: values = new Uint8Array(n); get = (p) => dv.getUint8(p); break;
            case SHORT: values = new Int16Array(n); get = (p) => dv.getInt16(p, true); break;
            case UNSIGNED_SHORT: values = new Uint16Array(n); get = (p) => dv.getUint16(p, true); break;
            case UNSIGNED_INT: values = new Uint32Array(n); get = (p) => dv.getUint32(p, true); break;
            default: values = new Float32Array(n); get = (p) => dv.getFloat32(p, true); break;
        }
        for (let e = 0; e < L.count; ++e) {
            const p0 = L.start + e * L.stride;
            for (let c = 0; c < L.ncomp; ++c) values[e * L.ncomp + c] = get(p0 + c * L.size);
        }
        return { index: L.index, type: L.type, componentType: L.componentType, normalized: L.normalized, count: L.count, ncomp: L.ncomp, values };
    }

    /**
     * The 4x4 matrices of a FLOAT MAT4 accessor (column-major, 16 numbers each; byteStride
     * and byteOffset honoured, little-endian). Another type or component type is reported
     * under `code`.
     * @param {unknown} index
     * @param {string} what
     * @param {string} [code]
     * @returns {{count: number, values: Float64Array}}
     */
    matrices(index, what, code = 'ACCESSOR_INVALID') {
        const acc = this.item('accessors', index, what);
        if (acc.type !== 'MAT4' || acc.componentType !== FLOAT || acc.normalized === true) {
            throw new GltfError(code, `${what} (accessor ${index}) is ${JSON.stringify(acc.type)} of component type ${JSON.stringify(acc.componentType)}; it must be MAT4 FLOAT`);
        }
        const L = this.layout(index, what, MATRIX_COMPONENTS);
        const dv = new DataView(L.buffer.buffer, L.buffer.byteOffset, L.buffer.byteLength);
        const values = new Float64Array(16 * L.count);
        for (let e = 0; e < L.count; ++e) {
            const p0 = L.start + e * L.stride;
            for (let c = 0; c < 16; ++c) values[16 * e + c] = dv.getFloat32(p0 + 4 * c, true);
        }
        return { count: L.count, values };
    }
}

/**
 * Values of a raw accessor as numbers per glTF 2.0 §3.11: FLOAT as stored; normalized unsigned
 * c / (2^n − 1); normalized signed max(c / (2^(n−1) − 1), −1); other integers as stored.
 * @param {RawAccessor} raw
 * @returns {Float64Array}
 */
export function dequantize(raw) {
    const out = new Float64Array(raw.values.length);
    const top = raw.normalized ? NORMALIZED_TOP[raw.componentType] : undefined;
    if (top === undefined) {
        for (let i = 0; i < out.length; ++i) out[i] = raw.values[i];
        return out;
    }
    const signed = raw.componentType === BYTE || raw.componentType === SHORT;
    for (let i = 0; i < out.length; ++i) {
        const v = raw.values[i] / top;
        out[i] = signed && v < -1 ? -1 : v;
    }
    return out;
}

/**
 * Array lengths against MAX_GLTF_ARRAY_ITEMS (SIZE_LIMIT_EXCEEDED), before any member is read.
 * @param {any} json
 */
function checkCounts(json) {
    for (const key of Object.keys(json)) {
        const value = json[key];
        if (Array.isArray(value) && value.length > MAX_GLTF_ARRAY_ITEMS) {
            throw new GltfError('SIZE_LIMIT_EXCEEDED', `the document has ${value.length} ${key}, more than the limit of ${MAX_GLTF_ARRAY_ITEMS}`);
        }
    }
    (Array.isArray(json.meshes) ? json.meshes : []).forEach((/** @type {any} */ mesh, /** @type {number} */ m) => {
        const prims = mesh && mesh.primitives;
        if (Array.isArray(prims) && prims.length > MAX_GLTF_ARRAY_ITEMS) {
            throw new GltfError('SIZE_LIMIT_EXCEEDED', `meshes[${m}] has ${prims.length} primitives, more than the limit of ${MAX_GLTF_ARRAY_ITEMS}`);
        }
    });
}

/**
 * Parse a .glb container or a .gltf JSON document (buffers as base64 data: URIs).
 * @param {Uint8Array|ArrayBuffer} input
 * @returns {GltfDocument}
 */
export function parseGltf(input) {
    const data = asBytes(input);
    /** @type {Uint8Array} */
    let jsonBytes;
    /** @type {Uint8Array|null} */
    let bin = null;
    const isGlb = data.byteLength >= 4 && data[0] === 0x67 && data[1] === 0x6c && data[2] === 0x54 && data[3] === 0x46;
    if (isGlb) {
        ({ json: jsonBytes, bin } = parseGlb(data));
    } else {
        let k = 0;
        while (k < data.byteLength && (data[k] === 0x20 || data[k] === 0x0a || data[k] === 0x0d || data[k] === 0x09 || data[k] === 0xef || data[k] === 0xbb || data[k] === 0xbf)) ++k;
        if (data[k] !== 0x7b) throw new GltfError('FILE_TYPE_UNSUPPORTED', 'neither a GLB container nor a glTF JSON document');
        jsonBytes = data;
    }
    let json;
    try {
        json = JSON.parse(new TextDecoder('utf-8', { fatal: true }).decode(jsonBytes));
    } catch (err) {
        throw new GltfError('JSON_INVALID', `invalid glTF JSON: ${/** @type {Error} */ (err).message}`);
    }
    if (typeof json !== 'object' || json === null || Array.isArray(json)) throw new GltfError('GLTF_SCHEMA_VIOLATION', 'the glTF JSON document must be an object');
    const version = json.asset && json.asset.version;
    if (typeof version !== 'string' || !/^2\.\d+$/.test(version)) {
        throw new GltfError('ASSET_VERSION_UNSUPPORTED', `unsupported glTF asset.version ${JSON.stringify(version)} (only 2.x)`);
    }
    for (const key of ['accessors', 'bufferViews', 'buffers', 'meshes', 'nodes']) {
        if (json[key] !== undefined && !Array.isArray(json[key])) throw new GltfError('GLTF_SCHEMA_VIOLATION', `${key} must be an array`);
    }
    checkCounts(json);
    /** @type {Uint8Array[]} */
    const buffers = [];
    const list = json.buffers || [];
    for (let b = 0; b < list.length; ++b) {
        const buf = list[b];
        const what = `buffers[${b}]`;
        if (typeof buf !== 'object' || buf === null) throw new GltfError('GLTF_SCHEMA_VIOLATION', `${what} must be an object`);
        /** @type {Uint8Array} */
        let bytes;
        if (buf.uri === undefined) {
            if (!isGlb || b !== 0 || !bin) throw new GltfError('BUFFER_MISSING_DATA', `${what} has no uri and there is no GLB binary chunk for it`);
            bytes = bin;
        } else if (typeof buf.uri === 'string') {
            bytes = dataUri(buf.uri, what);
        } else {
            throw new GltfError('GLTF_SCHEMA_VIOLATION', `${what}.uri must be a string`);
        }
        if (!isIndex(buf.byteLength)) throw new GltfError('GLTF_SCHEMA_VIOLATION', `${what}.byteLength must be a non-negative integer`);
        if (bytes.byteLength < buf.byteLength) {
            throw new GltfError('BUFFER_TOO_SHORT', `${what} declares ${buf.byteLength} bytes but holds ${bytes.byteLength}`);
        }
        buffers.push(bytes.subarray(0, buf.byteLength));
    }
    return new GltfDocument(json, buffers);
}

/**
 * The local matrix of a glTF node (column-major 4x4): `matrix`, or T * R * S.
 * @param {any} node
 * @returns {Float64Array}
 */
export function nodeLocalMatrix(node) {
    const m = new Float64Array(16);
    if (Array.isArray(node.matrix) && node.matrix.length === 16) {
        for (let i = 0; i < 16; ++i) m[i] = node.matrix[i];
        return m;
    }
    const t = Array.isArray(node.translation) ? node.translation : [0, 0, 0];
    const q = Array.isArray(node.rotation) ? node.rotation : [0, 0, 0, 1];
    const s = Array.isArray(node.scale) ? node.scale : [1, 1, 1];
    const [x, y, z, w] = q;
    const r = [
        1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y),
        2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x),
        2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y),
    ]; // column-major 3x3
    for (let c = 0; c < 3; ++c) for (let row = 0; row < 3; ++row) m[4 * c + row] = r[3 * c + row] * s[c];
    m[12] = t[0]; m[13] = t[1]; m[14] = t[2]; m[15] = 1;
    return m;
}

/**
 * @param {Float64Array} a column-major 4x4
 * @param {Float64Array} b column-major 4x4
 * @returns {Float64Array} a * b
 */
export function mat4Multiply(a, b) {
    const out = new Float64Array(16);
    for (let c = 0; c < 4; ++c) {
        for (let r = 0; r < 4; ++r) {
            let s = 0;
            for (let k = 0; k < 4; ++k) s += a[4 * k + r] * b[4 * c + k];
            out[4 * c + r] = s;
        }
    }
    return out;
}

/**
 * The parent of every node (−1 for a root), from `children`. A child index out of range is
 * UNRESOLVED_REFERENCE, a node with two parents NODE_GRAPH_INVALID (the validator's code).
 * @param {any} json
 * @returns {Int32Array}
 */
export function nodeParents(json) {
    const nodes = Array.isArray(json.nodes) ? json.nodes : [];
    const parent = new Int32Array(nodes.length).fill(-1);
    nodes.forEach((/** @type {any} */ node, /** @type {number} */ i) => {
        for (const c of (node && Array.isArray(node.children)) ? node.children : []) {
            if (!isIndex(c) || c >= nodes.length) throw new GltfError('UNRESOLVED_REFERENCE', `nodes[${i}].children: node ${JSON.stringify(c)} out of range`);
            if (parent[c] !== -1) throw new GltfError('NODE_GRAPH_INVALID', `node ${c} has more than one parent`);
            parent[c] = i;
        }
    });
    return parent;
}

/**
 * The global matrix of every node (column-major), parents from `children`.
 * A node in a cycle or with two parents is reported as NODE_GRAPH_INVALID.
 * Iterative (no recursion): a hierarchy of any depth, each node's matrix computed once.
 * @param {any} json
 * @returns {Float64Array[]}
 */
export function globalMatrices(json) {
    const nodes = Array.isArray(json.nodes) ? json.nodes : [];
    const parent = nodeParents(json);
    /** @type {(Float64Array|undefined)[]} */
    const out = new Array(nodes.length);
    /** @type {number[]} */
    const chain = [];
    for (let i = 0; i < nodes.length; ++i) {
        // walk up to a solved node or a root, then solve the chain from the top down
        chain.length = 0;
        for (let j = i; j >= 0 && !out[j]; j = parent[j]) {
            if (chain.length >= nodes.length) throw new GltfError('NODE_GRAPH_INVALID', `the node hierarchy has a cycle through node ${i}`);
            chain.push(j);
        }
        for (let k = chain.length - 1; k >= 0; --k) {
            const n = chain[k];
            const local = nodeLocalMatrix(nodes[n] || {});
            out[n] = parent[n] < 0 ? local : mat4Multiply(/** @type {Float64Array} */ (out[parent[n]]), local);
        }
    }
    return /** @type {Float64Array[]} */ (out);
}
