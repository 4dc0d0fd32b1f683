// What every browser page of the package's three.js harnesses does with the engine, once:
// a three.js WebGL2 renderer on the page's canvas with Spark's renderer in its scene, and the
// description of the engine and device (harness.json). The three.js twin of engine-page.js.

import * as THREE from 'three';
import { SparkRenderer } from '@sparkjsdev/spark';

/**
 * A three.js WebGL2 renderer on `canvas`, a scene holding a SparkRenderer, rendering only when asked.
 * @param {HTMLCanvasElement} canvas
 * @param {{width?: number, height?: number}} [options]  a fixed canvas size (else the canvas's own)
 */
export function startThree(canvas, options = {}) {
    if (options.width && options.height) {
        canvas.width = options.width;
        canvas.height = options.height;
    }
    const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, alpha: false, preserveDrawingBuffer: true });
    renderer.setPixelRatio(1);
    renderer.setSize(canvas.width, canvas.height, false);
    const scene = new THREE.Scene();
    const spark = new SparkRenderer({ renderer });
    scene.add(spark);
    return { renderer, scene, spark };
}

/**
 * The engine and device, as the harnesses report them (harness.json).
 * @param {THREE.WebGLRenderer} renderer
 */
export function describeThree(renderer) {
    const gl = renderer.getContext();
    const info = gl.getExtension('WEBGL_debug_renderer_info');
    const p = gl.getShaderPrecisionFormat(gl.FRAGMENT_SHADER, gl.HIGH_FLOAT);
    return {
        engine: 'three.js + Spark', engine_version: `three ${THREE.REVISION}`, device: 'webgl2',
        renderer: info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER),
        vendor: info ? gl.getParameter(info.UNMASKED_VENDOR_WEBGL) : gl.getParameter(gl.VENDOR),
        version: gl.getParameter(gl.VERSION), shading_language: gl.getParameter(gl.SHADING_LANGUAGE_VERSION),
        float_precision: p ? `highp float: precision ${p.precision} bits, range 2^${p.rangeMin}..2^${p.rangeMax}` : 'unknown',
        user_agent: navigator.userAgent,
    };
}
