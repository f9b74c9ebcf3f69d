// STB big-tile sampling (one fragment per big-tile reservoir slot): stratified
// reservoir sampling. Lights are split into K streams; iteration 0 gives slot s
// the light s, iteration k the light kK + (s + o_k) mod K with o_k from a PRNG
// seeded by (big tile, frame) -- the same for every slot, so no light lands in
// two slots. Each slot runs one-sample A-Chao WRS with target p = Phi / d^2
// (d: distance to the tile's central depth segment) and stores
// (light, W = sum p / p(selected)).
#include "common/frame.glsl"
#include "common/rng.glsl"
#include "common/packing.glsl"
#include "common/lights.glsl"

layout(binding = TEX_UNIT_HIZ) uniform sampler2D u_hiz;  // rg32f min/max depth, one texel per big tile
uniform ivec2 u_block;          // slot block per big tile (K = x * y)
uniform int u_big_px;           // big tile size (px)
uniform int u_target_mode;      // 0: segment (the talk's), 1: uniform (comparison)
uniform float u_weight_cap;     // W <= cap * candidates; <= 0: unbiased (no cap)

layout(location = 0) out uint o_sample;

float target(uint i, vec3 A, vec3 B) {
    if (u_target_mode == 1) return 1.0;
    vec3 P = lights[i].pos_range.xyz;
    vec3 ab = B - A;
    float t = clamp(dot(P - A, ab) / max(dot(ab, ab), 1e-20), 0.0, 1.0);
    vec3 d = P - (A + t * ab);
    float d2 = max(dot(d, d), LIM_MIN_LIGHT_DISTANCE * LIM_MIN_LIGHT_DISTANCE);
    return max(lights[i].intensity.w, 0.0) / d2;
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
        float pl = target(i, A, B);
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
