/**
 * The remap of the three.js plugin as a Spark "dyno" (Spark's GPU splat pipeline).
 *
 * `RemapModifier` is a `GsplatModifier` (Spark's `{gsplat} -> {gsplat}` block): it runs the
 * engine-free GLSL chunk of ../remap-glsl.js, literally unchanged, on the splat Spark hands it
 * and replaces its centre, quaternion and scales by the remapped ones (splat-local space:
 * installed as the SplatMesh's object modifier, so the mesh's own transform, the splat node's,
 * is applied after it by Spark; Spark then writes the depth it sorts by from the modified
 * splat, so splats are sorted by their deformed positions).
 *
 * The chunk's per-splat inputs are texel fetches at the splat's index (`gsplat.index`, the
 * file's splat order: the plugin builds Spark's splats in file order):
 *   gsvAnchorTex     RGBA32UI  faceIndex, bits of b1 (alpha1), b2 (alpha2), d (local) or rho (games)
 *   gsvLocalRotTex   RGBA32F   localRotation x, y, z, w (identity for games)
 *   gsvLocalScaleTex RGBA32F   localScale x, y, z
 * and its per-instance uniforms (gsvVertices, gsvFaces, gsvRest, gsvLaw) are the textures of
 * `AnchorTextures` (index.js); see ../remap-glsl.js for what they hold.
 *
 * Why the Gsplat hook (`objectModifiers`) and not the covariance one (`covObjectModifiers`):
 * Spark 2.2 runs covariance modifiers only on a SplatMesh built with `covSplats` (which needs
 * its ExtSplats storage), and its default accumulator builds no program from a covariance-only
 * generator ("Generator must be provided"); the Gsplat hook runs in every mode, and the chunk
 * already turns the affine law's covariance into rotation + scales (cyclic Jacobi), the same
 * code PlayCanvas renders.
 */

import { dyno } from '@sparkjsdev/spark';
import { REMAP_FAULTS, remapChunkGLSL } from '../remap-glsl.js';

/** Deliberately broken variants of the three.js plugin (conformance tests that the suite catches them). */
export const FAULTS = {
    ...REMAP_FAULTS,
    // render-level faults: the remap itself is right, what the engine draws is not
    /** the modifier hands Spark the scales in the wrong order (y, x, z) */
    'scale-swizzle': 'the modifier hands Spark the scales as (y, x, z)',
    /** the splat node's transform is not given to the SplatMesh (splat-local output drawn as world) */
    'node-transform': "the splat node's transform ignored",
};

/** The faults that break only what is drawn (the conformance readback is unaffected). */
export const RENDER_FAULTS = ['scale-swizzle', 'node-transform'];

/**
 * @param {string|null} fault
 * @returns {string|null}
 */
export function checkFault(fault) {
    if (fault !== null && !(fault in FAULTS)) {
        throw new Error(`unknown shader fault '${fault}' (known: ${Object.keys(FAULTS).join(', ')})`);
    }
    return fault;
}

/**
 * The GLSL globals of the modifier: the chunk, its per-splat loaders (prototypes before it,
 * bodies after it: the chunk defines gsvAt) and `gsvRemapIndex`.
 * @param {{fault?: string|null}} [options]
 * @returns {string}
 */
export function modifierGlobalsGLSL(options = {}) {
    const fault = checkFault(options.fault ?? null);
    return `
uniform highp usampler2D gsvAnchorTex;
uniform highp sampler2D gsvLocalRotTex;
uniform highp sampler2D gsvLocalScaleTex;
int gsvSplatIndex;
uvec4 loadGsvAnchor();
vec4 loadGsvLocalRot();
vec4 loadGsvLocalScale();
${remapChunkGLSL({ fault })}
uvec4 loadGsvAnchor() {
    return texelFetch(gsvAnchorTex, gsvAt(gsvSplatIndex, textureSize(gsvAnchorTex, 0).x), 0);
}
vec4 loadGsvLocalRot() {
    return texelFetch(gsvLocalRotTex, gsvAt(gsvSplatIndex, textureSize(gsvLocalRotTex, 0).x), 0);
}
vec4 loadGsvLocalScale() {
    return texelFetch(gsvLocalScaleTex, gsvAt(gsvSplatIndex, textureSize(gsvLocalScaleTex, 0).x), 0);
}
// splat 'index' (file order) remapped, splat-local space
void gsvRemapIndex(int index, out vec3 mean, out vec4 quat, out vec3 scale) {
    gsvSplatIndex = index;
    gsvRemapSplat(mean, quat, scale);
}
`;
}

/**
 * The uniforms of the modifier, by GLSL name ({value} objects, shared by every program that
 * runs the modifier: changing a value or a texture's data reaches them all).
 * @typedef {{[name: string]: {value: any}}} RemapUniforms
 */

/**
 * (Spark 2.2's declaration files use extensionless relative imports, which TypeScript's
 * nodenext resolution does not follow: its classes type as `any` here, so the blocks below
 * declare what they use.)
 * @typedef {{gsplat: typeof dyno.Gsplat}} GsplatIO
 */

/**
 * Spark's `{gsplat} -> {gsplat}` block running the remap (see the module comment).
 * @extends {dyno.Dyno<GsplatIO, GsplatIO>}
 */
export class RemapModifier extends dyno.Dyno {
    /**
     * @param {RemapUniforms} uniforms
     * @param {{fault?: string|null}} [options]
     */
    constructor(uniforms, options = {}) {
        const fault = checkFault(options.fault ?? null);
        const globals = modifierGlobalsGLSL({ fault });
        const scales = fault === 'scale-swizzle' ? 'gsvS.yxz' : 'gsvS';
        super({
            inTypes: { gsplat: dyno.Gsplat },
            outTypes: { gsplat: dyno.Gsplat },
            generate: (/** @type {{inputs: {gsplat?: string}, outputs: {gsplat?: string}}} */ { inputs, outputs }) => {
                const out = outputs.gsplat;
                const statements = out ? [
                    `${out} = ${inputs.gsplat};`,
                    `if (isGsplatActive(${out}.flags)) {`,
                    '    vec3 gsvM; vec4 gsvQ; vec3 gsvS;',
                    `    gsvRemapIndex(${out}.index, gsvM, gsvQ, gsvS);`,
                    `    ${out}.center = gsvM;`,
                    `    ${out}.quaternion = gsvQ;`,
                    `    ${out}.scales = ${scales};`,
                    '}',
                ] : [];
                return { globals: [globals], statements, uniforms };
            },
        });
    }
}

/**
 * Spark's `{gsplat} -> {rgba8}` block of the conformance readback: component `gsvComponent`
 * (0-2 centre, 3-6 quaternion x, y, z, w, 7-9 scales) of a splat, its float32 bits as four bytes
 * (little-endian), so that Spark's RGBA8 readback returns the exact float32 value.
 * @extends {dyno.Dyno<GsplatIO, {rgba8: 'vec4'}>}
 */
export class ComponentBits extends dyno.Dyno {
    /** @param {{value: number}} component  the uniform choosing the component */
    constructor(component) {
        super({
            inTypes: { gsplat: dyno.Gsplat },
            outTypes: { rgba8: /** @type {'vec4'} */ ('vec4') },
            generate: (/** @type {{inputs: {gsplat?: string}, outputs: {rgba8?: string}}} */ { inputs, outputs }) => {
                const g = inputs.gsplat;
                return {
                    globals: ['uniform int gsvComponent;'],
                    statements: outputs.rgba8 ? [
                        '{',
                        `    float gsvV = gsvComponent < 3 ? ${g}.center[gsvComponent]`,
                        `        : gsvComponent < 7 ? ${g}.quaternion[gsvComponent - 3] : ${g}.scales[gsvComponent - 7];`,
                        '    uint gsvU = floatBitsToUint(gsvV);',
                        `    ${outputs.rgba8} = vec4(uvec4(gsvU & 255u, (gsvU >> 8u) & 255u, (gsvU >> 16u) & 255u, gsvU >> 24u)) / 255.0;`,
                        '}',
                    ] : [],
                    uniforms: { gsvComponent: component },
                };
            },
        });
    }
}
