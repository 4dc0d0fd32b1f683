// glTF-Transform extensions for mesh-anchored Gaussian splats: KHR_gaussian_splatting and the
// GSVERSE_gaussian_splatting_mesh_anchor and KHR_gaussian_splatting_compression_spz_2 nested in
// it. Register them together (`gsverseExtensions`) with
// an I/O class, or with the gltf-transform CLI through gltf-transform.config.mjs (next to
// package.json). The classes import @gltf-transform/core: use the same copy as the I/O class.
//
//     import { NodeIO } from '@gltf-transform/core';
//     import { ALL_EXTENSIONS } from '@gltf-transform/extensions';
//     import { gsverseExtensions } from './src/gltf-transform/index.js';
//     const io = new NodeIO().registerExtensions([...ALL_EXTENSIONS, ...gsverseExtensions]);

import { GaussianSplatting, KHRGaussianSplatting, KHR_GAUSSIAN_SPLATTING, GSVERSE_MESH_ANCHOR } from './khr-gaussian-splatting.js';
import { GSVERSEMeshAnchor, MeshAnchor, MeshAnchorError, PROFILE_ACCESSORS } from './mesh-anchor.js';
import { KHRGaussianSplattingCompressionSpz, SpzCompression, SpzCompressionError, SPZ_EXTENSION } from './spz-compression.js';

export {
    GaussianSplatting, KHRGaussianSplatting, KHR_GAUSSIAN_SPLATTING, GSVERSE_MESH_ANCHOR,
    GSVERSEMeshAnchor, MeshAnchor, MeshAnchorError, PROFILE_ACCESSORS,
    KHRGaussianSplattingCompressionSpz, SpzCompression, SpzCompressionError, SPZ_EXTENSION,
};

/** The extension classes, to register together. */
export const gsverseExtensions = [KHRGaussianSplatting, GSVERSEMeshAnchor, KHRGaussianSplattingCompressionSpz];
