/**
 * The GLSL remap of the PlayCanvas plugin: the engine-free chunk of src/remap-glsl.js (its
 * per-splat inputs read through the engine's generated stream loaders, `splat.index` the
 * engine's row) wrapped for
 *   - the engine's unified work-buffer copy pass (`gsplatModifyVS` via the gsplat component's
 *     work-buffer modifier: `modifySplatCenter` / `modifySplatRotationScale`, see
 *     `modifyChunkGLSL()`), which is what renders, and
 *   - the conformance/benchmark pass (`processChunkGLSL()`, run by the engine's
 *     `GSplatProcessor` over the same splat streams), which writes float32 results that are
 *     read back from the GPU.
 * The per-splat inputs are extra resource streams in the engine's row order (`loadXxx()`).
 */

import { REMAP_FAULTS, cap, remapChunkGLSL as coreChunk } from '../remap-glsl.js';

export { GSV_JACOBI_SWEEPS, STREAM_ANCHOR, STREAM_LOCAL_ROT, STREAM_LOCAL_SCALE } from '../remap-glsl.js';

/** Deliberately broken variants (for the conformance test that the suite catches them). */
export const FAULTS = {
    ...REMAP_FAULTS,
    // render-level faults: the remap itself is right, what the engine draws is not
    /** the render wrapper hands the engine the scales in the wrong order (y, x, z) */
    'scale-swizzle': 'the render wrapper packs the scales as (y, x, z)',
    /** the render wrapper ignores the splat node's transform (splat-local output drawn as world) */
    'node-transform': "the render wrapper ignores the splat node's transform",
    /** splats keep the engine's sort by rest positions (the deformed centres are never sent) */
    'rest-sort': 'splats sorted by their rest positions, not the deformed ones',
};

/** The faults that break only what is drawn (the conformance remap pass is unaffected). */
export const RENDER_FAULTS = ['scale-swizzle', 'node-transform', 'rest-sort'];

/**
 * The remap functions (one string, shared by the render and the conformance pass).
 * @param {{fault?: string|null}} [options]
 * @returns {string}
 */
export function remapChunkGLSL(options = {}) {
    const fault = options.fault ?? null;
    if (fault !== null && !(fault in FAULTS)) {
        throw new Error(`unknown shader fault '${fault}' (known: ${Object.keys(FAULTS).join(', ')})`);
    }
    return coreChunk(options);
}

/**
 * The engine's work-buffer modifier (`gsplatModifyVS` of the unified copy pass): the remap in
 * splat-local space, then the instance transform as the engine applies it to its own splats
 * (center through matrix_model, rotation model_rotation * q, scale model_scale * s).
 * @param {{fault?: string|null}} [options]
 * @returns {string}
 */
export function modifyChunkGLSL(options = {}) {
    const fault = options.fault ?? null;
    const node = fault !== 'node-transform';
    const center = node ? '(matrix_model * vec4(gsvMeanLocal, 1.0)).xyz' : 'gsvMeanLocal';
    const quat = node ? 'quatMul(model_rotation, gsvQuatLocal)' : 'gsvQuatLocal';
    const local = fault === 'scale-swizzle' ? 'gsvScaleLocal.yxz' : 'gsvScaleLocal';
    return `${remapChunkGLSL(options)}
vec3 gsvMeanLocal;
vec4 gsvQuatLocal;
vec3 gsvScaleLocal;
void modifySplatCenter(inout vec3 center) {
    gsvRemapSplat(gsvMeanLocal, gsvQuatLocal, gsvScaleLocal);
    center = ${center};
}
void modifySplatRotationScale(vec3 originalCenter, vec3 modifiedCenter, inout vec4 rotation, inout vec3 scale) {
    vec4 q = ${quat};
    rotation = q.w < 0.0 ? -q : q;
    scale = ${node ? 'model_scale * ' : ''}${local};
}
void modifySplatColor(vec3 center, inout vec4 color) {
}
`;
}

/** Names of the float32 output streams of the conformance/benchmark pass. */
export const STREAM_OUT_MEAN = 'gsvOutMean';
export const STREAM_OUT_ROT = 'gsvOutRot';
export const STREAM_OUT_SCALE = 'gsvOutScale';

/**
 * `process()` for the engine's GSplatProcessor: the same remap, written to float32 streams
 * (mean, quaternion, scale) for GPU readback.
 * @param {{fault?: string|null}} [options]
 * @returns {string}
 */
export function processChunkGLSL(options = {}) {
    return `${remapChunkGLSL(options)}
void process() {
    vec3 mean;
    vec4 quat;
    vec3 scale;
    gsvRemapSplat(mean, quat, scale);
    write${cap(STREAM_OUT_MEAN)}(vec4(mean, 1.0));
    write${cap(STREAM_OUT_ROT)}(quat);
    write${cap(STREAM_OUT_SCALE)}(vec4(scale, 0.0));
}
`;
}

/** The remap chunk of the render and of the conformance pass (GLSL), without a fault. */
export const REMAP_GLSL = remapChunkGLSL();
