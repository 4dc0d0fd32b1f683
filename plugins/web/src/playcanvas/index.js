/**
 * @gsverse/web/playcanvas: mesh-anchored Gaussian splats (GSVERSE_gaussian_splatting_mesh_anchor)
 * remapped on the GPU inside PlayCanvas's unified gsplat pipeline (versions: SUPPORTED_PLAYCANVAS,
 * checked by engine.js).
 *
 *   import { loadAnchoredAsset } from '@gsverse/web/playcanvas';
 *   const { root, anchored, plain } = await loadAnchoredAsset(app, 'asset.glb' | bytes, {
 *       name,            // file name used in messages (default: from the URL, or 'asset.glb')
 *       parent,          // Entity to add root to (default app.root; null: not added)
 *       showAnchorMesh,  // keep the anchor mesh's own render component enabled (default false)
 *       fault,           // testing only: a deliberately broken shader variant (see shader.js)
 *   });
 *   // root:       the glTF scene instantiated by the engine's container loader (rest pose)
 *   // anchored:   AnchoredSplat[], one per anchored splat primitive
 *   // plain:      Entity[] holding the plain (unanchored) splats, left untouched
 *   // animations: [{index, name, duration}] the file's animations of its animated anchor
 *   //             meshes (skin, morph targets; spec §Animated anchor meshes), [] when none
 *
 *   const s = anchored[0];
 *   s.prim             // AnchoredPrimitive (../types.js): rest pose, anchors, anchorMesh, file order
 *   s.entity           // the Entity with the gsplat component (its world transform is the splat node's)
 *   s.anchorEntity     // the Entity rendering the anchor mesh, or null (hidden unless showAnchorMesh)
 *   s.order            // Uint32Array: engine splat row r holds file splat order[r]
 *   s.setVertices(v)   // Float32Array(3V): current anchor vertices in splat-local space, file
 *                      // vertex order; from world space: multiply by the inverse of
 *                      // s.entity.getWorldTransform(). The splats follow on the next frame.
 *   s.vertices         // copy of the current vertices
 *   s.reset()          // back to the rest vertices
 *   s.enabled = false  // remove the remap (the engine renders its stored rest pose); true again to remap
 *   s.animation        // AnchorAnimation (../animation.js) of an animated anchor mesh, or null
 *   s.setAnimationTime(i, t)  // pose the anchor mesh as the file's animation i at t seconds
 *                      // (the asset's own skin and morph targets, sampled in JS); returns the vertices
 *   s.lastRemapMs      // CPU time of the last setVertices (vertex upload + sort centres), ms
 *   s.lastSortMs       // the part of it spent on the deformed sort centres, ms
 *   s.sortDeformed     // true (default): splats are depth-sorted by their deformed positions
 *   s.sortPending      // true until the engine has sorted the current pose (paced by 'gsplat:sorted')
 *   s.destroy()
 *
 * Refused assets throw AnchorError (../anchor.js) with `.code` and a one-line message.
 * WebGL2 (GLSL, shader.js) and WebGPU (WGSL, shader-wgsl.js): the engine picks the chunk of
 * its device.
 */

import {
    Asset, Entity, GSplatData, Texture, Vec3,
    ADDRESS_CLAMP_TO_EDGE, FILTER_NEAREST, PIXELFORMAT_RGBA32F, PIXELFORMAT_RGBA32U,
} from 'playcanvas';
import { AnchorError, readAnchoredGlb } from '../anchor.js';
import { readAnchorAnimation } from '../animation.js';
import { parseGltf } from '../glb.js';
import { expandCompressed } from '../spz.js';
import { computeRest } from '../rest.js';
import { remapMeansInto } from '../remap-cpu.js';
import { centersChanged, checkComponent, checkEngine, checkResource, meshSplatAssets } from './engine.js';
import { STREAM_ANCHOR, STREAM_LOCAL_ROT, STREAM_LOCAL_SCALE, modifyChunkGLSL } from './shader.js';
import { modifyChunkWGSL } from './shader-wgsl.js';
import { DATA_TEXTURE_MAX_WIDTH } from '../remap-glsl.js';

export { FAULTS, remapChunkGLSL, modifyChunkGLSL, processChunkGLSL } from './shader.js';
export { remapChunkWGSL, modifyChunkWGSL, processChunkWGSL } from './shader-wgsl.js';
export { AnchorError };
export { SUPPORTED_PLAYCANVAS, PLAYCANVAS_VERSION } from './engine.js';

/** @typedef {import('../types.js').AnchoredPrimitive} AnchoredPrimitive */
/** @typedef {import('../types.js').RestQuantities} RestQuantities */
/** @typedef {import('../animation.js').AnchorAnimation} AnchorAnimation */
/** @typedef {import('../animation.js').AnimationInfo} AnimationInfo */
/** @typedef {import('playcanvas').AppBase} AppBase */
/** @typedef {import('playcanvas').GraphicsDevice} GraphicsDevice */
/** @typedef {import('playcanvas').GSplatResource} GSplatResource */
/** @typedef {import('playcanvas').GSplatComponent} GSplatComponent */

/** How long a handed-over set of sort centres holds later ones back at most (ms). */
const SORT_WAIT_MS = 1000;
/** frames after a sort on which vertices set before it are marked for drawing again (_onSorted) */
const REMARK_FRAMES = 4;


/**
 * @param {number} count
 * @returns {[number, number]}
 */
function textureSize(count) {
    const width = Math.max(1, Math.min(count, DATA_TEXTURE_MAX_WIDTH));
    return [width, Math.max(1, Math.ceil(count / width))];
}

/**
 * An RGBA32F or RGBA32U data texture, nearest sampling, no mipmaps.
 * @param {GraphicsDevice} device
 * @param {string} name
 * @param {number} count  texels needed
 * @param {number} format
 */
export function createDataTexture(device, name, count, format) {
    const [width, height] = textureSize(count);
    return new Texture(device, {
        name, width, height, format, mipmaps: false,
        minFilter: FILTER_NEAREST, magFilter: FILTER_NEAREST,
        addressU: ADDRESS_CLAMP_TO_EDGE, addressV: ADDRESS_CLAMP_TO_EDGE,
    });
}

/** 0 affine, 1 rigid, 2 games (the shader's gsvLaw). @param {AnchoredPrimitive} prim */
export function lawCode(prim) {
    if (prim.profile === 'games') return 2;
    return prim.deformation === 'rigid' ? 1 : 0;
}

/**
 * The engine's splat row order for file positions: PlayCanvas's KHR parser reorders rows by
 * GSplatData.calcMortonOrder(); recompute it with the engine's own function.
 * @param {Float32Array} means  (3N) file order
 * @returns {Uint32Array}  order[r] = file index of engine row r
 */
export function engineRowOrder(means) {
    const n = means.length / 3;
    const x = new Float32Array(n), y = new Float32Array(n), z = new Float32Array(n);
    for (let i = 0; i < n; ++i) { x[i] = means[3 * i]; y[i] = means[3 * i + 1]; z[i] = means[3 * i + 2]; }
    const props = [['x', x], ['y', y], ['z', z]].map(([name, storage]) => ({ type: 'float', name, storage, byteSize: 4 }));
    const data = new GSplatData([{ name: 'vertex', count: n, properties: /** @type {any} */ (props) }]);
    return data.calcMortonOrder();
}

/**
 * Fill the per-splat extra streams of an engine resource (engine row order).
 * @param {any} resource  GSplatResource
 * @param {AnchoredPrimitive} prim
 * @param {Uint32Array} order
 */
function fillStreams(resource, prim, order) {
    resource.format.addExtraStreams([
        { name: STREAM_ANCHOR, format: PIXELFORMAT_RGBA32U },
        { name: STREAM_LOCAL_ROT, format: PIXELFORMAT_RGBA32F },
        { name: STREAM_LOCAL_SCALE, format: PIXELFORMAT_RGBA32F },
    ]);
    const anchorTex = resource.getTexture(STREAM_ANCHOR);
    const rotTex = resource.getTexture(STREAM_LOCAL_ROT);
    const scaleTex = resource.getTexture(STREAM_LOCAL_SCALE);
    const anchor = /** @type {Uint32Array} */ (anchorTex.lock());
    const rot = /** @type {Float32Array} */ (rotTex.lock());
    const scale = /** @type {Float32Array} */ (scaleTex.lock());
    const bits = new Float32Array(3);
    const bitsU = new Uint32Array(bits.buffer);
    const games = prim.profile === 'games';
    const third = /** @type {Float32Array} */ (games ? prim.rho : prim.normalOffset);
    for (let r = 0; r < order.length; ++r) {
        const i = order[r];
        bits[0] = prim.barycentrics[2 * i];
        bits[1] = prim.barycentrics[2 * i + 1];
        bits[2] = third[i];
        anchor[4 * r] = prim.faceIndex[i];
        anchor[4 * r + 1] = bitsU[0];
        anchor[4 * r + 2] = bitsU[1];
        anchor[4 * r + 3] = bitsU[2];
        if (games) {
            rot[4 * r + 3] = 1;
        } else {
            const lr = /** @type {Float32Array} */ (prim.localRotation);
            const ls = /** @type {Float32Array} */ (prim.localScale);
            for (let k = 0; k < 4; ++k) rot[4 * r + k] = lr[4 * i + k];
            for (let k = 0; k < 3; ++k) scale[4 * r + k] = ls[3 * i + k];
        }
    }
    anchorTex.unlock();
    rotTex.unlock();
    scaleTex.unlock();
}

/**
 * Anchor data on the GPU for one anchored primitive: per-splat streams in the engine's
 * resource, per-face textures and the current vertices. Used by AnchoredSplat and by the
 * conformance/benchmark probe (probe.js).
 */
export class AnchorGpuData {
    /**
     * @param {GraphicsDevice} device
     * @param {GSplatResource} resource  the engine's splat resource of the primitive
     * @param {AnchoredPrimitive} prim
     * @param {string} [fileName]
     */
    constructor(device, resource, prim, fileName = 'asset') {
        this.device = device;
        this.resource = resource;
        this.prim = prim;
        checkResource(resource);
        /** @type {RestQuantities} */
        this.rest = computeRest(prim);
        this.order = engineRowOrder(prim.rest.means);
        /** @type {any} the engine's rows (GSplatData for glTF splats; other layouts are not compared) */
        const data = resource.gsplatData;
        if (resource.numSplats !== prim.count) {
            throw new AnchorError('ENGINE_MISMATCH', `${fileName}: the engine loaded ${resource.numSplats} splats, the file has ${prim.count}`);
        }
        if (data) {
            const x = data.getProp('x'), y = data.getProp('y'), z = data.getProp('z');
            const m = prim.rest.means;
            for (let r = 0; r < prim.count; ++r) {
                const i = this.order[r];
                if (!(Object.is(x[r], m[3 * i]) && Object.is(y[r], m[3 * i + 1]) && Object.is(z[r], m[3 * i + 2]))) {
                    throw new AnchorError('ENGINE_MISMATCH', `${fileName}: the engine's splat row ${r} does not hold file splat ${i} (unexpected row order; the engine's Morton order, GSplatData#calcMortonOrder, assumed)`);
                }
            }
        }
        fillStreams(resource, prim, this.order);
        const F = this.rest.faceCount;
        const V = prim.anchorMesh.vertexCount;
        this.law = lawCode(prim);
        this.faces = createDataTexture(device, 'gsvFaces', F, PIXELFORMAT_RGBA32U);
        const faces = /** @type {Uint32Array} */ (this.faces.lock());
        const idx = prim.anchorMesh.indices;
        for (let f = 0; f < F; ++f) {
            faces[4 * f] = idx[3 * f];
            faces[4 * f + 1] = idx[3 * f + 1];
            faces[4 * f + 2] = idx[3 * f + 2];
            faces[4 * f + 3] = this.rest.regular[f];
        }
        this.faces.unlock();
        this.restTex = createDataTexture(device, 'gsvRest', F, PIXELFORMAT_RGBA32F);
        const rest = /** @type {Float32Array} */ (this.restTex.lock());
        for (let f = 0; f < F; ++f) {       // binary64 -> float32 only here
            rest[4 * f] = this.rest.cinv[3 * f];
            rest[4 * f + 1] = this.rest.cinv[3 * f + 1];
            rest[4 * f + 2] = this.rest.cinv[3 * f + 2];
            rest[4 * f + 3] = this.rest.invSqrtArea[f];
        }
        this.restTex.unlock();
        this.verticesTex = createDataTexture(device, 'gsvVertices', V, PIXELFORMAT_RGBA32F);
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
        const t = /** @type {Float32Array} */ (this.verticesTex.lock());
        for (let v = 0; v < V; ++v) {
            t[4 * v] = vertices[3 * v];
            t[4 * v + 1] = vertices[3 * v + 1];
            t[4 * v + 2] = vertices[3 * v + 2];
        }
        this.verticesTex.unlock();
    }

    /** The uniforms of the remap chunk. @returns {[string, Texture|number][]} */
    parameters() {
        return [['gsvVertices', this.verticesTex], ['gsvFaces', this.faces], ['gsvRest', this.restTex], ['gsvLaw', this.law]];
    }

    destroy() {
        this.faces.destroy();
        this.restTex.destroy();
        this.verticesTex.destroy();
    }
}

/**
 * One anchored splat primitive rendered by the engine and remapped on the GPU.
 *
 * Depth order: PlayCanvas (WebGL2) sorts splats on the CPU, in a worker, by the resource's
 * `centers`. Every `setVertices` also computes the deformed means on the CPU (`remapMeansInto`:
 * per face v0, e1, e2 and m once, then three multiply-adds per coordinate and splat, in the
 * engine's row order) into those centres, grows the resource's bounds to hold them, and tells
 * the engine they changed, so the next frames are drawn back to front in the *deformed* pose.
 *
 * The engine shows new centres only once its worker has sorted them (a new world state, drawn
 * when sorted), so new centres on every frame of a moving body would hold the picture back for
 * as long as the body moves. At most one set of centres is therefore in flight: while the
 * engine has not reported a sort ('gsplat:sorted') since the last set was handed over, later
 * poses only mark the centres stale, and the sort report hands over the newest pose's centres.
 * (A sort not reported within SORT_WAIT_MS, e.g. while nothing is drawn, releases the gate.)
 */
export class AnchoredSplat {
    /**
     * @param {AnchorGpuData} gpu
     * @param {Entity} entity
     * @param {GSplatComponent[]} components  every gsplat component showing this primitive
     * @param {Entity|null} anchorEntity
     * @param {string|null} fault
     * @param {{fire: Function, on: Function, off: Function}|null} [scene]  the app's scene, whose
     *   'gsplat:sorted' events pace the sort centres (without it every setVertices hands them over)
     */
    constructor(gpu, entity, components, anchorEntity, fault, scene = null) {
        /** @type {AnchorGpuData} */
        this.gpu = gpu;
        /** @type {AnchoredPrimitive} */
        this.prim = gpu.prim;
        /** @type {Entity} */
        this.entity = entity;
        /** @type {Entity|null} */
        this.anchorEntity = anchorEntity;
        /** @type {Uint32Array} */
        this.order = gpu.order;
        /** @type {RestQuantities} */
        this.rest = gpu.rest;
        /** CPU time of the last setVertices (vertex upload and the sort centres), ms */
        this.lastRemapMs = 0;
        /** CPU time of the sort centres of the last setVertices (part of lastRemapMs), ms */
        this.lastSortMs = 0;
        /** false: splats stay sorted by their rest positions (cheaper; wrong once they turn) */
        this.sortDeformed = fault !== 'rest-sort';
        this._components = components;
        this._modifier = { glsl: modifyChunkGLSL({ fault }), wgsl: modifyChunkWGSL({ fault }) };
        this._enabled = true;
        const resource = gpu.resource;
        /** @type {Float32Array} the engine's own rest centres (row order), restored by reset */
        this._restCenters = new Float32Array(resource.centers.subarray(0, 3 * this.prim.count));
        // the engine's bounds hold every splat's extent beyond its centre (2x its largest scale);
        // keep that margin, grown with the deformed centres' extent
        const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
        boundsInto(this._restCenters, lo, hi);
        const box = resource.aabb, bmin = box.getMin(), bmax = box.getMax();
        this._margin = Math.max(0, lo[0] - bmin.x, lo[1] - bmin.y, lo[2] - bmin.z, bmax.x - hi[0], bmax.y - hi[1], bmax.z - hi[2]);
        this._restDiagonal = Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) || 1;
        /** the anchors the sort centres need, in the engine's row order (read in sequence per frame) */
        this._rows = rowOrderedMeansAnchors(this.prim, this.order);
        /** @type {AnchorAnimation|null} the file's animation of this anchor mesh, or null */
        this.animation = null;
        /** @type {Float32Array|null} */
        this._animated = null;
        /** time (ms) the last set of centres was handed to the engine, 0 when it has been sorted */
        this._centresInFlight = 0;
        /** a pose arrived while centres were in flight: hand its centres over after the sort */
        this._centresStale = false;
        this._scene = scene;
        /** vertices were set since the engine's last sort: mark the work buffer dirty after it */
        this._refreshAfterSort = false;
        this._app = components[0]?.system?.app ?? null;
        /** frames left on which to mark the work buffer dirty again (see _onSorted) */
        this._remarkFrames = 0;
        this._remark = () => {
            if (this._remarkFrames <= 0 || !this._scene) return;
            this._remarkFrames--;
            for (const c of this._components) c.setParameter('gsvVertices', this.gpu.verticesTex);
        };
        this._app?.on('update', this._remark);
        this._onSorted = () => {
            this._centresInFlight = 0;
            if (this._refreshAfterSort && this._app) {
                // Observed on PlayCanvas 2.21-2.23: vertices set while the engine is applying
                // a sort result can be left undrawn (the instance's dirty mark is consumed, the
                // work buffer keeps the previous pose: the last pose of a paused animation
                // stayed on screen after going back to rest, until anything else changed).
                // Marking the instance dirty again on the few frames after the sort event
                // draws them; the cost is at most REMARK_FRAMES work-buffer copies per sort.
                this._refreshAfterSort = false;
                this._remarkFrames = REMARK_FRAMES;
            }
            if (this._centresStale) this._updateCenters(this._enabled ? this.gpu.current : null);
        };
        scene?.on('gsplat:sorted', this._onSorted);
        for (const c of components) {
            checkComponent(c);
            c.setWorkBufferModifier(this._modifier);
            for (const [name, value] of gpu.parameters()) c.setParameter(name, value);
        }
    }

    /** false: the engine renders its own rest pose (the remap modifier removed); true: remapped */
    get enabled() {
        return this._enabled;
    }

    set enabled(value) {
        this._enabled = !!value;
        for (const c of this._components) {
            c.setWorkBufferModifier(this._enabled ? this._modifier : null);
            c.setParameter('gsvVertices', this.gpu.verticesTex);   // marks the instance dirty
        }
        this._updateCenters(this._enabled ? this.gpu.current : null);
    }

    /** @param {ArrayLike<number>} vertices  (3V) current anchor vertices, splat-local space */
    setVertices(vertices) {
        const t0 = performance.now();
        this.gpu.upload(vertices);
        // re-setting the texture marks the instance dirty: the work buffer is re-copied
        // through the remap on the next frame
        for (const c of this._components) c.setParameter('gsvVertices', this.gpu.verticesTex);
        this._refreshAfterSort = !!this._scene;
        const t1 = performance.now();
        if (this._enabled) this._updateCenters(this.gpu.current);
        const t2 = performance.now();
        this.lastSortMs = t2 - t1;
        this.lastRemapMs = t2 - t0;
    }

    /**
     * The engine's sort centres and bounds for the current pose (null: the rest pose as loaded).
     * @param {ArrayLike<number>|null} vertices
     * @private
     */
    _updateCenters(vertices) {
        if (!this.sortDeformed) return;
        if (this._scene && this._centresInFlight && performance.now() - this._centresInFlight < SORT_WAIT_MS) {
            this._centresStale = true;
            return;
        }
        this._centresStale = false;
        const resource = this.gpu.resource;
        const centers = /** @type {Float32Array} */ (resource.centers);
        if (vertices) remapMeansInto(/** @type {AnchoredPrimitive} */ (this._rows), this.rest, vertices, centers);
        else centers.set(this._restCenters);
        const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
        boundsInto(centers.subarray(0, 3 * this.prim.count), lo, hi);
        if (!(lo[0] <= hi[0] && lo[1] <= hi[1] && lo[2] <= hi[2])) return;   // non-finite pose: keep the last bounds
        const grow = Math.max(1, Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / this._restDiagonal);
        const m = this._margin * grow;
        resource.aabb.setMinMax(new Vec3(lo[0] - m, lo[1] - m, lo[2] - m), new Vec3(hi[0] + m, hi[1] + m, hi[2] + m));
        centersChanged(resource);
        this._centresInFlight = performance.now();
    }

    /**
     * True while the engine has not yet sorted the current pose (centres handed over and not
     * reported sorted, or stale ones waiting): a picture taken now may show the previous order.
     */
    get sortPending() {
        return this.sortDeformed && !!this._scene && (this._centresStale || this._centresInFlight > 0);
    }

    /**
     * Pose the anchor mesh as the file's animation `index` plays it at `time` seconds (its skin
     * and morph targets, spec §Animated anchor meshes; times outside the keys clamp), and remap.
     * @param {number} index  animation index in the file
     * @param {number} time  seconds
     * @returns {Float32Array}  the anchor vertices used (splat-local space; reused by the next call)
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

    /** @returns {Float32Array} copy of the current vertices */
    get vertices() {
        return new Float32Array(this.gpu.current);
    }

    reset() {
        this.setVertices(this.prim.anchorMesh.vertices);
    }

    destroy() {
        for (const c of this._components) {
            c.setWorkBufferModifier(null);
            for (const [name] of this.gpu.parameters()) c.deleteParameter(name);
        }
        this._scene?.off('gsplat:sorted', this._onSorted);
        this._app?.off('update', this._remark);
        this._scene = null;
        this._updateCenters(null);
        this.gpu.destroy();
    }
}

/**
 * What remapMeansInto reads of a primitive, with the per-splat arrays permuted into the engine's
 * row order (row r = file splat order[r]), so that the per-frame pass reads them in sequence.
 * @param {AnchoredPrimitive} prim
 * @param {Uint32Array} order
 */
function rowOrderedMeansAnchors(prim, order) {
    const n = prim.count;
    const faceIndex = new Uint32Array(n);
    const barycentrics = new Float64Array(2 * n);
    const offset = prim.normalOffset ? new Float64Array(n) : null;
    for (let r = 0; r < n; ++r) {
        const i = order[r];
        faceIndex[r] = prim.faceIndex[i];
        barycentrics[2 * r] = prim.barycentrics[2 * i];
        barycentrics[2 * r + 1] = prim.barycentrics[2 * i + 1];
        if (offset) offset[r] = /** @type {ArrayLike<number>} */ (prim.normalOffset)[i];
    }
    return { count: n, profile: prim.profile, anchorMesh: prim.anchorMesh, faceIndex, barycentrics, normalOffset: offset };
}

/**
 * Bounds of 3N positions into lo/hi (non-finite values skipped).
 * @param {ArrayLike<number>} p @param {number[]} lo @param {number[]} hi
 */
function boundsInto(p, lo, hi) {
    for (let i = 0; i < p.length; i += 3) {
        for (let k = 0; k < 3; ++k) {
            const v = p[i + k];
            if (v < lo[k]) lo[k] = v;
            if (v > hi[k]) hi[k] = v;
        }
    }
}

/**
 * Load the engine's container asset from bytes.
 * @param {AppBase} app
 * @param {Uint8Array} bytes
 * @param {string} name
 * @returns {Promise<Asset>}
 */
function loadContainer(app, bytes, name) {
    const url = URL.createObjectURL(new Blob([/** @type {BlobPart} */ (bytes)], { type: 'model/gltf-binary' }));
    const filename = /\.(glb|gltf)$/i.test(name) ? name : `${name}.glb`;
    const asset = new Asset(filename, 'container', { url, filename });
    return new Promise((resolve, reject) => {
        asset.once('load', () => { URL.revokeObjectURL(url); resolve(asset); });
        asset.once('error', (/** @type {any} */ err) => {
            URL.revokeObjectURL(url);
            reject(new AnchorError('ENGINE_LOAD', `${name}: the engine could not load the asset: ${err}`));
        });
        app.assets.add(asset);
        app.assets.load(asset);
    });
}

/**
 * Load a GLB with anchored splats: an SPZ-compressed rest pose decoded first (expandCompressed),
 * the engine's container loader for the rest pose, our reader for the anchors (refusals throw
 * AnchorError), anchor data uploaded once, the remap
 * installed as the instances' work-buffer modifier.
 * @param {AppBase} app
 * @param {string|Uint8Array|ArrayBuffer} source  URL or GLB bytes
 * @param {{name?: string, parent?: Entity|null, showAnchorMesh?: boolean, fault?: string|null}} [options]
 * @returns {Promise<{root: Entity, anchored: AnchoredSplat[], plain: Entity[], asset: Asset, animations: AnimationInfo[]}>}
 */
export async function loadAnchoredAsset(app, source, options = {}) {
    const device = app.graphicsDevice;
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
    const { anchored: prims, json } = readAnchoredGlb(bytes, { name });   // refusals throw here
    const doc = parseGltf(bytes);
    const animations = prims.map((prim) => readAnchorAnimation(doc, prim, { name }));   // and here
    checkEngine();
    const asset = await loadContainer(app, bytes, name);
    const container = /** @type {any} */ (asset.resource);
    const root = /** @type {Entity} */ (container.instantiateRenderEntity());
    const parent = options.parent === undefined ? app.root : options.parent;
    const gsplatComponents = /** @type {any[]} */ (root.findComponents('gsplat'));
    const anchoredAssetIds = new Set();
    /** @type {AnchoredSplat[]} */
    const anchored = [];
    for (const [p, prim] of prims.entries()) {
        const meshAssets = meshSplatAssets(container, prim.splatMesh);
        const khrBefore = json.meshes[prim.splatMesh].primitives
            .slice(0, prim.splatPrimitive).filter((/** @type {any} */ p) => p?.extensions?.KHR_gaussian_splatting).length;
        const gsplatAsset = meshAssets?.[khrBefore];
        if (!gsplatAsset?.resource) {
            throw new AnchorError('ENGINE_MISMATCH', `${name}: the engine created no splat resource for meshes[${prim.splatMesh}].primitives[${prim.splatPrimitive}]`);
        }
        anchoredAssetIds.add(gsplatAsset.id);
        const components = gsplatComponents.filter((c) => c.asset === gsplatAsset.id);
        const gpu = new AnchorGpuData(device, gsplatAsset.resource, prim, name);
        const renderAsset = container.renders?.[prim.anchorMesh.mesh];
        const anchorEntity = renderAsset
            ? /** @type {Entity|null} */ (root.findComponents('render').find((/** @type {any} */ r) => r.asset === renderAsset.id)?.entity ?? null)
            : null;
        if (anchorEntity?.render && !options.showAnchorMesh) anchorEntity.render.enabled = false;
        const entity = components[0]?.entity ?? root;
        const splat = new AnchoredSplat(gpu, entity, components, anchorEntity, options.fault ?? null, app.scene);
        splat.animation = animations[p];
        anchored.push(splat);
    }
    const plain = gsplatComponents.filter((c) => !anchoredAssetIds.has(c.asset)).map((c) => c.entity);
    if (parent) parent.addChild(root);
    return { root, anchored, plain, asset, animations: animations.find((a) => a)?.animations ?? [] };
}
