// The JS target of the fuzz harness (fuzz/js_worker.py starts it): one long-lived Node process
// that reads many GLB / glTF files with the web plugin's reader (plugins/web/src), as an
// application would: expandCompressed (an SPZ-compressed rest pose decoded), readAnchoredGlb,
// then per anchored primitive computeRest, remapCpu on the rest vertices and
// readAnchorAnimation (its first animation sampled), then readPhysics.
//
// Protocol (the USD worker's): one JSON request per line on stdin, {"path", "targets"}; one
// JSON line per target on stdout, {"target", "outcome", "detail", "codes"}. Outcomes: ok;
// refused (an AnchorError: the reader's own one-line refusal, with its code); internal (any
// other exception: its name, message and first stack frame).
import { readFileSync } from 'node:fs';
import { createInterface } from 'node:readline';
import {
    AnchorError, computeRest, expandCompressed, readAnchorAnimation, readAnchoredGlb, readPhysics, remapCpu,
} from '../plugins/web/src/index.js';

/** @param {string} path */
async function readAll(path) {
    const bytes = await expandCompressed(readFileSync(path), { name: 'input.glb' });
    const { anchored } = readAnchoredGlb(bytes, { name: 'input.glb' });
    for (const prim of anchored) {
        const rest = computeRest(prim);
        remapCpu(prim, rest, prim.anchorMesh.vertices);
        const anim = readAnchorAnimation(bytes, prim, { name: 'input.glb' });
        if (anim && anim.animations.length) anim.sample(0, anim.animations[0].duration / 2);
    }
    readPhysics(bytes, { name: 'input.glb' });
}

/** @param {any} err */
function describe(err) {
    const frame = String((err && err.stack) || '').split('\n').find((l) => /^\s+at /.test(l)) || '';
    const where = (frame.match(/([\w.-]+\.m?js:\d+)/) || ['?'])[0];
    return `${err && err.name}: ${err && err.message}`.slice(0, 300) + ` at ${where}`;
}

const lines = createInterface({ input: process.stdin });
for await (const line of lines) {
    const request = JSON.parse(line);
    for (const target of request.targets) {
        let reply;
        try {
            await readAll(request.path);
            reply = { target, outcome: 'ok', detail: '', codes: [] };
        } catch (err) {
            reply = err instanceof AnchorError
                ? { target, outcome: 'refused', detail: String(err.message).slice(0, 300), codes: [err.code] }
                : { target, outcome: 'internal', detail: describe(err), codes: [] };
        }
        process.stdout.write(JSON.stringify(reply) + '\n');
    }
}
