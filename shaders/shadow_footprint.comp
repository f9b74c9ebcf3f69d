// Shadow-map footprint (issue 33 item 5; tasks/shadow_footprint.py): per measured
// shadowed light, the largest map side any G-buffer receiver asks for, in texels per
// (texel per screen pixel). A receiver P at view depth D, distance l from the light,
// needs texels of l * w / side metres (w: the map's angular span per side) no wider
// than a pixel, D * 2 tan(fov_y / 2) / H metres: side = H w l / (2 D tan(fov_y / 2)),
// times the receiver's slope factor cos(view) / cos(light) (a texel stretches by
// 1 / cos(light) along the surface, which the camera sees shortened by cos(view):
// Stamminger and Drettakis 2002's projective aliasing), at most u_slope_max,
// times its weight: the light's share of P's unshadowed illuminance (measured
// lights + sun + dome) over u_share_full, clamped to 1; receivers where the light's
// display-relative diffuse radiance is below u_display_min ask nothing. Reduced with
// atomicMax on the float bits (order-preserving for floats >= 0), and counted in a
// histogram of LIM_FOOTPRINT_BINS half-octave bins of log2(side) per light (for a
// percentile; bin b holds sides in [2^(b/2), 2^((b+1)/2)), the first and last open).
#include "common/gbuffer.glsl"
#include "common/lights.glsl"
layout(local_size_x = 8, local_size_y = 8) in;

// x: FoV light index, y: the map's angular span per side w (2 tan(half angle) for a
// spot, sqrt(4 pi) for an octahedral omni map).
layout(std430, binding = SSBO_FOOTPRINT_LIGHTS) readonly buffer FootprintLights {
    vec4 fp_lights[];
};
// fp_need[i]: the maximum (float bits); fp_need[LIM_FOOTPRINT_LIGHTS + i * bins + b]: counts.
layout(std430, binding = SSBO_FOOTPRINT_OUT) buffer FootprintOut { uint fp_need[]; };

uniform uint u_count;          // measured lights (<= LIM_FOOTPRINT_LIGHTS)
uniform int u_stride;          // every u_stride-th pixel in x and y
uniform float u_share_full;    // share of the illuminance that asks the full density
uniform float u_display_min;   // display-relative radiance below which nothing is asked
uniform float u_slope_max;     // cap of the slope factor cos(view) / cos(light)

shared uint s_need[LIM_FOOTPRINT_LIGHTS];
shared uint s_hist[LIM_FOOTPRINT_LIGHTS * LIM_FOOTPRINT_BINS];

void main() {
    uint lid = gl_LocalInvocationIndex;
    for (uint i = lid; i < u_count; i += 64u) s_need[i] = 0u;
    for (uint i = lid; i < u_count * uint(LIM_FOOTPRINT_BINS); i += 64u) s_hist[i] = 0u;
    barrier();
    ivec2 px = ivec2(gl_GlobalInvocationID.xy) * u_stride;
    ivec2 size = ivec2(u_resolution.xy);
    vec3 P, N;
    if (px.x < size.x && px.y < size.y && read_geometry(px, P, N)) {
        float depth = texelFetch(g_depth, px, 0).r;
        // pixel footprint (m) at the receiver
        float pixel_m = 2.0 * u_tan_off.y * u_resolution.w;
        if (u_cam_pos.w < 0.5) pixel_m *= depth;
        float cos_v = max(dot(N, view_dir(P)), 0.0);
        float e_rest = dot(u_ambient.rgb, LUMINANCE_REC709) * PI;
        if (u_sun_dir.w > 0.5) {
            e_rest += dot(u_sun_illum.rgb, LUMINANCE_REC709) * max(dot(N, u_sun_dir.xyz), 0.0);
        }
        float e_sum = e_rest;
        for (uint i = 0u; i < u_count; ++i) {
            vec3 Ldir;
            float dist;
            vec3 e = light_illuminance(lights[uint(fp_lights[i].x)], P, Ldir, dist);
            e_sum += dot(e, LUMINANCE_REC709) * max(dot(N, Ldir), 0.0);
        }
        for (uint i = 0u; i < u_count; ++i) {
            vec3 Ldir;
            float dist;
            vec4 fl = fp_lights[i];
            vec3 e = light_illuminance(lights[uint(fl.x)], P, Ldir, dist);
            float cos_l = max(dot(N, Ldir), 0.0);
            float ei = dot(e, LUMINANCE_REC709) * cos_l;
            if (ei * u_clip.w / PI < u_display_min) continue;
            float weight = min(ei / max(e_sum * u_share_full, 1e-30), 1.0);
            float slope = min(cos_v, u_slope_max * cos_l) / cos_l;
            float need = weight * slope * fl.y * dist / pixel_m;
            atomicMax(s_need[i], floatBitsToUint(need));
            int b = clamp(int(floor(2.0 * log2(max(need, 1e-30)))), 0, LIM_FOOTPRINT_BINS - 1);
            atomicAdd(s_hist[i * uint(LIM_FOOTPRINT_BINS) + uint(b)], 1u);
        }
    }
    barrier();
    for (uint i = lid; i < u_count; i += 64u) {
        if (s_need[i] > 0u) atomicMax(fp_need[i], s_need[i]);
    }
    for (uint i = lid; i < u_count * uint(LIM_FOOTPRINT_BINS); i += 64u) {
        if (s_hist[i] > 0u) atomicAdd(fp_need[LIM_FOOTPRINT_LIGHTS + i], s_hist[i]);
    }
}
