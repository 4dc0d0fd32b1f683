// Which modules may import which engine: the engine-free core (src/*.js and every folder but
// the engine ones) imports no engine and no engine folder; only src/playcanvas/ imports
// PlayCanvas, only src/three/ imports three.js or Spark; neither engine folder imports the other.

import { test } from 'node:test';
import assert from 'node:assert/strict';
import { readdirSync, readFileSync } from 'node:fs';
import { join, relative, sep } from 'node:path';
import { fileURLToPath } from 'node:url';

const SRC = fileURLToPath(new URL('../src', import.meta.url));

/** The engine a module specifier belongs to, or null. @param {string} spec */
export function engineOf(spec) {
    if (spec === 'playcanvas' || spec.startsWith('playcanvas/')) return 'playcanvas';
    if (spec === 'three' || spec.startsWith('three/') || spec === '@sparkjsdev/spark' || spec.startsWith('@sparkjsdev/spark/')) return 'three';
    return null;
}

/**
 * Every module specifier of a source text: static imports and re-exports (`import ... from`,
 * `import '...'`, `export ... from`), dynamic `import('...')` and JSDoc `import('...')` types.
 * @param {string} text
 * @returns {string[]}
 */
export function specifiers(text) {
    const out = [];
    const patterns = [
        /\bimport\s+(?:[^'"`;]*?\s+from\s+)?['"]([^'"]+)['"]/g,
        /\bexport\s+[^'"`;]*?\s+from\s+['"]([^'"]+)['"]/g,
        /\bimport\s*\(\s*['"]([^'"]+)['"]\s*\)/g,
    ];
    for (const re of patterns) for (const m of text.matchAll(re)) out.push(m[1]);
    return out;
}

/** @param {string} dir @returns {string[]} */
function sources(dir) {
    return readdirSync(dir, { withFileTypes: true }).flatMap((e) => {
        const p = join(dir, e.name);
        return e.isDirectory() ? sources(p) : /\.(m?js)$/.test(e.name) ? [p] : [];
    });
}

test('the specifier scanner finds static, re-exported, dynamic and JSDoc imports', () => {
    const text = [
        "import * as pc from 'playcanvas';",
        "import { a,\n  b } from \"three\";",
        "export { c } from '@sparkjsdev/spark';",
        "const m = await import('three/addons/x.js');",
        "/** @typedef {import('playcanvas').AppBase} AppBase */",
        "import './side-effect.js';",
    ].join('\n');
    assert.deepEqual(specifiers(text).sort(), ['./side-effect.js', '@sparkjsdev/spark', 'playcanvas', 'playcanvas', 'three', 'three/addons/x.js'].sort());
    assert.equal(engineOf('three/addons/x.js'), 'three');
    assert.equal(engineOf('@sparkjsdev/spark'), 'three');
    assert.equal(engineOf('playcanvas'), 'playcanvas');
    assert.equal(engineOf('../anchor.js'), null);
});

test('only src/playcanvas/ imports PlayCanvas, only src/three/ imports three.js or Spark, the core neither', () => {
    const files = sources(SRC);
    assert.ok(files.some((f) => f.includes(`${sep}three${sep}`)) && files.some((f) => f.includes(`${sep}playcanvas${sep}`)));
    const wrong = [];
    for (const file of files) {
        const rel = relative(SRC, file).split(sep).join('/');
        const home = rel.startsWith('playcanvas/') ? 'playcanvas' : rel.startsWith('three/') ? 'three' : null;
        for (const spec of specifiers(readFileSync(file, 'utf8'))) {
            const engine = engineOf(spec);
            if (engine !== null && engine !== home) wrong.push(`${rel} imports ${spec}`);
            // relative imports into an engine folder from outside it
            const into = /(^|\/)(playcanvas|three)\//.exec(spec.startsWith('.') ? spec : '');
            if (into && into[2] !== home) wrong.push(`${rel} imports ${spec}`);
        }
    }
    assert.deepEqual(wrong, []);
});
