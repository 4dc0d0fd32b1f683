#!/usr/bin/env node
// node test/three-follow.mjs ASSET.glb T1 [T2 ...]: in headless Chromium, the three.js plugin's
// followSkinnedMesh on the anchor mesh as GLTFLoader builds it, played by an AnimationMixer at
// each time, against the package's animation sampler (test/page/three-follow.js); prints
// {maxError, extent, moved, vertices} as JSON. Run by tests/test_web_three.py.
import { dirname, basename, resolve } from 'node:path';

import { launchPage } from '../conformance/run-browser.mjs';

const [asset, ...times] = process.argv.slice(2);
if (!asset || !times.length) {
    process.stderr.write('usage: node test/three-follow.mjs ASSET.glb T1 [T2 ...]\n');
    process.exit(2);
}
const browser = await launchPage({ page: 'test/page/three-follow.html', extraMounts: { '/asset/': dirname(resolve(asset)) } });
try {
    const r = await browser.page.evaluate(([url, t]) => /** @type {any} */ (window).gsvFollow.follow(url, t),
        /** @type {[string, number[]]} */ ([`/asset/${basename(asset)}`, times.map(Number)]));
    process.stdout.write(`${JSON.stringify(r)}\n`);
} finally {
    await browser.close();
}
