// GPU time of the remap pass, where the device has timer queries.
//
// The remap runs inside PlayCanvas's unified gsplat pipeline, in the work-buffer copy pass (the
// `gsplatModifyVS` chunk installed by @gsverse/web/playcanvas). Where WebGL2 exposes
// EXT_disjoint_timer_query_webgl2, this wraps that pass of every gsplat manager in a
// TIME_ELAPSED query and reports the GPU time of the latest pass that ran. The engine's own GPU
// profiler only times whole frames in its release build, hence the wrapper; it reaches the work
// buffer through engine internals of PlayCanvas 2.23 and gives up quietly (available = false)
// where they are not found. Without timer queries (e.g. SwiftShader) the demo shows the CPU time
// of the vertex update instead and says so.

export class RemapTimer {
    /** @param {any} app a PlayCanvas AppBase */
    constructor(app) {
        this.app = app;
        const device = app.graphicsDevice;
        this.gl = device.isWebGL2 ? device.gl : null;
        /** @type {any} */
        this.ext = this.gl ? device.extDisjointTimerQuery : null;
        /** GPU time of the latest measured remap pass, ms; null until one is measured */
        this.ms = /** @type {number|null} */ (null);
        /** @type {WeakSet<object>} */
        this.patched = new WeakSet();
        /** @type {WebGLQuery[]} */
        this.pending = [];
        this.found = false;
    }

    /** Whether GPU timings can be taken on this device. */
    get available() {
        return !!this.ext;
    }

    /** Call once a frame: wraps new work buffers, collects finished queries. */
    update() {
        if (!this.ext) return;
        this.patch();
        const gl = /** @type {WebGL2RenderingContext} */ (this.gl);
        if (gl.getParameter(this.ext.GPU_DISJOINT_EXT)) {
            for (const q of this.pending) gl.deleteQuery(q);
            this.pending = [];
            return;
        }
        while (this.pending.length) {
            const q = this.pending[0];
            if (!gl.getQueryParameter(q, gl.QUERY_RESULT_AVAILABLE)) break;
            this.ms = gl.getQueryParameter(q, gl.QUERY_RESULT) / 1e6;
            gl.deleteQuery(q);
            this.pending.shift();
        }
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
                                timer.pending.push(q);
                            }
                        }
                    };
                }
            }
        }
    }
}
