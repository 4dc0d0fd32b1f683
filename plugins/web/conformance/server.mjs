// A minimal static file server on localhost for the browser conformance run, the benchmark
// and tests: GET only, a fixed set of URL prefixes mapped to folders, no directory listings.

import { createServer } from 'node:http';
import { createReadStream } from 'node:fs';
import { stat } from 'node:fs/promises';
import path from 'node:path';

const TYPES = {
    '.html': 'text/html; charset=utf-8',
    '.js': 'text/javascript; charset=utf-8',
    '.mjs': 'text/javascript; charset=utf-8',
    '.json': 'application/json',
    '.wasm': 'application/wasm',
    '.css': 'text/css',
    '.png': 'image/png',
    '.glb': 'model/gltf-binary',
};

/**
 * Serve folders under URL prefixes, e.g. {'/pkg/': '/path/to/plugins/web', '/suite/': suiteDir}.
 * @param {{[prefix: string]: string}} mounts
 * @param {{port?: number}} [options]
 * @returns {Promise<{url: string, close: () => Promise<void>}>}  url: http://127.0.0.1:PORT
 */
export async function startServer(mounts, options = {}) {
    const entries = Object.entries(mounts).map(([prefix, dir]) => [prefix, path.resolve(dir)]);
    const server = createServer(async (req, res) => {
        try {
            const url = new URL(req.url || '/', 'http://localhost');
            const pathname = decodeURIComponent(url.pathname);
            const mount = entries.find(([prefix]) => pathname.startsWith(prefix));
            if (req.method !== 'GET' || !mount) throw Object.assign(new Error('not found'), { status: 404 });
            const file = path.resolve(mount[1], '.' + pathname.slice(mount[0].length - 1));
            if (file !== mount[1] && !file.startsWith(mount[1] + path.sep)) throw Object.assign(new Error('forbidden'), { status: 403 });
            const info = await stat(file);
            if (!info.isFile()) throw Object.assign(new Error('not found'), { status: 404 });
            res.writeHead(200, {
                'content-type': TYPES[/** @type {keyof TYPES} */ (path.extname(file))] || 'application/octet-stream',
                'content-length': info.size,
                'cache-control': 'no-store',
            });
            createReadStream(file).pipe(res);
        } catch (err) {
            const status = /** @type {any} */ (err).status || 404;
            res.writeHead(status, { 'content-type': 'text/plain' });
            res.end(String(status));
        }
    });
    await new Promise((resolve) => server.listen(options.port ?? 0, '127.0.0.1', () => resolve(undefined)));
    const address = /** @type {import('node:net').AddressInfo} */ (server.address());
    return {
        url: `http://127.0.0.1:${address.port}`,
        close: () => new Promise((resolve) => { server.closeAllConnections?.(); server.close(() => resolve()); }),
    };
}
