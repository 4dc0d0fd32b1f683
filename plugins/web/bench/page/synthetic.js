// The synthetic workload of the browser benchmarks (engine-free): a deforming tube of
// 64 x 64 vertices (8064 faces) and n splats bound to random faces, as an AnchoredPrimitive
// (../../src/types.js), and the tube's deformation at time t. The rest pose is what an engine
// draws without the remap: identity rotations (glTF order x, y, z, w), scales 0.01, opacity 0.5.
// And the medians of the engine benchmark's rounds (bench/engines.mjs).

/** A small deterministic PRNG (mulberry32). @param {number} seed */
function random(seed) {
    return () => {
        seed = (seed + 0x6d2b79f5) | 0;
        let t = Math.imul(seed ^ (seed >>> 15), 1 | seed);
        t = (t + Math.imul(t ^ (t >>> 7), 61 | t)) ^ t;
        return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
    };
}

/**
 * A tube of rings x segments vertices and n splats bound to random faces.
 * @param {number} n @param {'affine'|'rigid'|'games'} law
 */
export function synthetic(n, law, rings = 64, segments = 64) {
    const V = rings * segments;
    const vertices = new Float32Array(3 * V);
    for (let r = 0; r < rings; ++r) {
        for (let s = 0; s < segments; ++s) {
            const a = (2 * Math.PI * s) / segments, v = r * segments + s;
            vertices[3 * v] = Math.cos(a);
            vertices[3 * v + 1] = (4 * r) / (rings - 1) - 2;
            vertices[3 * v + 2] = Math.sin(a);
        }
    }
    const F = 2 * (rings - 1) * segments;
    const indices = new Uint32Array(3 * F);
    let f = 0;
    for (let r = 0; r + 1 < rings; ++r) {
        for (let s = 0; s < segments; ++s) {
            const a = r * segments + s, b = r * segments + ((s + 1) % segments);
            indices.set([a, b, a + segments], 3 * f++);
            indices.set([b, b + segments, a + segments], 3 * f++);
        }
    }
    const rnd = random(12345);
    const faceIndex = new Uint32Array(n), barycentrics = new Float32Array(2 * n);
    const normalOffset = new Float32Array(n), rho = new Float32Array(n);
    const localRotation = new Float32Array(4 * n), localScale = new Float32Array(3 * n);
    const means = new Float32Array(3 * n);
    for (let i = 0; i < n; ++i) {
        const face = Math.floor(rnd() * F);
        let b1 = rnd(), b2 = rnd();
        if (b1 + b2 > 1) { b1 = 1 - b1; b2 = 1 - b2; }
        faceIndex[i] = face; barycentrics[2 * i] = b1; barycentrics[2 * i + 1] = b2;
        normalOffset[i] = 0.02 * (rnd() - 0.5); rho[i] = 0.5 + rnd();
        const q = [rnd() - 0.5, rnd() - 0.5, rnd() - 0.5, rnd() - 0.5];
        const len = Math.hypot(...q);
        for (let k = 0; k < 4; ++k) localRotation[4 * i + k] = q[k] / len;
        for (let k = 0; k < 3; ++k) localScale[3 * i + k] = 0.005 + 0.02 * rnd();
        const i0 = indices[3 * face], i1 = indices[3 * face + 1], i2 = indices[3 * face + 2];
        for (let k = 0; k < 3; ++k) {
            const v0 = vertices[3 * i0 + k];
            means[3 * i + k] = v0 + b1 * (vertices[3 * i1 + k] - v0) + b2 * (vertices[3 * i2 + k] - v0);
        }
    }
    const games = law === 'games';
    /** @type {any} */
    const prim = {
        splatMesh: 0, splatPrimitive: 0, node: null, nodeMatrix: null, count: n, shDegree: 0, shCoefficients: 1,
        rest: {
            means, rotations: new Float32Array(4 * n).map((_, k) => (k % 4 === 3 ? 1 : 0)),
            scales: new Float32Array(3 * n).fill(0.01), opacity: new Float32Array(n).fill(0.5), sh: new Float32Array(3 * n),
        },
        anchorMesh: { mesh: 1, primitive: 0, node: null, vertexCount: V, faceCount: F, indexed: true, vertices, indices },
        profile: games ? 'games' : 'local', deformation: games ? null : law,
        faceIndex, barycentrics, normalOffset: games ? null : normalOffset, localRotation: games ? null : localRotation,
        localScale: games ? null : localScale, rho: games ? rho : null, componentTypes: {},
    };
    return prim;
}

/**
 * A deformation of the tube at time t (bend + twist + breathing).
 * @param {Float32Array} rest @param {Float32Array} out @param {number} t
 */
export function deform(rest, out, t) {
    for (let v = 0; v < rest.length / 3; ++v) {
        const x = rest[3 * v], y = rest[3 * v + 1], z = rest[3 * v + 2];
        const a = 0.3 * Math.sin(t) * y, s = 1 + 0.1 * Math.sin(2 * t + y);
        out[3 * v] = s * (x * Math.cos(a) - z * Math.sin(a)) + 0.1 * Math.sin(t) * y * y;
        out[3 * v + 1] = y * (1 + 0.2 * Math.sin(t));
        out[3 * v + 2] = s * (x * Math.sin(a) + z * Math.cos(a));
    }
}

/** The median of a list of numbers. @param {number[]} x */
export function median(x) {
    const s = x.slice().sort((p, q) => p - q);
    return s.length ? s[Math.floor(s.length / 2)] : NaN;
}

/**
 * Medians of an engine's rounds, and the ratios to its own splat pass.
 * @param {string} engine @param {number} n @param {{[k: string]: number}[]} rows
 */
export function summarize(engine, n, rows) {
    /** @type {{[k: string]: any}} */
    const out = { engine, n, rounds: rows.length };
    for (const key of Object.keys(rows[0] || {})) out[key] = median(rows.map((r) => r[key]));
    out.remapRatio = out.remapMs / out.baseMs;
    out.sortRatio = out.sortMs / out.baseMs;
    return out;
}
