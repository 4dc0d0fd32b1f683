// Plain (unanchored) splats next to anchored ones in one asset (the plain primitive first in the
// same mesh): loadAnchoredAsset maps the anchored primitive to the right engine resource, leaves
// the plain one alone, and deforming the anchor mesh moves only the anchored splats on screen.
// Skipped without Chromium.
import test from 'node:test';
import assert from 'node:assert/strict';
import { existsSync, mkdtempSync, rmSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';

import { launchPage, timeScale } from '../conformance/run-browser.mjs';
import { KHR, anchoredBuilder } from './glb-writer.mjs';

const chromium = process.env.CHROMIUM || '/usr/bin/chromium';

/** An asset: anchored splats on a quad at x in [0.3, 1.3], plain splats at x in [-1.3, -0.3]. */
function mixedAsset() {
    const n = 20;
    const face = [], bary = [];
    for (let i = 0; i < n; ++i) {
        for (let j = 0; j < n; ++j) {
            const u = (i + 0.5) / n, v = (j + 0.5) / n;
            if (u + v < 1) { face.push(0); bary.push(u, v); } else { face.push(1); bary.push(1 - v, 1 - u); }
        }
    }
    const N = face.length;
    const b = anchoredBuilder({
        vertices: [0.3, -0.5, 0, 1.3, -0.5, 0, 0.3, 0.5, 0, 1.3, 0.5, 0], indices: [0, 1, 2, 3, 2, 1],
        profile: 'local', deformation: 'affine', face, bary, scale: new Array(3 * N).fill(0.04),
        patch: (/** @type {any} */ json, /** @type {any} */ builder) => {
            const means = new Float32Array(3 * N), rot = new Float32Array(4 * N);
            for (let i = 0; i < N; ++i) {
                means[3 * i] = -1.3 + (i % n) / (n - 1);
                means[3 * i + 1] = -0.5 + Math.floor(i / n) / (n - 1);
                rot[4 * i + 3] = 1;
            }
            const sh = new Float32Array(3 * N).fill(1);
            json.meshes[0].primitives.unshift({
                mode: 0,
                attributes: {
                    POSITION: builder.accessor(means, 'VEC3'),
                    [`${KHR}:ROTATION`]: builder.accessor(rot, 'VEC4'),
                    [`${KHR}:SCALE`]: builder.accessor(new Float32Array(3 * N).fill(0.04), 'VEC3'),
                    [`${KHR}:OPACITY`]: builder.accessor(new Float32Array(N).fill(0.8), 'SCALAR'),
                    [`${KHR}:SH_DEGREE_0_COEF_0`]: builder.accessor(sh, 'VEC3'),
                },
                extensions: { [KHR]: { kernel: 'ellipse', colorSpace: 'srgb_rec709_display', projection: 'perspective', sortingMethod: 'cameraDistance' } },
            });
        },
    });
    return b.glb();
}

test('plain splats stay put while anchored ones follow the anchor mesh', { skip: existsSync(chromium) ? false : `no Chromium at ${chromium}`, timeout: 120_000 * timeScale() }, async () => {
    const dir = mkdtempSync(join(tmpdir(), 'gsverse-mixed-'));
    writeFileSync(join(dir, 'mixed.glb'), mixedAsset());
    const browser = await launchPage({ page: 'conformance/page/render.html', extraMounts: { '/assets/': dir } });
    try {
        const page = browser.page;
        const info = await page.evaluate(() => /** @type {any} */ (window).gsvRender.load('/assets/mixed.glb'));
        assert.deepEqual(info.splats, [400]);
        assert.equal(info.plain, 1);
        assert.equal(info.plainModified, false);
        const before = await page.evaluate(() => /** @type {any} */ (window).gsvRender.columns());
        await page.evaluate(() => /** @type {any} */ (window).gsvRender.stretch(1, 1.5));
        const after = await page.evaluate(() => /** @type {any} */ (window).gsvRender.columns());
        const half = before.length / 2;
        const sum = (/** @type {number[]} */ a, /** @type {number} */ from, /** @type {number} */ to) => a.slice(from, to).reduce((s, x) => s + x, 0);
        assert.ok(sum(before, 0, half - 8) > 0 && sum(before, half + 8, before.length) > 0, 'both groups render');
        assert.deepEqual(after.slice(0, half - 8), before.slice(0, half - 8), 'the plain splats (left) did not change');
        assert.ok(sum(after, half + 8, before.length) > 1.2 * sum(before, half + 8, before.length), 'the anchored splats (right) grew');
    } finally {
        await browser.close();
        rmSync(dir, { recursive: true, force: true });
    }
});
