// STB reuse (issue 31), pass 1 of 2: per pixel, the initial reservoir from the pixel's
// small-tile samples, combined with last frame's reservoir of the same surface.
//
// * Initial candidates: the STB_N samples of the pixel's small tile (stb_smalltile.frag),
//   each a light with an unbiased contribution weight W_j for its stream (select=all: the
//   streams partition the K candidates, so the estimates add up) or for all lights
//   (select=quad/pixel/ris: N independent picks, each a whole estimate, so 1/N of the
//   sum: u_init_scale). Resampled by the per-pixel target p (common/reuse_target.glsl):
//   w_j = p(y_j) W_j x scale, W = sum w / p(y). Confidence M = 1.
// * STB_REUSE_BIGTILE (-o reuse_candidates=C > 0): instead, C of the big tile's K
//   reservoirs resampled with this pixel's own target, no small-tile pass
//   (common/reuse_initial.glsl).
// * STB_REUSE_QUAD (-o reuse_res=quad, with STB_REUSE_BIGTILE): one reservoir per 2x2
//   quad (this pass runs at half resolution), resampled at a random pixel of the quad
//   with that pixel's target + a defensive floor (LIM_REUSE_QUAD_FLOOR x the candidates'
//   mean target, > 0 for every light), so its W is an unbiased contribution weight for
//   all four pixels, which shade it with their own f: a quarter of the targets.
// * Temporal reuse: the previous frame's reservoir at this surface's previous pixel
//   (the G-buffer's motion vectors minus this frame's jitter, nearest texel), kept only
//   when that texel saw the same surface (its stored depth matches this point's depth in
//   the previous view, normal and roughness agree: disocclusion otherwise), its light
//   still in view (u_remap: previous FoV index -> this frame's), and M clamped to
//   u_m_cap. Its target is re-evaluated with this frame's light data (lights move and
//   change). Inside the influence sphere of a light that changed since the last frame
//   the history's M is capped further (u_change_caps; 0 drops it: its W was made for
//   the old lights, and a switched-off light's share lives on in the W of other
//   lights' reservoirs). Combined with the 1/M rule (confidence-weighted: same surface,
//   so the balance heuristic between the two reduces to it while the lights are
//   unchanged).
#include "common/gbuffer.glsl"
#include "common/rng.glsl"
#include "common/lights.glsl"
#include "common/links.glsl"
#include "common/tiles.glsl"
#define AREA_SHADOW_POINTS LIM_AREA_SHADOW_POINTS_STB
#include "common/shadow.glsl"
#include "common/reservoir.glsl"
#include "common/reuse_target.glsl"
#include "common/reuse_geometry.glsl"

#ifdef STB_REUSE_BIGTILE
#include "common/reuse_initial.glsl"
#else
uniform usampler2D u_smalltile;  // rgba32ui small-tile samples
#endif
uniform sampler2D u_motion;      // g_motion: current (jittered) - previous (unjittered) px
uniform usampler2D u_prev_res;   // last frame's reservoirs (reservoir_pack)
uniform sampler2D u_prev_geo;    // last frame's depth (m), oct normal, roughness
uniform mat4 u_prev_view;        // previous world -> view
uniform vec2 u_jitter;           // this frame's subpixel jitter (px)
uniform int u_history;           // 1: the previous frame's reservoirs are usable
uniform int u_remap;             // 1: FoV indices changed since the last frame
uniform float u_m_cap;           // history confidence cap
uniform float u_init_scale;      // 1 (streams) or 1/N (independent picks)
#ifndef STB_REUSE_BIGTILE  // else declared by common/reuse_initial.glsl
uniform float u_shadow_floor;    // < 1: the initial resampling's target x (floor + (1 - floor) V)
#endif
uniform int u_changes;           // lights changed since the last frame (<= LIM_REUSE_MAX_CHANGES)
uniform vec4 u_change_spheres[LIM_REUSE_MAX_CHANGES];  // their influence: centre xyz, radius (m)
uniform float u_change_caps[LIM_REUSE_MAX_CHANGES];    // history confidence cap inside

layout(std430, binding = SSBO_STB_REUSE_REMAP) readonly buffer ReuseRemap { int remap[]; };

layout(location = 0) out uvec4 o_reservoir;

void main() {
#ifdef STB_REUSE_QUAD
    // One reservoir per 2x2 quad, resampled at one of its pixels (a random one per quad
    // and frame; background pixels skipped) and shaded at all four (see the top).
    ivec2 qd = ivec2(gl_FragCoord.xy);
    Rng rq = rng_init(uint(qd.y) * 8192u + uint(qd.x) + 0x74000000u, u_counts.y);
    int k0 = int(rng_next(rq) >> 30);
    ivec2 px = 2 * qd;
    Surface s;
    bool found = false;
    for (int i = 0; i < 4 && !found; ++i) {
        int k = (k0 + i) & 3;
        ivec2 p = 2 * qd + ivec2(k & 1, k >> 1);
        if (all(lessThan(p, ivec2(u_resolution.xy))) && read_surface(p, s)) {
            px = p;
            found = true;
        }
    }
    if (!found) {
        o_reservoir = reservoir_pack(reservoir_empty());
        return;
    }
#else
    ivec2 px = ivec2(gl_FragCoord.xy);
    Surface s;
    if (!read_surface(px, s)) {
        o_reservoir = reservoir_pack(reservoir_empty());
        return;
    }
#endif
    vec2 fc = vec2(px) + 0.5;  // the pixel's centre (px)
#ifdef HAS_LINKS
    uint group = link_group(px);
#else
    uint group = 0u;
#endif
    Rng rng = rng_init(uint(px.y) * 8192u + uint(px.x) + 0x71000000u, u_counts.y);
    // The initial resampling may weight its candidates by a cheap visibility as well
    // (one hard shadow gather, u_shadow_floor < 1): its own reservoir (y0, W0 = sum w /
    // p_init(y0)) is then combined with the history below under the common target p.
    float pfloor = 0.0;  // added to every target of this pass (STB_REUSE_QUAD only)
#ifdef STB_REUSE_BIGTILE
    Reservoir r0 = reuse_initial_bigtile(fc, s, group, rng, pfloor);
#else
    Stream ini = stream_empty();
    ivec2 st; int slot;
    quad_owner(px, st, slot);
    uvec4 smp = texelFetch(u_smalltile, st, 0);
    for (int j = 0; j < STB_N; ++j) {
        uint li = sample_index(smp[j]);
        float Wj = sample_weight(smp[j]);
        if (li == LIM_EMPTY_LIGHT_INDEX || !(Wj > 0.0)) continue;
        float p = reuse_target(li, s, group);
        if (u_shadow_floor < 1.0 && p > 0.0) {
            float v = luminance(local_shadow_hard(lights[li], s.P, s.N));
            p *= u_shadow_floor + (1.0 - u_shadow_floor) * clamp(v, 0.0, 1.0);
        }
        stream_add(ini, li, p, p * Wj * u_init_scale, rng_float(rng));
    }
    Reservoir r0 = stream_reservoir(ini, 1.0, 1.0);
#endif
    Stream str = stream_empty();
    float M = 1.0;
    if (r0.y != LIM_EMPTY_LIGHT_INDEX) {
        float p0 = reuse_target(r0.y, s, group) + pfloor;
        stream_add(str, r0.y, p0, p0 * r0.W, rng_float(rng));  // M0 = 1
    }
    if (u_history == 1) {
        vec2 mv = texelFetch(u_motion, px, 0).xy - u_jitter;
        ivec2 q = ivec2(floor(fc - mv));
        if (all(greaterThanEqual(q, ivec2(0))) && all(lessThan(q, ivec2(u_resolution.xy)))) {
            vec4 g = texelFetch(u_prev_geo, q, 0);
            float prev_d = max(-(u_prev_view * vec4(s.P, 1.0)).z, 1e-6);
            if (reuse_similar(prev_d, s.N, s.roughness, g.x, oct_decode(g.yz), g.w)) {
                Reservoir h = reservoir_unpack(texelFetch(u_prev_res, q, 0));
                uint li = h.y;
                if (u_remap == 1 && li != LIM_EMPTY_LIGHT_INDEX) {
                    int m = remap[li];
                    li = m < 0 ? LIM_EMPTY_LIGHT_INDEX : uint(m);
                }
                float Mh = min(h.M, u_m_cap);
                for (int i = 0; i < u_changes; ++i) {
                    if (distance(s.P, u_change_spheres[i].xyz) < u_change_spheres[i].w) {
                        Mh = min(Mh, u_change_caps[i]);
                    }
                }
                float p = reuse_target(li, s, group) + pfloor;
                if (Mh > 0.0) {
                    stream_add(str, li, p, p * h.W * Mh, rng_float(rng));
                    M += Mh;
                }
            }
        }
    }
    o_reservoir = reservoir_pack(stream_reservoir(str, M, M));
}
