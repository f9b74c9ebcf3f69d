// Albedo demodulation of lighting (the temporal pass filters lighting / albedo, so
// texture detail neither widens its clip box nor blurs through its history).
#ifndef STB_DEMODULATION_GLSL
#define STB_DEMODULATION_GLSL

// The albedo lighting is divided by: the diffuse colour (base colour x (1 - metallic))
// plus F0, floored at 0.04 (black surfaces still keep their lighting).
vec3 demod_albedo_of(vec3 diffuse, vec3 f0) {
    return max(diffuse + f0, vec3(0.04));
}

// The same from the G-buffer's texels (diffuse = base colour x (1 - metallic), as
// read_surface in common/gbuffer.glsl has it).
vec3 demod_albedo(vec4 base_rough, vec4 f0_metal) {
    return demod_albedo_of(base_rough.rgb * (1.0 - f0_metal.a), f0_metal.rgb);
}
#endif
