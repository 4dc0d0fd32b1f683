// The Jolt module the demo's Node tests step their worlds with: the wasm build the web plugin's
// npm install brings, loaded once per test file (each PhysicsWorld allocates from it).

import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const REPO = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..', '..', '..');
export const JOLT = path.join(REPO, 'plugins', 'web', 'node_modules', 'jolt-physics', 'dist', 'jolt-physics.wasm-compat.js');
export const haveJolt = fs.existsSync(JOLT);

/** @type {any} */
let joltModule = null;
/** The Jolt module, initialised on first use. */
export async function jolt() {
    if (!joltModule) {
        const { default: initJolt } = await import(JOLT);
        joltModule = await initJolt();
    }
    return joltModule;
}
