/**
 * The one place where @gsverse/web/playcanvas touches PlayCanvas beyond its documented API, and
 * the check that those places exist. Every engine member the plugin relies on is named here;
 * a missing one throws AnchorError('ENGINE_UNSUPPORTED') naming the running engine version and
 * the supported range, instead of failing later with an undefined property deep in a frame.
 *
 * What the plugin needs, and why:
 *   - the container's per-mesh splat assets (`_meshGSplats`, private): which engine splat
 *     resource belongs to which glTF primitive (the container's flat `gsplats` list skips
 *     primitives the engine could not parse, so it cannot be indexed from the file);
 *   - a splat resource's `gsplatData` (rows in the engine's order, to check our row order),
 *     `format.addExtraStreams` and `getTexture` (the per-splat anchor streams), `centers`,
 *     `centersVersion` and `aabb` (the positions the CPU sorter orders splats by: bumping
 *     `centersVersion` makes the engine send the deformed centres to its sort worker);
 *   - `GSplatData#calcMortonOrder` (the row order the engine's KHR loader applies);
 *   - the gsplat component's work-buffer hook (`setWorkBufferModifier`, `setParameter`,
 *     `deleteParameter`).
 */

import { GSplatData, version as engineVersion } from 'playcanvas';
import { AnchorError } from '../anchor.js';

/** PlayCanvas versions this plugin is tested with (package.json peerDependencies says the same). */
export const SUPPORTED_PLAYCANVAS = '>=2.21.0 <2.24.0';

/** The running engine's version string. */
export const PLAYCANVAS_VERSION = String(engineVersion);

/**
 * [major, minor, patch] of a version string ("2.23.3", "2.23.3-beta.1"), or null.
 * @param {string} v
 * @returns {[number, number, number]|null}
 */
export function parseVersion(v) {
    const m = /^(\d+)\.(\d+)\.(\d+)/.exec(String(v));
    return m ? [Number(m[1]), Number(m[2]), Number(m[3])] : null;
}

/**
 * Whether `version` lies in a range of the form ">=A.B.C <D.E.F".
 * @param {string} version
 * @param {string} [range]
 */
export function inRange(version, range = SUPPORTED_PLAYCANVAS) {
    const v = parseVersion(version);
    const m = /^>=(\S+)\s+<(\S+)$/.exec(range);
    const lo = m && parseVersion(m[1]), hi = m && parseVersion(m[2]);
    if (!v || !lo || !hi) return false;
    const cmp = (/** @type {number[]} */ a, /** @type {number[]} */ b) => (a[0] - b[0]) || (a[1] - b[1]) || (a[2] - b[2]);
    return cmp(v, lo) >= 0 && cmp(v, hi) < 0;
}

/**
 * The error for a missing engine member.
 * @param {string} what  e.g. "GSplatResource#centersVersion"
 */
export function engineError(what) {
    return new AnchorError('ENGINE_UNSUPPORTED',
        `PlayCanvas ${PLAYCANVAS_VERSION}: ${what} not found; @gsverse/web/playcanvas supports PlayCanvas ${SUPPORTED_PLAYCANVAS}`);
}

let warned = false;

/**
 * Check the engine module itself (once per load): the members used before any asset exists.
 * An engine outside the supported range is used with one console warning; each member the
 * plugin needs is still checked where it is first used.
 */
export function checkEngine() {
    if (typeof GSplatData?.prototype?.calcMortonOrder !== 'function') throw engineError('GSplatData#calcMortonOrder');
    if (!warned && !inRange(PLAYCANVAS_VERSION)) {
        warned = true;
        console.warn(`@gsverse/web/playcanvas: PlayCanvas ${PLAYCANVAS_VERSION} is outside the tested range ${SUPPORTED_PLAYCANVAS}; continuing (a missing engine member is reported as ENGINE_UNSUPPORTED)`);
    }
}

/**
 * The engine splat assets of glTF mesh `mesh`, in primitive order (KHR primitives only).
 * @param {any} container  the engine's GlbContainerResource
 * @param {number} mesh
 * @returns {any[]|null}
 */
export function meshSplatAssets(container, mesh) {
    const table = container?._meshGSplats;
    if (!Array.isArray(table)) throw engineError('GlbContainerResource#_meshGSplats (splat assets per glTF mesh)');
    return table[mesh] ?? null;
}

/**
 * Check a splat resource for everything the plugin reads or writes on it.
 * @param {any} resource  GSplatResource
 */
export function checkResource(resource) {
    if (typeof resource?.numSplats !== 'number') throw engineError('GSplatResource#numSplats');
    if (typeof resource.format?.addExtraStreams !== 'function') throw engineError('GSplatResource#format.addExtraStreams');
    if (typeof resource.getTexture !== 'function') throw engineError('GSplatResource#getTexture');
    if (!(resource.centers instanceof Float32Array) || resource.centers.length < 3 * resource.numSplats) {
        throw engineError('GSplatResource#centers (CPU splat centres)');
    }
    if (typeof resource.centersVersion !== 'number') throw engineError('GSplatResource#centersVersion');
    if (typeof resource.aabb?.setMinMax !== 'function') throw engineError('GSplatResource#aabb');
}

/**
 * Check a gsplat component for the work-buffer hook.
 * @param {any} component  GSplatComponent
 */
export function checkComponent(component) {
    for (const name of ['setWorkBufferModifier', 'setParameter', 'deleteParameter']) {
        if (typeof component?.[name] !== 'function') throw engineError(`GSplatComponent#${name}`);
    }
}

/**
 * Tell the engine that the resource's CPU centres changed (the array was written in place):
 * the next frame sends them to the sort worker and sorts again.
 * @param {any} resource
 */
export function centersChanged(resource) {
    resource.centersVersion++;
}
