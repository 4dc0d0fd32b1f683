// The demo's engine adapter for three.js + Spark (@gsverse/web/three, the remap a Spark object
// modifier): the twin of engine-playcanvas.js (its Engine typedef is the interface). No GPU remap
// timer here (gputimer.js reads PlayCanvas's passes): the stats panel says so.

import * as THREE from 'three';
import { SparkRenderer } from '@sparkjsdev/spark';
import { loadAnchoredAsset } from '@gsverse/web/three';

/** @typedef {import('./engine-playcanvas.js').Engine} Engine */

/**
 * The node names of a GLB (its JSON chunk), as PlayCanvas names the entities.
 * @param {Uint8Array} bytes
 * @returns {(string|undefined)[]}
 */
function nodeNames(bytes) {
    const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
    const json = JSON.parse(new TextDecoder().decode(bytes.subarray(20, 20 + view.getUint32(12, true))));
    return (Array.isArray(json.nodes) ? json.nodes : []).map((/** @type {any} */ n) => n?.name);
}

/**
 * @param {HTMLCanvasElement} canvas
 * @param {{test: boolean}} options  test mode: black background, no ground, a preserved drawing buffer
 * @returns {Promise<Engine>}
 */
export async function createEngine(canvas, { test }) {
    const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, alpha: false, preserveDrawingBuffer: test });
    renderer.setPixelRatio(1);
    const scene = new THREE.Scene();
    scene.background = test ? new THREE.Color(0, 0, 0) : new THREE.Color(0.106, 0.114, 0.133);
    const spark = new SparkRenderer({ renderer });
    scene.add(spark);
    const camera = new THREE.PerspectiveCamera(35, 1, 0.01, 1000);
    const resize = () => {
        const w = canvas.clientWidth || window.innerWidth, h = canvas.clientHeight || window.innerHeight;
        renderer.setSize(w, h, false);
        camera.aspect = w / Math.max(1, h);
        camera.updateProjectionMatrix();
    };
    resize();
    window.addEventListener('resize', resize);
    const light = new THREE.DirectionalLight(0xffffff, 1.2);
    light.position.set(-0.5, 1, 0.6);
    scene.add(light, new THREE.AmbientLight(new THREE.Color(0.35, 0.35, 0.4), 1));
    /** @type {THREE.Mesh|null} */
    let plane = null;
    if (!test) {
        plane = new THREE.Mesh(new THREE.PlaneGeometry(1, 1).rotateX(-Math.PI / 2),
            new THREE.MeshLambertMaterial({ color: new THREE.Color(0.32, 0.34, 0.38) }));
        scene.add(plane);
    }
    const gl = renderer.getContext();
    const dbg = gl.getExtension('WEBGL_debug_renderer_info');
    const name = String(dbg ? gl.getParameter(dbg.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER));

    // debug lines: one LineSegments per drawLines call of a frame, reused from frame to frame
    /** @type {THREE.LineSegments[]} */
    const lines = [];
    let used = 0;
    /** @type {((dt: number) => void)[]} */
    const updates = [];
    const v = new THREE.Vector3();
    const size = () => [canvas.clientWidth || window.innerWidth, canvas.clientHeight || window.innerHeight];
    let fps = 0, last = -1;

    return {
        name: 'three',
        backend: `WebGL2 (three.js r${THREE.REVISION} + Spark), ${name}`,
        software: /swiftshader|llvmpipe|software/i.test(name),
        camera: {
            fov: camera.fov,
            place: (eye, target) => {
                camera.position.set(eye[0], eye[1], eye[2]);
                camera.lookAt(target[0], target[1], target[2]);
                camera.updateMatrixWorld();
            },
            eye: () => camera.position.toArray(),
            forward: () => camera.getWorldDirection(v).toArray(),
            toScreen: (p) => {
                const [w, h] = size();
                v.set(p[0], p[1], p[2]).project(camera);
                return [(v.x + 1) * 0.5 * w, (1 - v.y) * 0.5 * h];
            },
            ray: (x, y) => {
                const [w, h] = size();
                const nx = 2 * x / w - 1, ny = 1 - 2 * y / h;
                const a = new THREE.Vector3(nx, ny, -1).unproject(camera), b = new THREE.Vector3(nx, ny, 1).unproject(camera);
                return { origin: a.toArray(), dir: b.sub(a).toArray() };
            },
        },
        ground: plane && {
            place: (x, y, z, sx, sz) => {
                /** @type {THREE.Mesh} */ (plane).position.set(x, y, z);
                /** @type {THREE.Mesh} */ (plane).scale.set(sx, 1, sz);
            },
        },
        load: async (bytes, name) => {
            const loaded = await loadAnchoredAsset(bytes, { name });     // refusals throw before anything is read here
            const names = nodeNames(bytes);
            for (const splat of loaded.anchored) {
                const node = splat.prim.node;
                if (node !== null && names[node]) splat.mesh.name = /** @type {string} */ (names[node]);
            }
            scene.add(loaded.root);
            return {
                anchored: loaded.anchored, plain: loaded.plain, animations: loaded.animations ?? [],
                dispose: () => {
                    loaded.root.removeFromParent();
                    for (const p of loaded.plain) p.dispose();
                },
            };
        },
        node: (splat) => {
            const m = splat.mesh.matrix, t = new THREE.Vector3(), q = new THREE.Quaternion(), s = new THREE.Vector3();
            m.decompose(t, q, s);
            return {
                name: splat.mesh.name,
                matrix: () => {
                    splat.mesh.updateWorldMatrix(true, false);
                    return Float64Array.from(splat.mesh.matrixWorld.elements);
                },
                setPose: (tr, rot) => {
                    m.compose(t.set(tr[0], tr[1], tr[2]), q.set(rot[0], rot[1], rot[2], rot[3]), s);
                    splat.mesh.matrixWorldNeedsUpdate = true;
                },
                position: () => { m.decompose(t, q, v); return t.toArray(); },
                rotation: () => { m.decompose(t, q, v); return [q.x, q.y, q.z, q.w]; },
            };
        },
        drawLines: (data, color) => {
            if (used === lines.length) {
                const l = new THREE.LineSegments(new THREE.BufferGeometry(), new THREE.LineBasicMaterial());
                l.frustumCulled = false;
                scene.add(l);
                lines.push(l);
            }
            const l = lines[used++];
            const attr = l.geometry.getAttribute('position');
            if (!attr || attr.array.length !== data.length) l.geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(data.length), 3));
            /** @type {Float32Array} */ (l.geometry.getAttribute('position').array).set(data);
            l.geometry.getAttribute('position').needsUpdate = true;
            /** @type {THREE.LineBasicMaterial} */ (l.material).color.setRGB(color[0], color[1], color[2]);
            l.visible = true;
        },
        onUpdate: (fn) => { updates.push(fn); },
        onSorted: () => {},     // Spark sorts in its own worker; no per-sort event
        fps: () => Math.round(fps),
        idle: () => {
            const sp = /** @type {any} */ (spark);     // Spark's sort state (as the conformance pages read it)
            return !sp.sorting && !sp.sortDirty && sp.display === sp.current;
        },
        makeTimer: () => null,
        start: () => {
            renderer.setAnimationLoop((/** @type {number} */ time) => {
                const dt = last < 0 ? 1 / 60 : Math.max(0, (time - last) / 1000);
                last = time;
                if (dt > 0) fps += 0.1 * (1 / dt - fps);
                used = 0;
                for (const fn of updates) fn(dt);
                for (let i = used; i < lines.length; i++) lines[i].visible = false;
                renderer.render(scene, camera);
            });
        },
    };
}
