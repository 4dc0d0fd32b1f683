#!/usr/bin/env node
// The demo plays an asset's own animations (an anchor mesh with a skin or morph targets), in
// headless Chromium:
//
//   node examples/web/test/animation.mjs OUTDIR ASSET.glb
//
// Checks: the panel lists the file's animations; scrubbing to two times shows two different
// pictures (the rendered silhouettes differ), and the same time twice the same picture; "play"
// advances the time while frames are drawn and "pause" stops it; choosing "rest pose" gives the
// rest picture back; a pull of the soft body stretches the animated splats (the physics on top of
// the animation); no page errors. PNGs and results.json go to OUTDIR; exit status 1 on any failure.

import fs from 'node:fs';
import path from 'node:path';
import { startServer } from '../serve.mjs';
import { silhouette, meanDifference } from './measure.mjs';
import { launch, stableShot } from './browser.mjs';

const [outDir, asset] = process.argv.slice(2);
if (!outDir || !asset) {
    process.stderr.write('usage: animation.mjs OUTDIR ASSET.glb\n');
    process.exit(2);
}
if (!fs.existsSync(asset)) {
    process.stderr.write(`animation: FAIL: ${asset}: no such file\n`);
    process.exit(1);
}
fs.mkdirSync(outDir, { recursive: true });
const SCALE = Math.max(1, Number(process.env.GSVERSE_TIME_SCALE) || 1);

/** @type {{name: string, ok: boolean, detail: string}[]} */
const checks = [];
/** @param {string} name @param {boolean} ok @param {string} detail */
function check(name, ok, detail) {
    checks.push({ name, ok, detail });
    process.stdout.write(`${ok ? 'ok  ' : 'FAIL'}  ${name}: ${detail}\n`);
}

/** Mean absolute difference over the whole picture. @param {any} a @param {any} b */
const difference = (a, b) => meanDifference(a, b, { x0: 0, x1: a.width, y0: 0, y1: a.height });

let browser;
try {
    browser = await launch({ width: 480, height: 480 });
} catch (err) {
    process.stderr.write(`animation: FAIL: ${/** @type {Error} */ (err).message}\n`);
    process.exit(1);
}
const server = await startServer({ asset, port: 0 });
/** @type {string[]} */
const pageErrors = [];
let failed = false;
try {
    const page = await browser.context.newPage();
    page.on('pageerror', (/** @type {Error} */ e) => pageErrors.push(e.message));
    page.on('console', (/** @type {any} */ m) => { if (m.type() === 'error') pageErrors.push(m.text()); });
    page.setDefaultTimeout(120000 * SCALE);
    await page.goto(`${server.url}?test`);
    await page.evaluate(() => /** @type {any} */ (window).gsverseDemo.ready);
    /** @param {any} set */
    const animation = (set) => page.evaluate((/** @type {any} */ s) => /** @type {any} */ (window).gsverseDemo.animation(s), set);
    /** @param {string} name */
    const shot = (name) => stableShot(page, path.join(outDir, `${name}.png`), 60000 * SCALE);

    const state = await animation({});
    check('the panel lists the animations', state.animations.length > 0 && state.animations.every((/** @type {any} */ a) => a.duration > 0),
        state.animations.map((/** @type {any} */ a) => `${a.name} (${a.duration.toFixed(2)} s)`).join(', ') || 'none');
    const rest = await shot('rest');
    const duration = state.animations[0]?.duration ?? 1;
    const t1 = 0.3 * duration, t2 = 0.85 * duration;
    await animation({ chosen: 0, time: t1, playing: false });
    const a = await shot('t1');
    await animation({ time: t2 });
    const b = await shot('t2');
    await animation({ time: t1 });
    const a2 = await shot('t1-again');
    const dAB = difference(a, b), dAA = difference(a, a2), dRestA = difference(rest, a);
    check('scrubbing: two times give two pictures, the same time the same picture', dAB > 4 * Math.max(dAA, 0.05) && dRestA > 4 * Math.max(dAA, 0.05),
        `mean |difference| t1/t2 ${dAB.toFixed(2)}, rest/t1 ${dRestA.toFixed(2)}, t1/t1 again ${dAA.toFixed(2)} (of 255)`);
    const sa = silhouette(a), sb = silhouette(b);
    check('the splats move with the animation', sa.area !== sb.area || sa.x.lo !== sb.x.lo || sa.y.lo !== sb.y.lo,
        `silhouette ${sa.x.size}x${sa.y.size} px at ${sa.x.lo},${sa.y.lo} and ${sb.x.size}x${sb.y.size} px at ${sb.x.lo},${sb.y.lo}`);

    await animation({ time: 0, playing: true });
    const before = (await animation({})).time;
    await page.waitForTimeout(1500);
    const during = await animation({});
    check('play advances the time', during.playing && during.time !== before, `time ${before.toFixed(3)} s -> ${during.time.toFixed(3)} s`);
    const paused = await animation({ playing: false });
    await page.waitForTimeout(800);
    const after = await animation({});
    check('pause stops it', !after.playing && after.time === paused.time, `time ${paused.time.toFixed(3)} s, then ${after.time.toFixed(3)} s`);

    await animation({ chosen: -1 });
    const back = await shot('rest-again');
    const dRest = difference(rest, back);
    check('"rest pose" gives the rest picture back', dRest < Math.max(1, 0.25 * dRestA), `mean |difference| from the first rest picture ${dRest.toFixed(2)}`);

    // the physics under the animation: a pull of the soft body adds its displacement to the
    // animated pose (a scripted pull: physics paused, the end caps driven)
    await animation({ chosen: 0, time: t1, playing: false });
    const s1 = silhouette(await shot('animated'));
    const axis = (await page.evaluate(() => /** @type {any} */ (window).gsverseDemo.info())).axis;
    await page.evaluate((/** @type {string} */ ax) => /** @type {any} */ (window).gsverseDemo.pull(ax, 1.5), axis);
    const s2 = silhouette(await shot('animated-pulled'));
    const grow = axis === 'x' ? s2.x.size / s1.x.size : s2.y.size / s1.y.size;
    check('a pull stretches the animated splats (physics displacement on top of the animation)',
        axis === 'z' ? s2.area !== s1.area : grow > 1.15,
        `pull 1.5x along ${axis}: silhouette ${s1.x.size}x${s1.y.size} -> ${s2.x.size}x${s2.y.size} px`);
    const unexpected = pageErrors;
    check('no page errors', unexpected.length === 0, unexpected.slice(0, 3).join(' | ') || 'none');
} catch (err) {
    failed = true;
    process.stderr.write(`animation: FAIL: ${/** @type {Error} */ (err).stack || err}\n`);
} finally {
    await browser.close();
    await server.close();
}
fs.writeFileSync(path.join(outDir, 'results.json'), JSON.stringify({ checks, pageErrors }, null, 2));
const bad = checks.filter((c) => !c.ok);
if (failed || bad.length) {
    process.stderr.write(`animation: FAIL: ${bad.length} check(s) failed; screenshots in ${outDir}\n`);
    process.exit(1);
}
process.stdout.write(`animation: all ${checks.length} checks passed; screenshots in ${outDir}\n`);
