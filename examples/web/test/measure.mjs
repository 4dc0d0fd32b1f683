// Image measurements for the screenshot test: silhouette of the rendered splats on the plain
// test background, and the horizontal shift of the surface texture between two images.

/** @typedef {{width: number, height: number, rgba: Uint8Array}} Image */

/**
 * Silhouette of everything brighter than the (black) background.
 * @param {Image} img
 * @param {{threshold?: number, minCount?: number}} [options]
 *   threshold: largest channel value that counts as background; minCount: pixels a row or column
 *   needs to count (ignores stray halo pixels)
 */
export function silhouette(img, options = {}) {
    const threshold = options.threshold ?? 40, minCount = options.minCount ?? 4;
    const { width, height, rgba } = img;
    const rows = new Uint32Array(height), cols = new Uint32Array(width);
    let area = 0;
    for (let y = 0; y < height; y++) {
        for (let x = 0; x < width; x++) {
            const i = 4 * (y * width + x);
            if (Math.max(rgba[i], rgba[i + 1], rgba[i + 2]) > threshold) {
                rows[y]++; cols[x]++; area++;
            }
        }
    }
    const span = (/** @type {Uint32Array} */ c) => {
        let lo = -1, hi = -1;
        for (let i = 0; i < c.length; i++) if (c[i] >= minCount) { if (lo < 0) lo = i; hi = i; }
        return lo < 0 ? { lo: 0, hi: -1, size: 0 } : { lo, hi, size: hi - lo + 1 };
    };
    const x = span(cols), y = span(rows);
    return { x, y, area, fraction: area / (width * height), touchesBorder: x.lo === 0 || y.lo === 0 || x.hi === width - 1 || y.hi === height - 1 };
}

/** Luminance of pixel (x, y). @param {Image} img @param {number} x @param {number} y */
function lum(img, x, y) {
    const i = 4 * (y * img.width + x);
    return 0.299 * img.rgba[i] + 0.587 * img.rgba[i + 1] + 0.114 * img.rgba[i + 2];
}

/**
 * Horizontal shift (pixels) of the texture inside a window of `a` that best matches `b`
 * (sum of squared luminance differences over the window, shifts -maxShift..maxShift).
 * @param {Image} a @param {Image} b
 * @param {{x0: number, x1: number, y0: number, y1: number}} win
 * @param {number} maxShift
 * @returns {{shift: number, score: number, zero: number}} best shift, its mean squared error, and the error at shift 0
 */
export function horizontalShift(a, b, win, maxShift) {
    let best = 0, bestErr = Infinity, zero = Infinity;
    for (let s = -maxShift; s <= maxShift; s++) {
        let err = 0, n = 0;
        for (let y = win.y0; y < win.y1; y++) {
            for (let x = win.x0; x < win.x1; x++) {
                const xb = x + s;
                if (xb < 0 || xb >= b.width) continue;
                const d = lum(a, x, y) - lum(b, xb, y);
                err += d * d; n++;
            }
        }
        err /= Math.max(1, n);
        if (s === 0) zero = err;
        if (err < bestErr) { bestErr = err; best = s; }
    }
    return { shift: best, score: bestErr, zero };
}

/**
 * Mean absolute luminance difference of two images over a window.
 * @param {Image} a @param {Image} b @param {{x0: number, x1: number, y0: number, y1: number}} win
 */
export function meanDifference(a, b, win) {
    let s = 0, n = 0;
    for (let y = win.y0; y < win.y1; y++) for (let x = win.x0; x < win.x1; x++) { s += Math.abs(lum(a, x, y) - lum(b, x, y)); n++; }
    return s / Math.max(1, n);
}
