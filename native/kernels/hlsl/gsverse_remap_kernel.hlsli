// gsverse_remap_kernel.hlsli -- the remap of one splat from the engine's buffers.
// An engine include (engines/) declares these buffers, then includes this file and calls
// gsv_remap(i, profile, law, rotation_scale) once per splat i (profile 0 local, 1 games; law 0
// affine, 1 rigid; rotation_scale 1: also write gsv_rotations and gsv_scales), one dispatch for
// every splat:
//   StructuredBuffer<float> gsv_vertices  float[3V] the current anchor-mesh vertices, splat-local
//   StructuredBuffer<uint>  gsv_indices   uint[3F]  triangles (0, 1, ..., 3F-1 when not indexed)
//   StructuredBuffer<float> gsv_rest      float[8F] per face, computed in double on the CPU:
//                                                   C_r^-1 row-major (4), a_r, 1/sqrt(a_r),
//                                                   regular (1.0 or 0.0), unused
//   StructuredBuffer<uint>  gsv_face      uint[N]   face of every splat
//   StructuredBuffer<float> gsv_bary      float[2N] barycentrics (dequantized)
//   StructuredBuffer<float> gsv_offset    float[N]  local: normalOffset; games: rho
//   StructuredBuffer<float> gsv_rotation  float[4N] local: localRotation (x, y, z, w), normalized
//   StructuredBuffer<float> gsv_scale     float[3N] local: localScale
//   RWStructuredBuffer<float> gsv_means   float[3N] out
//   RWStructuredBuffer<float> gsv_cov     float[6N] out: xx, xy, xz, yy, yz, zz
//   RWStructuredBuffer<float> gsv_rotations float[4N] out if rotation_scale: x, y, z, w (w >= 0)
//   RWStructuredBuffer<float> gsv_scales  float[3N] out if rotation_scale (affine: by a Jacobi
//                                                   eigen-decomposition of the covariance)
// The layout is the GLSL kernel's (native/kernels/glsl/gsverse_remap.comp), binding for binding.

#include "gsverse_remap_core.hlsli"

float3 gsv_vertex(uint corner) {
    uint v = gsv_indices[corner];
    return float3(gsv_vertices[3 * v], gsv_vertices[3 * v + 1], gsv_vertices[3 * v + 2]);
}

void gsv_remap(uint i, uint profile, uint law, uint rotation_scale) {
    uint f = gsv_face[i];
    float3 v0 = gsv_vertex(3 * f), v1 = gsv_vertex(3 * f + 1), v2 = gsv_vertex(3 * f + 2);
    float2 bary = float2(gsv_bary[2 * i], gsv_bary[2 * i + 1]);
    float3 mean, scale = float3(0.0, 0.0, 0.0);
    float4 quat = float4(0.0, 0.0, 0.0, 1.0);
    float cov6[6];
    if (profile == 1) {
        float3x3 frame;
        gsv_games_splat(v0, v1, v2, bary, gsv_offset[i], mean, cov6, frame, scale);
        if (rotation_scale == 1) quat = gsv_mat_to_quat(frame);
    } else {
        uint r = 8 * f;
        GsvLocalFace face = gsv_local_face(
            v0, v1, v2, float4(gsv_rest[r], gsv_rest[r + 1], gsv_rest[r + 2], gsv_rest[r + 3]),
            gsv_rest[r + 5], gsv_rest[r + 6] != 0.0);
        float4 q = float4(gsv_rotation[4 * i], gsv_rotation[4 * i + 1], gsv_rotation[4 * i + 2],
                          gsv_rotation[4 * i + 3]);
        float3 s = float3(gsv_scale[3 * i], gsv_scale[3 * i + 1], gsv_scale[3 * i + 2]);
        gsv_local_splat(face, bary, gsv_offset[i], q, s, law == 1, mean, cov6);
        if (rotation_scale == 1) gsv_local_rotation_scale(face, q, s, law == 1, quat, scale);
    }
    gsv_means[3 * i] = mean.x;
    gsv_means[3 * i + 1] = mean.y;
    gsv_means[3 * i + 2] = mean.z;
    [unroll] for (uint j = 0; j < 6; ++j) gsv_cov[6 * i + j] = cov6[j];
    if (rotation_scale == 1) {
        [unroll] for (uint r = 0; r < 4; ++r) gsv_rotations[4 * i + r] = quat[r];
        [unroll] for (uint c = 0; c < 3; ++c) gsv_scales[3 * i + c] = scale[c];
    }
}
