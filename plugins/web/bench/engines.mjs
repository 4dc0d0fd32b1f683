#!/usr/bin/env node
// The remap and the deformed sort in each engine plugin against the engine's own splat pass
// (a benchmark, not a timed test):
//   node bench/engines.mjs [--sizes 100000,1000000] [--rounds 5] [--size 256] [--gpu] [--json]
// Headless Chromium as the conformance run starts it (WebGL2 through SwiftShader when there is
// no GPU), the synthetic workload of bench/page/synthetic.js (affine law), a canvas of
// --size x --size pixels with the tube filling about half its height. For PlayCanvas
// (bench/page/bench.js) and three.js + Spark (bench/page/three-bench.js), per size, --rounds
// rounds of three interleaved frames: a static frame (the engine's own per-frame splat work:
// the draw of every splat), a remapped frame (a new pose remapped, then the same draw; the
// remap's cost is PlayCanvas's frame minus the static one, Spark's regeneration pass timed on
// its own) and the sort by the deformed positions; medians over rounds, and the remap's and the
// sort's cost as ratios to the static frame. A software rasterizer makes the milliseconds say little about a
// GPU; the ratios are the result. The renderer string says which device drew.
// --gpu: Chromium asked for a real GPU (GPU_ARGS); when its WebGL renderer is a software one
// (SwiftShader, llvmpipe: no GPU here) nothing is timed and the output says which renderer.

import { launchPage } from '../conformance/run-browser.mjs';

/** WebGL renderer strings of software rasterizers. */
export const SOFTWARE_RENDERER = /swiftshader|llvmpipe|lavapipe|softpipe|software|basic render/i;

/** The engine pages: [engine, page under the package]. */
const PAGES = [['playcanvas', 'bench/page/index.html'], ['three', 'bench/page/three.html']];

async function main() {
    const args = process.argv.slice(2);
    const get = (/** @type {string} */ name, /** @type {string} */ fallback) => {
        const i = args.indexOf(name);
        return i >= 0 ? args[i + 1] : fallback;
    };
    const sizes = get('--sizes', '100000,1000000').split(',').map(Number);
    const rounds = Number(get('--rounds', '5'));
    const size = Number(get('--size', '256'));
    const engines = get('--engines', 'playcanvas,three').split(',');
    const json = args.includes('--json');
    const gpu = args.includes('--gpu');
    if (sizes.some((n) => !(Number.isInteger(n) && n > 0)) || !(rounds >= 1) || !(size >= 16)) {
        throw new Error('--sizes takes positive integers, --rounds at least 1, --size at least 16');
    }
    /** @type {any[]} */
    const backends = [];
    /** @type {any[]} */
    const rows = [];
    for (const [engine, page] of PAGES) {
        if (!engines.includes(engine)) continue;
        const browser = await launchPage({ page, gpu });
        try {
            const backend = await browser.page.evaluate((s) => /** @type {any} */ (window).gsvBench.init({ width: s, height: s }), size);
            backends.push({ ...backend, canvas: `${size}x${size}` });
            if (gpu && SOFTWARE_RENDERER.test(backend.renderer)) break;   // no GPU: nothing to time
            for (const n of sizes) {
                const r = await browser.page.evaluate(([n, rounds]) => /** @type {any} */ (window).gsvBench.engineFrames(n, { rounds }), [n, rounds]);
                rows.push(r);
                if (!json) {
                    process.stderr.write(`  ${r.engine} ${n}: static ${r.baseMs.toFixed(1)} ms, remap ${r.remapMs.toFixed(1)} ms `
                        + `(${r.remapRatio.toFixed(2)}x), sort ${r.sortMs.toFixed(1)} ms (${r.sortRatio.toFixed(2)}x)\n`);
                }
            }
        } finally {
            await browser.close();
        }
    }
    if (json) {
        process.stdout.write(`${JSON.stringify({ backends, rows, rounds, canvas: size, gpu }, null, 1)}\n`);
        return;
    }
    const lines = [];
    for (const b of backends) lines.push(`${b.engine}: ${b.device}, ${b.renderer}, canvas ${b.canvas}, ${b.cores} CPU cores`);
    lines.push('', '| engine | splats | static frame ms | remap ms | remap / static | sort ms | sort / static |',
        '|---|---|---|---|---|---|---|');
    for (const r of rows) {
        lines.push(`| ${r.engine} | ${r.n} | ${r.baseMs.toFixed(1)} | ${r.remapMs.toFixed(1)} | ${r.remapRatio.toFixed(2)} | `
            + `${r.sortMs.toFixed(1)} | ${r.sortRatio.toFixed(2)} |`);
    }
    process.stdout.write(`${lines.join('\n')}\n`);
}

main().catch((err) => {
    process.stderr.write(`${err instanceof Error ? err.message : String(err)}\n`);
    process.exit(1);
});
