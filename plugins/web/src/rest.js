// Rest quantities of the `local` profile, computed once per asset in binary64 (JavaScript
// numbers) from the stored float32 rest vertices, as spec/README.md §Outputs, precision and
// epsilons requires. They may then be uploaded as float32.

/** @typedef {import('./types.js').AnchoredPrimitive} AnchoredPrimitive */
/** @typedef {import('./types.js').RestQuantities} RestQuantities */

/** ε_deg: a triangle is regular iff a > ε_deg ℓ² (spec §Triangle frames). */
export const EPS_DEGENERATE = 1e-6;
/** ε of the games profile (mesh-local units). */
export const GAMES_EPS = 1e-8;

/**
 * perp(t) = normalize(t × u), u the coordinate axis with the smallest |t_k| (lowest k on ties).
 * @param {number} tx @param {number} ty @param {number} tz
 * @returns {[number, number, number]}
 */
export function perp(tx, ty, tz) {
    const ax = Math.abs(tx), ay = Math.abs(ty), az = Math.abs(tz);
    let k = 0;
    if (ay < ax) k = 1;
    if (az < (k === 0 ? ax : ay)) k = 2;
    let x, y, z;
    if (k === 0) { x = 0; y = tz; z = -ty; }          // t × (1, 0, 0)
    else if (k === 1) { x = -tz; y = 0; z = tx; }     // t × (0, 1, 0)
    else { x = ty; y = -tx; z = 0; }                  // t × (0, 0, 1)
    const len = Math.sqrt(x * x + y * y + z * z);
    return [x / len, y / len, z / len];
}

/**
 * The local frame of a triangle from its edges (spec §Triangle frames), in binary64.
 * Writes R = [t | b | n] row-major into r[o..o+8] and returns
 * {a, regular, c0, c1, c3, cx, cy, cz} with a = |e1 × e2|, C = [[c0, c1], [0, c3]] and the
 * cross product e1 × e2.
 * @param {number} e1x @param {number} e1y @param {number} e1z
 * @param {number} e2x @param {number} e2y @param {number} e2z
 * @param {Float64Array|number[]} r  receives R row-major at offset o
 * @param {number} o
 */
export function triangleFrame(e1x, e1y, e1z, e2x, e2y, e2z, r, o) {
    const e3x = e2x - e1x, e3y = e2y - e1y, e3z = e2z - e1z;
    const cx = e1y * e2z - e1z * e2y;
    const cy = e1z * e2x - e1x * e2z;
    const cz = e1x * e2y - e1y * e2x;
    const a = Math.sqrt(cx * cx + cy * cy + cz * cz);
    const s1 = e1x * e1x + e1y * e1y + e1z * e1z;
    const s2 = e2x * e2x + e2y * e2y + e2z * e2z;
    const s3 = e3x * e3x + e3y * e3y + e3z * e3z;
    let longest2 = s1 > s2 ? s1 : s2;
    if (s3 > longest2) longest2 = s3;
    let tx, ty, tz, bx, by, bz, nx, ny, nz;
    let c0 = 0, c1 = 0, c3 = 0;
    let regular = false;
    if (a > EPS_DEGENERATE * longest2) {
        const l1 = Math.sqrt(s1);
        tx = e1x / l1; ty = e1y / l1; tz = e1z / l1;
        nx = cx / a; ny = cy / a; nz = cz / a;
        c0 = l1;
        c1 = e2x * tx + e2y * ty + e2z * tz;
        c3 = a / l1;
        regular = true;
    } else if (longest2 > 0) {
        // a segment: t along the longest of (e1, e2, e3) by squared length, the first on ties
        let dx = e1x, dy = e1y, dz = e1z, best = s1;
        if (s2 > best) { dx = e2x; dy = e2y; dz = e2z; best = s2; }
        if (s3 > best) { dx = e3x; dy = e3y; dz = e3z; best = s3; }
        const l = Math.sqrt(best);
        tx = dx / l; ty = dy / l; tz = dz / l;
        [nx, ny, nz] = perp(tx, ty, tz);
        c0 = e1x * tx + e1y * ty + e1z * tz;
        c1 = e2x * tx + e2y * ty + e2z * tz;
    } else {
        tx = 1; ty = 0; tz = 0;
        nx = 0; ny = 0; nz = 1;
    }
    if (regular || longest2 > 0) {
        bx = ny * tz - nz * ty;   // b = n × t
        by = nz * tx - nx * tz;
        bz = nx * ty - ny * tx;
    } else {
        bx = 0; by = 1; bz = 0;
    }
    r[o] = tx; r[o + 1] = bx; r[o + 2] = nx;
    r[o + 3] = ty; r[o + 4] = by; r[o + 5] = ny;
    r[o + 6] = tz; r[o + 7] = bz; r[o + 8] = nz;
    return { a, regular, c0, c1, c3, cx, cy, cz };
}

/**
 * Rest quantities of every face of the anchor mesh, computed in binary64 (see RestQuantities
 * in types.js): regular flag, C_r⁻¹ (p, q, r), a_r, √a_r, 1/√a_r and R_r.
 * @param {AnchoredPrimitive|{anchorMesh: {vertices: ArrayLike<number>, indices: ArrayLike<number>}}} prim
 * @returns {RestQuantities}
 */
export function computeRest(prim) {
    const { vertices: v, indices: idx } = prim.anchorMesh;
    const F = Math.floor(idx.length / 3);
    const regular = new Uint8Array(F);
    const cinv = new Float64Array(3 * F);
    const area = new Float64Array(F);
    const sqrtArea = new Float64Array(F);
    const invSqrtArea = new Float64Array(F);
    const restFrame = new Float64Array(9 * F);
    for (let f = 0; f < F; ++f) {
        const i0 = 3 * idx[3 * f], i1 = 3 * idx[3 * f + 1], i2 = 3 * idx[3 * f + 2];
        const x0 = v[i0], y0 = v[i0 + 1], z0 = v[i0 + 2];
        const fr = triangleFrame(v[i1] - x0, v[i1 + 1] - y0, v[i1 + 2] - z0,
            v[i2] - x0, v[i2 + 1] - y0, v[i2 + 2] - z0, restFrame, 9 * f);
        area[f] = fr.a;
        if (fr.regular) {
            // C_r = [[p, q], [0, h]] -> C_r^-1 = [[1/p, -q/(p h)], [0, 1/h]]
            const p = fr.c0, q = fr.c1, h = fr.c3;
            regular[f] = 1;
            cinv[3 * f] = 1 / p;
            cinv[3 * f + 1] = -q / (p * h);
            cinv[3 * f + 2] = 1 / h;
            const root = Math.sqrt(fr.a);
            sqrtArea[f] = root;
            invSqrtArea[f] = 1 / root;
        } else {
            // degenerate at rest: G := I, k := 1 (spec §Faces degenerate at rest); unused
            cinv[3 * f] = 1;
            cinv[3 * f + 2] = 1;
            sqrtArea[f] = 1;
            invSqrtArea[f] = 1;
        }
    }
    return { faceCount: F, regular, cinv, area, sqrtArea, invSqrtArea, restFrame };
}
