// KHR_gaussian_splatting_compression_spz_2 (src/spz.js): the decoded rest pose equals the
// Python reader's number for number (an asset of gsverse-convert --compress spz, random streams
// of versions 2 and 3), the expanded asset reads as a plain one, every refusal with the Python
// reader's code, a gzip bomb stopped after its first slices, truncated streams.
import test from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync, spawnSync } from 'node:child_process';
import { existsSync, mkdtempSync, readFileSync, rmSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { fileURLToPath } from 'node:url';
import { gzipSync, deflateRawSync, constants } from 'node:zlib';

import { AnchorError, readAnchoredGlb } from '../src/anchor.js';
import { parseGlb, parseGltf, dequantize } from '../src/glb.js';
import {
    SPZ_EXTENSION, decodeSpz, expandCompressed, inflateBounded, inflateSliced, parseSpzHeader, streamLimit,
} from '../src/spz.js';
import { KHR, EXT } from './glb-writer.mjs';
import { launchPage, timeScale } from '../conformance/run-browser.mjs';

const repoPython = fileURLToPath(new URL('../../../.venv/bin/python', import.meta.url));

/** A Python that imports gsverse_format: the repository's .venv, else python3 on PATH. */
function findPython() {
    if (process.env.GSVERSE_PYTHON) return process.env.GSVERSE_PYTHON;
    if (existsSync(repoPython)) return repoPython;
    const probe = spawnSync('python3', ['-c', 'import gsverse_format'], { encoding: 'utf8' });
    return probe.status === 0 ? 'python3' : null;
}

const python = findPython();
const skip = python ? false : 'no Python with gsverse_format to make the fixtures';
const dir = python ? mkdtempSync(join(tmpdir(), 'gsverse-spz-')) : '';
if (python) execFileSync(python, [fileURLToPath(new URL('./spz_fixtures.py', import.meta.url)), dir], { stdio: 'inherit' });
test.after(() => { if (dir) rmSync(dir, { recursive: true, force: true }); });

/** @param {string} name */
const f32 = (name) => { const b = readFileSync(join(dir, name)); return new Float32Array(b.buffer, b.byteOffset, b.byteLength / 4); };

/** @param {ArrayLike<number>} actual @param {ArrayLike<number>} expected @param {string} what */
function same(actual, expected, what) {
    assert.equal(actual.length, expected.length, `${what}: length`);
    for (let i = 0; i < expected.length; ++i) {
        if (!Object.is(actual[i], expected[i]) && actual[i] !== expected[i]) assert.fail(`${what}[${i}]: ${actual[i]} vs Python ${expected[i]}`);
    }
}

/** The capsule asset's JSON and binary chunk. */
function capsule() {
    const { json, bin } = parseGlb(new Uint8Array(readFileSync(join(dir, 'capsule-spz.glb'))));
    return { json: JSON.parse(new TextDecoder().decode(json)), bin: /** @type {Uint8Array} */ (bin) };
}

/**
 * A GLB of `json` whose SPZ buffer view holds `payload` (appended to `bin`).
 * @param {any} json @param {Uint8Array} bin @param {Uint8Array} [payload]
 */
function glb(json, bin, payload) {
    let body = bin;
    if (payload) {
        const offset = Math.ceil(bin.length / 4) * 4;
        body = new Uint8Array(Math.ceil((offset + payload.length) / 4) * 4);
        body.set(bin);
        body.set(payload, offset);
        json.bufferViews.push({ buffer: 0, byteOffset: offset, byteLength: payload.length });
        spzObject(json).bufferView = json.bufferViews.length - 1;
        json.buffers[0].byteLength = body.length;
    }
    const text = new TextEncoder().encode(JSON.stringify(json));
    const jsonLen = Math.ceil(text.length / 4) * 4;
    const out = new Uint8Array(28 + jsonLen + body.length);
    const dv = new DataView(out.buffer);
    dv.setUint32(0, 0x46546c67, true); dv.setUint32(4, 2, true); dv.setUint32(8, out.length, true);
    dv.setUint32(12, jsonLen, true); dv.setUint32(16, 0x4e4f534a, true);
    out.fill(0x20, 20, 20 + jsonLen); out.set(text, 20);
    dv.setUint32(20 + jsonLen, body.length, true); dv.setUint32(24 + jsonLen, 0x004e4942, true);
    out.set(body, 28 + jsonLen);
    return out;
}

/** @param {any} json */
const khrOf = (json) => json.meshes[0].primitives[0].extensions[KHR];
/** @param {any} json */
const spzObject = (json) => khrOf(json).extensions[SPZ_EXTENSION];

/** The capsule's inflated SPZ stream. */
async function capsuleStream() {
    const { json, bin } = capsule();
    const v = json.bufferViews[spzObject(json).bufferView];
    return inflateBounded(bin.subarray(v.byteOffset || 0, (v.byteOffset || 0) + v.byteLength), streamLimit(3000), 'capsule');
}

/** @param {Uint8Array} bytes @param {string} code @param {RegExp} [message] */
async function refuses(bytes, code, message) {
    await assert.rejects(expandCompressed(bytes, { name: 'case.glb' }), (/** @type {any} */ err) => {
        assert.ok(err instanceof AnchorError, `an AnchorError, got ${err}`);
        assert.equal(err.code, code, err.message);
        assert.ok(err.message.startsWith('case.glb: '), err.message);
        assert.ok(!err.message.includes('\n'), 'one line');
        if (message) assert.match(err.message, message);
        return true;
    });
}

test('a compressed asset expands to the rest pose the Python reader decodes, and reads as a plain one', { skip }, async () => {
    const bytes = new Uint8Array(readFileSync(join(dir, 'capsule-spz.glb')));
    assert.throws(() => readAnchoredGlb(bytes, { name: 'c.glb' }), (/** @type {any} */ err) => {
        assert.equal(err.code, 'UNSUPPORTED_REQUIRED_EXTENSION');
        assert.match(err.message, /expandCompressed/);
        return true;
    });
    const expanded = await expandCompressed(bytes, { name: 'c.glb' });
    const doc = parseGltf(expanded);
    const prim = doc.json.meshes[0].primitives[0];
    assert.equal(khrOf(doc.json).extensions[SPZ_EXTENSION], undefined);
    assert.ok(khrOf(doc.json).extensions[EXT], 'the anchor extension stays');
    assert.ok(!(doc.json.extensionsUsed || []).includes(SPZ_EXTENSION));
    assert.ok(!(doc.json.extensionsRequired || []).includes(SPZ_EXTENSION));
    /** @param {string} name */
    const values = (name) => Float32Array.from(dequantize(doc.raw(prim.attributes[name], name)));
    same(values('POSITION'), f32('capsule.means.f32'), 'POSITION');
    same(values(`${KHR}:ROTATION`), f32('capsule.rotations.f32'), 'ROTATION');
    same(values(`${KHR}:SCALE`), f32('capsule.scales.f32'), 'SCALE');
    same(values(`${KHR}:OPACITY`), f32('capsule.opacity.f32'), 'OPACITY');
    const sh = f32('capsule.sh.f32');
    for (let k = 0; k < 4; ++k) {
        const l = Math.floor(Math.sqrt(k));
        const expected = new Float32Array(3000 * 3);
        for (let i = 0; i < 3000; ++i) for (let c = 0; c < 3; ++c) expected[3 * i + c] = sh[(4 * i + k) * 3 + c];
        same(values(`${KHR}:SH_DEGREE_${l}_COEF_${k - l * l}`), expected, `SH ${k}`);
    }
    const pos = doc.json.accessors[prim.attributes.POSITION];
    const means = f32('capsule.means.f32');
    for (let c = 0; c < 3; ++c) {
        let lo = Infinity;
        for (let i = c; i < means.length; i += 3) lo = Math.min(lo, means[i]);
        assert.equal(pos.min[c], lo);
    }
    // the expanded asset is a plain one: its derived anchors come from the decoded values
    const read = readAnchoredGlb(expanded, { name: 'c.glb' }).anchored[0];
    assert.equal(read.count, 3000);
    assert.equal(read.derived, true);
    same(read.rest.means, means, 'rest.means');
    // an asset without compressed primitives comes back as it is
    assert.equal(await expandCompressed(expanded), expanded);
});

for (const version of [2, 3]) {
    test(`a random version-${version} stream decodes as the Python decoder does`, { skip }, async () => {
        const raw = new Uint8Array(readFileSync(join(dir, `random-v${version}.spz`)));
        const data = await inflateBounded(raw, streamLimit(64), 'random');
        const h = parseSpzHeader(data, 'random');
        assert.equal(h.version, version);
        const s = decodeSpz(data, h);
        same(s.means, f32(`random-v${version}.means.f32`), 'means');
        same(s.rotations, f32(`random-v${version}.rotations.f32`), 'rotations');
        same(s.scales, f32(`random-v${version}.scales.f32`), 'scales');
        same(s.opacity, f32(`random-v${version}.opacity.f32`), 'opacity');
        same(s.sh, f32(`random-v${version}.sh.f32`), 'sh');
    });
}

test('zero padding after the gzip member is allowed', { skip }, async () => {
    const { json, bin } = capsule();
    const v = json.bufferViews[spzObject(json).bufferView];
    const member = bin.slice(v.byteOffset || 0, (v.byteOffset || 0) + v.byteLength);
    const padded = new Uint8Array(member.length + 7);
    padded.set(member);
    const expanded = await expandCompressed(glb(json, bin, padded), { name: 'case.glb' });
    const doc = parseGltf(expanded);
    same(Float32Array.from(dequantize(doc.raw(doc.json.meshes[0].primitives[0].attributes.POSITION, 'p'))), f32('capsule.means.f32'), 'POSITION');
});

test('broken, truncated and trailing gzip data are refused (SPZ_STREAM_INVALID)', { skip }, async () => {
    const { json, bin } = capsule();
    const v = json.bufferViews[spzObject(json).bufferView];
    const member = bin.slice(v.byteOffset || 0, (v.byteOffset || 0) + v.byteLength);
    const cases = [
        ['not gzip', new TextEncoder().encode('not a gzip member at all')],
        ['truncated member', member.subarray(0, member.length >> 1)],
        ['member without its trailer', member.subarray(0, member.length - 4)],
        ['junk after the member', new Uint8Array([...member, 1, 2, 3])],
        ['a second member', new Uint8Array([...member, ...gzipSync(new Uint8Array(16))])],
    ];
    for (const [what, payload] of cases) {
        await refuses(glb(capsule().json, bin, /** @type {Uint8Array} */ (payload)), 'SPZ_STREAM_INVALID', undefined).catch((err) => { throw new Error(`${what}: ${err.message}`); });
    }
});

test('stream contents the extension refuses', { skip }, async () => {
    const data = await capsuleStream();
    /** @param {(d: Uint8Array) => Uint8Array} edit @returns {Uint8Array} */
    const withStream = (edit) => { const { json, bin } = capsule(); return glb(json, bin, gzipSync(edit(data.slice()))); };
    const dvEdit = (/** @type {(dv: DataView) => void} */ f) => (/** @type {Uint8Array} */ d) => { f(new DataView(d.buffer)); return d; };
    await refuses(withStream(dvEdit((dv) => dv.setUint32(0, 0x12345678, true))), 'SPZ_STREAM_INVALID', /magic/);
    await refuses(withStream(dvEdit((dv) => dv.setUint32(4, 4, true))), 'SPZ_STREAM_INVALID', /version 4/);
    await refuses(withStream(dvEdit((dv) => dv.setUint8(14, 2))), 'SPZ_STREAM_INVALID', /flag bit 1/);
    await refuses(withStream(dvEdit((dv) => dv.setUint8(13, 25))), 'SPZ_STREAM_INVALID', /fractional bits/);
    await refuses(withStream((d) => d.subarray(0, d.length - 10)), 'SPZ_STREAM_INVALID', /inflates to/);      // truncated stream
    await refuses(withStream((d) => new Uint8Array([...d, 0, 0, 0])), 'SPZ_STREAM_INVALID', /inflates to/);   // longer than its splats need
    await refuses(withStream((d) => d.subarray(0, 10)), 'SPZ_STREAM_INVALID', /header/);
    await refuses(withStream(dvEdit((dv) => dv.setUint32(8, 2999, true))), 'SPZ_COUNT_MISMATCH', /2999/);
    await refuses(withStream(dvEdit((dv) => dv.setUint8(12, 2))), 'SPZ_SH_MISMATCH', /degree 2/);
});

test('placeholders and extension objects the reader refuses', { skip }, async () => {
    const { bin } = capsule();
    /** @param {(json: any) => void} edit */
    const edited = (edit) => { const { json } = capsule(); edit(json); return glb(json, bin); };
    const attrs = (/** @type {any} */ json) => json.meshes[0].primitives[0].attributes;
    await refuses(edited((json) => { json.accessors[attrs(json).COLOR_0].count = 2999; }), 'SPZ_COUNT_MISMATCH', /COLOR_0/);
    await refuses(edited((json) => { for (let n = 0; n < 3; ++n) delete attrs(json)[`${KHR}:SH_DEGREE_1_COEF_${n}`]; }), 'SPZ_SH_MISMATCH');
    await refuses(edited((json) => { spzObject(json).bufferView = 999; }), 'SPZ_BUFFER_VIEW_INVALID');
    await refuses(edited((json) => { delete spzObject(json).bufferView; }), 'SPZ_BUFFER_VIEW_INVALID');
    await refuses(edited((json) => { khrOf(json).extensions[SPZ_EXTENSION] = 3; }), 'SPZ_BUFFER_VIEW_INVALID');
    await refuses(edited((json) => { khrOf(json).extensions[EXT].barycentrics = attrs(json).POSITION; }), 'SPZ_EXPLICIT_ANCHORS');
    await refuses(edited((json) => { khrOf(json).extensions[EXT].profile = 'games'; }), 'SPZ_EXPLICIT_ANCHORS');
    // more splats than the stream's bytes can hold: refused before anything is inflated
    await refuses(edited((json) => { for (const a of Object.values(attrs(json))) json.accessors[a].count = 50_000_000; }), 'SIZE_LIMIT_EXCEEDED');
});

/**
 * A gzip member of 1 GiB of zeros: a deflate block of 16 MiB of zeros ending on a byte boundary
 * (sync flush), repeated 64 times, then an empty final block and a (wrong) trailer.
 */
function gzipBomb() {
    const block = deflateRawSync(new Uint8Array(1 << 24), { finishFlush: constants.Z_SYNC_FLUSH });
    const parts = [new Uint8Array([0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 255])];
    for (let i = 0; i < 64; ++i) parts.push(block);
    parts.push(new Uint8Array([3, 0]), new Uint8Array(8));
    const bomb = new Uint8Array(parts.reduce((n, p) => n + p.length, 0));
    let o = 0;
    for (const p of parts) { bomb.set(p, o); o += p.length; }
    return bomb;
}

test('a gzip bomb is stopped after its first slices, never inflated whole', { skip }, async () => {
    const bomb = gzipBomb();
    const limit = streamLimit(3000);
    const run = await inflateSliced(bomb, limit);
    assert.equal(run.over, true);
    assert.equal(run.out.length, 0);
    assert.ok(run.fed < bomb.length / 4, `fed ${run.fed} of ${bomb.length} compressed bytes`);
    const { json, bin } = capsule();
    await refuses(glb(json, bin, bomb), 'SPZ_STREAM_INVALID', new RegExp(`more than the ${limit} bytes`));
});

const chromium = process.env.CHROMIUM || '/usr/bin/chromium';

test('in Chromium: the same expanded bytes, zero padding accepted, junk and a bomb refused', {
    skip: skip || (existsSync(chromium) ? false : `no Chromium at ${chromium}`), timeout: 120_000 * timeScale(),
}, async () => {
    const { json, bin } = capsule();
    const v = json.bufferViews[spzObject(json).bufferView];
    const member = bin.slice(v.byteOffset || 0, (v.byteOffset || 0) + v.byteLength);
    const padded = new Uint8Array(member.length + 7);
    padded.set(member);
    writeFileSync(join(dir, 'padded.glb'), glb(capsule().json, bin, padded));
    writeFileSync(join(dir, 'junk.glb'), glb(capsule().json, bin, new Uint8Array([...member, 1, 2, 3])));
    writeFileSync(join(dir, 'bomb.glb'), glb(capsule().json, bin, gzipBomb()));
    const browser = await launchPage({ page: 'conformance/page/render.html', extraMounts: { '/assets/': dir } });
    try {
        const got = await browser.page.evaluate(async () => {
            const url = '/pkg/src/spz.js';     // the package as the page's server mounts it
            const { expandCompressed } = await import(url);
            /** @param {string} name */
            const run = async (name) => {
                const bytes = new Uint8Array(await (await fetch(`/assets/${name}`)).arrayBuffer());
                try {
                    const out = await expandCompressed(bytes, { name });
                    let s = '';
                    for (let i = 0; i < out.length; i += 0x8000) s += String.fromCharCode(...out.subarray(i, i + 0x8000));
                    return { b64: btoa(s) };
                } catch (err) {
                    return { code: /** @type {any} */ (err).code, message: /** @type {any} */ (err).message };
                }
            };
            return { capsule: await run('capsule-spz.glb'), padded: await run('padded.glb'), junk: await run('junk.glb'), bomb: await run('bomb.glb') };
        });
        const expected = await expandCompressed(new Uint8Array(readFileSync(join(dir, 'capsule-spz.glb'))));
        assert.deepEqual(new Uint8Array(Buffer.from(got.capsule.b64 ?? '', 'base64')), expected, got.capsule.message);
        const padExpected = await expandCompressed(new Uint8Array(readFileSync(join(dir, 'padded.glb'))));
        assert.deepEqual(new Uint8Array(Buffer.from(got.padded.b64 ?? '', 'base64')), padExpected, got.padded.message);
        assert.equal(got.junk.code, 'SPZ_STREAM_INVALID', got.junk.message);
        assert.equal(got.bomb.code, 'SPZ_STREAM_INVALID', got.bomb.message);
        assert.match(got.bomb.message, /more than the \d+ bytes/);
    } finally {
        await browser.close();
    }
});
