/**
 * A bone-only approximation of the triangle remap, for engines that can skin splats only by
 * bones (Spark's `SplatSkinning`: at most 4 bones a splat and 256 bones, weights through its JS
 * API; others like it). Engine-free; runs in Node and browsers.
 *
 * Each splat of a skinned anchor mesh gets the skin weights of its anchor triangle's corners,
 * blended by the splat's barycentrics: w_j = Σ_k b_k w_{v_k, j} over the corners v_k (b_0 =
 * 1 − b_1 − b_2; the games profile's α the same way; negative barycentrics of a splat outside its
 * triangle clamped to 0 and the rest renormalized), then the `maxBones` largest kept (ties: the
 * lower joint) and renormalized to sum 1. The splat then moves by linear blend skinning of its
 * rest centre by those bones, which is what a bone-skinning engine does; the exact remap moves
 * it with the deformed triangle instead. The two agree where the triangle moves rigidly with one
 * bone and part where a triangle stretches, folds or is pulled by more than `maxBones` joints;
 * morph targets are lost entirely (a bone engine has none). `boneOnlyMeansInto` is that bone
 * skinning on the CPU, to measure the difference (bench/bone-only.mjs).
 */

/** @typedef {import('./types.js').AnchoredPrimitive} AnchoredPrimitive */
/** @typedef {import('./animation.js').AnchorAnimation} AnchorAnimation */

/** Spark's SplatSkinning: bones a splat at most. */
export const MAX_SPLAT_BONES = 4;

/**
 * Per-splat bone indices and weights (file splat order), `maxBones` slots a splat; unused slots
 * hold bone 0 with weight 0.
 * @param {AnchoredPrimitive} prim
 * @param {AnchorAnimation} animation  readAnchorAnimation of the same file (a skinned anchor mesh)
 * @param {{maxBones?: number}} [options]
 * @returns {{maxBones: number, bones: Uint16Array, weights: Float32Array}}  (maxBones·N) each
 */
export function splatBoneWeights(prim, animation, options = {}) {
    const maxBones = options.maxBones ?? MAX_SPLAT_BONES;
    if (!(Number.isInteger(maxBones) && maxBones >= 1)) throw new RangeError(`maxBones must be a positive integer, got ${maxBones}`);
    if (!animation.skinned) throw new RangeError('splatBoneWeights: the anchor mesh has no skin');
    const n = prim.count;
    const idx = prim.anchorMesh.indices;
    const offsets = animation.offsets, ij = animation.influenceJoint, iw = animation.influenceWeight;
    const bones = new Uint16Array(maxBones * n);
    const weights = new Float32Array(maxBones * n);
    /** @type {Map<number, number>} */
    const acc = new Map();
    const b = [0, 0, 0];
    for (let i = 0; i < n; ++i) {
        const f = prim.faceIndex[i];
        b[1] = Math.max(0, prim.barycentrics[2 * i]);
        b[2] = Math.max(0, prim.barycentrics[2 * i + 1]);
        b[0] = Math.max(0, 1 - prim.barycentrics[2 * i] - prim.barycentrics[2 * i + 1]);
        const sum = b[0] + b[1] + b[2];
        acc.clear();
        for (let k = 0; k < 3; ++k) {
            const bk = sum > 0 ? b[k] / sum : 1 / 3;
            if (bk === 0) continue;
            const v = idx[3 * f + k];
            for (let e = offsets[v]; e < offsets[v + 1]; ++e) acc.set(ij[e], (acc.get(ij[e]) ?? 0) + bk * iw[e]);
        }
        const top = [...acc.entries()].sort((x, y) => y[1] - x[1] || x[0] - y[0]).slice(0, maxBones);
        const total = top.reduce((s, [, w]) => s + w, 0);
        top.forEach(([joint, w], slot) => {
            bones[maxBones * i + slot] = joint;
            weights[maxBones * i + slot] = total > 0 ? w / total : 0;
        });
    }
    return { maxBones, bones, weights };
}

/**
 * The splats' centres skinned by their bones alone (linear blend skinning of the rest centres
 * with `animation`'s current joint matrices, then M⁻¹ of the splat node): what a bone-skinning
 * engine draws. Call after `animation.sample(...)` (which updates the joint matrices).
 * @param {AnchorAnimation} animation
 * @param {{maxBones: number, bones: Uint16Array, weights: Float32Array}} boneWeights
 * @param {ArrayLike<number>} restMeans  (3N) splat-local rest centres
 * @param {Float32Array|Float64Array} out  (3N)
 */
export function boneOnlyMeansInto(animation, boneWeights, restMeans, out) {
    const J = animation.jointMatrices, M = animation.splatInverse;
    const { maxBones, bones, weights } = boneWeights;
    const n = restMeans.length / 3;
    for (let i = 0; i < n; ++i) {
        const x = restMeans[3 * i], y = restMeans[3 * i + 1], z = restMeans[3 * i + 2];
        let sx = 0, sy = 0, sz = 0;
        for (let s = maxBones * i; s < maxBones * (i + 1); ++s) {
            const w = weights[s];
            if (w === 0) continue;
            const m = 12 * bones[s];
            sx += w * (J[m] * x + J[m + 3] * y + J[m + 6] * z + J[m + 9]);
            sy += w * (J[m + 1] * x + J[m + 4] * y + J[m + 7] * z + J[m + 10]);
            sz += w * (J[m + 2] * x + J[m + 5] * y + J[m + 8] * z + J[m + 11]);
        }
        out[3 * i] = M[0] * sx + M[4] * sy + M[8] * sz + M[12];
        out[3 * i + 1] = M[1] * sx + M[5] * sy + M[9] * sz + M[13];
        out[3 * i + 2] = M[2] * sx + M[6] * sy + M[10] * sz + M[14];
    }
    return out;
}
