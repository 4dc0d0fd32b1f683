/**
 * A GPU pass that runs the remap chunk (the same string as the render's work-buffer modifier)
 * with the engine's GSplatProcessor over the splat streams of an anchored primitive, into
 * float32 output streams, and reads the results back: the conformance harness and the
 * benchmark use it. Outputs are returned in file splat order.
 */

import { GSplatProcessor, PIXELFORMAT_RGBA32F } from 'playcanvas';
import {
    STREAM_ANCHOR, STREAM_LOCAL_ROT, STREAM_LOCAL_SCALE, STREAM_OUT_MEAN, STREAM_OUT_ROT, STREAM_OUT_SCALE,
    processChunkGLSL,
} from './shader.js';
import { processChunkWGSL } from './shader-wgsl.js';

/** @typedef {import('./index.js').AnchorGpuData} AnchorGpuData */

export class RemapProbe {
    /**
     * @param {AnchorGpuData} gpu
     * @param {{fault?: string|null}} [options]
     */
    constructor(gpu, options = {}) {
        this.gpu = gpu;
        const resource = gpu.resource;
        resource.format.addExtraStreams([
            { name: STREAM_OUT_MEAN, format: PIXELFORMAT_RGBA32F },
            { name: STREAM_OUT_ROT, format: PIXELFORMAT_RGBA32F },
            { name: STREAM_OUT_SCALE, format: PIXELFORMAT_RGBA32F },
        ]);
        this.processor = new GSplatProcessor(gpu.device,
            { resource, streams: [STREAM_ANCHOR, STREAM_LOCAL_ROT, STREAM_LOCAL_SCALE] },
            { resource, streams: [STREAM_OUT_MEAN, STREAM_OUT_ROT, STREAM_OUT_SCALE] },
            { processGLSL: processChunkGLSL({ fault: options.fault ?? null }), processWGSL: processChunkWGSL({ fault: options.fault ?? null }) });
        for (const [name, value] of gpu.parameters()) this.processor.setParameter(name, value);
    }

    /**
     * Remap onto vertices on the GPU (no readback).
     * @param {ArrayLike<number>} [vertices]  (3V) splat-local; omitted: the current ones
     */
    run(vertices) {
        if (vertices) this.gpu.upload(vertices);
        this.processor.process();
    }

    /**
     * Read the last results back from the GPU, in file splat order.
     * @returns {Promise<{means: Float32Array, rotations: Float32Array, scales: Float32Array}>}
     */
    async read() {
        /** @type {any} the output streams exist: the constructor added them */
        const resource = this.gpu.resource;
        const n = this.gpu.prim.count;
        const order = this.gpu.order;
        const { x: w, y: h } = resource.textureDimensions;
        /** @param {string} name */
        const readStream = (name) => resource.getTexture(name).read(0, 0, w, h, { immediate: true });
        const [mean, rot, scale] = /** @type {Float32Array[]} */ (await Promise.all(
            [STREAM_OUT_MEAN, STREAM_OUT_ROT, STREAM_OUT_SCALE].map(readStream)));
        const means = new Float32Array(3 * n), rotations = new Float32Array(4 * n), scales = new Float32Array(3 * n);
        for (let r = 0; r < n; ++r) {
            const i = order[r];
            for (let k = 0; k < 3; ++k) {
                means[3 * i + k] = mean[4 * r + k];
                scales[3 * i + k] = scale[4 * r + k];
            }
            for (let k = 0; k < 4; ++k) rotations[4 * i + k] = rot[4 * r + k];
        }
        return { means, rotations, scales };
    }

    destroy() {
        this.processor.destroy();
    }
}
