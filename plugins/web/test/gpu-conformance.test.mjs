// The GPU path in headless Chromium (WebGL2; SwiftShader without a GPU): the whole conformance
// suite passes `gsverse-conformance check`, and the deliberately broken shaders fail exactly the
// cases they should (frame-axis: every `local` remap case; games-axis: every `games` remap
// case). The WGSL twin passes too on PlayCanvas's WebGPU device where Chromium offers a WebGPU
// adapter (skipped otherwise). Needs Chromium (/usr/bin/chromium or $CHROMIUM) and the gsverse-conformance CLI
// ($GSVERSE_CONFORMANCE, the repository's .venv, or PATH); skipped without them. The suite
// is $GSVERSE_SUITE or exported into a temporary folder.
import test from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync, spawnSync } from 'node:child_process';
import { existsSync, mkdtempSync, readFileSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { fileURLToPath } from 'node:url';

import { runSuiteInBrowser, timeScale } from '../conformance/run-browser.mjs';

const chromium = process.env.CHROMIUM || '/usr/bin/chromium';
const repoVenv = fileURLToPath(new URL('../../../.venv/bin/gsverse-conformance', import.meta.url));

function findCli() {
    if (process.env.GSVERSE_CONFORMANCE) return process.env.GSVERSE_CONFORMANCE;
    if (existsSync(repoVenv)) return repoVenv;
    const which = spawnSync('which', ['gsverse-conformance'], { encoding: 'utf8' });
    return which.status === 0 ? which.stdout.trim() : null;
}

const cli = findCli();
const skip = !existsSync(chromium) ? `no Chromium at ${chromium}` : !cli ? 'no gsverse-conformance CLI' : false;

/**
 * `gsverse-conformance check --format json --level numbers` (the render level: tests/test_web_plugin.py)
 * @param {string} suite @param {string} results
 * @returns {any}
 */
function check(suite, results) {
    const r = spawnSync(/** @type {string} */ (cli), ['check', suite, results, '--format', 'json', '--level', 'numbers'], { encoding: 'utf8', maxBuffer: 1 << 28 });
    return JSON.parse(r.stdout);
}

test('GPU remap in Chromium passes the suite; broken shaders fail exactly their cases', { skip, timeout: 600_000 * timeScale() }, async (t) => {
    const tmp = mkdtempSync(join(tmpdir(), 'gsverse-gpu-'));
    try {
        let suite = process.env.GSVERSE_SUITE;
        if (!suite) {
            suite = join(tmp, 'suite');
            execFileSync(/** @type {string} */ (cli), ['export', suite], { stdio: 'ignore' });
        }
        const index = JSON.parse(readFileSync(join(suite, 'suite.json'), 'utf8'));
        /** @param {string} tag */
        const remapWith = (tag) => index.cases.filter((/** @type {any} */ c) => (c.kind === 'remap' || c.kind === 'rig') && c.tags.includes(tag))
            .map((/** @type {any} */ c) => c.id).sort();

        await t.test('every case passes', async () => {
            const results = join(tmp, 'gpu');
            const run = await runSuiteInBrowser(suite, results);
            assert.equal(run.summary.filter((s) => s.outcome === 'error').length, 0);
            const report = check(suite, results);
            const failed = report.cases.filter((/** @type {any} */ c) => c.status !== 'pass');
            assert.deepEqual(failed.map((/** @type {any} */ c) => `${c.id}: ${c.message}`), []);
            assert.equal(report.summary.passed, index.cases.length);
            assert.match(String(report.harness.backend), /webgl2/i);
        });

        for (const [fault, tag] of [['frame-axis', 'profile:local'], ['games-axis', 'profile:games']]) {
            await t.test(`--fault ${fault} fails exactly the ${tag} remap cases`, async () => {
                const results = join(tmp, fault);
                await runSuiteInBrowser(suite, results, { fault });
                const report = check(suite, results);
                const failed = report.cases.filter((/** @type {any} */ c) => c.status !== 'pass').map((/** @type {any} */ c) => c.id).sort();
                const expected = remapWith(tag);
                assert.ok(expected.length > 0);
                assert.deepEqual(failed, expected);
            });
        }

        await t.test('the WGSL twin passes every case on WebGPU', async (t2) => {
            const results = join(tmp, 'webgpu');
            try {
                await runSuiteInBrowser(suite, results, { backend: 'webgpu' });
            } catch (err) {
                if (/no webgpu device/i.test(String(err))) return t2.skip('no WebGPU adapter in this Chromium');
                throw err;
            }
            const report = check(suite, results);
            const failed = report.cases.filter((/** @type {any} */ c) => c.status !== 'pass');
            assert.deepEqual(failed.map((/** @type {any} */ c) => `${c.id}: ${c.message}`), []);
            assert.match(String(report.harness.backend), /webgpu/i);
        });
    } finally {
        rmSync(tmp, { recursive: true, force: true });
    }
});
