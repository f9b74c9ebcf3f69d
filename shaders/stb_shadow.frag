// STB deferred shadow terms: one 8-bit term per (quad, small-tile sample), laid
// out as one block of quads per small tile. term = shadow visibility x cone
// falloff x normalised IES (all in [0, 1]), evaluated at the quad's surface
// point; 1 LSB of temporal noise against banding: stochastic rounding
// floor(255 t + u), u uniform in [0, 1), which is unbiased (a fixed +-0.5 LSB
// dither is not: it averages to the LSB midpoint).
#include "common/gbuffer.glsl"
#include "common/rng.glsl"
#include "common/lights.glsl"
#include "common/shadow.glsl"
#include "common/tiles.glsl"

uniform usampler2D u_smalltile;  // rgba32ui small-tile samples

layout(location = 0) out vec4 o_terms;

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
    // The quad's term is evaluated at one of its 4 pixels, chosen at random each
    // frame: accumulated frames see the quad's average (a 2x2 box filter), not a
    // fixed corner.
    Rng pick = rng_init(uint(tx.y) * 8192u + uint(tx.x) + 0x50000000u, u_counts.y);
    int first = int(rng_u16(pick)) & 3;
    for (int kk = 0; kk < 4 && !found; ++kk) {
        int k = (first + kk) & 3;
        ivec2 p = px + ivec2(k & 1, k >> 1);
        if (any(lessThan(p, ivec2(0))) || any(greaterThanEqual(p, ivec2(u_resolution.xy)))) continue;
        found = read_surface(p, surf);
    }
#endif
    if (found) {
        uvec4 smp = texelFetch(u_smalltile, st, 0);
        Rng rng = rng_init(uint(tx.y) * 8192u + uint(tx.x) + 0x40000000u, u_counts.y);
        for (int j = 0; j < STB_N; ++j) {
            uint li = sample_index(smp[j]);
            if (li == LIM_EMPTY_LIGHT_INDEX) continue;
            Light L = lights[li];
            vec3 Ldir = normalize(L.pos_range.xyz - surf.P);
            float t = light_shape_scalar(L, -Ldir) * luminance(local_shadow(L, surf.P, surf.N));
            t = clamp(t, 0.0, 1.0);
            terms[j] = min(floor(t * 255.0 + rng_float(rng)), 255.0) / 255.0;
        }
    }
    o_terms = terms;
}
