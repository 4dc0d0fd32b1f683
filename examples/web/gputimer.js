// GPU time of the remap, where the device has timer queries.
//
// The remap runs inside PlayCanvas's unified gsplat pipeline, in the work-buffer pass (the
// `gsplatModifyVS` chunk installed by @gsverse/web/playcanvas), where the engine also copies
// every splat of every gsplat in view into its work buffer: timing that pass times the copy as
// much as the remap. The remap's own cost is measured apart: about once a second, the plugin's
// RemapProbe (the same remap chunk run alone through the engine's GSplatProcessor over the
// primitive's splats, into three float output streams) is run under a TIME_ELAPSED query, one
// per anchored primitive, on the current vertices. Both figures are kept: `remapMs` (the remap
// alone) and `workBufferMs` (the whole work-buffer pass, for comparison).
//
// Where WebGL2 has no EXT_disjoint_timer_query_webgl2 (e.g. SwiftShader) nothing is timed on the
// GPU and `available` is false; the demo says so and shows the CPU side of the vertex update.
// The work-buffer wrapper reaches the work buffer through engine internals of PlayCanvas 2.23 and
// gives up quietly where they are not found; a probe that cannot be built is given up the same
// way (`probeError`).

/** @typedef {{gpu: any, prim: {count: number}}} AnchoredLike  an AnchoredSplat */
/** @typedef {{run: (v?: ArrayLike<number>) => void, read: () => Promise<unknown>, destroy: () => void}} Probe  a RemapProbe */

export class RemapTimer {
    /**
     * @param {any} app a PlayCanvas AppBase
     * @param {(gpu: any) => Probe} makeProbe
     *   builds a RemapProbe for an AnchoredSplat's `gpu`
     * @param {{interval?: number}} [options] ms between remap timings
     */
    constructor(app, makeProbe, options = {}) {
        this.app = app;
        this.makeProbe = makeProbe;
        this.interval = options.interval ?? 1000;
        const device = app.graphicsDevice;
        this.gl = /** @type {WebGL2RenderingContext|null} */ (device.isWebGL2 ? device.gl : null);
        /** @type {any} */
        this.ext = this.gl ? device.extDisjointTimerQuery : null;
        /** GPU time of the latest remap timing (all anchored primitives), ms; null until measured */
        this.remapMs = /** @type {number|null} */ (null);
        /** splats the latest remap timing covered */
        this.remapSplats = 0;
        /** GPU time of the latest work-buffer pass, ms; null until measured */
        this.workBufferMs = /** @type {number|null} */ (null);
        /** why a remap probe could not be built, or null */
        this.probeError = /** @type {string|null} */ (null);
        /** @type {Map<object, Probe>} */
        this.probes = new Map();
        /** @type {WeakSet<object>} */
        this.patched = new WeakSet();
        /** @type {{q: WebGLQuery, kind: 'remap'|'work', splats: number}[]} */
        this.pending = [];
        this.last = -Infinity;
        this.found = false;
    }

    /** Whether GPU timings can be taken on this device. */
    get available() {
        return !!this.ext;
    }

    /**
     * Call once a frame, before the frame renders: collects finished queries, wraps new work
     * buffers, and about once per `interval` times the remap of `anchored` on its own.
     * @param {AnchoredLike[]} anchored
     */
    update(anchored) {
        if (!this.ext) return;
        const gl = /** @type {WebGL2RenderingContext} */ (this.gl);
        this.patch();
        if (gl.getParameter(this.ext.GPU_DISJOINT_EXT)) {
            for (const p of this.pending) gl.deleteQuery(p.q);
            this.pending = [];
        }
        while (this.pending.length) {
            const p = this.pending[0];
            if (!gl.getQueryParameter(p.q, gl.QUERY_RESULT_AVAILABLE)) break;
            const ms = gl.getQueryParameter(p.q, gl.QUERY_RESULT) / 1e6;
            if (p.kind === 'remap') {
                this.remapMs = ms;
                this.remapSplats = p.splats;
            } else {
                this.workBufferMs = ms;
            }
            gl.deleteQuery(p.q);
            this.pending.shift();
        }
        const now = performance.now();
        if (anchored.length && now - this.last >= this.interval && this.pending.length < 8) {
            this.last = now;
            this.timeRemap(anchored);
        }
    }

    /**
     * Run the remap of every anchored primitive alone under one timer query.
     * @param {AnchoredLike[]} anchored
     * @private
     */
    timeRemap(anchored) {
        const probes = [];
        for (const s of anchored) {
            const p = this.probe(s);
            if (p) probes.push(p);
        }
        if (!probes.length) return;
        const gl = /** @type {WebGL2RenderingContext} */ (this.gl);
        const q = gl.createQuery();
        if (!q) return;
        gl.beginQuery(this.ext.TIME_ELAPSED_EXT, q);
        try {
            for (const p of probes) p.run();
        } finally {
            gl.endQuery(this.ext.TIME_ELAPSED_EXT);
        }
        this.pending.push({ q, kind: 'remap', splats: anchored.reduce((n, s) => n + s.prim.count, 0) });
    }

    /**
     * The probe of an anchored primitive (built on first use), or null if it cannot be built.
     * @param {AnchoredLike} splat
     */
    probe(splat) {
        let p = this.probes.get(splat);
        if (p || this.probeError) return p ?? null;
        try {
            p = this.makeProbe(splat.gpu);
            this.probes.set(splat, p);
            return p;
        } catch (err) {
            this.probeError = String(/** @type {any} */ (err)?.message ?? err);
            return null;
        }
    }

    /**
     * Wall-clock time of one remap of `anchored` run alone, waited for by reading the last
     * primitive's results back (RemapProbe.read), ms: on a software rasterizer this is the CPU's
     * emulation of the pass, not GPU time; elsewhere it includes the readback.
     * @param {AnchoredLike[]} anchored
     * @returns {Promise<number|null>}
     */
    async fencedRemapMs(anchored) {
        const probes = anchored.map((s) => this.probe(s)).filter((p) => p !== null);
        if (!probes.length) return null;
        const t0 = performance.now();
        for (const p of probes) p.run();
        await probes[probes.length - 1].read();
        return performance.now() - t0;
    }

    /** Destroy the probes (the asset they belong to is going away). */
    clear() {
        for (const p of this.probes.values()) p.destroy();
        this.probes.clear();
        this.probeError = null;
        this.remapMs = null;
        this.workBufferMs = null;
    }

    /** @private */
    patch() {
        const director = this.app.renderer?.gsplatDirector;
        if (!director?.camerasMap) return;
        for (const cameraData of director.camerasMap.values()) {
            for (const layerData of cameraData.layersMap?.values?.() ?? []) {
                for (const manager of [layerData.gsplatManager, layerData.gsplatManagerShadow]) {
                    const wb = manager?.world?.workBuffer;
                    if (!wb || typeof wb.render !== 'function' || this.patched.has(wb)) continue;
                    this.patched.add(wb);
                    this.found = true;
                    const render = wb.render;
                    const timer = this;
                    wb.render = function (/** @type {any[]} */ ...args) {
                        const gl = /** @type {WebGL2RenderingContext} */ (timer.gl);
                        const q = timer.pending.length < 8 ? gl.createQuery() : null;
                        if (q) gl.beginQuery(timer.ext.TIME_ELAPSED_EXT, q);
                        try {
                            return render.apply(this, args);
                        } finally {
                            if (q) {
                                gl.endQuery(timer.ext.TIME_ELAPSED_EXT);
                                timer.pending.push({ q, kind: 'work', splats: 0 });
                            }
                        }
                    };
                }
            }
        }
    }
}
