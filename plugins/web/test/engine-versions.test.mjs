// The PlayCanvas versions the plugin supports. package.json's peer range and SUPPORTED_PLAYCANVAS
// (src/playcanvas/engine.js) agree; the default engine (devDependency `playcanvas`) lies in the
// range and the lowest version of the range is installed too (devDependency `playcanvas-lowest`).
// In headless Chromium, against the lowest version: the shipped example renders through the
// work-buffer remap and follows a stretch, like test/gpu-render.test.mjs does with the default
// version (the page is conformance/page/render.html, served with node_modules/playcanvas pointing
// at the engine under test). Against the lowest and the default engine: with an engine member the
// plugin needs taken away for the duration of the check, loadAnchoredAsset throws AnchorError
// ENGINE_UNSUPPORTED naming the running version. An engine reporting a version outside the range
// (the default engine, its version export replaced) with every member present renders, with
// one console warning; a missing member there is still ENGINE_UNSUPPORTED. Browser parts skipped without Chromium or the example asset.
import test from 'node:test';
import assert from 'node:assert/strict';
import { existsSync, mkdirSync, mkdtempSync, readFileSync, rmSync, symlinkSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { fileURLToPath } from 'node:url';

import { launchPage, timeScale } from '../conformance/run-browser.mjs';
import { renderAndStretch } from './render-stretch.mjs';
import { PLAYCANVAS_VERSION, SUPPORTED_PLAYCANVAS, inRange, parseVersion } from '../src/playcanvas/engine.js';

const PKG = fileURLToPath(new URL('..', import.meta.url));
const NM = join(PKG, 'node_modules');
const pkg = JSON.parse(readFileSync(join(PKG, 'package.json'), 'utf8'));
const chromium = process.env.CHROMIUM || '/usr/bin/chromium';
const examples = fileURLToPath(new URL('../../../examples', import.meta.url));
const asset = `${examples}/web/capsule.glb`;
const skip = !existsSync(chromium) ? `no Chromium at ${chromium}` : !existsSync(asset) ? 'no examples/web/capsule.glb' : false;

/** @param {string} dir  an installed engine package @returns {string} its version */
function installedVersion(dir) {
    const file = join(NM, dir, 'package.json');
    assert.ok(existsSync(file), `${dir} is not installed in ${NM}: run 'npm ci' there`);
    const p = JSON.parse(readFileSync(file, 'utf8'));
    assert.equal(p.name, 'playcanvas');
    return p.version;
}

/** The bounds of SUPPORTED_PLAYCANVAS. */
function bounds() {
    const m = /^>=(\d+\.\d+\.\d+) <(\d+\.\d+\.\d+)$/.exec(SUPPORTED_PLAYCANVAS);
    assert.ok(m, `SUPPORTED_PLAYCANVAS is ">=A.B.C <D.E.F" (${SUPPORTED_PLAYCANVAS})`);
    return { lo: m[1], hi: m[2] };
}

test('the peer range, SUPPORTED_PLAYCANVAS and the installed engines agree', () => {
    const { lo, hi } = bounds();
    assert.equal(pkg.peerDependencies.playcanvas, SUPPORTED_PLAYCANVAS);
    const lockPeer = JSON.parse(readFileSync(join(PKG, 'package-lock.json'), 'utf8')).packages[''].peerDependencies.playcanvas;
    assert.equal(lockPeer, SUPPORTED_PLAYCANVAS, 'package-lock.json is up to date');
    // the default engine, the one Node resolves and the pages import
    const defaultVersion = installedVersion('playcanvas');
    assert.equal(defaultVersion, pkg.devDependencies.playcanvas);
    assert.equal(PLAYCANVAS_VERSION, defaultVersion);
    assert.ok(inRange(defaultVersion), `${defaultVersion} in ${SUPPORTED_PLAYCANVAS}`);
    // the lowest version of the range is the one tested below
    assert.equal(pkg.devDependencies['playcanvas-lowest'], `npm:playcanvas@${lo}`);
    assert.equal(installedVersion('playcanvas-lowest'), lo);
    // the range check itself, at its ends
    const [a, b] = /** @type {[number, number, number]} */ (parseVersion(lo));
    assert.ok(inRange(lo) && inRange(`${lo}-beta.1`));
    assert.ok(!inRange(b > 0 ? `${a}.${b - 1}.99` : `${a - 1}.99.99`));
    assert.ok(!inRange(hi));
    assert.ok(!inRange('not a version'));
});

/**
 * A folder to serve as /pkg/ for conformance/page/render.html: links to this package's src/ and
 * conformance/, and node_modules/ set up by `engine` (the page's import map names
 * /pkg/node_modules/playcanvas/build/playcanvas.mjs).
 * @param {string} tmp
 * @param {(modules: string) => void} engine
 */
function servedPackage(tmp, engine) {
    const modules = join(tmp, 'node_modules');
    mkdirSync(modules, { recursive: true });
    for (const d of ['src', 'conformance']) symlinkSync(join(PKG, d), join(tmp, d), 'dir');
    engine(modules);
    return tmp;
}

/**
 * Open render.html with an engine; `pkgDir` null: this package as it is (the default engine).
 * @param {string|null} pkgDir
 */
async function openPage(pkgDir) {
    /** @type {{[prefix: string]: string}} */
    const mounts = { '/examples/': examples };
    if (pkgDir) mounts['/pkg/'] = pkgDir;
    const browser = await launchPage({ page: 'conformance/page/render.html', extraMounts: mounts });
    /** @type {string[]} */
    const warnings = [];
    browser.page.on('console', (msg) => {
        if (msg.type() === 'warning' && msg.text().includes('@gsverse/web')) warnings.push(msg.text());
    });
    const version = await browser.page.evaluate(async () => (await import('playcanvas')).version);
    return { ...browser, warnings, version };
}

/**
 * In the page: load the example once per engine member the plugin needs, with that member taken
 * away from a real engine object until the load has failed (restored afterwards), then once more
 * with everything in place. Returns what each load threw, or {ok} for a load that succeeded.
 * @param {import('playwright-core').Page} page
 * @returns {Promise<{[member: string]: {ok?: boolean, anchorError?: boolean, code?: string, message?: string}}>}
 */
function loadWithoutMembers(page) {
    return page.evaluate(async () => {
        const plugin = '/pkg/src/playcanvas/index.js';
        const pc = await import('playcanvas');
        const { loadAnchoredAsset, AnchorError } = await import(plugin);
        const canvas = document.createElement('canvas');
        canvas.width = canvas.height = 64;
        document.body.appendChild(canvas);
        const graphicsDevice = await pc.createGraphicsDevice(canvas, /** @type {any} */ ({ deviceTypes: ['webgl2'], antialias: false }));
        const app = new pc.Application(canvas, { graphicsDevice });
        const bytes = new Uint8Array(await (await fetch('/examples/web/capsule.glb')).arrayBuffer());
        /** @param {any} proto @param {string} name @returns {() => void} */
        const removeMethod = (proto, name) => {
            let owner = proto;
            while (owner && !Object.hasOwn(owner, name)) owner = Object.getPrototypeOf(owner);
            if (!owner) throw new Error(`the engine has no ${name} to remove`);
            const d = /** @type {PropertyDescriptor} */ (Object.getOwnPropertyDescriptor(owner, name));
            delete owner[name];
            return () => Object.defineProperty(owner, name, d);
        };
        /** @param {string} event @param {(asset: any) => void} change @returns {() => void} */
        const onAssets = (event, change) => {
            app.assets.on(event, change);
            return () => app.assets.off(event, change);
        };
        /** @type {{[member: string]: () => () => void}} */
        const removals = {
            // the engine module: GSplatData#calcMortonOrder
            calcMortonOrder: () => removeMethod(pc.GSplatData.prototype, 'calcMortonOrder'),
            // the loaded container's per-mesh table, gone once the engine has instantiated the
            // scene from it (the registry's load event comes before the asset's own)
            _meshGSplats: () => onAssets('load', (a) => {
                if (a.type !== 'container') return;
                const container = a.resource, instantiate = container.instantiateRenderEntity;
                container.instantiateRenderEntity = function (/** @type {any[]} */ ...args) {
                    const root = instantiate.apply(this, args);
                    delete this._meshGSplats;
                    return root;
                };
            }),
            // each splat resource the container creates
            centersVersion: () => onAssets('add', (a) => { if (a.type === 'gsplat' && a.resource) delete a.resource.centersVersion; }),
            // the gsplat component's work-buffer hook
            setWorkBufferModifier: () => removeMethod(pc.GSplatComponent.prototype, 'setWorkBufferModifier'),
        };
        /** @type {{[member: string]: any}} */
        const out = {};
        const attempt = async () => {
            try {
                const loaded = await loadAnchoredAsset(app, bytes, { name: 'capsule.glb', parent: null });
                const count = loaded.anchored.length;
                for (const s of loaded.anchored) s.destroy();
                loaded.root.destroy();
                return { ok: count === 1 };
            } catch (err) {
                const e = /** @type {any} */ (err);
                return { anchorError: e instanceof AnchorError, code: e?.code, message: String(e?.message ?? e) };
            }
        };
        for (const [member, remove] of Object.entries(removals)) {
            const restore = remove();
            try {
                out[member] = await attempt();
            } finally {
                restore();
            }
        }
        out.restored = await attempt();
        app.destroy();
        return out;
    });
}

/**
 * @param {Awaited<ReturnType<typeof loadWithoutMembers>>} results
 * @param {string} version  the running engine's
 */
function assertUnsupported(results, version) {
    const named = {
        calcMortonOrder: 'GSplatData#calcMortonOrder', _meshGSplats: 'GlbContainerResource#_meshGSplats',
        centersVersion: 'GSplatResource#centersVersion', setWorkBufferModifier: 'GSplatComponent#setWorkBufferModifier',
    };
    for (const [member, what] of Object.entries(named)) {
        const r = results[member];
        assert.ok(r, `${member} was checked`);
        assert.equal(r.ok, undefined, `without ${member}, loadAnchoredAsset must fail`);
        assert.equal(r.anchorError, true, `${member}: ${r.message}`);
        assert.equal(r.code, 'ENGINE_UNSUPPORTED', `${member}: ${r.message}`);
        assert.ok(r.message?.startsWith(`PlayCanvas ${version}: ${what}`), `${member}: ${r.message}`);
        assert.ok(r.message?.includes(`supports PlayCanvas ${SUPPORTED_PLAYCANVAS}`), `${member}: ${r.message}`);
    }
    assert.deepEqual(results.restored, { ok: true }, 'with every member back, the same load succeeds');
}

test('the lowest supported PlayCanvas: the example renders and follows a stretch; a missing member is named', { skip, timeout: 240_000 * timeScale() }, async (t) => {
    const { lo } = bounds();
    const tmp = mkdtempSync(join(tmpdir(), 'gsverse-engine-lowest-'));
    /** @type {Awaited<ReturnType<typeof openPage>>|undefined} */
    let browser;
    try {
        const served = servedPackage(tmp, (modules) => symlinkSync(join(NM, 'playcanvas-lowest'), join(modules, 'playcanvas'), 'dir'));
        browser = await openPage(served);
        assert.equal(browser.version, lo, 'the page runs the lowest supported engine');
        await t.test('renders through the work-buffer remap and follows a stretch', () => renderAndStretch(/** @type {any} */ (browser).page));
        await t.test('a missing engine member throws ENGINE_UNSUPPORTED naming the version', async () => {
            assertUnsupported(await loadWithoutMembers(/** @type {any} */ (browser).page), lo);
        });
        assert.deepEqual(browser.warnings, [], 'no warning inside the range');
    } finally {
        await browser?.close();
        rmSync(tmp, { recursive: true, force: true });
    }
});

test('the default PlayCanvas: a missing engine member throws ENGINE_UNSUPPORTED naming the version', { skip, timeout: 180_000 * timeScale() }, async () => {
    const browser = await openPage(null);
    try {
        assert.equal(browser.version, installedVersion('playcanvas'));
        assertUnsupported(await loadWithoutMembers(browser.page), browser.version);
        assert.deepEqual(browser.warnings, [], 'no warning inside the range');
    } finally {
        await browser.close();
    }
});

test('an engine version outside the range with every member present: one console warning, and it renders', { skip, timeout: 180_000 * timeScale() }, async () => {
    const { hi } = bounds();
    const tmp = mkdtempSync(join(tmpdir(), 'gsverse-engine-outside-'));
    /** @type {Awaited<ReturnType<typeof openPage>>|undefined} */
    let browser;
    try {
        // the default engine, its `version` export replaced by the range's (exclusive) upper bound
        const served = servedPackage(tmp, (modules) => {
            symlinkSync(join(NM, 'playcanvas'), join(modules, 'playcanvas-engine'), 'dir');
            mkdirSync(join(modules, 'playcanvas', 'build'), { recursive: true });
            writeFileSync(join(modules, 'playcanvas', 'build', 'playcanvas.mjs'),
                `export * from '../../playcanvas-engine/build/playcanvas.mjs';\nexport const version = '${hi}';\n`);
        });
        browser = await openPage(served);
        assert.equal(browser.version, hi);
        const info = await browser.page.evaluate(() => /** @type {any} */ (window).gsvRender.load('/examples/web/capsule.glb'));
        assert.equal(info.splats.length, 1);
        const lit = await browser.page.evaluate(() => /** @type {any} */ (window).gsvRender.measure());
        assert.ok(lit.lit > 500, `it renders (${lit.lit} lit pixels)`);
        // five more loads (a missing member is still ENGINE_UNSUPPORTED): still the one warning
        assertUnsupported(await loadWithoutMembers(browser.page), hi);
        assert.equal(browser.warnings.length, 1, `one warning for six loads: ${JSON.stringify(browser.warnings)}`);
        assert.match(browser.warnings[0], new RegExp(`PlayCanvas ${hi.replace(/\./g, '\\.')} is outside the tested range ${SUPPORTED_PLAYCANVAS}`));
    } finally {
        await browser?.close();
        rmSync(tmp, { recursive: true, force: true });
    }
});
