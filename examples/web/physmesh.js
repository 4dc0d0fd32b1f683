// The physics mesh of an anchor mesh, and the embedding that drives the anchor mesh from it.
//
// The soft body does not simulate the anchor mesh itself. A mesh reconstructed from a capture
// (~10,000 vertices, ~20,000 faces) costs 25-35 ms per Jolt step; it is open (a few hundred border
// edges), often of genus > 0 (a donut) and full of slivers, and as a shell it crumples or explodes
// when its ends are moved quickly. The shipped capsule's 642-vertex shell, held up by a core of
// spokes, crumples when compressed to 0.6x and stays crumpled when let go. So the anchor mesh is
// embedded in a lattice:
//
// - the lattice: cubes on a grid fitted to the anchor mesh's bounding box (its outer nodes lie on
//   the box), keeping the cells its faces touch and the cells they enclose (whatever the outside
//   cannot reach through untouched cells), so the body is a solid of any topology: open, closed,
//   a torus, several pieces. The resolution is the finest whose node count fits the budget
//   (`DEFAULT_BUDGET`). Each cell is split into 5 tetrahedra; their edges (cell edges and face
//   diagonals) are soft distance constraints, their volumes stiff volume constraints. That mix
//   was measured (README, "Physics mesh"): with stiff distances a compressed lattice can only
//   give way by turning cells inside out, which Jolt's volume constraint (it keeps |volume|) does
//   not resist, and it stays folded when let go; with soft distances and stiff volumes it bulges
//   and springs back.
// - the embedding: each anchor vertex is bound to the 8 corners of the cell it lies in, with
//   trilinear weights (which reproduce any affine motion of the lattice exactly, rigid motions
//   included). The anchor vertex is its own rest position plus the weighted displacement of
//   those nodes,
//       a_i = A_i + sum_j w_ij (x_j - X_j),
//   so at rest (x = X) every anchor vertex is exactly its rest position, bit for bit, and the
//   anchor mesh, whose vertex order the splats are bound to, is only ever moved, never changed.
//
// The welded anchor mesh itself ("surface": edge, shear and bend constraints from its faces, plus
// the core chain and spokes for a closed mesh) is still available (`kind: 'surface'`, `?physics=
// surface` in the demo), for meshes within the budget; its embedding is each anchor vertex's
// welded vertex with weight 1.

/** Largest node count of the physics mesh. Measured with `jolt-physics` 1.1 (wasm-compat, 10
 * iterations) in Node: a lattice of ~800 nodes steps in 1.2-1.6 ms, ~1,450 nodes in 2-3.6 ms,
 * while a 20,000-face reconstructed mesh stepped as it is takes 25-35 ms (README, "Physics mesh"). */
export const DEFAULT_BUDGET = 800;

/**
 * Axis-aligned bounds of 3V positions.
 * @param {ArrayLike<number>} p
 * @returns {{min: number[], max: number[], size: number[], center: number[]}}
 */
export function bounds(p) {
    const min = [Infinity, Infinity, Infinity], max = [-Infinity, -Infinity, -Infinity];
    for (let i = 0; i < p.length; i += 3) {
        for (let k = 0; k < 3; k++) {
            const v = p[i + k];
            if (v < min[k]) min[k] = v;
            if (v > max[k]) max[k] = v;
        }
    }
    const size = [0, 1, 2].map((k) => max[k] - min[k]);
    const center = [0, 1, 2].map((k) => 0.5 * (max[k] + min[k]));
    return { min, max, size, center };
}

/**
 * Weld vertices that share a position (within `tolerance`, absolute units).
 * Positions are snapped to a grid of `tolerance`; exact duplicates always weld.
 * @param {ArrayLike<number>} vertices 3V positions
 * @param {number} tolerance
 * @returns {{map: Uint32Array, positions: Float32Array, count: number}} map: anchor vertex -> welded vertex
 */
export function weldVertices(vertices, tolerance) {
    const n = vertices.length / 3;
    const map = new Uint32Array(n);
    /** @type {Map<string, number>} */
    const seen = new Map();
    const out = [];
    const inv = tolerance > 0 ? 1 / tolerance : 0;
    for (let i = 0; i < n; i++) {
        const x = vertices[3 * i], y = vertices[3 * i + 1], z = vertices[3 * i + 2];
        const key = inv ? `${Math.round(x * inv)},${Math.round(y * inv)},${Math.round(z * inv)}` : `${x},${y},${z}`;
        let w = seen.get(key);
        if (w === undefined) {
            w = out.length / 3;
            seen.set(key, w);
            out.push(x, y, z);
        }
        map[i] = w;
    }
    return { map, positions: new Float32Array(out), count: out.length / 3 };
}

/**
 * Faces on welded vertices, without degenerate or repeated faces.
 * @param {ArrayLike<number>} indices 3F anchor-vertex indices
 * @param {Uint32Array} map anchor vertex -> welded vertex
 * @returns {Uint32Array}
 */
export function weldFaces(indices, map) {
    const out = [];
    const seen = new Set();
    for (let f = 0; f < indices.length; f += 3) {
        const a = map[indices[f]], b = map[indices[f + 1]], c = map[indices[f + 2]];
        if (a === b || b === c || a === c) continue;
        const key = [a, b, c].sort((p, q) => p - q).join(',');
        if (seen.has(key)) continue;
        seen.add(key);
        out.push(a, b, c);
    }
    return new Uint32Array(out);
}

/**
 * Whether a triangle mesh is closed (every edge shared by exactly two faces).
 * @param {ArrayLike<number>} faces
 * @returns {boolean}
 */
export function isClosed(faces) {
    /** @type {Map<number, number>} */
    const count = new Map();
    for (let f = 0; f < faces.length; f += 3) {
        for (let e = 0; e < 3; e++) {
            const a = faces[f + e], b = faces[f + (e + 1) % 3];
            const key = a < b ? a * 4294967296 + b : b * 4294967296 + a;
            count.set(key, (count.get(key) || 0) + 1);
        }
    }
    if (count.size === 0) return false;
    for (const c of count.values()) if (c !== 2) return false;
    return true;
}

/**
 * Interior points of a closed mesh: `count` points evenly spread along its longest axis through
 * the centroid (count 1: the centroid; 0: about two per thickness along the axis).
 * @param {ArrayLike<number>} p 3W positions
 * @param {number} count
 * @returns {number[]}
 */
export function coreVertices(p, count) {
    const n = p.length / 3;
    const c = [0, 0, 0];
    for (let i = 0; i < n; i++) for (let k = 0; k < 3; k++) c[k] += p[3 * i + k] / n;
    const b = bounds(p);
    const axis = b.size.indexOf(Math.max(...b.size));
    if (count <= 0) {
        const others = b.size.filter((_, k) => k !== axis);
        const thick = Math.max(1e-9, 0.5 * (others[0] + others[1]));
        count = Math.max(1, Math.min(12, Math.round(2 * b.size[axis] / thick)));
    }
    if (count <= 1) return c;
    const out = [];
    for (let j = 0; j < count; j++) {
        const q = c.slice();
        q[axis] = b.min[axis] + b.size[axis] * (j + 0.5) / count;
        out.push(...q);
    }
    return out;
}

// ---- triangle / box overlap (separating axes, after Akenine-Möller) ---------------------------

/**
 * Whether the triangle (v0, v1, v2) overlaps the box centred at `c` with half sizes `h`.
 * @param {number[]} c @param {number[]} h @param {number[]} v0 @param {number[]} v1 @param {number[]} v2
 */
export function triangleOverlapsBox(c, h, v0, v1, v2) {
    const a = [v0[0] - c[0], v0[1] - c[1], v0[2] - c[2]];
    const b = [v1[0] - c[0], v1[1] - c[1], v1[2] - c[2]];
    const d = [v2[0] - c[0], v2[1] - c[1], v2[2] - c[2]];
    // the box's face normals
    for (let k = 0; k < 3; k++) {
        if (Math.min(a[k], b[k], d[k]) > h[k] || Math.max(a[k], b[k], d[k]) < -h[k]) return false;
    }
    const e = [[b[0] - a[0], b[1] - a[1], b[2] - a[2]], [d[0] - b[0], d[1] - b[1], d[2] - b[2]], [a[0] - d[0], a[1] - d[1], a[2] - d[2]]];
    // the triangle's plane
    const n = [e[0][1] * e[1][2] - e[0][2] * e[1][1], e[0][2] * e[1][0] - e[0][0] * e[1][2], e[0][0] * e[1][1] - e[0][1] * e[1][0]];
    const r = h[0] * Math.abs(n[0]) + h[1] * Math.abs(n[1]) + h[2] * Math.abs(n[2]);
    const s = n[0] * a[0] + n[1] * a[1] + n[2] * a[2];
    if (Math.abs(s) > r) return false;
    // the nine cross products of box axes and triangle edges
    for (const ed of e) {
        for (let k = 0; k < 3; k++) {
            // axis = unit_k x ed
            const ax = [0, 0, 0];
            const k1 = (k + 1) % 3, k2 = (k + 2) % 3;
            ax[k1] = -ed[k2];
            ax[k2] = ed[k1];
            const pa = ax[0] * a[0] + ax[1] * a[1] + ax[2] * a[2];
            const pb = ax[0] * b[0] + ax[1] * b[1] + ax[2] * b[2];
            const pd = ax[0] * d[0] + ax[1] * d[1] + ax[2] * d[2];
            const rad = h[0] * Math.abs(ax[0]) + h[1] * Math.abs(ax[1]) + h[2] * Math.abs(ax[2]);
            if (Math.min(pa, pb, pd) > rad || Math.max(pa, pb, pd) < -rad) return false;
        }
    }
    return true;
}

// ---- the lattice ------------------------------------------------------------------------------

/**
 * A grid fitted to a bounding box: `n[k]` cells of size `h[k]` from `min[k]` along each axis, so
 * that the outer nodes lie on the box (cells close to cubes of side `cell`).
 * @param {{min: number[], size: number[]}} box @param {number} cell
 */
export function fitGrid(box, cell) {
    const min = box.min.slice(), n = [1, 1, 1], h = [cell, cell, cell];
    for (let k = 0; k < 3; k++) {
        if (box.size[k] > 1e-3 * cell) {
            n[k] = Math.max(1, Math.ceil(box.size[k] / cell - 1e-9));
            h[k] = box.size[k] / n[k];
        } else {
            min[k] = box.min[k] + 0.5 * box.size[k] - 0.5 * cell;     // flat along k: one cell thick
        }
    }
    return { min, n, h };
}

/**
 * The cell of a point (clamped to the grid) and its position in the cell (0..1 per axis).
 * @param {{min: number[], n: number[], h: number[]}} g @param {ArrayLike<number>} p @param {number} o offset into p
 * @param {number[]} cell out: cell indices @param {number[]} t out: local coordinates
 */
function locate(g, p, o, cell, t) {
    for (let k = 0; k < 3; k++) {
        const s = (p[o + k] - g.min[k]) / g.h[k];
        const c = Math.min(g.n[k] - 1, Math.max(0, Math.floor(s)));
        cell[k] = c;
        t[k] = Math.min(1, Math.max(0, s - c));
    }
}

/**
 * Cells of the grid the surface touches (faces overlapping a cell, and every vertex's cell) and
 * the cells it encloses (not reachable from outside the grid through untouched cells).
 * @param {{min: number[], n: number[], h: number[]}} g
 * @param {ArrayLike<number>} p 3W positions @param {ArrayLike<number>} faces
 * @returns {Uint8Array} 1 per occupied cell, index i + n0 * (j + n1 * k)
 */
export function occupiedCells(g, p, faces) {
    const [n0, n1, n2] = g.n;
    const occ = new Uint8Array(n0 * n1 * n2);
    const cell = [0, 0, 0], t = [0, 0, 0];
    for (let i = 0; i < p.length; i += 3) {
        locate(g, p, i, cell, t);
        occ[cell[0] + n0 * (cell[1] + n1 * cell[2])] = 1;
    }
    const half = g.h.map((x) => 0.5 * x * (1 + 1e-6));
    const c = [0, 0, 0];
    for (let f = 0; f < faces.length; f += 3) {
        const v = [0, 1, 2].map((j) => [p[3 * faces[f + j]], p[3 * faces[f + j] + 1], p[3 * faces[f + j] + 2]]);
        const lo = [0, 0, 0], hi = [0, 0, 0];
        for (let k = 0; k < 3; k++) {
            const a = Math.min(v[0][k], v[1][k], v[2][k]), b = Math.max(v[0][k], v[1][k], v[2][k]);
            // cells whose (slightly grown) box may touch the face's box; a face on a grid plane
            // touches the cells on both sides, a face on the grid's outer plane the last cell
            lo[k] = Math.min(g.n[k] - 1, Math.max(0, Math.floor((a - g.min[k]) / g.h[k] - 1e-6)));
            hi[k] = Math.min(g.n[k] - 1, Math.max(0, Math.floor((b - g.min[k]) / g.h[k] + 1e-6)));
        }
        for (let z = lo[2]; z <= hi[2]; z++) {
            for (let y = lo[1]; y <= hi[1]; y++) {
                for (let x = lo[0]; x <= hi[0]; x++) {
                    const id = x + n0 * (y + n1 * z);
                    if (occ[id]) continue;
                    c[0] = g.min[0] + (x + 0.5) * g.h[0]; c[1] = g.min[1] + (y + 0.5) * g.h[1]; c[2] = g.min[2] + (z + 0.5) * g.h[2];
                    if (triangleOverlapsBox(c, half, v[0], v[1], v[2])) occ[id] = 1;
                }
            }
        }
    }
    // flood the outside from the grid's border cells; what it cannot reach is enclosed
    const outside = new Uint8Array(occ.length);
    const queue = new Int32Array(occ.length);
    let head = 0, tail = 0;
    const push = (/** @type {number} */ x, /** @type {number} */ y, /** @type {number} */ z) => {
        if (x < 0 || y < 0 || z < 0 || x >= n0 || y >= n1 || z >= n2) return;
        const id = x + n0 * (y + n1 * z);
        if (occ[id] || outside[id]) return;
        outside[id] = 1;
        queue[tail++] = id;
    };
    for (let z = 0; z < n2; z++) {
        for (let y = 0; y < n1; y++) {
            for (let x = 0; x < n0; x++) {
                if (x === 0 || y === 0 || z === 0 || x === n0 - 1 || y === n1 - 1 || z === n2 - 1) push(x, y, z);
            }
        }
    }
    while (head < tail) {
        const id = queue[head++];
        const x = id % n0, y = Math.floor(id / n0) % n1, z = Math.floor(id / (n0 * n1));
        push(x - 1, y, z); push(x + 1, y, z); push(x, y - 1, z); push(x, y + 1, z); push(x, y, z - 1); push(x, y, z + 1);
    }
    for (let i = 0; i < occ.length; i++) if (!outside[i]) occ[i] = 1;
    return occ;
}

/** Corner offsets of a cell, corner c = x + 2y + 4z. */
const CORNERS = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0, 0, 1], [1, 0, 1], [0, 1, 1], [1, 1, 1]];
/** Five tetrahedra of a cube (corner indices), and the mirrored set for alternate cells, so that
 * neighbouring cells share their face diagonals. */
const TETS = [[[0, 1, 2, 4], [1, 3, 2, 7], [1, 2, 4, 7], [1, 4, 5, 7], [2, 4, 7, 6]],
    [[0, 1, 3, 5], [0, 3, 2, 6], [0, 5, 4, 6], [3, 5, 7, 6], [0, 3, 5, 6]]];
/** Faces of a cell: the neighbour's offset and the corners of the face, counter-clockwise seen
 * from outside. */
const CELL_FACES = /** @type {[number[], number[]][]} */ ([
    [[-1, 0, 0], [0, 4, 6, 2]], [[1, 0, 0], [1, 3, 7, 5]],
    [[0, -1, 0], [0, 1, 5, 4]], [[0, 1, 0], [2, 6, 7, 3]],
    [[0, 0, -1], [0, 2, 3, 1]], [[0, 0, 1], [4, 5, 7, 6]],
]);

/**
 * Nodes of the occupied cells of a grid.
 * @param {{min: number[], n: number[], h: number[]}} g @param {Uint8Array} occ
 * @returns {{index: Int32Array, count: number}} index: grid node -> lattice node (-1: none)
 */
function latticeNodes(g, occ) {
    const [n0, n1, n2] = g.n;
    const index = new Int32Array((n0 + 1) * (n1 + 1) * (n2 + 1)).fill(-1);
    let count = 0;
    for (let z = 0; z < n2; z++) {
        for (let y = 0; y < n1; y++) {
            for (let x = 0; x < n0; x++) {
                if (!occ[x + n0 * (y + n1 * z)]) continue;
                for (const o of CORNERS) {
                    const id = x + o[0] + (n0 + 1) * (y + o[1] + (n1 + 1) * (z + o[2]));
                    if (index[id] < 0) index[id] = count++;
                }
            }
        }
    }
    return { index, count };
}

/**
 * The finest grid fitted to the surface's bounds whose lattice has at most `budget` nodes.
 * @param {ArrayLike<number>} p 3W positions @param {ArrayLike<number>} faces @param {number} budget
 */
export function chooseGrid(p, faces, budget) {
    const box = bounds(p);
    const longest = Math.max(...box.size) || 1;
    /** @param {number} cells cells along the longest axis */
    const attempt = (cells) => {
        const g = fitGrid(box, longest / cells);
        const occ = occupiedCells(g, p, faces);
        return { g, occ, nodes: latticeNodes(g, occ) };
    };
    let lo = 1, hi = 64;
    let best = attempt(lo);
    while (lo < hi) {
        const mid = Math.ceil((lo + hi) / 2);
        const r = attempt(mid);
        if (r.nodes.count <= budget) {
            lo = mid;
            best = r;
        } else {
            hi = mid - 1;
        }
    }
    return best;
}

/**
 * @typedef {object} Embedding
 * @property {number} k         physics vertices per anchor vertex
 * @property {Uint32Array} nodes  k per anchor vertex
 * @property {Float32Array} weights k per anchor vertex (summing to 1)
 */

/**
 * @typedef {object} PhysicsMesh
 * @property {'surface'|'lattice'} kind
 * @property {Float32Array} positions 3N world rest positions of the simulated vertices: the
 *   `count` surface or lattice vertices, then the core vertices (surface kind only)
 * @property {number} count      vertices that are pinned, picked and drawn
 * @property {Uint32Array} faces triangles on them (surface: the welded anchor faces, which give the
 *   edge, shear and bend constraints; lattice: the lattice's outer faces, for the wireframe)
 * @property {boolean} closed
 * @property {Uint32Array} edges extra distance constraints (pairs): spokes and spine, or the
 *   lattice's edges and diagonals
 * @property {Float32Array} edgeCompliance one per extra edge
 * @property {Uint32Array} volumes tetrahedra (4 vertices each) with volume constraints
 * @property {Embedding} embedding
 * @property {string} reason   why this kind was chosen
 * @property {{cells: number[], cellSize: number[]}|null} grid lattice resolution
 */

/**
 * The physics mesh of an anchor mesh (see the head of this file).
 * @param {ArrayLike<number>} vertices 3V anchor vertices (world space)
 * @param {ArrayLike<number>} indices 3F anchor faces
 * @param {{kind?: 'lattice'|'surface', budget?: number, coreCount?: number, spokeCompliance?: number,
 *          edgeCompliance?: number, latticeCompliance?: number, diagonalCompliance?: number}} [options]
 *   kind: 'lattice' (default) or 'surface' (the welded anchor mesh itself, when it has at most
 *   `budget` vertices; a lattice otherwise)
 * @returns {PhysicsMesh}
 */
export function buildPhysicsMesh(vertices, indices, options = {}) {
    const budget = options.budget ?? DEFAULT_BUDGET;
    const box = bounds(vertices);
    const diag = Math.hypot(...box.size) || 1;
    const weld = weldVertices(vertices, diag * 1e-6);
    const faces = weldFaces(indices, weld.map);
    if (faces.length === 0) throw new Error('the anchor mesh has no non-degenerate face');
    const closed = isClosed(faces);
    if (options.kind === 'surface') {
        if (weld.count <= budget) {
            // a closed mesh gets interior "core" vertices tied to the surface by spokes
            const spoke = options.spokeCompliance ?? 1e-4;
            const core = closed && spoke >= 0 ? coreVertices(weld.positions, options.coreCount ?? 0) : [];
            return surfaceMesh(weld, faces, closed, core, options, 'surface requested');
        }
        return latticeMesh(weld, faces, budget, options, `surface requested, but ${weld.count} welded vertices are over the budget of ${budget}`);
    }
    return latticeMesh(weld, faces, budget, options, 'lattice');
}

/**
 * @param {{map: Uint32Array, positions: Float32Array, count: number}} weld
 * @param {Uint32Array} faces @param {boolean} closed @param {number[]} core
 * @param {{spokeCompliance?: number, edgeCompliance?: number}} options @param {string} reason
 * @returns {PhysicsMesh}
 */
function surfaceMesh(weld, faces, closed, core, options, reason) {
    const count = weld.count;
    const positions = new Float32Array(3 * count + core.length);
    positions.set(weld.positions);
    positions.set(core, 3 * count);
    // spokes: every surface vertex to its two nearest core vertices; a spine along the core
    const edges = [], comp = [];
    const nc = core.length / 3;
    const spoke = options.spokeCompliance ?? 1e-4;
    for (let i = 0; i < count && nc; i++) {
        const d = [];
        for (let k = 0; k < nc; k++) {
            let q = 0;
            for (let j = 0; j < 3; j++) q += (positions[3 * i + j] - core[3 * k + j]) ** 2;
            d.push([q, k]);
        }
        d.sort((x, y) => x[0] - y[0]);
        for (const [, k] of d.slice(0, Math.min(2, nc))) { edges.push(i, count + k); comp.push(spoke); }
    }
    for (let k = 0; k + 1 < nc; k++) { edges.push(count + k, count + k + 1); comp.push(options.edgeCompliance ?? 1e-3); }
    return {
        kind: 'surface', positions, count, faces, closed,
        edges: new Uint32Array(edges), edgeCompliance: new Float32Array(comp), volumes: new Uint32Array(0),
        embedding: { k: 1, nodes: weld.map, weights: new Float32Array(weld.map.length).fill(1) },
        reason, grid: null,
    };
}

/**
 * @param {{map: Uint32Array, positions: Float32Array, count: number}} weld
 * @param {Uint32Array} faces @param {number} budget
 * @param {{latticeCompliance?: number, diagonalCompliance?: number}} options
 * @param {string} reason
 * @returns {PhysicsMesh}
 */
function latticeMesh(weld, faces, budget, options, reason) {
    const { g, occ, nodes } = chooseGrid(weld.positions, faces, budget);
    const [n0, n1, n2] = g.n;
    const nodeId = (/** @type {number} */ x, /** @type {number} */ y, /** @type {number} */ z) => nodes.index[x + (n0 + 1) * (y + (n1 + 1) * z)];
    const positions = new Float32Array(3 * nodes.count);
    for (let z = 0; z <= n2; z++) {
        for (let y = 0; y <= n1; y++) {
            for (let x = 0; x <= n0; x++) {
                const i = nodeId(x, y, z);
                if (i < 0) continue;
                positions[3 * i] = g.min[0] + x * g.h[0];
                positions[3 * i + 1] = g.min[1] + y * g.h[1];
                positions[3 * i + 2] = g.min[2] + z * g.h[2];
            }
        }
    }
    const edgeC = options.latticeCompliance ?? 1e-2, diagC = options.diagonalCompliance ?? 1e-2;
    /** @type {Map<number, number>} */
    const edgeSet = new Map();
    const volumes = [], outer = [];
    for (let z = 0; z < n2; z++) {
        for (let y = 0; y < n1; y++) {
            for (let x = 0; x < n0; x++) {
                if (!occ[x + n0 * (y + n1 * z)]) continue;
                const c = CORNERS.map((o) => nodeId(x + o[0], y + o[1], z + o[2]));
                for (const t of TETS[(x + y + z) & 1]) {
                    for (let a = 0; a < 4; a++) {
                        for (let b = a + 1; b < 4; b++) {
                            const i = Math.min(c[t[a]], c[t[b]]), j = Math.max(c[t[a]], c[t[b]]);
                            const along = t[a] ^ t[b];          // corner bits that differ: one for a cell edge
                            edgeSet.set(i * 4294967296 + j, along === 1 || along === 2 || along === 4 ? edgeC : diagC);
                        }
                    }
                }
                for (const t of TETS[(x + y + z) & 1]) {
                    // Jolt keeps the signed volume (x2-x1)x(x3-x1).(x4-x1) at |rest volume|:
                    // orient every tetrahedron positively, or half of them turn inside out
                    const q = t.map((j) => CORNERS[j]);
                    const a = [0, 1, 2].map((k) => (q[1][k] - q[0][k]) * g.h[k]);
                    const b = [0, 1, 2].map((k) => (q[2][k] - q[0][k]) * g.h[k]);
                    const d = [0, 1, 2].map((k) => (q[3][k] - q[0][k]) * g.h[k]);
                    const six = a[0] * (b[1] * d[2] - b[2] * d[1]) - a[1] * (b[0] * d[2] - b[2] * d[0]) + a[2] * (b[0] * d[1] - b[1] * d[0]);
                    if (six > 0) volumes.push(c[t[0]], c[t[1]], c[t[2]], c[t[3]]);
                    else volumes.push(c[t[0]], c[t[2]], c[t[1]], c[t[3]]);
                }
                for (const [o, q] of CELL_FACES) {
                    const nx = x + o[0], ny = y + o[1], nz = z + o[2];
                    const inside = nx >= 0 && ny >= 0 && nz >= 0 && nx < n0 && ny < n1 && nz < n2 && occ[nx + n0 * (ny + n1 * nz)];
                    if (!inside) outer.push(c[q[0]], c[q[1]], c[q[2]], c[q[0]], c[q[2]], c[q[3]]);
                }
            }
        }
    }
    const edges = new Uint32Array(2 * edgeSet.size), comp = new Float32Array(edgeSet.size);
    let e = 0;
    for (const [key, cc] of edgeSet) {
        edges[2 * e] = Math.floor(key / 4294967296);
        edges[2 * e + 1] = key % 4294967296;
        comp[e++] = cc;
    }
    // embedding: the corners of each anchor vertex's cell, trilinear weights
    const A = weld.map.length;
    const nodesOut = new Uint32Array(8 * A), weights = new Float32Array(8 * A);
    const cell = [0, 0, 0], t = [0, 0, 0];
    const wNodes = new Uint32Array(8 * weld.count), wWeights = new Float32Array(8 * weld.count);
    for (let i = 0; i < weld.count; i++) {
        locate(g, weld.positions, 3 * i, cell, t);
        for (let q = 0; q < 8; q++) {
            const o = CORNERS[q];
            const id = nodeId(cell[0] + o[0], cell[1] + o[1], cell[2] + o[2]);
            if (id < 0) throw new Error('an anchor vertex lies outside the lattice');
            wNodes[8 * i + q] = id;
            wWeights[8 * i + q] = (o[0] ? t[0] : 1 - t[0]) * (o[1] ? t[1] : 1 - t[1]) * (o[2] ? t[2] : 1 - t[2]);
        }
    }
    for (let a = 0; a < A; a++) {
        const w = weld.map[a];
        nodesOut.set(wNodes.subarray(8 * w, 8 * w + 8), 8 * a);
        weights.set(wWeights.subarray(8 * w, 8 * w + 8), 8 * a);
    }
    return {
        kind: 'lattice', positions, count: nodes.count, faces: new Uint32Array(outer), closed: true,
        edges, edgeCompliance: comp, volumes: new Uint32Array(volumes),
        embedding: { k: 8, nodes: nodesOut, weights },
        reason, grid: { cells: g.n.slice(), cellSize: g.h.slice() },
    };
}

/**
 * Anchor vertices from physics vertices: a_i = A_i + sum_j w_ij (x_j - X_j) (see the head of
 * this file).
 * @param {Embedding} emb
 * @param {ArrayLike<number>} restAnchor 3V rest anchor vertices A
 * @param {ArrayLike<number>} displacement 3N displacements x - X of the physics vertices
 * @param {Float32Array} out 3V
 */
export function applyEmbedding(emb, restAnchor, displacement, out) {
    const { k, nodes, weights } = emb;
    const A = restAnchor.length / 3;
    for (let a = 0; a < A; a++) {
        let dx = 0, dy = 0, dz = 0;
        for (let q = k * a, end = q + k; q < end; q++) {
            const w = weights[q], j = 3 * nodes[q];
            dx += w * displacement[j]; dy += w * displacement[j + 1]; dz += w * displacement[j + 2];
        }
        out[3 * a] = restAnchor[3 * a] + dx;
        out[3 * a + 1] = restAnchor[3 * a + 1] + dy;
        out[3 * a + 2] = restAnchor[3 * a + 2] + dz;
    }
    return out;
}
