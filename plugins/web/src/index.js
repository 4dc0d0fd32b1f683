// @gsverse/web: reading GSVERSE_gaussian_splatting_mesh_anchor assets, rest quantities and the
// CPU remap. The PlayCanvas GPU plugin is the separate entry point '@gsverse/web/playcanvas'.

export { AnchorError, readAnchoredGlb, ANCHOR_ACCESSORS, EXTENSION, KHR } from './anchor.js';
export { GltfError, parseGltf, dequantize, globalMatrices } from './glb.js';
export { computeRest, triangleFrame, perp, EPS_DEGENERATE, GAMES_EPS } from './rest.js';
export { expandFaceCounts, deriveLocalAnchors } from './compact.js';
export { remapCpu, remapCpuRotationScale, localFaces, gamesFaces, gamesFrame } from './remap-cpu.js';
export {
    eigenSymmetric3, jacobi3, covToRotationScale, covToRotationScaleInto, rotationScaleToCov, matrixToQuat,
    matrixToQuatInto, quatToMatrix, JACOBI_SWEEPS,
} from './decompose.js';
