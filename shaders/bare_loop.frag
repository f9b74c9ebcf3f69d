// The bare light loop (`--lighting bare`): a yardstick, not a lighting method to look
// at. Every FoV light of the same light buffer as a point light, unshadowed: position,
// colour x intensity (cd), Lambert, inverse square, the range window -- the least a
// correct per-pixel loop over the lights can do; run it beside another method in one
// `stb bench` to read that method's cost as a ratio to it (issue 34). Scene-linear
// radiance (nits).
#include "common/gbuffer.glsl"
#include "common/lights.glsl"
#include "common/lighting_out.glsl"

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    Surface s;
    if (!read_surface(px, s)) {
        write_background(px);
        return;
    }
    vec3 E = vec3(0.0);  // illuminance (lux)
    uint n = u_counts.x;
    for (uint i = 0u; i < n; ++i) {
        vec4 pr = lights[i].pos_range;
        vec3 d = pr.xyz - s.P;
        float d2 = dot(d, d);
        if (d2 >= pr.w * pr.w) continue;
        float dist = sqrt(d2);
        float ndl = max(dot(s.N, d) / max(dist, 1e-12), 0.0);
        float r = max(dist, LIM_MIN_LIGHT_DISTANCE);
        E += lights[i].intensity.rgb * (ndl * range_window(dist, pr.w) / (r * r));
    }
    write_lighting(px, s, s.diffuse * (1.0 / PI) * E);
}
