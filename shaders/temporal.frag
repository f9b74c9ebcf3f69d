// Temporal reuse for a moving camera (--temporal taa), one full-screen pass:
//  * reprojection: the previous position of the surface under this pixel from the
//    G-buffer's motion vectors (camera motion and animated transforms) minus this
//    frame's subpixel jitter (history lives on the unjittered pixel grid);
//  * disocclusion: the previous frame's linear depth and normal (u_prev_geo) at the
//    4 texels of the bilinear footprint against the depth this surface had in the
//    previous view (and its normal); Catmull-Rom (5 bilinear taps) where all 4
//    agree, bilinear over the agreeing texels where some do, no history otherwise
//    (the normal test only rejects opposite sides, e.g. of a thin wall: at a crease
//    the jitter moves the pixel between faces at one depth, and a stricter test
//    dropped ~5 % of a still courtyard's pixels every frame); where nothing of the
//    footprint matches but the texel's old surface is still beside the pixel (an edge
//    the jitter crosses), the history of a 3x3 texel that saw this surface is borrowed;
//  * history rejection on noisy input: variance clipping of the history against a
//    depth-weighted 13-tap neighbourhood (3x3 + 4 taps at distance 2) of lighting
//    demodulated by albedo (the statistics of a spatially pre-filtered signal, not
//    of single noisy pixels: a lone pixel that missed a light does not collapse the
//    box), clip towards the mean (not a per-channel clamp);
//  * blending: 1/n with a per-pixel history length n (alpha channel) up to
//    u_max_len (longer, with a wider box, where the surface has not moved), in scene-linear units (an exposure change scales history, current
//    and box alike, so the blend does not depend on the exposure);
//  * out: remodulated colour (display), demodulated history + n, depth + normal +
//    the second moment of demodulated luminance (the pixel's temporal spread).
#include "common/frame.glsl"
#include "common/packing.glsl"

uniform sampler2D u_current;   // lighting (scene-linear, this frame, jittered raster)
uniform sampler2D u_depth;     // g_depth: linear view depth (m), 0 = no geometry
uniform sampler2D u_normal;    // g_normal: octahedral world normal
uniform sampler2D u_motion;    // g_motion: current (jittered) - previous (unjittered) px
uniform sampler2D u_base;      // g_base_rough
uniform sampler2D u_f0;        // g_f0_metal
uniform sampler2D u_history;   // previous demodulated lighting, a = history length (linear)
uniform sampler2D u_prev_geo;  // previous depth (m), octahedral normal, luma 2nd moment
uniform mat4 u_prev_view;      // previous world -> view
uniform vec2 u_jitter;         // this frame's jitter (px, image content shift)
uniform float u_reset;         // 1: ignore the history
uniform vec2 u_max_len;        // history length cap (frames): moving, still pixel
uniform vec2 u_gamma;          // clip box half extent (std devs): moving, still pixel
// Lights that changed a lot this frame: within a sphere (centre, radius: its
// influence range grown by its move) the history is capped at u_light_caps[i]
// frames (1: dropped: a light switched off is gone from this frame on).
uniform int u_light_changes;
uniform vec4 u_light_spheres[16];
uniform float u_light_caps[16];

layout(location = 0) out vec4 o_color;
layout(location = 1) out vec4 o_history;
layout(location = 2) out vec4 o_geo;

float luma(vec3 c) {
    return dot(c, LUMINANCE_REC709);
}

vec3 albedo_at(ivec2 px) {
    vec4 b = texelFetch(u_base, px, 0);
    vec4 f = texelFetch(u_f0, px, 0);
    return max(b.rgb * (1.0 - f.a) + f.rgb, vec3(0.04));
}

vec3 history_bilinear_at(vec2 uv) {
    return texture(u_history, uv).rgb;
}

// Catmull-Rom through 5 bilinear taps (the 4 corner taps' weights are dropped).
vec3 history_catmull_rom(vec2 pos) {
    vec2 inv = u_resolution.zw;
    vec2 t1 = floor(pos - 0.5) + 0.5;
    vec2 f = pos - t1;
    vec2 w0 = f * (-0.5 + f * (1.0 - 0.5 * f));
    vec2 w1 = 1.0 + f * f * (-2.5 + 1.5 * f);
    vec2 w2 = f * (0.5 + f * (2.0 - 1.5 * f));
    vec2 w3 = f * f * (-0.5 + 0.5 * f);
    vec2 w12 = w1 + w2;
    vec2 t12 = (t1 + w2 / w12) * inv;
    vec2 t0 = (t1 - 1.0) * inv;
    vec2 t3 = (t1 + 2.0) * inv;
    vec3 r = history_bilinear_at(vec2(t12.x, t0.y)) * (w12.x * w0.y)
           + history_bilinear_at(vec2(t0.x, t12.y)) * (w0.x * w12.y)
           + history_bilinear_at(t12) * (w12.x * w12.y)
           + history_bilinear_at(vec2(t3.x, t12.y)) * (w3.x * w12.y)
           + history_bilinear_at(vec2(t12.x, t3.y)) * (w12.x * w3.y);
    float ws = w12.x * w0.y + w0.x * w12.y + w12.x * w12.y + w3.x * w12.y + w12.x * w3.y;
    return max(r / ws, vec3(0.0));
}

vec3 clip_towards_mean(vec3 mu, vec3 ext, vec3 h) {
    vec3 v = h - mu;
    vec3 a = abs(v) / max(ext, vec3(1e-7));
    float m = max(a.x, max(a.y, a.z));
    return m > 1.0 ? mu + v / m : h;
}

const ivec2 TAPS[13] = ivec2[13](
    ivec2(0, 0), ivec2(-1, -1), ivec2(0, -1), ivec2(1, -1), ivec2(-1, 0), ivec2(1, 0),
    ivec2(-1, 1), ivec2(0, 1), ivec2(1, 1), ivec2(-2, 0), ivec2(2, 0), ivec2(0, -2), ivec2(0, 2));

void main() {
    ivec2 ip = ivec2(gl_FragCoord.xy);
    ivec2 size = ivec2(u_resolution.xy);
    float d = texelFetch(u_depth, ip, 0).r;
    vec2 enc = texelFetch(u_normal, ip, 0).xy;
    vec3 n = oct_decode(enc);
    vec3 alb = albedo_at(ip);
    vec4 cur4 = texelFetch(u_current, ip, 0);
    vec3 cur = cur4.rgb / alb;

    // Neighbourhood statistics (depth-weighted: other surfaces do not widen the box).
    vec3 m1 = vec3(0.0);
    vec3 m2 = vec3(0.0);
    float wsum = 0.0;
    for (int i = 0; i < 13; ++i) {
        ivec2 q = clamp(ip + TAPS[i], ivec2(0), size - 1);
        float dq = texelFetch(u_depth, q, 0).r;
        float w = abs(dq - d) <= 0.05 * max(d, 1e-4) + 1e-6 ? 1.0 : 0.0;
        vec3 c = texelFetch(u_current, q, 0).rgb / albedo_at(q);
        m1 += w * c;
        m2 += w * c * c;
        wsum += w;
    }
    m1 /= wsum;
    m2 /= wsum;
    vec3 sigma = sqrt(max(m2 - m1 * m1, vec3(0.0)));

    // Reprojection (unjittered previous pixel position) and disocclusion.
    vec2 mv = texelFetch(u_motion, ip, 0).xy - u_jitter;
    vec2 pos = gl_FragCoord.xy - mv;
    float prev_d = d;
    // A pixel whose surface has not moved (< 0.5 px) keeps a longer history and a
    // wider box: with a still camera the box only has to catch what the light
    // caps and disocclusion miss, and every clip of noisy input is a bias.
    float still = clamp(1.0 - 2.0 * length(mv), 0.0, 1.0);
    float gamma = mix(u_gamma.x, u_gamma.y, still);
    float max_len = floor(mix(u_max_len.x, u_max_len.y, still) + 0.5);
    if (d > 0.0) {
        vec3 world = world_pos_from_depth(gl_FragCoord.xy, d);
        prev_d = max(-(u_prev_view * vec4(world, 1.0)).z, 1e-6);
        for (int i = 0; i < u_light_changes; ++i) {
            if (distance(world, u_light_spheres[i].xyz) < u_light_spheres[i].w) {
                max_len = min(max_len, u_light_caps[i]);
            }
        }
    }
    float tol = 0.03 * prev_d + 1e-4;
    float shift = prev_d - d;  // this surface's depth change, applied to its neighbours
    vec2 base = floor(pos - 0.5);
    vec2 f = pos - 0.5 - base;
    float valid_w = 0.0;
    int valid_n = 0;
    float hist_len = 0.0;
    vec3 bil = vec3(0.0);
    float mom2 = 0.0;
    for (int k = 0; k < 4; ++k) {
        ivec2 t = ivec2(base) + ivec2(k & 1, k >> 1);
        if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, size))) continue;
        vec4 g = texelFetch(u_prev_geo, t, 0);
        bool same;
        if (d <= 0.0) {
            same = g.x <= 0.0;
        } else {
            vec3 gn = oct_decode(g.yz);
            same = g.x > 0.0 && abs(g.x - prev_d) <= tol && dot(gn, n) > -0.5;
            // Else: is it a surface of this 3x3 neighbourhood (depth, facing the same
            // half-space), seen through another jitter offset at an edge? Not a
            // disocclusion. (A normal test of 0.9 reset the pixels of curved rims,
            // whose normal turns by more than that between neighbours, every time
            // the jitter moved them on or off the rim.)
            // (Fetched here, not kept from the statistics loop: only edge pixels
            // get this far, and arrays indexed in loops are slow on llvmpipe.)
            for (int j = 1; j < 9 && !same && g.x > 0.0; ++j) {
                ivec2 q = clamp(ip + TAPS[j], ivec2(0), size - 1);
                float dj = texelFetch(u_depth, q, 0).r;
                same = dj > 0.0 && abs(g.x - (dj + shift)) <= 0.03 * g.x + 1e-4
                       && dot(gn, oct_decode(texelFetch(u_normal, q, 0).xy)) > 0.0;
            }
        }
        if (!same) continue;
        vec4 h = texelFetch(u_history, t, 0);
        float w = (k & 1) == 1 ? f.x : 1.0 - f.x;
        w *= (k >> 1) == 1 ? f.y : 1.0 - f.y;
        bil += w * h.rgb;
        mom2 += w * g.w;
        valid_w += w;
        valid_n += 1;
        hist_len += w * h.a;
    }

    // History borrowing: nothing of the footprint is this surface, but what this
    // texel saw last frame is still beside the pixel: an edge the jitter moves across
    // (a 1 px post, a silhouette against the sky, a curved rim), not a disocclusion
    // (floor uncovered by a moving box: the box is gone from the neighbourhood). Take
    // the history of the 3x3 texel around the reprojected position that saw this
    // surface last frame (nearest depth, same side), instead of starting again from
    // one frame's noise. Only such pixels pay for the search.
    ivec2 c0 = ivec2(floor(pos));
    bool edge = false;  // the surface this texel saw last frame is still beside this pixel
    if (valid_n == 0 && u_reset < 0.5 && all(greaterThanEqual(c0, ivec2(0))) && all(lessThan(c0, size))) {
        float g0 = texelFetch(u_prev_geo, c0, 0).x;
        for (int j = 1; j < 9 && !edge; ++j) {
            float dj = texelFetch(u_depth, clamp(ip + TAPS[j], ivec2(0), size - 1), 0).r;
            edge = g0 <= 0.0 ? dj <= 0.0 : dj > 0.0 && abs(g0 - (dj + shift)) <= 0.05 * g0 + 1e-4;
        }
    }
    if (edge) {
        float best = 1e30;
        for (int j = 1; j < 9; ++j) {
            ivec2 t = c0 + TAPS[j];
            if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, size))) continue;
            vec4 g = texelFetch(u_prev_geo, t, 0);
            float err;
            if (d <= 0.0) {
                if (g.x > 0.0) continue;
                err = 0.0;
            } else {
                err = abs(g.x - prev_d);
                if (!(g.x > 0.0) || err > 0.05 * prev_d + 1e-4 || dot(oct_decode(g.yz), n) < 0.5) continue;
            }
            if (err >= best) continue;
            best = err;
            vec4 h = texelFetch(u_history, t, 0);
            bil = h.rgb;
            mom2 = g.w;
            hist_len = h.a;
            valid_w = 1.0;
            valid_n = 1;
        }
    }

    // History fix: a pixel with a short history (disoccluded, or capped by a light
    // change) takes the neighbourhood mean instead of its own noisy sample for its
    // first frames (full weight at n = 1, none from n = 5 on).
    vec3 result = m1;
    float len = 1.0;
    float lc = luma(cur);
    float tm2 = lc * lc;
    if (u_reset < 0.5 && valid_n > 0 && valid_w > 1e-4) {
        vec3 h = valid_n == 4 ? history_catmull_rom(pos) : bil / valid_w;
        // The box: spatial spread, widened to the pixel's own temporal spread
        // (STB picks lights per tile, so neighbours share a frame's misses and
        // the spatial spread alone underestimates the noise: clipping to it
        // pulled converged history back to one frame's noise).
        mom2 /= valid_w;
        float lh = luma(h);
        float sigma_t = sqrt(max(mom2 - lh * lh, 0.0));
        vec3 ext = gamma * max(sigma, vec3(sigma_t)) + 1e-3 * m1;
        h = clip_towards_mean(m1, ext, h);
        len = min(floor(hist_len / valid_w + 0.5) + 1.0, max_len);
        result = mix(h, mix(m1, cur, clamp((len - 1.0) / 4.0, 0.0, 1.0)), 1.0 / len);
        tm2 = mix(mom2, tm2, 1.0 / len);
    }
    o_history = vec4(result, len);
    o_color = vec4(result * alb, cur4.a);
    o_geo = vec4(d, enc, tm2);
}
