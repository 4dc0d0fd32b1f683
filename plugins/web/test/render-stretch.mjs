// The render check shared by test/gpu-render.test.mjs (the installed engine) and
// test/engine-versions.test.mjs (every supported engine version): on the render page
// (conformance/page/render.html, /examples/ mounted), the shipped example loads with
// loadAnchoredAsset, the remapped rest pose renders like the engine's own rest pose (the engine
// stores rotations and scales as half floats, the remap outputs float32: at most 1% of the lit
// pixels differ), and stretching the anchor mesh 1.5x along an axis stretches the rendered
// splats by about that factor while the other extent stays.
import assert from 'node:assert/strict';

/** @param {import('playwright-core').Page} page */
export async function renderAndStretch(page) {
    const info = await page.evaluate(() => /** @type {any} */ (window).gsvRender.load('/examples/web/capsule.glb'));
    assert.deepEqual(info.splats.length, 1);
    const cmp = await page.evaluate(() => /** @type {any} */ (window).gsvRender.compareToEngine());
    assert.ok(cmp.lit > 500, `the rest pose renders (${cmp.lit} lit pixels)`);
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
}
