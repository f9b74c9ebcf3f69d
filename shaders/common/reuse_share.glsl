// STB reuse (issue 31), -o reuse_res=share (STB_REUSE_SHARE, fused shading pass only):
// the 2x2 quad's four pixels each resample C / 4 of one big tile's slots (disjoint
// strata, common/reuse_initial.glsl), then every pixel combines the quad's four
// reservoirs by generalized RIS with the balance heuristic over the four pixels' own
// targets, m_i(y) = p_i(y) / sum_j p_j(y) (unbiased; background pixels have p_j = 0):
// each pixel's own target ranks C / 4 candidates, yet its light comes from all C, for
// C / 4 + 3 target evaluations instead of C.
// The exchange inside the quad uses fine derivatives (GL_ARB_derivative_control: on
// llvmpipe and GPUs alike the 2x2 quad's invocations run together), so every
// invocation of the quad -- background and helper invocations included -- must reach
// reuse_share_quad in uniform control flow.
#ifndef STB_REUSE_SHARE_GLSL
#define STB_REUSE_SHARE_GLSL

// (value of this pixel, of its row partner) -> (this pixel's, row partner's, then the
// same two of the other row: positions q, q ^ 1, q ^ 2, q ^ 3 with q = x&1 + 2 (y&1)).
vec2 share_row(float v, bool left) {
    float d = dFdxFine(v);
    return vec2(v, left ? v + d : v - d);
}

// Sum over the quad's four invocations, per component.
vec4 share_sum(vec4 v, bool left, bool top) {
    vec4 dx = dFdxFine(v);
    vec4 row = v + (left ? v + dx : v - dx);
    vec4 dy = dFdyFine(row);
    return row + (top ? row + dy : row - dy);
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
    // This pixel's (light index, resampling weight sum p(y) W) and the quad's others'.
    float wsum = has ? r.W * r.p : 0.0;
#ifdef STB_REUSE_SLOT_TARGET
    // the pick's slot texel (its light index: the big-tile reservoir at that texel)
    float yf = has ? float(reuse_sel_texel.y * 4096 + reuse_sel_texel.x) : -1.0;
#else
    float yf = has ? float(r.y) : -1.0;
#endif
    vec2 ry = share_row(yf, left), rw = share_row(wsum, left);
    vec4 mine = vec4(ry, rw);
    vec4 dy = dFdyFine(mine);
    vec4 other = top ? mine + dy : mine - dy;
    // Slot k holds the quad position q ^ k.
    float ys[4] = float[4](ry.x, ry.y, other.x, other.y);
    float ws[4] = float[4](rw.x, rw.y, other.z, other.w);
    uint yi[4];
    vec4 P = vec4(0.0);  // this pixel's target of each slot's light
    for (int k = 0; k < 4; ++k) {
#ifdef STB_REUSE_SLOT_TARGET
        yi[k] = LIM_EMPTY_LIGHT_INDEX;
        if (k == 0) {
            yi[k] = has ? r.y : LIM_EMPTY_LIGHT_INDEX;
            P[k] = has ? r.p : 0.0;
        } else if (ok && ys[k] > -0.5) {
            int code = int(ys[k] + 0.5);
            ivec2 texel = ivec2(code % 4096, code / 4096);
            vec4 sh = texelFetch(u_slot_shape, texel, 0);
            if (sh.z > 0.0) {
                yi[k] = reuse_slot_light(texel);
                P[k] = reuse_slot_target(texelFetch(u_slot_pos, texel, 0), sh, texelFetch(u_slot_axis, texel, 0), texel,
                                         s, group);
                if (u_shadow_floor < 1.0 && P[k] > 0.0) {
                    float v = luminance(local_shadow_hard(lights[yi[k]], s.P, s.N));
                    P[k] *= u_shadow_floor + (1.0 - u_shadow_floor) * clamp(v, 0.0, 1.0);
                }
            }
        }
#else
        yi[k] = ys[k] < -0.5 ? LIM_EMPTY_LIGHT_INDEX : uint(ys[k] + 0.5);
        if (k == 0) {
            P[k] = has ? r.p : 0.0;
        } else if (ok && yi[k] != LIM_EMPTY_LIGHT_INDEX) {
            P[k] = reuse_initial_target(yi[k], s, group);
        }
#endif
    }
    // Sum over the quad of p_j(y of quad position i): reorder P to absolute positions
    // (slot k is position q ^ k), sum, and back.
    vec4 Pa;
    for (int i = 0; i < 4; ++i) Pa[i] = P[i ^ q];
    vec4 Sa = share_sum(Pa, left, top);
    Stream str = stream_empty();
    Rng rs = rng_init(uint(px.y) * 8192u + uint(px.x) + 0x74000000u, u_counts.y);
    for (int k = 0; k < 4; ++k) {
        float S = Sa[k ^ q];
        float w = S > 0.0 && P[k] > 0.0 ? max(ws[k], 0.0) * P[k] / S : 0.0;
        stream_add(str, yi[k], P[k], w, rng_float(rs));
    }
    return stream_reservoir(str, 1.0, 1.0);
}
#endif
