// The render path in headless Chromium: the shipped example loads with loadAnchoredAsset, the
// remap runs in PlayCanvas's work-buffer copy pass, the remapped rest pose renders like the
// engine's own rest pose, and stretching the anchor mesh 1.5x along an axis stretches the
// rendered splats by about that factor. Skipped without Chromium or the example asset.
import test from 'node:test';
import assert from 'node:assert/strict';
import { existsSync } from 'node:fs';
import { fileURLToPath } from 'node:url';

import { launchPage, timeScale } from '../conformance/run-browser.mjs';

const chromium = process.env.CHROMIUM || '/usr/bin/chromium';
const examples = fileURLToPath(new URL('../../../examples', import.meta.url));
const asset = `${examples}/web/capsule.glb`;
const skip = !existsSync(chromium) ? `no Chromium at ${chromium}` : !existsSync(asset) ? 'no examples/web/capsule.glb' : false;

test('the example renders through the work-buffer remap and follows a stretch', { skip, timeout: 180_000 * timeScale() }, async () => {
    const browser = await launchPage({ page: 'conformance/page/render.html', extraMounts: { '/examples/': examples } });
    try {
        const page = browser.page;
        const info = await page.evaluate(() => /** @type {any} */ (window).gsvRender.load('/examples/web/capsule.glb'));
        assert.deepEqual(info.splats.length, 1);
        const cmp = await page.evaluate(() => /** @type {any} */ (window).gsvRender.compareToEngine());
        assert.ok(cmp.lit > 500, `the rest pose renders (${cmp.lit} lit pixels)`);
        // the engine stores rotations and scales as half floats, the remap outputs float32
        assert.ok(cmp.differing <= cmp.lit / 100, `remapped rest pose = engine rest pose (${JSON.stringify(cmp)})`);
        const rest = await page.evaluate(() => /** @type {any} */ (window).gsvRender.stretch(1, 1));
        for (const axis of [0, 1]) {
            const s = await page.evaluate((a) => /** @type {any} */ (window).gsvRender.stretch(a, 1.5), axis);
            const size = (/** @type {any} */ e) => (axis === 0 ? e.x1 - e.x0 : e.y1 - e.y0) + 1;
            const other = (/** @type {any} */ e) => (axis === 0 ? e.y1 - e.y0 : e.x1 - e.x0) + 1;
            const ratio = size(s) / size(rest);
            assert.ok(ratio > 1.35 && ratio < 1.65, `axis ${axis}: rendered extent grew ${ratio.toFixed(3)}x`);
            assert.ok(Math.abs(other(s) / other(rest) - 1) < 0.1, `axis ${axis}: the other extent stays`);
        }
    } finally {
        await browser.close();
    }
});
