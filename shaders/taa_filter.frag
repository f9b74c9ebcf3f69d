// Edge-aware spatial filter of taa's demodulated lighting (RenderSettings.taa_filter
// levels; tasks/taa_filter.py), display only: the history keeps its unfiltered
// values. SVGF-style a-trous (B3 5x5 kernel, step 2^level) over lighting / albedo
// with the emission taken out (it is exact, not noise), weighted by
//  * depth: exp(-|dz| / (|offset| . |grad z| + 1e-3 z)) (the centre's depth slope,
//    the smaller of the one-sided differences, so a silhouette does not widen it);
//  * normal: max(n_p . n_q, 0)^128;
//  * luminance: exp(-|l_p - l_q| / (sigma_l sqrt(var_p + cq.a))), var the 3x3
//    Gaussian of the per-pixel variance carried in alpha (level 0: the temporal
//    variance of this pixel's frames, taa_geo.w - luma(history)^2). The stop is
//    symmetric, so a bright pixel and its dark neighbour exchange equal weights and
//    the filter keeps the mean (an asymmetric stop spreads outliers down: -10 %);
//  * sky and emission-only pixels pass through.
// Variance is filtered with the squared weights (it is the next level's stop).
// Passes (u_mode): 0 prepare (demodulated lighting - emission, variance), 1 a level,
// 2 the last level, remodulated (display colour = (filtered + emission / albedo) x albedo).
#include "common/frame.glsl"
#include "common/packing.glsl"

uniform sampler2D u_src;       // mode 0: taa history (rgb, a = n); else previous level (rgb, a = variance)
uniform sampler2D u_geo;       // taa geometry: linear depth (m), oct normal, luma 2nd moment
uniform sampler2D u_albedo;    // taa_albedo: demodulation albedo, lighting alpha
uniform sampler2D u_history;   // taa history (mode 2: the emission share, unfiltered)
uniform sampler2D u_emission;  // g_emission
uniform int u_mode;
uniform int u_step;            // tap spacing (px)
uniform float u_sigma_l;       // luminance stop (standard deviations)

layout(location = 0) out vec4 o_out;

float luma(vec3 c) {
    return dot(c, LUMINANCE_REC709);
}

// Demodulated emission of pixel q (clamped to the history's lighting).
vec3 emission_demod(ivec2 q, vec3 lighting) {
    vec3 alb = texelFetch(u_albedo, q, 0).rgb;
    return min(texelFetch(u_emission, q, 0).rgb / alb, lighting);
}

// The temporal variance of this pixel's frames (luma), 3x3 Gaussian over its neighbours.
float variance_3x3(ivec2 ip, ivec2 size) {
    float v = 0.0;
    for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
            float k = (dx == 0 ? 0.5 : 0.25) * (dy == 0 ? 0.5 : 0.25);
            ivec2 q = clamp(ip + ivec2(dx, dy), ivec2(0), size - 1);
            float lh = luma(texelFetch(u_history, q, 0).rgb);
            v += k * max(texelFetch(u_geo, q, 0).w - lh * lh, 0.0);
        }
    }
    return v;
}

void main() {
    ivec2 ip = ivec2(gl_FragCoord.xy);
    ivec2 size = ivec2(u_resolution.xy);
    vec4 g = texelFetch(u_geo, ip, 0);
    if (u_mode == 0) {
        vec3 h = texelFetch(u_history, ip, 0).rgb;
        o_out = vec4(h - emission_demod(ip, h), variance_3x3(ip, size));
        return;
    }
    vec4 c = texelFetch(u_src, ip, 0);
    float z = g.x;
    vec4 res = c;
    if (z > 0.0) {
        vec3 n = oct_decode(g.yz);
        float zl = texelFetch(u_geo, ivec2(max(ip.x - 1, 0), ip.y), 0).x;
        float zr = texelFetch(u_geo, ivec2(min(ip.x + 1, size.x - 1), ip.y), 0).x;
        float zd = texelFetch(u_geo, ivec2(ip.x, max(ip.y - 1, 0)), 0).x;
        float zu = texelFetch(u_geo, ivec2(ip.x, min(ip.y + 1, size.y - 1)), 0).x;
        vec2 grad = vec2(min(abs(z - zl), abs(z - zr)), min(abs(z - zd), abs(z - zu)));
        float var_p = c.a;
        float lp = luma(c.rgb);
        const float H[5] = float[5](0.0625, 0.25, 0.375, 0.25, 0.0625);
        vec3 acc = vec3(0.0);
        float wsum = 0.0;
        float vacc = 0.0;
        for (int j = -2; j <= 2; ++j) {
            for (int i = -2; i <= 2; ++i) {
                float k = H[i + 2] * H[j + 2];
                ivec2 off = ivec2(i, j) * u_step;
                ivec2 q = clamp(ip + off, ivec2(0), size - 1);
                vec4 cq = texelFetch(u_src, q, 0);
                float w = k;
                if (i != 0 || j != 0) {
                    vec4 gq = texelFetch(u_geo, q, 0);
                    float wz = exp(-abs(z - gq.x) / (dot(abs(vec2(off)), grad) + 1e-3 * z + 1e-6));
                    float wn = pow(max(dot(n, oct_decode(gq.yz)), 0.0), 128.0);
                    float wl = exp(-abs(lp - luma(cq.rgb)) / (u_sigma_l * sqrt(var_p + cq.a) + 1e-6));
                    w = gq.x > 0.0 ? k * wz * wn * wl : 0.0;
                }
                acc += w * cq.rgb;
                wsum += w;
                vacc += w * w * cq.a;
            }
        }
        res = vec4(acc / wsum, vacc / (wsum * wsum));
    }
    if (u_mode == 2) {
        vec4 alb = texelFetch(u_albedo, ip, 0);
        vec3 hist = texelFetch(u_history, ip, 0).rgb;
        vec3 lighting = z > 0.0 ? res.rgb + emission_demod(ip, hist) : hist;
        o_out = vec4(max(lighting, vec3(0.0)) * alb.rgb, alb.a);
    } else {
        o_out = res;
    }
}
