// STB reuse (issue 31), -o reuse_target=tile: the per-slot half of the initial target,
// one fragment per big-tile reservoir slot (the stb_bigtile texture's layout). The
// light's shaping without its cone -- IES x emission model x focusTint, the part of the
// target that costs the most per candidate on llvmpipe (an IES texture lookup, a branch
// per light type that every lane runs) -- is evaluated once per slot, towards the
// maximum over a grid of the G-buffer's surface points of the pixels that may use the
// tile (STB_REUSE_SLOT_GRID^2 from stb_reuse.slot_grid: 4 x 4 for 32 px tiles and up,
// 2 x 2 for 16 px; over the tile +- half a tile) and the tile's central
// segment's point nearest the light, floored at LIM_REUSE_SLOT_SHAPE_FLOOR so the
// target stays > 0 wherever the light may reach a pixel (unbiased). The cone and the
// IES table are left to the pixel, in cos space from a third texel (o_axis: no acos; a
// narrow cone or IES lobe between the grid's points would otherwise sit at the floor,
// and its pixels' picks carry ~100x weights: fireflies). A light with an IES
// angleScale keeps its table in the grid's maximum (o_shape.w = -1). The pixel's part
// (common/reuse_initial.glsl: reuse_slot_target) is then distance, range window, cone,
// IES, horizon and BRDF, from these three texels and no light record (the light's
// index is read once per pixel, for its pick, from the big-tile reservoir itself).
//   o_pos:   light position (m, world), influence range (m)
//   o_shape: x luminous intensity x shaping (no cone) towards the tile (cd, luminance),
//            y half extent (m; 0: a point light), z W_bt (the slot's contribution
//            weight; 0: empty slot), w the IES layer looked up per pixel (-1: none)
//   o_axis:  the cone's falloff as t = clamp(w + dot(Ldir, xyz), 0, 1), Ldir the unit
//            direction towards the light, shape 1 - t^2 (3 - 2 t): xyz the emission
//            axis / dc, w (cos cutoff + dc) / dc, dc = cos(smooth start) - cos(cutoff)
//            (>= LIM_REUSE_SLOT_CONE_MIN_DCOS); a light without a cone: xyz its unit
//            axis (0 without an IES layer either), w = -2 (t = 0, shape 1). The IES
//            lookup's axis is normalize(xyz).
// stb_reuse.slot_grid(big_tile), defined by the pass; alone (a compile check): the largest.
#ifndef STB_REUSE_SLOT_GRID
#define STB_REUSE_SLOT_GRID LIM_REUSE_SLOT_GRID
#endif
#include "common/frame.glsl"
#include "common/gbuffer.glsl"
#include "common/packing.glsl"
#include "common/lights.glsl"
#include "common/bigtile_target.glsl"

uniform usampler2D u_bigtile;  // r32ui big-tile reservoirs
uniform ivec2 u_block;         // slot block per big tile (K = x * y)

layout(location = 0) out vec4 o_pos;
layout(location = 1) out vec4 o_shape;
layout(location = 2) out vec4 o_axis;
#ifdef HAS_LINKS
#include "common/links.glsl"
layout(location = 3) out uint o_link;  // the light's link mask over the groups (0: empty)
#endif

// IES (unless per pixel: ies_pixel) x emission model of L towards the point X (leaving
// the light); the cone is the pixel's (o_axis): cone.y past CONE_CUTOFF_TEST_RAD skips it.
float slot_shape(Light L, vec3 X, bool ies_pixel) {
    vec3 d = X - L.pos_range.xyz;
    vec3 w = d / max(length(d), 1e-12);
    vec4 no_cone = vec4(L.cone.x, 2.0 * CONE_CUTOFF_TEST_RAD + 4.0, L.cone.zw);
    vec4 tint_ies = ies_pixel ? vec4(L.tint_ies.rgb, -1.0) : L.tint_ies;
    return light_shape_scalar_m(L.axis_emit, no_cone, tint_ies, L.tangent_tex.xyz, L.ies_shadow.y, w)
         * emission_shape(L, w);
}

// o_axis for L (see the header): the cone light_shape_scalar_m applies, in cos space,
// and the IES lookup's axis.
vec4 slot_axis(Light L) {
#ifdef HAS_CONES
    if (L.cone.y < CONE_CUTOFF_TEST_RAD) {
        // the cutoff a hair wide so that rounding never zeroes the target where the
        // shading (acos against the cutoff) is still > 0
        float c_cut = cos(min(L.cone.y * (1.0 + LIM_REUSE_SLOT_CONE_MARGIN), PI));
        float c_start = L.cone.y > L.cone.z ? cos(max(L.cone.z, 0.0)) : c_cut;
        float dc = max(c_start - c_cut, LIM_REUSE_SLOT_CONE_MIN_DCOS);
        return vec4(L.axis_emit.xyz / dc, (c_cut + dc) / dc);
    }
#endif
    return vec4(L.axis_emit.xyz, -2.0);  // |dot| <= 1: t = 0
}

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    uint smp = texelFetch(u_bigtile, p, 0).r;
    uint li = sample_index(smp);
    float Wj = sample_weight(smp);
    o_pos = vec4(0.0);
    o_shape = vec4(0.0, 0.0, 0.0, -1.0);
    o_axis = vec4(0.0, 0.0, 0.0, -2.0);
#ifdef HAS_LINKS
    o_link = 0u;
#endif
    if (li == LIM_EMPTY_LIGHT_INDEX || li >= u_counts.x || !(Wj > 0.0)) return;
    Light L = lights[li];
    ivec2 tile = p / u_block;
#ifdef HAS_IES
    bool ies_pixel = L.tint_ies.w >= 0.0 && L.ies_shadow.y == 0.0;
#else
    bool ies_pixel = false;
#endif
    // The maximum over a grid of surface points of the pixels that may use this tile
    // (the tile +- half a tile), and the tile's central segment's point nearest the
    // light (always: covers background-only grids).
    vec3 A, B, C;
    float R;
    tile_segment(tile, A, B, C, R);
    vec3 ab = B - A;
    float t = clamp(dot(L.pos_range.xyz - A, ab) / max(dot(ab, ab), 1e-12), 0.0, 1.0);
    vec3 Xbest = A + t * ab;
    float shape = slot_shape(L, Xbest, ies_pixel);
    const int G = STB_REUSE_SLOT_GRID;
    vec2 lo = (vec2(tile) - 0.5) * float(u_big_px);
    float step_px = 2.0 * float(u_big_px) / float(G);
    for (int gy = 0; gy < G; ++gy) {
        for (int gx = 0; gx < G; ++gx) {
            vec2 q = clamp(lo + (vec2(gx, gy) + 0.5) * step_px, vec2(0.5), u_resolution.xy - 0.5);
            float z = texelFetch(g_depth, ivec2(q), 0).r;
            if (z <= 0.0) continue;
            vec3 X = world_pos_from_depth(q, z);
            float sh = slot_shape(L, X, ies_pixel);
            if (sh > shape) {
                shape = sh;
                Xbest = X;
            }
        }
    }
    vec3 d = Xbest - L.pos_range.xyz;
    vec3 w = d / max(length(d), 1e-12);
    shape = max(shape, LIM_REUSE_SLOT_SHAPE_FLOOR);
    float I = luminance(L.intensity.rgb * light_tint_rgb(L, w)) * shape;
    float he = L.area.z == AREA_POINT ? 0.0 : light_half_extent(L);
    o_pos = L.pos_range;
    o_shape = vec4(I, he, Wj, ies_pixel ? L.tint_ies.w : -1.0);
    o_axis = slot_axis(L);
#ifdef HAS_LINKS
    o_link = link_mask[li];
#endif
}
