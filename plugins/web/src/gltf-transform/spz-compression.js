// glTF-Transform support for KHR_gaussian_splatting_compression_spz_2 (spec/README.md
// §SPZ-compressed rest pose), nested in a splat primitive's KHR_gaussian_splatting object: the
// SPZ stream is carried through read, transform and write as it is, never decoded (gunzip is
// asynchronous; glTF-Transform's extension hooks are not). As KHR_draco_mesh_compression does in
// glTF-Transform, the primitive's attribute accessors are written by this extension, as
// placeholders: type, component type and count, no bufferView (POSITION with the bounds it was
// read with), and the stream goes into a buffer view of its own.
//
// The placeholders read as zeros, so transforms see no splat data. Writing refuses (one-line
// SpzCompressionError, nothing written) when a transform changed what the stream describes:
// the number of splats, the attributes, or values written into a placeholder.

import { Extension, ExtensionProperty, PropertyType } from '@gltf-transform/core';
import { SPZ_EXTENSION } from '../anchor.js';
import { KHR_GAUSSIAN_SPLATTING } from './khr-gaussian-splatting.js';

/** @typedef {import('@gltf-transform/core').Accessor} Accessor */
/** @typedef {import('@gltf-transform/core').Primitive} Primitive */
/** @typedef {import('@gltf-transform/core').ReaderContext} ReaderContext */
/** @typedef {import('@gltf-transform/core').WriterContext} WriterContext */

export { SPZ_EXTENSION };

/** A compressed primitive that cannot be written consistently; `message` is one line. */
export class SpzCompressionError extends Error {
    /** @param {string} message */
    constructor(message) {
        super(message);
        this.name = 'SpzCompressionError';
    }
}

/**
 * @typedef {Object} ISpzCompression
 * @property {string} name
 * @property {Record<string, unknown>} extras
 * @property {Uint8Array | null} stream the buffer view's bytes: one gzip member holding the SPZ stream
 */

/**
 * The `KHR_gaussian_splatting_compression_spz_2` object of one splat primitive: its stream.
 * @extends {ExtensionProperty<ISpzCompression>}
 */
export class SpzCompression extends ExtensionProperty {
    static EXTENSION_NAME = SPZ_EXTENSION;

    /** @returns {typeof SPZ_EXTENSION} */
    get extensionName() { return SPZ_EXTENSION; }
    /** @returns {'SpzCompression'} */
    get propertyType() { return 'SpzCompression'; }
    /** @returns {['Primitive']} */
    get parentTypes() { return [PropertyType.PRIMITIVE]; }

    /**
     * @protected
     * @returns {undefined}
     */
    init() {
        /**
         * The placeholders as read: attribute -> count and POSITION's bounds (null when made
         * with the API).
         * @type {{attributes: Map<string, number>, min: number[] | null, max: number[] | null} | null}
         */
        this.readState = null;
    }

    /**
     * @protected
     * @returns {import('@gltf-transform/core').Nullable<ISpzCompression>}
     */
    getDefaults() {
        return Object.assign(super.getDefaults(), { stream: null });
    }

    /** @returns {Uint8Array | null} */
    getStream() { return this.get('stream'); }
    /** @param {Uint8Array | null} stream */
    setStream(stream) { return this.set('stream', stream); }

    /**
     * @param {this} other
     * @param {import('@gltf-transform/core').PropertyResolver<import('@gltf-transform/core').Property>} [resolve]
     * @returns {this}
     */
    copy(other, resolve) {
        super.copy(other, resolve);
        this.readState = other.readState;
        return this;
    }
}

/**
 * [`KHR_gaussian_splatting_compression_spz_2`](../../../spec/README.md) for glTF-Transform:
 * keeps SPZ-compressed splat primitives compressed through read, transform and write. Register
 * it with {@link KHRGaussianSplatting} (the `gsverseExtensions` list).
 */
export class KHRGaussianSplattingCompressionSpz extends Extension {
    static EXTENSION_NAME = SPZ_EXTENSION;
    extensionName = SPZ_EXTENSION;
    /** @type {import('@gltf-transform/core').PropertyType[]} */
    prewriteTypes = [PropertyType.ACCESSOR, PropertyType.BUFFER];

    /** Creates a compression object for a splat {@link Primitive}. */
    createSpzCompression() {
        return new SpzCompression(this.document.getGraph());
    }

    /**
     * @param {ReaderContext} context
     * @returns {this}
     */
    read(context) {
        const json = context.jsonDoc.json;
        (json.meshes || []).forEach((meshDef, m) => {
            (meshDef.primitives || []).forEach((primDef, p) => {
                const khr = /** @type {Record<string, any> | undefined} */ (primDef.extensions?.[KHR_GAUSSIAN_SPLATTING]);
                const def = /** @type {Record<string, any> | undefined} */ (khr?.extensions?.[SPZ_EXTENSION]);
                if (def === undefined) return;
                const where = `${SPZ_EXTENSION}: meshes[${m}].primitives[${p}]`;
                const view = def && Number.isInteger(def.bufferView) ? context.bufferViews[def.bufferView] : undefined;
                if (!view) throw new SpzCompressionError(`${where}: bufferView ${JSON.stringify(def?.bufferView)} does not exist`);
                const spz = this.createSpzCompression().setStream(view.slice());
                /** @type {Map<string, number>} */
                const attributes = new Map();
                for (const [semantic, index] of Object.entries(primDef.attributes || {})) {
                    attributes.set(semantic, json.accessors?.[index]?.count ?? -1);
                }
                const position = json.accessors?.[primDef.attributes?.POSITION ?? -1];
                spz.readState = { attributes, min: position?.min ?? null, max: position?.max ?? null };
                if (def.extras && typeof def.extras === 'object') spz.setExtras(def.extras);
                context.meshes[m].listPrimitives()[p].setExtension(SPZ_EXTENSION, spz);
            });
        });
        return this;
    }

    /**
     * ACCESSOR: the compressed primitives' attributes written here as placeholders (no
     * bufferView), before the core writer lays out the others. BUFFER: the streams handed to
     * the first buffer as buffer views of their own.
     * @param {WriterContext} context
     * @param {import('@gltf-transform/core').PropertyType} type
     * @returns {this}
     */
    prewrite(context, type) {
        const json = context.jsonDoc.json;
        for (const [prim, spz, where] of this.compressed(context)) {
            if (type === PropertyType.BUFFER) {
                const buffer = this.document.getRoot().listBuffers()[0];
                const stream = spz.getStream();
                if (!buffer || !stream) throw new SpzCompressionError(`${where}: no buffer to write the SPZ stream into`);
                const views = context.otherBufferViews.get(buffer) || [];
                views.push(stream);
                context.otherBufferViews.set(buffer, views);
                continue;
            }
            checkPlaceholders(prim, spz, where);
            for (const semantic of prim.listSemantics()) {
                const accessor = /** @type {Accessor} */ (prim.getAttribute(semantic));
                if (context.accessorIndexMap.has(accessor)) continue;   // shared by another compressed primitive
                const def = context.createAccessorDef(accessor);
                delete def.min;     // the bounds of zeros; POSITION's own are set in write()
                delete def.max;
                json.accessors = json.accessors || [];
                context.accessorIndexMap.set(accessor, json.accessors.length);
                json.accessors.push(def);
            }
        }
        return this;
    }

    /**
     * @param {WriterContext} context
     * @returns {this}
     */
    write(context) {
        const json = context.jsonDoc.json;
        const meshDefs = json.meshes || [];
        const accessors = json.accessors || [];
        /** @type {Set<number>} */
        const used = new Set();
        for (const [prim, spz, where, meshIndex, p] of this.compressed(context)) {
            const primDef = meshDefs[meshIndex].primitives[p];
            // one placeholder per attribute: dedup merges placeholders (all zeros) into one
            // accessor, which would give the others POSITION's bounds
            for (const semantic of prim.listSemantics()) {
                let index = primDef.attributes[semantic];
                if (used.has(index)) {
                    const { min: _min, max: _max, ...copy } = accessors[index];
                    accessors.push(copy);
                    index = accessors.length - 1;
                    primDef.attributes[semantic] = index;
                }
                used.add(index);
                if (semantic === 'POSITION' && spz.readState?.min && spz.readState.max) {
                    accessors[index].min = spz.readState.min;
                    accessors[index].max = spz.readState.max;
                }
            }
            const view = context.otherBufferViewsIndexMap.get(/** @type {Uint8Array} */ (spz.getStream()));
            if (view === undefined) throw new SpzCompressionError(`${where}: the SPZ stream was not written`);
            primDef.extensions = primDef.extensions || {};
            const khr = /** @type {Record<string, any>} */ (primDef.extensions[KHR_GAUSSIAN_SPLATTING] ||= {});
            khr.extensions = khr.extensions || {};
            /** @type {Record<string, unknown>} */
            const def = { bufferView: view };
            if (Object.keys(spz.getExtras()).length) def.extras = spz.getExtras();
            khr.extensions[SPZ_EXTENSION] = def;
        }
        return this;
    }

    /**
     * The compressed primitives to write: (primitive, its object, where, mesh index, primitive index).
     * @param {WriterContext} context
     * @returns {[Primitive, SpzCompression, string, number, number][]}
     */
    compressed(context) {
        /** @type {[Primitive, SpzCompression, string, number, number][]} */
        const out = [];
        // before the meshes are written (prewrite) meshIndexMap is empty: number them as the
        // writer will, every mesh of the root in order
        this.document.getRoot().listMeshes().forEach((mesh, m) => {
            const meshIndex = context.meshIndexMap.get(mesh) ?? m;
            mesh.listPrimitives().forEach((prim, p) => {
                const spz = prim.getExtension(SPZ_EXTENSION);
                if (!(spz instanceof SpzCompression)) return;
                const where = `${SPZ_EXTENSION}: refusing to write meshes[${meshIndex}].primitives[${p}]`;
                if (!prim.getExtension(KHR_GAUSSIAN_SPLATTING)) {
                    throw new SpzCompressionError(`${where}: it has no ${KHR_GAUSSIAN_SPLATTING} object (register both gsverseExtensions)`);
                }
                out.push([prim, spz, where, meshIndex, p]);
            });
        });
        return out;
    }
}

/**
 * The placeholders must still be what the stream describes: the same attributes, each of the
 * stream's splat count, all zeros (what glTF reads from an accessor without a bufferView).
 * @param {Primitive} prim
 * @param {SpzCompression} spz
 * @param {string} where
 */
function checkPlaceholders(prim, spz, where) {
    const state = spz.readState;
    const semantics = prim.listSemantics();
    if (state) {
        const before = Array.from(state.attributes.keys()).sort().join(', ');
        const after = semantics.slice().sort().join(', ');
        if (before !== after) throw new SpzCompressionError(`${where}: a transform changed its attributes (${before} -> ${after}); the SPZ stream supplies the ones it was read with`);
    }
    for (const semantic of semantics) {
        const accessor = /** @type {Accessor} */ (prim.getAttribute(semantic));
        const count = state?.attributes.get(semantic);
        if (count !== undefined && accessor.getCount() !== count) {
            throw new SpzCompressionError(`${where}: its ${semantic} has ${accessor.getCount()} elements, the SPZ stream ${count} splats (a transform added, removed or merged splats)`);
        }
        const array = accessor.getArray();
        let nonzero = false;
        for (let i = 0; array && i < array.length && !nonzero; ++i) nonzero = array[i] !== 0;
        if (nonzero) {
            throw new SpzCompressionError(`${where}: a transform wrote values into its ${semantic} placeholder; the SPZ stream holds the splats and does not change with them`);
        }
    }
}
