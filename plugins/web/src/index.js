// @gsverse/web: reading GSVERSE_gaussian_splatting_mesh_anchor assets, rest quantities and the
// CPU remap. The GPU plugins are the separate entry points '@gsverse/web/playcanvas' and
// '@gsverse/web/three'.

export { AnchorError, readAnchoredGlb, ANCHOR_ACCESSORS, EXTENSION, KHR } from './anchor.js';
export {
    SPZ_EXTENSION, SH_SIGNS as SPZ_SH_SIGNS, MAX_SPZ_AMPLIFICATION, expandCompressed, hasCompressedPrimitives, inflateBounded as inflateSpzBounded,
    parseSpzHeader, decodeSpz, streamLimit as spzStreamLimit,
} from './spz.js';
export { GltfError, parseGltf, dequantize, globalMatrices, MAX_DATA_URI_BYTES, MAX_GLTF_ARRAY_ITEMS, MAX_READ_AMPLIFICATION, READ_AMPLIFICATION_SLACK } from './glb.js';
export { computeRest, triangleFrame, perp, EPS_DEGENERATE, GAMES_EPS } from './rest.js';
export { expandFaceCounts, deriveLocalAnchors } from './compact.js';
export { remapCpu, remapCpuRotationScale, remapMeansInto, localFaces, gamesFaces, gamesFrame } from './remap-cpu.js';
export {
    eigenSymmetric3, jacobi3, covToRotationScale, covToRotationScaleInto, rotationScaleToCov, matrixToQuat,
    matrixToQuatInto, quatToMatrix, JACOBI_SWEEPS,
} from './decompose.js';
export { AnchorAnimation, readAnchorAnimation } from './animation.js';
export { splatBoneWeights, boneOnlyMeansInto, MAX_SPLAT_BONES } from './bone-weights.js';
export { invertInto } from './keyframes.js';
export { readPhysics, RIGID_BODIES, IMPLICIT_SHAPES, PHYSICS_KINDS } from './physics.js';

// the shared types (src/types.js), for `import type { AnchoredPrimitive } from '@gsverse/web'`
/** @typedef {import('./types.js').RestPose} RestPose */
/** @typedef {import('./types.js').AnchorMesh} AnchorMesh */
/** @typedef {import('./types.js').AnchoredPrimitive} AnchoredPrimitive */
/** @typedef {import('./types.js').AnchoredGlb} AnchoredGlb */
/** @typedef {import('./types.js').RestQuantities} RestQuantities */
/** @typedef {import('./types.js').RemapOutput} RemapOutput */
/** @typedef {import('./types.js').RotationScaleOutput} RotationScaleOutput */
/** @typedef {import('./types.js').PhysicsObject} PhysicsObject */
/** @typedef {import('./types.js').PhysicsShape} PhysicsShape */
/** @typedef {import('./types.js').PhysicsScene} PhysicsScene */
/** @typedef {import('./types.js').PhysicsMotion} PhysicsMotion */
