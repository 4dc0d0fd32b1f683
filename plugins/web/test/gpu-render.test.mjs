// The render path in headless Chromium: the shipped example loads with loadAnchoredAsset, the
// remap runs in PlayCanvas's work-buffer copy pass, the remapped rest pose renders like the
// engine's own rest pose, and stretching the anchor mesh 1.5x along an axis stretches the
// rendered splats by about that factor. Skipped without Chromium or the example asset.
import test from 'node:test';
import { existsSync } from 'node:fs';
import { fileURLToPath } from 'node:url';

import { launchPage, timeScale } from '../conformance/run-browser.mjs';
import { renderAndStretch } from './render-stretch.mjs';

const chromium = process.env.CHROMIUM || '/usr/bin/chromium';
const examples = fileURLToPath(new URL('../../../examples', import.meta.url));
const asset = `${examples}/web/capsule.glb`;
const skip = !existsSync(chromium) ? `no Chromium at ${chromium}` : !existsSync(asset) ? 'no examples/web/capsule.glb' : false;

test('the example renders through the work-buffer remap and follows a stretch', { skip, timeout: 180_000 * timeScale() }, async () => {
    const browser = await launchPage({ page: 'conformance/page/render.html', extraMounts: { '/examples/': examples } });
    try {
        await renderAndStretch(browser.page);
    } finally {
        await browser.close();
    }
});
