// Albedo demodulation of lighting (the temporal pass filters lighting / albedo, so
// texture detail neither widens its clip box nor blurs through its history).
#ifndef STB_DEMODULATION_GLSL
#define STB_DEMODULATION_GLSL

// The albedo lighting is divided by: diffuse base colour (non-metal part) plus F0,
// floored at 0.04 (black surfaces still keep their lighting).
vec3 demod_albedo(vec4 base_rough, vec4 f0_metal) {
    return max(base_rough.rgb * (1.0 - f0_metal.a) + f0_metal.rgb, vec3(0.04));
}
#endif
