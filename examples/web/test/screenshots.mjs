#!/usr/bin/env node
// Screenshot test of the web demo in headless Chromium (playwright-core + the system chromium,
// WebGL2 on SwiftShader where there is no GPU).
//
//   node examples/web/test/screenshots.mjs OUTDIR [--readme] [--engine playcanvas|three]
//
// The same checks run on either engine of the demo (?engine=three: three.js + Spark).
// Loads the demo with the shipped example (examples/web/capsule.glb) in test mode (fixed
// front camera, black background, physics paused; scripted manipulations drive the soft body's
// end caps kinematically and settle it with a fixed number of fixed steps, so the poses are
// deterministic), takes screenshots and measures the rendered splats in them:
//   - rest: something is drawn, inside the frame;
//   - pull('y', 1.5): the rendered extent along y grows by 1.3..1.7x, the other axis stays sane;
//   - reset: back to the rest silhouette;
//   - twist(+60 / -60) about the view axis: the front end turns, so the red-to-cyan colour axis
//     of the splats turns with the twist's sign by 20..85 degrees, nothing blows up;
//   - twist(90) about the long axis: silhouette kept, the held end unchanged, the turned end changed;
//   - the SPZ-compressed capsule (capsule-spz.glb): loads, the rest silhouette and colours of
//     the uncompressed one, a 1.5x pull grows its rendered extent 1.3..1.7x;
//   - a .ply dropped on the page says to convert it with gsverse-convert first;
//   - a refused asset (an anchor mesh reference that resolves to nothing) shows the AnchorError
//     on the page and leaves the loaded asset in place.
// PNGs and results.json go to OUTDIR; exit status 1 on any failure. With --readme the demo
// mid-stretch is also written to examples/web/screenshot-stretch.png.

import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { startServer, DEFAULT_ASSET } from '../serve.mjs';
import { silhouette, meanDifference } from './measure.mjs';
import { launch, stableShot } from './browser.mjs';

const HERE = path.dirname(fileURLToPath(import.meta.url));

/** @param {string} msg @returns {never} */
function die(msg) {
    process.stderr.write(`screenshots: FAIL: ${msg}\n`);
    process.exit(1);
}

const args = process.argv.slice(2);
const readme = args.includes('--readme');
const engineAt = args.indexOf('--engine');
const engine = engineAt >= 0 ? args[engineAt + 1] : 'playcanvas';
const outDir = args.find((a, i) => !a.startsWith('--') && !(engineAt >= 0 && i === engineAt + 1));
if (!outDir || !['playcanvas', 'three'].includes(engine)) {
    process.stderr.write('usage: screenshots.mjs OUTDIR [--readme] [--engine playcanvas|three]\n');
    process.exit(2);
}
if (!fs.existsSync(DEFAULT_ASSET)) die(`${DEFAULT_ASSET} is missing (it ships with the repository)`);
/** @type {Awaited<ReturnType<typeof launch>>} */
let browser;
try {
    browser = await launch();
} catch (err) {
    die(/** @type {Error} */ (err).message);
}
const context = browser.context;
fs.mkdirSync(outDir, { recursive: true });

/** @type {{name: string, ok: boolean, detail: string}[]} */
const checks = [];
/** @param {string} name @param {boolean} ok @param {string} detail */
function check(name, ok, detail) {
    checks.push({ name, ok, detail });
    process.stdout.write(`${ok ? 'ok  ' : 'FAIL'}  ${name}: ${detail}\n`);
}
/** @param {number} v @param {number} lo @param {number} hi */
const within = (v, lo, hi) => v >= lo && v <= hi;

/**
 * Weighted centroids of the red-ish and the cyan-ish splat pixels; returns the angle (degrees,
 * y up) of the vector from red to cyan.
 * @param {{width: number, height: number, rgba: Uint8Array}} img
 */
function colourAxis(img) {
    let rx = 0, ry = 0, rw = 0, cx = 0, cy = 0, cw = 0;
    const { width, height, rgba } = img;
    for (let y = 0; y < height; y++) {
        for (let x = 0; x < width; x++) {
            const i = 4 * (y * width + x);
            const r = rgba[i], b = rgba[i + 2];
            if (Math.max(r, rgba[i + 1], b) <= 40) continue;
            const red = Math.max(0, r - b), cyan = Math.max(0, b - r);
            rx += red * x; ry += red * y; rw += red;
            cx += cyan * x; cy += cyan * y; cw += cyan;
        }
    }
    if (!rw || !cw) return NaN;
    return Math.atan2(-(cy / cw - ry / rw), cx / cw - rx / rw) * 180 / Math.PI;
}

/** @param {number} a @param {number} b signed difference of angles in degrees, -180..180 */
const angleDiff = (a, b) => ((a - b + 540) % 360) - 180;

const server = await startServer({ port: 0 });
/** @type {string[]} */
const pageErrors = [];
let failed = false;
try {
    const page = await context.newPage();
    page.on('pageerror', (/** @type {Error} */ e) => pageErrors.push(e.message));
    page.on('console', (/** @type {any} */ m) => { if (m.type() === 'error') pageErrors.push(m.text()); });
    page.setDefaultTimeout(120000);
    const query = engine === 'three' ? '&engine=three' : '';
    await page.goto(`${server.url}?test${query}`);
    const info = await page.evaluate(() => /** @type {any} */ (window).gsverseDemo.ready);
    process.stdout.write(`demo: ${info.asset}, ${info.splats.anchored} anchored splats, engine ${info.engine}, backend ${info.backend}\n`);
    check('the engine asked for', info.engine === engine, `${info.engine}`);

    /** The frame once the splats are drawn and stable (browser.mjs). @param {string} name */
    const shot = (name) => stableShot(page, path.join(outDir, `${name}.png`));
    /** @param {string} expr @param {any[]} a */
    const call = (expr, ...a) => page.evaluate((/** @type {[string, any[]]} */ [e, x]) => /** @type {any} */ (window).gsverseDemo[e](...x), [expr, a]);

    // rest
    const rest = await shot('rest');
    const s0 = silhouette(rest);
    const e0 = await call('extent');
    check('rest not blank', s0.fraction > 0.02 && !s0.touchesBorder,
        `${s0.x.size}x${s0.y.size} px, ${(100 * s0.fraction).toFixed(1)}% of the frame${s0.touchesBorder ? ', touches the border' : ''}`);

    // pull 1.5x along y
    const e1 = await call('pull', 'y', 1.5);
    const pulled = await shot('stretch');
    const s1 = silhouette(pulled);
    const ry = s1.y.size / s0.y.size, rx = s1.x.size / s0.x.size;
    check('pull 1.5x along y: rendered extent', within(ry, 1.3, 1.7),
        `y ${s0.y.size} -> ${s1.y.size} px = ${ry.toFixed(3)}x (anchor mesh ${(e1[1] / e0[1]).toFixed(3)}x)`);
    check('pull: not exploded', within(rx, 0.6, 1.15) && s1.area > 0.5 * s0.area && !s1.touchesBorder,
        `x ${rx.toFixed(3)}x, drawn area ${(s1.area / s0.area).toFixed(2)}x rest`);

    // reset
    await call('reset');
    const back = await shot('reset');
    const s2 = silhouette(back);
    check('reset: back to rest', Math.abs(s2.y.size - s0.y.size) <= 3 && Math.abs(s2.x.size - s0.x.size) <= 3,
        `${s2.x.size}x${s2.y.size} px (rest ${s0.x.size}x${s0.y.size})`);

    // twist about the view axis: the front end turns in the image plane
    const a0 = colourAxis(rest);
    for (const [deg, name] of /** @type {[number, string][]} */ ([[60, 'twist-ccw'], [-60, 'twist-cw']])) {
        await call('reset');
        await call('twist', deg, 'z');
        const img = await shot(name);
        const s = silhouette(img);
        const turn = angleDiff(colourAxis(img), a0);
        const ok = Math.sign(turn) === Math.sign(deg) && within(Math.abs(turn), 20, 85);
        check(`twist ${deg} deg about the view axis: colour axis turns`, ok, `red->cyan axis turned ${turn.toFixed(1)} deg (rest ${a0.toFixed(1)} deg)`);
        const bx = s.x.size / s0.x.size, by = s.y.size / s0.y.size;
        check(`twist ${deg}: not exploded`, bx <= 1.8 && by <= 1.3 && s.area > 0.5 * s0.area && !s.touchesBorder,
            `extent ${bx.toFixed(3)}x, ${by.toFixed(3)}y, drawn area ${(s.area / s0.area).toFixed(2)}x rest`);
    }

    // twist about the long axis: silhouette kept, held (low) end unchanged, turned (high) end changed
    await call('reset');
    await call('twist', 90, 'y');
    const tl = await shot('twist-long');
    const s3 = silhouette(tl);
    const h = s0.y.size, cx = (s0.x.lo + s0.x.hi) >> 1, half = s0.x.size >> 2;
    /** @param {number} k band index 0 (top) .. 7 (bottom) */
    const band = (k) => meanDifference(rest, tl, { x0: cx - half, x1: cx + half, y0: s0.y.lo + Math.round(h * k / 8), y1: s0.y.lo + Math.round(h * (k + 1) / 8) });
    const bands = [0, 1, 2, 3, 4, 5, 6, 7].map(band);
    const top = Math.max(...bands.slice(0, 4)), bottom = bands[7];
    check('twist 90 deg about the long axis: silhouette kept', within(s3.y.size / s0.y.size, 0.9, 1.1) && within(s3.x.size / s0.x.size, 0.85, 1.3),
        `${(s3.x.size / s0.x.size).toFixed(3)}x, ${(s3.y.size / s0.y.size).toFixed(3)}y`);
    check('twist about the long axis: turned end changed, held end kept', bottom < 0.5 * top,
        `mean |difference| from rest per band, top to bottom: ${bands.map((v) => v.toFixed(1)).join(', ')}`);

    // the same capsule with its rest pose SPZ-compressed (capsule-spz.glb): it loads through the
    // plugin's expandCompressed, looks like the uncompressed one and deforms
    const spz = await page.evaluate(async () => {
        const demo = /** @type {any} */ (window).gsverseDemo;
        const bytes = new Uint8Array(await (await fetch('/capsule-spz.glb')).arrayBuffer());
        try {
            await demo.load(bytes, 'capsule-spz.glb');
            return { loaded: true, extent: demo.extent() };
        } catch (e) {
            return { loaded: false, error: String(/** @type {any} */ (e).message || e) };
        }
    });
    check('SPZ-compressed capsule loads', spz.loaded, spz.loaded ? `extent ${JSON.stringify(spz.extent.map((/** @type {number} */ v) => +v.toFixed(3)))}` : spz.error);
    if (spz.loaded) {
        const restSpz = await shot('spz-rest');
        const c0 = silhouette(restSpz);
        check('SPZ capsule at rest: the silhouette of the uncompressed one', Math.abs(c0.y.size - s0.y.size) <= 3 && Math.abs(c0.x.size - s0.x.size) <= 3 && c0.fraction > 0.02,
            `${c0.x.size}x${c0.y.size} px (uncompressed ${s0.x.size}x${s0.y.size})`);
        // colours as well: the quantization moves a pixel by about 1 of 255 on average (measured
        // 0.5 to 0.8), a wrong frame or SH sign by about as much as the 90-degree twist (10 to 12)
        const dSpz = meanDifference(rest, restSpz, { x0: s0.x.lo, x1: s0.x.hi, y0: s0.y.lo, y1: s0.y.hi });
        check('SPZ capsule at rest: the colours of the uncompressed one', dSpz < 3, `mean |difference| ${dSpz.toFixed(2)} of 255`);
        await call('pull', 'y', 1.5);
        const c1 = silhouette(await shot('spz-stretch'));
        const cy = c1.y.size / c0.y.size;
        check('SPZ capsule: pull 1.5x along y grows the rendered extent', within(cy, 1.3, 1.7) && !c1.touchesBorder,
            `y ${c0.y.size} -> ${c1.y.size} px = ${cy.toFixed(3)}x`);
        // back to the uncompressed capsule for what follows
        await page.evaluate(async () => {
            const demo = /** @type {any} */ (window).gsverseDemo;
            await demo.load(new Uint8Array(await (await fetch('/capsule.glb')).arrayBuffer()), 'capsule.glb');
        });
    }

    // a refused asset
    await call('reset');
    const glb = fs.readFileSync(DEFAULT_ASSET);
    const needle = Buffer.from('{"mesh":1,"primitive":0,"profile"');
    const at = glb.indexOf(needle);
    if (at < 0) {
        check('refused asset: on-page error', false, 'could not build the broken asset (anchor reference not found in the example)');
    } else {
        const broken = Buffer.from(glb);
        broken.write('{"mesh":7', at, 'latin1');
        const outcome = await page.evaluate(async (/** @type {string} */ b64) => {
            const bytes = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
            const demo = /** @type {any} */ (window).gsverseDemo;
            try {
                await demo.load(bytes, 'broken-reference.glb');
                return { loaded: true, error: demo.error(), extent: demo.extent() };
            } catch (e) {
                return { loaded: false, name: /** @type {any} */ (e).name, error: demo.error(), extent: demo.extent() };
            }
        }, broken.toString('base64'));
        await shot('refused');
        const err = outcome.error;
        check('refused asset: on-page error', !outcome.loaded && outcome.name === 'AnchorError' && !!err && err.code === 'UNRESOLVED_REFERENCE' && /broken-reference\.glb/.test(err.text),
            err ? `"${err.text}"` : 'no error shown');
        check('refused asset: previous asset kept', Array.isArray(outcome.extent), `extent ${JSON.stringify(outcome.extent?.map((/** @type {number} */ v) => +v.toFixed(3)))}`);
    }
    // a splat file dropped on the page: it says to convert it first
    const ply = await page.evaluate(async () => {
        const demo = /** @type {any} */ (window).gsverseDemo;
        try {
            await demo.load(new TextEncoder().encode('ply\nformat binary_little_endian 1.0\n'), 'splats.ply');
            return { loaded: true, error: demo.error() };
        } catch {
            return { loaded: false, error: demo.error(), extent: demo.extent() };
        }
    });
    check('a dropped .ply says to convert it first', !ply.loaded && !!ply.error && /gsverse-convert splats\.ply splats\.glb/.test(ply.error.text) && Array.isArray(ply.extent),
        ply.error ? `"${ply.error.text}"` : 'no error shown');
    const unexpected = pageErrors.filter((e) => !/broken-reference|UNRESOLVED_REFERENCE|splats\.ply/.test(e));
    check('no unexpected page errors', unexpected.length === 0, unexpected.length ? unexpected.slice(0, 3).join(' | ') : 'none');
    await page.close();

    // the demo as a person sees it, mid-stretch (for the README)
    const view = await context.newPage();
    await view.setViewportSize({ width: 1000, height: 640 });
    await view.goto(engine === 'three' ? `${server.url}?engine=three` : server.url);
    await view.evaluate(() => /** @type {any} */ (window).gsverseDemo.ready);
    await view.evaluate(() => /** @type {any} */ (window).gsverseDemo.pull('y', 1.5));
    const demoPng = await view.screenshot({ path: path.join(outDir, 'demo-stretch.png') });
    if (readme && engine === 'playcanvas') fs.writeFileSync(path.join(HERE, '..', 'screenshot-stretch.png'), demoPng);
    await view.close();
} catch (err) {
    failed = true;
    process.stderr.write(`screenshots: FAIL: ${/** @type {Error} */ (err).stack || err}\n`);
    if (pageErrors.length) process.stderr.write(`page errors:\n  ${pageErrors.join('\n  ')}\n`);
} finally {
    await browser.close();
    await server.close();
}

fs.writeFileSync(path.join(outDir, 'results.json'), JSON.stringify({ checks, pageErrors }, null, 2));
const bad = checks.filter((c) => !c.ok);
if (failed || bad.length) {
    process.stderr.write(`screenshots: FAIL: ${bad.length} check(s) failed${failed ? ' and the run stopped early' : ''}; screenshots in ${outDir}\n`);
    process.exit(1);
}
process.stdout.write(`screenshots: all ${checks.length} checks passed; screenshots in ${outDir}\n`);
