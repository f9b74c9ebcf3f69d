// STB big-tile targets (stb_bigtile.frag, stb_bigtile_clusters.comp): the region a
// big tile's reservoirs serve (a bounding sphere of the 3x3 big tiles around it, between
// their min and max depth) and the target of one light for the tile's central depth
// segment A-B. Modes (u_target_mode): 0 "segment" (the talk's Phi / d^2), 1 "uniform",
// 2 "shaped" (segment x emission, cone and IES, 0 where the light cannot reach the region).
#ifndef STB_BIGTILE_TARGET_GLSL
#define STB_BIGTILE_TARGET_GLSL
#include "common/frame.glsl"
#include "common/lights.glsl"

layout(binding = TEX_UNIT_HIZ) uniform sampler2D u_hiz;  // rg32f min/max depth, one texel per big tile
uniform int u_big_px;           // big tile size (px)
uniform int u_target_mode;      // 0: segment (the talk's), 1: uniform, 2: shaped (default)

// Bounding sphere (world) of every surface point a small tile using this big tile's
// reservoir may shade: the 3x3 big tiles around `tile`, between their min and max
// depth (all of the view range when none of them has geometry).
void region_sphere(ivec2 tile, out vec3 C, out float R) {
    ivec2 grid = textureSize(u_hiz, 0);
    vec2 zr = vec2(3.0e38, 0.0);
    for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
            ivec2 t = tile + ivec2(dx, dy);
            if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, grid))) continue;
            vec2 m = texelFetch(u_hiz, t, 0).rg;
            if (m.y > 0.0) zr = vec2(min(zr.x, m.x), max(zr.y, m.y));
        }
    }
    if (zr.y <= 0.0) zr = u_clip.xy;
    vec2 lo = clamp((vec2(tile) - 1.0) * float(u_big_px), vec2(0.0), u_resolution.xy);
    vec2 hi = clamp((vec2(tile) + 2.0) * float(u_big_px), vec2(0.0), u_resolution.xy);
    vec3 corner[8];
    C = vec3(0.0);
    for (int k = 0; k < 8; ++k) {
        vec2 px = vec2((k & 1) != 0 ? hi.x : lo.x, (k & 2) != 0 ? hi.y : lo.y);
        corner[k] = world_pos_from_depth(px, (k & 4) != 0 ? zr.y : zr.x);
        C += corner[k] * 0.125;
    }
    R = 0.0;
    for (int k = 0; k < 8; ++k) R = max(R, distance(C, corner[k]));
    R = R * 1.001 + 1e-4;
}

float target_light(Light L, vec3 A, vec3 B, vec3 C, float R) {
    if (u_target_mode == 1) return 1.0;
    vec3 P = L.pos_range.xyz;
    vec3 ab = B - A;
    float t = clamp(dot(P - A, ab) / max(dot(ab, ab), 1e-20), 0.0, 1.0);
    vec3 d = P - (A + t * ab);
    float ext = light_half_extent(L);  // area lights: no 1/d^2 peak inside their size
    float d2 = max(dot(d, d) + ext * ext, LIM_MIN_LIGHT_DISTANCE * LIM_MIN_LIGHT_DISTANCE);
    float p = max(L.intensity.w, 0.0) / d2;
    if (u_target_mode == 0) return p;
    // "shaped": zero where the light cannot reach the region, shape-weighted elsewhere.
    vec3 toC = C - P;
    float dc = length(toC);
    if (dc > L.pos_range.w + R) return 0.0;                        // out of range
    vec3 axis = L.axis_emit.xyz;
    if (L.axis_emit.w == EMIT_COSINE && dot(axis, toC) < -R) return 0.0;  // behind
#ifdef HAS_CONES
    if (L.cone.y < CONE_CUTOFF_TEST_RAD && dc > R) {
        float alpha = acos(clamp(dot(axis, toC) / dc, -1.0, 1.0));
        if (alpha - asin(clamp(R / dc, 0.0, 1.0)) > L.cone.y) return 0.0;  // outside cone
    }
#endif
    vec3 w = -d / max(length(d), 1e-12);                              // light -> segment
    float shape = emission_shape(L, w) * light_shape_scalar(L, w);
    return p * max(shape, LIM_BIGTILE_SHAPE_FLOOR);
}

float target(uint i, vec3 A, vec3 B, vec3 C, float R) {
    if (u_target_mode == 1) return 1.0;
    return target_light(lights[i], A, B, C, R);
}

// The tile's central segment (world, A at the min depth, B at the max) and, for the
// shaped target, its region sphere (C, R); R = 3e38 otherwise.
void tile_segment(ivec2 tile, out vec3 A, out vec3 B, out vec3 C, out float R) {
    vec2 mm = texelFetch(u_hiz, tile, 0).rg;
    if (mm.y <= 0.0) {
        // No geometry in this tile, but stochastic bilinear selection lets
        // neighbouring small tiles use it: fill it with the whole view ray as
        // its segment (any positive target keeps their estimate unbiased).
        mm = u_clip.xy;
    }
    vec2 c = min((vec2(tile) + 0.5) * float(u_big_px), u_resolution.xy - 0.5);
    A = world_pos_from_depth(c, mm.x);
    B = world_pos_from_depth(c, mm.y);
    C = vec3(0.0);
    R = 3.0e38;
    if (u_target_mode == 2) region_sphere(tile, C, R);
}
#endif
