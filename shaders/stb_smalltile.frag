// STB small-tile resampling (one fragment per small tile): pick its big tile by
// stochastic bilinear selection (centre jittered by up to one big tile), build
// the refined target from 4 random quads of the tile (luminance-weighted
// illuminance x Lambert + Blinn-Phong on the averaged material x (V cos+ + eps)),
// and run SRS of STB_N streams over the big tile's K samples. Weight of the
// stored sample: W' = sum(p_hat * W_bt) / p_hat(selected).
//
// Light linking (HAS_LINKS): a candidate whose light lights none of the link groups of
// this tile's pixels contributes nothing to any of them (the lighting pass multiplies
// every contribution by the light's bit for the pixel's group), so it is dropped like
// an empty slot: no target, no share of the defensive floor, never selected. Dropping
// it is unbiased: a stream's estimate is sum over its kept candidates of f(l) W_bt(l),
// and the dropped ones have f = 0 at every pixel that uses the tile's samples (the
// tile's own pixels). A kept light gets target 0 at sampled points whose group it does
// not light (f = 0 there too); it stays selectable through the floor wherever some
// pixel of the tile is in a group it lights, so the target is positive wherever f can
// be -- tests/test_links.py compares STB against the scene without the light.
#include "common/gbuffer.glsl"
#include "common/rng.glsl"
#include "common/lights.glsl"
#include "common/shadow.glsl"
#include "common/tiles.glsl"
#include "common/stb_target.glsl"
#include "common/links.glsl"

uniform usampler2D u_bigtile;    // r32ui reservoirs, u_block texels per big tile
uniform ivec2 u_block;
uniform int u_big_px;
uniform ivec2 u_big_tiles;       // big-tile grid size
uniform float u_eps;             // added to V cos+ (talk: keeps p_hat > 0 in shadow)
uniform float u_weight_cap;      // W' <= cap * candidates * W_bt(sel); <= 0: no cap
uniform int u_stochastic_bilinear;
uniform float u_pdf_floor;       // defensive mixture: p_hat += floor x mean p_hat of the K candidates (0: none)

layout(location = 0) out uvec4 o_samples;

#ifdef HAS_LINKS
struct PdfPoint { vec3 P; vec3 N; vec3 V; uint group; };
#else
struct PdfPoint { vec3 P; vec3 N; vec3 V; };
#endif

void main() {
    ivec2 st = ivec2(gl_FragCoord.xy);
    uint st_index = uint(st.y) * 4096u + uint(st.x);
    Rng rng = rng_init(st_index + 0x20000000u, u_counts.y);
    Rng off = rng_init(st_index + 0x30000000u, u_counts.y ^ 0x68e31da4u);
    uvec4 result = uvec4(pack_sample(LIM_EMPTY_LIGHT_INDEX, 0.0));

    // -- 4 random quads of this tile: surface points and the averaged material --
    PdfPoint pts[4];
    int npts = 0;
    float kd = 0.0, ks = 0.0, rough = 0.0;
    int nq = quads_per_tile();
    // Up to 4 valid points: quads off-screen or on background are redrawn (edge
    // tiles would otherwise end up with no samples and darken their pixels).
    for (int i = 0; i < 16 && npts < 4; ++i) {
        int slot = int(rng_u16(rng)) % nq;
        ivec2 px = quad_pixel(st, slot) + ivec2(int(rng_u16(rng)) & 1, int(rng_u16(rng)) & 1);
        if (any(lessThan(px, ivec2(0))) || any(greaterThanEqual(px, ivec2(u_resolution.xy)))) continue;
        Surface s;
        if (!read_surface(px, s)) continue;
        pts[npts].P = s.P; pts[npts].N = s.N; pts[npts].V = s.V;
#ifdef HAS_LINKS
        pts[npts].group = link_group(px);
#endif
        kd += luminance(s.diffuse); ks += luminance(s.f0); rough += s.roughness;
        npts++;
    }
    // Deterministic fallback: any valid quad (tiles with only a few pixels on screen).
    for (int slot = 0; slot < nq && npts == 0; ++slot) {
        for (int k = 0; k < 4 && npts == 0; ++k) {
            ivec2 px = quad_pixel(st, slot) + ivec2(k & 1, k >> 1);
            if (any(lessThan(px, ivec2(0))) || any(greaterThanEqual(px, ivec2(u_resolution.xy)))) continue;
            Surface s;
            if (!read_surface(px, s)) continue;
            pts[0].P = s.P; pts[0].N = s.N; pts[0].V = s.V;
#ifdef HAS_LINKS
            pts[0].group = link_group(px);
#endif
            kd = luminance(s.diffuse); ks = luminance(s.f0); rough = s.roughness;
            npts = 1;
        }
    }
    if (npts == 0) { o_samples = result; return; }
    kd /= float(npts); ks /= float(npts); rough /= float(npts);
    float a = max(rough * rough, LIM_GGX_ALPHA_MIN);
    float spec_n = max(2.0 / (a * a) - 2.0, 1.0);          // Blinn-Phong exponent from GGX alpha
    float spec_norm = (spec_n + 2.0) / (2.0 * PI);

    // -- stochastic bilinear big-tile selection --
    vec2 c = small_tile_centre(st);
    if (u_stochastic_bilinear == 1) {
        c += (vec2(rng_float(rng), rng_float(rng)) - 0.5) * float(u_big_px);
    }
    ivec2 bt = clamp(ivec2(floor(c / float(u_big_px))), ivec2(0), u_big_tiles - 1);

#ifdef HAS_LINKS
    // The link groups of this tile's pixels (every pixel that shades with its samples).
    uint tile_groups = 0u;
    for (int q = 0; q < nq; ++q) {
        ivec2 qp = quad_pixel(st, q);
        for (int k = 0; k < 4; ++k) {
            ivec2 px = qp + ivec2(k & 1, k >> 1);
            if (any(lessThan(px, ivec2(0))) || any(greaterThanEqual(px, ivec2(u_resolution.xy)))) continue;
            if (texelFetch(g_depth, px, 0).r <= 0.0) continue;  // background: not lit
            tile_groups |= 1u << link_group(px);
        }
    }
#endif

    // -- SRS over the big tile's K samples into STB_N streams --
    const int K = STB_K;  // compile-time (= u_block.x * u_block.y): loops unroll, arrays fit
    // Targets of all K candidates first, so the defensive mixture can use their mean.
    float ph_all[STB_K];
    float wbt_all[STB_K];
    uint li_all[STB_K];
    float ph_sum = 0.0;
    float ph_n = 0.0;
    for (int slot = 0; slot < K; ++slot) {
        ivec2 tx = bt * u_block + ivec2(slot % u_block.x, slot / u_block.x);
        uint smp = texelFetch(u_bigtile, tx, 0).r;
        uint li = sample_index(smp);
        float wbt = sample_weight(smp);
#ifdef HAS_LINKS
        // Lights none of the tile's pixels: dropped like an empty slot (see the top).
        if (li != LIM_EMPTY_LIGHT_INDEX && (link_mask[li] & tile_groups) == 0u) wbt = 0.0;
#endif
        li_all[slot] = li;
        wbt_all[slot] = wbt;
        ph_all[slot] = 0.0;
        if (li == LIM_EMPTY_LIGHT_INDEX || wbt <= 0.0) continue;
        Light L = lights[li];
        float ph = 0.0;
        for (int k = 0; k < npts; ++k) {
#ifdef HAS_LINKS
            if (!light_linked(li, pts[k].group)) continue;  // f = 0 at this point
#endif
            vec2 t = stb_point_target(L, pts[k].P, pts[k].N, pts[k].V, kd, ks, spec_n, spec_norm, true);
            if (t.x <= 0.0 && t.y <= 0.0) continue;  // out of range: no shadow lookup
            float V = luminance(local_shadow_hard(L, pts[k].P, pts[k].N));
            ph += V * t.x + t.y * u_eps;
        }
        ph /= float(npts);
        ph_all[slot] = ph;
        ph_sum += ph;
        ph_n += 1.0;
    }
    // Defensive mixture: p_hat' = p_hat + floor x mean(p_hat), relative to this
    // tile's own targets (so invariant to the scene's brightness). A light that lights
    // some pixel of the tile but none of the 4 sampled points (outside a cone,
    // beyond its range there...) stays selectable with a bounded weight: the
    // estimate stays unbiased (the talk accepts this bias) and its tail stays light.
    // u_pdf_floor = 0 is the talk's estimator (p_hat alone). Nothing lit at any
    // sampled point: every candidate equally (uniform), whatever the floor.
    float mean_ph = ph_n > 0.0 ? ph_sum / ph_n : 0.0;
    bool uniform_pick = !(mean_ph > 0.0);
    float floor_ph = u_pdf_floor * mean_ph;

#ifdef STB_SELECT_ONE
    // Quad/pixel selection: STB_N independent picks (with replacement) over all K
    // candidates, each a complete one-sample estimate W = sum(p_hat x W_bt) /
    // p_hat(selected); every quad (or pixel) uses one of them (quad_stream /
    // pixel_stream), so the tile's pixels do not all share one light: its noise is
    // less correlated across the tile, for the lighting cost of one sample.
    float total = 0.0;
    float count = 0.0;
    float w_all[STB_K];
    for (int slot = 0; slot < K; ++slot) {
        w_all[slot] = 0.0;
        if (li_all[slot] == LIM_EMPTY_LIGHT_INDEX || wbt_all[slot] <= 0.0) continue;
        float ph = uniform_pick ? 1.0 : ph_all[slot] + floor_ph;
        w_all[slot] = ph * wbt_all[slot];
        total += w_all[slot];
        count += 1.0;
    }
    for (int j = 0; j < STB_N; ++j) {
        if (!(total > 0.0)) break;
        float u = rng_float(rng) * total;
        int pick = -1;
        float acc = 0.0;
        for (int slot = 0; slot < K; ++slot) {
            if (w_all[slot] <= 0.0) continue;
            pick = slot;  // the last positive candidate absorbs rounding at the top
            acc += w_all[slot];
            if (u < acc) break;
        }
        float ph = uniform_pick ? 1.0 : ph_all[pick] + floor_ph;
        float W = total / ph;
        if (u_weight_cap > 0.0) W = min(W, u_weight_cap * count * wbt_all[pick]);
        result[j] = pack_sample(li_all[pick], W);
    }
#else
    // Iteration `base` hands slots base..base+N-1 to the N streams, rotated by a
    // random offset: each big-tile slot lands in exactly one stream.
    float total[STB_N];
    float sel_p[STB_N];
    float sel_wbt[STB_N];
    float count[STB_N];
    uint sel[STB_N];
    for (int j = 0; j < STB_N; ++j) {
        total[j] = 0.0; sel_p[j] = 0.0; sel_wbt[j] = 0.0; count[j] = 0.0;
        sel[j] = LIM_EMPTY_LIGHT_INDEX;
    }
    for (int base = 0; base < K; base += STB_N) {
        int o = base == 0 ? 0 : int(rng_next(off) >> 16) % STB_N;
        for (int j = 0; j < STB_N; ++j) {
            int slot = base + (j + o) % STB_N;
            if (slot >= K) continue;
            uint li = li_all[slot];
            float wbt = wbt_all[slot];
            if (li == LIM_EMPTY_LIGHT_INDEX || wbt <= 0.0) continue;
            float ph = uniform_pick ? 1.0 : ph_all[slot] + floor_ph;
            float w = ph * wbt;
            count[j] += 1.0;
            total[j] += w;
            if (w > 0.0 && rng_float(rng) * total[j] <= w) {
                sel[j] = li;
                sel_p[j] = ph;
                sel_wbt[j] = wbt;
            }
        }
    }
    for (int j = 0; j < STB_N; ++j) {
        float W = sel_p[j] > 0.0 ? total[j] / sel_p[j] : 0.0;
        if (u_weight_cap > 0.0) W = min(W, u_weight_cap * count[j] * sel_wbt[j]);
        result[j] = pack_sample(sel[j], W);
    }
#endif
    o_samples = result;
}
