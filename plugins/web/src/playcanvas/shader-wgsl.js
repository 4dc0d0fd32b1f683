/**
 * WGSL (WebGPU) twin of shader.js: the same remap, line for line, for PlayCanvas's WebGPU
 * device. Inputs, precision rules and the Jacobi decomposition are documented in shader.js;
 * only the syntax differs (uniforms through `uniform.`, textures `texture_2d<uff>` /
 * `texture_2d<u32>`, out-parameters returned in a struct, pointers for in-out matrices).
 * The conformance suite runs it through GSplatProcessor (`run-browser.mjs --backend webgpu`);
 * the work-buffer modifier below is the same remap plus the engine's instance transform, but
 * headless Chromium with a software WebGPU adapter cannot present a canvas, so the WebGPU
 * render path is exercised only on machines with a WebGPU-capable browser.
 */

import {
    FAULTS, GSV_JACOBI_SWEEPS, STREAM_ANCHOR, STREAM_LOCAL_ROT, STREAM_LOCAL_SCALE,
    STREAM_OUT_MEAN, STREAM_OUT_ROT, STREAM_OUT_SCALE,
} from './shader.js';

/** @param {string} s */
const cap = (s) => s.charAt(0).toUpperCase() + s.slice(1);

/**
 * The remap functions in WGSL (shared by the render and the conformance pass on WebGPU).
 * @param {{fault?: string|null}} [options]
 * @returns {string}
 */
export function remapChunkWGSL(options = {}) {
    const fault = options.fault ?? null;
    if (fault !== null && !(fault in FAULTS)) {
        throw new Error(`unknown shader fault '${fault}' (known: ${Object.keys(FAULTS).join(', ')})`);
    }
    const localCross = fault === 'frame-axis' ? 'cross(e2, e1)' : 'cross(e1, e2)';
    const gamesU = fault === 'games-axis' ? 'e2 - g' : 'e1 - g';
    const gamesW = fault === 'games-axis' ? 'e1 - g' : 'e2 - g';
    return /* wgsl */ `
// ---- GS-Verse mesh-anchor remap (spec v1.1), WGSL ----
var gsvVertices: texture_2d<uff>;
var gsvFaces: texture_2d<u32>;
var gsvRest: texture_2d<uff>;
uniform gsvLaw: f32;

const GSV_EPS_DEG: f32 = 1e-6;
const GSV_GAMES_EPS: f32 = 1e-8;
const GSV_JACOBI_SWEEPS: i32 = ${GSV_JACOBI_SWEEPS};

struct GsvSplat {
    mean: vec3f,
    quat: vec4f,
    scale: vec3f,
}

fn gsvAt(i: u32, width: u32) -> vec2i { return vec2i(i32(i % width), i32(i / width)); }
fn gsvVertex(i: u32) -> vec3f {
    return textureLoad(gsvVertices, gsvAt(i, textureDimensions(gsvVertices).x), 0).xyz;
}

fn gsvPerp(t: vec3f) -> vec3f {
    let a = abs(t);
    var k = 0;
    if (a.y < a.x) { k = 1; }
    if (a.z < select(a.y, a.x, k == 0)) { k = 2; }
    let u = vec3f(select(0.0, 1.0, k == 0), select(0.0, 1.0, k == 1), select(0.0, 1.0, k == 2));
    let c = cross(t, u);
    return c / sqrt(dot(c, c));
}

fn gsvQuatToMat(q0: vec4f) -> mat3x3f {
    let len = sqrt(dot(q0, q0));
    var q = vec4f(0.0, 0.0, 0.0, 1.0);
    if (len > 0.0) { q = q0 / len; }
    let x = q.x; let y = q.y; let z = q.z; let w = q.w;
    return mat3x3f(
        1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y),
        2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x),
        2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y));
}

fn gsvMatToQuat(m: mat3x3f) -> vec4f {
    let m00 = m[0][0]; let m11 = m[1][1]; let m22 = m[2][2];
    let m01 = m[1][0]; let m02 = m[2][0]; let m10 = m[0][1]; let m12 = m[2][1]; let m20 = m[0][2]; let m21 = m[1][2];
    let tr = m00 + m11 + m22;
    let cand = vec4f(1.0 + 2.0 * m00 - tr, 1.0 + 2.0 * m11 - tr, 1.0 + 2.0 * m22 - tr, 1.0 + tr);
    var k = 0;
    var best = cand.x;
    if (cand.y > best) { k = 1; best = cand.y; }
    if (cand.z > best) { k = 2; best = cand.z; }
    if (cand.w > best) { k = 3; best = cand.w; }
    let s = 2.0 * sqrt(max(best, 0.0));
    if (!(s > 0.0)) { return vec4f(0.0, 0.0, 0.0, 1.0); }
    var q: vec4f;
    if (k == 3) { q = vec4f((m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, s / 4.0); }
    else if (k == 0) { q = vec4f(s / 4.0, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s); }
    else if (k == 1) { q = vec4f((m01 + m10) / s, s / 4.0, (m12 + m21) / s, (m02 - m20) / s); }
    else { q = vec4f((m02 + m20) / s, (m12 + m21) / s, s / 4.0, (m10 - m01) / s); }
    let len = sqrt(dot(q, q));
    return select(q, -q, q.w < 0.0) / len;
}

fn gsvJacobiRotate(a: ptr<function, mat3x3f>, v: ptr<function, mat3x3f>, p: i32, q: i32) {
    let apq = (*a)[q][p];
    if (apq == 0.0) { return; }
    let theta = ((*a)[q][q] - (*a)[p][p]) / (2.0 * apq);
    let t = select(-1.0, 1.0, theta >= 0.0) / (abs(theta) + sqrt(theta * theta + 1.0));
    let c = 1.0 / sqrt(t * t + 1.0);
    let s = t * c;
    var cp = (*a)[p];
    var cq = (*a)[q];
    (*a)[p] = c * cp - s * cq;
    (*a)[q] = s * cp + c * cq;
    *a = transpose(*a);
    cp = (*a)[p];
    cq = (*a)[q];
    (*a)[p] = c * cp - s * cq;
    (*a)[q] = s * cp + c * cq;
    (*a)[q][p] = 0.0;
    (*a)[p][q] = 0.0;
    cp = (*v)[p];
    cq = (*v)[q];
    (*v)[p] = c * cp - s * cq;
    (*v)[q] = s * cp + c * cq;
}

fn gsvCovToRotScale(sigma: mat3x3f, res: ptr<function, GsvSplat>) {
    let m0 = abs(sigma[0]); let m1 = abs(sigma[1]); let m2 = abs(sigma[2]);
    let norm = max(max(max(m0.x, m0.y), max(m0.z, m1.y)), max(m1.z, m2.z));
    if (!(norm > 0.0)) {
        (*res).quat = vec4f(0.0, 0.0, 0.0, 1.0);
        (*res).scale = vec3f(0.0);
        return;
    }
    var a = sigma * (1.0 / norm);
    var v = mat3x3f(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
    for (var sweep = 0; sweep < GSV_JACOBI_SWEEPS; sweep++) {
        gsvJacobiRotate(&a, &v, 0, 1);
        gsvJacobiRotate(&a, &v, 0, 2);
        gsvJacobiRotate(&a, &v, 1, 2);
    }
    if (determinant(v) < 0.0) { v[2] = -v[2]; }
    (*res).quat = gsvMatToQuat(v);
    (*res).scale = sqrt(max(vec3f(a[0][0], a[1][1], a[2][2]) * norm, vec3f(0.0)));
}

fn gsvRemapLocal(anchor: vec4u, localRot: vec4f, localScale: vec3f, rigid: bool) -> GsvSplat {
    var res: GsvSplat;
    let face = anchor.x;
    let b1 = bitcast<f32>(anchor.y); let b2 = bitcast<f32>(anchor.z); let d = bitcast<f32>(anchor.w);
    let corners = textureLoad(gsvFaces, gsvAt(face, textureDimensions(gsvFaces).x), 0);
    let rest = textureLoad(gsvRest, gsvAt(face, textureDimensions(gsvRest).x), 0);
    let v0 = gsvVertex(corners.x);
    let e1 = gsvVertex(corners.y) - v0;
    let e2 = gsvVertex(corners.z) - v0;
    let e3 = e2 - e1;
    let cr = ${localCross};
    let ac = sqrt(dot(cr, cr));
    let s1 = dot(e1, e1); let s2 = dot(e2, e2); let s3 = dot(e3, e3);
    let longest2 = max(max(s1, s2), s3);
    var t: vec3f;
    var n: vec3f;
    if (ac > GSV_EPS_DEG * longest2) {
        t = e1 / sqrt(s1);
        n = cr / ac;
    } else if (longest2 > 0.0) {
        var dir = e1;
        var best = s1;
        if (s2 > best) { dir = e2; best = s2; }
        if (s3 > best) { dir = e3; best = s3; }
        t = dir / sqrt(best);
        n = gsvPerp(t);
    } else {
        t = vec3f(1.0, 0.0, 0.0);
        n = vec3f(0.0, 0.0, 1.0);
    }
    let b = cross(n, t);
    let rc = mat3x3f(t, b, n);
    var k: f32;
    var m: vec3f;
    var a: mat3x3f;
    if (corners.w != 0u) {
        let rootc = sqrt(ac);
        k = rootc * rest.w;
        m = select(vec3f(0.0), cr / rootc * rest.w, rootc > 0.0);
        a = mat3x3f(e1 * rest.x, e1 * rest.y + e2 * rest.z, m);
    } else {
        k = 1.0;
        m = n;
        a = rc;
    }
    res.mean = v0 + (b1 * e1 + b2 * e2 + d * m);
    let rl = gsvQuatToMat(localRot);
    if (rigid) {
        res.quat = gsvMatToQuat(rc * rl);
        res.scale = k * localScale;
    } else {
        let mm = a * mat3x3f(rl[0] * localScale.x, rl[1] * localScale.y, rl[2] * localScale.z);
        gsvCovToRotScale(mm * transpose(mm), &res);
    }
    return res;
}

fn gsvRemapGames(anchor: vec4u) -> GsvSplat {
    var res: GsvSplat;
    let face = anchor.x;
    let a1 = bitcast<f32>(anchor.y); let a2 = bitcast<f32>(anchor.z); let rho = bitcast<f32>(anchor.w);
    let corners = textureLoad(gsvFaces, gsvAt(face, textureDimensions(gsvFaces).x), 0);
    let v0 = gsvVertex(corners.x);
    let e1 = gsvVertex(corners.y) - v0;
    let e2 = gsvVertex(corners.z) - v0;
    let g = (e1 + e2) / 3.0;
    let u = ${gamesU};
    let w = ${gamesW};
    let e3 = e2 - e1;
    let cr = cross(e1, e2);
    let ac = sqrt(dot(cr, cr));
    let longest2 = max(max(dot(e1, e1), dot(e2, e2)), dot(e3, e3));
    let tol = GSV_EPS_DEG * sqrt(longest2);
    let lu = sqrt(dot(u, u));
    var n: vec3f;
    var fb1: vec3f;
    var fb2: vec3f;
    if (ac > GSV_EPS_DEG * longest2) {
        fb1 = u / lu;
        n = cr / ac;
        fb2 = cross(n, fb1);
    } else if (lu > tol) {
        fb1 = u / lu;
        let r = w - dot(w, fb1) * fb1;
        let lr = sqrt(dot(r, r));
        if (lr > tol) { fb2 = r / lr; } else { fb2 = gsvPerp(fb1); }
        n = cross(fb1, fb2);
    } else if (longest2 > 0.0) {
        fb2 = w / sqrt(dot(w, w));
        fb1 = gsvPerp(fb2);
        n = cross(fb1, fb2);
    } else {
        n = vec3f(0.0, 0.0, 1.0);
        fb1 = vec3f(1.0, 0.0, 0.0);
        fb2 = vec3f(0.0, 1.0, 0.0);
    }
    let base = vec3f(GSV_GAMES_EPS, (lu + GSV_GAMES_EPS) / 2.0, dot(w, fb2) / 2.0);
    res.mean = v0 + (a1 * e1 + a2 * e2);
    res.scale = max(rho * base, vec3f(0.0)) + GSV_GAMES_EPS;
    res.quat = gsvMatToQuat(mat3x3f(n, fb1, fb2));
    return res;
}

fn gsvRemapSplat() -> GsvSplat {
    let anchor = load${cap(STREAM_ANCHOR)}();
    if (uniform.gsvLaw > 1.5) {
        return gsvRemapGames(anchor);
    }
    return gsvRemapLocal(anchor, load${cap(STREAM_LOCAL_ROT)}(), load${cap(STREAM_LOCAL_SCALE)}().xyz, uniform.gsvLaw > 0.5);
}
// ---- end of GS-Verse remap ----
`;
}

/**
 * The work-buffer modifier in WGSL (see modifyChunkGLSL).
 * @param {{fault?: string|null}} [options]
 */
export function modifyChunkWGSL(options = {}) {
    const fault = options.fault ?? null;
    const node = fault !== 'node-transform';
    const center = node ? '(uniform.matrix_model * vec4f(gsvLocal.mean, 1.0)).xyz' : 'gsvLocal.mean';
    const quat = node ? 'vec4f(quatMul(half4(uniform.model_rotation), half4(gsvLocal.quat)))' : 'gsvLocal.quat';
    const local = fault === 'scale-swizzle' ? 'gsvLocal.scale.yxz' : 'gsvLocal.scale';
    return `${remapChunkWGSL(options)}
var<private> gsvLocal: GsvSplat;
fn modifySplatCenter(center: ptr<function, vec3f>) {
    gsvLocal = gsvRemapSplat();
    *center = ${center};
}
fn modifySplatRotationScale(originalCenter: vec3f, modifiedCenter: vec3f, rotation: ptr<function, vec4f>, scale: ptr<function, vec3f>) {
    let q = ${quat};
    *rotation = select(q, -q, q.w < 0.0);
    *scale = ${node ? 'uniform.model_scale * ' : ''}${local};
}
fn modifySplatColor(center: vec3f, color: ptr<function, vec4f>) {
}
`;
}

/**
 * `process()` for GSplatProcessor in WGSL (see processChunkGLSL).
 * @param {{fault?: string|null}} [options]
 */
export function processChunkWGSL(options = {}) {
    return `${remapChunkWGSL(options)}
fn process() {
    let r = gsvRemapSplat();
    write${cap(STREAM_OUT_MEAN)}(vec4f(r.mean, 1.0));
    write${cap(STREAM_OUT_ROT)}(r.quat);
    write${cap(STREAM_OUT_SCALE)}(vec4f(r.scale, 0.0));
}
`;
}

/** The remap chunk of the render and of the conformance pass (WGSL), without a fault. */
export const REMAP_WGSL = remapChunkWGSL();
