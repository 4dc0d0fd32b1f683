/**
 * The bone-only approximation (../bone-weights.js) drawn by Spark's own skinning
 * (`SplatSkinning`, dual-quaternion mode): for a character whose splats may follow its bones
 * instead of its triangles (cheaper per frame: no vertex upload, no remap; see
 * bench/bone-only.mjs for how far it is from the exact remap).
 *
 *   const bones = new BoneSkinnedSplats(anchored[0]);   // replaces the triangle remap
 *   bones.setAnimationTime(animations[1].index, t);    // per frame
 *   bones.dispose();                                   // back to the triangle remap
 *
 * Each bone's transform is the joint matrix of the file's skin at that time (global joint
 * matrix times inverse bind matrix, sampled by ../animation.js), taken to splat-local space by
 * M⁻¹ of the splat node, and handed to Spark as a rotation and a translation (Spark's
 * dual-quaternion skinning has no scale: a joint that scales is drawn unscaled). Spark stores
 * each weight in 8 bits, and skins the rest centres as its PackedSplats store them (half floats:
 * about 2e-4 of the Fox's height at rest, where the triangle remap, which recomputes every
 * centre, has none of that).
 */

import * as THREE from 'three';
import { SplatSkinning, SplatSkinningMode } from '@sparkjsdev/spark';
import { AnchorError } from '../anchor.js';
import { MAX_SPLAT_BONES, splatBoneWeights } from '../bone-weights.js';

/** @typedef {import('./index.js').AnchoredSplatMesh} AnchoredSplatMesh */

/** Spark's SplatSkinning: bone indices are 8 bits. */
export const MAX_SPARK_BONES = 256;

export class BoneSkinnedSplats {
    /** @param {AnchoredSplatMesh} splat  an anchored primitive whose anchor mesh is skinned */
    constructor(splat) {
        const animation = splat.animation;
        if (!animation || !animation.skinned) {
            throw new AnchorError('NO_ANIMATION', 'bone skinning needs a skinned anchor mesh (this anchored primitive has no skin)');
        }
        if (animation.jointCount > MAX_SPARK_BONES) {
            throw new AnchorError('ENGINE_UNSUPPORTED', `the skin has ${animation.jointCount} joints; Spark's SplatSkinning takes at most ${MAX_SPARK_BONES}`);
        }
        this.splat = splat;
        this.animation = animation;
        /** the per-splat bones and weights (file order) */
        this.boneWeights = splatBoneWeights(splat.prim, animation, { maxBones: MAX_SPLAT_BONES });
        const n = splat.prim.count;
        const mesh = splat.mesh;
        this.skinning = new SplatSkinning({ mesh, numSplats: n, numBones: animation.jointCount, mode: SplatSkinningMode.DUAL_QUATERNION });
        const b = new THREE.Vector4(), w = new THREE.Vector4();
        const { bones, weights } = this.boneWeights;
        for (let i = 0; i < n; ++i) {
            b.fromArray(bones, 4 * i);
            w.fromArray(weights, 4 * i);
            this.skinning.setSplatBones(i, b, w);
        }
        this.skinning.skinTexture.needsUpdate = true;
        this._wasEnabled = splat.enabled;
        splat.enabled = false;              // the rest splats, moved by their bones only
        mesh.skinning = this.skinning;
        mesh.updateGenerator();
        this._m = new THREE.Matrix4();
        this._inv = new THREE.Matrix4();
        this._q = new THREE.Quaternion();
        this._p = new THREE.Vector3();
        this._s = new THREE.Vector3();
        this.setAnimationTime(-1, 0);
    }

    /**
     * Pose the bones as the file's animation `index` at `time` seconds (-1: the rest pose).
     * @param {number} index @param {number} time
     */
    setAnimationTime(index, time) {
        const a = this.animation;
        if (index < 0) a.rest();
        else a.sample(index, time);
        const J = a.jointMatrices, M = a.splatInverse;
        this._inv.fromArray(Array.from(M));
        for (let j = 0; j < a.jointCount; ++j) {
            const o = 12 * j;
            this._m.set(
                J[o], J[o + 3], J[o + 6], J[o + 9],
                J[o + 1], J[o + 4], J[o + 7], J[o + 10],
                J[o + 2], J[o + 5], J[o + 8], J[o + 11],
                0, 0, 0, 1);
            this._m.premultiply(this._inv);
            this._m.decompose(this._p, this._q, this._s);
            this.skinning.setBoneQuatPos(j, this._q, this._p);
        }
        this.skinning.updateBones();
    }

    /** Back to the triangle remap. */
    dispose() {
        this.splat.mesh.skinning = null;
        this.splat.enabled = this._wasEnabled;
        this.skinning.skinTexture.dispose();
        this.skinning.boneTexture.dispose();
    }
}
