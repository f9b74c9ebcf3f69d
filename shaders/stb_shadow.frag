// STB deferred shadow terms: one 8-bit term per (quad, small-tile sample), laid
// out as one block of quads per small tile. term = shadow visibility x cone
// falloff x normalised IES (all in [0, 1]), evaluated at one surface point of the
// quad; 1 LSB of temporal noise against banding: stochastic rounding
// floor(255 t + u), u uniform in [0, 1), which is unbiased (a fixed +-0.5 LSB
// dither is not: it averages to the LSB midpoint).
//
// Edge-aware sharing: the quad's term stands for its 4 pixels only where they agree
// with the representative point (distance within LIM_TERM_SHARE_REL_DISTANCE of the
// light distance, normals within LIM_TERM_SHARE_NORMAL_COS). Where they do not (depth
// edges, creases, points close to the light), bit j of the second target is set and
// the lighting pass evaluates that sample's term per pixel.
#include "common/gbuffer.glsl"
#include "common/rng.glsl"
#include "common/lights.glsl"
#include "common/shadow.glsl"
#include "common/tiles.glsl"

uniform usampler2D u_smalltile;  // rgba32ui small-tile samples

layout(location = 0) out vec4 o_terms;
#ifndef STB_PIXEL_TERMS
layout(location = 1) out uint o_split;  // bit j: sample j is evaluated per pixel
#endif

float sample_term(Light L, Surface surf) {
    vec3 Ldir = normalize(L.pos_range.xyz - surf.P);
    return clamp(light_shape_scalar(L, -Ldir) * luminance(local_shadow(L, surf.P, surf.N)),
                 0.0, 1.0);
}

void main() {
    ivec2 tx = ivec2(gl_FragCoord.xy);
    vec4 terms = vec4(0.0);
    Surface surf;
    bool found = false;
#ifdef STB_PIXEL_TERMS
    // Full-resolution terms (the talk's "full-res shadows at additional cost"):
    // one texel per pixel, evaluated at that pixel.
    ivec2 st; int slot;
    quad_owner(tx, st, slot);
    found = read_surface(tx, surf);
#else
    int s = quads_per_side();
    ivec2 st = tx / s;
    ivec2 q = tx - st * s;
    int slot = q.y * s + q.x;
    ivec2 px = quad_pixel(st, slot);
    Surface quad[4];
    bool valid[4];
    for (int k = 0; k < 4; ++k) {
        ivec2 p = px + ivec2(k & 1, k >> 1);
        valid[k] = all(greaterThanEqual(p, ivec2(0))) && all(lessThan(p, ivec2(u_resolution.xy)))
                   && read_surface(p, quad[k]);
    }
    // The representative is one of the 4 pixels, chosen at random each frame:
    // accumulated frames see the quad's average, not a fixed corner.
    Rng pick = rng_init(uint(tx.y) * 8192u + uint(tx.x) + 0x50000000u, u_counts.y);
    int first = int(rng_u16(pick)) & 3;
    int rep = -1;
    for (int kk = 0; kk < 4 && rep < 0; ++kk) {
        int k = (first + kk) & 3;
        if (valid[k]) rep = k;
    }
    found = rep >= 0;
    if (found) surf = quad[rep];
    uint split = 0u;
#endif
    if (found) {
        uvec4 smp = texelFetch(u_smalltile, st, 0);
        Rng rng = rng_init(uint(tx.y) * 8192u + uint(tx.x) + 0x40000000u, u_counts.y);
        for (int j = 0; j < STB_N; ++j) {
            uint li = sample_index(smp[j]);
            if (li == LIM_EMPTY_LIGHT_INDEX) continue;
            Light L = lights[li];
            float t = sample_term(L, surf);
            terms[j] = min(floor(t * 255.0 + rng_float(rng)), 255.0) / 255.0;
#ifndef STB_PIXEL_TERMS
            float share = LIM_TERM_SHARE_REL_DISTANCE * length(L.pos_range.xyz - surf.P);
            for (int k = 0; k < 4; ++k) {
                if (!valid[k] || k == rep) continue;
                if (distance(quad[k].P, surf.P) > share
                    || dot(quad[k].N, surf.N) < LIM_TERM_SHARE_NORMAL_COS) {
                    split |= 1u << uint(j);
                }
            }
#endif
        }
    }
    o_terms = terms;
#ifndef STB_PIXEL_TERMS
    o_split = split;
#endif
}
