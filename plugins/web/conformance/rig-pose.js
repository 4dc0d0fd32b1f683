// The poses of the conformance suite's rig cases (spec/conformance.md §Rig cases), shared by
// the Node runner and the browser page: an implementation with an animation sampler samples
// the asset's own animation at the pose's time (src/animation.js: morph, skin, M⁻¹), instead
// of reading the deformed vertices the suite ships for implementations without one.
// Engine-free; runs in Node and browsers.

/** @typedef {import('../src/animation.js').AnchorAnimation} AnchorAnimation */

/**
 * The anchor vertices of a rig case's pose in the splat primitive's local space.
 * @param {AnchorAnimation|null} animation  readAnchorAnimation of the case's asset
 * @param {{kind: string, animation?: number, time?: number}} source  the pose's `source`
 * @returns {Float32Array}
 */
export function rigPose(animation, source) {
    if (!animation) throw new Error('a rig case whose anchor mesh has no skin and no morph targets');
    if (source.kind === 'rest') return animation.rest();
    if (source.kind !== 'animation') throw new Error(`unknown rig pose source '${source.kind}'`);
    return animation.sample(/** @type {number} */ (source.animation), /** @type {number} */ (source.time));
}
