#!/usr/bin/env node
// Remap cost per frame in the browser (a benchmark, not a timed test):
//   node bench/remap-browser.mjs [--sizes 100000,1000000] [--laws affine,rigid,games]
//                                [--backend webgl2|webgpu] [--sort] [--json]
// Headless Chromium (the flags of the conformance run: WebGL2 through SwiftShader when there is
// no GPU), synthetic anchored splats on a deforming tube (64 x 64 vertices, 8064 faces). Per
// frame: the anchor vertices uploaded (RGBA32F texture) and every splat remapped by the render's
// remap chunk (engine GSplatProcessor pass, float32 outputs), GPU work fenced by a synchronous
// readback each frame; median over >= 5 frames and >= 1.5 s. The CPU column is the JavaScript
// path (remap-cpu.js, binary64, rotation + scale) on the same data, in the same browser.
// --backend webgpu times the WGSL twin (fence: an awaited 1-texel readback).
// --sort adds the cost of ordering the splats by their deformed positions in a rendered scene
// (affine law): the deformed means computed into the engine's sort centres on the CPU, the
// engine's sort in its worker, and the time until the sorted order arrives.

import { launchPage } from '../conformance/run-browser.mjs';

/** @typedef {'webgl2'|'webgpu'} Backend */

async function main() {
    const args = process.argv.slice(2);
    const get = (/** @type {string} */ name, /** @type {string} */ fallback) => {
        const i = args.indexOf(name);
        return i >= 0 ? args[i + 1] : fallback;
    };
    const sizes = get('--sizes', '100000,1000000').split(',').map(Number);
    const laws = /** @type {('affine'|'rigid'|'games')[]} */ (get('--laws', 'affine,rigid,games').split(','));
    const json = args.includes('--json');
    const backendName = /** @type {Backend} */ (get('--backend', 'webgl2'));
    const browser = await launchPage({ page: 'bench/page/index.html', webgpu: backendName === 'webgpu' });
    try {
        const backend = await browser.page.evaluate((b) => /** @type {any} */ (window).gsvBench.init({ backend: b }), backendName);
        /** @type {any[]} */
        const rows = [];
        for (const n of sizes) {
            for (const law of laws) {
                const cpuFrames = n >= 1000000 ? 1 : 2;
                const r = await browser.page.evaluate(([n, law, cpuFrames]) => /** @type {any} */ (window).gsvBench.run(n, law, { cpuFrames }), /** @type {[number, string, number]} */ ([n, law, cpuFrames]));
                rows.push(r);
                if (!json) process.stderr.write(`  ${n} ${law}: ${r.medianMs.toFixed(1)} ms/frame (${r.frames} frames)\n`);
            }
        }
        /** @type {any[]} */
        const sortRows = [];
        if (args.includes('--sort')) {
            for (const n of sizes) {
                const r = await browser.page.evaluate((n) => /** @type {any} */ (window).gsvBench.sort(n, 'affine'), n);
                sortRows.push(r);
                if (!json) process.stderr.write(`  sort ${n}: centres ${r.centresMs.toFixed(1)} ms, worker ${r.sortMs.toFixed(1)} ms\n`);
            }
        }
        if (json) {
            process.stdout.write(`${JSON.stringify({ backend, rows, sort: sortRows }, null, 1)}\n`);
            return;
        }
        const lines = [
            `GS-Verse remap per frame in the browser: ${backend.engine}, ${backend.device}, ${backend.renderer}`,
            `(${backend.cores} CPU cores; per frame = anchor vertex upload + GPU remap of every splat, fenced by a readback)`,
            '',
            '| splats    | law    | GPU ms/frame (median) | GPU min | splats/s (GPU) | CPU JS ms/frame |',
            '|-----------|--------|-----------------------|---------|----------------|-----------------|',
        ];
        for (const r of rows) {
            lines.push(`| ${String(r.n).padEnd(9)} | ${r.law.padEnd(6)} | ${r.medianMs.toFixed(1).padStart(21)} | ${r.minMs.toFixed(1).padStart(7)} | `
                + `${(r.n / (r.medianMs / 1000) / 1e6).toFixed(1).padStart(10)} M/s | ${r.cpuMs.toFixed(1).padStart(15)} |${r.finite ? '' : ' NON-FINITE OUTPUT'}`);
        }
        if (sortRows.length) {
            lines.push('', 'Depth order of the deformed splats (affine law; medians per frame):', '',
                '| splats    | sort centres (CPU, in setVertices) ms | engine sort (worker) ms | setVertices to sorted ms | vertex upload alone ms |',
                '|-----------|---------------------------------------|-------------------------|--------------------------|------------------------|');
            for (const r of sortRows) {
                lines.push(`| ${String(r.n).padEnd(9)} | ${r.centresMs.toFixed(1).padStart(37)} | ${r.sortMs.toFixed(1).padStart(23)} | ${r.latencyMs.toFixed(1).padStart(24)} | ${r.uploadMs.toFixed(2).padStart(22)} |`);
            }
        }
        process.stdout.write(`${lines.join('\n')}\n`);
    } finally {
        await browser.close();
    }
}

main().catch((err) => {
    process.stderr.write(`${err instanceof Error ? err.stack : String(err)}\n`);
    process.exit(1);
});
