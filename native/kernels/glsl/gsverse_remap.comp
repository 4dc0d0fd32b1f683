#version 450
// gsverse_remap.comp -- one dispatch remaps every splat of an anchored primitive from the
// current anchor-mesh vertices (GLSL 450 compute: Vulkan, Godot 4's RenderingDevice).
// One invocation per splat; the splat's face is recomputed by each of its splats (no shared
// state, so splats need not be sorted by face; a face-sorted asset keeps the reads of a
// workgroup on few faces). Buffers (std430, tightly packed floats/uints, set 0):
//   0 params   uint[5]: splat count (end), first splat of this dispatch, profile (0 local,
//                       1 games), law (0 affine, 1 rigid), rotation + scale outputs (0 or 1)
//   1 vertices float[3V]   the current anchor-mesh vertices, splat-local space
//   2 indices  uint[3F]    the anchor mesh's triangles (0, 1, ..., 3F-1 when not indexed)
//   3 rest     float[8F]   per face, from gsv_prepare_rest (double, stored as float):
//                          C_r^-1 row-major (4), a_r, 1/sqrt(a_r), regular (1.0 or 0.0), unused
//   4 face     uint[N]     face of every splat (from faceIndex or faceCounts)
//   5 bary     float[2N]   barycentrics (dequantized)
//   6 offset   float[N]    local: normalOffset; games: rho
//   7 rotation float[4N]   local: localRotation (x, y, z, w), normalized; games: unused
//   8 scale    float[3N]   local: localScale; games: unused
//   9 means    float[3N]   out
//  10 cov      float[6N]   out: xx, xy, xz, yy, yz, zz
//  11 rotations float[4N]  out when params[4] = 1: x, y, z, w (w >= 0)
//  12 scales   float[3N]   out when params[4] = 1 (rigid and games directly; affine by a
//                          Jacobi eigen-decomposition of the covariance, which is normative)
#extension GL_GOOGLE_include_directive : require
#include "gsverse_remap_core.glsl"

layout(local_size_x = 64) in;

layout(std430, set = 0, binding = 0) readonly buffer Params { uint gsv_params[]; };
layout(std430, set = 0, binding = 1) readonly buffer Vertices { float gsv_vertices[]; };
layout(std430, set = 0, binding = 2) readonly buffer Indices { uint gsv_indices[]; };
layout(std430, set = 0, binding = 3) readonly buffer Rest { float gsv_rest[]; };
layout(std430, set = 0, binding = 4) readonly buffer Face { uint gsv_face[]; };
layout(std430, set = 0, binding = 5) readonly buffer Bary { float gsv_bary[]; };
layout(std430, set = 0, binding = 6) readonly buffer Offset { float gsv_offset[]; };
layout(std430, set = 0, binding = 7) readonly buffer Rotation { float gsv_rotation[]; };
layout(std430, set = 0, binding = 8) readonly buffer Scale { float gsv_scale[]; };
layout(std430, set = 0, binding = 9) writeonly buffer Means { float gsv_means[]; };
layout(std430, set = 0, binding = 10) writeonly buffer Cov { float gsv_cov[]; };
layout(std430, set = 0, binding = 11) writeonly buffer Rotations { float gsv_rotations[]; };
layout(std430, set = 0, binding = 12) writeonly buffer Scales { float gsv_scales[]; };

vec3 gsv_vertex(uint corner) {
    uint v = gsv_indices[corner];
    return vec3(gsv_vertices[3u * v], gsv_vertices[3u * v + 1u], gsv_vertices[3u * v + 2u]);
}

void main() {
    // a 2D grid of workgroups when there are more than 65535 of them
    uint i = gsv_params[1] + gl_GlobalInvocationID.x
           + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x;
    if (i >= gsv_params[0]) return;
    uint f = gsv_face[i];
    vec3 v0 = gsv_vertex(3u * f), v1 = gsv_vertex(3u * f + 1u), v2 = gsv_vertex(3u * f + 2u);
    vec2 bary = vec2(gsv_bary[2u * i], gsv_bary[2u * i + 1u]);
    vec3 mean, scale;
    vec4 quat;
    float cov6[6];
    bool rotation_scale = gsv_params[4] == 1u;
    if (gsv_params[2] == 1u) {
        mat3 frame;
        gsv_games_splat(v0, v1, v2, bary, gsv_offset[i], mean, cov6, frame, scale);
        if (rotation_scale) quat = gsv_mat_to_quat(frame);
    } else {
        uint r = 8u * f;
        GsvLocalFace face = gsv_local_face(
            v0, v1, v2, vec4(gsv_rest[r], gsv_rest[r + 1u], gsv_rest[r + 2u], gsv_rest[r + 3u]),
            gsv_rest[r + 5u], gsv_rest[r + 6u] != 0.0);
        vec4 q = vec4(gsv_rotation[4u * i], gsv_rotation[4u * i + 1u], gsv_rotation[4u * i + 2u],
                      gsv_rotation[4u * i + 3u]);
        vec3 s = vec3(gsv_scale[3u * i], gsv_scale[3u * i + 1u], gsv_scale[3u * i + 2u]);
        gsv_local_splat(face, bary, gsv_offset[i], q, s, gsv_params[3] == 1u, mean, cov6);
        if (rotation_scale)
            gsv_local_rotation_scale(face, q, s, gsv_params[3] == 1u, quat, scale);
    }
    for (uint j = 0u; j < 3u; ++j) gsv_means[3u * i + j] = mean[j];
    for (uint j = 0u; j < 6u; ++j) gsv_cov[6u * i + j] = cov6[j];
    if (rotation_scale) {
        for (uint j = 0u; j < 4u; ++j) gsv_rotations[4u * i + j] = quat[j];
        for (uint j = 0u; j < 3u; ++j) gsv_scales[3u * i + j] = scale[j];
    }
}
