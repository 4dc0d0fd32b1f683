// glTF-Transform support for KHR_gaussian_splatting: the primitive-level extension object
// (kernel, colorSpace, projection, sortingMethod) read into a GaussianSplatting property and
// written back. The vertex attributes (POSITION, KHR_gaussian_splatting:ROTATION, ...) are plain
// primitive attributes that glTF-Transform keeps on its own. Nested extensions are written by
// their own extension classes (GSVERSE_gaussian_splatting_mesh_anchor: mesh-anchor.js).

import { Extension, ExtensionProperty, PropertyType } from '@gltf-transform/core';

/** @typedef {import('@gltf-transform/core').ReaderContext} ReaderContext */
/** @typedef {import('@gltf-transform/core').WriterContext} WriterContext */
/** @typedef {import('@gltf-transform/core').Primitive} Primitive */

export const KHR_GAUSSIAN_SPLATTING = 'KHR_gaussian_splatting';
export const GSVERSE_MESH_ANCHOR = 'GSVERSE_gaussian_splatting_mesh_anchor';

/** The properties of the extension object this class models (everything else is kept verbatim). */
const KNOWN = ['kernel', 'colorSpace', 'projection', 'sortingMethod'];

/**
 * @typedef {Object} IGaussianSplatting
 * @property {string} name
 * @property {Record<string, unknown>} extras
 * @property {string | null} kernel
 * @property {string | null} colorSpace
 * @property {string | null} projection
 * @property {string | null} sortingMethod
 * @property {Record<string, unknown>} other properties of the extension object this class does not model, kept as read
 */

/**
 * The `KHR_gaussian_splatting` object of one splat primitive.
 * @extends {ExtensionProperty<IGaussianSplatting>}
 */
export class GaussianSplatting extends ExtensionProperty {
    static EXTENSION_NAME = KHR_GAUSSIAN_SPLATTING;

    /** @returns {typeof KHR_GAUSSIAN_SPLATTING} */
    get extensionName() { return KHR_GAUSSIAN_SPLATTING; }
    /** @returns {'GaussianSplatting'} */
    get propertyType() { return 'GaussianSplatting'; }
    // the precise types below keep these members in the generated declarations (types/), where
    // ExtensionProperty's abstract members must be implemented
    /** @returns {['Primitive']} */
    get parentTypes() { return [PropertyType.PRIMITIVE]; }

    /**
     * @protected
     * @returns {undefined}
     */
    init() {
        /** @type {boolean} read from a file (false when made with the API) */
        this.readFromFile = false;
    }

    /**
     * @param {this} other
     * @param {import('@gltf-transform/core').PropertyResolver<import('@gltf-transform/core').Property>} [resolve]
     * @returns {this}
     */
    copy(other, resolve) {
        super.copy(other, resolve);
        this.readFromFile = other.readFromFile;
        return this;
    }

    /**
     * @protected
     * @returns {import('@gltf-transform/core').Nullable<IGaussianSplatting>}
     */
    getDefaults() {
        return Object.assign(super.getDefaults(), {
            kernel: null, colorSpace: null, projection: null, sortingMethod: null, other: {},
        });
    }

    /** @returns {string | null} */
    getKernel() { return this.get('kernel'); }
    /** @param {string | null} kernel */
    setKernel(kernel) { return this.set('kernel', kernel); }
    /** @returns {string | null} */
    getColorSpace() { return this.get('colorSpace'); }
    /** @param {string | null} colorSpace */
    setColorSpace(colorSpace) { return this.set('colorSpace', colorSpace); }
    /** @returns {string | null} */
    getProjection() { return this.get('projection'); }
    /** @param {string | null} projection */
    setProjection(projection) { return this.set('projection', projection); }
    /** @returns {string | null} */
    getSortingMethod() { return this.get('sortingMethod'); }
    /** @param {string | null} sortingMethod */
    setSortingMethod(sortingMethod) { return this.set('sortingMethod', sortingMethod); }
    /** Properties of the extension object not modelled here, as read. @returns {Record<string, unknown>} */
    getOtherProperties() { return this.get('other'); }
    /** @param {Record<string, unknown>} other */
    setOtherProperties(other) { return this.set('other', other); }
}

/**
 * [`KHR_gaussian_splatting`](https://github.com/KhronosGroup/glTF/tree/main/extensions/2.0/Khronos/KHR_gaussian_splatting)
 * for glTF-Transform: keeps the splat primitives' extension object through read, transform and
 * write. Register it together with {@link GSVERSEMeshAnchor} (the `gsverseExtensions` list) to
 * keep mesh-anchored splats anchored.
 */
export class KHRGaussianSplatting extends Extension {
    static EXTENSION_NAME = KHR_GAUSSIAN_SPLATTING;
    extensionName = KHR_GAUSSIAN_SPLATTING;

    /** Creates a `KHR_gaussian_splatting` object for a splat {@link Primitive} (mode POINTS). */
    createGaussianSplatting() {
        return new GaussianSplatting(this.document.getGraph());
    }

    /**
     * @param {ReaderContext} context
     * @returns {this}
     */
    read(context) {
        const logger = this.document.getLogger();
        const registered = new Set(this.document.getRoot().listExtensionsUsed().map((ext) => ext.extensionName));
        (context.jsonDoc.json.meshes || []).forEach((meshDef, m) => {
            (meshDef.primitives || []).forEach((primDef, p) => {
                const def = /** @type {Record<string, any> | undefined} */ (primDef.extensions?.[KHR_GAUSSIAN_SPLATTING]);
                if (!def || typeof def !== 'object') return;
                const splat = this.createGaussianSplatting();
                splat.readFromFile = true;
                /** @type {Record<string, unknown>} */
                const other = {};
                for (const [key, value] of Object.entries(def)) {
                    if (key === 'extensions' || key === 'extras') continue;
                    if (KNOWN.includes(key) && typeof value === 'string') continue;
                    other[key] = value;
                }
                splat.setKernel(typeof def.kernel === 'string' ? def.kernel : null)
                    .setColorSpace(typeof def.colorSpace === 'string' ? def.colorSpace : null)
                    .setProjection(typeof def.projection === 'string' ? def.projection : null)
                    .setSortingMethod(typeof def.sortingMethod === 'string' ? def.sortingMethod : null)
                    .setOtherProperties(other);
                if (def.extras && typeof def.extras === 'object') splat.setExtras(def.extras);
                for (const name of Object.keys(def.extensions || {})) {
                    if (registered.has(name)) continue;   // GSVERSE_mesh_anchor, the SPZ compression: their own classes
                    logger.warn(`${KHR_GAUSSIAN_SPLATTING}: meshes[${m}].primitives[${p}]: nested extension "${name}" `
                        + 'is not registered and will not be written.');
                }
                context.meshes[m].listPrimitives()[p].setExtension(KHR_GAUSSIAN_SPLATTING, splat);
            });
        });
        return this;
    }

    /**
     * @param {WriterContext} context
     * @returns {this}
     */
    write(context) {
        const meshDefs = context.jsonDoc.json.meshes || [];
        /** @type {Set<GaussianSplatting>} */
        const written = new Set();
        for (const mesh of this.document.getRoot().listMeshes()) {
            const meshIndex = context.meshIndexMap.get(mesh);
            if (meshIndex === undefined) continue;
            mesh.listPrimitives().forEach((prim, p) => {
                const splat = prim.getExtension(KHR_GAUSSIAN_SPLATTING);
                if (!(splat instanceof GaussianSplatting)) return;
                written.add(splat);
                const primDef = meshDefs[meshIndex].primitives[p];
                primDef.extensions = primDef.extensions || {};
                // A nested extension (written by its own class, in any order) is kept.
                const previous = /** @type {Record<string, any> | undefined} */ (primDef.extensions[KHR_GAUSSIAN_SPLATTING]);
                /** @type {Record<string, unknown>} */
                const def = {};
                for (const [key, value] of [['kernel', splat.getKernel()], ['colorSpace', splat.getColorSpace()],
                    ['projection', splat.getProjection()], ['sortingMethod', splat.getSortingMethod()]]) {
                    if (value !== null) def[/** @type {string} */ (key)] = value;
                }
                Object.assign(def, splat.getOtherProperties());
                if (Object.keys(splat.getExtras()).length) def.extras = splat.getExtras();
                if (previous?.extensions) def.extensions = previous.extensions;
                primDef.extensions[KHR_GAUSSIAN_SPLATTING] = def;
            });
        }
        const lost = Array.from(this.properties).filter((prop) => prop instanceof GaussianSplatting
            && prop.readFromFile && !written.has(prop)).length;
        if (lost) {
            this.document.getLogger().warn(`${KHR_GAUSSIAN_SPLATTING}: ${lost} splat primitive(s) read from the input `
                + 'are no longer in the output (a transform such as join rebuilt or removed them); '
                + 'what replaced them is written without this extension.');
        }
        return this;
    }
}
