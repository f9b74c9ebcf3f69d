// STB big-tile sampling (one fragment per big-tile reservoir slot): stratified
// reservoir sampling. Lights are split into K streams; iteration 0 gives slot s
// the light s, iteration k the light kK + (s + o_k) mod K with o_k from a PRNG
// seeded by (big tile, frame) -- the same for every slot, so no light lands in
// two slots. Each slot runs one-sample A-Chao WRS with target p = Phi / d^2
// (d: distance to the tile's central depth segment) and stores
// (light, W = sum p / p(selected)).
//
// Target modes: 0 "segment" (the talk's Phi / d^2), 1 "uniform", 2 "shaped":
// Phi / d^2 x max(emission x cone x IES towards the segment's nearest point,
// LIM_BIGTILE_SHAPE_FLOOR), and exactly 0 for a light that cannot reach any pixel
// that may use this reservoir: the 3x3 big tiles around it (stochastic bilinear
// selection reaches one tile over) between their min and max depth, bounded by a
// sphere -- out of range, behind a one-sided emitter, or outside the cone. Positive
// wherever the light can contribute, so the estimate stays unbiased.
#include "common/frame.glsl"
#include "common/rng.glsl"
#include "common/packing.glsl"
#include "common/lights.glsl"

layout(binding = TEX_UNIT_HIZ) uniform sampler2D u_hiz;  // rg32f min/max depth, one texel per big tile
uniform ivec2 u_block;          // slot block per big tile (K = x * y)
uniform int u_big_px;           // big tile size (px)
uniform int u_target_mode;      // 0: segment (the talk's), 1: uniform, 2: shaped (default)
uniform float u_weight_cap;     // W <= cap * candidates; <= 0: unbiased (no cap)

layout(location = 0) out uint o_sample;

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

float target(uint i, vec3 A, vec3 B, vec3 C, float R) {
    if (u_target_mode == 1) return 1.0;
    Light L = lights[i];
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

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    ivec2 tile = p / u_block;
    ivec2 local = p - tile * u_block;
    uint K = uint(u_block.x * u_block.y);
    uint slot = uint(local.y * u_block.x + local.x);
    uint n = u_counts.x;
    vec2 mm = texelFetch(u_hiz, tile, 0).rg;
    if (slot >= n) {
        o_sample = pack_sample(LIM_EMPTY_LIGHT_INDEX, 0.0);
        return;
    }
    if (mm.y <= 0.0) {
        // No geometry in this tile, but stochastic bilinear selection lets
        // neighbouring small tiles use it: fill it with the whole view ray as
        // its segment (any positive target keeps their estimate unbiased).
        mm = u_clip.xy;
    }
    vec2 c = min((vec2(tile) + 0.5) * float(u_big_px), u_resolution.xy - 0.5);
    vec3 A = world_pos_from_depth(c, mm.x);
    vec3 B = world_pos_from_depth(c, mm.y);
    vec3 C = vec3(0.0);
    float R = 3.0e38;
    if (u_target_mode == 2) region_sphere(tile, C, R);
    uint tile_index = uint(tile.y) * 4096u + uint(tile.x);
    Rng off = rng_init(tile_index, u_counts.y);
    Rng acc = rng_init(tile_index * uint(LIM_BIG_TILE_SLOTS_MAX) + slot + 0x10000000u, u_counts.y ^ 0x5bd1e995u);
    float total = 0.0, sel_p = 0.0;
    uint sel = LIM_EMPTY_LIGHT_INDEX;
    float count = 0.0;
    for (uint base = 0u; base < n; base += K) {
        uint o = base == 0u ? 0u : (rng_next(off) >> 16) % K;
        uint i = base + (slot + o) % K;
        if (i >= n) continue;
        float pl = target(i, A, B, C, R);
        count += 1.0;
        total += pl;
        if (pl > 0.0 && rng_float(acc) * total <= pl) {
            sel = i;
            sel_p = pl;
        }
    }
    float W = sel_p > 0.0 ? total / sel_p : 0.0;
    if (u_weight_cap > 0.0) W = min(W, u_weight_cap * count);
    o_sample = pack_sample(sel, W);
}
