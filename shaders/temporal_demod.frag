// Temporal pass, step 1 (--temporal taa): lighting demodulated by albedo and the
// linear depth in one rgba32f texel, once per pixel, so the main pass's 13-tap
// neighbourhood (temporal.frag) reads one texture per tap instead of four (lighting,
// base colour, F0/metal, depth) and divides no more; the albedo and the lighting's
// alpha in a second one, for the main pass's remodulation (one float fetch instead
// of three half-float ones: llvmpipe converts half floats in software).
#include "common/demodulation.glsl"

uniform sampler2D u_current;   // lighting (scene-linear, this frame, jittered raster)
uniform sampler2D u_depth;     // g_depth: linear view depth (m), 0 = no geometry
uniform sampler2D u_base;      // g_base_rough
uniform sampler2D u_f0;        // g_f0_metal

layout(location = 0) out vec4 o_demod;   // rgb lighting / albedo, a linear depth (m)
layout(location = 1) out vec4 o_albedo;  // rgb demodulation albedo, a lighting alpha

void main() {
    ivec2 ip = ivec2(gl_FragCoord.xy);
    vec3 alb = demod_albedo(texelFetch(u_base, ip, 0), texelFetch(u_f0, ip, 0));
    vec4 cur = texelFetch(u_current, ip, 0);
    o_demod = vec4(cur.rgb / alb, texelFetch(u_depth, ip, 0).r);
    o_albedo = vec4(alb, cur.a);
}
