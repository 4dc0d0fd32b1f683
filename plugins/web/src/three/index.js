/**
 * @gsverse/web/three: mesh-anchored Gaussian splats (GSVERSE_gaussian_splatting_mesh_anchor)
 * for three.js, rendered by Spark (`@sparkjsdev/spark`) and remapped on the GPU in Spark's
 * splat pipeline (shader.js: the engine-free GLSL chunk as a Spark object modifier).
 *
 *   import { SparkRenderer } from '@sparkjsdev/spark';
 *   import { loadAnchoredAsset } from '@gsverse/web/three';
 *   scene.add(new SparkRenderer({ renderer }));
 *   const { root, anchored, plain, animations } = await loadAnchoredAsset('asset.glb' | bytes, {
 *       name,            // file name used in messages (default: from the URL, or 'asset.glb')
 *       fault,           // testing only: a deliberately broken variant (shader.js FAULTS)
 *   });
 *   scene.add(root);
 *   // root:       a THREE.Group holding one SplatMesh per splat primitive of the file, each
 *   //             placed by its splat node's global matrix
 *   // anchored:   AnchoredSplatMesh[], one per anchored splat primitive
 *   // plain:      SplatMesh[] of the plain (unanchored) splats, rendered as stored
 *   // animations: [{index, name, duration}] the file's animations of its animated anchor meshes
 *
 *   const s = anchored[0];
 *   s.mesh             // the Spark SplatMesh (its matrix is the splat node's global matrix)
 *   s.prim             // AnchoredPrimitive (../types.js)
 *   s.setVertices(v)   // Float32Array(3V): anchor vertices in splat-local space, file vertex
 *                      // order; Spark regenerates the splats on its next update
 *   s.vertices, s.reset(), s.enabled, s.animation, s.setAnimationTime(i, t)  // as PlayCanvas's
 *   s.followSkinnedMesh(m)  // pose from a three.js SkinnedMesh (e.g. the anchor mesh as
 *                      // GLTFLoader builds it, played by an AnimationMixer): call every frame
 *   new BoneSkinnedSplats(s)  // the bone-only approximation by Spark's SplatSkinning (skinning.js)
 *   s.destroy()
 *
 * Splat order: Spark's splats are built in the file's order (splat i of the file is Spark's
 * splat i), so the per-splat anchor textures are indexed by the file's order.
 * Refused assets throw AnchorError (../anchor.js) with `.code` and a one-line message, before
 * anything is built. WebGL2 only (Spark renders through three.js's WebGLRenderer).
 */

import * as THREE from 'three';
import { PackedSplats, SplatMesh } from '@sparkjsdev/spark';
import { AnchorError, SH_C0, readAnchoredGlb, readRestPose } from '../anchor.js';
import { readAnchorAnimation } from '../animation.js';
import { globalMatrices, parseGltf } from '../glb.js';
import { expandCompressed } from '../spz.js';
import { computeRest } from '../rest.js';
import { DATA_TEXTURE_MAX_WIDTH } from '../remap-glsl.js';
import { RemapModifier, checkFault } from './shader.js';

export { FAULTS, RENDER_FAULTS, RemapModifier, modifierGlobalsGLSL } from './shader.js';
export { BoneSkinnedSplats, MAX_SPARK_BONES } from './skinning.js';
export { AnchorError };

/** @typedef {import('../types.js').AnchoredPrimitive} AnchoredPrimitive */
/** @typedef {import('../types.js').RestPose} RestPose */
/** @typedef {import('../types.js').RestQuantities} RestQuantities */
/** @typedef {import('../animation.js').AnchorAnimation} AnchorAnimation */
/** @typedef {import('../animation.js').AnimationInfo} AnimationInfo */
/** @typedef {import('./shader.js').RemapUniforms} RemapUniforms */


/**
 * An RGBA data texture of `count` texels (row-major, width at most DATA_TEXTURE_MAX_WIDTH), nearest sampling.
 * @param {number} count
 * @param {'float'|'uint'} kind  RGBA32F or RGBA32UI
 */
function dataTexture(count, kind) {
    const width = Math.max(1, Math.min(count, DATA_TEXTURE_MAX_WIDTH));
    const height = Math.max(1, Math.ceil(count / width));
    const data = kind === 'float' ? new Float32Array(4 * width * height) : new Uint32Array(4 * width * height);
    const format = kind === 'float' ? THREE.RGBAFormat : THREE.RGBAIntegerFormat;
    const type = kind === 'float' ? THREE.FloatType : THREE.UnsignedIntType;
    const texture = new THREE.DataTexture(data, width, height, format, type);
    texture.internalFormat = kind === 'float' ? 'RGBA32F' : 'RGBA32UI';
    texture.minFilter = THREE.NearestFilter;
    texture.magFilter = THREE.NearestFilter;
    texture.generateMipmaps = false;
    texture.needsUpdate = true;
    return { texture, data };
}

/** 0 affine, 1 rigid, 2 games (the chunk's gsvLaw). @param {AnchoredPrimitive} prim */
export function lawCode(prim) {
    if (prim.profile === 'games') return 2;
    return prim.deformation === 'rigid' ? 1 : 0;
}

/**
 * The anchor data of one anchored primitive as textures (file order), and the current vertices.
 */
export class AnchorTextures {
    /** @param {AnchoredPrimitive} prim */
    constructor(prim) {
        this.prim = prim;
        /** @type {RestQuantities} */
        this.rest = computeRest(prim);
        const n = prim.count, F = this.rest.faceCount, V = prim.anchorMesh.vertexCount;
        const anchor = dataTexture(n, 'uint'), rot = dataTexture(n, 'float'), scale = dataTexture(n, 'float');
        const bits = new Float32Array(3), bitsU = new Uint32Array(bits.buffer);
        const games = prim.profile === 'games';
        const third = /** @type {ArrayLike<number>} */ (games ? prim.rho : prim.normalOffset);
        const a = /** @type {Uint32Array} */ (anchor.data), r = /** @type {Float32Array} */ (rot.data);
        const s = /** @type {Float32Array} */ (scale.data);
        for (let i = 0; i < n; ++i) {
            bits[0] = prim.barycentrics[2 * i];
            bits[1] = prim.barycentrics[2 * i + 1];
            bits[2] = third[i];
            a[4 * i] = prim.faceIndex[i];
            a[4 * i + 1] = bitsU[0];
            a[4 * i + 2] = bitsU[1];
            a[4 * i + 3] = bitsU[2];
            if (games) {
                r[4 * i + 3] = 1;
            } else {
                const lr = /** @type {ArrayLike<number>} */ (prim.localRotation), ls = /** @type {ArrayLike<number>} */ (prim.localScale);
                for (let k = 0; k < 4; ++k) r[4 * i + k] = lr[4 * i + k];
                for (let k = 0; k < 3; ++k) s[4 * i + k] = ls[3 * i + k];
            }
        }
        const faces = dataTexture(F, 'uint'), restTex = dataTexture(F, 'float');
        const fd = /** @type {Uint32Array} */ (faces.data), rd = /** @type {Float32Array} */ (restTex.data);
        const idx = prim.anchorMesh.indices;
        for (let f = 0; f < F; ++f) {
            fd[4 * f] = idx[3 * f];
            fd[4 * f + 1] = idx[3 * f + 1];
            fd[4 * f + 2] = idx[3 * f + 2];
            fd[4 * f + 3] = this.rest.regular[f];
            rd[4 * f] = this.rest.cinv[3 * f];          // binary64 -> float32 only here
            rd[4 * f + 1] = this.rest.cinv[3 * f + 1];
            rd[4 * f + 2] = this.rest.cinv[3 * f + 2];
            rd[4 * f + 3] = this.rest.invSqrtArea[f];
        }
        this.vertices = dataTexture(V, 'float');
        this.textures = [anchor.texture, rot.texture, scale.texture, faces.texture, restTex.texture, this.vertices.texture];
        /** @type {RemapUniforms} the modifier's uniforms (shader.js), by GLSL name */
        this.uniforms = {
            gsvAnchorTex: { value: anchor.texture },
            gsvLocalRotTex: { value: rot.texture },
            gsvLocalScaleTex: { value: scale.texture },
            gsvFaces: { value: faces.texture },
            gsvRest: { value: restTex.texture },
            gsvVertices: { value: this.vertices.texture },
            gsvLaw: { value: lawCode(prim) },
        };
        this.current = new Float32Array(prim.anchorMesh.vertices);
        this.upload(this.current);
    }

    /** @param {ArrayLike<number>} vertices  (3V) splat-local space, file vertex order */
    upload(vertices) {
        const V = this.prim.anchorMesh.vertexCount;
        if (vertices.length !== 3 * V) {
            throw new RangeError(`setVertices: expected ${3 * V} numbers (${V} vertices), got ${vertices.length}`);
        }
        if (vertices !== this.current) this.current.set(vertices);
        const t = /** @type {Float32Array} */ (this.vertices.data);
        for (let v = 0; v < V; ++v) {
            t[4 * v] = vertices[3 * v];
            t[4 * v + 1] = vertices[3 * v + 1];
            t[4 * v + 2] = vertices[3 * v + 2];
        }
        this.vertices.texture.needsUpdate = true;
    }

    dispose() {
        for (const t of this.textures) t.dispose();
    }
}

/**
 * Spark's splats of a rest pose, in its order: centre, scales, rotation, opacity and the DC
 * colour (Spark's PackedSplats; higher SH degrees are not passed on).
 * @param {RestPose} rest
 * @param {number} count
 * @param {number} shCoefficients  K of the rest pose's sh array
 */
export function packRestPose(rest, count, shCoefficients) {
    const packed = new PackedSplats({ maxSplats: Math.max(1, count) });
    const c = new THREE.Vector3(), s = new THREE.Vector3(), q = new THREE.Quaternion(), color = new THREE.Color();
    const K = shCoefficients;
    for (let i = 0; i < count; ++i) {
        c.set(rest.means[3 * i], rest.means[3 * i + 1], rest.means[3 * i + 2]);
        s.set(rest.scales[3 * i], rest.scales[3 * i + 1], rest.scales[3 * i + 2]);
        q.set(rest.rotations[4 * i], rest.rotations[4 * i + 1], rest.rotations[4 * i + 2], rest.rotations[4 * i + 3]);
        const dc = 3 * K * i;
        // Spark's colours are the splats' display values as stored (no colour management)
        color.setRGB(0.5 + SH_C0 * rest.sh[dc], 0.5 + SH_C0 * rest.sh[dc + 1], 0.5 + SH_C0 * rest.sh[dc + 2], THREE.LinearSRGBColorSpace);
        packed.pushSplat(c, s, q, rest.opacity[i], color);
    }
    return packed;
}

/**
 * A THREE.Matrix4 from a column-major 4x4 (identity for null).
 * @param {ArrayLike<number>|null} m
 */
function matrix4(m) {
    const out = new THREE.Matrix4();
    if (m) out.fromArray(Array.from(m));
    return out;
}

/**
 * One anchored splat primitive: a Spark SplatMesh whose splats are remapped on the GPU.
 */
export class AnchoredSplatMesh {
    /**
     * @param {AnchoredPrimitive} prim
     * @param {{fault?: string|null}} [options]
     */
    constructor(prim, options = {}) {
        const fault = checkFault(options.fault ?? null);
        /** @type {AnchoredPrimitive} */
        this.prim = prim;
        /** @type {AnchorTextures} */
        this.gpu = new AnchorTextures(prim);
        /** @type {RestQuantities} */
        this.rest = this.gpu.rest;
        /** @type {import('./shader.js').RemapModifier} the remap, installed as the mesh's object modifier */
        this._modifier = new RemapModifier(this.gpu.uniforms, { fault });
        this.mesh = new SplatMesh({
            packedSplats: packRestPose(prim.rest, prim.count, prim.shCoefficients),
            objectModifier: this._modifier,
        });
        this.mesh.name = `gsverse anchored splats (mesh ${prim.splatMesh}, primitive ${prim.splatPrimitive})`;
        this.mesh.matrixAutoUpdate = false;
        if (fault !== 'node-transform') this.mesh.matrix.copy(matrix4(prim.nodeMatrix));
        this.mesh.matrixWorldNeedsUpdate = true;
        this._enabled = true;
        /** @type {AnchorAnimation|null} */
        this.animation = null;
        /** @type {Float32Array|null} */
        this._animated = null;
        /** @type {Float32Array|null} */
        this._skinned = null;
    }

    /** false: Spark renders the stored rest pose (no modifier); true: remapped */
    get enabled() {
        return this._enabled;
    }

    set enabled(value) {
        this._enabled = !!value;
        this.mesh.objectModifier = this._enabled ? this._modifier : undefined;
        this.mesh.updateGenerator();
    }

    /** @param {ArrayLike<number>} vertices  (3V) current anchor vertices, splat-local space */
    setVertices(vertices) {
        this.gpu.upload(vertices);
        this.mesh.updateVersion();   // Spark regenerates the splats (and sorts them) on its next update
    }

    /** @returns {Float32Array} copy of the current vertices */
    get vertices() {
        return new Float32Array(this.gpu.current);
    }

    reset() {
        this.setVertices(this.prim.anchorMesh.vertices);
    }

    /**
     * Pose the anchor mesh as the file's animation `index` at `time` seconds (its skin and morph
     * targets sampled by ../animation.js, spec §Animated anchor meshes), and remap.
     * @param {number} index @param {number} time
     * @returns {Float32Array} the vertices used (splat-local space; reused by the next call)
     */
    setAnimationTime(index, time) {
        if (!this.animation) {
            throw new AnchorError('NO_ANIMATION', 'this anchored primitive has no animated anchor mesh (no skin or morph targets on its anchor node)');
        }
        this._animated ??= new Float32Array(3 * this.prim.anchorMesh.vertexCount);
        this.animation.sample(index, time, this._animated);
        this.setVertices(this._animated);
        return this._animated;
    }

    /**
     * Pose from the anchor mesh as three.js poses it: a SkinnedMesh skinned by three.js (e.g. the
     * anchor mesh of the same file loaded by GLTFLoader and played by an AnimationMixer), or a
     * Mesh with morph targets; its vertices are taken on the CPU by three.js
     * (`getVertexPosition`: morph targets, then skinning) and mapped to splat-local space as
     * spec §Animated anchor meshes says: skinned vertices from the mesh's space to world space
     * (its world matrix; three.js's bind matrix keeps the skinned pose in the mesh's space),
     * then by the inverse of this SplatMesh's world matrix (M⁻¹ of the splat node, when both
     * scenes sit at the same place); unskinned (morphed) vertices are splat-local already (the
     * anchor node's transform is ignored). The mesh must hold the anchor primitive's vertices in
     * file order (GLTFLoader keeps the accessor order). Call after the mixer's update.
     * @param {THREE.Mesh} mesh
     * @returns {Float32Array} the vertices used (splat-local space; reused by the next call)
     */
    followSkinnedMesh(mesh) {
        const V = this.prim.anchorMesh.vertexCount;
        const position = mesh.geometry.getAttribute('position');
        if (!position || position.count !== V) {
            throw new RangeError(`followSkinnedMesh: the mesh has ${position ? position.count : 0} vertices, the anchor mesh ${V}`);
        }
        const skinned = mesh instanceof THREE.SkinnedMesh;
        /** @type {THREE.Matrix4|null} */
        let toLocal = null;
        if (skinned) {
            mesh.updateWorldMatrix(true, false);
            this.mesh.updateWorldMatrix(true, false);
            mesh.skeleton.update();
            toLocal = this.mesh.matrixWorld.clone().invert().multiply(mesh.matrixWorld);
        }
        this._skinned ??= new Float32Array(3 * V);
        const p = new THREE.Vector3();
        for (let v = 0; v < V; ++v) {
            mesh.getVertexPosition(v, p);
            if (toLocal) p.applyMatrix4(toLocal);
            this._skinned[3 * v] = p.x;
            this._skinned[3 * v + 1] = p.y;
            this._skinned[3 * v + 2] = p.z;
        }
        this.setVertices(this._skinned);
        return this._skinned;
    }

    destroy() {
        this.mesh.removeFromParent();
        this.mesh.dispose();
        this.gpu.dispose();
    }
}

/**
 * Load a GLB with anchored splats for three.js + Spark (an SPZ-compressed rest pose decoded first,
 * expandCompressed): our reader for the anchors and the splats (refusals throw AnchorError before anything is built), one Spark SplatMesh per splat
 * primitive under `root`, the remap installed as each anchored mesh's object modifier.
 * @param {string|Uint8Array|ArrayBuffer} source  URL or GLB bytes
 * @param {{name?: string, fault?: string|null}} [options]
 * @returns {Promise<{root: THREE.Group, anchored: AnchoredSplatMesh[], plain: SplatMesh[], animations: AnimationInfo[]}>}
 */
export async function loadAnchoredAsset(source, options = {}) {
    /** @type {Uint8Array} */
    let bytes;
    let name = options.name;
    if (typeof source === 'string') {
        const response = await fetch(source);
        if (!response.ok) throw new Error(`${source}: HTTP ${response.status}`);
        bytes = new Uint8Array(await response.arrayBuffer());
        name = name || source.split('/').pop() || 'asset.glb';
    } else {
        bytes = source instanceof Uint8Array ? source : new Uint8Array(source);
    }
    name = name || 'asset.glb';
    bytes = await expandCompressed(bytes, { name });   // SPZ-compressed rest poses decoded (refusals throw here)
    const fault = checkFault(options.fault ?? null);
    const { anchored: prims, plain: plainRefs, json } = readAnchoredGlb(bytes, { name });   // refusals throw here
    const doc = parseGltf(bytes);
    const animations = prims.map((prim) => readAnchorAnimation(doc, prim, { name }));   // and here
    const plainPoses = plainRefs.map(({ mesh, primitive }) => readRestPose(doc, json.meshes[mesh].primitives[primitive], `${name} meshes[${mesh}].primitives[${primitive}]`));
    const matrices = globalMatrices(json);
    const root = new THREE.Group();
    root.name = name;
    const anchored = prims.map((prim, p) => {
        const splat = new AnchoredSplatMesh(prim, { fault });
        splat.animation = animations[p];
        root.add(splat.mesh);
        return splat;
    });
    const plain = plainRefs.map(({ mesh, primitive }, k) => {
        const pose = plainPoses[k];
        const K = pose.count ? pose.rest.sh.length / (3 * pose.count) : 1;
        const splats = new SplatMesh({ packedSplats: packRestPose(pose.rest, pose.count, K) });
        splats.name = `gsverse plain splats (mesh ${mesh}, primitive ${primitive})`;
        const node = (Array.isArray(json.nodes) ? json.nodes : []).findIndex((/** @type {any} */ n) => n && n.mesh === mesh);
        splats.matrixAutoUpdate = false;
        if (node >= 0) splats.matrix.copy(matrix4(matrices[node]));
        root.add(splats);
        return splats;
    });
    return { root, anchored, plain, animations: animations.find((a) => a)?.animations ?? [] };
}
