#!/usr/bin/env node
// node test/three-bones.mjs ASSET.glb F1 [F2 ...]: in headless Chromium, the three.js plugin's
// BoneSkinnedSplats (Spark's dual-quaternion SplatSkinning) read back from the GPU against the
// exact remap at the rest pose and at fractions F of animation 0 (test/page/three-bones.js);
// prints {splats, height, rows: [{time, median, p95, max}]} as JSON (errors relative to the
// height; the rest pose first, time null). Run by tests/test_web_bone_only.py.
import { dirname, basename, resolve } from 'node:path';

import { launchPage } from '../conformance/run-browser.mjs';

const [asset, ...fractions] = process.argv.slice(2);
if (!asset || !fractions.length) {
    process.stderr.write('usage: node test/three-bones.mjs ASSET.glb F1 [F2 ...]\n');
    process.exit(2);
}
const browser = await launchPage({ page: 'test/page/three-bones.html', extraMounts: { '/asset/': dirname(resolve(asset)) } });
try {
    const r = await browser.page.evaluate(([url, f]) => /** @type {any} */ (window).gsvBones.bones(url, f),
        /** @type {[string, number[]]} */ ([`/asset/${basename(asset)}`, fractions.map(Number)]));
    process.stdout.write(`${JSON.stringify(r)}\n`);
} finally {
    await browser.close();
}
