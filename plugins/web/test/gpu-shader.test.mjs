// The shader sources of the PlayCanvas plugin (no browser needed): the render's work-buffer
// modifier and the conformance/benchmark pass embed literally the same remap chunk, in GLSL and
// in WGSL; the deliberately broken variants differ from it only where they should; the Jacobi
// sweep count is the one of src/decompose.js.
import test from 'node:test';
import assert from 'node:assert/strict';

import {
    FAULTS, GSV_JACOBI_SWEEPS, REMAP_GLSL, modifyChunkGLSL, processChunkGLSL, remapChunkGLSL,
} from '../src/playcanvas/shader.js';
import { REMAP_WGSL, modifyChunkWGSL, processChunkWGSL, remapChunkWGSL } from '../src/playcanvas/shader-wgsl.js';
import { JACOBI_SWEEPS } from '../src/decompose.js';

test('render and conformance pass share the remap chunk verbatim', () => {
    assert.ok(modifyChunkGLSL().startsWith(REMAP_GLSL));
    assert.ok(processChunkGLSL().startsWith(REMAP_GLSL));
    assert.ok(modifyChunkWGSL().startsWith(REMAP_WGSL));
    assert.ok(processChunkWGSL().startsWith(REMAP_WGSL));
    assert.match(modifyChunkGLSL(), /void modifySplatCenter\(inout vec3 center\)/);
    assert.match(modifyChunkGLSL(), /void modifySplatRotationScale\(/);
    assert.match(processChunkGLSL(), /void process\(\)/);
    for (const fault of Object.keys(FAULTS)) {
        assert.ok(modifyChunkGLSL({ fault }).startsWith(remapChunkGLSL({ fault })));
        assert.ok(processChunkGLSL({ fault }).startsWith(remapChunkGLSL({ fault })));
        assert.ok(processChunkWGSL({ fault }).startsWith(remapChunkWGSL({ fault })));
    }
});

test('fault variants change only the frame they name', () => {
    /** @param {string} a @param {string} b */
    const changed = (a, b) => {
        const x = a.split('\n'), y = b.split('\n');
        assert.equal(x.length, y.length);
        return x.filter((line, i) => line !== y[i]).map((line) => line.trim());
    };
    assert.deepEqual(changed(remapChunkGLSL({ fault: 'frame-axis' }), REMAP_GLSL), ['vec3 cr = cross(e2, e1);']);
    assert.deepEqual(changed(remapChunkGLSL({ fault: 'games-axis' }), REMAP_GLSL), ['vec3 u = e2 - g;', 'vec3 w = e1 - g;']);
    assert.deepEqual(changed(remapChunkWGSL({ fault: 'frame-axis' }), REMAP_WGSL), ['let cr = cross(e2, e1);']);
    assert.throws(() => remapChunkGLSL({ fault: 'no-such-fault' }), /unknown shader fault/);
});

test('the shader decomposition uses the sweep count of decompose.js', () => {
    assert.equal(GSV_JACOBI_SWEEPS, JACOBI_SWEEPS);
    assert.match(REMAP_GLSL, new RegExp(`#define GSV_JACOBI_SWEEPS ${JACOBI_SWEEPS}\\b`));
    assert.match(REMAP_WGSL, new RegExp(`const GSV_JACOBI_SWEEPS: i32 = ${JACOBI_SWEEPS};`));
});
