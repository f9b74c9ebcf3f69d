// The reference's textured dome (issue 37; renderer/dome_shadows.py): this frame's
// importance-sampled directions, each a distant light of illuminance E_k =
// radiance / (n pdf) (lux) with its own orthographic shadow map, tiled in one depth
// atlas. Averaged over accumulated frames it converges to the dome's shadowed light.
#ifndef STB_DOME_SAMPLED_GLSL
#define STB_DOME_SAMPLED_GLSL
#include "common/brdf.glsl"
#include "common/dome.glsl"

uniform sampler2DShadow u_dome_shadow;        // depth atlas, u_dome_tiles.x x .y tiles
uniform mat4 u_dome_vp[LIM_DOME_SAMPLES];     // world -> tile clip
uniform vec4 u_dome_dir[LIM_DOME_SAMPLES];    // xyz unit direction to the sample, w normal bias (m)
uniform vec4 u_dome_illum[LIM_DOME_SAMPLES];  // rgb illuminance (lux), w depth bias
uniform vec4 u_dome_tiles;                    // columns, rows, sample count

// Visibility of sample k at P (normal N): one hardware 2x2 compare in its tile, the
// point pushed along N by the normal bias grown with the slope tan(N, L) (grazing
// samples see a steep depth gradient across one texel).
float dome_sample_visibility(int k, vec3 P, vec3 N, float NoL) {
    float slope = min(sqrt(max(1.0 - NoL * NoL, 0.0)) / max(NoL, 1e-3), 8.0);
    vec4 c = u_dome_vp[k] * vec4(P + N * (u_dome_dir[k].w * (1.0 + slope)), 1.0);
    vec3 q = c.xyz / c.w * 0.5 + 0.5;
    if (any(lessThan(q.xy, vec2(0.0))) || any(greaterThan(q.xy, vec2(1.0))) || q.z > 1.0) {
        return 1.0;
    }
    vec2 tile = vec2(float(k % int(u_dome_tiles.x)), float(k / int(u_dome_tiles.x)));
    vec2 texel = 1.0 / vec2(textureSize(u_dome_shadow, 0));
    vec2 uv = (tile + clamp(q.xy, texel * u_dome_tiles.xy, 1.0 - texel * u_dome_tiles.xy))
        / u_dome_tiles.xy;
    return texture(u_dome_shadow, vec3(uv, q.z - u_dome_illum[k].w));
}

// Reflected radiance (nits) of the sampled dome at surface s.
vec3 dome_sampled(Surface s) {
    vec3 c = vec3(0.0);
    int n = int(u_dome_tiles.z);
    for (int k = 0; k < n; ++k) {
        vec3 L = u_dome_dir[k].xyz;
        float NoL = dot(L, s.N);
        if (NoL <= 0.0) continue;
        vec3 d, sp;
        brdf_eval(s, L, d, sp);
        float v = dome_sample_visibility(k, s.P, s.N, NoL);
        c += (d * u_dome_mult.x + sp * u_dome_mult.y) * u_dome_illum[k].rgb * v;
    }
    return c;
}
#endif
