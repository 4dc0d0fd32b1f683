// The three.js plugin without a GPU (Node): what loadAnchoredAsset builds (Spark's splats in the
// file's order, each SplatMesh placed by its splat node's global matrix), the refusals (the same
// AnchorError codes as the reader's, nothing built), the vertex upload, the enabled switch, the
// faults and the modifier's GLSL (the core chunk verbatim), and followSkinnedMesh on an unskinned
// mesh. The GPU side is tested in the browser (tests/test_web_three.py).
import test from 'node:test';
import assert from 'node:assert/strict';

import * as THREE from 'three';
import { AnchorError, readAnchoredGlb } from '../src/anchor.js';
import { remapChunkGLSL } from '../src/remap-glsl.js';
import { FAULTS, loadAnchoredAsset, modifierGlobalsGLSL } from '../src/three/index.js';
import { anchoredGlb } from './glb-writer.mjs';

const VERTICES = [0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0];
const NODE = [2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 1, 2, 3, 1];

/** @param {any} [extra] */
function asset(extra = {}) {
    return anchoredGlb({
        vertices: VERTICES, indices: [0, 1, 2, 3, 2, 1], profile: 'local', deformation: 'affine',
        face: [0, 1, 1], bary: [0.2, 0.2, 0.3, 0.1, 0.25, 0.5], nodeMatrix: NODE, ...extra,
    });
}

test('loadAnchoredAsset builds one SplatMesh per splat primitive, in file order, placed by the splat node', async () => {
    const { root, anchored, plain, animations } = await loadAnchoredAsset(asset(), { name: 'quad.glb' });
    assert.equal(anchored.length, 1);
    assert.equal(plain.length, 0);
    assert.deepEqual(animations, []);
    const s = anchored[0];
    assert.equal(s.mesh.parent, root);
    assert.deepEqual(s.mesh.matrix.elements, NODE);
    assert.equal(s.mesh.matrixAutoUpdate, false);
    assert.equal(/** @type {any} */ (s.mesh.packedSplats).numSplats, 3);
    // Spark's splat i is the file's splat i: the rest centres come back in file order
    /** @type {number[][]} */
    const centres = [];
    s.mesh.packedSplats?.forEachSplat((/** @type {number} */ i, /** @type {THREE.Vector3} */ c) => centres.push([i, c.x, c.y]));
    const means = s.prim.rest.means;
    centres.forEach(([i, x, y]) => {
        assert.ok(Math.abs(x - means[3 * i]) < 1e-3 && Math.abs(y - means[3 * i + 1]) < 1e-3, `splat ${i}`);
    });
    // the anchor textures: per splat face + barycentric bits, per face the corners
    const a = /** @type {Uint32Array} */ (s.gpu.uniforms.gsvAnchorTex.value.image.data);
    assert.deepEqual([a[0], a[4], a[8]], [0, 1, 1]);
    assert.equal(new Float32Array(a.buffer, 4, 1)[0], Math.fround(0.2));
    const f = /** @type {Uint32Array} */ (s.gpu.uniforms.gsvFaces.value.image.data);
    assert.deepEqual(Array.from(f.subarray(0, 8)), [0, 1, 2, 1, 3, 2, 1, 1]);
    assert.equal(s.gpu.uniforms.gsvLaw.value, 0);
    s.destroy();
});

test('a refused asset throws the reader\'s AnchorError code, before anything is built', async () => {
    const bad = asset({ face: [0, 1, 7] });
    /** @type {any} */
    let expected = null;
    try { readAnchoredGlb(bad, { name: 'bad.glb' }); } catch (err) { expected = err; }
    assert.ok(expected instanceof AnchorError, 'the reader refuses it');
    await assert.rejects(loadAnchoredAsset(bad, { name: 'bad.glb' }), (err) => {
        assert.ok(err instanceof AnchorError);
        assert.equal(/** @type {AnchorError} */ (err).code, expected.code);
        assert.match(/** @type {Error} */ (err).message, /^bad\.glb/);
        return true;
    });
});

test('setVertices uploads the vertices and asks Spark to regenerate; wrong sizes are refused', async () => {
    const { anchored } = await loadAnchoredAsset(asset());
    const s = anchored[0];
    const v0 = s.mesh.version;
    const moved = Float32Array.from(VERTICES, (x, i) => (i % 3 === 1 ? 1.5 * x : x));
    s.setVertices(moved);
    assert.ok(s.mesh.version > v0, 'the mesh version moved on');
    assert.deepEqual(Array.from(s.vertices), Array.from(moved));
    const tex = /** @type {Float32Array} */ (s.gpu.uniforms.gsvVertices.value.image.data);
    assert.deepEqual(Array.from(tex.subarray(8, 12)), [0, 1.5, 0, 0]);
    assert.throws(() => s.setVertices(new Float32Array(5)), RangeError);
    s.reset();
    assert.deepEqual(Array.from(s.vertices), VERTICES);
    assert.throws(() => s.setAnimationTime(0, 0), (err) => err instanceof AnchorError && err.code === 'NO_ANIMATION');
    s.destroy();
});

test('enabled switches the remap modifier off and on', async () => {
    const { anchored } = await loadAnchoredAsset(asset());
    const s = anchored[0];
    assert.equal(s.mesh.objectModifiers?.length, 1);
    s.enabled = false;
    assert.equal(s.mesh.objectModifiers, undefined);
    s.enabled = true;
    assert.equal(s.mesh.objectModifiers?.length, 1);
    s.destroy();
});

test('the modifier runs the core GLSL chunk verbatim; faults are checked by name', async () => {
    assert.ok(modifierGlobalsGLSL().includes(remapChunkGLSL()));
    assert.ok(modifierGlobalsGLSL({ fault: 'frame-axis' }).includes(remapChunkGLSL({ fault: 'frame-axis' })));
    assert.notEqual(modifierGlobalsGLSL({ fault: 'frame-axis' }), modifierGlobalsGLSL());
    // a render fault leaves the remap itself right
    assert.equal(modifierGlobalsGLSL({ fault: 'scale-swizzle' }), modifierGlobalsGLSL());
    assert.deepEqual(Object.keys(FAULTS).sort(), ['frame-axis', 'games-axis', 'node-transform', 'scale-swizzle']);
    await assert.rejects(loadAnchoredAsset(asset(), { fault: 'rest-sort' }), /unknown shader fault 'rest-sort'/);
    const { anchored } = await loadAnchoredAsset(asset(), { fault: 'node-transform' });
    assert.deepEqual(anchored[0].mesh.matrix.elements, new THREE.Matrix4().elements, 'the node transform ignored');
    anchored[0].destroy();
});

test('followSkinnedMesh takes an unskinned mesh\'s vertices as splat-local (the anchor node\'s transform ignored)', async () => {
    const { anchored } = await loadAnchoredAsset(asset());
    const s = anchored[0];
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.BufferAttribute(Float32Array.from(VERTICES, (x) => 3 * x), 3));
    const mesh = new THREE.Mesh(geometry);
    mesh.position.set(10, 20, 30);
    mesh.updateMatrixWorld(true);
    const got = s.followSkinnedMesh(mesh);
    assert.deepEqual(Array.from(got), VERTICES.map((x) => 3 * x));
    assert.deepEqual(Array.from(s.vertices), VERTICES.map((x) => 3 * x));
    const short = new THREE.Mesh(new THREE.BufferGeometry().setAttribute('position', new THREE.BufferAttribute(new Float32Array(9), 3)));
    assert.throws(() => s.followSkinnedMesh(short), /3 vertices, the anchor mesh 4/);
    s.destroy();
});
