// The lighting pass's outputs, one definition for every method's lighting shader:
// scene-linear radiance (location 0; nits x u_clip.w) and, with TAA_DEMOD_OUT
// (--temporal taa), the temporal pass's inputs, written here once per pixel while
// the surface is at hand instead of by a separate full-screen pass:
//  * location 1: lighting / albedo (common/demodulation.glsl), linear depth (m);
//  * location 2: the albedo, the lighting's alpha.
#ifndef STB_LIGHTING_OUT_GLSL
#define STB_LIGHTING_OUT_GLSL
#include "common/gbuffer.glsl"
#ifdef HAS_DOME_MAP
#include "common/dome.glsl"
#endif
#ifdef RECT_EMITTERS_SEEN
#include "common/rect_emitter.glsl"
#endif

layout(location = 0) out vec4 o_color;
#ifdef TAA_DEMOD_OUT
#include "common/demodulation.glsl"
layout(location = 1) out vec4 o_demod;
layout(location = 2) out vec4 o_albedo;

void write_demod(ivec2 px, vec4 color, vec3 alb) {
    o_demod = vec4(color.rgb / alb, texelFetch(g_depth, px, 0).r);
    o_albedo = vec4(alb, color.a);
}
#endif

// A background pixel: the dome seen directly (alpha 1), else transparent black. A
// textured dome the camera sees (HAS_DOME_MAP, u_dome_mult.z) shows its map; a textured
// RectLight the camera sees (RECT_EMITTERS_SEEN) its texture, in front of the dome.
void write_background(ivec2 px) {
    vec3 bg = u_ambient.rgb;
    bool seen = bg.r + bg.g + bg.b > 0.0;
#ifdef HAS_DOME_MAP
    if (u_dome_mult.z > 0.5) {
        vec3 d = -view_dir(world_pos_from_depth(vec2(px) + 0.5, 1.0));
        bg += dome_sky(d);
        seen = true;
    }
#endif
#ifdef RECT_EMITTERS_SEEN
    vec3 O, D, rad;
    camera_ray(vec2(px) + 0.5, O, D);
    if (rect_emitter_seen(O, D, 3.0e38, rad)) {
        bg = rad;
        seen = true;
    }
#endif
    o_color = seen ? vec4(sanitize_radiance(bg * u_clip.w), 1.0) : vec4(0.0);
#ifdef TAA_DEMOD_OUT
    write_demod(px, o_color, demod_albedo(texelFetch(g_base_rough, px, 0),
                                          texelFetch(g_f0_metal, px, 0)));
#endif
}

// A surface pixel's radiance c (nits, before the exposure scale u_clip.w); a textured
// RectLight face nearer than the surface (RECT_EMITTERS_SEEN) replaces it.
void write_lighting(ivec2 px, Surface s, vec3 c) {
#ifdef RECT_EMITTERS_SEEN
    vec3 O, D, rad;
    camera_ray(vec2(px) + 0.5, O, D);
    if (rect_emitter_seen(O, D, dot(s.P - O, D), rad)) c = rad;
#endif
    o_color = vec4(sanitize_radiance(c * u_clip.w), 1.0);
#ifdef TAA_DEMOD_OUT
    write_demod(px, o_color, demod_albedo_of(s.diffuse, s.f0));
#endif
}
#endif
