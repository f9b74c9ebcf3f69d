// Reading the G-buffer (written by gbuffer.frag) into a Surface.
#ifndef STB_GBUFFER_GLSL
#define STB_GBUFFER_GLSL
#include "common/frame.glsl"
#include "common/packing.glsl"
#include "common/brdf.glsl"

uniform sampler2D g_depth;      // r32f linear view depth (m), 0 = background
uniform sampler2D g_normal;     // rg16f octahedral world normal
uniform sampler2D g_base_rough; // rgba16f base colour, roughness
uniform sampler2D g_f0_metal;   // rgba16f F0, metallic
uniform sampler2D g_emission;   // rgba16f rgb emitted radiance x exposure scale u_clip.w
                                // (display-relative, so fp16 holds it at any light
                                // scale: surface_emission), a occlusion
#ifdef HAS_CLEARCOAT
uniform sampler2D g_coat;       // rg16f clearcoat weight, clearcoat roughness
#endif

// Position and normal only (2 fetches): false for background pixels.
bool read_geometry(ivec2 px, out vec3 P, out vec3 N) {
    float depth = texelFetch(g_depth, px, 0).r;
    if (depth <= 0.0) return false;
    P = world_pos_from_depth(vec2(px) + 0.5, depth);
    N = oct_decode(texelFetch(g_normal, px, 0).rg);
    return true;
}

// False for background pixels.
bool read_surface(ivec2 px, out Surface s) {
    float depth = texelFetch(g_depth, px, 0).r;
    if (depth <= 0.0) return false;
    vec2 pixel = vec2(px) + 0.5;
    s.P = world_pos_from_depth(pixel, depth);
    s.N = oct_decode(texelFetch(g_normal, px, 0).rg);
    s.V = view_dir(s.P);
    vec4 br = texelFetch(g_base_rough, px, 0);
    vec4 fm = texelFetch(g_f0_metal, px, 0);
    s.roughness = clamp(br.a, 0.02, 1.0);
    s.alpha = max(s.roughness * s.roughness, LIM_GGX_ALPHA_MIN);
    s.diffuse = br.rgb * (1.0 - fm.a);
    s.f0 = fm.rgb;
#ifdef HAS_AMBIENT
    s.occlusion = texelFetch(g_emission, px, 0).a;  // passes with a dome bind g_emission
#else
    s.occlusion = 1.0;
#endif
#ifdef HAS_CLEARCOAT
    vec2 coat = texelFetch(g_coat, px, 0).rg;
    s.coat = clamp(coat.r, 0.0, 1.0);
    float cr = clamp(coat.g, 0.02, 1.0);
    s.coat_alpha = max(cr * cr, LIM_GGX_ALPHA_MIN);
#else
    s.coat = 0.0;
    s.coat_alpha = 1.0;
#endif
    return true;
}

// Emitted radiance of pixel px (nits; g_emission holds it times the exposure scale).
vec3 surface_emission(ivec2 px) {
    return texelFetch(g_emission, px, 0).rgb / u_clip.w;
}
#endif
