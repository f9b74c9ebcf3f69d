// STB reuse (issue 31): a pixel's initial reservoir straight from its big tile's
// reservoirs (-o reuse_candidates=C > 0, STB_REUSE_BIGTILE = C). The pixel picks its big
// tile by stochastic bilinear selection (its centre jittered by up to one big tile),
// then the slots o, o + s, ..., s = K / C apart, o uniform in [0, s): a random stratum of
// the K streams, each kept slot standing for s of them (x s: unbiased, the K streams
// partition the lights). Each candidate is weighted w = p(y) W_bt(y) s with the pixel's
// own target p (common/reuse_target.glsl; optionally x a hard shadow gather,
// u_shadow_floor < 1); W = sum w / p(y), capped at u_weight_cap x s x count x W_bt(y)
// like the small tile's. STB_REUSE_QUAD: + pfloor (out) on every target, the defensive
// floor that keeps a quad's reservoir unbiased at its other pixels.
// Used by the temporal pass and, fused (no spatial or temporal reuse), the shading pass.
#ifndef STB_REUSE_INITIAL_GLSL
#define STB_REUSE_INITIAL_GLSL

uniform usampler2D u_bigtile;    // r32ui big-tile reservoirs, u_block texels per big tile
uniform ivec2 u_block;           // slot block per big tile (K = x * y)
uniform int u_big_px;            // big tile side (px)
uniform ivec2 u_big_tiles;       // big-tile grid size
uniform int u_stochastic_bilinear;
uniform float u_weight_cap;      // W <= cap x s x count x W_bt(selected); <= 0: no cap
uniform float u_shadow_floor;    // < 1: the initial resampling's target x (floor + (1 - floor) V)

#ifdef STB_REUSE_CHEAP_TARGET
// -o reuse_target=cheap: reuse_target's point-light form from two of the light's ten
// vec4s (position + range, intensity): luminous intensity x range window / d^2 x
// (cos+ + eps) x (Lambert + Blinn-Phong); no cone, IES or area shape (> 0 wherever the
// light is in range, so still unbiased; a worse fit for spots and large area lights).
float reuse_cheap_target(uint li, Surface s, uint group) {
    if (li == LIM_EMPTY_LIGHT_INDEX || li >= u_counts.x) return 0.0;
#ifdef HAS_LINKS
    if (!light_linked(li, group)) return 0.0;
#endif
    vec4 pr = lights[li].pos_range;
    vec3 d = pr.xyz - s.P;
    float dist = length(d);
    if (!(dist < pr.w)) return 0.0;
    vec3 Ldir = d / max(dist, 1e-12);
    float r = max(dist, LIM_MIN_LIGHT_DISTANCE);
    float Ev = luminance(lights[li].intensity.rgb) * range_window(dist, pr.w) / (r * r);
    float a = max(s.alpha, LIM_GGX_ALPHA_MIN);
    float spec_n = max(2.0 / (a * a) - 2.0, 1.0);
    float NoH = max(dot(s.N, normalize(s.V + Ldir)), 0.0);
    float fv = luminance(s.diffuse) / PI
             + luminance(s.f0) * (spec_n + 2.0) / (2.0 * PI) * pow(NoH, spec_n);
    float p = Ev * fv * (max(dot(s.N, Ldir), 0.0) + u_eps);
    return p > 0.0 && !isinf(p) ? p : 0.0;
}
#endif

// The initial target of light li at s: reuse_target (or the cheap one), x (floor +
// (1 - floor) x a hard shadow gather) when u_shadow_floor < 1.
float reuse_initial_target(uint li, Surface s, uint group) {
#ifdef STB_REUSE_CHEAP_TARGET
    float p = reuse_cheap_target(li, s, group);
#else
    float p = reuse_target(li, s, group);
#endif
    if (u_shadow_floor < 1.0 && p > 0.0) {
        float v = luminance(local_shadow_hard(lights[li], s.P, s.N));
        p *= u_shadow_floor + (1.0 - u_shadow_floor) * clamp(v, 0.0, 1.0);
    }
    return p;
}

Reservoir reuse_initial_bigtile(vec2 fc, Surface s, uint group, inout Rng rng, out float pfloor) {
    pfloor = 0.0;
    vec2 c = fc;
    if (u_stochastic_bilinear == 1) {
        c += (vec2(rng_float(rng), rng_float(rng)) - 0.5) * float(u_big_px);
    }
    ivec2 bt = clamp(ivec2(floor(c / float(u_big_px))), ivec2(0), u_big_tiles - 1);
    const int STRIDE = STB_K / STB_REUSE_BIGTILE;  // s: slots each kept one stands for
    int o = min(int(rng_float(rng) * float(STRIDE)), STRIDE - 1);
    float count = 0.0;
    float sel_wbt = 0.0;
    Stream ini = stream_empty();
#ifdef STB_REUSE_QUAD
    // Two loops: the floor needs the candidates' mean target first.
    float psum = 0.0;
    uint cl[STB_REUSE_BIGTILE];
    float cw[STB_REUSE_BIGTILE];
    float cp[STB_REUSE_BIGTILE];
    for (int j = 0; j < STB_REUSE_BIGTILE; ++j) {
        int slot = o + j * STRIDE;
        uint smp = texelFetch(u_bigtile, bt * u_block + ivec2(slot % u_block.x, slot / u_block.x), 0).r;
        cl[j] = sample_index(smp);
        cw[j] = sample_weight(smp);
        cp[j] = 0.0;
        if (cl[j] == LIM_EMPTY_LIGHT_INDEX || !(cw[j] > 0.0)) continue;
        count += 1.0;
        cp[j] = reuse_initial_target(cl[j], s, group);
        psum += cp[j];
    }
    // Defensive floor: the quad's other pixels shade this reservoir too, so its target
    // must be > 0 wherever theirs may be (W is then an unbiased contribution weight for
    // every pixel of the quad): + LIM_REUSE_QUAD_FLOOR x the candidates' mean target
    // (1 where no candidate reaches this pixel: uniform).
    pfloor = psum > 0.0 ? LIM_REUSE_QUAD_FLOOR * psum / max(count, 1.0) : 1.0;
    for (int j = 0; j < STB_REUSE_BIGTILE; ++j) {
        uint li = cl[j];
        float Wj = cw[j];
        if (li == LIM_EMPTY_LIGHT_INDEX || !(Wj > 0.0)) continue;
        float p = cp[j] + pfloor;
#else
    // One streaming loop (no per-candidate arrays: cheaper on llvmpipe).
    for (int j = 0; j < STB_REUSE_BIGTILE; ++j) {
        int slot = o + j * STRIDE;
        uint smp = texelFetch(u_bigtile, bt * u_block + ivec2(slot % u_block.x, slot / u_block.x), 0).r;
        uint li = sample_index(smp);
        float Wj = sample_weight(smp);
        if (li == LIM_EMPTY_LIGHT_INDEX || !(Wj > 0.0)) continue;
        count += 1.0;
        float p = reuse_initial_target(li, s, group);
#endif
        float w = p * Wj * float(STRIDE);
        float u = rng_float(rng);
        if (!(w > 0.0) || isinf(w)) continue;
        ini.wsum += w;
        if (u * ini.wsum < w) {  // stream_add, remembering the pick's W_bt for the cap
            ini.y = li;
            ini.py = p;
            sel_wbt = Wj;
        }
    }
    Reservoir r0 = stream_reservoir(ini, 1.0, 1.0);
    if (u_weight_cap > 0.0 && r0.y != LIM_EMPTY_LIGHT_INDEX) {
        r0.W = min(r0.W, u_weight_cap * float(STRIDE) * count * sel_wbt);
    }
    return r0;
}
#endif
