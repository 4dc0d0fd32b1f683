// The compact anchor encodings of GSVERSE_gaussian_splatting_mesh_anchor 1.2 (spec/README.md):
// per-face splat counts instead of a face index per splat (`faceCounts`), and `local` anchors
// derived from the rest pose instead of stored (no `barycentrics`, `normalOffset`,
// `localRotation`, `localScale`). Both are expanded here to the per-splat arrays of an explicit
// (1.1) asset, so the remap, CPU or GPU, is the same for every encoding.

import { triangleFrame } from './rest.js';
import { matrixToQuatInto } from './decompose.js';

/**
 * Per-splat face indices of splats stored grouped by face in face order: splat i belongs to
 * face f with S_f <= i < S_{f+1}, S_f = sum of counts[g] for g < f.
 *
 * The running sum is compared with `splats` after every addition and the expansion stops at
 * the first face that would overrun it, so the sum never exceeds splats + 2^32 − 1 and stays an
 * exact integer in binary64 (below 2^53) however many faces there are: a 64-bit-safe sum
 * without BigInt.
 * @param {ArrayLike<number>} counts  (T) non-negative integers (an UNSIGNED_BYTE/SHORT/INT accessor)
 * @param {number} splats  N, the POSITION count of the splat primitive
 * @returns {{faceIndex: Uint32Array|null, sum: number, exceeded: boolean}}  faceIndex null when
 *   the counts do not add up to `splats`; `sum` is then the sum so far (the exact total when
 *   `exceeded` is false, more than `splats` when true)
 */
export function expandFaceCounts(counts, splats) {
    let sum = 0;
    for (let f = 0; f < counts.length; ++f) {
        sum += counts[f];
        if (sum > splats) return { faceIndex: null, sum, exceeded: true };
    }
    if (sum !== splats) return { faceIndex: null, sum, exceeded: false };
    const faceIndex = new Uint32Array(splats);
    let i = 0;
    for (let f = 0; f < counts.length; ++f) {
        const end = i + counts[f];
        faceIndex.fill(f, i, end);
        i = end;
    }
    return { faceIndex, sum, exceeded: false };
}

/**
 * Derived `local` anchors of one splat primitive (spec/README.md §Writing anchors, steps 2–3),
 * computed in binary64 and rounded once to float32, as the spec's readers use them (then like
 * stored FLOAT anchors).
 * @typedef {object} DerivedAnchors
 * @property {Float32Array} barycentrics   (2N) b1, b2
 * @property {Float32Array} normalOffset   (N) d
 * @property {Float32Array} localRotation  (4N) q_l = conj(q_r) ⊗ q, unit, w >= 0
 * @property {Float32Array} localScale     (3N) s_l = s
 */

/**
 * Derive `local` anchors from the rest pose and the rest anchor triangles, per splat i on face
 * f = faceIndex[i], with R_r = [t | b | n] the rest frame, C_r the rest edge matrix and v0 the
 * first corner of triangle f (spec §Triangle frames):
 *   (x, y, z) = R_rᵀ (μ − v0);  b2 = y / C_r[1,1];  b1 = (x − C_r[0,1] b2) / C_r[0,0];  d = z;
 *   q_l = conj(q_r) ⊗ q  (Hamilton product, x, y, z, w; q_r the quaternion of R_r);  s_l = s.
 * Everything is in binary64 from the dequantized rest pose, each result rounded once to float32
 * at the end (spec §Derived `local` anchors). Returns the index of the first
 * splat whose face is degenerate at rest (C_r singular) instead, when there is one.
 * @param {{vertices: ArrayLike<number>, indices: ArrayLike<number>, faceCount: number}} mesh
 *   the anchor mesh (rest vertices in splat-local space)
 * @param {Uint32Array} faceIndex  (N) every value < mesh.faceCount
 * @param {ArrayLike<number>} means      (3N) rest POSITION, dequantized
 * @param {ArrayLike<number>} rotations  (4N) rest ROTATION x, y, z, w, dequantized (normalized here; zero: identity)
 * @param {ArrayLike<number>} scales     (3N) rest SCALE, dequantized
 * @returns {{anchors: DerivedAnchors, degenerateSplat: -1} | {anchors: null, degenerateSplat: number}}
 */
export function deriveLocalAnchors(mesh, faceIndex, means, rotations, scales) {
    const F = mesh.faceCount;
    const v = mesh.vertices;
    const idx = mesh.indices;
    const N = faceIndex.length;
    // per face: R_r (9, row-major), C_r entries c00, c01, c11, q_r (4), regular flag
    const frame = new Float64Array(9 * F);
    const shape = new Float64Array(3 * F);
    const qr = new Float64Array(4 * F);
    const regular = new Uint8Array(F);
    for (let f = 0; f < F; ++f) {
        const i0 = 3 * idx[3 * f], i1 = 3 * idx[3 * f + 1], i2 = 3 * idx[3 * f + 2];
        const x0 = v[i0], y0 = v[i0 + 1], z0 = v[i0 + 2];
        const fr = triangleFrame(v[i1] - x0, v[i1 + 1] - y0, v[i1 + 2] - z0,
            v[i2] - x0, v[i2 + 1] - y0, v[i2 + 2] - z0, frame, 9 * f);
        if (!fr.regular) continue;
        regular[f] = 1;
        shape[3 * f] = fr.c0;
        shape[3 * f + 1] = fr.c1;
        shape[3 * f + 2] = fr.c3;
        matrixToQuatInto(frame, 9 * f, qr, 4 * f);
    }
    for (let i = 0; i < N; ++i) {
        if (!regular[faceIndex[i]]) return { anchors: null, degenerateSplat: i };
    }
    const barycentrics = new Float32Array(2 * N);
    const normalOffset = new Float32Array(N);
    const localRotation = new Float32Array(4 * N);
    const localScale = Float32Array.from(scales);
    for (let i = 0; i < N; ++i) {
        const f = faceIndex[i];
        const r = 9 * f;
        const o = 3 * idx[3 * f];
        const px = means[3 * i] - v[o], py = means[3 * i + 1] - v[o + 1], pz = means[3 * i + 2] - v[o + 2];
        // (x, y, z) = R_rᵀ (μ − v0): the dot products with the columns t, b, n
        const x = frame[r] * px + frame[r + 3] * py + frame[r + 6] * pz;
        const y = frame[r + 1] * px + frame[r + 4] * py + frame[r + 7] * pz;
        const z = frame[r + 2] * px + frame[r + 5] * py + frame[r + 8] * pz;
        const b2 = y / shape[3 * f + 2];
        barycentrics[2 * i] = (x - shape[3 * f + 1] * b2) / shape[3 * f];
        barycentrics[2 * i + 1] = b2;
        normalOffset[i] = z;
        // q (normalized; zero: identity), then conj(q_r) ⊗ q
        let bx = rotations[4 * i], by = rotations[4 * i + 1], bz = rotations[4 * i + 2], bw = rotations[4 * i + 3];
        const len = Math.sqrt(bx * bx + by * by + bz * bz + bw * bw);
        if (len > 0) { bx /= len; by /= len; bz /= len; bw /= len; } else { bx = 0; by = 0; bz = 0; bw = 1; }
        const ax = -qr[4 * f], ay = -qr[4 * f + 1], az = -qr[4 * f + 2], aw = qr[4 * f + 3];
        let lx = aw * bx + ax * bw + ay * bz - az * by;
        let ly = aw * by - ax * bz + ay * bw + az * bx;
        let lz = aw * bz + ax * by - ay * bx + az * bw;
        let lw = aw * bw - ax * bx - ay * by - az * bz;
        let ll = Math.sqrt(lx * lx + ly * ly + lz * lz + lw * lw);
        if (lw < 0) ll = -ll;      // w >= 0, as a binder writes it (q and −q are one rotation)
        lx /= ll; ly /= ll; lz /= ll; lw /= ll;
        localRotation[4 * i] = lx;
        localRotation[4 * i + 1] = ly;
        localRotation[4 * i + 2] = lz;
        localRotation[4 * i + 3] = lw;
    }
    return { anchors: { barycentrics, normalOffset, localRotation, localScale }, degenerateSplat: -1 };
}
