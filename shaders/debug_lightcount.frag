// Debug AOV "lightcount": number of FoV lights whose influence sphere (range)
// contains the pixel's world position; 0 on background. Brute force over the
// light buffer (a debug view: O(pixels x FoV lights)). r32f output.
#include "common/gbuffer.glsl"
#include "common/lights.glsl"

layout(location = 0) out float o_count;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    float depth = texelFetch(g_depth, px, 0).r;
    if (depth <= 0.0) { o_count = 0.0; return; }
    vec3 P = world_pos_from_depth(vec2(px) + 0.5, depth);
    uint n = u_counts.x;
    uint count = 0u;
    for (uint i = 0u; i < n; ++i) {
        vec3 d = lights[i].pos_range.xyz - P;
        float r = lights[i].pos_range.w;
        if (dot(d, d) < r * r) count++;
    }
    o_count = float(count);
}
