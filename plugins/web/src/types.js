// Shared JSDoc types of @gsverse/web. This module exports nothing at run time; import the
// types with `/** @typedef {import('./types.js').AnchoredPrimitive} AnchoredPrimitive */`.

/**
 * The rest pose of a splat primitive as imported (spec/README.md §Overview;
 * KHR_gaussian_splatting attributes, dequantized).
 * @typedef {object} RestPose
 * @property {Float32Array} means      (3N) POSITION, splat-local space
 * @property {Float32Array} rotations  (4N) unit quaternions x, y, z, w (normalized on import)
 * @property {Float32Array} scales     (3N) linear scales
 * @property {Float32Array} opacity    (N) linear opacity
 * @property {Float32Array} sh         (N*K*3) SH coefficients, coefficient-major (k = l² + n), then RGB
 */

/**
 * The anchor triangle primitive (spec/README.md §The anchor mesh).
 * @typedef {object} AnchorMesh
 * @property {number} mesh          glTF mesh index
 * @property {number} primitive     primitive index in that mesh
 * @property {number|null} node     the node instantiating the anchor mesh (its transform is ignored), or null
 * @property {number} vertexCount   V
 * @property {number} faceCount     F
 * @property {boolean} indexed      false for a non-indexed anchor primitive
 * @property {Float32Array} vertices (3V) rest positions in file order, splat-local space
 * @property {Uint32Array} indices  (3F) corners of each triangle in stored order (0..3F-1 when not indexed)
 */

/**
 * One anchored splat primitive with its anchors, dequantized.
 * @typedef {object} AnchoredPrimitive
 * @property {number} splatMesh         glTF mesh index of the KHR splat primitive
 * @property {number} splatPrimitive    primitive index in that mesh
 * @property {number|null} node         the (first) node instantiating the splat mesh, or null
 * @property {Float64Array|null} nodeMatrix  that node's global matrix (column-major 4x4), or null
 * @property {number} count             N, splats
 * @property {number} shDegree          B
 * @property {number} shCoefficients    K = (B + 1)²
 * @property {RestPose} rest
 * @property {AnchorMesh} anchorMesh
 * @property {'local'|'games'} profile
 * @property {'affine'|'rigid'|null} deformation  null for games
 * @property {'faceIndex'|'faceCounts'} faceEncoding  how the file stores the faces: a face index per
 *   splat, or per-face splat counts (splats grouped by face), expanded to faceIndex on import
 * @property {boolean} derived  true when the file stores no `local` anchors but the face
 *   (no barycentrics): barycentrics, normalOffset, localRotation and localScale were derived on
 *   import in binary64 from the rest pose and the rest anchor triangles, rounded once to float32
 * @property {Uint32Array} faceIndex     (N)
 * @property {Float32Array|Float64Array} barycentrics (2N) b1, b2 (local) or α1, α2 (games), dequantized; b0 = 1 − b1 − b2
 * @property {Float32Array|Float64Array|null} normalOffset  (N) local only
 * @property {Float32Array|Float64Array|null} localRotation (4N) unit x, y, z, w, local only
 * @property {Float32Array|Float64Array|null} localScale    (3N) linear, ≥ 0 when stored, local only
 * @property {Float32Array|null} rho           (N) games only
 * @property {{[key: string]: string}} componentTypes  stored component type of each anchor accessor, e.g. {barycentrics: 'UNSIGNED_SHORT normalized'}
 */

/**
 * The result of readAnchoredGlb.
 * @typedef {object} AnchoredGlb
 * @property {AnchoredPrimitive[]} anchored  every anchored splat primitive
 * @property {{mesh: number, primitive: number}[]} plain  KHR splat primitives without anchors
 * @property {{[key: string]: any}} json  the glTF JSON document (as parsed)
 */

/**
 * Rest quantities of the `local` profile, computed once per asset in binary64 from the stored
 * float32 rest vertices (spec/README.md §Outputs, precision and epsilons). Arrays are per
 * face f of the anchor mesh; the `games` profile needs none of them (they are computed anyway).
 * @typedef {object} RestQuantities
 * @property {number} faceCount       F
 * @property {Uint8Array} regular     (F) 1 when a_r > ε_deg ℓ_r² (regular at rest), 0 when degenerate at rest
 * @property {Float64Array} cinv      (3F) C_r⁻¹ = [[p, q], [0, r]] stored p, q, r: p = 1/|e1|,
 *   q = −(e2·t)/(|e1| h), r = 1/h with h = a_r/|e1|; the identity (1, 0, 1) on faces degenerate at rest
 * @property {Float64Array} area      (F) a_r = |e1 × e2| (twice the area; the true value on degenerate faces too)
 * @property {Float64Array} sqrtArea  (F) √a_r on faces regular at rest, 1 on faces degenerate at rest
 * @property {Float64Array} invSqrtArea (F) 1/√a_r on faces regular at rest, 1 on faces degenerate at rest
 * @property {Float64Array} restFrame (9F) R_r = [t | b | n] row-major (columns t, b, n) of every rest face
 */

/**
 * Means and covariances of a remap.
 * @typedef {object} RemapOutput
 * @property {Float32Array} means  (3N)
 * @property {Float32Array} cov    (6N) xx, xy, xz, yy, yz, zz
 */

/**
 * Means, rotations and scales of a remap (any pair with R diag(s)² Rᵀ = Σ).
 * @typedef {object} RotationScaleOutput
 * @property {Float32Array} means      (3N)
 * @property {Float32Array} rotations  (4N) unit x, y, z, w
 * @property {Float32Array} scales     (3N) linear
 */

/**
 * The motion of a physics object (KHR_physics_rigid_bodies `motion`, defaults filled in).
 * @typedef {object} PhysicsMotion
 * @property {boolean} isKinematic
 * @property {number|null} mass            null: the engine's choice (from the collider)
 * @property {number} gravityFactor
 * @property {number[]} linearVelocity     initial, node space
 * @property {number[]} angularVelocity    initial
 */

/**
 * A splat node that is a physics object.
 * @typedef {object} PhysicsObject
 * @property {number} node                 the splat node's index
 * @property {string} name
 * @property {'rigid'|'soft'|'kinematic'|'static'} kind  soft: simulate the anchor mesh as a soft body (motion ignored)
 * @property {PhysicsMotion|null} motion   null for a static body
 * @property {Float64Array} matrix         the node's global matrix (column-major 4x4)
 * @property {{node: number, convexHull: boolean, vertices: Float32Array, indices: Uint32Array}} collider
 *   the collider mesh (node `node`), in the splat node's local space: 3V positions, 3F corners
 */

/**
 * A node without splats whose collider is an implicit shape (the ground: a static box).
 * @typedef {object} PhysicsShape
 * @property {number} node
 * @property {string} name
 * @property {'rigid'|'soft'|'kinematic'|'static'} kind
 * @property {Float64Array} matrix         the node's global matrix; the shape is centred at its origin
 * @property {number} shape                index in KHR_implicit_shapes.shapes
 * @property {'box'|'sphere'} type
 * @property {number[]} [size]             box: full size along x, y, z
 * @property {number} [radius]             sphere
 */

/**
 * The result of readPhysics.
 * @typedef {object} PhysicsScene
 * @property {PhysicsObject[]} objects
 * @property {PhysicsShape[]} shapes
 */

export {};
