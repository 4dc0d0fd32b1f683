#!/usr/bin/env node
// The conformance harness of the GPU path, in a real browser:
//   node conformance/run-browser.mjs SUITE RESULTS [--engine playcanvas|three] [--level numbers|render|all]
//                                    [--fault NAME] [--cases GLOB] [--backend webgl2|webgpu] [--json]
// serves the package and SUITE on localhost, starts headless Chromium (playwright-core, the
// system /usr/bin/chromium or $CHROMIUM, WebGL2 through ANGLE/SwiftShader when there is no GPU),
// imports every case with the PlayCanvas plugin, remaps every pose on the GPU with the same
// remap chunk that renders, reads the float32 results back and writes the dump layout of
// spec/conformance.md (rotation + scale dumps) into RESULTS, with `refused` for refusals and
// RESULTS/harness.json naming the engine and the WebGL renderer. The poses of a rig case are
// the asset's own animation sampled in the page (src/animation.js). --fault NAME builds a
// deliberately broken shader (see src/playcanvas/shader.js FAULTS) or animation
// (ANIMATION_FAULTS of src/animation.js). --backend webgpu runs the
// WGSL twin on PlayCanvas's WebGPU device (Chromium's WebGPU, SwiftShader adapter here). Then
// `gsverse-conformance check SUITE RESULTS` judges it.
// The render level (the suite's `render_cases`): every frame of every render case is rendered
// by the engine with the plugin (conformance/page/render-cases.js) and written as
// RESULTS/<id>/frame_NNN.png. --level picks the levels (default: both).
// --engine three runs the same with the three.js plugin (src/three/: Spark's splats, the remap
// as Spark's object modifier, read back by Spark's Readback; WebGL2 only); its faults are
// those of src/three/shader.js FAULTS. Default: playcanvas.

import { mkdirSync, mkdtempSync, readFileSync, rmSync, writeFileSync } from 'node:fs';
import { cpus, loadavg, tmpdir } from 'node:os';
import { join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';

import { chromium } from 'playwright-core';

import { matchesGlob, readRenderSuite, readSuite, writeCaseResults, writeHarness } from './dump.mjs';
import { encodePngRgb } from './png.mjs';
import { startServer } from './server.mjs';

const PKG_DIR = fileURLToPath(new URL('..', import.meta.url));

/** Chromium flags: headless, software WebGL2 (SwiftShader) where there is no GPU, no network. */
export const CHROMIUM_ARGS = [
    '--headless', '--no-sandbox', '--disable-gpu', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
    '--ignore-gpu-blocklist', '--disable-background-networking', '--disable-component-update',
    '--disable-sync', '--no-first-run',
];

/**
 * Chromium flags for a real GPU when there is one (benchmarks): Chromium's own choice of GL
 * backend, the GPU blocklist ignored; SwiftShader only as its fallback (the renderer string
 * then says so).
 */
export const GPU_ARGS = CHROMIUM_ARGS.filter((a) => a !== '--disable-gpu' && a !== '--use-angle=swiftshader');

/**
 * The pages of each engine plugin: numbers level, render level, and how harness.json names it.
 * @type {{[engine: string]: {numbers: string, render: string, name: (device: string) => string, dump: string}}}
 */
export const ENGINES = {
    playcanvas: {
        numbers: 'conformance/page/index.html',
        render: 'conformance/page/render-cases.html',
        name: (device) => `@gsverse/web PlayCanvas plugin (GPU remap, src/playcanvas/${device === 'webgpu' ? 'shader-wgsl.js, WGSL' : 'shader.js, GLSL'})`,
        dump: 'rotation+scale read back from the GPU (RGBA32F); rest, opacity and SH from the importer',
    },
    three: {
        numbers: 'conformance/page/three.html',
        render: 'conformance/page/three-render-cases.html',
        name: () => '@gsverse/web three.js plugin (GPU remap as a Spark object modifier, src/three/shader.js, GLSL)',
        dump: "rotation+scale read back from the GPU (Spark's Readback, float32 bits as RGBA8); rest, opacity and SH from the importer",
    },
};

/** Extra flags for WebGPU (software adapter when there is no GPU). */
export const WEBGPU_ARGS = ['--enable-unsafe-webgpu', '--use-webgpu-adapter=swiftshader'];

/**
 * How much longer than on an idle machine browser work may take here: $GSVERSE_TIME_SCALE when
 * set (the test runners pass theirs on), else the one-minute load average per CPU core, at
 * least 1 and at most 8. Time limits of the browser runs and their tests are multiplied by it,
 * so a busy machine is slower, not failing.
 */
export function timeScale() {
    const fromEnv = Number(process.env.GSVERSE_TIME_SCALE);
    const scale = Number.isFinite(fromEnv) && fromEnv > 0 ? fromEnv : loadavg()[0] / Math.max(1, cpus().length);
    return Math.min(8, Math.max(1, scale));
}

/** Attempts at starting Chromium: a start that fails (a busy machine, a crashed helper process) is retried. */
const LAUNCH_ATTEMPTS = 3;

/**
 * Start headless Chromium with a fresh profile, retrying a failed start (only the start: a
 * failure after the browser is up is reported as it is).
 * @param {boolean} webgpu
 * @param {boolean} [gpu]  GPU_ARGS: a real GPU where there is one
 * @returns {Promise<{context: import('playwright-core').BrowserContext, userDataDir: string}>}
 */
async function launchBrowser(webgpu, gpu = false) {
    let lastError = null;
    for (let attempt = 1; attempt <= LAUNCH_ATTEMPTS; ++attempt) {
        const userDataDir = mkdtempSync(join(tmpdir(), 'gsverse-chromium-'));
        try {
            const context = await chromium.launchPersistentContext(userDataDir, {
                executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
                headless: true,
                args: gpu ? GPU_ARGS : webgpu ? [...CHROMIUM_ARGS, ...WEBGPU_ARGS] : CHROMIUM_ARGS,
                viewport: { width: 256, height: 256 },
                timeout: 60000 * timeScale(),
            });
            return { context, userDataDir };
        } catch (err) {
            lastError = err;
            rmSync(userDataDir, { recursive: true, force: true });
            if (attempt < LAUNCH_ATTEMPTS) await new Promise((r) => setTimeout(r, 1000 * attempt));
        }
    }
    throw new Error(`Chromium did not start (${LAUNCH_ATTEMPTS} attempts): ${lastError instanceof Error ? lastError.message.split('\n')[0] : lastError}`);
}

/**
 * Start the static server and headless Chromium on a page of this package.
 * @param {{suiteDir?: string, page?: string, extraMounts?: {[prefix: string]: string}, webgpu?: boolean, gpu?: boolean}} options
 *   page: path under the package, e.g. 'conformance/page/index.html'; gpu: GPU_ARGS (benchmarks)
 * @returns {Promise<{page: import('playwright-core').Page, url: string, close: () => Promise<void>}>}
 */
export async function launchPage(options) {
    /** @type {{[prefix: string]: string}} */
    const mounts = { '/pkg/': PKG_DIR, ...(options.extraMounts || {}) };
    if (options.suiteDir) mounts['/suite/'] = options.suiteDir;
    const server = await startServer(mounts);
    /** @type {import('playwright-core').BrowserContext} */
    let context;
    /** @type {string} */
    let userDataDir;
    try {
        ({ context, userDataDir } = await launchBrowser(!!options.webgpu, !!options.gpu));
    } catch (err) {
        await server.close();
        throw err;
    }
    const close = async () => {
        await context.close();
        await server.close();
        rmSync(userDataDir, { recursive: true, force: true });
    };
    const page = context.pages()[0] || await context.newPage();
    /** @type {string[]} */
    const consoleErrors = [];
    page.on('console', (msg) => { if (msg.type() === 'error') consoleErrors.push(msg.text()); });
    page.on('pageerror', (err) => consoleErrors.push(String(err)));
    const url = `${server.url}/pkg/${options.page || 'conformance/page/index.html'}`;
    try {
        await page.goto(url, { timeout: 30000 * timeScale() });
        await page.waitForFunction(() => /** @type {any} */ (window).gsvReady === true, null, { timeout: 30000 * timeScale() });
    } catch (err) {
        await close();
        throw new Error(`the page did not start: ${consoleErrors.join(' | ') || err}`);
    }
    return { page, url, close };
}

/** @param {string} b64 */
function f32(b64) {
    const bytes = Buffer.from(b64, 'base64');
    const out = new Float32Array(bytes.byteLength / 4);
    new Uint8Array(out.buffer).set(bytes);
    return out;
}

/** @param {any} dump */
function decodeDump(dump) {
    /** @type {{[key: string]: Float32Array}} */
    const out = {};
    for (const [key, value] of Object.entries(dump || {})) out[key] = f32(/** @type {string} */ (value));
    return out;
}

/**
 * @param {string|undefined} engine
 */
function engineOf(engine) {
    const e = ENGINES[engine || 'playcanvas'];
    if (!e) throw new Error(`unknown engine '${engine}' (known: ${Object.keys(ENGINES).join(', ')})`);
    return e;
}

/**
 * Run a suite in the browser and write RESULTS.
 * @param {string} suiteDir
 * @param {string} resultsDir
 * @param {{fault?: string|null, cases?: string, backend?: 'webgl2'|'webgpu', engine?: string, log?: (line: string) => void}} [options]
 */
export async function runSuiteInBrowser(suiteDir, resultsDir, options = {}) {
    const log = options.log || (() => {});
    const t0 = performance.now();
    const backendName = options.backend || 'webgl2';
    const engine = engineOf(options.engine);
    const browser = await launchPage({ suiteDir, page: engine.numbers, webgpu: backendName === 'webgpu' });
    /** @type {{id: string, kind: string, outcome: string, code?: string, ms: number}[]} */
    const summary = [];
    try {
        const backend = await browser.page.evaluate((b) => /** @type {any} */ (window).gsvConformance.init({ backend: b }), backendName);
        const pkg = JSON.parse(readFileSync(join(PKG_DIR, 'package.json'), 'utf8'));
        writeHarness(resultsDir, {
            name: engine.name(backend.device),
            version: pkg.version,
            engine: `${backend.engine} ${backend.engine_version}`,
            backend: `${backend.device}: ${backend.renderer}`,
            renderer: backend.renderer,
            vendor: backend.vendor,
            api: backend.version,
            shading_language: backend.shading_language,
            browser: backend.user_agent,
            precision: `float32 GPU arithmetic (${backend.float_precision}); rest quantities in binary64 on the CPU, uploaded as float32`,
            dump: engine.dump,
            fault: options.fault || null,
        });
        for (const { manifest } of readSuite(suiteDir)) {
            if (!matchesGlob(manifest.id, options.cases)) continue;
            const t1 = performance.now();
            /** @type {import('./dump.mjs').CaseResults & {code?: string}} */
            let results;
            try {
                const r = await browser.page.evaluate(
                    ([path, fault]) => /** @type {any} */ (window).gsvConformance.runCase(path, { fault }),
                    [`cases/${manifest.id}`, options.fault || null]);
                if (r.refused !== undefined) {
                    results = { refused: r.refused, code: r.code };
                } else {
                    results = { rest: decodeDump(r.rest), poses: r.poses.map(decodeDump), posed: decodeDump(r.posed) };
                }
            } catch (err) {
                results = { error: `${err instanceof Error ? err.message : String(err)}` };
            }
            writeCaseResults(resultsDir, manifest.id, results);
            const outcome = results.refused !== undefined ? 'refused' : results.error !== undefined ? 'error' : 'remapped';
            const ms = performance.now() - t1;
            summary.push({ id: manifest.id, kind: manifest.kind, outcome, code: results.code, ms });
            log(`${outcome.padEnd(8)} ${manifest.id}${results.code ? ` ${results.code}` : ''}${results.error ? ` ${results.error.split('\n')[0]}` : ''} ${ms.toFixed(0)} ms`);
        }
        return { backend, summary, seconds: (performance.now() - t0) / 1000 };
    } finally {
        await browser.close();
    }
}

/**
 * Render every render case of a suite in the browser and write RESULTS/<id>/frame_NNN.png
 * (or `refused` / `error`).
 * @param {string} suiteDir
 * @param {string} resultsDir
 * @param {{fault?: string|null, cases?: string, backend?: 'webgl2'|'webgpu', engine?: string, log?: (line: string) => void}} [options]
 */
export async function runRenderCasesInBrowser(suiteDir, resultsDir, options = {}) {
    const log = options.log || (() => {});
    const t0 = performance.now();
    const backendName = options.backend || 'webgl2';
    const cases = readRenderSuite(suiteDir).filter(({ manifest }) => matchesGlob(manifest.id, options.cases));
    /** @type {{id: string, kind: string, outcome: string, code?: string, ms: number}[]} */
    const summary = [];
    if (!cases.length) return { backend: null, summary, seconds: 0 };
    const browser = await launchPage({ suiteDir, page: engineOf(options.engine).render, webgpu: backendName === 'webgpu' });
    try {
        const backend = await browser.page.evaluate((b) => /** @type {any} */ (window).gsvRenderCases.init({ backend: b }), backendName);
        for (const { manifest } of cases) {
            const t1 = performance.now();
            const folder = join(resultsDir, manifest.id);
            rmSync(folder, { recursive: true, force: true });
            mkdirSync(folder, { recursive: true });
            let outcome = 'rendered';
            /** @type {string|undefined} */
            let code;
            try {
                const r = await browser.page.evaluate(
                    ([path, fault, sortWaitMs]) => /** @type {any} */ (window).gsvRenderCases.renderCase(path, { fault, sortWaitMs }),
                    /** @type {[string, string|null, number]} */ ([`cases/${manifest.id}`, options.fault || null, 3000 * timeScale()]));
                if (r.refused !== undefined) {
                    outcome = 'refused';
                    code = r.code;
                    writeFileSync(join(folder, 'refused'), `${r.refused}\n`);
                } else {
                    for (const f of r.frames) {
                        writeFileSync(join(folder, f.name), encodePngRgb(f.width, f.height, new Uint8Array(Buffer.from(f.rgba, 'base64'))));
                    }
                }
            } catch (err) {
                outcome = 'error';
                writeFileSync(join(folder, 'error'), `${err instanceof Error ? err.message : String(err)}\n`);
            }
            const ms = performance.now() - t1;
            summary.push({ id: manifest.id, kind: 'render', outcome, code, ms });
            log(`${outcome.padEnd(8)} ${manifest.id}${code ? ` ${code}` : ''} ${ms.toFixed(0)} ms`);
        }
        return { backend, summary, seconds: (performance.now() - t0) / 1000 };
    } finally {
        await browser.close();
    }
}

async function main() {
    const args = process.argv.slice(2);
    /** @type {{[key: string]: string}} */
    const values = {};
    const flags = new Set();
    /** @type {string[]} */
    const positional = [];
    for (let i = 0; i < args.length; ++i) {
        if (['--fault', '--cases', '--backend', '--level', '--engine'].includes(args[i])) values[args[i]] = args[++i];
        else if (args[i].startsWith('--')) flags.add(args[i]);
        else positional.push(args[i]);
    }
    if (positional.length !== 2) {
        process.stderr.write('usage: node conformance/run-browser.mjs SUITE RESULTS [--engine playcanvas|three] [--level numbers|render|all] [--fault NAME] [--cases GLOB] [--backend webgl2|webgpu] [--json]\n');
        process.exit(2);
    }
    const level = values['--level'] || 'all';
    if (!['numbers', 'render', 'all'].includes(level)) {
        process.stderr.write(`run-browser: --level must be numbers, render or all (got ${level})\n`);
        process.exit(2);
    }
    const engineName = values['--engine'] || 'playcanvas';
    if (!(engineName in ENGINES)) {
        process.stderr.write(`run-browser: --engine must be ${Object.keys(ENGINES).join(' or ')} (got ${engineName})\n`);
        process.exit(2);
    }
    const [suiteDir, resultsDir] = positional.map((p) => resolve(p));
    const json = flags.has('--json');
    const options = {
        fault: values['--fault'] || null,
        cases: values['--cases'],
        backend: /** @type {'webgl2'|'webgpu'} */ (values['--backend'] || 'webgl2'),
        engine: engineName,
        log: json ? undefined : (/** @type {string} */ line) => process.stdout.write(`${line}\n`),
    };
    let backend = null, seconds = 0;
    /** @type {{id: string, kind: string, outcome: string, code?: string, ms: number}[]} */
    const summary = [];
    if (level !== 'render') {
        const run = await runSuiteInBrowser(suiteDir, resultsDir, options);
        ({ backend } = run);
        seconds += run.seconds;
        summary.push(...run.summary);
    }
    if (level !== 'numbers') {
        const run = await runRenderCasesInBrowser(suiteDir, resultsDir, options);
        backend = backend || run.backend;
        seconds += run.seconds;
        summary.push(...run.summary);
        if (level === 'render' && run.backend) {
            writeHarness(resultsDir, { name: `${engineOf(engineName).name(run.backend.device)} (render level)`, engine: `${run.backend.engine} ${run.backend.engine_version}`,
                backend: `${run.backend.device}: ${run.backend.renderer}`, fault: options.fault });
        }
    }
    const count = (/** @type {string} */ o) => summary.filter((s) => s.outcome === o).length;
    const totals = { cases: summary.length, remapped: count('remapped'), rendered: count('rendered'), refused: count('refused'), errors: count('error') };
    if (json) {
        process.stdout.write(`${JSON.stringify({ results: resultsDir, backend, seconds, ...totals, cases: summary }, null, 1)}\n`);
    } else {
        process.stdout.write(`${totals.cases} cases: ${totals.remapped} remapped, ${totals.rendered} rendered, ${totals.refused} refused, ${totals.errors} errors `
            + `in ${seconds.toFixed(1)} s${backend ? ` on ${backend.engine} ${backend.engine_version}, ${backend.device}: ${backend.renderer}` : ''} -> ${resultsDir}\n`);
    }
    process.exit(totals.errors ? 1 : 0);
}

if (process.argv[1] && resolve(process.argv[1]) === fileURLToPath(import.meta.url)) {
    main().catch((err) => {
        process.stderr.write(`${err instanceof Error ? err.stack : String(err)}\n`);
        process.exit(1);
    });
}
