#!/usr/bin/env node
// The conformance harness of the CPU path, in Node:
//   node conformance/run-node.mjs SUITE RESULTS [--json] [--cases GLOB] [--rotation-scale] [--fault NAME]
// imports every case of SUITE/suite.json with readAnchoredGlb (SPZ-compressed rest poses
// expanded first by expandCompressed), remaps every pose with
// remapCpu and writes the dump layout of spec/conformance.md into RESULTS; then
// `gsverse-conformance check SUITE RESULTS` judges it. The poses of a rig case come from the
// asset's own animation, sampled by src/animation.js (conformance/rig-pose.js). --rotation-scale
// dumps rotation + scale pairs instead of covariances. --fault NAME breaks the animation on
// purpose (ANIMATION_FAULTS of src/animation.js) or the SPZ decoding (SPZ_FAULTS of src/spz.js). --json prints a JSON summary instead of a
// line per case.

import { readFileSync } from 'node:fs';
import { join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';

import { readAnchoredGlb, AnchorError } from '../src/anchor.js';
import { readAnchorAnimation } from '../src/animation.js';
import { SPZ_FAULTS, expandCompressed } from '../src/spz.js';
import { computeRest } from '../src/rest.js';
import { remapCpu, remapCpuRotationScale } from '../src/remap-cpu.js';
import { matchesGlob, readF32, readSuite, writeCaseResults, writeHarness } from './dump.mjs';
import { rigPose } from './rig-pose.js';

/** @typedef {import('./dump.mjs').CaseResults} CaseResults */
/** @typedef {import('./dump.mjs').DumpArrays} DumpArrays */

/**
 * Run the CPU path over one case.
 * @param {string} folder  the case folder
 * @param {any} manifest
 * @param {{rotationScale?: boolean, fault?: string|null}} [options]
 * @returns {Promise<CaseResults & {code?: string}>}
 */
export async function runCase(folder, manifest, options = {}) {
    let glb;
    /** @type {import('../src/animation.js').AnchorAnimation|null} */
    let animation = null;
    const rig = manifest.kind === 'rig';
    try {
        const spzFault = SPZ_FAULTS.includes(options.fault ?? '') ? options.fault : null;
        const bytes = await expandCompressed(readFileSync(join(folder, manifest.files.asset)), { name: manifest.files.asset, fault: spzFault });
        glb = readAnchoredGlb(bytes, { name: manifest.files.asset });
        if (rig && glb.anchored.length === 1) {
            animation = readAnchorAnimation(bytes, glb.anchored[0], { name: manifest.files.asset, fault: spzFault ? null : options.fault ?? null });
        }
    } catch (err) {
        if (err instanceof AnchorError) return { refused: `${err.code}: ${err.message}`, code: err.code };
        return { error: `import failed: ${err instanceof Error ? err.stack : String(err)}` };
    }
    /** @type {CaseResults} */
    const results = {};
    try {
        if (glb.anchored.length !== 1) throw new Error(`expected one anchored splat primitive, found ${glb.anchored.length}`);
        const prim = glb.anchored[0];
        results.rest = {
            means: prim.rest.means, rotation: prim.rest.rotations, scale: prim.rest.scales,
            opacity: prim.rest.opacity, sh: prim.rest.sh,
        };
        const rest = computeRest(prim);
        results.poses = [];
        const count = rig ? manifest.poses.length : (manifest.files.poses || []).length;
        for (let p = 0; p < count; ++p) {
            const vertices = rig ? rigPose(animation, manifest.poses[p].source) : readF32(join(folder, manifest.files.poses[p]));
            if (options.rotationScale) {
                const r = remapCpuRotationScale(prim, rest, vertices);
                results.poses.push({ means: r.means, rotation: r.rotations, scale: r.scales });
            } else {
                const r = remapCpu(prim, rest, vertices);
                results.poses.push({ means: r.means, cov: r.cov });
            }
        }
        // opacity and SH pass through the remap unchanged
        results.posed = { opacity: prim.rest.opacity, sh: prim.rest.sh };
    } catch (err) {
        results.error = `${err instanceof Error ? err.stack : String(err)}`;
    }
    return results;
}

/**
 * Run every case of a suite and write RESULTS.
 * @param {string} suiteDir
 * @param {string} resultsDir
 * @param {{rotationScale?: boolean, fault?: string|null, cases?: string, log?: (line: string) => void}} [options]
 * @returns {Promise<{id: string, kind: string, outcome: string, code?: string, expected?: string}[]>}
 */
export async function runSuite(suiteDir, resultsDir, options = {}) {
    const pkg = JSON.parse(readFileSync(new URL('../package.json', import.meta.url), 'utf8'));
    writeHarness(resultsDir, {
        name: '@gsverse/web CPU path (remap-cpu.js)',
        version: pkg.version,
        engine: 'node',
        engine_version: process.version,
        backend: 'CPU (JavaScript)',
        precision: 'binary64 arithmetic (rest and per-frame), float32 outputs',
        dump: options.rotationScale ? 'rotation+scale' : 'cov',
        fault: options.fault || null,
    });
    const log = options.log || (() => {});
    /** @type {{id: string, kind: string, outcome: string, code?: string, expected?: string}[]} */
    const summary = [];
    for (const { folder, manifest } of readSuite(suiteDir)) {
        if (!matchesGlob(manifest.id, options.cases)) continue;
        const t0 = performance.now();
        const results = await runCase(folder, manifest, options);
        writeCaseResults(resultsDir, manifest.id, results);
        const outcome = results.refused !== undefined ? 'refused' : results.error !== undefined ? 'error' : 'remapped';
        const entry = { id: manifest.id, kind: manifest.kind, outcome, code: results.code, expected: manifest.validator_code };
        summary.push(entry);
        const codeNote = entry.code ? ` ${entry.code}${entry.expected && entry.expected !== entry.code ? ` (manifest: ${entry.expected})` : ''}` : '';
        log(`${outcome.padEnd(8)} ${manifest.id}${codeNote} ${(performance.now() - t0).toFixed(0)} ms`);
    }
    return summary;
}

async function main() {
    const args = process.argv.slice(2);
    const flags = new Set(args.filter((a) => a.startsWith('--') && a !== '--cases' && a !== '--fault'));
    const casesAt = args.indexOf('--cases');
    const cases = casesAt >= 0 ? args[casesAt + 1] : undefined;
    const faultAt = args.indexOf('--fault');
    const fault = faultAt >= 0 ? args[faultAt + 1] : undefined;
    const positional = args.filter((a, i) => !a.startsWith('--') && (casesAt < 0 || i !== casesAt + 1) && (faultAt < 0 || i !== faultAt + 1));
    if (positional.length !== 2) {
        process.stderr.write('usage: node conformance/run-node.mjs SUITE RESULTS [--json] [--cases GLOB] [--rotation-scale] [--fault NAME]\n');
        process.exit(2);
    }
    const [suiteDir, resultsDir] = positional.map((p) => resolve(p));
    const json = flags.has('--json');
    const summary = await runSuite(suiteDir, resultsDir, {
        rotationScale: flags.has('--rotation-scale'),
        fault: fault || null,
        cases,
        log: json ? undefined : (line) => process.stdout.write(`${line}\n`),
    });
    const count = (/** @type {string} */ o) => summary.filter((s) => s.outcome === o).length;
    const totals = { cases: summary.length, remapped: count('remapped'), refused: count('refused'), errors: count('error') };
    if (json) process.stdout.write(`${JSON.stringify({ results: resultsDir, ...totals, cases: summary }, null, 1)}\n`);
    else process.stdout.write(`${totals.cases} cases: ${totals.remapped} remapped, ${totals.refused} refused, ${totals.errors} errors -> ${resultsDir}\n`);
    process.exit(totals.errors ? 1 : 0);
}

if (process.argv[1] && resolve(process.argv[1]) === fileURLToPath(import.meta.url)) main();
