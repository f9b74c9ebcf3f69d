// STB reuse (issue 31): the per-pixel target of a light at a surface, p(y) (luminance,
// unshadowed): the small tile's cheap target at this one point (common/stb_target.glsl:
// area irradiance x diffuse + Blinn-Phong specular, with the light's cone and IES)
// + eps x its facing illuminance x BRDF, so it is > 0 wherever the light reaches the
// point: the reuse stays unbiased however poorly it follows the shaded value, which is
// the same light shaded with the pixel's shadow term. 0 for a light not linked to the
// pixel's link group (it cannot contribute there).
#ifndef STB_REUSE_TARGET_GLSL
#define STB_REUSE_TARGET_GLSL
#include "common/stb_target.glsl"

uniform float u_eps;  // the small-tile target's floor weight (-o eps)

float reuse_target(uint li, Surface s, uint group) {
    if (li == LIM_EMPTY_LIGHT_INDEX || li >= u_counts.x) return 0.0;
#ifdef HAS_LINKS
    if (!light_linked(li, group)) return 0.0;
#endif
    float a = max(s.alpha, LIM_GGX_ALPHA_MIN);
    float spec_n = max(2.0 / (a * a) - 2.0, 1.0);
    vec2 t = stb_point_target(lights[li], s.P, s.N, s.V, luminance(s.diffuse), luminance(s.f0),
                              spec_n, (spec_n + 2.0) / (2.0 * PI), true);
    float p = t.x + t.y * u_eps;
    return p > 0.0 && !isinf(p) ? p : 0.0;
}
#endif
