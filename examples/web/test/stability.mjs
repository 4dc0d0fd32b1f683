#!/usr/bin/env node
// Stability test of the web demo in headless Chromium: the slider jumps, let go, drop, shake and a
// fast drag, on any anchored assets (the test converts nothing: it takes the .glb files it is
// given).
//
//   node examples/web/test/stability.mjs OUTDIR ASSET.glb [ASSET.glb ...] [--engine playcanvas|three]
//
// The same checks run on either engine of the demo (?engine=three: three.js + Spark).
// Each asset is opened in the demo in test mode (fixed front camera, black background) with the
// physics running in real time, and driven the way a person drives it: the stretch slider jumps
// 1.0 -> 1.7 -> 0.6, "let go", "drop", "shake", then a fast drag of the body's far end. The page
// records every frame (gsverseDemo.monitor): frames and physics steps, the longest frame interval,
// and the anchor mesh's smallest and largest world extent per axis. Checks, per phase:
//   - bounded extent. While the ends are held or just let go (no gravity, no turning): every axis
//     within 0.4..2.2x its rest extent, and the held pose reached (1.7x, then 0.5..0.85x, along the
//     long axis). While it may turn (drop, shake, drag): no axis beyond 2.2x the rest's longest
//     extent, and the box diagonal within 0.5..2.2x the rest diagonal (a rigid turn keeps it
//     within 1/sqrt(3)..sqrt(3)x);
//   - the rendered silhouette bounded the same way, and not blank;
//   - the page keeps rendering: the phase's physics steps are taken within a generous wall-clock
//     allowance (the machine may be busy), frames advance; the longest frame interval is reported;
//   - the guard never had to put a body back (SoftBodyMesh.guardTrips stays 0);
//   - the physics mesh is within the budget; the remap figure on the panel says what it measures;
//   - no page errors.
// PNGs (ASSET-PHASE.png) and results.json go to OUTDIR; exit status 1 on any failure.

import fs from 'node:fs';
import path from 'node:path';
import { startServer } from '../serve.mjs';
import { silhouette } from './measure.mjs';
import { launch, stableShot } from './browser.mjs';
import { DEFAULT_BUDGET } from '../physmesh.js';

/** Wall-clock allowance for one phase's physics steps (ms): generous, machines are busy (and
 * longer by GSVERSE_TIME_SCALE, how much slower than idle the machine is, where it is set). */
const PHASE_MS = Number(process.env.GSVERSE_PHASE_MS || 240000) * Math.max(1, Number(process.env.GSVERSE_TIME_SCALE) || 1);

const argv = process.argv.slice(2);
const engineAt = argv.indexOf('--engine');
const engine = engineAt >= 0 ? argv[engineAt + 1] : 'playcanvas';
const args = engineAt >= 0 ? [...argv.slice(0, engineAt), ...argv.slice(engineAt + 2)] : argv;
const outDir = args[0];
const assets = args.slice(1);
if (!outDir || !assets.length || args.some((a) => a.startsWith('--')) || !['playcanvas', 'three'].includes(engine)) {
    process.stderr.write('usage: stability.mjs OUTDIR ASSET.glb [ASSET.glb ...] [--engine playcanvas|three]\n');
    process.exit(2);
}
for (const a of assets) {
    if (!fs.existsSync(a)) {
        process.stderr.write(`stability: FAIL: ${a}: no such file\n`);
        process.exit(1);
    }
}
fs.mkdirSync(outDir, { recursive: true });

/** @type {{asset: string, name: string, ok: boolean, detail: string}[]} */
const checks = [];
/** @type {Record<string, any>} */
const measured = {};
/** @param {string} asset @param {string} name @param {boolean} ok @param {string} detail */
function check(asset, name, ok, detail) {
    checks.push({ asset, name, ok, detail });
    process.stdout.write(`${ok ? 'ok  ' : 'FAIL'}  ${asset}: ${name}: ${detail}\n`);
}
/** @param {number} v @param {number} lo @param {number} hi */
const within = (v, lo, hi) => v >= lo && v <= hi;
/** @param {number[]} a */
const fmt = (a) => a.map((v) => v.toFixed(2)).join(' x ');

let browser;
try {
    browser = await launch({ width: 640, height: 480 });
} catch (err) {
    process.stderr.write(`stability: FAIL: ${/** @type {Error} */ (err).message}\n`);
    process.exit(1);
}
let failed = false;

try {
    for (const asset of assets) {
        const label = path.basename(asset, '.glb');
        const server = await startServer({ asset, port: 0 });
        const page = await browser.context.newPage();
        /** @type {string[]} */
        const pageErrors = [];
        page.on('pageerror', (/** @type {Error} */ e) => pageErrors.push(e.message));
        page.on('console', (/** @type {any} */ m) => { if (m.type() === 'error') pageErrors.push(m.text()); });
        page.setDefaultTimeout(PHASE_MS);
        try {
            await runAsset(page, server.url, label, pageErrors);
        } catch (err) {
            failed = true;
            check(label, 'ran to the end', false, String(/** @type {Error} */ (err).stack || err).split('\n').slice(0, 3).join(' | '));
        } finally {
            await page.close();
            await server.close();
        }
    }
} finally {
    await browser.close();
}

/**
 * @param {any} page @param {string} url @param {string} label @param {string[]} pageErrors
 */
async function runAsset(page, url, label, pageErrors) {
    /** @param {string} fn @param {any[]} a */
    const call = (fn, ...a) => page.evaluate((/** @type {[string, any[]]} */ [f, x]) => /** @type {any} */ (window).gsverseDemo[f](...x), [fn, a]);
    const t0 = Date.now();
    await page.goto(`${url}?test${engine === 'three' ? '&engine=three' : ''}`);
    const info = await page.evaluate(() => /** @type {any} */ (window).gsverseDemo.ready);
    const body = info.bodies[0];
    process.stdout.write(`${label}: ${info.splats.anchored} anchored splats, anchor mesh ${body.vertices} vertices / ${body.faces} faces, `
        + `physics ${body.physics} of ${body.physicsVertices} vertices${body.grid ? ` (${body.grid.join('x')} cells)` : ''}, loaded in ${((Date.now() - t0) / 1000).toFixed(1)} s\n`);
    const budget = DEFAULT_BUDGET;
    check(label, 'physics mesh within the budget', body.physics === 'lattice' && body.physicsVertices <= budget && body.physicsVertices >= 50,
        `${body.physics}, ${body.physicsVertices} vertices for a ${body.vertices}-vertex anchor mesh (budget ${budget})`);

    const restImg = await stableShot(page, path.join(outDir, `${label}-rest.png`));
    const s0 = silhouette(restImg);
    const rest = /** @type {number[]} */ (await call('extent'));
    const longest = Math.max(...rest), restDiag = Math.hypot(...rest);
    const axis = rest.indexOf(longest);
    check(label, 'rest not blank', s0.fraction > 0.005, `${s0.x.size}x${s0.y.size} px`);
    /** @type {Record<string, any>} */
    const phases = {};
    measured[label] = { info, rest, phases };
    await call('pause', false);
    await call('monitor', true);

    /**
     * Run one phase: do `action`, wait for `steps` physics steps, screenshot (physics paused for
     * the capture), return what the page recorded.
     * @param {string} name @param {() => Promise<any>} action @param {number} steps
     */
    const phase = async (name, action, steps) => {
        const start = Date.now();
        await call('monitor', true);
        await action();
        let m = await call('monitor', false);
        while (m.steps < steps && Date.now() - start < PHASE_MS) {
            await page.waitForTimeout(200);
            m = await call('monitor', false);
        }
        const wall = Date.now() - start;
        await call('pause', true);
        const img = await stableShot(page, path.join(outDir, `${label}-${name}.png`), 20000);
        await call('pause', false);
        const s = silhouette(img);
        const r = { ...m, wallMs: wall, silhouette: { w: s.x.size, h: s.y.size, area: s.area } };
        phases[name] = r;
        check(label, `${name}: page kept rendering`, m.steps >= steps && m.frames > 0,
            `${m.steps}/${steps} physics steps, ${m.frames} frames, ${m.sorts} engine sorts in ${(wall / 1000).toFixed(1)} s (longest frame interval ${(m.maxFrameMs / 1000).toFixed(2)} s, ${m.stepMs.toFixed(2)} ms/step)`);
        check(label, `${name}: the guard never tripped`, m.guardTrips === 0, `${m.guardTrips} trips`);
        return { m, s };
    };
    /** @param {string} name @param {any} m @param {any} s */
    const heldBounds = (name, m, s) => {
        const lo = m.min.map((/** @type {number} */ v, /** @type {number} */ k) => v / rest[k]);
        const hi = m.max.map((/** @type {number} */ v, /** @type {number} */ k) => v / rest[k]);
        check(label, `${name}: extent within 0.4..2.2x rest per axis`, lo.every((/** @type {number} */ v) => v >= 0.4) && hi.every((/** @type {number} */ v) => v <= 2.2),
            `min ${fmt(lo)}, max ${fmt(hi)} of rest`);
        const w = s.x.size / s0.x.size, h = s.y.size / s0.y.size, a = s.area / s0.area;
        check(label, `${name}: rendered silhouette bounded`, within(w, 0.4, 2.2) && within(h, 0.4, 2.2) && within(a, 0.3, 2.5),
            `${w.toFixed(2)}x wide, ${h.toFixed(2)}x high, area ${a.toFixed(2)}x rest`);
    };
    /** @param {string} name @param {any} m @param {any} s */
    const freeBounds = (name, m, s) => {
        const hi = Math.max(...m.max) / longest;
        const diagHi = Math.hypot(...m.max) / restDiag, diagLo = Math.hypot(...m.min) / restDiag;
        check(label, `${name}: extent bounded (turning allowed)`, hi <= 2.2 && diagHi <= 2.2 && diagLo >= 0.5,
            `largest axis ${hi.toFixed(2)}x the rest's longest, box diagonal ${diagLo.toFixed(2)}..${diagHi.toFixed(2)}x rest`);
        const big = Math.max(s0.x.size, s0.y.size);
        const w = s.x.size / big, h = s.y.size / big, a = s.area / s0.area;
        check(label, `${name}: rendered silhouette bounded`, s.fraction > 0 && w <= 2.2 && h <= 2.2 && within(a, 0.3, 2.5),
            `${s.x.size}x${s.y.size} px (rest ${s0.x.size}x${s0.y.size}), area ${a.toFixed(2)}x rest`);
    };

    // the stretch slider jumps 1.0 -> 1.7 -> 0.6, then let go
    let r = await phase('stretch-1.7', () => call('stretchSlider', 1.7), 60);
    heldBounds('stretch-1.7', r.m, r.s);
    check(label, 'stretch-1.7: reached', within(r.m.last[axis] / rest[axis], 1.55, 1.85), `${(r.m.last[axis] / rest[axis]).toFixed(3)}x along ${'xyz'[axis]}`);
    r = await phase('squeeze-0.6', () => call('stretchSlider', 0.6), 80);
    heldBounds('squeeze-0.6', r.m, r.s);
    check(label, 'squeeze-0.6: reached', within(r.m.last[axis] / rest[axis], 0.5, 0.85), `${(r.m.last[axis] / rest[axis]).toFixed(3)}x along ${'xyz'[axis]}`);
    r = await phase('let-go', () => call('release'), 90);
    heldBounds('let-go', r.m, r.s);
    // drop onto the ground, shake, a fast drag of the far end
    r = await phase('drop', () => call('drop'), 120);
    freeBounds('drop', r.m, r.s);
    r = await phase('shake', () => call('shake'), 180);
    freeBounds('shake', r.m, r.s);
    await call('reset');
    await call('pause', false);
    /** @type {any} */
    let dragged = null;
    r = await phase('drag', async () => { dragged = await call('drag', { pixels: 400, frames: 2, hold: 20 }); }, 60);
    check(label, 'drag: grabbed', !!dragged?.grabbed, `from ${dragged?.from.map((/** @type {number} */ v) => v.toFixed(0))} to ${dragged?.to.map((/** @type {number} */ v) => v.toFixed(0))} px in 2 frames`);
    freeBounds('drag', r.m, r.s);

    // the remap figure: what it measures, said on the panel
    const once = await call('remapOnce');
    const after = await call('info');
    const stats = /** @type {string} */ (await call('stats'));
    const remapLine = stats.split('\n').find((l) => l.startsWith('remap:')) || '';
    const honest = after.gpuTimer
        ? /the remap alone|waiting for a GPU timing|not timed/.test(remapLine)
        : /not measurable/.test(remapLine);
    check(label, 'remap figure labelled', honest && !/work-buffer/.test(remapLine), `"${remapLine}"`);
    if (engine === 'three') {
        // the remap timer and probe are PlayCanvas's (gputimer.js): on three.js the page says so
        check(label, 'remap probe: none on three.js', once === null && /not measurable/.test(remapLine), `remapOnce ${once}`);
    } else {
        check(label, 'remap probe runs', typeof once === 'number' && once > 0 && Number.isFinite(once),
            `the remap alone, run and read back: ${once?.toFixed?.(2)} ms wall clock${after.software ? ' (software rasterizer: CPU emulation)' : ''}`);
    }
    measured[label].remap = { gpuTimer: after.gpuTimer, remapGpuMs: after.remapGpuMs, workBufferGpuMs: after.workBufferGpuMs, fencedMs: once, setVerticesCpuMs: after.setVerticesCpuMs, stats };
    check(label, 'no page errors', pageErrors.length === 0, pageErrors.length ? pageErrors.slice(0, 3).join(' | ') : 'none');
}

fs.writeFileSync(path.join(outDir, 'results.json'), JSON.stringify({ checks, measured }, null, 2));
const bad = checks.filter((c) => !c.ok);
if (failed || bad.length) {
    process.stderr.write(`stability: FAIL: ${bad.length} check(s) failed; screenshots in ${outDir}\n`);
    process.exit(1);
}
process.stdout.write(`stability: all ${checks.length} checks passed; screenshots in ${outDir}\n`);
