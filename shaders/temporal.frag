// Temporal reuse for a moving camera (--temporal taa), one full-screen pass after the
// lighting pass, which wrote its demodulated input (common/lighting_out.glsl):
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
//    the jitter crosses), a 3x3 texel that saw this surface lends its history (not a
//    nearer surface's to a moving pixel: parallax, an occluder's trail);
//  * history rejection on noisy input: variance clipping of the history against a
//    depth-weighted 13-tap neighbourhood (3x3 + 4 taps at distance 2) of lighting
//    demodulated by albedo (the statistics of a spatially pre-filtered signal, not
//    of single noisy pixels: a lone pixel that missed a light does not collapse the
//    box), clip towards the mean (not a per-channel clamp);
//  * blending: 1/n with a per-pixel history length n (alpha channel) up to
//    u_max_len (longer, with a wider box, where the surface has not moved); where it
//    moves, the new sample is the neighbourhood mean (u_cur_weight), so the camera's
//    motion does not show as flicker; in scene-linear units (an exposure change scales
//    history, current and box alike, so the blend does not depend on the exposure);
//  * out: remodulated colour (display), demodulated history + n, depth + normal +
//    the second moment of demodulated luminance (the pixel's temporal spread).
// Steps, in main()'s order: neighbourhood_stats, reproject, footprint_history
// (disocclusion: same_surface, neighbour_surface), the edge-left cap, history_catmull_rom,
// clip_towards_mean, blend, young_estimate (display only; issue 31 "(taa8)"). Cost (llvmpipe, docs/PERFORMANCE.md): the neighbourhood
// reads lighting / albedo + depth from one texture the lighting pass wrote (one fetch
// a tap instead of four), the remodulation its albedo + alpha texture,
// and the edge test fetches each neighbour's depth and normal once for all 4
// footprint texels.
#include "common/frame.glsl"
#include "common/packing.glsl"

uniform sampler2D u_demod;     // lighting / albedo (rgb), linear depth (m) (lighting pass)
uniform sampler2D u_albedo;    // demodulation albedo (rgb), lighting alpha (lighting pass)
uniform sampler2D u_normal;    // g_normal: octahedral world normal
uniform sampler2D u_motion;    // g_motion: current (jittered) - previous (unjittered) px
uniform sampler2D u_history;   // previous demodulated lighting, a = history length (linear)
uniform sampler2D u_prev_geo;  // previous depth (m), octahedral normal, luma 2nd moment
uniform sampler2D u_base_rough;  // g_base_rough: base colour, perceptual roughness (a)
uniform mat4 u_prev_view;      // previous world -> view
uniform vec4 u_prev_tan;       // previous view: tan half extents xy, aperture offsets zw (unit depth)
uniform float u_edge_slack;    // px: how far a neighbour's motion may leave an old texel (edges)
uniform float u_edge_motion;  // px^2: a 3x3 neighbour moving against the pixel
uniform vec2 u_edge_run;      // frames in a row with an edge before a flat neighbourhood caps; most counted
uniform float u_plane_tol;     // px footprints: an old texel's point off this surface's plane
uniform vec2 u_jitter;         // this frame's jitter (px, image content shift)
uniform float u_reset;         // 1: ignore the history
uniform vec2 u_max_len;        // history length cap (frames): moving, still pixel
uniform vec2 u_gamma;          // clip box half extent (std devs): moving, still pixel
uniform float u_cur_weight;    // a moving pixel's own sample against the neighbourhood mean
uniform float u_lent_near;     // 1: a nearer surface's history may be lent to a moving pixel; 0: not
uniform float u_lent_spread;   // a moving pixel's lent history: weight of its temporal spread (0-1)
// History cap from the specular lobe (x: k; y: least frames): k x the lobe's
// width (GGX alpha, rad) / the angle (rad) the view direction at the surface turned
// since the previous frame -- about how far a highlight slides over the surface a
// frame, so older history holds it where it was (a lag that reprojection by the
// surface's motion cannot follow).
uniform vec2 u_lobe;
uniform vec4 u_prev_eye;  // previous camera: position (m), w 0; orthographic: backward axis, w 1
// Compiled in only where the cap is on (the reuse's variant: temporal.py), so that the
// other methods' and the talk's STB program go without it: llvmpipe runs an `if`'s body
// in every SIMD stamp, masked, and a loop of 0 trips still cost ~5 % of the pass there.
#ifndef TAA_LOBE_CAP
#define TAA_LOBE_CAP 0
#endif
// Young history (shorter than u_young.x frames: a disocclusion): the display shows,
// with weight u_young.y (tapering to 0 at u_young.x), a Savitzky-Golay estimate
// (quadratic least squares over the 5x5 grid around the pixel, weights u_young_c)
// of this frame's history, from every tap's reprojected previous history blended with
// its current sample -- only where every tap is this pixel's tangent plane (within
// u_young.z pixel footprints per px of offset), now and in the previous frame.
// Display only: the history keeps its own samples.
uniform vec4 u_young;  // length limit (frames), weight, plane tolerance, edge-left cap (frames)
uniform float u_young_c[LIM_TAA_YOUNG_GRID * LIM_TAA_YOUNG_GRID];
// Lights that changed a lot this frame: within a sphere (centre, radius: its
// influence range grown by its move) the history is capped at u_light_caps[i]
// frames (1: dropped: a light switched off is gone from this frame on).
uniform int u_light_changes;
uniform vec4 u_light_spheres[LIM_MAX_LIGHT_CHANGES];
uniform float u_light_caps[LIM_MAX_LIGHT_CHANGES];

layout(location = 0) out vec4 o_color;
layout(location = 1) out vec4 o_history;
layout(location = 2) out vec4 o_geo;

float luma(vec3 c) {
    return dot(c, LUMINANCE_REC709);
}

vec3 history_bilinear_at(vec2 uv) {
    return textureLod(u_history, uv, 0.0).rgb;
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

// This pixel's surface in view space: its point, normal and pixel footprint (m per px
// at its depth), for the tangent-plane tests of neighbourhood_stats and young_estimate.
struct SurfacePlane {
    vec3 p;
    vec3 nv;
    float foot;
};

SurfacePlane surface_plane(float d, vec3 n) {
    return SurfacePlane(view_pos_from_depth(gl_FragCoord.xy, d), mat3(u_view) * n,
                        2.0 * u_tan_off.y * u_resolution.w * (u_cam_pos.w > 0.5 ? 1.0 : d));
}

// Depth-weighted mean and standard deviation of the demodulated lighting over the
// 13 taps (other surfaces do not widen the box).
// Also: `edge`, a 3x3 tap is off this pixel's tangent plane (u_young.z pixel
// footprints per px of offset; sky against surface) and is a 5 % depth step or moves
// against it (motion vectors more than sqrt(u_edge_motion) px apart); `flat_`, no tap
// of the 13 is off the plane.
void neighbourhood_stats(ivec2 ip, ivec2 size, float d, SurfacePlane sp, out vec3 m1,
                         out vec3 sigma, out bool edge, out bool flat_) {
    m1 = vec3(0.0);
    vec3 m2 = vec3(0.0);
    float wsum = 0.0;
    edge = false;
    flat_ = true;
    vec2 mv0 = texelFetch(u_motion, ip, 0).xy;
    for (int i = 0; i < 13; ++i) {
        ivec2 q = clamp(ip + TAPS[i], ivec2(0), size - 1);
        vec4 s = texelFetch(u_demod, q, 0);
        float w = abs(s.a - d) <= 0.05 * max(d, 1e-4) + 1e-6 ? 1.0 : 0.0;
        vec3 pq = view_pos_from_depth(vec2(q) + 0.5, s.a);
        float tol = u_young.z * length(vec2(TAPS[i])) * sp.foot + 1e-4;
        bool on = d > 0.0 ? s.a > 0.0 && abs(dot(sp.nv, pq - sp.p)) <= tol : s.a <= 0.0;
        if (i < 9) {
            // another surface: off the plane and a depth step, or moving against this
            // pixel (an object passing; the jitter moves both sides alike)
            vec2 dm = texelFetch(u_motion, q, 0).xy - mv0;
            edge = edge || (!on && (w == 0.0 || dot(dm, dm) > u_edge_motion));
        }
        flat_ = flat_ && on;
        m1 += w * s.rgb;
        m2 += w * s.rgb * s.rgb;
        wsum += w;
    }
    m1 /= wsum;
    m2 /= wsum;
    sigma = sqrt(max(m2 - m1 * m1, vec3(0.0)));
}

struct Reprojection {
    vec2 pos;       // previous (unjittered) pixel position
    float prev_d;   // this surface's depth in the previous view (m)
    float gamma;    // clip box half extent (std devs)
    float max_len;  // history length cap (frames)
    float cur_w;    // weight of the pixel's own sample against the neighbourhood mean
    float still;    // 1: the surface has not moved (< 0.5 px); 0: moved >= 0.5 px
    vec3 prev_p;    // this surface's point in the previous view space (m)
    vec3 prev_n;    // ... its normal there
};

// Reprojection (unjittered previous pixel position), box size and history cap. A
// pixel whose surface has not moved (< 0.5 px) keeps a longer history and a wider
// box: with a still camera the box only has to catch what the light caps and
// disocclusion miss, and every clip of noisy input is a bias.
Reprojection reproject(ivec2 ip, float d, vec3 n) {
    Reprojection r;
    vec2 mv = texelFetch(u_motion, ip, 0).xy - u_jitter;
    r.pos = gl_FragCoord.xy - mv;
    r.prev_d = d;
    float still = clamp(1.0 - 2.0 * length(mv), 0.0, 1.0);
    r.gamma = mix(u_gamma.x, u_gamma.y, still);
    r.max_len = floor(mix(u_max_len.x, u_max_len.y, still) + 0.5);
    r.cur_w = mix(u_cur_weight, 1.0, still);
    r.still = still;
    r.prev_p = vec3(0.0);
    r.prev_n = vec3(0.0);
    if (d > 0.0) {
        vec3 world = world_pos_from_depth(gl_FragCoord.xy, d);
        r.prev_p = (u_prev_view * vec4(world, 1.0)).xyz;
        r.prev_d = max(-r.prev_p.z, 1e-6);
        r.prev_n = mat3(u_prev_view) * n;
#if TAA_LOBE_CAP
        {
            vec3 v1 = u_prev_eye.w > 0.5 ? normalize(u_prev_eye.xyz) : normalize(u_prev_eye.xyz - world);
            vec3 dv = view_dir(world) - v1;
            float turn = 2.0 * asin(min(0.5 * length(dv), 1.0));  // (acos loses small angles)
            float rough = texelFetch(u_base_rough, ip, 0).a;
            float lobe = u_lobe.x * max(rough * rough, 1e-3) / max(turn, 1e-6);
            r.max_len = min(r.max_len, max(floor(lobe), u_lobe.y));
        }
#endif
        for (int i = 0; i < u_light_changes; ++i) {
            if (distance(world, u_light_spheres[i].xyz) < u_light_spheres[i].w) {
                r.max_len = min(r.max_len, u_light_caps[i]);
            }
        }
    }
    return r;
}

// The history's alpha is its length n (whole frames) + r / LIM_TAA_EDGE_RUN_SCALE: r,
// how many frames in a row (up to u_edge_run.y) the pixel had an edge beside it
// (`edge` of neighbourhood_stats). Rounding a bilinear mix of alphas to whole frames
// ignores r (r / scale < 0.25).
float edge_run(float alpha) {
    return floor((alpha - floor(alpha)) * float(LIM_TAA_EDGE_RUN_SCALE) + 0.5);
}

struct Footprint {
    vec3 bil;        // bilinear-weighted sum of the agreeing texels' history
    float mom2;      // ... of their luma second moments
    float hist_len;  // ... of their history lengths
    float valid_w;   // sum of the agreeing texels' bilinear weights
    int valid_n;     // agreeing texels (4: Catmull-Rom)
    float edge_run;  // most frames in a row an agreeing texel's history had an edge beside it
    bool lent;       // some of it is a neighbour's surface's history (borrow_history: all of it)
};

// How far (m) an old texel's depth may lie from a surface's depth `depth` and still be
// that surface (same_surface, neighbour_surface, may_lend): 3 %.
float depth_tol(float depth) {
    return 0.03 * depth + 1e-4;
}

// Previous texel `g` (depth, oct normal; gn decoded) is this pixel's surface: the
// depth it had in the previous view, not its opposite side (sky: sky).
bool same_surface(vec4 g, vec3 gn, float d, vec3 n, Reprojection r, ivec2 t) {
    if (d <= 0.0) {
        return g.x <= 0.0;
    }
    bool ok = g.x > 0.0 && abs(g.x - r.prev_d) <= depth_tol(r.prev_d) && dot(gn, n) > -0.5;
    if (ok && u_plane_tol > 0.0) {
        // The texel's old point (its pixel centre through the previous view's
        // projection, jitter included) lies on this surface's tangent plane: a face
        // meeting it at a crease (a box standing on the floor) is within 3 % of the
        // floor's depth near the crease, but off its plane.
        vec2 ndc = (vec2(t) + 0.5) * u_resolution.zw * 2.0 - 1.0;
        vec2 xy = ndc * u_prev_tan.xy + u_prev_tan.zw;
        bool ortho = u_cam_pos.w > 0.5;
        vec3 q = ortho ? vec3(xy, -g.x) : vec3(xy * g.x, -g.x);
        float foot = 2.0 * u_prev_tan.y * u_resolution.w * (ortho ? 1.0 : g.x);
        ok = abs(dot(r.prev_n, q - r.prev_p)) <= u_plane_tol * foot + 1e-4;
    }
    return ok;
}

// Does the surface of a 3x3 neighbour whose (unjittered) motion is mvj, seen last
// frame at `texel` (previous pixel position), land beside this pixel now? A jitter
// edge moves with its surfaces (camera, rigid motion: mvj ~ this pixel's motion) and
// does; a moving object's old texels do not -- the floor behind a sliding box took
// the box's history as "an edge the jitter crosses" while the box's trailing side was
// in the 3x3 (issue 31, docs/STB_NOTES.md "(reuse6)").
bool moves_beside(vec2 texel, vec2 mvj) {
    return all(lessThanEqual(abs(texel + mvj - gl_FragCoord.xy), vec2(u_edge_slack)));
}

// Else: is it the surface of a 3x3 neighbour (depth dj moved like this pixel's by
// `shift`, facing the same half-space as nj), seen through another jitter offset at
// an edge? Not a disocclusion. (A normal test of 0.9 reset the pixels of curved rims,
// whose normal turns by more than that between neighbours, every time the jitter
// moved them on or off the rim.)
bool neighbour_surface(vec4 g, vec3 gn, float dj, vec3 nj, float shift) {
    return dj > 0.0 && abs(g.x - (dj + shift)) <= depth_tol(g.x) && dot(gn, nj) > 0.0;
}

// May old texel `g`, a 3x3 neighbour's surface, lend its history to this pixel? Not
// to a moving pixel (u_lent_near 0) when it lay nearer than this pixel's surface did
// in the previous view (beyond same_surface's 3 %): that is a foreground occluder
// whose silhouette moves over this surface (parallax: the chess orbit's back-row
// pieces over the table behind them), and its history kept the occluder's light as a
// trail, the clip box being widened by the history's own temporal spread (issue 31,
// docs/STB_NOTES.md "(taa10)", "(taa11)"). The pixel then borrows its own surface's
// history from beside (borrow_history) or starts again. A still pixel keeps the
// jitter's edges: its history is the edge's antialiasing.
bool may_lend(vec4 g, Reprojection r) {
    bool nearer = g.x < r.prev_d - depth_tol(r.prev_d);
    return !nearer || r.still >= 0.5 || u_lent_near > 0.5;
}

// Disocclusion over the 4 texels of the bilinear footprint and the bilinear sums of
// the agreeing ones. Each 3x3 neighbour's depth and normal is fetched once, and only
// while a footprint texel still needs it (edge pixels).
Footprint footprint_history(ivec2 ip, ivec2 size, float d, vec3 n, Reprojection r) {
    ivec2 base = ivec2(floor(r.pos - 0.5));
    vec2 f = r.pos - 0.5 - floor(r.pos - 0.5);
    vec4 g[4];
    vec3 gn[4];
    bool inside[4];
    bool same[4];
    bool open = false;  // some texel may still be a neighbour's surface
    bool lent = false;
    for (int k = 0; k < 4; ++k) {
        ivec2 t = base + ivec2(k & 1, k >> 1);
        inside[k] = all(greaterThanEqual(t, ivec2(0))) && all(lessThan(t, size));
        g[k] = inside[k] ? texelFetch(u_prev_geo, t, 0) : vec4(0.0);
        gn[k] = oct_decode(g[k].yz);
        same[k] = inside[k] && same_surface(g[k], gn[k], d, n, r, t);
        open = open || (inside[k] && !same[k] && d > 0.0 && g[k].x > 0.0);
    }
    float shift = r.prev_d - d;  // this surface's depth change, applied to its neighbours
    for (int j = 1; j < 9 && open; ++j) {
        ivec2 q = clamp(ip + TAPS[j], ivec2(0), size - 1);
        float dj = texelFetch(u_demod, q, 0).a;
        vec3 nj = oct_decode(texelFetch(u_normal, q, 0).xy);
        vec2 mvj = texelFetch(u_motion, q, 0).xy - u_jitter;
        open = false;
        for (int k = 0; k < 4; ++k) {
            if (inside[k] && !same[k] && d > 0.0 && g[k].x > 0.0) {
                vec2 texel = vec2(base + ivec2(k & 1, k >> 1)) + 0.5;
                same[k] = moves_beside(texel, mvj) && neighbour_surface(g[k], gn[k], dj, nj, shift)
                          && may_lend(g[k], r);
                lent = lent || same[k];
                open = open || !same[k];
            }
        }
    }
    Footprint fp = Footprint(vec3(0.0), 0.0, 0.0, 0.0, 0, 0.0, lent);
    for (int k = 0; k < 4; ++k) {
        if (!same[k]) continue;
        vec4 h = texelFetch(u_history, base + ivec2(k & 1, k >> 1), 0);
        float w = (k & 1) == 1 ? f.x : 1.0 - f.x;
        w *= (k >> 1) == 1 ? f.y : 1.0 - f.y;
        fp.bil += w * h.rgb;
        fp.mom2 += w * g[k].w;
        // (texels the bilinear footprint weighs little belong to the next pixel)
        if (w > 0.25) fp.edge_run = max(fp.edge_run, edge_run(h.a));
        fp.valid_w += w;
        fp.valid_n += 1;
        fp.hist_len += w * h.a;
    }
    return fp;
}

// History borrowing: nothing of the footprint is this surface, but what the texel
// under the pixel saw last frame is still beside it -- an edge the jitter moves
// across (a 1 px post, a silhouette against the sky, a curved rim), not a
// disocclusion (floor uncovered by a moving box: the box is gone from the
// neighbourhood). Then the history of the 3x3 texel around the reprojected position
// that saw this surface last frame (nearest depth, same side) stands in, instead of
// starting again from one frame's noise. Only such pixels pay for the search.
Footprint borrow_history(ivec2 ip, ivec2 size, float d, vec3 n, Reprojection r) {
    Footprint fp = Footprint(vec3(0.0), 0.0, 0.0, 0.0, 0, 0.0, true);
    ivec2 c0 = ivec2(floor(r.pos));
    if (any(lessThan(c0, ivec2(0))) || any(greaterThanEqual(c0, size))) return fp;
    float g0 = texelFetch(u_prev_geo, c0, 0).x;
    float shift = r.prev_d - d;
    bool edge = false;
    for (int j = 1; j < 9 && !edge; ++j) {
        ivec2 q = clamp(ip + TAPS[j], ivec2(0), size - 1);
        float dj = texelFetch(u_demod, q, 0).a;
        edge = g0 <= 0.0 ? dj <= 0.0 : dj > 0.0 && abs(g0 - (dj + shift)) <= 0.05 * g0 + 1e-4;
        edge = edge && moves_beside(vec2(c0) + 0.5, texelFetch(u_motion, q, 0).xy - u_jitter);
    }
    if (!edge) return fp;
    float best = 1e30;
    for (int j = 1; j < 9; ++j) {
        ivec2 t = c0 + TAPS[j];
        if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, size))) continue;
        vec4 g = texelFetch(u_prev_geo, t, 0);
        float err = 0.0;
        if (d <= 0.0) {
            if (g.x > 0.0) continue;
        } else {
            err = abs(g.x - r.prev_d);
            if (!(g.x > 0.0) || err > 0.05 * r.prev_d + 1e-4 || dot(oct_decode(g.yz), n) < 0.5) {
                continue;
            }
        }
        if (err >= best) continue;
        best = err;
        vec4 h = texelFetch(u_history, t, 0);
        fp = Footprint(h.rgb, g.w, h.a, 1.0, 1, edge_run(h.a), true);
    }
    return fp;
}

// A young pixel's (history `len` frames < u_young.x, not capped by a light change)
// Savitzky-Golay estimate of its new history from the 5x5 grid around it (weights
// u_young_c, row-major: the centre value of a least-squares quadratic through the
// grid). Each tap's value is its previous history (bilinear, at the pixel's
// reprojected position + the tap's offset) blended 1/(n+1) with its current sample
// (taa's blend without the clip); the centre tap is this pixel's own new history
// `own`. Only where every tap is this pixel's tangent plane now (the 13 taps of the
// neighbourhood: `flat_`; the 12 others tested here) and, for its history, in the
// previous view; otherwise (an edge, a history texel of another surface) there is no
// estimate (a = 0). A quadratic keeps a smooth gradient of the lighting (a light's
// hot spot) that a plain mean blurs. A loop whose trip count is 0 for other pixels:
// llvmpipe skips a loop in a SIMD stamp none of whose pixels needs it (not an `if`:
// docs/STB_NOTES.md "(reuse5)"), so only stamps holding a young pixel on a flat
// neighbourhood pay (not the edges a moving camera uncovers).
vec4 young_estimate(ivec2 ip, ivec2 size, float d, SurfacePlane sp, bool flat_, Reprojection r,
                    vec3 own, float len) {
    bool young = flat_ && d > 0.0 && len < u_young.x && r.max_len >= u_young.x && u_reset < 0.5;
    const int YG = LIM_TAA_YOUNG_GRID, YR = LIM_TAA_YOUNG_GRID / 2;
    int taps = young ? YG * YG : 0;
    bool ortho = u_cam_pos.w > 0.5;
    float prev_foot = 2.0 * u_prev_tan.y * u_resolution.w;
    vec3 sum = vec3(0.0);
    bool ok = young;
    for (int i = 0; i < taps; ++i) {
        ivec2 o = ivec2(i % YG - YR, i / YG - YR);
        if (i == YG * YG / 2) {
            sum += u_young_c[i] * own;
            continue;
        }
        ivec2 q = ip + o;
        vec2 pp = r.pos + vec2(o);
        ivec2 t = ivec2(floor(pp));
        if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, size))
            || any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, size))) {
            ok = false;
            break;
        }
        float lo = length(vec2(o));
        vec4 s = texelFetch(u_demod, q, 0);
        // the 13-tap neighbourhood is on the plane (flat_); the others: tested
        bool inner = abs(o.x) + abs(o.y) <= 2 && (o.x == 0 || o.y == 0 || abs(o.x) == 1);
        vec3 pq = view_pos_from_depth(vec2(q) + 0.5, s.a);
        bool on = inner
                  || (s.a > 0.0 && abs(dot(sp.nv, pq - sp.p)) <= u_young.z * lo * sp.foot + 1e-4);
        // the tap's history texel: its old point on this surface's plane in the previous view
        float gd = texelFetch(u_prev_geo, t, 0).x;
        vec2 xy = ((vec2(t) + 0.5) * u_resolution.zw * 2.0 - 1.0) * u_prev_tan.xy + u_prev_tan.zw;
        vec3 pg = ortho ? vec3(xy, -gd) : vec3(xy * gd, -gd);
        float tol = u_young.z * lo * prev_foot * (ortho ? 1.0 : gd) + 1e-4;
        if (!on || !(gd > 0.0) || abs(dot(r.prev_n, pg - r.prev_p)) > tol) {
            ok = false;
            break;
        }
        vec4 h = textureLod(u_history, pp * u_resolution.zw, 0.0);
        sum += u_young_c[i] * mix(h.rgb, s.rgb, 1.0 / (floor(h.a) + 1.0));
    }
    return ok ? vec4(max(sum, vec3(0.0)), 1.0) : vec4(0.0);
}

// The new sample blended into the history: the neighbourhood mean instead of the
// pixel's own noisy sample for a short history (disoccluded, or capped by a light
// change: full weight at n = 1, none from n = 5 on), and for a moving pixel always
// in part (r.cur_w: the innovation each frame adds is then the 13-tap mean's noise,
// not one pixel's, so the image flickers less while the camera moves; a still pixel
// keeps its own samples and converges to its own value). Returns the demodulated
// result and its history length; tm2: the luma second moment to keep.
vec4 blend(vec3 cur, vec3 m1, vec3 sigma, Reprojection r, Footprint fp, out float tm2) {
    vec3 result = m1;
    float len = 1.0;
    float lc = luma(cur);
    tm2 = lc * lc;
    if (u_reset < 0.5 && fp.valid_n > 0 && fp.valid_w > 1e-4) {
        vec3 h = fp.valid_n == 4 ? history_catmull_rom(r.pos) : fp.bil / fp.valid_w;
        // The box: spatial spread, widened to the pixel's own temporal spread
        // (STB picks lights per tile, so neighbours share a frame's misses and
        // the spatial spread alone underestimates the noise: clipping to it
        // pulled converged history back to one frame's noise).
        float mom2 = fp.mom2 / fp.valid_w;
        float lh = luma(h);
        float var_t = max(mom2 - lh * lh, 0.0);
        // A history lent by a neighbour's surface (an edge the jitter crosses, or
        // borrow_history's): its spread is partly the neighbour's and that between the
        // two surfaces, not this surface's noise; a moving pixel takes only
        // u_lent_spread of it (by how far it moved), in the box and in the moment
        // kept. Lit by the reuse only (temporal.py LENT_SPREAD_MOVING); 1 (STB
        // defaults, others): this branch never runs, images unchanged.
        bool cut = fp.lent && u_lent_spread < 1.0 && r.still < 1.0;
        if (cut) var_t *= mix(u_lent_spread, 1.0, r.still);
        float sigma_t = sqrt(var_t);
        vec3 ext = r.gamma * max(sigma, vec3(sigma_t)) + 1e-3 * m1;
        h = clip_towards_mean(m1, ext, h);
        if (cut) mom2 = luma(h) * luma(h) + var_t;
        len = min(floor(fp.hist_len / fp.valid_w + 0.5) + 1.0, r.max_len);
        result = mix(h, mix(m1, cur, clamp((len - 1.0) / 4.0, 0.0, r.cur_w)), 1.0 / len);
        tm2 = mix(mom2, tm2, 1.0 / len);
    }
    return vec4(result, len);
}

void main() {
    ivec2 ip = ivec2(gl_FragCoord.xy);
    ivec2 size = ivec2(u_resolution.xy);
    vec4 centre = texelFetch(u_demod, ip, 0);
    float d = centre.a;
    vec2 enc = texelFetch(u_normal, ip, 0).xy;
    vec3 m1, sigma;
    vec3 n = oct_decode(enc);
    bool edge, flat_;
    SurfacePlane sp = surface_plane(d, n);
    neighbourhood_stats(ip, size, d, sp, m1, sigma, edge, flat_);
    Reprojection r = reproject(ip, d, n);
    Footprint fp = footprint_history(ip, size, d, n, r);
    if (fp.valid_n == 0 && u_reset < 0.5) fp = borrow_history(ip, size, d, n, r);
    // History taken beside an edge (a 3x3 neighbour of another surface) for at least
    // u_edge_run.x frames in a row, whose whole 13-tap neighbourhood is now one plane:
    // the edge left by more than the jitter moves it (an object moved away; a still or
    // rigidly moving scene keeps its edges beside their pixels), and the history mixes
    // the two surfaces: capped. The run keeps out thin features (a post narrower than
    // a pixel) that the jitter shows in some frames and not others: their pixels'
    // history is their antialiasing.
    if (fp.edge_run >= u_edge_run.x && flat_) r.max_len = min(r.max_len, u_young.w);
    float tm2;
    vec4 hist = blend(centre.rgb, m1, sigma, r, fp, tm2);
    float run = edge && fp.valid_n > 0 && u_reset < 0.5 ? min(fp.edge_run + 1.0, u_edge_run.y) : float(edge);
    o_history = vec4(hist.rgb, hist.a + run / float(LIM_TAA_EDGE_RUN_SCALE));
    // A young history shows less of its own noise: its neighbourhood's quadratic
    // estimate weighs in by u_young.y, tapering linearly to nothing at u_young.x frames.
    vec3 shown = hist.rgb;
    vec4 ye = young_estimate(ip, size, d, sp, flat_, r, hist.rgb, hist.a);
    if (ye.a > 0.0) {
        float taper = clamp(1.0 - (hist.a - 1.0) / max(u_young.x - 1.0, 1.0), 0.0, 1.0);
        shown = mix(hist.rgb, ye.rgb, u_young.y * taper);
    }
    vec4 alb = texelFetch(u_albedo, ip, 0);
    o_color = vec4(shown * alb.rgb, alb.a);
    o_geo = vec4(d, enc, tm2);
}
