// The TypeScript declarations shipped in the package. `npm pack` (its prepack script generates
// types/ from the JSDoc of src/), the tarball unpacked into a throwaway consumer project, the
// consumer's other dependencies linked from this package's node_modules (no network), and
// `tsc --strict --noEmit` over a consumer that calls the three entry points with typed variables:
// it must compile with nodenext and with bundler resolution, also against the lowest supported
// PlayCanvas. The consumer also holds `@ts-expect-error` misuses, so declarations that degrade to
// `any` fail too; and a deliberate type error must be reported.
import test from 'node:test';
import assert from 'node:assert/strict';
import { spawnSync } from 'node:child_process';
import { mkdirSync, mkdtempSync, readFileSync, readdirSync, rmSync, symlinkSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const PKG = fileURLToPath(new URL('..', import.meta.url));
const NM = join(PKG, 'node_modules');
const pkg = JSON.parse(readFileSync(join(PKG, 'package.json'), 'utf8'));

/**
 * @param {string} cmd @param {string[]} args @param {string} cwd
 * @returns {{status: number|null, out: string}}
 */
function run(cmd, args, cwd) {
    const r = spawnSync(cmd, args, {
        cwd, encoding: 'utf8', maxBuffer: 1 << 26,
        env: { ...process.env, npm_config_update_notifier: 'false', npm_config_fund: 'false', npm_config_audit: 'false' },
    });
    return { status: r.status, out: `${r.stdout}${r.stderr}${r.error ? String(r.error) : ''}` };
}

// Uses the three other entry points the way an application does. Every `@ts-expect-error` line must be
// an error: with `any` in the declarations it is not, and tsc reports the unused directive.
const CONSUMER = `
import {
    AnchorError, computeRest, readAnchoredGlb, readPhysics, remapCpu, remapCpuRotationScale,
    type PhysicsScene, type PhysicsObject, type AnchoredGlb, type AnchoredPrimitive, type RemapOutput, type RestQuantities, type RotationScaleOutput,
} from '@gsverse/web';
import { AnchoredSplat, PLAYCANVAS_VERSION, SUPPORTED_PLAYCANVAS, loadAnchoredAsset } from '@gsverse/web/playcanvas';
import {
    GSVERSEMeshAnchor, KHRGaussianSplatting, KHR_GAUSSIAN_SPLATTING, GSVERSE_MESH_ANCHOR, MeshAnchor, gsverseExtensions,
} from '@gsverse/web/gltf-transform';
import { Document, NodeIO, Primitive } from '@gltf-transform/core';
import { ALL_EXTENSIONS } from '@gltf-transform/extensions';
import { Application, Entity, type AppBase, type Asset } from 'playcanvas';

export function cpu(bytes: Uint8Array, vertices: Float32Array): RemapOutput {
    const glb: AnchoredGlb = readAnchoredGlb(bytes, { name: 'asset.glb' });
    const prim: AnchoredPrimitive = glb.anchored[0];
    const count: number = prim.count;
    const profile: 'local' | 'games' = prim.profile;
    const restVertices: Float32Array = prim.anchorMesh.vertices;
    const rest: RestQuantities = computeRest(prim);
    const out: RemapOutput = remapCpu(prim, rest, vertices);
    const means: Float32Array = out.means;
    const rs: RotationScaleOutput = remapCpuRotationScale(prim, null, vertices);
    const firstPlain: number | undefined = glb.plain[0]?.mesh;
    // @ts-expect-error the rest quantities are not a number
    remapCpu(prim, 3, vertices);
    // @ts-expect-error the covariances are a Float32Array
    const cov: string = out.cov;
    // @ts-expect-error readAnchoredGlb takes bytes
    readAnchoredGlb('asset.glb');
    // @ts-expect-error a primitive has no such member
    prim.nonexistent;
    return count + means.length + rs.scales.length + restVertices.length + (firstPlain ?? 0) > 0 && profile ? out : out;
}

export function physics(bytes: Uint8Array): number {
    const scene: PhysicsScene = readPhysics(bytes, { name: 'scene.glb' });
    const first: PhysicsObject | undefined = scene.objects[0];
    const kind: 'rigid' | 'soft' | 'kinematic' | 'static' | undefined = first?.kind;
    const hull: Float32Array | undefined = first?.collider.vertices;
    const box: number[] | undefined = scene.shapes[0]?.size;
    // @ts-expect-error a kind is one of four strings
    const wrong: number | undefined = first?.kind;
    return (hull?.length ?? 0) + (box?.[1] ?? 0) + (kind ? 1 : 0) + (wrong ?? 0);
}

export function refusalCode(err: unknown): string | null {
    return err instanceof AnchorError ? err.code : null;
}

export async function gpu(app: AppBase, source: string | Uint8Array): Promise<number> {
    const range: string = SUPPORTED_PLAYCANVAS;
    const version: string = PLAYCANVAS_VERSION;
    const { root, anchored, plain, asset } = await loadAnchoredAsset(app, source, { name: 'asset.glb', parent: null, showAnchorMesh: true });
    const scene: Entity = root;
    const container: Asset = asset;
    const others: Entity[] = plain;
    const splat: AnchoredSplat = anchored[0];
    const rest: Float32Array = splat.prim.anchorMesh.vertices;
    splat.setVertices(rest.map((v) => v * 1.5));
    const current: Float32Array = splat.vertices;
    const order: Uint32Array = splat.order;
    const target: Entity = splat.entity;
    const anchorEntity: Entity | null = splat.anchorEntity;
    splat.enabled = false;
    const enabled: boolean = splat.enabled;
    splat.sortDeformed = true;
    splat.reset();
    const ms: number = splat.lastRemapMs + splat.lastSortMs;
    splat.destroy();
    // @ts-expect-error the vertices are numbers
    splat.setVertices(['0', '1', '2']);
    // @ts-expect-error a source is a URL or GLB bytes
    await loadAnchoredAsset(app, 42);
    // @ts-expect-error parent is an Entity
    await loadAnchoredAsset(app, source, { parent: 'root' });
    // @ts-expect-error lastRemapMs is a number
    const wrong: string = splat.lastRemapMs;
    // @ts-expect-error the result has no such member
    (await loadAnchoredAsset(app, source)).nonexistent;
    return ms + current.length + order.length + others.length + range.length + version.length
        + (enabled ? 1 : 0) + (scene === target ? 1 : 0) + (anchorEntity ? 1 : 0) + (container.id ?? 0);
}

export function start(canvas: HTMLCanvasElement, url: string): Promise<number> {
    const app = new Application(canvas, {});
    app.start();
    return gpu(app, url);
}

export async function author(): Promise<Uint8Array> {
    const io = new NodeIO().registerExtensions([...ALL_EXTENSIONS, ...gsverseExtensions]);
    const doc = new Document();
    const buffer = doc.createBuffer();
    const khr = doc.createExtension(KHRGaussianSplatting);
    const ext = doc.createExtension(GSVERSEMeshAnchor);
    const anchorMesh = doc.createMesh('anchor').addPrimitive(doc.createPrimitive()
        .setAttribute('POSITION', doc.createAccessor().setType('VEC3').setArray(new Float32Array([0, 0, 0, 1, 0, 0, 0, 1, 0])).setBuffer(buffer)));
    const prim = doc.createPrimitive().setMode(Primitive.Mode.POINTS)
        .setAttribute('POSITION', doc.createAccessor().setType('VEC3').setArray(new Float32Array([0.25, 0.25, 0])).setBuffer(buffer));
    prim.setExtension(KHR_GAUSSIAN_SPLATTING, khr.createGaussianSplatting().setKernel('ellipse'));
    const anchor: MeshAnchor = ext.createMeshAnchor().setMesh(anchorMesh).setProfile('local').setDeformation('affine')
        .setAccessor('faceIndex', doc.createAccessor().setType('SCALAR').setArray(new Uint8Array([0])).setBuffer(buffer));
    prim.setExtension(GSVERSE_MESH_ANCHOR, anchor);
    const profile: string = anchor.getProfile();
    // @ts-expect-error not an anchor accessor
    anchor.setAccessor('colour', null);
    // @ts-expect-error the primitive index is a number
    anchor.setPrimitive('0');
    doc.createScene().addChild(doc.createNode('splats').setMesh(doc.createMesh('splats').addPrimitive(prim)));
    return profile ? io.writeBinary(doc) : new Uint8Array();
}
`;

// The three.js entry point, as an application uses it (a separate file: Spark's own declarations
// use extensionless relative imports, which nodenext resolution refuses, so it is compiled with
// bundler resolution, libraries checked, and with nodenext only with skipLibCheck).
const THREE_CONSUMER = `
import * as THREE from 'three';
import { SparkRenderer, SplatMesh } from '@sparkjsdev/spark';
import { AnchoredSplatMesh, BoneSkinnedSplats, loadAnchoredAsset, type AnchorError } from '@gsverse/web/three';

export async function three(renderer: THREE.WebGLRenderer, source: string | Uint8Array): Promise<number> {
    const scene = new THREE.Scene();
    scene.add(new SparkRenderer({ renderer }));
    const { root, anchored, plain, animations } = await loadAnchoredAsset(source, { name: 'asset.glb' });
    const group: THREE.Group = root;
    scene.add(group);
    const splat: AnchoredSplatMesh = anchored[0];
    const mesh: SplatMesh = splat.mesh;
    const others: SplatMesh[] = plain;
    const rest: Float32Array = splat.prim.anchorMesh.vertices;
    splat.setVertices(rest.map((v) => v * 1.5));
    const current: Float32Array = splat.vertices;
    if (animations.length) splat.setAnimationTime(animations[0].index, 0.5);
    splat.enabled = false;
    const bones = splat.animation?.skinned ? new BoneSkinnedSplats(splat) : null;
    bones?.setAnimationTime(0, 0.25);
    bones?.dispose();
    splat.reset();
    splat.destroy();
    // @ts-expect-error the vertices are numbers
    splat.setVertices(['0', '1', '2']);
    // @ts-expect-error a source is a URL or GLB bytes
    await loadAnchoredAsset(42);
    // @ts-expect-error the result has no such member
    (await loadAnchoredAsset(source)).nonexistent;
    return current.length + others.length + (mesh.visible ? 1 : 0);
}

export function code(err: AnchorError): string {
    return err.code;
}
`;

// A deliberate error: tsc must report it (the check above can fail).
const BROKEN = `
import { loadAnchoredAsset } from '@gsverse/web/playcanvas';
import { remapCpu } from '@gsverse/web';
import type { AppBase } from 'playcanvas';
export async function broken(app: AppBase): Promise<string> {
    const { anchored } = await loadAnchoredAsset(app, 'asset.glb');
    const ms: string = anchored[0].lastRemapMs;
    return ms + remapCpu.name;
}
`;

/**
 * @param {string} module @param {string} moduleResolution @param {boolean} [skipLibCheck]
 * @param {string} [file]
 */
function tsconfig(module, moduleResolution, skipLibCheck = false, file = 'index.ts') {
    return JSON.stringify({
        compilerOptions: {
            // skipLibCheck off: the shipped declarations themselves are checked (esnext: the
            // glTF-Transform declarations name Float16Array)
            strict: true, noEmit: true, module, moduleResolution, target: 'es2022', lib: ['esnext', 'dom'],
            skipLibCheck,
        },
        files: [file],
    }, null, 2);
}

test('the packed tarball ships declarations that a strict TypeScript consumer compiles against', { timeout: 300_000 }, async (t) => {
    const tmp = mkdtempSync(join(tmpdir(), 'gsverse-types-'));
    try {
        const packed = run('npm', ['pack', '--pack-destination', tmp], PKG);
        assert.equal(packed.status, 0, `npm pack failed:\n${packed.out}`);
        const tarballs = readdirSync(tmp).filter((f) => f.endsWith('.tgz'));
        assert.equal(tarballs.length, 1, packed.out);
        const tarball = join(tmp, tarballs[0]);

        const listed = run('tar', ['tzf', tarball], tmp);
        assert.equal(listed.status, 0, listed.out);
        const files = new Set(listed.out.split('\n').filter(Boolean).map((f) => f.replace(/^package\//, '')));
        const declared = [pkg.types, ...Object.values(pkg.exports).map((/** @type {any} */ e) => e.types)];
        assert.equal(declared.length, 1 + Object.keys(pkg.exports).length);
        for (const entry of Object.values(pkg.exports)) {
            assert.deepEqual(Object.keys(/** @type {any} */ (entry)), ['types', 'default'], 'the types condition comes first');
        }
        for (const d of declared) {
            assert.match(d, /^\.\/types\/.*\.d\.ts$/);
            assert.ok(files.has(d.slice(2)), `${d} is in the tarball`);
        }
        for (const f of files) {
            if (f.startsWith('src/') && f.endsWith('.js')) {
                assert.ok(files.has(`types/${f.slice(4, -3)}.d.ts`), `declarations of ${f} are in the tarball`);
            }
        }

        const consumer = join(tmp, 'consumer');
        const modules = join(consumer, 'node_modules');
        const unpacked = join(modules, '@gsverse', 'web');
        mkdirSync(unpacked, { recursive: true });
        const untar = run('tar', ['xzf', tarball, '-C', unpacked, '--strip-components=1'], tmp);
        assert.equal(untar.status, 0, untar.out);
        // as npm installs them: besides the peers, @gltf-transform/core's property-graph (the
        // extension classes' declarations name its Graph type) and PlayCanvas's @types/webxr
        const links = [
            'typescript', 'playcanvas', '@gltf-transform/core', '@gltf-transform/extensions', 'property-graph',
            '@types/node', '@types/webxr',
            // the three.js entry point's peers and what @types/three's declarations import
            'three', '@sparkjsdev/spark', '@types/three', '@types/stats.js', '@webgpu/types', 'fflate',
        ];
        for (const name of links) {
            mkdirSync(dirname(join(modules, name)), { recursive: true });
            symlinkSync(join(NM, name), join(modules, name), 'dir');
        }
        writeFileSync(join(consumer, 'package.json'), JSON.stringify({ name: 'consumer', private: true, type: 'module' }));
        writeFileSync(join(consumer, 'index.ts'), CONSUMER);
        writeFileSync(join(consumer, 'three.ts'), THREE_CONSUMER);
        writeFileSync(join(consumer, 'tsconfig.three-bundler.json'), tsconfig('esnext', 'bundler', false, 'three.ts'));
        writeFileSync(join(consumer, 'tsconfig.three-nodenext.json'), tsconfig('nodenext', 'nodenext', true, 'three.ts'));
        writeFileSync(join(consumer, 'tsconfig.nodenext.json'), tsconfig('nodenext', 'nodenext'));
        writeFileSync(join(consumer, 'tsconfig.bundler.json'), tsconfig('esnext', 'bundler'));
        // for the error in the consumer's own code only (quicker: the libraries are not checked)
        writeFileSync(join(consumer, 'tsconfig.quick.json'), tsconfig('nodenext', 'nodenext', true));
        const tsc = join(modules, 'typescript', 'bin', 'tsc');
        /** @param {string} config */
        const compile = (config) => run(process.execPath, [tsc, '-p', config, '--strict', '--noEmit'], consumer);

        await t.test('tsc --strict, moduleResolution nodenext', () => {
            const r = compile('tsconfig.nodenext.json');
            assert.equal(r.status, 0, r.out);
        });
        await t.test('tsc --strict, moduleResolution bundler', () => {
            const r = compile('tsconfig.bundler.json');
            assert.equal(r.status, 0, r.out);
        });
        await t.test('tsc --strict, the three.js entry point (bundler; nodenext with skipLibCheck)', () => {
            for (const config of ['tsconfig.three-bundler.json', 'tsconfig.three-nodenext.json']) {
                const r = compile(config);
                assert.equal(r.status, 0, `${config}:\n${r.out}`);
            }
        });
        await t.test('tsc --strict against the lowest supported PlayCanvas', () => {
            const lowest = JSON.parse(readFileSync(join(NM, 'playcanvas-lowest', 'package.json'), 'utf8')).version;
            rmSync(join(modules, 'playcanvas'));
            symlinkSync(join(NM, 'playcanvas-lowest'), join(modules, 'playcanvas'), 'dir');
            try {
                const r = compile('tsconfig.nodenext.json');
                assert.equal(r.status, 0, `PlayCanvas ${lowest}:\n${r.out}`);
            } finally {
                rmSync(join(modules, 'playcanvas'));
                symlinkSync(join(NM, 'playcanvas'), join(modules, 'playcanvas'), 'dir');
            }
        });
        await t.test('a type error in the consumer is reported', () => {
            writeFileSync(join(consumer, 'index.ts'), BROKEN);
            const r = compile('tsconfig.quick.json');
            assert.notEqual(r.status, 0, 'tsc accepted a type error');
            assert.match(r.out, /index\.ts\(7,11\): error TS2322: Type 'number' is not assignable to type 'string'/);
            assert.doesNotMatch(r.out, /TS7016/, 'the declarations are found');
        });
    } finally {
        rmSync(tmp, { recursive: true, force: true });
    }
});
