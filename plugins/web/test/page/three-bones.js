// The three.js plugin's BoneSkinnedSplats (src/three/skinning.js: the bone-only approximation
// drawn by Spark's own dual-quaternion skinning) read back from the GPU: the centres Spark
// computes (Spark's Readback over fetch -> SplatSkinning -> the float32 bits), against the
// exact triangle remap (remapMeansInto) at the rest pose and at times of animation 0, relative to
// the mesh's largest extent, as bench/bone-only.mjs measures the CPU linear-blend version.

import * as THREE from 'three';
import { Readback, dyno } from '@sparkjsdev/spark';
import { loadAnchoredAsset } from '../../src/three/index.js';
import { BoneSkinnedSplats } from '../../src/three/skinning.js';
import { ComponentBits } from '../../src/three/shader.js';
import { remapMeansInto } from '../../src/remap-cpu.js';

/**
 * @param {string} url
 * @param {number[]} fractions  of animation 0's duration
 */
async function bones(url, fractions) {
    const canvas = document.createElement('canvas');
    const renderer = new THREE.WebGLRenderer({ canvas });
    const bytes = new Uint8Array(await (await fetch(url)).arrayBuffer());
    const { anchored } = await loadAnchoredAsset(bytes, { name: url.split('/').pop() });
    const splat = anchored[0];
    const skinned = new BoneSkinnedSplats(splat);
    const n = splat.prim.count;
    const component = { value: 0 };
    const packed = /** @type {any} */ (splat.mesh.packedSplats);
    const bits = /** @type {any} */ (new ComponentBits(component));
    const reader = dyno.dynoBlock(/** @type {{index: 'int'}} */ ({ index: 'int' }), /** @type {{rgba8: 'vec4'}} */ ({ rgba8: 'vec4' }), (/** @type {{index?: any}} */ { index }) => {
        const gsplat = skinned.skinning.modify(packed.fetchSplat({ index }));
        return { rgba8: bits.apply({ gsplat }).rgba8 };
    });
    const readback = new Readback({ renderer });
    const buffer = new Uint8Array(4 * Math.ceil(n / 2048) * 2048);
    const got = new Float32Array(3 * n), exact = new Float32Array(3 * n);
    const anim = /** @type {any} */ (splat.animation);
    const rest = anim.rest();
    let height = 0;
    for (let k = 0; k < 3; ++k) {
        let lo = Infinity, hi = -Infinity;
        for (let i = k; i < rest.length; i += 3) { lo = Math.min(lo, rest[i]); hi = Math.max(hi, rest[i]); }
        height = Math.max(height, hi - lo);
    }
    const duration = anim.animations[0].duration;
    const rows = [];
    for (const f of [-1, ...fractions]) {
        const time = Math.max(0, f) * duration;
        skinned.setAnimationTime(f < 0 ? -1 : 0, time);
        const vertices = f < 0 ? anim.rest() : anim.sample(0, time);
        remapMeansInto(splat.prim, splat.rest, vertices, exact);
        for (let k = 0; k < 3; ++k) {
            component.value = k;
            await readback.renderReadback({ reader, count: n, renderer, readback: buffer });
            const values = new Float32Array(buffer.buffer, 0, n);
            for (let i = 0; i < n; ++i) got[3 * i + k] = values[i];
        }
        const err = new Float64Array(n);
        for (let i = 0; i < n; ++i) err[i] = Math.hypot(got[3 * i] - exact[3 * i], got[3 * i + 1] - exact[3 * i + 1], got[3 * i + 2] - exact[3 * i + 2]) / height;
        err.sort();
        rows.push({ time: f < 0 ? null : time, median: err[Math.floor(n / 2)], p95: err[Math.floor(0.95 * (n - 1))], max: err[n - 1] });
    }
    readback.dispose();
    skinned.dispose();
    splat.destroy();
    renderer.dispose();
    return { splats: n, height, rows };
}

/** @type {any} */ (window).gsvBones = { bones };
/** @type {any} */ (window).gsvReady = true;
