#!/usr/bin/env node
// Read the KHR_gaussian_splatting primitives of a glTF asset with the
// PlayCanvas engine's own glTF parser, and print what it decoded as JSON.
//
// Usage: node read_khr_glb.mjs FILE.glb|FILE.gltf
//
// The asset goes through the engine's GlbParser.parse (the code path of a
// PlayCanvas "container" asset) on a NullGraphicsDevice, with the engine's
// KHR_gaussian_splatting resource extension registered exactly as the gsplat
// component system registers it.  Nothing is re-implemented here: the
// splat values printed are the engine's GSplatData property arrays, only
// renamed back to KHR terms.  Only self-contained assets are read: GLB
// binary chunks and base64 data: URIs; any other buffer URI is refused.
//
// How PlayCanvas 2.23.3 stores a KHR primitive (khr-gaussian-splatting.js)
// ------------------------------------------------------------------------
// It builds a GSplatData with one "vertex" element whose float32 properties
// use the names of the INRIA 3DGS PLY layout, but with `activated = true`,
// which tells the engine that scales are already linear and opacities are
// already in [0, 1].  (PLY files come in with activated = false: scale_* is
// log-scale and opacity is a logit; the engine then applies exp()/sigmoid.)
// Normalized integer accessors are dequantized by GltfAccessor.getDataFloat32
// (i8 max(c/127,-1), u8 c/255, i16 max(c/32767,-1), u16 c/65535); other
// integer accessors are converted to float unchanged.
//
//   x, y, z                <- POSITION[0..2]
//   rot_0, rot_1, rot_2, rot_3
//                          <- ROTATION w, x, y, z   (KHR stores x, y, z, w;
//                             so KHR xyzw = rot_1, rot_2, rot_3, rot_0; the
//                             engine does not normalise)
//   scale_0..2             <- SCALE[0..2], linear (activated; no log)
//   opacity                <- OPACITY, in [0, 1] (activated; no logit)
//   f_dc_0..2              <- SH_DEGREE_0_COEF_0 r, g, b
//   f_rest_i               <- SH degrees 1..B, channel-major like PLY:
//                             with R = (B+1)^2 - 1 rest coefficients and
//                             j = 0..R-1 the running index over
//                             (l = 1..B, n = 0..2l), f_rest_{c*R + j} is
//                             channel c of SH_DEGREE_l_COEF_n.
// B is the highest degree l for which every SH_DEGREE_l_COEF_n is present
// (and all lower ones); a primitive missing POSITION, ROTATION, SCALE,
// OPACITY or SH_DEGREE_0_COEF_0 (or with a count mismatch) yields no splats.
//
// Row order: the engine then calls GSplatData.reorderData(), which sorts the
// rows by a Morton code of the positions, so the engine's rows are NOT in
// file order.  This script wraps GSplatData.prototype.reorder (without
// changing what it does) to record the permutation: `fileIndex[i]` is the
// row of the file that became engine row i.  The arrays printed are in
// FILE order (engine arrays gathered back through fileIndex); `fileIndex`
// itself is printed too.
//
// Output (stdout, one JSON object):
// {
//   "engine": "playcanvas", "engineVersion": "2.23.3",
//   "splats": [ {                      one per decoded splat primitive
//     "mesh": glTF mesh index,
//     "primitive": primitive index in that mesh, or null if ambiguous,
//     "meshName": name or null,
//     "count": N,
//     "position": [x0,y0,z0, x1,...]                  (N*3)
//     "rotation": [x0,y0,z0,w0, ...]  quaternion xyzw (N*4)
//     "scale":    [sx0,sy0,sz0, ...]  linear          (N*3)
//     "opacity":  [a0, a1, ...]       in [0, 1]       (N)
//     "sh": {"degree": B, "coefficients": K = (B+1)^2,
//            "values": [...]}  (N*K*3) splat-major, then coefficient
//                      k = l*l + n, then channel r,g,b; k = 0 is the DC term
//     "fileIndex": [...]               (N) see "Row order" above
//     "playcanvas": {"activated": bool, "shBands": B,
//                    "properties": [engine property names, in order]}
//   } ],
//   "meshes": [ {                      one per glTF mesh
//     "mesh": index, "name": name or null,
//     "splatPrimitives": number of splat primitives decoded from it,
//     "renderPrimitives": [{"mode": PlayCanvas primitive type (same numbers
//        as glTF mode: 0 points, 4 triangles, ...), "indexed": bool,
//        "count": index or vertex count drawn, "vertexCount": n}]
//        for its other primitives, which the engine builds as ordinary meshes
//   } ]
// }
// Non-finite numbers are written as the strings "NaN", "Infinity" and
// "-Infinity".
// Exit status: 0 on success (also when no splats were found), 2 when the
// file could not be read or parsed.

import fs from 'node:fs';
import path from 'node:path';
import { NullGraphicsDevice, version as engineVersion } from 'playcanvas';
import { GlbParser } from 'playcanvas/build/playcanvas/src/framework/parsers/glb-parser.js';
import { khrGaussianSplatting } from 'playcanvas/build/playcanvas/src/framework/parsers/glb/extensions/khr-gaussian-splatting.js';
import { GSplatData } from 'playcanvas/build/playcanvas/src/scene/gsplat/gsplat-data.js';

const fail = (msg) => {
    process.stderr.write(`read_khr_glb: ${msg}\n`);
    process.exit(2);
};

// Record the permutation the engine applies; behaviour is unchanged.
const engineReorder = GSplatData.prototype.reorder;
GSplatData.prototype.reorder = function (order) {
    this.fileIndexOfRow = Uint32Array.from(order, (v) => (this.fileIndexOfRow ? this.fileIndexOfRow[v] : v));
    return engineReorder.call(this, order);
};

const parseAsset = (filename, bytes) => new Promise((resolve, reject) => {
    const device = new NullGraphicsDevice();
    // The asset registry is only used for images (refused below) and for
    // registry.loader._app (only used for cameras and lights, skipped below).
    const registry = { loader: { _app: null } };
    const options = {
        buffer: {
            // Allow the GLB binary chunk and data: URIs; refuse the rest.
            processAsync: (gltfBuffer, callback) => {
                const uri = gltfBuffer.uri;
                if (uri === undefined || /^data:/i.test(uri)) {
                    callback(null, null);
                } else {
                    callback(`external buffer URI refused: ${uri}`);
                }
            }
        },
        // Images would need the engine's texture loaders (browser APIs):
        // refuse them.  Splat files carry none.
        image: {
            processAsync: (gltfImage, callback) => {
                callback('assets with images are not supported by this reader');
            }
        },
        // Cameras and KHR_lights_punctual lights become components of an
        // application's entities; without an application, skip them.
        camera: { process: () => null },
        light: { process: () => null }
    };
    const data = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
    GlbParser.parse(path.basename(filename), '', data, device, registry, options, [khrGaussianSplatting],
        (err, result) => (err ? reject(new Error(String(err))) : resolve(result)));
});

const toList = (arr) => Array.from(arr, (v) => v);

const describe = (gsplatData, meshIndex, primitiveIndex, meshName) => {
    const n = gsplatData.numSplats;
    const prop = (name) => {
        const p = gsplatData.getProp(name);
        if (!p) {
            throw new Error(`mesh ${meshIndex}: engine data has no property ${name}`);
        }
        return p;
    };
    const fileIndex = gsplatData.fileIndexOfRow ?? Uint32Array.from({ length: n }, (_, i) => i);
    // engine row i holds file row fileIndex[i]; scatter back to file order
    const rowOfFile = new Uint32Array(n);
    for (let i = 0; i < n; i++) rowOfFile[fileIndex[i]] = i;

    const gather = (names) => {
        const cols = names.map(prop);
        const out = new Array(n * names.length);
        for (let f = 0; f < n; f++) {
            const r = rowOfFile[f];
            for (let c = 0; c < cols.length; c++) out[f * cols.length + c] = cols[c][r];
        }
        return out;
    };

    const bands = gsplatData.shBands;
    const rest = (bands + 1) * (bands + 1) - 1;
    const k = rest + 1;
    const shCols = [];
    for (let j = 0; j < k; j++) {
        for (let c = 0; c < 3; c++) {
            shCols.push(j === 0 ? `f_dc_${c}` : `f_rest_${c * rest + (j - 1)}`);
        }
    }

    const activated = gsplatData.activated;
    let scale = gather(['scale_0', 'scale_1', 'scale_2']);
    let opacity = gather(['opacity']);
    if (!activated) {
        // PLY convention (not what the KHR parser produces): undo log/logit.
        scale = scale.map(Math.exp);
        opacity = opacity.map((v) => 1 / (1 + Math.exp(-v)));
    }

    return {
        mesh: meshIndex,
        primitive: primitiveIndex,
        meshName,
        count: n,
        position: gather(['x', 'y', 'z']),
        rotation: gather(['rot_1', 'rot_2', 'rot_3', 'rot_0']),
        scale,
        opacity,
        sh: { degree: bands, coefficients: k, values: gather(shCols) },
        fileIndex: toList(fileIndex),
        playcanvas: {
            activated,
            shBands: bands,
            properties: gsplatData.getElement('vertex').properties.map((p) => p.name)
        }
    };
};

const main = async () => {
    const args = process.argv.slice(2);
    if (args.length !== 1 || args[0].startsWith('-')) {
        fail('usage: node read_khr_glb.mjs FILE.glb|FILE.gltf');
    }
    const file = args[0];
    let bytes;
    try {
        bytes = fs.readFileSync(file);
    } catch (e) {
        fail(`cannot read ${file}: ${e.message}`);
    }
    let result;
    try {
        result = await parseAsset(file, bytes);
    } catch (e) {
        fail(`${file}: PlayCanvas could not parse the asset: ${e.message}`);
    }
    const gltf = result.gltf;
    const perMesh = result[khrGaussianSplatting.resourceName] ?? [];
    const splats = [];
    perMesh.forEach((resources, meshIndex) => {
        if (!resources) return;
        const gltfMesh = gltf.meshes[meshIndex];
        const candidates = [];
        gltfMesh.primitives.forEach((p, j) => {
            if (khrGaussianSplatting.handlesPrimitive(p)) candidates.push(j);
        });
        resources.forEach((resource, ordinal) => {
            const primitiveIndex = candidates.length === resources.length ? candidates[ordinal] : null;
            splats.push(describe(resource.gsplatData, meshIndex, primitiveIndex, gltfMesh.name ?? null));
        });
    });
    // What the engine made of every glTF mesh: splat resources, and ordinary
    // render meshes (PlayCanvas Mesh objects for the non-splat primitives).
    const meshes = (gltf.meshes ?? []).map((gltfMesh, i) => ({
        mesh: i,
        name: gltfMesh.name ?? null,
        splatPrimitives: perMesh[i]?.length ?? 0,
        renderPrimitives: (result.renders[i]?.meshes ?? []).map((m) => ({
            mode: m.primitive[0].type,
            indexed: !!m.primitive[0].indexed,
            count: m.primitive[0].count,
            vertexCount: m.vertexBuffer?.numVertices ?? 0
        }))
    }));
    // JSON has no NaN/Infinity: write such numbers as the strings "NaN",
    // "Infinity", "-Infinity" (Python's float() reads them back).
    const replacer = (key, value) => (typeof value === 'number' && !Number.isFinite(value) ? String(value) : value);
    process.stdout.write(`${JSON.stringify({ engine: 'playcanvas', engineVersion, meshes, splats }, replacer)}\n`);
};

main().catch((e) => fail(e?.stack ?? String(e)));
