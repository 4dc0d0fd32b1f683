// The conformance suite's files and dump layout (spec/conformance.md §The suite: files and
// manifests, §The harness and the dump layout), shared by the Node (CPU) and browser (GPU)
// runners. Arrays are raw little-endian without header: Float32Array -> .f32,
// Float64Array -> .f64.

import { mkdirSync, readFileSync, writeFileSync } from 'node:fs';
import { join } from 'node:path';

/**
 * Arrays of one dump ("rest", "pose_NNN" or "posed"): means and either cov or rotation +
 * scale; opacity and sh where the dump has them.
 * @typedef {object} DumpArrays
 * @property {Float32Array|Float64Array} [means]     (N, 3)
 * @property {Float32Array|Float64Array} [cov]       (N, 6) xx, xy, xz, yy, yz, zz
 * @property {Float32Array|Float64Array} [rotation]  (N, 4) x, y, z, w
 * @property {Float32Array|Float64Array} [scale]     (N, 3)
 * @property {Float32Array|Float64Array} [opacity]   (N,)
 * @property {Float32Array|Float64Array} [sh]        (N, K, 3)
 */

/**
 * Everything a harness writes for one case.
 * @typedef {object} CaseResults
 * @property {string} [refused]   the importer's message: the asset was refused
 * @property {string} [error]     the harness itself failed on this case
 * @property {DumpArrays} [rest]  imported rest pose: means, cov or rotation + scale, opacity, sh
 * @property {DumpArrays[]} [poses]  per pose file, in manifest order: means, cov or rotation + scale
 * @property {DumpArrays} [posed] opacity and sh after the last pose
 */

const LITTLE_ENDIAN = new Uint8Array(new Uint16Array([1]).buffer)[0] === 1;

/**
 * Write one array raw little-endian to `stem` + `.f32` or `.f64` (by its type).
 * @param {string} stem
 * @param {Float32Array|Float64Array} array
 */
export function writeArray(stem, array) {
    if (!LITTLE_ENDIAN) throw new Error('dump.mjs writes little-endian arrays on little-endian hosts only');
    const ext = array instanceof Float64Array ? '.f64' : '.f32';
    const data = array instanceof Float64Array || array instanceof Float32Array ? array : Float32Array.from(array);
    writeFileSync(stem + ext, new Uint8Array(data.buffer, data.byteOffset, data.byteLength));
}

/**
 * Write the arrays of one dump: `<folder>/<prefix>.<key>.f32|f64`.
 * @param {string} folder
 * @param {string} prefix  "rest", "pose_000", ..., "posed"
 * @param {DumpArrays} arrays
 */
export function writeDump(folder, prefix, arrays) {
    for (const [key, value] of Object.entries(arrays)) {
        if (value) writeArray(join(folder, `${prefix}.${key}`), value);
    }
}

/**
 * The dump prefix of pose `index`: pose_000, pose_001, ...
 * @param {number} index
 */
export function posePrefix(index) {
    return `pose_${String(index).padStart(3, '0')}`;
}

/**
 * Write a case's results into `RESULTS/<id>/` in the dump layout: `refused`, or `error`, or the
 * rest, pose and posed dumps (an `error` is written next to the dumps when both are given).
 * @param {string} resultsDir
 * @param {string} id
 * @param {CaseResults} results
 * @returns {string} the case folder
 */
export function writeCaseResults(resultsDir, id, results) {
    const folder = join(resultsDir, id);
    mkdirSync(folder, { recursive: true });
    if (results.refused !== undefined) {
        writeFileSync(join(folder, 'refused'), `${results.refused}\n`);
        return folder;
    }
    if (results.rest) writeDump(folder, 'rest', results.rest);
    (results.poses || []).forEach((pose, p) => writeDump(folder, posePrefix(p), pose));
    if (results.posed) writeDump(folder, 'posed', results.posed);
    if (results.error !== undefined) writeFileSync(join(folder, 'error'), `${results.error}\n`);
    return folder;
}

/**
 * Write `RESULTS/harness.json` (the report echoes it).
 * @param {string} resultsDir
 * @param {object} info  name, version, engine, backend, precision, ...
 */
export function writeHarness(resultsDir, info) {
    mkdirSync(resultsDir, { recursive: true });
    writeFileSync(join(resultsDir, 'harness.json'), `${JSON.stringify(info, null, 1)}\n`);
}

/**
 * Every case of a suite, in suite order.
 * @param {string} suiteDir
 * @returns {{folder: string, manifest: any}[]}
 */
export function readSuite(suiteDir) {
    const index = JSON.parse(readFileSync(join(suiteDir, 'suite.json'), 'utf8'));
    return index.cases.map((/** @type {{path: string}} */ entry) => {
        const folder = join(suiteDir, entry.path);
        return { folder, manifest: JSON.parse(readFileSync(join(folder, 'case.json'), 'utf8')) };
    });
}

/**
 * Every render case of a suite (suite.json `render_cases`; none in suites before the render
 * level), in suite order.
 * @param {string} suiteDir
 * @returns {{folder: string, manifest: any}[]}
 */
export function readRenderSuite(suiteDir) {
    const index = JSON.parse(readFileSync(join(suiteDir, 'suite.json'), 'utf8'));
    return (index.render_cases || []).map((/** @type {{path: string}} */ entry) => {
        const folder = join(suiteDir, entry.path);
        return { folder, manifest: JSON.parse(readFileSync(join(folder, 'case.json'), 'utf8')) };
    });
}

/**
 * A raw little-endian float32 file (a pose: (V, 3) anchor vertices).
 * @param {string} path
 * @returns {Float32Array}
 */
export function readF32(path) {
    const bytes = readFileSync(path);
    const out = new Float32Array(bytes.byteLength / 4);
    new Uint8Array(out.buffer).set(bytes);
    return out;
}

/**
 * Does the case id match a glob (`*` any run of characters, `?` one character)?
 * @param {string} id
 * @param {string|undefined} glob
 */
export function matchesGlob(id, glob) {
    if (!glob) return true;
    const re = new RegExp(`^${glob.split('*').map((part) => part.split('?').map((s) => s.replace(/[.+^${}()|[\]\\]/g, '\\$&')).join('.')).join('.*')}$`);
    return re.test(id);
}
