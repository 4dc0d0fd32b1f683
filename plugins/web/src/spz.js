// KHR_gaussian_splatting_compression_spz_2 (spec/README.md §SPZ-compressed rest pose): a splat
// primitive's rest pose stored as one gzip member holding an SPZ stream (versions 2 and 3), its
// attributes kept as placeholder accessors without a bufferView. Engine-free, no dependency:
// gunzip is the platform's DecompressionStream('gzip') (browsers, Node >= 18), which is
// asynchronous, so a compressed asset is first *expanded* (expandCompressed): the stream decoded
// and written back as plain FLOAT accessors, the SPZ extension removed; everything else
// (readAnchoredGlb, PlayCanvas's own glTF parser, Spark) then sees a plain KHR asset. Refusals
// throw AnchorError with the gsverse-validate codes of the Python reader
// (gsverse_format/io/gltf/spz.py).

import { AnchorError, EXTENSION, KHR, SPZ_EXTENSION, shDegree } from './anchor.js';
import { crc32 } from './crc32.js';
import { FLOAT, GltfError, UNSIGNED_BYTE, UNSIGNED_SHORT, isIndex, parseGltf } from './glb.js';

export { SPZ_EXTENSION };

const MAGIC = 0x5053474e;   // 'NGSP'
const HEADER_BYTES = 16;
const COLOR_SCALE = 0.15;
const SQRT1_2 = 0.7071067811865476;
/** The SH degree-0 basis constant of the fallback colour, as the draft's table writes it. */
const COLOR_C0 = 0.282095;
/**
 * Signs of SH coefficient k = 0..15 under SPZ's RUB -> glTF turn (180 degrees about Y);
 * positions and quaternions change the sign of x and z.
 */
export const SH_SIGNS = [1, 1, -1, -1, -1, -1, 1, 1, 1, 1, 1, 1, -1, -1, -1, -1];
/**
 * Float32 attribute bytes N splats may decode to: at most this many times the bytes of their
 * stream plus READ_AMPLIFICATION_SLACK (the Python reader's `limits.MAX_SPZ_AMPLIFICATION`);
 * checked before anything is inflated.
 */
export const MAX_SPZ_AMPLIFICATION = 64;
const READ_AMPLIFICATION_SLACK = 2 ** 26;
/**
 * Compressed bytes handed to the decompressor at a time: deflate expands a byte to at most
 * about 1032, so one slice inflates to at most about 64 MiB before the byte cap is checked.
 */
const INFLATE_SLICE = 1 << 16;

/**
 * Bytes of a stream of `count` splats (header and attributes) of `version` and SH `degree`.
 * @param {number} version @param {number} count @param {number} degree
 */
export function streamBytes(version, count, degree) {
    return HEADER_BYTES + count * (9 + 1 + 3 + 3 + (version >= 3 ? 4 : 3) + 3 * ((degree + 1) ** 2 - 1));
}

/**
 * The most bytes the stream of `count` splats may inflate to (version 3, SH degree 3: the
 * longest stream of that many splats); inflation stops there.
 * @param {number} count
 */
export function streamLimit(count) {
    return streamBytes(3, count, 3);
}

/**
 * Inflate one gzip member with the platform's DecompressionStream, fed in slices and read as
 * it goes: more than `limit` output bytes stop the work and refuse (a compression bomb never
 * inflates past `limit` plus one slice's output).
 * @param {Uint8Array} raw
 * @param {number} limit
 * @returns {Promise<{out: Uint8Array, error: string|null, over: boolean, fed: number}>}
 *   out: what it inflated to (empty when over); error: the decompressor's complaint; over: more
 *   than `limit` bytes came out; fed: the compressed bytes handed over before it stopped
 */
export async function inflateSliced(raw, limit) {
    const ds = new DecompressionStream('gzip');
    const writer = ds.writable.getWriter();
    const reader = ds.readable.getReader();
    let fed = 0;
    const feeding = (async () => {
        for (let p = 0; p < raw.length; p += INFLATE_SLICE) {
            await writer.write(/** @type {Uint8Array<ArrayBuffer>} */ (raw.subarray(p, p + INFLATE_SLICE)));
            fed = Math.min(raw.length, p + INFLATE_SLICE);
        }
        await writer.close();
    })().catch(() => {});   // the reader below reports every failure
    /** @type {Uint8Array[]} */
    const chunks = [];
    let total = 0;
    let error = null;
    let over = false;
    try {
        for (;;) {
            const { done, value } = await reader.read();
            if (done) break;
            total += value.byteLength;
            if (total > limit) { over = true; break; }
            chunks.push(value);
        }
    } catch (err) {
        error = /** @type {Error} */ (err).message || String(err);
    }
    if (over) {
        await reader.cancel().catch(() => {});
        await writer.abort().catch(() => {});
    }
    await feeding;
    const out = new Uint8Array(over ? 0 : total);
    let o = 0;
    if (!over) for (const c of chunks) { out.set(c, o); o += c.byteLength; }
    return { out, error, over, fed };
}

/**
 * The content of the single gzip member `raw`, refused (SPZ_STREAM_INVALID) past `limit`
 * bytes without inflating further, when broken, truncated, or followed by anything but zero
 * bytes. The member's end is found by its trailer (CRC-32 and length of what it inflated to),
 * so browsers (which refuse any byte after the member) and Node (which ignores some) agree.
 * Browsers refuse zero padding too: when `sizes` (the lengths the content may have) say where
 * the member ends before its padding (its trailer's last 4 bytes are the content's length),
 * only the member is handed over.
 * @param {Uint8Array} raw
 * @param {number} limit
 * @param {string} where
 * @param {number[]} [sizes]
 * @returns {Promise<Uint8Array>}
 */
export async function inflateBounded(raw, limit, where, sizes = []) {
    if (typeof DecompressionStream !== 'function') {
        throw new AnchorError('SPZ_STREAM_INVALID', `${where}: this platform has no DecompressionStream('gzip') to inflate the SPZ stream`);
    }
    let end = raw.length;
    while (end > 0 && raw[end - 1] === 0) --end;      // the member ends at or after `end`
    let member = raw;
    for (let e = Math.max(end, 18); e <= Math.min(raw.length, end + 4) && member === raw && end < raw.length; ++e) {
        const isize = new DataView(raw.buffer, raw.byteOffset + e - 4, 4).getUint32(0, true);
        if (sizes.includes(isize)) member = raw.subarray(0, e);
    }
    const { out, error, over } = await inflateSliced(member, limit);
    if (over) throw new AnchorError('SPZ_STREAM_INVALID', `${where}: the SPZ stream inflates to more than the ${limit} bytes its splats hold`);
    const crc = crc32(out);
    const size = out.length >>> 0;
    let found = -1;
    for (let e = Math.max(end, 18); e <= raw.length && found < 0; ++e) {
        const dv = new DataView(raw.buffer, raw.byteOffset + e - 8, 8);
        if (dv.getUint32(0, true) === crc && dv.getUint32(4, true) === size) found = e;
    }
    if (found < 0) {
        const cause = error ? `broken or truncated gzip stream of SPZ data (${error})` : 'bytes other than zero padding follow the gzip member of SPZ data';
        throw new AnchorError('SPZ_STREAM_INVALID', `${where}: ${cause}`);
    }
    return out;
}

/**
 * The header of an inflated stream, checked (SPZ_STREAM_INVALID): the magic, version 2 or 3,
 * SH degree <= 3, at most 24 fractional bits, no extension records (flag bit 1).
 * @param {Uint8Array} data
 * @param {string} where
 * @returns {{version: number, count: number, degree: number, fractionalBits: number, flags: number}}
 */
export function parseSpzHeader(data, where) {
    const bad = (/** @type {string} */ why) => new AnchorError('SPZ_STREAM_INVALID', `${where}: ${why}`);
    if (data.length < HEADER_BYTES) throw bad(`the SPZ stream holds ${data.length} bytes, less than its ${HEADER_BYTES}-byte header`);
    const dv = new DataView(data.buffer, data.byteOffset, HEADER_BYTES);
    if (dv.getUint32(0, true) !== MAGIC) throw bad('not an SPZ stream (no NGSP magic)');
    const version = dv.getUint32(4, true);
    if (version !== 2 && version !== 3) throw bad(`SPZ version ${version} in a gzip stream is not supported (versions 2 and 3 are)`);
    const count = dv.getUint32(8, true);
    const degree = data[12];
    const fractionalBits = data[13];
    const flags = data[14];
    if (degree > 3) throw bad(`SPZ SH degree ${degree} is not supported (0..3)`);
    if (fractionalBits > 24) throw bad(`${fractionalBits} fractional bits is more than the 24 a position has`);
    return { version, count, degree, fractionalBits, flags };
}

/**
 * Deliberately broken decodings (testing only: the conformance suite must catch them):
 * `spz-frame` keeps SPZ's RUB frame (no negated x and z), `spz-sh-signs` leaves the SH
 * coefficients' signs as stored.
 */
export const SPZ_FAULTS = Object.freeze(['spz-frame', 'spz-sh-signs']);

/**
 * The decoded splats of a whole stream (spec's decoding table): binary64, then float32, in
 * glTF's frame (x and z of positions and quaternions negated, SH coefficient k times
 * SH_SIGNS[k]), quaternions normalized. `sh` holds (degree+1)^2 RGB coefficients per splat.
 * @param {Uint8Array} data  the inflated stream, its length already checked
 * @param {{version: number, count: number, degree: number, fractionalBits: number}} h
 * @param {string|null} [fault]  one of SPZ_FAULTS (testing only)
 */
export function decodeSpz(data, h, fault = null) {
    if (fault !== null && !SPZ_FAULTS.includes(fault)) throw new Error(`unknown SPZ fault '${fault}' (known: ${SPZ_FAULTS.join(', ')})`);
    const turn = fault === 'spz-frame' ? 1 : -1;
    const signs = fault === 'spz-sh-signs' ? SH_SIGNS.map(() => 1) : SH_SIGNS;
    const n = h.count;
    const K = (h.degree + 1) ** 2;
    const means = new Float32Array(3 * n);
    const rotations = new Float32Array(4 * n);
    const scales = new Float32Array(3 * n);
    const opacity = new Float32Array(n);
    const sh = new Float32Array(3 * K * n);
    let o = HEADER_BYTES;
    const step = 2 ** h.fractionalBits;
    const axis = [turn, 1, turn];
    for (let i = 0; i < 3 * n; ++i, o += 3) {
        let q = data[o] | (data[o + 1] << 8) | (data[o + 2] << 16);
        if (q & 0x800000) q -= 0x1000000;
        means[i] = axis[i % 3] * (q / step);
    }
    for (let i = 0; i < n; ++i) opacity[i] = data[o++] / 255;
    for (let i = 0; i < n; ++i) for (let c = 0; c < 3; ++c) sh[3 * K * i + c] = (data[o++] / 255 - 0.5) / COLOR_SCALE;
    for (let i = 0; i < 3 * n; ++i) scales[i] = Math.exp(data[o++] / 16 - 10);
    const q = [0, 0, 0, 0];
    const dv = new DataView(data.buffer, data.byteOffset, data.byteLength);
    for (let i = 0; i < n; ++i) {
        if (h.version >= 3) {
            let comp = dv.getUint32(o, true);
            o += 4;
            const largest = comp >>> 30;
            let sum = 0;
            for (let k = 3; k >= 0; --k) {
                if (k === largest) continue;
                const v = SQRT1_2 * (comp & 511) / 511;
                q[k] = (comp >>> 9) & 1 ? -v : v;
                sum += q[k] * q[k];
                comp >>>= 10;
            }
            q[largest] = Math.sqrt(Math.max(0, 1 - sum));
        } else {
            q[0] = data[o] / 127.5 - 1; q[1] = data[o + 1] / 127.5 - 1; q[2] = data[o + 2] / 127.5 - 1;
            o += 3;
            q[3] = Math.sqrt(Math.max(0, 1 - q[0] * q[0] - q[1] * q[1] - q[2] * q[2]));
        }
        const x = turn * q[0], y = q[1], z = turn * q[2], w = q[3];
        const len = Math.sqrt(x * x + y * y + z * z + w * w);
        rotations[4 * i] = x / len; rotations[4 * i + 1] = y / len; rotations[4 * i + 2] = z / len; rotations[4 * i + 3] = w / len;
    }
    for (let i = 0; i < n; ++i) {
        for (let k = 1; k < K; ++k) {
            for (let c = 0; c < 3; ++c) sh[3 * (K * i + k) + c] = signs[k] * ((data[o++] - 128) / 128);
        }
    }
    return { count: n, degree: h.degree, means, rotations, scales, opacity, sh };
}

/** @param {any} khr @returns {boolean} */
function nestsSpz(khr) {
    const nested = khr && typeof khr === 'object' ? khr.extensions : null;
    return !!nested && typeof nested === 'object' && nested[SPZ_EXTENSION] !== undefined;
}

/**
 * Whether a parsed glTF document has a primitive stored through the SPZ extension.
 * @param {any} json
 */
export function hasCompressedPrimitives(json) {
    for (const mesh of Array.isArray(json.meshes) ? json.meshes : []) {
        for (const prim of mesh && Array.isArray(mesh.primitives) ? mesh.primitives : []) {
            if (prim && prim.extensions && nestsSpz(prim.extensions[KHR])) return true;
        }
    }
    return false;
}

const ROTATION = `${KHR}:ROTATION`;
const SCALE = `${KHR}:SCALE`;
const OPACITY = `${KHR}:OPACITY`;
/** @param {number} k */
const shName = (k) => { const l = Math.floor(Math.sqrt(k)); return `${KHR}:SH_DEGREE_${l}_COEF_${k - l * l}`; };

/**
 * Decode one compressed primitive (its placeholders checked as the Python reader does).
 * @param {import('./glb.js').GltfDocument} doc
 * @param {any} prim
 * @param {string} where
 * @param {string|null} fault
 */
async function decodePrimitive(doc, prim, where, fault) {
    const json = doc.json;
    const khr = prim.extensions[KHR];
    const attrs = prim.attributes && typeof prim.attributes === 'object' ? prim.attributes : {};
    const missing = ['POSITION', ROTATION, SCALE, OPACITY].filter((a) => !(a in attrs));
    if (missing.length) throw new AnchorError('KHR_ATTRIBUTE_MISSING', `${where}: required ${KHR} attribute(s) missing: ${missing.join(', ')}`);
    const degree = shDegree(attrs, where);
    /** @type {{[name: string]: string[]}} */
    const expected = { POSITION: ['VEC3'], [ROTATION]: ['VEC4'], [SCALE]: ['VEC3'], [OPACITY]: ['SCALAR'], COLOR_0: ['VEC3', 'VEC4'] };
    for (let k = 0; k < (degree + 1) ** 2; ++k) expected[shName(k)] = ['VEC3'];
    /** @type {{[name: string]: number}} */
    const counts = {};
    for (const [name, types] of Object.entries(expected)) {
        if (!(name in attrs)) continue;
        const acc = doc.item('accessors', attrs[name], `${where} ${name}: accessor`);
        if (!types.includes(acc.type)) {
            throw new AnchorError('KHR_ATTRIBUTE_FORMAT', `${where} ${name} (accessor ${attrs[name]}) has type ${JSON.stringify(acc.type)}, not ${types.join(' or ')}`);
        }
        counts[name] = isIndex(acc.count) ? acc.count : 0;
    }
    const count = counts.POSITION;
    const wrong = Object.keys(counts).find((name) => counts[name] !== count);
    if (wrong !== undefined) {
        throw new AnchorError('SPZ_COUNT_MISMATCH', `${where}: ${wrong} has ${counts[wrong]} elements, POSITION has ${count} (the placeholders of a compressed primitive must all have the stream's count)`);
    }
    if (degree < 0) throw new AnchorError('KHR_ATTRIBUTE_MISSING', `${where}: required ${KHR} attribute missing: ${shName(0)}`);
    const anchor = khr.extensions[EXTENSION];
    if (anchor && typeof anchor === 'object' && (anchor.profile === 'games' || anchor.barycentrics !== undefined)) {
        throw new AnchorError('SPZ_EXPLICIT_ANCHORS', `${where}: a compressed rest pose carries stored (${anchor.profile === 'games' ? 'games' : 'explicit local'}) anchors; only derived local anchors may be stored with ${SPZ_EXTENSION} (its quantization exceeds the rest-pose consistency the stored anchors need)`);
    }
    const obj = khr.extensions[SPZ_EXTENSION];
    const what = `${where} ${SPZ_EXTENSION}`;
    if (typeof obj !== 'object' || obj === null || Array.isArray(obj) || !('bufferView' in obj)) {
        throw new AnchorError('SPZ_BUFFER_VIEW_INVALID', `${what} must be an object with a bufferView`);
    }
    const views = Array.isArray(json.bufferViews) ? json.bufferViews : [];
    const v = obj.bufferView;
    if (!isIndex(v) || v >= views.length || typeof views[v] !== 'object' || views[v] === null) {
        throw new AnchorError('SPZ_BUFFER_VIEW_INVALID', `${what}.bufferView ${JSON.stringify(v)} does not index a buffer view (${views.length} bufferViews)`);
    }
    const view = views[v];
    let buffer;
    try {
        buffer = doc.buffer(view.buffer, `bufferViews[${v}].buffer`);
    } catch (err) {
        throw new AnchorError('SPZ_BUFFER_VIEW_INVALID', `${what}: ${/** @type {Error} */ (err).message}`);
    }
    const offset = view.byteOffset === undefined ? 0 : view.byteOffset;
    const length = view.byteLength;
    if (!isIndex(offset) || !isIndex(length) || offset + length > buffer.byteLength) {
        throw new AnchorError('SPZ_BUFFER_VIEW_INVALID', `${what}: bufferViews[${v}] does not lie inside its buffer (${buffer.byteLength} bytes)`);
    }
    const decoded = count * (4 * (3 + 4 + 3 + 1 + 3 * (degree + 1) ** 2) + 4);
    if (decoded > MAX_SPZ_AMPLIFICATION * length + READ_AMPLIFICATION_SLACK) {
        throw new AnchorError('SIZE_LIMIT_EXCEEDED', `${what}: ${count} splats would decode to ${decoded} bytes, more than ${MAX_SPZ_AMPLIFICATION} times the ${length} bytes of their stream`);
    }
    const whereStream = `${what} (bufferViews[${v}])`;
    const sizes = [streamBytes(3, count, degree), streamBytes(2, count, degree)];
    const data = await inflateBounded(buffer.subarray(offset, offset + length), streamLimit(count), whereStream, sizes);
    const h = parseSpzHeader(data, whereStream);
    if (h.count !== count) throw new AnchorError('SPZ_COUNT_MISMATCH', `${whereStream} holds ${h.count} splats but the primitive's accessors have ${count}`);
    if (h.degree !== degree) throw new AnchorError('SPZ_SH_MISMATCH', `${whereStream} has SH degree ${h.degree} but the primitive's SH attributes are of degree ${degree}`);
    if (h.flags & 2) throw new AnchorError('SPZ_STREAM_INVALID', `${whereStream} carries SPZ extension records (flag bit 1), which the glTF extension does not allow`);
    const need = streamBytes(h.version, count, degree);
    if (data.length !== need) {
        throw new AnchorError('SPZ_STREAM_INVALID', `${whereStream} inflates to ${data.length} bytes; ${count} splats of SH degree ${degree} in version ${h.version} take ${need}`);
    }
    return decodeSpz(data, h, fault);
}

/**
 * The fallback colour (0.5 + 0.282095 f_dc clamped to [0, 1], opacity) in the placeholder's
 * component type (FLOAT, or normalized UNSIGNED_BYTE / UNSIGNED_SHORT rounded to nearest).
 * @param {ReturnType<typeof decodeSpz>} s
 * @param {any} acc
 */
function fallbackColor(s, acc) {
    const ncomp = acc.type === 'VEC3' ? 3 : 4;
    const K = (s.degree + 1) ** 2;
    const top = acc.componentType === UNSIGNED_BYTE ? 255 : acc.componentType === UNSIGNED_SHORT ? 65535 : 0;
    const out = top === 255 ? new Uint8Array(ncomp * s.count) : top ? new Uint16Array(ncomp * s.count) : new Float32Array(ncomp * s.count);
    for (let i = 0; i < s.count; ++i) {
        for (let c = 0; c < ncomp; ++c) {
            const x = c < 3 ? Math.min(Math.max(0.5 + COLOR_C0 * s.sh[3 * K * i + c], 0), 1) : s.opacity[i];
            out[ncomp * i + c] = top ? Math.round(x * top) : x;
        }
    }
    return out;
}

/**
 * Expand every SPZ-compressed primitive of a GLB (or .gltf with data: URIs): the streams
 * decoded (spec §SPZ-compressed rest pose) and written as plain accessors (FLOAT, COLOR_0 in
 * its placeholder's component type) in new buffer views appended to the binary chunk (or, for
 * .gltf, a new data: URI buffer), the extension object removed from each primitive and the
 * name from extensionsUsed and extensionsRequired; every other member, index and byte is
 * kept. An asset without compressed primitives comes back as it is (the same bytes). Refusals
 * throw AnchorError naming the file (`options.name`).
 * @param {Uint8Array|ArrayBuffer} bytes
 * @param {{name?: string, fault?: string|null}} [options]  fault: one of SPZ_FAULTS (testing only)
 * @returns {Promise<Uint8Array>}
 */
export async function expandCompressed(bytes, options = {}) {
    const name = options.name || 'asset';
    const fault = options.fault ?? null;
    if (fault !== null && !SPZ_FAULTS.includes(fault)) throw new Error(`unknown SPZ fault '${fault}' (known: ${SPZ_FAULTS.join(', ')})`);
    const input = bytes instanceof Uint8Array ? bytes : new Uint8Array(bytes);
    try {
        const doc = parseGltf(input);
        const json = doc.json;
        if (!hasCompressedPrimitives(json)) return input;
        const isGlb = input[0] === 0x67 && input[1] === 0x6c && input[2] === 0x54 && input[3] === 0x46;
        const appendToBin = isGlb && Array.isArray(json.buffers) && json.buffers.length > 0 && json.buffers[0].uri === undefined;
        const base = appendToBin ? doc.buffers[0].byteLength : 0;
        /** @type {Uint8Array[]} */
        const parts = [];
        let size = base;
        const bufferIndex = appendToBin ? 0 : (Array.isArray(json.buffers) ? json.buffers.length : 0);
        json.bufferViews = Array.isArray(json.bufferViews) ? json.bufferViews : [];
        /** @param {ArrayBufferView} arr @returns {number} the new buffer view */
        const addView = (arr) => {
            const pad = (4 - (size % 4)) % 4;
            if (pad) { parts.push(new Uint8Array(pad)); size += pad; }
            parts.push(new Uint8Array(arr.buffer, arr.byteOffset, arr.byteLength));
            json.bufferViews.push({ buffer: bufferIndex, byteOffset: size, byteLength: arr.byteLength });
            size += arr.byteLength;
            return json.bufferViews.length - 1;
        };
        const rewritten = new Set();
        const meshes = Array.isArray(json.meshes) ? json.meshes : [];
        for (let m = 0; m < meshes.length; ++m) {
            const prims = meshes[m] && Array.isArray(meshes[m].primitives) ? meshes[m].primitives : [];
            for (let p = 0; p < prims.length; ++p) {
                const prim = prims[p];
                const khr = prim && prim.extensions ? prim.extensions[KHR] : undefined;
                if (!nestsSpz(khr)) continue;
                const s = await decodePrimitive(doc, prim, `meshes[${m}].primitives[${p}]`, fault);
                const K = (s.degree + 1) ** 2;
                /** @type {{[name: string]: ArrayBufferView}} */
                const values = { POSITION: s.means, [ROTATION]: s.rotations, [SCALE]: s.scales, [OPACITY]: s.opacity };
                for (let k = 0; k < K; ++k) {
                    const coef = new Float32Array(3 * s.count);
                    for (let i = 0; i < s.count; ++i) for (let c = 0; c < 3; ++c) coef[3 * i + c] = s.sh[3 * (K * i + k) + c];
                    values[shName(k)] = coef;
                }
                if ('COLOR_0' in prim.attributes) values.COLOR_0 = fallbackColor(s, json.accessors[prim.attributes.COLOR_0]);
                for (const [attr, arr] of Object.entries(values)) {
                    let index = prim.attributes[attr];
                    const old = json.accessors[index];
                    const acc = { ...old, bufferView: addView(arr) };
                    delete acc.byteOffset;
                    delete acc.sparse;
                    if (attr !== 'COLOR_0') acc.componentType = FLOAT;
                    if (attr === 'POSITION') {
                        // the bounds of the decoded positions (a placeholder's may be missing)
                        const lo = [Infinity, Infinity, Infinity];
                        const hi = [-Infinity, -Infinity, -Infinity];
                        for (let i = 0; i < s.means.length; ++i) {
                            lo[i % 3] = Math.min(lo[i % 3], s.means[i]);
                            hi[i % 3] = Math.max(hi[i % 3], s.means[i]);
                        }
                        if (s.count) { acc.min = lo; acc.max = hi; }
                    }
                    if (rewritten.has(index)) {
                        json.accessors.push(acc);         // a placeholder two primitives share
                        index = json.accessors.length - 1;
                        prim.attributes[attr] = index;
                    } else {
                        json.accessors[index] = acc;
                    }
                    rewritten.add(index);
                }
                delete khr.extensions[SPZ_EXTENSION];
                if (!Object.keys(khr.extensions).length) delete khr.extensions;
            }
        }
        for (const key of ['extensionsUsed', 'extensionsRequired']) {
            if (!Array.isArray(json[key])) continue;
            json[key] = json[key].filter((/** @type {unknown} */ e) => e !== SPZ_EXTENSION);
            if (!json[key].length) delete json[key];
        }
        const pad = (4 - (size % 4)) % 4;
        if (pad) { parts.push(new Uint8Array(pad)); size += pad; }
        const added = new Uint8Array(size - base);
        let o = 0;
        for (const part of parts) { added.set(part, o); o += part.byteLength; }
        if (appendToBin) {
            const bin = new Uint8Array(size);
            bin.set(doc.buffers[0], 0);
            bin.set(added, base);
            json.buffers[0].byteLength = size;
            return writeGlb(json, bin);
        }
        json.buffers = Array.isArray(json.buffers) ? json.buffers : [];
        json.buffers.push({ byteLength: added.byteLength, uri: `data:application/octet-stream;base64,${toBase64(added)}` });
        if (isGlb) return writeGlb(json, null);
        return new TextEncoder().encode(JSON.stringify(json));
    } catch (err) {
        if (err instanceof AnchorError || err instanceof GltfError) throw new AnchorError(err.code, `${name}: ${err.message}`);
        throw err;
    }
}

/** @param {Uint8Array} bytes */
function toBase64(bytes) {
    const alphabet = 'ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/';
    let out = '';
    for (let i = 0; i < bytes.length; i += 3) {
        const a = bytes[i], b = i + 1 < bytes.length ? bytes[i + 1] : 0, c = i + 2 < bytes.length ? bytes[i + 2] : 0;
        out += alphabet[a >> 2] + alphabet[((a & 3) << 4) | (b >> 4)]
            + (i + 1 < bytes.length ? alphabet[((b & 15) << 2) | (c >> 6)] : '=')
            + (i + 2 < bytes.length ? alphabet[c & 63] : '=');
    }
    return out;
}

/**
 * A GLB of `json` and the binary chunk `bin` (none when null).
 * @param {any} json
 * @param {Uint8Array|null} bin
 */
function writeGlb(json, bin) {
    const text = new TextEncoder().encode(JSON.stringify(json));
    const jsonPad = (4 - (text.length % 4)) % 4;
    const jsonLen = text.length + jsonPad;
    const binLen = bin ? bin.length : 0;
    const total = 12 + 8 + jsonLen + (bin ? 8 + binLen : 0);
    const out = new Uint8Array(total);
    const dv = new DataView(out.buffer);
    dv.setUint32(0, 0x46546c67, true);
    dv.setUint32(4, 2, true);
    dv.setUint32(8, total, true);
    dv.setUint32(12, jsonLen, true);
    dv.setUint32(16, 0x4e4f534a, true);
    out.set(text, 20);
    out.fill(0x20, 20 + text.length, 20 + jsonLen);
    if (bin) {
        dv.setUint32(20 + jsonLen, binLen, true);
        dv.setUint32(24 + jsonLen, 0x004e4942, true);
        out.set(bin, 28 + jsonLen);
    }
    return out;
}
