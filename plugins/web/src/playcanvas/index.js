/**
 * @gsverse/web/playcanvas: mesh-anchored Gaussian splats (GSVERSE_gaussian_splatting_mesh_anchor)
 * remapped on the GPU inside PlayCanvas 2.23.3's unified gsplat pipeline.
 *
 *   import { loadAnchoredAsset } from '@gsverse/web/playcanvas';
 *   const { root, anchored, plain } = await loadAnchoredAsset(app, 'asset.glb' | bytes, {
 *       name,            // file name used in messages (default: from the URL, or 'asset.glb')
 *       parent,          // Entity to add root to (default app.root; null: not added)
 *       showAnchorMesh,  // keep the anchor mesh's own render component enabled (default false)
 *       fault,           // testing only: a deliberately broken shader variant (see shader.js)
 *   });
 *   // root:     the glTF scene instantiated by the engine's container loader (rest pose)
 *   // anchored: AnchoredSplat[], one per anchored splat primitive
 *   // plain:    Entity[] holding the plain (unanchored) splats, left untouched
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
 *   s.lastRemapMs      // CPU time of the last setVertices (upload + work-buffer scheduling), ms
 *   s.destroy()
 *
 * Refused assets throw AnchorError (../anchor.js) with `.code` and a one-line message.
 * WebGL2 (GLSL, shader.js) and WebGPU (WGSL, shader-wgsl.js): the engine picks the chunk of
 * its device.
 */

import {
    Asset, Entity, GSplatData, Texture,
    ADDRESS_CLAMP_TO_EDGE, FILTER_NEAREST, PIXELFORMAT_RGBA32F, PIXELFORMAT_RGBA32U,
} from 'playcanvas';
import { AnchorError, readAnchoredGlb } from '../anchor.js';
import { computeRest } from '../rest.js';
import { STREAM_ANCHOR, STREAM_LOCAL_ROT, STREAM_LOCAL_SCALE, modifyChunkGLSL } from './shader.js';
import { modifyChunkWGSL } from './shader-wgsl.js';

export { FAULTS, remapChunkGLSL, modifyChunkGLSL, processChunkGLSL } from './shader.js';
export { remapChunkWGSL, modifyChunkWGSL, processChunkWGSL } from './shader-wgsl.js';
export { AnchorError };

/** @typedef {import('../types.js').AnchoredPrimitive} AnchoredPrimitive */
/** @typedef {import('../types.js').RestQuantities} RestQuantities */
/** @typedef {import('playcanvas').AppBase} AppBase */
/** @typedef {import('playcanvas').GraphicsDevice} GraphicsDevice */

/** Largest width of the data textures (every WebGL2 device supports 4096). */
const MAX_WIDTH = 4096;

/**
 * @param {number} count
 * @returns {[number, number]}
 */
function textureSize(count) {
    const width = Math.max(1, Math.min(count, MAX_WIDTH));
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
     * @param {any} resource  the engine's GSplatResource of the primitive
     * @param {AnchoredPrimitive} prim
     * @param {string} [fileName]
     */
    constructor(device, resource, prim, fileName = 'asset') {
        this.device = device;
        this.resource = resource;
        this.prim = prim;
        /** @type {RestQuantities} */
        this.rest = computeRest(prim);
        this.order = engineRowOrder(prim.rest.means);
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
                    throw new AnchorError('ENGINE_MISMATCH', `${fileName}: the engine's splat row ${r} does not hold file splat ${i} (unexpected row order; PlayCanvas 2.23.3 Morton order assumed)`);
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

    /** The uniforms of the remap chunk. @returns {[string, any][]} */
    parameters() {
        return [['gsvVertices', this.verticesTex], ['gsvFaces', this.faces], ['gsvRest', this.restTex], ['gsvLaw', this.law]];
    }

    destroy() {
        this.faces.destroy();
        this.restTex.destroy();
        this.verticesTex.destroy();
    }
}

/** One anchored splat primitive rendered by the engine and remapped on the GPU. */
export class AnchoredSplat {
    /**
     * @param {AnchorGpuData} gpu
     * @param {Entity} entity
     * @param {any[]} components  every gsplat component showing this primitive
     * @param {Entity|null} anchorEntity
     * @param {string|null} fault
     */
    constructor(gpu, entity, components, anchorEntity, fault) {
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
        /** CPU time of the last setVertices, ms */
        this.lastRemapMs = 0;
        this._components = components;
        this._modifier = { glsl: modifyChunkGLSL({ fault }), wgsl: modifyChunkWGSL({ fault }) };
        this._enabled = true;
        for (const c of components) {
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
    }

    /** @param {ArrayLike<number>} vertices  (3V) current anchor vertices, splat-local space */
    setVertices(vertices) {
        const t0 = performance.now();
        this.gpu.upload(vertices);
        // re-setting the texture marks the instance dirty: the work buffer is re-copied
        // through the remap on the next frame
        for (const c of this._components) c.setParameter('gsvVertices', this.gpu.verticesTex);
        this.lastRemapMs = performance.now() - t0;
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
        this.gpu.destroy();
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
 * Load a GLB with anchored splats: the engine's container loader for the rest pose, our
 * reader for the anchors (refusals throw AnchorError), anchor data uploaded once, the remap
 * installed as the instances' work-buffer modifier.
 * @param {AppBase} app
 * @param {string|Uint8Array|ArrayBuffer} source  URL or GLB bytes
 * @param {{name?: string, parent?: Entity|null, showAnchorMesh?: boolean, fault?: string|null}} [options]
 * @returns {Promise<{root: Entity, anchored: AnchoredSplat[], plain: Entity[], asset: Asset}>}
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
    const { anchored: prims } = readAnchoredGlb(bytes, { name });   // refusals throw here
    const asset = await loadContainer(app, bytes, name);
    const container = /** @type {any} */ (asset.resource);
    const root = /** @type {Entity} */ (container.instantiateRenderEntity());
    const parent = options.parent === undefined ? app.root : options.parent;
    const gsplatComponents = /** @type {any[]} */ (root.findComponents('gsplat'));
    const anchoredAssetIds = new Set();
    /** @type {AnchoredSplat[]} */
    const anchored = [];
    for (const prim of prims) {
        const meshAssets = container._meshGSplats?.[prim.splatMesh];
        const khrBefore = container.data?.gltf?.meshes?.[prim.splatMesh]?.primitives
            ?.slice(0, prim.splatPrimitive).filter((/** @type {any} */ p) => p?.extensions?.KHR_gaussian_splatting).length ?? 0;
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
        anchored.push(new AnchoredSplat(gpu, entity, components, anchorEntity, options.fault ?? null));
    }
    const plain = gsplatComponents.filter((c) => !anchoredAssetIds.has(c.asset)).map((c) => c.entity);
    if (parent) parent.addChild(root);
    return { root, anchored, plain, asset };
}
