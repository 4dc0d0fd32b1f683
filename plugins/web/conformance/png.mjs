// PNG encoding of the pictures a render harness writes (8-bit RGB, no interlace), with Node's
// zlib: what `gsverse-conformance check` reads back for the render cases.

import { deflateSync } from 'node:zlib';

import { crc32 } from '../src/crc32.js';

/**
 * @param {string} type  four ASCII letters
 * @param {Uint8Array} data
 */
function chunk(type, data) {
    const out = new Uint8Array(12 + data.length);
    const view = new DataView(out.buffer);
    view.setUint32(0, data.length);
    for (let i = 0; i < 4; ++i) out[4 + i] = type.charCodeAt(i);
    out.set(data, 8);
    view.setUint32(8 + data.length, crc32(out.subarray(4, 8 + data.length)));
    return out;
}

/**
 * Encode top-down RGBA8 pixels as an 8-bit RGB PNG (alpha dropped: the pictures are opaque,
 * drawn over black).
 * @param {number} width
 * @param {number} height
 * @param {Uint8Array} rgba  width * height * 4 bytes, rows top to bottom
 * @returns {Uint8Array}
 */
export function encodePngRgb(width, height, rgba) {
    if (rgba.length !== width * height * 4) throw new RangeError(`expected ${width * height * 4} bytes of RGBA, got ${rgba.length}`);
    const raw = new Uint8Array(height * (1 + 3 * width));
    for (let y = 0; y < height; ++y) {
        const row = y * (1 + 3 * width);
        raw[row] = 0;   // filter: none
        for (let x = 0; x < width; ++x) {
            const s = 4 * (y * width + x), d = row + 1 + 3 * x;
            raw[d] = rgba[s];
            raw[d + 1] = rgba[s + 1];
            raw[d + 2] = rgba[s + 2];
        }
    }
    const header = new Uint8Array(13);
    const hv = new DataView(header.buffer);
    hv.setUint32(0, width);
    hv.setUint32(4, height);
    header.set([8, 2, 0, 0, 0], 8);   // 8 bits, RGB, deflate, no filter method, no interlace
    const parts = [new Uint8Array([137, 80, 78, 71, 13, 10, 26, 10]), chunk('IHDR', header),
        chunk('IDAT', new Uint8Array(deflateSync(raw))), chunk('IEND', new Uint8Array(0))];
    const out = new Uint8Array(parts.reduce((n, p) => n + p.length, 0));
    let o = 0;
    for (const p of parts) { out.set(p, o); o += p.length; }
    return out;
}
