// Bit packing: octahedral normals, STB 32-bit light samples.
#ifndef STB_PACKING_GLSL
#define STB_PACKING_GLSL

// Octahedral encoding of a unit vector to [-1, 1]^2 (Meyer et al. 2010).
vec2 oct_wrap(vec2 v) {
    return (1.0 - abs(v.yx)) * vec2(v.x >= 0.0 ? 1.0 : -1.0, v.y >= 0.0 ? 1.0 : -1.0);
}
vec2 oct_encode(vec3 n) {
    n /= (abs(n.x) + abs(n.y) + abs(n.z));
    vec2 e = n.z >= 0.0 ? n.xy : oct_wrap(n.xy);
    return e;
}
vec3 oct_decode(vec2 e) {
    vec3 n = vec3(e.xy, 1.0 - abs(e.x) - abs(e.y));
    float t = clamp(-n.z, 0.0, 1.0);
    n.xy += vec2(n.x >= 0.0 ? -t : t, n.y >= 0.0 ? -t : t);
    return normalize(n);
}

// STB sample: top LIM_SAMPLE_INDEX_BITS bits = FoV light index, low bits =
// log2(weight) in 1/LIM_WEIGHT_STEPS octave steps from LIM_WEIGHT_LOG2_MIN;
// code 0 = weight 0. Index LIM_EMPTY_LIGHT_INDEX = empty slot. (limits.py)
const uint STB_WEIGHT_BITS = 32u - uint(LIM_SAMPLE_INDEX_BITS);
const uint STB_WEIGHT_MASK = (1u << STB_WEIGHT_BITS) - 1u;

uint pack_sample(uint light_index, float weight) {
    uint code = 0u;
    if (weight > 0.0) {
        float l = (log2(weight) - LIM_WEIGHT_LOG2_MIN) * LIM_WEIGHT_STEPS;
        code = uint(clamp(floor(l + 0.5), 1.0, float(STB_WEIGHT_MASK)));
    }
    return (light_index << STB_WEIGHT_BITS) | code;
}
uint sample_index(uint s) { return s >> STB_WEIGHT_BITS; }
float sample_weight(uint s) {
    uint code = s & STB_WEIGHT_MASK;
    if (code == 0u) return 0.0;
    return exp2(float(code) / LIM_WEIGHT_STEPS + LIM_WEIGHT_LOG2_MIN);
}
#endif
