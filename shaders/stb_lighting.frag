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

#include "common/lighting_out.glsl"

#ifdef STB_RIS_SELECT
#include "common/rng.glsl"
#include "common/stb_target.glsl"
uniform float u_eps;  // as the small-tile target's: keeps the target positive in shadow
// Cheap per-pixel resampling target of a light at surface s: the small tile's target
// (common/stb_target.glsl) at this one point, without the cone/IES part (the term
// holds it), + eps x the facing illuminance so it stays > 0 wherever the light
// reaches the pixel.
float ris_target(Light L, Surface s) {
    float a = max(s.alpha, LIM_GGX_ALPHA_MIN);
    float spec_n = max(2.0 / (a * a) - 2.0, 1.0);
    vec2 t = stb_point_target(L, s.P, s.N, s.V, luminance(s.diffuse), luminance(s.f0), spec_n,
                              (spec_n + 2.0) / (2.0 * PI), false);
    return t.x + t.y * u_eps;
}
#endif

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    Surface s;
    vec3 emission = surface_emission(px);
    if (!read_surface(px, s)) {
        write_background(px);
        return;
    }
#ifdef HAS_LINKS
    uint group = link_group(px);  // lights test their mask bit for it (common/links.glsl)
    vec3 c = sun_and_ambient(s, group);
#else
    vec3 c = sun_and_ambient(s);
#endif
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
#ifdef STB_RIS_SELECT
    // Per-pixel resampling of the tile's N independent samples (each a complete
    // estimate with weight W_j): pick j with probability ~ p_j W_j, where p_j is a cheap
    // unshadowed target at this pixel x the sample's term (the one this pixel is shaded
    // with) plus a defensive share of the mean, and shade only that one with weight
    // sum(p W) / (N p_j) -- resampled importance sampling, unbiased while p_j > 0
    // wherever the sample can contribute (ris_target keeps it positive wherever the
    // light reaches the pixel; a zero term means a zero contribution). When p_j ~ the
    // shaded value this is the N-sample mean for the cost of one shade (plus the N terms
    // of the term pass and N cheap targets here).
    vec4 pix_terms = terms;
#if !defined(STB_UNIT_TERMS) && !defined(STB_PIXEL_TERMS)
    if (split != 0u) {
        vec4 own_terms = texelFetch(u_pixel_terms, px, 0);
        for (int j = 0; j < STB_N; ++j) {
            if ((split & (1u << uint(j))) != 0u) pix_terms[j] = own_terms[j];
        }
    }
#endif
    float rw[STB_N];
    float rp[STB_N];
    float rp_sum = 0.0;
    for (int j = 0; j < STB_N; ++j) {
        uint lj = sample_index(smp[j]);
        rp[j] = 0.0;
        if (lj == LIM_EMPTY_LIGHT_INDEX || !(sample_weight(smp[j]) > 0.0)) continue;
#ifdef HAS_LINKS
        if (!light_linked(lj, group)) continue;  // no contribution here: never picked
#endif
        rp[j] = ris_target(lights[lj], s) * pix_terms[j];
        rp_sum += rp[j];
    }
    float rw_sum = 0.0;
    for (int j = 0; j < STB_N; ++j) {
        float Wj = sample_weight(smp[j]);
        rw[j] = 0.0;
        if (!(rp[j] > 0.0)) continue;  // no target: the light cannot reach this pixel
        rw[j] = (rp[j] + LIM_RIS_PDF_FLOOR * rp_sum / float(STB_N)) * Wj;
        rw_sum += rw[j];
    }
    int j0 = STB_N;  // nothing to shade unless a sample has a positive weight
    float ris_scale = 0.0;
    if (rw_sum > 0.0) {
        Rng prng = rng_init(uint(px.y) * 8192u + uint(px.x) + 0x70000000u, u_counts.y);
        float u = rng_float(prng) * rw_sum;
        float acc = 0.0;
        for (int j = 0; j < STB_N; ++j) {
            if (rw[j] <= 0.0) continue;
            j0 = j;  // the last positive one absorbs rounding at the top
            acc += rw[j];
            if (u < acc) break;
        }
        // Shaded below with weight W_j0 x term; the RIS weight replaces W_j0 by
        // sum(p W) / (N p_j0) = W_j0 x sum / (N rw_j0).
        ris_scale = rw_sum / (float(STB_N) * rw[j0]);
    }
    int j1 = min(j0 + 1, STB_N);
#else
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
#endif  // STB_RIS_SELECT
    for (int j = j0; j < j1; ++j) {
        uint li = sample_index(smp[j]);
        float W = sample_weight(smp[j]);
        bool own = (split & (1u << uint(j))) != 0u;  // term evaluated here, per pixel
        if (li == LIM_EMPTY_LIGHT_INDEX || W <= 0.0 || (!own && terms[j] <= 0.0)) continue;
#ifdef HAS_LINKS
        if (!light_linked(li, group)) continue;  // the light does not light this pixel's prim
#endif
        Light L = lights[li];
        vec3 Ldir, d, sp;
        if (!light_reflect(L, s, Ldir, d, sp)) continue;  // area lights: common/area.glsl
        float term = terms[j];
#if !defined(STB_UNIT_TERMS) && !defined(STB_PIXEL_TERMS)
        if (own) term = texelFetch(u_pixel_terms, px, 0)[j];
#endif
        if (term <= 0.0) continue;
#ifdef STB_RIS_SELECT
        W *= ris_scale;
#endif
        c += (d * L.misc.z + sp * L.misc.w) * term * W;
    }
    c += emission;
    write_lighting(px, s, c);
}
