// STB deferred shadow terms: one 8-bit term per (quad, small-tile sample), laid
// out as one block of quads per small tile. term = shadow visibility x cone
// falloff x normalised IES (all in [0, 1]), evaluated at one surface point of the
// quad; 1 LSB of temporal noise against banding: stochastic rounding
// floor(255 t + u), u uniform in [0, 1), which is unbiased (a fixed +-0.5 LSB
// dither is not: it averages to the LSB midpoint).
//
// Edge-aware sharing: the quad's term stands for its 4 pixels only where they lie
// within LIM_TERM_SHARE_REL_DISTANCE of the light distance of the representative point.
// Where they do not (depth edges, points close to the light), bit j of the second
// target is set and
// that sample's term is evaluated for each of the 4 pixels here and stored per pixel
// (u_pixel_terms, read by the lighting pass only where the bit is set): the shadow
// lookups stay in this pass, 4 per split quad instead of 1.
#include "common/gbuffer.glsl"
#include "common/rng.glsl"
#include "common/lights.glsl"
// Area lights: fewer light points per term, a fresh point set each frame (the frames'
// average converges to the whole light's visibility, the reference's value).
#define AREA_SHADOW_POINTS LIM_AREA_SHADOW_POINTS_STB
#define AREA_SHADOW_PER_FRAME
#include "common/shadow.glsl"
#include "common/tiles.glsl"

uniform usampler2D u_smalltile;  // rgba32ui small-tile samples

layout(location = 0) out vec4 o_terms;
#ifndef STB_PIXEL_TERMS
layout(location = 1) out uint o_split;  // bit j: sample j is evaluated per pixel
layout(rgba8, binding = IMAGE_UNIT_PIXEL_TERMS) writeonly uniform image2D u_pixel_terms;  // split quads only
#endif

float sample_term(Light L, vec3 P, vec3 N) {
    vec3 Ldir = normalize(L.pos_range.xyz - P);
    return clamp(light_shape_scalar(L, -Ldir) * luminance(local_shadow(L, P, N)), 0.0, 1.0);
}

void main() {
    ivec2 tx = ivec2(gl_FragCoord.xy);
    vec4 terms = vec4(0.0);
    vec3 P, N;
    bool found = false;
#ifdef STB_PIXEL_TERMS
    // Full-resolution terms (the talk's "full-res shadows at additional cost"):
    // one texel per pixel, evaluated at that pixel.
    ivec2 st; int slot;
    quad_owner(tx, st, slot);
    found = read_geometry(tx, P, N);
#else
    int s = quads_per_side();
    ivec2 st = tx / s;
    ivec2 q = tx - st * s;
    int slot = q.y * s + q.x;
    ivec2 px = quad_pixel(st, slot);
    // Positions of the 4 pixels (depth only: one fetch each); normals are fetched only
    // where needed (the representative, and the pixels of a split quad).
    vec3 qP[4];
    bool valid[4];
    for (int k = 0; k < 4; ++k) {
        ivec2 p = px + ivec2(k & 1, k >> 1);
        valid[k] = false;
        if (any(lessThan(p, ivec2(0))) || any(greaterThanEqual(p, ivec2(u_resolution.xy)))) continue;
        float depth = texelFetch(g_depth, p, 0).r;
        valid[k] = depth > 0.0;
        qP[k] = world_pos_from_depth(vec2(p) + 0.5, depth);
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
    if (found) {
        P = qP[rep];
        N = oct_decode(texelFetch(g_normal, px + ivec2(rep & 1, rep >> 1), 0).rg);
    }
    uint split = 0u;
#endif
    // Samples j0 .. j1 - 1: all N, or (quad selection) the one this quad's pixels use;
    // a loop of one iteration, not N with a divergent skip.
#ifdef STB_QUAD_SELECT
    int j0 = quad_stream(st, slot);
    int j1 = j0 + 1;
#else
    int j0 = 0, j1 = STB_N;
#endif
    if (found) {
        uvec4 smp = texelFetch(u_smalltile, st, 0);
        Rng rng = rng_init(uint(tx.y) * 8192u + uint(tx.x) + 0x40000000u, u_counts.y);
        for (int j = j0; j < j1; ++j) {
            uint li = sample_index(smp[j]);
            if (li == LIM_EMPTY_LIGHT_INDEX) continue;
            Light L = lights[li];
            float t = sample_term(L, P, N);
            terms[j] = min(floor(t * 255.0 + rng_float(rng)), 255.0) / 255.0;
#ifndef STB_PIXEL_TERMS
            float share = LIM_TERM_SHARE_REL_DISTANCE * length(L.pos_range.xyz - P);
            for (int k = 0; k < 4; ++k) {
                if (!valid[k] || k == rep) continue;
                if (distance(qP[k], P) > share) {
                    split |= 1u << uint(j);
                }
            }
#endif
        }
    }
#ifndef STB_PIXEL_TERMS
    if (split != 0u) {
        uvec4 smp = texelFetch(u_smalltile, st, 0);
        Rng rng = rng_init(uint(tx.y) * 8192u + uint(tx.x) + 0x60000000u, u_counts.y);
        for (int k = 0; k < 4; ++k) {
            if (!valid[k]) continue;
            vec3 Nk = oct_decode(texelFetch(g_normal, px + ivec2(k & 1, k >> 1), 0).rg);
            vec4 pt = terms;  // the representative's (and unsplit samples') terms
            for (int j = j0; j < j1; ++j) {
                if (k == rep || (split & (1u << uint(j))) == 0u) continue;
                float t = sample_term(lights[sample_index(smp[j])], qP[k], Nk);
                pt[j] = min(floor(t * 255.0 + rng_float(rng)), 255.0) / 255.0;
            }
            imageStore(u_pixel_terms, px + ivec2(k & 1, k >> 1), pt);
        }
    }
    o_split = split;
#endif
    o_terms = terms;
}
