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

// The window position (px) of the pixel whose per-pixel hashes (stochastic PCF, the
// area-shadow point shift) these are: the fragment's own, unless a pass that shades a
// listed pixel elsewhere (stb_reuse_area.frag) defines SHADOW_PIXEL to it first.
#ifndef SHADOW_PIXEL
#define SHADOW_PIXEL gl_FragCoord.xy
#endif

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

// Soft shadow of an area light by PCSS (Fernando 2005) -- the method before the
// multi-point visibility below, kept for comparison runs (LIM_AREA_SHADOW_POINTS = 0,
// tools/area_lights.py --pcss / cost --models) -- on the map captured from the light's centre, with the kernel shaped like the light. A blocker at distance z from
// the light shadows the receiver (distance D) from the light's points seen through a
// copy of the light's shape scaled by (D - z) / z around the receiver. Taps are points
// of that shape (a Vogel disk mapped onto its two half axes, area-preserving), projected
// along the light direction onto the receiver's plane and then exactly into the map,
// each compared with its own distance to the light (no receiver-plane bias; octahedral
// seams need no care). The blocker search uses z = max(near, D / 20); the filter the
// mean blocker distance. Both are capped at LIM_PCSS_MAX_TEXELS map texels.
// The blocker-search region shared by PCSS and the area lights' early out: the light's
// shape axes A, B seen from the receiver, the receiver plane's slope along the light
// direction, the kernel cap and the search scale (z = max(near, D / 20)).
struct BlockerRegion {
    vec3 Lc;       // map's light position
    float range;   // map's range (m)
    vec3 ldir;     // receiver -> light centre (unit)
    float ndl;     // N . ldir, kept >= 0.05 in magnitude
    vec3 A, B;     // light half axes (world)
    float cap;     // world size of LIM_PCSS_MAX_TEXELS at the receiver
    float amax;    // the larger half axis
    float search;  // search radius (x the axes)
};

BlockerRegion blocker_region(Light L, ShadowMap S, vec3 Pb, vec3 N, float dist) {
    BlockerRegion r;
    r.Lc = S.pos_range.xyz;
    r.range = S.pos_range.w;
    r.ldir = (r.Lc - Pb) / max(dist, 1e-9);
    r.ndl = dot(N, r.ldir);
    if (abs(r.ndl) < 0.05) r.ndl = r.ndl < 0.0 ? -0.05 : 0.05;
    light_shadow_axes(L, r.ldir, r.A, r.B);
    r.cap = LIM_PCSS_MAX_TEXELS * S.params.y * dist;
    r.amax = max(length(r.A), length(r.B));
    float zmin = max(S.params.x, 0.05 * dist);
    r.search = min((dist - zmin) / zmin, r.cap / max(r.amax, 1e-6));
    return r;
}

float shadow_pcss(Light L, ShadowMap S, vec3 Pb, vec3 N, float dist, float rot) {
    BlockerRegion R = blocker_region(L, S, Pb, N, dist);
    vec3 Lc = R.Lc, ldir = R.ldir, A = R.A, B = R.B;
    float range = R.range, ndl = R.ndl, cap = R.cap, amax = R.amax, search = R.search;
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

// ---- Area lights: visibility towards several points of the light (issue 20) ----------
// The map is captured from the light's centre C. Visibility of the light from a receiver
// is the fraction (weighted by each point's diffuse contribution) of light points L_j
// whose segment L_j -> receiver is unoccluded, each segment tested by ray-marching the
// centre map: a point X is "behind" when |X - C| exceeds the map's depth towards X. The
// segment is blocked where it goes from in front to behind *through a surface*: the
// crossing is bisected and kept only when X is then within a thin band behind the map's
// depth (a real front surface); entering the centre's shadow volume from the side
// (behind a silhouette, where the depth jumps) leaves X far behind and is not a block.
// Limits: the map holds only surfaces C sees, so a blocker the light's edge sees but
// its centre does not (or one nearer C than the map's near plane) casts nothing.
#ifndef AREA_SHADOW_POINTS
#define AREA_SHADOW_POINTS LIM_AREA_SHADOW_POINTS
#endif

// R2 low-discrepancy point k (Roberts 2018) in [0, 1)^2, Cranley-Patterson shifted by u0.
vec2 r2_point(int k, vec2 u0) {
    return fract(u0 + float(k) * vec2(0.7548776662, 0.5698402910));
}

// Point of light L (world, m) for the unit-square sample u, as seen from receiver Pb:
// rect and disk uniformly by area; a sphere's silhouette disk facing Pb; a cylinder's
// strip (its length x its diameter) facing Pb. C: the captured centre.
vec3 light_sample_point(Light L, vec3 C, vec3 Pb, vec2 u) {
    vec3 X = L.tangent_tex.xyz;
    float kind = L.area.z;
    if (kind == AREA_RECT) {
        return C + X * (L.area.x * (2.0 * u.x - 1.0)) + light_bitangent(L) * (L.area.y * (2.0 * u.y - 1.0));
    }
    vec3 w = Pb - C;
    float D = length(w);
    w /= max(D, 1e-9);
    if (kind == AREA_CYLINDER) {
        vec3 side = cross(X, w);
        side = dot(side, side) > 1e-8 ? normalize(side) : light_bitangent(L);
        return C + X * (L.area.x * (2.0 * u.x - 1.0)) + side * (L.area.y * (2.0 * u.y - 1.0));
    }
    float r = L.area.x;
    vec3 c = C, A, B;
    if (kind == AREA_DISK) {
        A = X; B = light_bitangent(L);
    } else {                                   // sphere: the silhouette circle from Pb
        float q = min(r / max(D, 1e-9), 0.999);
        c = C + w * (r * q);
        r *= sqrt(1.0 - q * q);
        A = normalize(abs(w.y) < 0.9 ? cross(w, vec3(0.0, 1.0, 0.0)) : cross(w, vec3(1.0, 0.0, 0.0)));
        B = cross(w, A);
    }
    float rr = r * sqrt(u.x), a = 6.2831853 * u.y;
    return c + rr * (cos(a) * A + sin(a) * B);
}

// How far (m) X lies behind the map's first surface towards it: |X - C| minus the depth
// of the nearest texel (a silhouette stays where it is, +-half a texel) -- or, within
// `near_rcv` of the receiver, minus the farthest depth of the 2x2 gather (conservative:
// the receiver's own surface never reads as in front of it). False outside a spot map
// (nothing known there: in front).
bool map_behind(ShadowMap S, vec3 X, bool near_rcv, out float delta) {
    vec2 t;
    delta = -1.0;
    if (!shadow_texel(S, X, t)) return false;
    // One gather serves both: the nearest texel, floor(t + 0.5), is one of the 2x2
    // (gather order (0,1) (1,1) (1,0) (0,0); t - floor(t) >= 0.5 picks the +1 texel, the
    // same texel as floor(t + 0.5) for these sizes): on llvmpipe both sides of the
    // `near_rcv` branch ran, a gather and a texelFetch per lookup.
    vec2 base = floor(t);
    vec4 g = textureGather(u_shadow_atlas, (base + 1.0) * S.params.z, 0);
    bvec2 hi = greaterThanEqual(t - base, vec2(0.5));
    float nearest = hi.y ? (hi.x ? g.y : g.x) : (hi.x ? g.z : g.w);
    float z = near_rcv ? max(max(g.x, g.y), max(g.z, g.w)) : nearest;
    // z = 1: nothing within the map's range in that direction: X is in front.
    delta = z < LIM_AREA_SHADOW_EMPTY_DEPTH ? length(X - S.pos_range.xyz) - z * S.pos_range.w : -1.0;
    return true;
}

// Visibility in [0, 1] of segment A (on the light) -> B (the biased receiver) through
// the centre map: LIM_AREA_SHADOW_STEPS samples at t = (i + tj) / steps, tj in (0, 1],
// and one at B; the first front-to-behind transition is bisected
// (LIM_AREA_SHADOW_REFINE times) and is a block when the point then lies within the
// thickness band behind the map's depth.
float segment_visibility(Light L, ShadowMap S, vec3 A, vec3 B, float tj) {
    float prev = -1.0, tprev = 0.0;             // A: on the light, nearer than the near plane
    float len = length(B - A);
    vec3 C = S.pos_range.xyz;
    // Within this many metres of the receiver (at the receiver's distance) lookups are
    // the conservative gather-max.
    float rcv = LIM_AREA_SHADOW_RECEIVER_TEXELS * S.params.y;
    // One loop, one lookup an iteration: a march sample (k < 0) or a bisection step k of
    // the transition found there. The same lookups in the same order per pixel as a
    // march loop with the bisection nested in an `if` -- whose body (a loop of its own
    // and the block test) llvmpipe ran at every march step of the whole SIMD group.
    int i = 0;                                  // next march sample
    int k = -1;                                 // bisection step (-1: marching)
    float t = 0.0, dl = -1.0, ta = 0.0, tb = 0.0, db = 0.0;
    for (int it = 0; it < (LIM_AREA_SHADOW_STEPS + 1) * (LIM_AREA_SHADOW_REFINE + 1); ++it) {
        if (k < 0) {
            if (i > LIM_AREA_SHADOW_STEPS) break;
            t = i < LIM_AREA_SHADOW_STEPS ? (float(i) + tj) / float(LIM_AREA_SHADOW_STEPS) : 1.0;
            if (t <= tprev) { ++i; continue; }
        }
        float tq = k < 0 ? t : 0.5 * (ta + tb);
        vec3 X = mix(A, B, tq);
        float d;
        map_behind(S, X, (1.0 - tq) * len < rcv * length(X - C), d);
        if (k < 0) {
            dl = d;
            if (dl > 0.0 && prev <= 0.0) { ta = tprev; tb = t; db = dl; k = 0; }
        } else {
            if (d > 0.0) { tb = tq; db = d; } else ta = tq;
            ++k;
        }
        if (k == LIM_AREA_SHADOW_REFINE) {     // the transition refined: a block?
            vec3 Xb = mix(A, B, tb);
            float thick = LIM_AREA_SHADOW_THICK_TEXELS * S.params.y * length(Xb - C)
                        + LIM_AREA_SHADOW_THICK_STEPS * (tb - ta) * len;
            if (db < thick) {
                float maxd = L.shadow_color.w;
                if (maxd <= 0.0) return 0.0;
                float to_occ = (1.0 - tb) * len;
                float fall = L.misc.x > 0.0 ? min(L.misc.x, maxd) : 0.0;
                float fade = fall > 0.0
                    ? pow(clamp((to_occ - (maxd - fall)) / fall, 0.0, 1.0), max(L.misc.y, 1e-3))
                    : (to_occ > maxd ? 1.0 : 0.0);
                if (fade < 1.0) return fade;
            }
            k = -1;
        }
        if (k < 0) {
            prev = dl;
            tprev = t;
            ++i;
        }
    }
    return 1.0;
}

// Early out of shadow_area: LIM_AREA_SHADOW_SEARCH taps over PCSS's blocker-search
// region (pcss_blockers); a tap is a blocker only where all 4 texels of its gather are
// nearer than the tap (at grazing incidence the receiver's own surface differs by more
// than the normal offset between neighbouring texels, and would otherwise "block"
// every pixel). False: no blocker anywhere in the region, the receiver is fully lit.
bool area_blocker_search(Light L, ShadowMap S, vec3 Pb, vec3 N, float dist, float rot) {
    BlockerRegion R = blocker_region(L, S, Pb, N, dist);
    vec3 Lc = R.Lc, ldir = R.ldir, A = R.A, B = R.B;
    float range = R.range, ndl = R.ndl, search = R.search;
    float a = LIM_AREA_SHADOW_SEARCH_CONE * light_half_extent(L);
    // Depth tolerance per metre of distance: texels at grazing incidence (1 / cos, up to
    // 1 / LIM_AREA_SHADOW_SEARCH_COS) -- a blocker stands clear of the receiver's plane.
    float tol = LIM_AREA_SHADOW_THICK_TEXELS * S.params.y / max(abs(dot(N, ldir)), LIM_AREA_SHADOW_SEARCH_COS);
    // Tap 0 is the receiver itself (the centre's hard shadow: a blocker on the axis,
    // however large, is seen there); taps 1.. a Vogel disk over the region.
    for (int k = 0; k <= LIM_AREA_SHADOW_SEARCH; ++k) {
        vec2 o2 = k == 0 ? vec2(0.0) : vogel(k - 1, LIM_AREA_SHADOW_SEARCH, rot) * search;
        vec3 o = A * o2.x + B * o2.y;
        vec3 X = Pb + o - ldir * (dot(o, N) / ndl);
        vec2 tk;
        if (!shadow_texel(S, X, tk)) continue;
        vec4 g = textureGather(u_shadow_atlas, (floor(tk) + 1.0) * S.params.z, 0);
        float rx = length(X - Lc);
        float z = max(max(g.x, g.y), max(g.z, g.w));
        // z = 1: nothing within the map's range there (a tap past the range is no blocker)
        // ... and a surface at distance zr from the light towards the tap, which lies h
        // off the axis receiver -> light centre (so the surface lies h zr / rx off it),
        // meets the cone receiver -> light (radius a (D - zr) / D there; a: the light's
        // half extent) only when zr (h D + a rx) <= a rx D.
        float zr = z * range;
        vec3 dx = X - Pb;
        float hx = length(dx - ldir * dot(dx, ldir));
        if (z < LIM_AREA_SHADOW_EMPTY_DEPTH && zr < rx - tol * rx && zr * (hx * dist + a * rx) <= a * rx * dist) return true;
    }
    return false;
}

// Visibility of area light L from the biased receiver Pb (normal N): the weighted
// fraction of AREA_SHADOW_POINTS light points (R2 set shifted by u0) whose segments are
// unoccluded; weights are each point's diffuse contribution cos_r (cos_e) / d^2 (x the
// texture's luminance on a textured rect), so points below the receiver's horizon (or
// behind a one-sided emitter) do not count.
float shadow_area(Light L, ShadowMap S, vec3 Pb, vec3 N, vec2 u0, float dist) {
    vec3 C = S.pos_range.xyz;
#if LIM_AREA_SHADOW_SEARCH > 0
    if (!area_blocker_search(L, S, Pb, N, dist, u0.x * 6.2831853)) return 1.0;
#endif
    vec3 Z = L.axis_emit.xyz;
    bool planar = L.area.z == AREA_RECT || L.area.z == AREA_DISK;
    float vs = 0.0, ws = 0.0;
    for (int k = 0; k < AREA_SHADOW_POINTS; ++k) {
        vec2 u = r2_point(k, u0);
        vec3 Lj = light_sample_point(L, C, Pb, u);
        vec3 d = Lj - Pb;
        float dd = max(dot(d, d), 1e-10);
        vec3 w = d * inversesqrt(dd);
        float wt = max(dot(N, w), 0.0) / dd;
        if (planar) wt *= max(-dot(Z, w), 0.0);
#ifdef RECT_TEXTURES
        // A textured rect: each point weighs its texture's luminance too (the texture
        // at the points' spacing), so a dark part's shadow does not count.
        if (L.tangent_tex.w >= 0.0 && L.area.z == AREA_RECT)
            wt *= dot(rect_tex_at(L.tangent_tex.w, u, rect_tex_max_lod()
                                  - 0.5 * log2(float(AREA_SHADOW_POINTS))), LUMINANCE_REC709);
#endif
        if (wt <= 0.0) continue;
        ws += wt;
        float tj = 1.0 - fract(u0.y + 0.6180340 * float(k));
        vs += wt * segment_visibility(L, S, Lj, Pb, tj);
    }
    return ws > 0.0 ? vs / ws : 1.0;
}

// Returns the RGB transmission mix(shadow:color, 1, visibility). soft: PCSS for lights
// shaded as areas; false: one bilinear PCF gather for every light (STB's resampling
// targets: an approximate visibility is all a target needs, at 1/24 of the taps).
vec3 local_shadow_impl(Light L, vec3 P, vec3 N, vec2 jitter, bool soft, vec2 u0) {
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
    float v;
    if (!(soft && light_is_area(L, dist0))) v = shadow_tap(L, S, t, ref, dist);
#if LIM_AREA_SHADOW_POINTS > 0
    else v = shadow_area(L, S, Pb, N, u0, dist);
#else
    else v = shadow_pcss(L, S, Pb, N, dist, jitter.x * 6.2831853);   // comparison runs only
#endif
    return mix(L.shadow_color.rgb, vec3(1.0), v);
}

// Shift of the area-shadow point set (r2_point) for this pixel: a per-pixel hash, so a
// penumbra's quantisation into AREA_SHADOW_POINTS levels is fine noise, not bands; with
// AREA_SHADOW_PER_FRAME (STB's term pass, fewer points) also per frame, so accumulated
// frames converge to the whole light's visibility; with AREA_SHADOW_SEQUENCE (the exact
// methods) per integrated frame (FrameContext.sample_index: 0 for a lone frame).
#ifdef AREA_SHADOW_SEQUENCE
uniform float u_area_shadow_index;
#endif
vec2 area_shadow_shift() {
    uvec2 q = uvec2(SHADOW_PIXEL);
    uint h = q.x * 1973u + q.y * 9277u + 0x68e31da4u;
#if defined(AREA_SHADOW_SEQUENCE)
    h += uint(u_area_shadow_index) * 26699u;
#elif defined(AREA_SHADOW_PER_FRAME)
    h += uint(u_clip.z) * 26699u;
#endif
    h ^= h >> 15; h *= 0x2c1b3c6du; h ^= h >> 12; h *= 0x297a2d39u; h ^= h >> 15;
    return vec2(float(h & 0xffffu), float(h >> 16)) / 65536.0;
}

vec3 local_shadow_jittered(Light L, vec3 P, vec3 N, vec2 jitter) {
    return local_shadow_impl(L, P, N, jitter, true, area_shadow_shift());
}

// Hard (single-gather) visibility for resampling targets.
vec3 local_shadow_hard(Light L, vec3 P, vec3 N) {
    return local_shadow_impl(L, P, N, vec2(0.0), false, vec2(0.0));
}

vec3 local_shadow(Light L, vec3 P, vec3 N) {
#ifdef STOCHASTIC_PCF
    // Stochastic PCF: one random sub-texel offset (+-0.5 texel) per pixel and frame
    // on top of the 4-tap gather -- softer edges for the same single gather.
    uvec2 q = uvec2(SHADOW_PIXEL);
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
vec3 light_radiance_impl(Light L, Surface s, const bool shadowed) {
    vec3 Ldir, d, sp;
    if (!light_reflect_exact(L, s, Ldir, d, sp)) return vec3(0.0);
    vec3 c = (d * L.misc.z + sp * L.misc.w) * light_shape_scalar(L, -Ldir);
    if (c.r + c.g + c.b <= 0.0) return vec3(0.0);
    return shadowed ? c * local_shadow(L, s.P, s.N) : c;
}
vec3 light_radiance(Light L, Surface s) { return light_radiance_impl(L, s, true); }
// light_radiance for a light without a shadow map (ies_shadow.z < 0: local_shadow is 1,
// the same value) with the shadow code left out: the exact methods' loops over the
// lights without shadows (SPLIT_UNSHADOWED, light_buffer.unshadowed_first; on llvmpipe
// a loop's shadow code runs for every light of the SIMD group, shadowed or not).
vec3 light_radiance_unshadowed(Light L, Surface s) { return light_radiance_impl(L, s, false); }

// light_radiance for a sphere light (L.area.z == AREA_SPHERE: radius > 0, not
// treatAsPoint) with only the sphere's code: the point model, or the closed-form diffuse
// and the specular (point model, blended with LTC over the silhouette where the lobe is
// narrow against the light) -- the same operations as light_reflect's sphere path, so
// the same value, without the rect / disk / cylinder code. `narrow`: the light is
// narrow against every lobe it reaches (area_spec_weight is 0 at every receiver:
// renderer/light_buffer.narrow_spheres), so the LTC code is left out; on llvmpipe a
// branch's body runs even where no lane takes it. The exact methods loop over their
// sphere lights with light_radiance_sphere_narrow / light_radiance_sphere_wide.
vec3 light_radiance_sphere_impl(Light L, Surface s, const bool narrow, const bool shadowed) {
#ifdef HAS_CLEARCOAT
    if (s.coat > 0.0) return light_radiance(L, s);
#endif
    vec3 Ldir;
    float dist;
    float f = light_falloff(L, s.P, Ldir, dist);
    if (f <= 0.0) return vec3(0.0);
    float ws = narrow || L.misc.w == 0.0 ? 0.0 : area_spec_weight(L.area.x, dist, s.alpha);
    vec3 dsp, ssp, d, sp;
    brdf_eval(s, Ldir, dsp, ssp);
    if (!light_is_area(L, dist) && ws <= 0.0) {
        vec3 E = L.intensity.rgb * light_shape_rgb(L, -Ldir) * f;
        d = dsp * E;
        sp = ssp * E;
    } else if (narrow) {
        if (!sphere_reflect_narrow(L, s, Ldir, dist, f, ssp, d, sp)) return vec3(0.0);
    } else if (!sphere_reflect(L, s, Ldir, dist, f, ws, ssp, d, sp)) {
        return vec3(0.0);
    }
    vec3 c = (d * L.misc.z + sp * L.misc.w) * light_shape_scalar(L, -Ldir);
    if (c.r + c.g + c.b <= 0.0) return vec3(0.0);
    return shadowed ? c * local_shadow(L, s.P, s.N) : c;
}
vec3 light_radiance_sphere_narrow(Light L, Surface s) {
    return light_radiance_sphere_impl(L, s, true, true);
}
vec3 light_radiance_sphere_wide(Light L, Surface s) {
    return light_radiance_sphere_impl(L, s, false, true);
}
// The same for sphere lights without a shadow map (light_radiance_unshadowed).
vec3 light_radiance_sphere_narrow_unshadowed(Light L, Surface s) {
    return light_radiance_sphere_impl(L, s, true, false);
}
vec3 light_radiance_sphere_wide_unshadowed(Light L, Surface s) {
    return light_radiance_sphere_impl(L, s, false, false);
}

// light_radiance for light i of the light buffer, a light without extent
// (light_half_extent == 0: never an area, no specular LTC weight), with only the point
// model's code: the same operations as light_reflect's point path, so the same value.
// The exact methods loop over their point lights with this (u_point_lights): where
// both sides of a branch execute (llvmpipe's SIMD lanes), a loop carrying the polygon
// and LTC code pays for it on every light. It takes the light's index, not a Light:
// it reads pos_range alone for the range test and the other members only past it (on
// llvmpipe a Light argument copied all ten vec4 of every light from the SSBO before
// the test: the reference's point loop cost 5.8x the bare loop, issue 34).
vec3 light_radiance_point_at(uint i, Surface s) {
    vec3 Ldir;
    float dist;
    float f = light_falloff_m(lights[i].pos_range, s.P, Ldir, dist);
    if (f <= 0.0) return vec3(0.0);
    vec4 axis_emit = lights[i].axis_emit;
    vec4 cone = lights[i].cone;
    vec4 tint_ies = lights[i].tint_ies;
    vec3 tangent = lights[i].tangent_tex.xyz;
    vec4 ies_shadow = lights[i].ies_shadow;
    vec3 E = lights[i].intensity.rgb
           * (light_tint_rgb_m(axis_emit, cone, tint_ies, ies_shadow.x, -Ldir)
              * emission_shape_m(axis_emit, tangent, -Ldir))
           * f;
    vec3 d, sp;
#ifdef HAS_CLEARCOAT
    if (s.coat > 0.0) {  // area_reflect_coated's point path (ws = wc = 0)
        vec3 dsp, ssp;
        float csp, fc;
        brdf_eval_layers(s, Ldir, dsp, ssp, csp, fc);
        float att = 1.0 - fc;
        d = dsp * E * att;
        sp = ssp * E * att + vec3(csp) * E;
    } else
#endif
    {
        vec3 dsp, ssp;
        brdf_eval(s, Ldir, dsp, ssp);
        d = dsp * E;
        sp = ssp * E;
    }
    vec4 misc = lights[i].misc;
    vec3 c = (d * misc.z + sp * misc.w)
           * light_shape_scalar_m(axis_emit, cone, tint_ies, tangent, ies_shadow.y, -Ldir);
    if (c.r + c.g + c.b <= 0.0) return vec3(0.0);
#ifdef HAS_SHADOWS
    if (ies_shadow.z < 0.0) return c;  // unshadowed: no Light copy for local_shadow
    return c * local_shadow(lights[i], s.P, s.N);
#else
    return c;
#endif
}
#endif
