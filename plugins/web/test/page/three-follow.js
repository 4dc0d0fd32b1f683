// The three.js plugin's followSkinnedMesh against the package's own animation sampler: an asset
// with an animated anchor mesh is loaded twice, by the plugin and by three.js's GLTFLoader; the
// anchor mesh as three.js builds it (a SkinnedMesh, or a Mesh with morph targets) is played by
// an AnimationMixer at each time, followSkinnedMesh takes its vertices, and they are compared
// with AnchorAnimation#sample (src/animation.js) at the same time.

import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { loadAnchoredAsset } from '../../src/three/index.js';

/**
 * @param {string} url  the asset
 * @param {number[]} times  seconds, in the file's animation 0
 * @returns {Promise<{maxError: number, extent: number, moved: number, vertices: number}>}
 *   maxError: the largest coordinate difference over all times; extent: the rest pose's
 *   largest extent; moved: the largest coordinate change from the rest pose (so a comparison of
 *   two rest poses shows)
 */
async function follow(url, times) {
    const bytes = new Uint8Array(await (await fetch(url)).arrayBuffer());
    const { root, anchored } = await loadAnchoredAsset(bytes, { name: url.split('/').pop() });
    const splat = anchored[0];
    const gltf = await new GLTFLoader().parseAsync(bytes.slice().buffer, '');
    // the splat node's world matrix as the plugin placed it: the same scene graph, both at the root
    root.updateMatrixWorld(true);
    gltf.scene.updateMatrixWorld(true);
    /** @type {THREE.Mesh|null} */
    let anchorMesh = null;
    gltf.scene.traverse((/** @type {any} */ o) => {
        const a = gltf.parser.associations.get(o);
        if (o.isMesh && a && a.meshes === splat.prim.anchorMesh.mesh && a.primitives === splat.prim.anchorMesh.primitive) anchorMesh = o;
    });
    if (!anchorMesh) throw new Error('GLTFLoader built no mesh for the anchor primitive');
    const mixer = new THREE.AnimationMixer(gltf.scene);
    const action = mixer.clipAction(gltf.animations[0]);
    // times past the end clamp, as the package's sampler does (a mixer loops by default)
    action.setLoop(THREE.LoopOnce, 1);
    action.clampWhenFinished = true;
    action.play();
    const rest = splat.prim.anchorMesh.vertices;
    let extent = 0;
    for (let k = 0; k < 3; ++k) {
        let lo = Infinity, hi = -Infinity;
        for (let v = k; v < rest.length; v += 3) { lo = Math.min(lo, rest[v]); hi = Math.max(hi, rest[v]); }
        extent = Math.max(extent, hi - lo);
    }
    let maxError = 0, moved = 0;
    const expected = new Float32Array(rest.length);
    for (const t of times) {
        mixer.setTime(t);
        gltf.scene.updateMatrixWorld(true);
        const got = splat.followSkinnedMesh(/** @type {THREE.Mesh} */ (anchorMesh));
        /** @type {any} */ (splat.animation).sample(0, t, expected);
        for (let i = 0; i < expected.length; ++i) {
            maxError = Math.max(maxError, Math.abs(got[i] - expected[i]));
            moved = Math.max(moved, Math.abs(expected[i] - rest[i]));
        }
    }
    splat.destroy();
    return { maxError, extent, moved, vertices: rest.length / 3 };
}

/** @type {any} */ (window).gsvFollow = { follow };
/** @type {any} */ (window).gsvReady = true;
