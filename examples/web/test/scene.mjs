#!/usr/bin/env node
// The physics scene in headless Chromium: examples/web/scene.glb (chair rigid, pillow soft, lamp
// kinematic, a ground box, a floor of plain background splats; gsverse-convert --physics
// --ground) opened in test mode (fixed camera, physics paused).
//
//   node examples/web/test/scene.mjs OUTDIR [--engine playcanvas|three]
//
// The same checks run on either engine of the demo (?engine=three: three.js + Spark).
// The physics runs a fixed number of fixed steps (gsverseDemo.simulate: 1/60 s each, no wall
// clock), then a scripted pull of the soft body (pull: its ends pinned, a fixed number of steps).
// Checks, from the demo's state and from the pictures:
//   - settle as the file has it (SETTLE steps): the chair comes to rest on the ground;
//   - drop (the chair and the pillow lifted, paused) and STEPS steps: the chair's node dropped by
//     more than FALL (world units) and its hull rests on the ground (its lowest point within
//     Jolt's penetration slop of the top face); the lamp (kinematic) has not moved; the pillow
//     lies on the ground; in the pictures the chair left its lifted place and the background (the
//     floor away from the objects) did not change;
//   - pull('x', 1.5): the pillow's anchor mesh extent along x grows by at least STRETCH, and in
//     the picture the pixels that changed along the pillow's rows span at least STRETCH times its
//     settled width on screen;
//   - reset: the chair is back where the file puts it; no page errors.
// PNGs and results.json go to OUTDIR; exit status 1 on any failure.

import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { startServer } from '../serve.mjs';
import { meanDifference } from './measure.mjs';
import { launch, stableShot } from './browser.mjs';

const HERE = path.dirname(fileURLToPath(import.meta.url));
const SCENE = path.join(HERE, '..', 'scene.glb');
/** physics steps of 1/60 s: to settle the scene as the file has it, and after the drop (the chair
 * falls in about 0.4 s) */
const SETTLE = 60;
const STEPS = 240;
/** how far the chair's node must have dropped after the drop (world units; it is lifted by half
 * the scene's height, 0.6) */
const FALL = 0.4;
/** the pull, and the growth of the pillow's extent along x that it must at least give */
const PULL = 1.5;
const STRETCH = 1.3;
/** Jolt's default penetration slop, in simulation units (1 simulation unit = the scene's size) */
const SLOP = 0.02;

const args = process.argv.slice(2);
const engineAt = args.indexOf('--engine');
const engine = engineAt >= 0 ? args[engineAt + 1] : 'playcanvas';
const outDir = args.find((a, i) => !a.startsWith('--') && !(engineAt >= 0 && i === engineAt + 1));
if (!outDir || !['playcanvas', 'three'].includes(engine)) {
    process.stderr.write('usage: scene.mjs OUTDIR [--engine playcanvas|three]\n');
    process.exit(2);
}
if (!fs.existsSync(SCENE)) {
    process.stderr.write(`scene: FAIL: ${SCENE} is missing (it ships with the repository)\n`);
    process.exit(1);
}
fs.mkdirSync(outDir, { recursive: true });

/** @type {{name: string, ok: boolean, detail: string}[]} */
const checks = [];
/** @param {string} name @param {boolean} ok @param {string} detail */
function check(name, ok, detail) {
    checks.push({ name, ok, detail });
    process.stdout.write(`${ok ? 'ok  ' : 'FAIL'}  ${name}: ${detail}\n`);
}
const f3 = (/** @type {number} */ v) => v.toFixed(3);

/**
 * The screen box (pixels, clamped to the image) of a world box.
 * @param {any} page @param {number[]} min @param {number[]} max @param {{width: number, height: number}} img
 */
async function screenBox(page, min, max, img) {
    const corners = [];
    for (const x of [min[0], max[0]]) for (const y of [min[1], max[1]]) for (const z of [min[2], max[2]]) corners.push([x, y, z]);
    const s = await page.evaluate((/** @type {number[][]} */ c) => /** @type {any} */ (window).gsverseDemo.toScreen(c), corners);
    const xs = s.map((/** @type {number[]} */ p) => p[0]), ys = s.map((/** @type {number[]} */ p) => p[1]);
    const clamp = (/** @type {number} */ v, /** @type {number} */ hi) => Math.max(0, Math.min(hi, Math.round(v)));
    return { x0: clamp(Math.min(...xs), img.width), x1: clamp(Math.max(...xs), img.width), y0: clamp(Math.min(...ys), img.height), y1: clamp(Math.max(...ys), img.height) };
}

/**
 * The columns where the two pictures differ (luminance by more than 40 in at least 3 rows of the
 * window): their span in pixels.
 * @param {any} a @param {any} b @param {{x0: number, x1: number, y0: number, y1: number}} win
 */
function changedSpan(a, b, win) {
    let lo = -1, hi = -1;
    const lum = (/** @type {any} */ img, /** @type {number} */ i) => 0.299 * img.rgba[i] + 0.587 * img.rgba[i + 1] + 0.114 * img.rgba[i + 2];
    for (let x = win.x0; x < win.x1; x++) {
        let n = 0;
        for (let y = win.y0; y < win.y1; y++) {
            const i = 4 * (y * a.width + x);
            if (Math.abs(lum(a, i) - lum(b, i)) > 40) n++;
        }
        if (n >= 3) { if (lo < 0) lo = x; hi = x; }
    }
    return lo < 0 ? 0 : hi - lo + 1;
}

/** @type {Awaited<ReturnType<typeof launch>>|null} */
let browser = null;
/** @type {string[]} */
const pageErrors = [];
let failed = false;
const server = await startServer({ port: 0 });
try {
    browser = await launch();
    const page = await browser.context.newPage();
    page.on('pageerror', (/** @type {Error} */ e) => pageErrors.push(e.message));
    page.on('console', (/** @type {any} */ m) => { if (m.type() === 'error') pageErrors.push(m.text()); });
    page.setDefaultTimeout(120000);
    await page.goto(`${server.url}?test&asset=/scene.glb${engine === 'three' ? '&engine=three' : ''}`);
    const info = await page.evaluate(() => /** @type {any} */ (window).gsverseDemo.ready);
    check('the engine asked for', info.engine === engine, `${info.engine}`);
    process.stdout.write(`scene: ${info.asset}, ${info.splats.anchored} anchored splats, ${info.splats.plain} plain, backend ${info.backend}\n`);
    /** @param {string} expr @param {any[]} a */
    const call = (expr, ...a) => page.evaluate((/** @type {[string, any[]]} */ [e, x]) => /** @type {any} */ (window).gsverseDemo[e](...x), [expr, a]);
    /** @param {string} name */
    const shot = (name) => stableShot(page, path.join(outDir, `${name}.png`));

    const kinds = Object.fromEntries(info.objects.objects.map((/** @type {any} */ o) => [o.name, o.kind]));
    check('the scene\'s objects by kind', kinds.chair === 'rigid' && kinds.pillow === 'soft' && kinds.lamp === 'kinematic' && info.objects.groundTop !== null,
        JSON.stringify(kinds) + `, ground top ${info.objects.groundTop}`);
    const byName = (/** @type {any} */ state, /** @type {string} */ n) => state.objects.find((/** @type {any} */ o) => o.name === n);
    await shot('scene-rest');
    const before = info.objects;
    const ground = before.groundTop;
    // the page simulates in a frame where the objects' bounds are one unit large
    const size = Math.max(...[0, 1, 2].map((k) => Math.max(...before.objects.map((/** @type {any} */ o) => o.max[k]))
        - Math.min(...before.objects.map((/** @type {any} */ o) => o.min[k]))));
    const slop = SLOP * size;
    /** @param {any} o */
    const onGround = (o) => o.min[1] >= ground - slop && o.min[1] <= ground + slop;

    // as the file has it: the objects stand just above the ground box and settle onto it
    const standing = await call('simulate', SETTLE);
    const s0 = byName(standing, 'chair');
    check('as the file has it, the chair settles on the ground', onGround(s0),
        `its hull's lowest point ${f3(byName(before, 'chair').min[1])} -> ${f3(s0.min[1])}, the ground's top ${f3(ground)}`);

    // drop: lifted, then a fixed number of fixed steps
    await call('drop', false);
    const lifted = await call('objects');
    const rest = await shot('scene-dropped');
    const after = await call('simulate', STEPS);
    const settled = await shot('scene-settled');
    const c0 = byName(lifted, 'chair'), c1 = byName(after, 'chair');
    const drop = c0.position[1] - c1.position[1];
    check('the rigid chair fell', drop > FALL, `its node's world y ${f3(c0.position[1])} -> ${f3(c1.position[1])} (dropped ${f3(drop)}, more than ${FALL} required)`);
    check('the chair rests on the ground', onGround(c1),
        `its hull's lowest point ${f3(c1.min[1])}, the ground's top ${f3(ground)} (within Jolt's penetration slop ${f3(slop)})`);
    const l0 = byName(lifted, 'lamp'), l1 = byName(after, 'lamp');
    check('the kinematic lamp stayed', l0.position.every((/** @type {number} */ v, /** @type {number} */ k) => Math.abs(v - l1.position[k]) < 1e-6),
        `${l0.position.map(f3)} -> ${l1.position.map(f3)}`);
    const p0 = byName(lifted, 'pillow'), p1 = byName(after, 'pillow');
    check('the soft pillow fell onto the ground', p1.min[1] < p0.min[1] - 0.2 && p1.min[1] >= ground - slop,
        `its lowest point ${f3(p0.min[1])} -> ${f3(p1.min[1])}`);
    const chairWas = await screenBox(page, c0.min, c0.max, rest);
    const chairIs = await screenBox(page, c1.min, c1.max, rest);
    // the part of the chair's lifted place that it left
    const left = { ...chairWas, y1: Math.min(chairWas.y1, chairIs.y0) };
    const moved = meanDifference(rest, settled, left);
    check('in the picture, the chair left its place', left.y1 - left.y0 > 10 && moved > 20,
        `mean luminance change ${moved.toFixed(1)} over the ${left.x1 - left.x0}x${left.y1 - left.y0} px it left`);
    // the background away from every object: the floor in front of them and beside them; both
    // must show splats (not the black clear colour)
    const boxes = await Promise.all([...lifted.objects, ...after.objects].map((/** @type {any} */ o) => screenBox(page, o.min, o.max, rest)));
    const lo = Math.min(...boxes.map((b) => b.x0)), hi = Math.max(...boxes.map((b) => b.x1)), bottom = Math.max(...boxes.map((b) => b.y1));
    const regions = {
        front: { x0: lo, x1: hi, y0: bottom + 10, y1: Math.min(rest.height, bottom + 40) },
        beside: { x0: Math.max(0, lo - 60), x1: lo - 10, y0: bottom - 40, y1: bottom },
    };
    const black = rest.rgba.map(() => 0);
    const background = Object.entries(regions).map(([name, w]) => ({
        name, w, shown: meanDifference(rest, { ...rest, rgba: black }, w), change: meanDifference(rest, settled, w),
    }));
    check('the background stayed put', background.every((b) => b.w.x1 - b.w.x0 > 10 && b.w.y1 - b.w.y0 > 10 && b.shown > 15 && b.change < 1),
        background.map((b) => `floor ${b.name} ${b.w.x1 - b.w.x0}x${b.w.y1 - b.w.y0} px: mean luminance ${b.shown.toFixed(1)}, change ${b.change.toFixed(2)}`).join('; '));

    // the scripted pull of the soft pillow
    const e0 = p1.max[0] - p1.min[0];
    await call('pull', 'x', PULL);
    const pulled = await shot('scene-pulled');
    const p2 = byName(await call('objects'), 'pillow');
    const e1 = p2.max[0] - p2.min[0];
    check(`pull ${PULL}x along x: the pillow's anchor mesh stretched`, e1 / e0 >= STRETCH,
        `extent along x ${f3(e0)} -> ${f3(e1)} = ${(e1 / e0).toFixed(3)}x (at least ${STRETCH}x required)`);
    const was = await screenBox(page, p1.min, p1.max, rest), is = await screenBox(page, p2.min, p2.max, rest);
    const band = { x0: 0, x1: rest.width, y0: Math.min(was.y0, is.y0), y1: Math.max(was.y1, is.y1) };
    const span = changedSpan(settled, pulled, band), width = was.x1 - was.x0;
    check('in the picture, the pillow stretched', span >= STRETCH * width,
        `the pixels that changed along its rows span ${span} px, its settled width is ${width} px (${(span / Math.max(1, width)).toFixed(2)}x)`);
    const still2 = Math.max(...Object.values(regions).map((w) => meanDifference(settled, pulled, w)));
    check('the pull moved nothing else', still2 < 1, `mean luminance change ${still2.toFixed(2)} on the floor away from the objects`);

    // reset puts the rigid objects back
    await call('reset');
    const r = byName(await call('objects'), 'chair');
    const file = byName(before, 'chair');
    check('reset: the chair is back where the file puts it', Math.abs(r.position[1] - file.position[1]) < 1e-4, `node y ${f3(r.position[1])}`);
    await shot('scene-reset');
    check('no page errors', pageErrors.length === 0, pageErrors.length ? pageErrors.slice(0, 3).join(' | ') : 'none');
    await page.close();
} catch (err) {
    failed = true;
    process.stderr.write(`scene: FAIL: ${/** @type {Error} */ (err).stack || err}\n`);
    if (pageErrors.length) process.stderr.write(`page errors:\n  ${pageErrors.join('\n  ')}\n`);
} finally {
    await browser?.close();
    await server.close();
}

fs.writeFileSync(path.join(outDir, 'results.json'), JSON.stringify({ checks, pageErrors }, null, 2));
const bad = checks.filter((c) => !c.ok);
if (failed || bad.length || !checks.length) {
    process.stderr.write(`scene: FAIL: ${bad.length} check(s) failed${failed ? ' and the run stopped early' : ''}; screenshots in ${outDir}\n`);
    process.exit(1);
}
process.stdout.write(`scene: all ${checks.length} checks passed; screenshots in ${outDir}\n`);
