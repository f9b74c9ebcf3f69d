// Shadow terms of local lights from the 16-bit shadow atlas (shared by every
// lighting method). Maps store (distance to the light + bias) / range, linear,
// in [0, 1]; spot lights a perspective map, omni lights an octahedral one.
// Lookups use the light transform the map was *captured* with (the record),
// not the light's current one. 4-tap gather PCF (hardware-style bilinear
// weights), optional stochastic PCF (one random sub-texel offset per lookup).
#ifndef STB_SHADOW_GLSL
#define STB_SHADOW_GLSL
#include "common/lights.glsl"
#include "common/octahedral.glsl"

#ifdef HAS_SHADOWS
struct ShadowMap {
    mat4 view_proj;   // spot: captured world -> clip
    vec4 pos_range;   // captured light position (m), range (m) = depth normalisation
    vec4 atlas;       // interior origin x, y (texels), interior side (texels), type (0 spot, 1 omni)
    vec4 params;      // x near (m), y texel angle (rad), z 1 / atlas size, w normal-bias scale
};
layout(std430, binding = SSBO_SHADOW_MAPS) readonly buffer ShadowBuffer { ShadowMap shadow_maps[]; };
uniform sampler2D u_shadow_atlas;   // r16 unorm

// Visibility in [0, 1] of one bilinear 2x2 gather at atlas texel coordinate t
// (reference depth ref = distance / range), with the light's shadow max distance and
// falloff (occluders further than it from the receiver do not shadow).
float shadow_tap(Light L, ShadowMap S, vec2 t, float ref, float dist) {
    vec2 base = floor(t);
    vec2 f = t - base;
    vec4 g = textureGather(u_shadow_atlas, (base + 1.0) * S.params.z, 0);
    // gather order: (0,1) (1,1) (1,0) (0,0)
    vec4 w = vec4((1.0 - f.x) * f.y, f.x * f.y, f.x * (1.0 - f.y), (1.0 - f.x) * (1.0 - f.y));
    vec4 lit = vec4(greaterThanEqual(g, vec4(ref)));
    float maxd = L.shadow_color.w;
    if (maxd > 0.0) {
        vec4 to_occ = vec4(dist) - g * S.pos_range.w;
        float fall = L.misc.x > 0.0 ? min(L.misc.x, maxd) : 0.0;
        vec4 fade = fall > 0.0
            ? pow(clamp((to_occ - (maxd - fall)) / fall, 0.0, 1.0), vec4(max(L.misc.y, 1e-3)))
            : vec4(greaterThan(to_occ, vec4(maxd)));
        lit = max(lit, fade);
    }
    return dot(lit, w);
}

#define PCSS_SEARCH_TAPS 8
#define PCSS_FILTER_TAPS 16

// Vogel-spiral offset k of n on the unit disk, rotated by `rot` (rad).
vec2 vogel(int k, int n, float rot) {
    float r = sqrt((float(k) + 0.5) / float(n));
    float a = float(k) * 2.39996323 + rot;
    return r * vec2(cos(a), sin(a));
}

// Atlas texel coordinate of world point X in map S; false outside a spot map.
bool shadow_texel(ShadowMap S, vec3 X, out vec2 t) {
    vec2 uv;
    if (S.atlas.w < 0.5) {
        vec4 c = S.view_proj * vec4(X, 1.0);
        if (c.w <= 0.0) return false;
        uv = c.xy / c.w * 0.5 + 0.5;
        if (any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0)))) return false;
    } else {
        uv = oct_dir_to_uv(normalize(X - S.pos_range.xyz));
    }
    t = S.atlas.xy + uv * S.atlas.z - 0.5;
    return true;
}

// Soft shadow of an area light: PCSS (Fernando 2005) on the map captured from the
// light's centre, with the kernel shaped like the light. A blocker at distance z from
// the light shadows the receiver (distance D) from the light's points seen through a
// copy of the light's shape scaled by (D - z) / z around the receiver. Taps are points
// of that shape (a Vogel disk mapped onto its two half axes, area-preserving), projected
// along the light direction onto the receiver's plane and then exactly into the map,
// each compared with its own distance to the light (no receiver-plane bias; octahedral
// seams need no care). The blocker search uses z = max(near, D / 20); the filter the
// mean blocker distance. Both are capped at LIM_PCSS_MAX_TEXELS map texels.
float shadow_pcss(Light L, ShadowMap S, vec3 Pb, vec3 N, float dist, float rot) {
    vec3 Lc = S.pos_range.xyz;
    float range = S.pos_range.w;
    vec3 ldir = (Lc - Pb) / max(dist, 1e-9);
    float ndl = dot(N, ldir);
    if (abs(ndl) < 0.05) ndl = ndl < 0.0 ? -0.05 : 0.05;
    vec3 A, B;
    light_shadow_axes(L, ldir, A, B);
    float cap = LIM_PCSS_MAX_TEXELS * S.params.y * dist;   // world size of the cap
    float amax = max(length(A), length(B));
    float zmin = max(S.params.x, 0.05 * dist);
    float search = min((dist - zmin) / zmin, cap / max(amax, 1e-6));
    float zsum = 0.0, zn = 0.0;
    for (int k = 0; k < PCSS_SEARCH_TAPS; ++k) {
        vec2 o2 = vogel(k, PCSS_SEARCH_TAPS, rot) * search;
        vec3 o = A * o2.x + B * o2.y;
        vec3 X = Pb + o - ldir * (dot(o, N) / ndl);
        vec2 tk;
        if (!shadow_texel(S, X, tk)) continue;
        float rk = length(X - Lc) / range;
        vec4 g = textureGather(u_shadow_atlas, (floor(tk) + 1.0) * S.params.z, 0);
        vec4 b = vec4(lessThan(g, vec4(rk)));
        zsum += dot(b, g);
        zn += dot(b, vec4(1.0));
    }
    if (zn <= 0.0) return 1.0;                            // no blocker: fully lit
    float zb = max(zsum / zn * range, 1e-4);
    float pen = min(max(dist - zb, 0.0) / zb, cap / max(amax, 1e-6));
    float v = 0.0;
    for (int k = 0; k < PCSS_FILTER_TAPS; ++k) {
        vec2 o2 = vogel(k, PCSS_FILTER_TAPS, rot) * pen;
        vec3 o = A * o2.x + B * o2.y;
        vec3 X = Pb + o - ldir * (dot(o, N) / ndl);
        vec2 tk;
        if (!shadow_texel(S, X, tk)) { v += 1.0; continue; }
        v += shadow_tap(L, S, tk, length(X - Lc) / range, dist);
    }
    return v / float(PCSS_FILTER_TAPS);
}

// Returns the RGB transmission mix(shadow:color, 1, visibility). soft: PCSS for lights
// shaded as areas; false: one bilinear PCF gather for every light (STB's resampling
// targets: an approximate visibility is all a target needs, at 1/24 of the taps).
vec3 local_shadow_impl(Light L, vec3 P, vec3 N, vec2 jitter, bool soft) {
    int m = int(L.ies_shadow.z);
    if (m < 0) return vec3(1.0);
    ShadowMap S = shadow_maps[m];
    vec3 to_l = S.pos_range.xyz - P;
    float dist0 = length(to_l);
    vec3 ldir = to_l / max(dist0, 1e-9);
    float texel_world = S.params.y * dist0;
    // Slope-scaled normal offset: at grazing incidence one texel spans tan(theta)
    // texels of depth, so push the lookup further off the surface (clamped).
    float c = clamp(abs(dot(N, ldir)), 0.05, 1.0);
    float slope = clamp(sqrt(1.0 - c * c) / c, 1.0, 4.0);
    vec3 Pb = P + N * (texel_world * S.params.w * min(slope, 2.0))
            + ldir * (texel_world * (0.5 + (0.75 + length(jitter)) * slope));
    vec3 d = Pb - S.pos_range.xyz;
    float dist = length(d);
    float range = S.pos_range.w;
    float ref = dist / range;
    if (ref >= 1.0) return vec3(1.0);
    vec2 uv;
    if (S.atlas.w < 0.5) {
        vec4 c = S.view_proj * vec4(Pb, 1.0);
        if (c.w <= 0.0) return vec3(1.0);
        uv = c.xy / c.w * 0.5 + 0.5;
        if (any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0)))) return vec3(1.0);
    } else {
        uv = oct_dir_to_uv(d / max(dist, 1e-12));
    }
    // Atlas texel coordinates; the 3 px border holds clamp / octahedral-mirror data.
    vec2 t = S.atlas.xy + uv * S.atlas.z - 0.5 + jitter;
    // Soft shadows where the light is shaded as an area (same size rule as area.glsl).
    float v = soft && light_is_area(L, dist0)
        ? shadow_pcss(L, S, Pb, N, dist, jitter.x * 6.2831853)
        : shadow_tap(L, S, t, ref, dist);
    return mix(L.shadow_color.rgb, vec3(1.0), v);
}

vec3 local_shadow_jittered(Light L, vec3 P, vec3 N, vec2 jitter) {
    return local_shadow_impl(L, P, N, jitter, true);
}

// Hard (single-gather) visibility for resampling targets.
vec3 local_shadow_hard(Light L, vec3 P, vec3 N) {
    return local_shadow_impl(L, P, N, vec2(0.0), false);
}

vec3 local_shadow(Light L, vec3 P, vec3 N) {
#ifdef STOCHASTIC_PCF
    // Stochastic PCF: one random sub-texel offset (+-0.5 texel) per pixel and frame
    // on top of the 4-tap gather -- softer edges for the same single gather.
    uvec2 q = uvec2(gl_FragCoord.xy);
    uint h = q.x * 1973u + q.y * 9277u + uint(u_clip.z) * 26699u;
    h ^= h >> 15; h *= 0x2c1b3c6du; h ^= h >> 12; h *= 0x297a2d39u; h ^= h >> 15;
    vec2 j = vec2(float(h & 0xffffu), float(h >> 16)) / 65536.0 - 0.5;
    return local_shadow_jittered(L, P, N, j);
#else
    return local_shadow_jittered(L, P, N, vec2(0.0));
#endif
}
#else
vec3 local_shadow(Light L, vec3 P, vec3 N) { return vec3(1.0); }
vec3 local_shadow_jittered(Light L, vec3 P, vec3 N, vec2 jitter) { return vec3(1.0); }
vec3 local_shadow_hard(Light L, vec3 P, vec3 N) { return vec3(1.0); }
#endif

// Shadowed radiance (nits) light L reflects towards s.V: the exact methods' per-light
// term (reference, tiled, clustered, lighttree). Area lights are integrated over their
// area (common/area.glsl); the shadow lookup is skipped where nothing is reflected.
vec3 light_radiance(Light L, Surface s) {
    vec3 Ldir, d, sp;
    if (!light_reflect(L, s, Ldir, d, sp)) return vec3(0.0);
    vec3 c = (d * L.misc.z + sp * L.misc.w) * light_shape_scalar(L, -Ldir);
    if (c.r + c.g + c.b <= 0.0) return vec3(0.0);
    return c * local_shadow(L, s.P, s.N);
}
#endif
