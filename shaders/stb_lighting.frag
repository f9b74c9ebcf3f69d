// STB lighting: per pixel, its small tile's STB_N samples: BRDF x light colour
// and shape (emission model, focus tint, IES scale) / d^2 x the quad's shadow
// term x sample weight; plus sun, dome and emission. The cost does not depend
// on the number of lights. A sample whose quad term does not stand for this pixel
// (split bit set by stb_shadow.frag at depth edges and creases) takes this pixel's own
// term, which the shadow pass stored at full resolution. STB_UNIT_TERMS: every term is 1 (no shadows,
// cones or IES among the lights in view; the term pass did not run).
#include "common/gbuffer.glsl"
#include "common/sun.glsl"
#include "common/lights.glsl"
#include "common/tiles.glsl"

uniform usampler2D u_smalltile;
#ifndef STB_UNIT_TERMS
uniform sampler2D u_terms;
#ifndef STB_PIXEL_TERMS
uniform usampler2D u_term_split;
uniform sampler2D u_pixel_terms;
#endif
#endif

layout(location = 0) out vec4 o_color;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    Surface s;
    vec3 emission = texelFetch(g_emission, px, 0).rgb;
    if (!read_surface(px, s)) {
        o_color = u_ambient.r + u_ambient.g + u_ambient.b > 0.0
            ? vec4(sanitize_radiance(u_ambient.rgb * u_clip.w), 1.0) : vec4(0.0);
        return;
    }
    vec3 c = sun_and_ambient(s);
    ivec2 st; int slot;
    quad_owner(px, st, slot);
    uvec4 smp = texelFetch(u_smalltile, st, 0);
    uint split = 0u;
#if defined(STB_UNIT_TERMS)
    vec4 terms = vec4(1.0);
#elif defined(STB_PIXEL_TERMS)
    vec4 terms = texelFetch(u_terms, px, 0);
#else
    ivec2 tt = term_texel(st, slot);
    vec4 terms = texelFetch(u_terms, tt, 0);
    split = texelFetch(u_term_split, tt, 0).r;
#endif
    // Samples j0 .. j1 - 1: all N, or the one this quad/pixel selects (a loop of one
    // iteration, not N with a divergent skip: SIMD lanes would run all N).
#if defined(STB_QUAD_SELECT)
    int j0 = quad_stream(st, slot);
#elif defined(STB_PIXEL_SELECT)
    int j0 = pixel_stream(px);
#else
    int j0 = 0;
#endif
#ifdef STB_SELECT_ONE
    int j1 = j0 + 1;
#else
    int j1 = STB_N;
#endif
    for (int j = j0; j < j1; ++j) {
        uint li = sample_index(smp[j]);
        float W = sample_weight(smp[j]);
        bool own = (split & (1u << uint(j))) != 0u;  // term evaluated here, per pixel
        if (li == LIM_EMPTY_LIGHT_INDEX || W <= 0.0 || (!own && terms[j] <= 0.0)) continue;
        Light L = lights[li];
        vec3 Ldir, d, sp;
        if (!light_reflect(L, s, Ldir, d, sp)) continue;  // area lights: common/area.glsl
        float term = terms[j];
#if !defined(STB_UNIT_TERMS) && !defined(STB_PIXEL_TERMS)
        if (own) term = texelFetch(u_pixel_terms, px, 0)[j];
#endif
        if (term <= 0.0) continue;
        c += (d * L.misc.z + sp * L.misc.w) * term * W;
    }
    c += emission;
    o_color = vec4(sanitize_radiance(c * u_clip.w), 1.0);
}
