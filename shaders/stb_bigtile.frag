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
#include "common/bigtile_target.glsl"

uniform ivec2 u_block;          // slot block per big tile (K = x * y)
uniform float u_weight_cap;     // W <= cap * candidates; <= 0: unbiased (no cap)

layout(location = 0) out uint o_sample;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    ivec2 tile = p / u_block;
    ivec2 local = p - tile * u_block;
    const uint K = uint(STB_K);  // compile-time: u_block.x * u_block.y
    uint slot = uint(local.y * u_block.x + local.x);
    uint n = u_counts.x;
    if (slot >= n) {
        o_sample = pack_sample(LIM_EMPTY_LIGHT_INDEX, 0.0);
        return;
    }
    vec3 A, B, C;
    float R;
    tile_segment(tile, A, B, C, R);
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
