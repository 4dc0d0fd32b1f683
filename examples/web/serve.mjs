#!/usr/bin/env node
// Serve the GS-Verse web demo on localhost.
//
//   node examples/web/serve.mjs [ASSET.glb] [--port N] [--no-open]
//   (or, in plugins/web: npm run demo -- [ASSET.glb] [--port N] [--no-open])
//
// Serves the demo page (this folder), the plugin sources (plugins/web/src), and the two browser
// builds the page needs from plugins/web/node_modules (the PlayCanvas ES module build and the
// jolt-physics wasm-compat build; for ?engine=three, three.js's build and addons and Spark's
// build) under /vendor/, mapped by the page's import map. The asset
// (default: examples/web/capsule.glb, shipped) is served at /asset/NAME; the page reads /config.json
// to find it. Only files under those roots are served (no path traversal), only on 127.0.0.1,
// and nothing is fetched from the network.

import http from 'node:http';
import fs from 'node:fs';
import path from 'node:path';
import { spawn } from 'node:child_process';
import { fileURLToPath } from 'node:url';

const HERE = path.dirname(fileURLToPath(import.meta.url));
const REPO = path.resolve(HERE, '..', '..');
const PLUGIN = path.join(REPO, 'plugins', 'web');
const MODULES = path.join(PLUGIN, 'node_modules');
/** The demo's own asset, shipped in the repository: the capsule example of examples/capsule converted
 * with `gsverse-convert examples/capsule/splats.ply examples/web/capsule.glb --mesh
 * examples/capsule/mesh.obj --anchors compact` (tests/test_web_demo.py checks it is what that
 * command writes). */
export const DEFAULT_ASSET = path.join(REPO, 'examples', 'web', 'capsule.glb');
const DEFAULT_PORT = 8123;

/** Single files served under /vendor/ (import-map targets). */
const VENDOR = {
    'playcanvas.mjs': path.join(MODULES, 'playcanvas', 'build', 'playcanvas.mjs'),
    'jolt-physics.wasm-compat.js': path.join(MODULES, 'jolt-physics', 'dist', 'jolt-physics.wasm-compat.js'),
};

/** Folders served under /vendor/NAME/ (import-map targets that import their neighbours). */
const VENDOR_DIRS = {
    three: path.join(MODULES, 'three'),
    spark: path.join(MODULES, '@sparkjsdev', 'spark', 'dist'),
};

const TYPES = {
    '.html': 'text/html; charset=utf-8',
    '.js': 'text/javascript; charset=utf-8',
    '.mjs': 'text/javascript; charset=utf-8',
    '.css': 'text/css; charset=utf-8',
    '.json': 'application/json',
    '.glb': 'model/gltf-binary',
    '.gltf': 'model/gltf+json',
    '.png': 'image/png',
    '.wasm': 'application/wasm',
};

/**
 * Resolve a URL path under a root directory; null if it would leave the root.
 * @param {string} root
 * @param {string} rel  URL path below the mount point (already decoded)
 * @returns {string|null}
 */
export function safeJoin(root, rel) {
    if (rel.includes('\0')) return null;
    const parts = rel.split(/[\\/]+/).filter((p) => p !== '' && p !== '.');
    if (parts.some((p) => p === '..')) return null;
    const full = path.resolve(root, ...parts);
    if (full !== root && !full.startsWith(root + path.sep)) return null;
    return full;
}

/**
 * Map a request path to a file (or a generated body).
 * @param {string} pathname decoded URL path
 * @param {{asset: string|null}} state
 * @returns {{file?: string, body?: string, type?: string}|null}
 */
function route(pathname, state) {
    if (pathname === '/' || pathname === '/index.html') return { file: path.join(HERE, 'index.html') };
    if (pathname === '/config.json') {
        const name = state.asset ? path.basename(state.asset) : null;
        return {
            body: JSON.stringify({ asset: name ? `/asset/${encodeURIComponent(name)}` : null, name }),
            type: TYPES['.json'],
        };
    }
    if (pathname.startsWith('/asset/')) return state.asset ? { file: state.asset } : null;
    const dir = /^\/vendor\/(three|spark)\/(.*)$/.exec(pathname);
    if (dir) {
        const file = safeJoin(VENDOR_DIRS[/** @type {keyof typeof VENDOR_DIRS} */ (dir[1])], dir[2]);
        return file ? { file } : null;
    }
    if (pathname.startsWith('/vendor/')) {
        const file = VENDOR[/** @type {keyof typeof VENDOR} */ (pathname.slice(8))];
        return file ? { file } : null;
    }
    if (pathname.startsWith('/src/')) {
        const file = safeJoin(path.join(PLUGIN, 'src'), pathname.slice(5));
        return file ? { file } : null;
    }
    if (pathname.startsWith('/test/')) return null;     // the test harness is not part of the page
    const file = safeJoin(HERE, pathname.slice(1));
    return file ? { file } : null;
}

/**
 * Start the demo server.
 * @param {{asset?: string|null, port?: number, host?: string}} [options]
 * @returns {Promise<{server: http.Server, url: string, close: () => Promise<void>}>}
 */
export function startServer(options = {}) {
    const state = { asset: options.asset === undefined ? DEFAULT_ASSET : options.asset };
    if (state.asset) state.asset = path.resolve(state.asset);
    const host = options.host ?? '127.0.0.1';
    const server = http.createServer((req, res) => {
        const send = (/** @type {number} */ status, /** @type {string} */ text) => {
            res.writeHead(status, { 'content-type': 'text/plain; charset=utf-8' });
            res.end(text);
        };
        if (req.method !== 'GET' && req.method !== 'HEAD') return send(405, 'method not allowed');
        let pathname;
        try {
            pathname = decodeURIComponent(new URL(req.url || '/', 'http://localhost').pathname);
        } catch {
            return send(400, 'bad request');
        }
        const target = route(pathname, state);
        if (!target) return send(404, 'not found');
        const headers = { 'cache-control': 'no-store' };
        if (target.body !== undefined) {
            res.writeHead(200, { ...headers, 'content-type': target.type || 'text/plain' });
            return res.end(req.method === 'HEAD' ? undefined : target.body);
        }
        const file = /** @type {string} */ (target.file);
        fs.stat(file, (err, st) => {
            if (err || !st.isFile()) return send(404, 'not found');
            res.writeHead(200, {
                ...headers,
                'content-type': TYPES[/** @type {keyof typeof TYPES} */ (path.extname(file).toLowerCase())] || 'application/octet-stream',
                'content-length': st.size,
            });
            if (req.method === 'HEAD') return res.end();
            fs.createReadStream(file).pipe(res);
        });
    });
    return new Promise((resolve, reject) => {
        server.once('error', reject);
        server.listen(options.port ?? DEFAULT_PORT, host, () => {
            const addr = /** @type {import('node:net').AddressInfo} */ (server.address());
            resolve({
                server,
                url: `http://${host}:${addr.port}/`,
                close: () => new Promise((r) => server.close(() => r())),
            });
        });
    });
}

/** @param {string[]} argv */
function parseArgs(argv) {
    /** @type {{asset: string|null, port: number, open: boolean}} */
    const out = { asset: null, port: DEFAULT_PORT, open: true };
    for (let i = 0; i < argv.length; i++) {
        const a = argv[i];
        if (a === '--no-open') out.open = false;
        else if (a === '--port') out.port = Number(argv[++i]);
        else if (a.startsWith('--port=')) out.port = Number(a.slice(7));
        else if (a === '-h' || a === '--help') {
            process.stdout.write('usage: serve.mjs [ASSET.glb] [--port N] [--no-open]\n');
            process.exit(0);
        } else if (a.startsWith('-')) throw new Error(`unknown option ${a}`);
        else if (out.asset) throw new Error('only one asset can be given (drop more onto the page)');
        else out.asset = a;
    }
    if (!Number.isInteger(out.port) || out.port < 0 || out.port > 65535) throw new Error('--port needs a number 0..65535');
    return out;
}

async function main() {
    let args;
    try {
        args = parseArgs(process.argv.slice(2));
    } catch (err) {
        process.stderr.write(`serve.mjs: ${/** @type {Error} */ (err).message}\nusage: serve.mjs [ASSET.glb] [--port N] [--no-open]\n`);
        process.exit(2);
    }
    // under `npm run demo`, a relative path is relative to where npm was run (INIT_CWD)
    const asset = args.asset ? path.resolve(process.env.INIT_CWD || process.cwd(), args.asset) : DEFAULT_ASSET;
    if (!fs.existsSync(asset)) {
        const hint = args.asset ? '' : ' (it ships with the repository: restore it with git checkout, or pass an asset)';
        process.stderr.write(`serve.mjs: ${asset}: no such file${hint}\n`);
        process.exit(1);
    }
    for (const file of Object.values(VENDOR)) {
        if (!fs.existsSync(file)) {
            process.stderr.write(`serve.mjs: ${file} is missing: run npm ci in plugins/web\n`);
            process.exit(1);
        }
    }
    let started;
    try {
        started = await startServer({ asset, port: args.port });
    } catch (err) {
        process.stderr.write(`serve.mjs: cannot listen on port ${args.port}: ${/** @type {Error} */ (err).message}\n`);
        process.exit(1);
    }
    process.stdout.write(`GS-Verse demo: ${started.url}  (asset ${path.relative(process.cwd(), asset) || asset}; Ctrl+C to stop)\n`);
    if (args.open) {
        const opener = process.platform === 'darwin' ? 'open' : process.platform === 'win32' ? 'explorer' : 'xdg-open';
        try {
            const child = spawn(opener, [started.url], { stdio: 'ignore', detached: true });
            child.on('error', () => {});
            child.unref();
        } catch {
            // no browser opener here: the URL above is enough
        }
    }
}

if (process.argv[1] && path.resolve(process.argv[1]) === fileURLToPath(import.meta.url)) main();
