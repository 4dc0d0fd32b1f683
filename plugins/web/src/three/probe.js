/**
 * The remap of an AnchoredSplatMesh run by Spark on the GPU and read back as float32 (the
 * conformance harness and benchmarks): Spark's `Readback` runs a block that fetches each splat
 * from the mesh's own PackedSplats, applies the same RemapModifier (shader.js: the same GLSL,
 * the same uniforms and textures) and writes one float32 component of the result as four bytes;
 * ten passes (centre, quaternion, scales) give the remapped splats exactly as Spark got them.
 */

import { Readback, dyno } from '@sparkjsdev/spark';
import { REMAP_FAULTS } from '../remap-glsl.js';
import { ComponentBits, RemapModifier } from './shader.js';

/** @typedef {import('./index.js').AnchoredSplatMesh} AnchoredSplatMesh */

/** Spark's readback rows: buffers are rounded up to whole rows of this many splats. */
const ROW = 2048;

export class RemapProbe {
    /**
     * @param {import('three').WebGLRenderer} renderer
     * @param {AnchoredSplatMesh} splat
     * @param {{fault?: string|null}} [options]  a remap fault (REMAP_FAULTS); render faults
     *   do not change the numbers
     */
    constructor(renderer, splat, options = {}) {
        const fault = options.fault && options.fault in REMAP_FAULTS ? options.fault : null;
        this.renderer = renderer;
        this.splat = splat;
        this.count = splat.prim.count;
        this.component = { value: 0 };
        const packed = /** @type {import('@sparkjsdev/spark').PackedSplats} */ (splat.mesh.packedSplats);
        // typed as any: Spark's classes type as any here (see shader.js)
        const modifier = /** @type {any} */ (new RemapModifier(splat.gpu.uniforms, { fault }));
        const bits = /** @type {any} */ (new ComponentBits(this.component));
        const io = /** @type {{index: 'int'}} */ ({ index: 'int' });
        this.reader = dyno.dynoBlock(io, /** @type {{rgba8: 'vec4'}} */ ({ rgba8: 'vec4' }), (/** @type {{index?: any}} */ { index }) => {
            if (!index) throw new Error('the readback block has no index');
            packed.prepareFetchSplat();
            const rest = packed.fetchSplat({ index });
            const { gsplat } = modifier.apply({ gsplat: rest });
            return { rgba8: bits.apply({ gsplat }).rgba8 };
        });
        this.readback = new Readback({ renderer });
        this.buffer = new Uint8Array(4 * Math.ceil(Math.max(1, this.count) / ROW) * ROW);
    }

    /** @param {ArrayLike<number>} vertices  (3V) anchor vertices, splat-local space */
    async run(vertices) {
        this.splat.gpu.upload(vertices);
        const n = this.count;
        const means = new Float32Array(3 * n), rotations = new Float32Array(4 * n), scales = new Float32Array(3 * n);
        const targets = [[means, 3, 0], [rotations, 4, 3], [scales, 3, 7]];
        for (const [array, width, first] of /** @type {[Float32Array, number, number][]} */ (targets)) {
            for (let k = 0; k < width; ++k) {
                this.component.value = first + k;
                await this.readback.renderReadback({ reader: this.reader, count: n, renderer: this.renderer, readback: this.buffer });
                const values = new Float32Array(this.buffer.buffer, 0, n);
                for (let i = 0; i < n; ++i) array[width * i + k] = values[i];
            }
        }
        return { means, rotations, scales };
    }

    destroy() {
        this.readback.dispose();
    }
}
