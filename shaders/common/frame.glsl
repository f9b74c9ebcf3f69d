// Per-frame constants (std140 UBO, binding UBO_FRAME), written once per frame by
// render/frame_data.py. Render frame: Y up, metres. Matrices are uploaded from
// row-vector numpy matrices, so in GLSL they apply as `M * v`.
#ifndef STB_FRAME_GLSL
#define STB_FRAME_GLSL
layout(std140, binding = UBO_FRAME) uniform FrameBlock {
    mat4 u_view;            // world -> view
    mat4 u_proj;            // view -> clip
    mat4 u_view_proj;       // world -> clip
    mat4 u_inv_view;        // view -> world
    mat4 u_prev_view_proj;  // previous frame's world -> clip (motion vectors)
    mat4 u_sun_view_proj;   // world -> sun shadow-map clip
    vec4 u_cam_pos;         // xyz camera position (m), w: 1 = orthographic
    vec4 u_resolution;      // width, height, 1/width, 1/height (px)
    vec4 u_tan_off;         // tan(fov_x/2), tan(fov_y/2), aperture offset x, y (at unit depth)
    vec4 u_clip;            // near, far (m), frame index, camera exposure scale
    vec4 u_sun_dir;         // xyz unit direction towards the sun (world), w: 1 = sun on
    vec4 u_sun_illum;       // rgb illuminance facing the sun (lux), w: 1 = sun shadow on
    vec4 u_sun_mult;        // x diffuse, y specular multiplier, z shadow bias (m), w normal bias (m)
    vec4 u_sun_shadow_color;// rgb shadow colour, w shadow-map texel size (1/px)
    vec4 u_ambient;         // rgb dome radiance (nits), w number of extra distant lights
    vec4 u_dist_dir[LIM_MAX_EXTRA_DISTANT];     // extra (unshadowed) distant lights: xyz towards the light, w diffuse mult
    vec4 u_dist_illum[LIM_MAX_EXTRA_DISTANT];   // rgb illuminance (lux), w specular mult
    uvec4 u_counts;         // x FoV light count, y seed, z, w big tiles x, y (LIM_BIG_TILE_PX)
};

// Linear view depth (m, > 0) + pixel -> view-space position.
vec3 view_pos_from_depth(vec2 pixel, float depth) {
    vec2 ndc = pixel * u_resolution.zw * 2.0 - 1.0;
    if (u_cam_pos.w > 0.5) {
        return vec3(ndc * u_tan_off.xy + u_tan_off.zw, -depth);
    }
    return vec3((ndc * u_tan_off.xy + u_tan_off.zw) * depth, -depth);
}

vec3 world_pos_from_depth(vec2 pixel, float depth) {
    return (u_inv_view * vec4(view_pos_from_depth(pixel, depth), 1.0)).xyz;
}

// Unit vector from the surface towards the eye.
vec3 view_dir(vec3 world_pos) {
    if (u_cam_pos.w > 0.5) {
        return normalize(u_inv_view[2].xyz);
    }
    return normalize(u_cam_pos.xyz - world_pos);
}
#endif
