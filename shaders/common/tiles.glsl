// STB tile geometry: big tiles, (interleaved) small tiles of quads, and the
// quad <-> (small tile, slot) mappings. Interleaved mode: 4 small tiles share a
// 32x32 px footprint (INTERLEAVE_FOOTPRINT_PX, 16x16 quads); the 16x16 inverse LUT
// gives each quad's (tile 0..3, slot 0..63) and the forward table each (tile, slot)'s quad
// (tools/gen_quad_patterns.py). The footprint grid (and with it the 2x2
// quad grid) is shifted by a per-frame offset of any number of pixels. Plain mode: small tile = S x S px block, slot = quad
// row-major. Small tile (sx, sy) of footprint F is (2F.x + (t & 1), 2F.y + (t >> 1)).
#ifndef STB_TILES_GLSL
#define STB_TILES_GLSL

uniform isampler2D u_quad_lut;      // 16x16 r32i per layer: tile | slot << QUAD_LUT_SLOT_SHIFT
uniform isampler2D u_quad_fwd;      // 64x4 r32i per layer: qx | qy << QUAD_FWD_Y_SHIFT, row = tile
uniform ivec2 u_pattern_offset;     // px, per frame (0 .. footprint - 1)
uniform int u_pattern_layer;        // this frame's pattern in the LUTs (layers stacked in y)
uniform int u_interleave;           // 1: interleaved footprints, 0: plain small tiles
uniform int u_small_px;             // small tile size in plain mode (px)

// Interleaved mode: footprint, its small tiles (px) and their quads per side.
const int IL_FOOT_PX = INTERLEAVE_FOOTPRINT_PX;
const int IL_SMALL_PX = INTERLEAVE_FOOTPRINT_PX / 2;
const int IL_QUADS = INTERLEAVE_QUADS_PER_SIDE;

int quads_per_side() { return u_interleave == 1 ? IL_QUADS : u_small_px / 2; }

// Small tile and slot owning pixel px.
void quad_owner(ivec2 px, out ivec2 small_tile, out int slot) {
    ivec2 p = px + u_pattern_offset;
    if (u_interleave == 1) {
        ivec2 f = p / IL_FOOT_PX;
        ivec2 q = (p - f * IL_FOOT_PX) / 2;
        int v = texelFetch(u_quad_lut, q + ivec2(0, 16 * u_pattern_layer), 0).r;
        int t = v & ((1 << QUAD_LUT_SLOT_SHIFT) - 1);
        slot = v >> QUAD_LUT_SLOT_SHIFT;
        small_tile = 2 * f + ivec2(t & 1, t >> 1);
    } else {
        small_tile = p / u_small_px;
        ivec2 q = (p - small_tile * u_small_px) / 2;
        slot = q.y * (u_small_px / 2) + q.x;
    }
}

// Top-left pixel of the quad of (small tile, slot); may be outside the image.
ivec2 quad_pixel(ivec2 small_tile, int slot) {
    if (u_interleave == 1) {
        ivec2 f = small_tile / 2;
        int t = (small_tile.x & 1) | ((small_tile.y & 1) << 1);
        int v = texelFetch(u_quad_fwd, ivec2(slot, t + 4 * u_pattern_layer), 0).r;
        ivec2 q = ivec2(v & ((1 << QUAD_FWD_Y_SHIFT) - 1), v >> QUAD_FWD_Y_SHIFT);
        return f * IL_FOOT_PX + q * 2 - u_pattern_offset;
    }
    int s = u_small_px / 2;
    ivec2 q = ivec2(slot % s, slot / s);
    return small_tile * u_small_px + q * 2 - u_pattern_offset;
}

// Nominal centre of a small tile (px).
vec2 small_tile_centre(ivec2 small_tile) {
    if (u_interleave == 1) {
        return vec2(small_tile / 2) * float(IL_FOOT_PX) + vec2(small_tile & 1) * float(IL_SMALL_PX)
               + 0.5 * float(IL_SMALL_PX) - vec2(u_pattern_offset);
    }
    return (vec2(small_tile) + 0.5) * float(u_small_px) - vec2(u_pattern_offset);
}

int quads_per_tile() {
    return u_interleave == 1 ? IL_QUADS * IL_QUADS : (u_small_px / 2) * (u_small_px / 2);
}

// Texel of the shadow-term block of (small tile, slot).
ivec2 term_texel(ivec2 small_tile, int slot) {
    int s = quads_per_side();
    return small_tile * s + ivec2(slot % s, slot / s);
}

#ifdef STB_SELECT_ONE
#include "common/rng.glsl"
// One hash of (a, b, c, frame seed): rng_init's mixing step.
uint select_hash(uint a, uint b, uint c) {
    return rng_init(a * 73856093u ^ b * 19349663u ^ c * 83492791u, u_counts.y).state;
}// Quad selection: the one small-tile sample (0 .. STB_N - 1) this quad uses this
// frame, a hash of (small tile, slot, frame seed). The shadow and lighting passes
// compute the same value, so a quad's term and its light always match.
int quad_stream(ivec2 small_tile, int slot) {
    return int(select_hash(uint(small_tile.y), uint(small_tile.x), uint(slot)) % uint(STB_N));
}
// Pixel selection: the one sample pixel px uses this frame (the shadow pass computes
// every sample's term, so any choice has its term).
int pixel_stream(ivec2 px) {
    return int(select_hash(uint(px.y), uint(px.x), 0x51u) % uint(STB_N));
}
#endif
#endif
