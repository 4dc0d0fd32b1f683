// The Node conformance harness and the dump layout (spec/conformance.md §The harness and the
// dump layout) on a two-case suite written by the test.
import test from 'node:test';
import assert from 'node:assert/strict';
import { existsSync, mkdirSync, mkdtempSync, readFileSync, rmSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';

import { matchesGlob, posePrefix, readF32, writeCaseResults } from '../conformance/dump.mjs';
import { runSuite } from '../conformance/run-node.mjs';
import { anchoredGlb, KHR, EXT } from './glb-writer.mjs';

/** Write a suite with one remap case (worked example 1) and one invalid case. @param {string} root */
function writeSuite(root) {
    const spec = {
        vertices: [0, 0, 0, 2, 0, 0, 0, 1, 0], indices: [0, 1, 2], profile: /** @type {const} */ ('local'), deformation: 'affine',
        face: [0], bary: [0.25, 0.5], offset: [0.125], rotation: [0, 0, 0, 1], scale: [0.125, 0.375, 0.0625], shDegree: 1,
    };
    const cases = [
        { id: 'example-1', kind: 'remap', bytes: anchoredGlb(spec), poses: [[0, 0, 0, 2, 0, 0, 0, 1, 0], [0, 0, 0, 0, 4, 0, -1, 0, 0]] },
        {
            id: 'invalid-zero-rotation', kind: 'invalid', poses: [],
            bytes: anchoredGlb({ ...spec, rotation: [0, 0, 0, 0] }),
        },
    ];
    for (const c of cases) {
        const folder = join(root, 'cases', c.id);
        mkdirSync(join(folder, 'poses'), { recursive: true });
        writeFileSync(join(folder, 'asset.glb'), c.bytes);
        const poses = c.poses.map((p, i) => {
            const file = `poses/${posePrefix(i)}.f32`;
            writeFileSync(join(folder, file), new Uint8Array(Float32Array.from(p).buffer));
            return file;
        });
        /** @type {any} */
        const manifest = { id: c.id, kind: c.kind, files: { asset: 'asset.glb', poses } };
        if (c.kind === 'invalid') manifest.validator_code = 'ROTATION_NOT_UNIT';
        writeFileSync(join(folder, 'case.json'), JSON.stringify(manifest));
    }
    writeFileSync(join(root, 'suite.json'), JSON.stringify({
        version: 2, cases: cases.map((c) => ({ id: c.id, kind: c.kind, path: `cases/${c.id}` })),
    }));
}

test('run-node writes the dump layout for a remap case and refused for an invalid one', async () => {
    const root = mkdtempSync(join(tmpdir(), 'gsverse-web-suite-'));
    try {
        writeSuite(join(root, 'suite'));
        const results = join(root, 'results');
        const summary = await runSuite(join(root, 'suite'), results);
        assert.deepEqual(summary.map((s) => s.outcome), ['remapped', 'refused']);
        assert.equal(summary[1].code, 'ROTATION_NOT_UNIT');
        const harness = JSON.parse(readFileSync(join(results, 'harness.json'), 'utf8'));
        assert.equal(harness.engine, 'node');
        assert.ok(harness.precision);
        const dir = join(results, 'example-1');
        /** @type {[string, number][]} */
        const sizes = [
            ['rest.means.f32', 3], ['rest.rotation.f32', 4], ['rest.scale.f32', 3], ['rest.opacity.f32', 1], ['rest.sh.f32', 12],
            ['pose_000.means.f32', 3], ['pose_000.cov.f32', 6], ['pose_001.means.f32', 3], ['pose_001.cov.f32', 6],
            ['posed.opacity.f32', 1], ['posed.sh.f32', 12],
        ];
        for (const [file, n] of sizes) assert.equal(readFileSync(join(dir, file)).byteLength, 4 * n, file);
        assert.ok(!existsSync(join(dir, 'refused')) && !existsSync(join(dir, 'error')));
        const mean = readF32(join(dir, 'pose_001.means.f32'));
        const cov = readF32(join(dir, 'pose_001.cov.f32'));
        assert.ok(Math.abs(mean[0] + 0.5) < 1e-7 && Math.abs(mean[1] - 1) < 1e-7 && Math.abs(mean[2] - 0.1767766953) < 1e-7, `${mean}`);
        assert.ok(Math.abs(cov[0] - 0.140625) < 1e-8 && Math.abs(cov[3] - 0.0625) < 1e-8 && Math.abs(cov[5] - 0.0078125) < 1e-8, `${cov}`);
        const refused = readFileSync(join(results, 'invalid-zero-rotation', 'refused'), 'utf8');
        assert.match(refused, /ROTATION_NOT_UNIT/);
        // --rotation-scale dumps rotation + scale pairs instead of covariances
        const rs = join(root, 'results-rs');
        await runSuite(join(root, 'suite'), rs, { rotationScale: true, cases: 'example-*' });
        assert.ok(existsSync(join(rs, 'example-1', 'pose_001.rotation.f32')));
        assert.ok(!existsSync(join(rs, 'example-1', 'pose_001.cov.f32')));
        assert.ok(!existsSync(join(rs, 'invalid-zero-rotation')));
    } finally {
        rmSync(root, { recursive: true, force: true });
    }
});

test('writeCaseResults: .f64 for Float64Array, error next to dumps, glob matching', () => {
    const root = mkdtempSync(join(tmpdir(), 'gsverse-web-dump-'));
    try {
        const dir = writeCaseResults(root, 'c', { rest: { means: Float64Array.from([1, 2, 3]) }, poses: [{ means: new Float32Array(3) }], error: 'boom' });
        assert.equal(readFileSync(join(dir, 'rest.means.f64')).byteLength, 24);
        assert.equal(new Float64Array(new Uint8Array(readFileSync(join(dir, 'rest.means.f64'))).buffer)[2], 3);
        assert.ok(existsSync(join(dir, 'pose_000.means.f32')));
        assert.equal(readFileSync(join(dir, 'error'), 'utf8'), 'boom\n');
    } finally {
        rmSync(root, { recursive: true, force: true });
    }
    assert.ok(matchesGlob('local-affine-stretch', 'local-*'));
    assert.ok(matchesGlob('games-x', undefined));
    assert.ok(!matchesGlob('games-x', 'local-*'));
    assert.ok(matchesGlob('a.b', 'a.?'));
    assert.ok(!matchesGlob('axb', 'a.b'));
    void KHR; void EXT;
});
