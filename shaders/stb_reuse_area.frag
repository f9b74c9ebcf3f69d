// STB reuse (issue 31), fused shading pass, part 2 (common/reuse_area.glsl): the picks
// that need light_reflect's area path, one fragment per listed pixel. Drawn over a
// viewport u_list_width wide and just tall enough for the list: fragment (x, y) shades
// list entry y x u_list_width + x, so every 4x2 stamp is eight listed pixels (dense
// SIMD groups, instead of the first pass's stamps where one area pick made all eight
// lanes run the area path). A fragment pass rather than a compute one: llvmpipe runs
// this code about 2x slower as a compute shader (measured, docs/STB_NOTES.md). Per
// pixel exactly stb_reuse_shade.frag's shading of its pick: the stored sun + ambient
// radiance, + light_reflect x term x W, + emission, written by image stores as
// common/lighting_out.glsl's write_lighting (not used with RECT_EMITTERS_SEEN).
uniform int u_list_width;

// The list entry of this fragment.
uint reuse_area_entry() {
    ivec2 f = ivec2(gl_FragCoord.xy);
    return uint(f.y) * uint(u_list_width) + uint(f.x);
}

// The listed pixel: common/shadow.glsl's per-pixel hashes are that pixel's (a macro
// named gl_FragCoord would use a reserved name, GLSL 4.30 sections 3.3 and 3.7).
ivec2 g_px = ivec2(0);
#define SHADOW_PIXEL (vec2(g_px) + 0.5)

#include "common/gbuffer.glsl"
#include "common/lights.glsl"
#define AREA_SHADOW_POINTS LIM_AREA_SHADOW_POINTS_STB
#define AREA_SHADOW_PER_FRAME
#include "common/shadow.glsl"
#include "common/reservoir.glsl"
#include "common/reuse_area.glsl"
#ifdef TAA_DEMOD_OUT
#include "common/demodulation.glsl"
#endif

uniform int u_vis_reuse;  // 1: store shadowed picks as empty reservoirs

layout(rgba32ui, binding = IMAGE_UNIT_REUSE_RESERVOIR) uniform uimage2D u_hist_res;
layout(rgba32f, binding = IMAGE_UNIT_REUSE_PARTIAL) readonly uniform image2D u_partial;
layout(rgba16f, binding = IMAGE_UNIT_REUSE_OUT_COLOR) writeonly uniform image2D u_out_color;
#ifdef TAA_DEMOD_OUT
layout(rgba32f, binding = IMAGE_UNIT_REUSE_OUT_DEMOD) writeonly uniform image2D u_out_demod;
layout(rgba32f, binding = IMAGE_UNIT_REUSE_OUT_ALBEDO) writeonly uniform image2D u_out_albedo;
#endif

void main() {
    uint i = reuse_area_entry();
    if (i >= reuse_area_count) return;
    uint code = reuse_area_px[i];
    g_px = ivec2(int(code & 0xffffu), int(code >> 16));
    Surface s;
    read_surface(g_px, s);  // a surface pixel: the first pass listed it
    Reservoir fin = reservoir_unpack(imageLoad(u_hist_res, g_px));
    vec3 c = imageLoad(u_partial, g_px).rgb;
    Light L = lights[fin.y];
    vec3 Ldir, d, sp;
    float term = 0.0;
    if (light_reflect(L, s, Ldir, d, sp)) {
        term = reuse_term(L, s.P, s.N);
        c += (d * L.misc.z + sp * L.misc.w) * term * fin.W;
    }
    if (u_vis_reuse == 1 && term <= 0.0) {
        fin.W = 0.0;
        fin.y = LIM_EMPTY_LIGHT_INDEX;
        fin.p = 0.0;
        imageStore(u_hist_res, g_px, reservoir_pack(fin));
    }
    c += surface_emission(g_px);
    vec4 color = vec4(sanitize_radiance(c * u_clip.w), 1.0);
    imageStore(u_out_color, g_px, color);
#ifdef TAA_DEMOD_OUT
    vec3 alb = demod_albedo_of(s.diffuse, s.f0);
    imageStore(u_out_demod, g_px, vec4(color.rgb / alb, texelFetch(g_depth, g_px, 0).r));
    imageStore(u_out_albedo, g_px, vec4(alb, color.a));
#endif
}
