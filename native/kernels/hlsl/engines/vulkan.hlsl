// engines/vulkan.hlsl -- the HLSL remap kernel with Vulkan bindings (set 0, bindings 0..12, the
// GLSL kernel's layout), as native/kernels/vulkan/gsv_vk.c dispatches it. Compile:
//   glslangValidator -D -V -S comp -e main engines/vulkan.hlsl -o remap.spv
//   dxc -spirv -T cs_6_0 -E main engines/vulkan.hlsl -Fo remap.spv
// gsv_params: splat count, first splat, profile (0 local, 1 games), law (0 affine, 1 rigid),
// rotation + scale outputs (0 or 1).

[[vk::binding(0, 0)]] StructuredBuffer<uint> gsv_params;
[[vk::binding(1, 0)]] StructuredBuffer<float> gsv_vertices;
[[vk::binding(2, 0)]] StructuredBuffer<uint> gsv_indices;
[[vk::binding(3, 0)]] StructuredBuffer<float> gsv_rest;
[[vk::binding(4, 0)]] StructuredBuffer<uint> gsv_face;
[[vk::binding(5, 0)]] StructuredBuffer<float> gsv_bary;
[[vk::binding(6, 0)]] StructuredBuffer<float> gsv_offset;
[[vk::binding(7, 0)]] StructuredBuffer<float> gsv_rotation;
[[vk::binding(8, 0)]] StructuredBuffer<float> gsv_scale;
[[vk::binding(9, 0)]] RWStructuredBuffer<float> gsv_means;
[[vk::binding(10, 0)]] RWStructuredBuffer<float> gsv_cov;
[[vk::binding(11, 0)]] RWStructuredBuffer<float> gsv_rotations;
[[vk::binding(12, 0)]] RWStructuredBuffer<float> gsv_scales;

#include "../gsverse_remap_kernel.hlsli"

// More than 65535 workgroups come as rows of 65535 (the host's 2D grid): 65535 * 64 splats a row.
static const uint GSV_ROW = 65535 * 64;

[numthreads(64, 1, 1)]
void main(uint3 id : SV_DispatchThreadID) {
    uint i = gsv_params[1] + id.x + id.y * GSV_ROW;
    if (i >= gsv_params[0]) return;
    gsv_remap(i, gsv_params[2], gsv_params[3], gsv_params[4]);
}
