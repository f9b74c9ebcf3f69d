// Debug AOV "reuse_m" (STB with -o reuse=on): the confidence M of each pixel's stored
// reservoir after this frame's temporal and spatial reuse (candidates' worth: 1 = the
// pixel's own candidates only), on a log2 heat ramp from 1 to LIM_REUSE_DEBUG_M_MAX;
// black where M = 0 (no surface, or nothing was found).
#include "common/frame.glsl"
#include "common/reservoir.glsl"
#include "common/debug_colors.glsl"

uniform usampler2D u_reuse_res;  // this frame's stored reservoirs (reservoir_pack)

layout(location = 0) out vec4 o_color;

void main() {
    Reservoir r = reservoir_unpack(texelFetch(u_reuse_res, ivec2(gl_FragCoord.xy), 0));
    float t = log2(max(r.M, 1.0)) / log2(LIM_REUSE_DEBUG_M_MAX);
    o_color = vec4(r.M > 0.0 ? heat_ramp(t) : vec3(0.0), 1.0);
}
