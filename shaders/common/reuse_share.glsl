// STB reuse (issue 31), -o reuse_res=share (STB_REUSE_SHARE, fused shading pass only):
// the 2x2 quad's four pixels each resample C / 4 of one big tile's slots (disjoint
// strata, common/reuse_initial.glsl), then every pixel combines the quad's four
// reservoirs by generalized RIS: each pixel's own target ranks C / 4 candidates, yet its
// light comes from all C, for C / 4 + 3 target evaluations instead of C.
// MIS weights: m_i(y) = c_i(y) / sum_j c_j(y), c_j = min(p_j(y) / (ratio x max_l p_l(y)), 1)
// (LIM_REUSE_SHARE_MIS_RATIO; p_j: pixel j's target, 0 for background pixels). They sum
// to 1 over the pixels that can draw y, so the combination is unbiased. Not the balance
// heuristic p_i / sum p_j: the strata are disjoint, so only one pixel of the quad holds a
// given slot in a frame, and p_i / sum p_j left the quad's pixels a per-quad error of
// their targets' spread (one light: 2.7 % per pixel, a linked light's neighbours
// likewise); pixels within the ratio of the largest target weigh alike (exact for one
// light), and below it the weight falls with p_i (no fireflies from small targets).
// The exchange inside the quad uses fine derivatives (GL_ARB_derivative_control: on
// llvmpipe and GPUs alike the 2x2 quad's invocations run together), so every
// invocation of the quad -- background and helper invocations included -- must reach
// reuse_share_quad in uniform control flow, and compute its values from textures only:
// llvmpipe loads nothing from a storage buffer in a helper invocation, and splits the
// full-screen triangle in two, so the quads along that seam hold helpers (the slot
// target reads textures, links included: u_slot_link; stb.py refuses the light-buffer
// targets and the shadow gather with share).
#ifndef STB_REUSE_SHARE_GLSL
#define STB_REUSE_SHARE_GLSL
#ifndef STB_REUSE_SLOT_TARGET
#error "reuse_res=share reads the slot targets only (-o reuse_target=tile)"
#endif

// This pixel's values and the quad's others': slot k holds quad position q ^ k
// (q = x&1 + 2 (y&1)), per component.
void share_all(vec3 v, bool left, bool top, out vec3 s0, out vec3 s1, out vec3 s2, out vec3 s3) {
    vec3 dx = dFdxFine(v);
    s0 = v;
    s1 = left ? v + dx : v - dx;
    vec3 d0 = dFdyFine(s0), d1 = dFdyFine(s1);
    s2 = top ? s0 + d0 : s0 - d0;
    s3 = top ? s1 + d1 : s1 - d1;
}

// Sum over the quad's four invocations, per component.
vec4 share_sum(vec4 v, bool left, bool top) {
    vec4 dx = dFdxFine(v);
    vec4 row = v + (left ? v + dx : v - dx);
    vec4 dy = dFdyFine(row);
    return row + (top ? row + dy : row - dy);
}

// Maximum over the quad's four invocations, per component.
vec4 share_max(vec4 v, bool left, bool top) {
    vec4 dx = dFdxFine(v);
    vec4 row = max(v, left ? v + dx : v - dx);
    vec4 dy = dFdyFine(row);
    return max(row, top ? row + dy : row - dy);
}

Reservoir reuse_share_quad(ivec2 px, bool ok, Surface s, uint group) {
    bool left = (px.x & 1) == 0, top = (px.y & 1) == 0;
    int q = (px.x & 1) + 2 * (px.y & 1);
    Reservoir r = reservoir_empty();
    if (ok) {
        Rng ri = rng_init(uint(px.y) * 8192u + uint(px.x) + 0x71000000u, u_counts.y);
        ivec2 qp = px >> 1;
        Rng qr = rng_init(uint(qp.y) * 8192u + uint(qp.x) + 0x73000000u, u_counts.y);
        float pf;
        r = reuse_initial_bigtile(vec2(px) + 0.5, s, group, ri, pf, qr, q);
    }
    bool has = ok && r.y != LIM_EMPTY_LIGHT_INDEX && r.W > 0.0;
    // This pixel's (pick's slot texel, resampling weight sum p(y) W, p(y)) and the quad's
    // others'; the slot texel names the light (the big-tile reservoir at that texel).
    float yf = has ? float(reuse_sel_texel.y * 4096 + reuse_sel_texel.x) : -1.0;
    vec3 e[4];
    share_all(vec3(yf, has ? r.W * r.p : 0.0, has ? r.p : 0.0), left, top, e[0], e[1], e[2], e[3]);
    uint yi[4];
    vec4 P = vec4(0.0);  // this pixel's target of each slot's light
    for (int k = 0; k < 4; ++k) {
        yi[k] = LIM_EMPTY_LIGHT_INDEX;
        if (k == 0) {
            yi[k] = has ? r.y : LIM_EMPTY_LIGHT_INDEX;
            P[k] = has ? r.p : 0.0;
        } else if (ok && e[k].x > -0.5) {
            int code = int(e[k].x + 0.5);
            ivec2 texel = ivec2(code % 4096, code / 4096);
            vec4 sh = texelFetch(u_slot_shape, texel, 0);
            if (sh.z > 0.0) {
                yi[k] = reuse_slot_light(texel);
                P[k] = reuse_slot_target(texelFetch(u_slot_pos, texel, 0), sh, texelFetch(u_slot_axis, texel, 0), texel,
                                         s, group);
            }
        }
    }
    // This pixel's target of each quad position's pick (slot k is position q ^ k); the
    // quad's largest, then the sum of the MIS weights' numerators c_j.
    vec4 Pa;
    for (int i = 0; i < 4; ++i) Pa[i] = P[i ^ q];
    vec4 Ma = share_max(Pa, left, top);
    const float RATIO = LIM_REUSE_SHARE_MIS_RATIO;
    vec4 ca = vec4(0.0);
    for (int i = 0; i < 4; ++i) ca[i] = Ma[i] > 0.0 ? min(Pa[i] / (RATIO * Ma[i]), 1.0) : 0.0;
    vec4 Ca = share_sum(ca, left, top);
    Stream str = stream_empty();
    Rng rs = rng_init(uint(px.y) * 8192u + uint(px.x) + 0x74000000u, u_counts.y);
    for (int k = 0; k < 4; ++k) {
        // m_i p(y) W_i with W_i = wsum_i / p_i(y_i): c_i / p_i = 1 / max(p_i, ratio x max)
        int a = k ^ q;
        float pi = e[k].z, den = max(pi, RATIO * Ma[a]) * Ca[a];
        float w = den > 0.0 && pi > 0.0 && P[k] > 0.0 ? max(e[k].y, 0.0) * P[k] / den : 0.0;
        stream_add(str, yi[k], P[k], w, rng_float(rs));
    }
    return stream_reservoir(str, 1.0, 1.0);
}
#endif
