// The talk's fast LCG (SIGGRAPH 2025 STB appendix): state = state * 2797636423 + 2659483769,
// floats from the top 23 bits. Seeded from (tile index, frame index).
#ifndef STB_RNG_GLSL
#define STB_RNG_GLSL
struct Rng { uint state; };

Rng rng_init(uint a, uint b) {
    // Mix the two seeds so neighbouring tiles/frames decorrelate (one PCG-style hash step).
    uint s = a * 283u + b * 309769u + 0x9E3779B9u;
    s ^= s >> 16; s *= 0x7feb352du; s ^= s >> 15; s *= 0x846ca68bu; s ^= s >> 16;
    Rng r; r.state = s; return r;
}
uint rng_next(inout Rng r) {
    r.state = r.state * 2797636423u + 2659483769u;
    return r.state;
}
// [0, 1)
float rng_float(inout Rng r) {
    return uintBitsToFloat((rng_next(r) >> 9) | 0x3f800000u) - 1.0;
}
// [0, 65536)
uint rng_u16(inout Rng r) { return rng_next(r) >> 16; }
#endif
