#!/usr/bin/env node
// node tests/render_js/render-playcanvas.mjs JOB.json OUT.rgba
// Renders an anchored GLB in headless Chromium with PlayCanvas and the @gsverse/web plugin.
// JOB.json: {asset, width, height, eye, target, fov, near, far, vertices?: path of a raw
// little-endian float32 (V, 3) file, gamma: "none"|"srgb"}. Writes the top-down RGBA8 pixels
// to OUT.rgba and prints {width, height, renderer} as JSON.
import { readFileSync, writeFileSync } from 'node:fs';
import { dirname, basename, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';

import { launchPage } from '../../plugins/web/conformance/run-browser.mjs';

const HERE = dirname(fileURLToPath(import.meta.url));
const [jobPath, outPath] = process.argv.slice(2);
const job = JSON.parse(readFileSync(jobPath, 'utf8'));
const assetDir = dirname(resolve(job.asset));
const browser = await launchPage({
    page: '../../tests/render_js/page.html',
    extraMounts: { '/tests/render_js/': HERE, '/asset/': assetDir },
});
try {
    const vertices = job.vertices ? Array.from(new Float32Array(readFileSync(job.vertices).buffer.slice(0))) : null;
    const res = await browser.page.evaluate((o) => /** @type {any} */ (window).gsvCompare.render(o),
        { ...job, url: `/asset/${basename(job.asset)}`, vertices });
    writeFileSync(outPath, Buffer.from(res.rgba, 'base64'));
    console.log(JSON.stringify({ width: res.width, height: res.height, renderer: res.renderer }));
} finally {
    await browser.close();
}
