// Headless Chromium for the demo's browser tests: playwright-core from plugins/web and the system
// chromium (WebGL2 on SwiftShader where there is no GPU), plus the helpers both tests use.

import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { decodePng } from './png.mjs';
import { silhouette } from './measure.mjs';

const HERE = path.dirname(fileURLToPath(import.meta.url));
export const REPO = path.resolve(HERE, '..', '..', '..');
export const CHROMIUM = process.env.CHROMIUM || '/usr/bin/chromium';
const FLAGS = ['--headless', '--no-sandbox', '--disable-gpu', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
    '--ignore-gpu-blocklist', '--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run',
    // a test page in a background tab must not be throttled
    '--disable-background-timer-throttling', '--disable-renderer-backgrounding', '--disable-backgrounding-occluded-windows'];

/** Attempts at starting Chromium: only the start is retried (a busy machine, a crashed helper). */
const LAUNCH_ATTEMPTS = 3;

/**
 * Launch Chromium with a fresh profile (a failed start is retried).
 * @param {{width?: number, height?: number}} [viewport]
 * @returns {Promise<{context: any, close: () => Promise<void>}>}
 */
export async function launch(viewport = {}) {
    if (!fs.existsSync(CHROMIUM)) throw new Error(`${CHROMIUM} not found (install chromium, or set CHROMIUM)`);
    let playwright;
    try {
        playwright = await import(path.join(REPO, 'plugins', 'web', 'node_modules', 'playwright-core', 'index.mjs'));
    } catch {
        throw new Error('playwright-core is not installed: run npm ci in plugins/web');
    }
    const scale = Math.min(8, Math.max(1, Number(process.env.GSVERSE_TIME_SCALE) || 1));
    let profile = '', context = null, lastError = null;
    for (let attempt = 1; attempt <= LAUNCH_ATTEMPTS && !context; ++attempt) {
        profile = fs.mkdtempSync(path.join(os.tmpdir(), 'gsverse-demo-'));
        try {
            context = await playwright.chromium.launchPersistentContext(profile, {
                executablePath: CHROMIUM, args: FLAGS, headless: true, timeout: 60000 * scale,
                viewport: { width: viewport.width ?? 800, height: viewport.height ?? 600 }, deviceScaleFactor: 1,
            });
        } catch (err) {
            lastError = err;
            fs.rmSync(profile, { recursive: true, force: true });
            if (attempt < LAUNCH_ATTEMPTS) await new Promise((r) => setTimeout(r, 1000 * attempt));
        }
    }
    if (!context) throw new Error(`Chromium did not start (${LAUNCH_ATTEMPTS} attempts): ${/** @type {Error} */ (lastError)?.message?.split('\n')[0]}`);
    return {
        context,
        close: async () => {
            await context.close();
            fs.rmSync(profile, { recursive: true, force: true });
        },
    };
}

/**
 * The frame once the splats are drawn and stable: the engine sorts splats in a worker and may
 * present a few frames before the first sorted draw, more so on a loaded machine; two
 * consecutive captures with the same non-empty silhouette, each taken two frames after the page
 * reports it settled (`gsverseDemo.settled()`: no change or sort pending), or `timeout` ms, end
 * the wait. The PNG
 * is written to `file` when given.
 * @param {any} page @param {string|null} file @param {number} [timeout]
 */
export async function stableShot(page, file, timeout = 60000) {
    const deadline = Date.now() + timeout;
    /** @type {any} */
    let prev = null;
    for (;;) {
        // a capture counts only once the page says it shows its current state (a loaded
        // machine may present old frames while a sort or a change is still pending)
        await page.waitForFunction(() => {
            const demo = /** @type {any} */ (window).gsverseDemo;
            return !demo?.settled || demo.settled();
        }, null, { timeout: Math.max(1, deadline - Date.now()), polling: 50 }).catch(() => {});
        await page.evaluate(() => /** @type {any} */ (window).gsverseDemo?.frames?.(2));
        const png = await page.screenshot();
        const img = decodePng(png);
        const s = silhouette(img);
        const stable = prev !== null && s.fraction > 0 && s.area === prev.area
            && s.x.size === prev.x.size && s.y.size === prev.y.size;
        if (stable || Date.now() > deadline) {
            if (file) fs.writeFileSync(file, png);
            return img;
        }
        prev = s;
        await page.waitForTimeout(250);
    }
}
