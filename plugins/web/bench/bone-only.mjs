#!/usr/bin/env node
// How far the bone-only approximation (src/bone-weights.js: each splat skinned by at most 4 bones
// blended from its anchor triangle's corner weights, what Spark's SplatSkinning can draw) is
// from the exact triangle remap, on an asset with a skinned anchor mesh (a benchmark of
// accuracy, not of time):
//   node bench/bone-only.mjs ASSET.glb [--fractions 0.1,0.3,0.5,0.7,0.9] [--max-bones 4] [--json]
// For the rest pose, and every animation of the file at every fraction of its duration: the anchor vertices
// sampled by src/animation.js, the exact centres by remapMeansInto, the bone-only centres by
// boneOnlyMeansInto; the distance between the two per splat, relative to the character's height
// (the largest extent of the rest anchor vertices), as median, 95th percentile and maximum.

import { readFileSync } from 'node:fs';
import { basename } from 'node:path';

import { readAnchoredGlb } from '../src/anchor.js';
import { readAnchorAnimation } from '../src/animation.js';
import { boneOnlyMeansInto, splatBoneWeights, MAX_SPLAT_BONES } from '../src/bone-weights.js';
import { computeRest } from '../src/rest.js';
import { remapMeansInto } from '../src/remap-cpu.js';

/**
 * @param {Float64Array} sorted
 * @param {number} q
 */
function quantile(sorted, q) {
    return sorted[Math.min(sorted.length - 1, Math.floor(q * (sorted.length - 1) + 0.5))];
}

/**
 * The bone-only error of every animation at every fraction of its duration.
 * @param {Uint8Array} bytes
 * @param {{name?: string, fractions?: number[], maxBones?: number}} [options]
 */
export function boneOnlyErrors(bytes, options = {}) {
    const name = options.name || 'asset.glb';
    const fractions = options.fractions || [0.1, 0.3, 0.5, 0.7, 0.9];
    const { anchored } = readAnchoredGlb(bytes, { name });
    const prim = anchored.find((p) => p.anchorMesh.node !== null);
    if (!prim) throw new Error(`${name}: no anchored primitive with an instantiated anchor mesh`);
    const animation = readAnchorAnimation(bytes, prim, { name });
    if (!animation || !animation.skinned) throw new Error(`${name}: the anchor mesh has no skin`);
    const bw = splatBoneWeights(prim, animation, { maxBones: options.maxBones ?? MAX_SPLAT_BONES });
    const rest = computeRest(prim);
    const v0 = animation.rest();
    let height = 0;
    for (let k = 0; k < 3; ++k) {
        let lo = Infinity, hi = -Infinity;
        for (let i = k; i < v0.length; i += 3) { lo = Math.min(lo, v0[i]); hi = Math.max(hi, v0[i]); }
        height = Math.max(height, hi - lo);
    }
    const n = prim.count;
    const exact = new Float32Array(3 * n), bone = new Float64Array(3 * n), err = new Float64Array(n);
    const vertices = new Float32Array(3 * prim.anchorMesh.vertexCount);
    const rows = [];
    // the rest pose first (the nodes' own values: both must give the stored rest centres), then
    // every animation at every fraction of its duration
    const poses = [{ name: '(rest)', index: -1, time: 0 }, ...animation.animations.flatMap((info) => fractions.map((f) => ({ name: info.name || `#${info.index}`, index: info.index, time: f * info.duration })))];
    for (const { name: anim, index, time } of poses) {
        if (index < 0) animation.rest(vertices);
        else animation.sample(index, time, vertices);
        remapMeansInto(prim, rest, vertices, exact);
        boneOnlyMeansInto(animation, bw, prim.rest.means, bone);
        for (let i = 0; i < n; ++i) {
            err[i] = Math.hypot(bone[3 * i] - exact[3 * i], bone[3 * i + 1] - exact[3 * i + 1], bone[3 * i + 2] - exact[3 * i + 2]) / height;
        }
        const sorted = Float64Array.from(err).sort();
        rows.push({ animation: anim, time, median: quantile(sorted, 0.5), p95: quantile(sorted, 0.95), max: sorted[n - 1] });
    }
    return { asset: name, splats: n, vertices: prim.anchorMesh.vertexCount, joints: animation.jointCount, maxBones: bw.maxBones, height, rows };
}

function main() {
    const args = process.argv.slice(2);
    const get = (/** @type {string} */ flag) => {
        const i = args.indexOf(flag);
        return i >= 0 ? args[i + 1] : undefined;
    };
    const asset = args.find((a, i) => !a.startsWith('--') && !['--fractions', '--max-bones'].includes(args[i - 1]));
    if (!asset) {
        process.stderr.write('usage: node bench/bone-only.mjs ASSET.glb [--fractions 0.1,0.3,0.5,0.7,0.9] [--max-bones 4] [--json]\n');
        process.exit(2);
    }
    const fractions = get('--fractions')?.split(',').map(Number);
    const maxBones = get('--max-bones') ? Number(get('--max-bones')) : undefined;
    const r = boneOnlyErrors(new Uint8Array(readFileSync(asset)), { name: basename(asset), fractions, maxBones });
    if (args.includes('--json')) {
        process.stdout.write(`${JSON.stringify(r, null, 1)}\n`);
        return;
    }
    process.stdout.write(`${r.asset}: ${r.splats} splats, ${r.vertices} anchor vertices, ${r.joints} joints, at most ${r.maxBones} bones a splat; `
        + `errors relative to the height ${r.height.toPrecision(4)}\n`);
    process.stdout.write('| animation | time (s) | median | p95 | max |\n|---|---|---|---|---|\n');
    for (const row of r.rows) {
        process.stdout.write(`| ${row.animation} | ${row.time.toFixed(3)} | ${(100 * row.median).toFixed(3)}% | ${(100 * row.p95).toFixed(3)}% | ${(100 * row.max).toFixed(3)}% |\n`);
    }
}

if (process.argv[1] && import.meta.url.endsWith(basename(process.argv[1]))) main();
