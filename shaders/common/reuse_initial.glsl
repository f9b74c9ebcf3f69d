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

#ifdef STB_REUSE_SLOT_TARGET
// -o reuse_target=tile: the pixel's part of the initial target from the slot's three
// texels (stb_reuse_slots.frag: position + range, shaped intensity + half extent + W_bt
// + IES layer, the cone in cos space + the emission axis): the point form of
// common/stb_target.glsl (area horizon, Lambert + Blinn-Phong, + eps x the facing
// illuminance x BRDF) with the emission shaping taken towards the tile, the cone and
// the IES table (its maximum over phi, gl_delegate.ies_cos_rowmax) at this pixel. > 0
// wherever the light is in range, inside its cone and its table is > 0 (the tile's
// shaping is floored; the cone's cutoff is widened a hair; the table's lookup never
// falls below it): unbiased. The slot's light index is not read per candidate (one
// texel fewer): the pick's comes from the big-tile reservoir (reuse_slot_light).
uniform sampler2D u_slot_pos;    // rgba32f: light position (m), range (m)
uniform sampler2D u_slot_shape;  // rgba32f: shaped cd, half extent (m), W_bt (0: empty), IES layer (-1: none here)
uniform sampler2D u_slot_axis;   // rgba32f: axis / dc, (cos cutoff + dc) / dc (no cone: unit axis, -2)
#ifdef HAS_LINKS
uniform usampler2D u_slot_link;  // r32ui: the light's link mask (a texture: see common/reuse_share.glsl)
#endif
#ifdef HAS_IES
uniform sampler2DArray u_ies_cos;  // per layer: the table's max over phi against cos off the axis
#endif

// The light index of the big-tile slot at texel (the FoV list's).
uint reuse_slot_light(ivec2 texel) {
    return sample_index(texelFetch(u_bigtile, texel, 0).r);
}

float reuse_slot_target(vec4 pr, vec4 sh, vec4 ax, ivec2 texel, Surface s, uint group) {
    if (!(sh.z > 0.0)) return 0.0;
#ifdef HAS_LINKS
    if (((texelFetch(u_slot_link, texel, 0).r >> group) & 1u) == 0u) return 0.0;
#endif
    vec3 d = pr.xyz - s.P;
    float dist = length(d);
    if (!(dist < pr.w)) return 0.0;
    vec3 Ldir = d / max(dist, 1e-12);
    float r = max(dist, LIM_MIN_LIGHT_DISTANCE);
    // the cone (light_shape_scalar_m's smoothstep, in cos instead of angle): no branch
    float cax = dot(Ldir, ax.xyz);
    float tc = clamp(ax.w + cax, 0.0, 1.0);  // dir leaving = -Ldir
    float Ev = sh.x * range_window(dist, pr.w) * (1.0 - tc * tc * (3.0 - 2.0 * tc)) / (r * r);
#ifdef HAS_IES
    if (sh.w >= 0.0) {  // the IES table's maximum over phi at this cos (>= the table)
        // the nearest bin: bin j holds the maximum over [c_(j-1), c_(j+1)], which
        // covers every cos that rounds to it (an integer fetch, no filtering)
        float cl = cax * inversesqrt(max(dot(ax.xyz, ax.xyz), 1e-30));  // dot(Ldir, unit axis)
        int j = int((0.5 - 0.5 * cl) * float(LIM_REUSE_IES_COS_BINS - 1) + 0.5);
        Ev *= texelFetch(u_ies_cos, ivec3(clamp(j, 0, LIM_REUSE_IES_COS_BINS - 1), 0, int(sh.w)), 0).r;
    }
#endif
    float NoL = dot(s.N, Ldir);
    // area horizon (light_target_irradiance): the sphere of the light's half extent
    float e = clamp(sh.y / r, 1e-4, 1.0);
    bool area = sh.y > LIM_AREA_POINT_RATIO * dist;
    float c = !area || NoL >= e ? max(NoL, 0.0) : (NoL > -e ? (NoL + e) * (NoL + e) / (4.0 * e) : 0.0);
    float a = max(s.alpha, LIM_GGX_ALPHA_MIN);
    float spec_n = max(2.0 / (a * a) - 2.0, 1.0);
    float NoH = max(dot(s.N, normalize(s.V + Ldir)), 0.0);
    float kd = luminance(s.diffuse) / PI;
    // Schlick's rational stand-in for pow(NoH, n), x / (n - n x + x): a division
    // instead of a log2 and an exp2 per candidate (a target needs only the shape).
    float ks = luminance(s.f0) * (spec_n + 2.0) / (2.0 * PI) * NoH / max(spec_n - spec_n * NoH + NoH, 1e-6);
    float p = Ev * (kd * c + ks * max(NoL, 0.0) + u_eps * (kd + ks));
    return p > 0.0 && !isinf(p) ? p : 0.0;
}

// The slot target of the big-tile slot at texel (its offset within the tile's block).
float reuse_slot_target_at(ivec2 texel, Surface s, uint group) {
    return reuse_slot_target(texelFetch(u_slot_pos, texel, 0), texelFetch(u_slot_shape, texel, 0),
                             texelFetch(u_slot_axis, texel, 0), texel, s, group);
}
#endif

// The selected candidate's slot texel (reuse_initial_bigtile; -1: none).
ivec2 reuse_sel_texel = ivec2(-1);

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

#ifdef STB_REUSE_SHARE
// -o reuse_res=share: the 2x2 quad's four pixels split the C = STB_REUSE_BIGTILE slots
// of one big tile between them, C / 4 each (slots o0 + STRIDE (q' + 4 j), q' = (q + r)
// mod 4: the quad's pixel q rotated by r). The tile jitter, o0 and r come from the
// quad's own random stream (qrng, the same at its four pixels), so each pixel's stratum
// is marginally uniform over [0, 4 STRIDE) (unbiased alone) and the four together see
// all C slots once (stb_reuse_shade.frag combines their reservoirs).
const int REUSE_PER_PIXEL = STB_REUSE_BIGTILE / 4;
const int REUSE_SLOT_STEP = 4 * (STB_K / STB_REUSE_BIGTILE);
#else
const int REUSE_PER_PIXEL = STB_REUSE_BIGTILE;
const int REUSE_SLOT_STEP = STB_K / STB_REUSE_BIGTILE;
#endif

Reservoir reuse_initial_bigtile(vec2 fc, Surface s, uint group, inout Rng rng, out float pfloor
#ifdef STB_REUSE_SHARE
                                , inout Rng qrng, int q
#endif
) {
    pfloor = 0.0;
    vec2 c = fc;
#ifdef STB_REUSE_SHARE
    c = floor(fc * 0.5) * 2.0 + 1.0;  // the quad's centre (px), the same at its 4 pixels
    vec2 jit = vec2(rng_float(qrng), rng_float(qrng));
    float uo = rng_float(qrng);
    int rot = min(int(rng_float(qrng) * 4.0), 3);
    if (u_stochastic_bilinear == 1) {
        c += (jit - 0.5) * float(u_big_px);
    }
#else
    if (u_stochastic_bilinear == 1) {
        c += (vec2(rng_float(rng), rng_float(rng)) - 0.5) * float(u_big_px);
    }
#endif
    ivec2 bt = clamp(ivec2(floor(c / float(u_big_px))), ivec2(0), u_big_tiles - 1);
    const int STRIDE = REUSE_SLOT_STEP;  // s: slots each kept one stands for
#ifdef STB_REUSE_SHARE
    const int S0 = STB_K / STB_REUSE_BIGTILE;
    int o = min(int(uo * float(S0)), S0 - 1) + S0 * ((q + rot) & 3);
#else
    int o = min(int(rng_float(rng) * float(STRIDE)), STRIDE - 1);
#endif
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
    ivec2 sel_texel = ivec2(-1);
    for (int j = 0; j < REUSE_PER_PIXEL; ++j) {
        int slot = o + j * STRIDE;
        ivec2 texel = bt * u_block + ivec2(slot % u_block.x, slot / u_block.x);
#ifdef STB_REUSE_SLOT_TARGET
        vec4 sh = texelFetch(u_slot_shape, texel, 0);
        if (!(sh.z > 0.0)) continue;
        uint li = LIM_EMPTY_LIGHT_INDEX;  // read for the pick only (below)
        float Wj = sh.z;
        count += 1.0;
        float p = reuse_slot_target(texelFetch(u_slot_pos, texel, 0), sh, texelFetch(u_slot_axis, texel, 0), texel,
                                    s, group);
        if (u_shadow_floor < 1.0 && p > 0.0) {
            float v = luminance(local_shadow_hard(lights[reuse_slot_light(texel)], s.P, s.N));
            p *= u_shadow_floor + (1.0 - u_shadow_floor) * clamp(v, 0.0, 1.0);
        }
#else
        uint smp = texelFetch(u_bigtile, texel, 0).r;
        uint li = sample_index(smp);
        float Wj = sample_weight(smp);
        if (li == LIM_EMPTY_LIGHT_INDEX || !(Wj > 0.0)) continue;
        count += 1.0;
        float p = reuse_initial_target(li, s, group);
#endif
#endif
        float w = p * Wj * float(STRIDE);
        float u = rng_float(rng);
        if (!(w > 0.0) || isinf(w)) continue;
        ini.wsum += w;
        if (u * ini.wsum < w) {  // stream_add, remembering the pick's W_bt for the cap
            ini.y = li;
            ini.py = p;
            sel_wbt = Wj;
#ifndef STB_REUSE_QUAD
            sel_texel = texel;
#endif
        }
    }
#ifndef STB_REUSE_QUAD
    reuse_sel_texel = sel_texel;
#endif
#ifdef STB_REUSE_SLOT_TARGET
    if (sel_texel.x >= 0) ini.y = reuse_slot_light(sel_texel);
#endif
    Reservoir r0 = stream_reservoir(ini, 1.0, 1.0);
    if (u_weight_cap > 0.0 && r0.y != LIM_EMPTY_LIGHT_INDEX) {
        r0.W = min(r0.W, u_weight_cap * float(STRIDE) * count * sel_wbt);
    }
    return r0;
}
#endif
