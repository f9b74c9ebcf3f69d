// STB reuse (issue 31), pass 2 of 2: spatial reuse, visibility and shading, per pixel.
//
// * Spatial reuse: u_k neighbours at random offsets within u_radius px (a fresh draw
//   per pixel and frame), each kept when its surface is like this pixel's
//   (common/reuse_geometry.glsl); their reservoirs (this frame's, after temporal reuse:
//   u_reuse) are combined with the pixel's own by generalized resampled importance
//   sampling. Two MIS weights (u_mis): 0 = the 1/M rule (w_i = p_c(y_i) W_i M_i,
//   W = sum w / (M p_c(y)): cheap, biased where a neighbour could not have produced
//   this pixel's sample or the other way round); 1 = the generalized balance heuristic
//   with confidences, m_i(y) = M_i p_i(y) / sum_j M_j p_j(y) over the kept reservoirs'
//   own surfaces (unbiased; (k + 1)^2 target evaluations); 2 = pairwise MIS (unbiased,
//   2k + 1 evaluations; see below).
// * Visibility: the chosen light's term at this pixel (shadow x cone x normalised IES,
//   as the term pass computes it, at full resolution): the target is unshadowed, so
//   shadowed candidates are shaded with their zero term and add nothing.
// * Shading: sun, ambient and emission as stb_lighting.frag, plus f(y) x W.
// * STB_REUSE_AREA_PASS (fused only): picks that need light_reflect's area path are
//   listed and shaded by stb_reuse_area.frag instead (common/reuse_area.glsl).
// * STB_REUSE_FUSED (reuse_candidates > 0, pixel resolution, k = 0, no temporal reuse
//   this frame): the pass computes the pixel's initial reservoir itself
//   (common/reuse_initial.glsl) instead of reading the temporal pass's: one full-screen
//   pass and one G-buffer read fewer, the same estimate.
// * History: the final reservoir and this pixel's surface go to the image units read
//   by the next frame's temporal pass. u_vis_reuse = 1 stores a reservoir whose light
//   is fully shadowed here as empty (ReSTIR's visibility reuse: less noise in shadow,
//   biased at shadow edges).
#include "common/gbuffer.glsl"
#include "common/rng.glsl"
#include "common/sun.glsl"
#include "common/lights.glsl"
#define AREA_SHADOW_POINTS LIM_AREA_SHADOW_POINTS_STB
#define AREA_SHADOW_PER_FRAME
#include "common/shadow.glsl"
#include "common/reservoir.glsl"
#include "common/reuse_target.glsl"
#include "common/reuse_geometry.glsl"
#include "common/reuse_area.glsl"
#include "common/lighting_out.glsl"
#ifdef STB_REUSE_FUSED
#include "common/reuse_initial.glsl"
#endif
#ifdef STB_REUSE_SHARE
#include "common/reuse_share.glsl"
#endif

uniform usampler2D u_reuse;  // this frame's reservoirs after temporal reuse
uniform int u_k;             // spatial neighbours (0 .. LIM_REUSE_K_MAX)
uniform float u_radius;      // px
uniform int u_mis;           // 0: 1/M, 1: generalized balance heuristic
uniform int u_vis_reuse;     // 1: store shadowed picks as empty reservoirs

layout(rgba32ui, binding = IMAGE_UNIT_REUSE_RESERVOIR) writeonly uniform uimage2D u_hist_res;
layout(rgba32f, binding = IMAGE_UNIT_REUSE_SURFACE) writeonly uniform image2D u_hist_geo;

const int NMAX = LIM_REUSE_K_MAX + 1;

// This frame's reservoir of pixel px: its own, or its quad's (STB_REUSE_QUAD: resampled
// at one pixel of the quad; its neighbours' MIS targets are then evaluated at the
// neighbour pixels, not at the pixels that resampled them -- exact for reuse_k = 0).
ivec2 reuse_texel(ivec2 px) {
#ifdef STB_REUSE_QUAD
    return px / 2;
#else
    return px;
#endif
}

#ifdef STB_REUSE_AREA_PASS
// This pixel's sun + ambient radiance, for stb_reuse_area.frag (listed pixels only).
layout(rgba32f, binding = IMAGE_UNIT_REUSE_PARTIAL) writeonly uniform image2D u_partial;
#endif

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    Surface s;
#ifdef STB_REUSE_SHARE
    // Every invocation of the 2x2 quad (helpers outside the image too) joins the
    // exchange before any of them leaves.
    bool ok = all(lessThan(px, ivec2(u_resolution.xy))) && read_surface(px, s);
    uint sgroup = 0u;
#ifdef HAS_LINKS
    if (ok) sgroup = link_group(px);
#endif
    Reservoir shared_res = reuse_share_quad(px, ok, s, sgroup);
#else
    bool ok = read_surface(px, s);
#endif
    vec3 emission = surface_emission(px);
    if (!ok) {
        imageStore(u_hist_res, px, reservoir_pack(reservoir_empty()));
        imageStore(u_hist_geo, px, vec4(0.0));
        write_background(px);
        return;
    }
    float depth = texelFetch(g_depth, px, 0).r;
#ifdef HAS_LINKS
    uint group = link_group(px);
    vec3 c = sun_and_ambient(s, group);
#else
    uint group = 0u;
    vec3 c = sun_and_ambient(s);
#endif
    // Candidate reservoirs: 0 = this pixel's, then the kept neighbours.
    Reservoir res[NMAX];
    Surface srf[NMAX];
    uint grp[NMAX];
#if defined(STB_REUSE_SHARE)
    res[0] = shared_res;
#elif defined(STB_REUSE_FUSED)
    {
        Rng ri = rng_init(uint(px.y) * 8192u + uint(px.x) + 0x71000000u, u_counts.y);
        float pfloor;
        res[0] = reuse_initial_bigtile(vec2(px) + 0.5, s, group, ri, pfloor);
    }
#else
    res[0] = reservoir_unpack(texelFetch(u_reuse, reuse_texel(px), 0));
#endif
    srf[0] = s;
    grp[0] = group;
    int n = 1;
    Rng rng = rng_init(uint(px.y) * 8192u + uint(px.x) + 0x72000000u, u_counts.y);
    for (int i = 0; i < u_k; ++i) {
        float r = u_radius * sqrt(rng_float(rng));
        float a = 2.0 * PI * rng_float(rng);
        ivec2 q = px + ivec2(floor(r * vec2(cos(a), sin(a)) + 0.5));
        if (reuse_texel(q) == reuse_texel(px) || any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, ivec2(u_resolution.xy)))) continue;
        Surface sq;
        if (!read_surface(q, sq)) continue;
        float dq = texelFetch(g_depth, q, 0).r;
        if (!reuse_similar(depth, s.N, s.roughness, dq, sq.N, sq.roughness)) continue;
        res[n] = reservoir_unpack(texelFetch(u_reuse, reuse_texel(q), 0));
        srf[n] = sq;
#ifdef HAS_LINKS
        grp[n] = link_group(q);
#else
        grp[n] = 0u;
#endif
        ++n;
    }
#ifndef STB_REUSE_FUSED
    Stream str = stream_empty();
    float M = 0.0;
    for (int i = 0; i < n; ++i) M += res[i].M;
    for (int i = 0; i < n; ++i) {
        Reservoir ri = res[i];
        if (ri.y == LIM_EMPTY_LIGHT_INDEX || !(ri.W > 0.0)) continue;
        float pc = reuse_target(ri.y, s, group);
        float w;
        if (u_mis == 2) {
            // Pairwise MIS with confidences: the canonical (this pixel, c = 0) against each
            // neighbour j in turn, A_j(x) = Mn p_j(x) / (Mn p_j(x) + Mc p_c(x)), pair j
            // weighted M_j / Mn (Mn: the neighbours' total M); m_j(y_j) = M_j / Mn x
            // A_j(y_j), m_c(y_c) = sum_j M_j / Mn x (1 - A_j(y_c)). Sums to 1 for any x,
            // 0 where p_j(x) = 0, and M_i / M for equal targets; 2k + 1 targets
            // (p_j(y_j) is the neighbour's own, stored with its reservoir).
            float Mc = res[0].M, Mn = M - res[0].M;
            float m;
            if (n == 1 || !(Mn > 0.0)) {
                m = i == 0 ? 1.0 : 0.0;
            } else if (i == 0) {
                m = 0.0;
                for (int j = 1; j < n; ++j) {
                    float pj = reuse_target(ri.y, srf[j], grp[j]);
                    float den = Mn * pj + Mc * pc;
                    m += den > 0.0 ? res[j].M / Mn * (Mc * pc / den) : res[j].M / Mn;
                }
            } else {
                float den = Mn * ri.p + Mc * pc;
                m = den > 0.0 ? res[i].M * ri.p / den : 0.0;
            }
            w = m * pc * ri.W;
        } else if (u_mis == 1) {
            // m_i(y_i) = M_i p_i(y_i) / sum_j M_j p_j(y_i); p_0 = pc.
            float num = 0.0, den = 0.0;
            for (int j = 0; j < n; ++j) {
                float pj = j == 0 ? pc : reuse_target(ri.y, srf[j], grp[j]);
                den += res[j].M * pj;
                if (j == i) num = res[j].M * pj;
            }
            w = den > 0.0 ? num / den * pc * ri.W : 0.0;
        } else {
            w = pc * ri.W * ri.M;
        }
        stream_add(str, ri.y, pc, w, rng_float(rng));
    }
    Reservoir fin = stream_reservoir(str, M, u_mis == 0 ? M : 1.0);
#else
    // Fused (k = 0): resampling the one reservoir would return it (W = p W / p): it is
    // kept as it is, one target evaluation fewer per pixel.
    Reservoir fin = res[0];
#endif
    if (fin.y != LIM_EMPTY_LIGHT_INDEX) {
        Light L = lights[fin.y];
        vec3 Ldir, d, sp;
        float term = 0.0;
#ifdef STB_REUSE_AREA_PASS
        // light_reflect's point model here; a pick that needs its area path is listed
        // for stb_reuse_area.frag with this pixel's radiance so far (common/reuse_area.glsl).
        int how = reuse_point_reflect(L, s, Ldir, d, sp);
        if (how == REUSE_AREA_PATH) {
            reuse_area_px[atomicAdd(reuse_area_count, 1u)] = uint(px.x) | (uint(px.y) << 16);
            imageStore(u_partial, px, vec4(c, 0.0));
            term = 1.0;  // stb_reuse_area.frag applies u_vis_reuse
        } else if (how == REUSE_POINT_MODEL) {
#else
        if (light_reflect(L, s, Ldir, d, sp)) {
#endif
            term = reuse_term(L, s.P, s.N);
            c += (d * L.misc.z + sp * L.misc.w) * term * fin.W;
        }
        if (u_vis_reuse == 1 && term <= 0.0) {
            fin.W = 0.0;
            fin.y = LIM_EMPTY_LIGHT_INDEX;
            fin.p = 0.0;
        }
    }
    imageStore(u_hist_res, px, reservoir_pack(fin));
    imageStore(u_hist_geo, px, vec4(depth, texelFetch(g_normal, px, 0).rg, s.roughness));
    c += emission;
    write_lighting(px, s, c);
}
