// Debug AOV "reuse_light" (STB with -o reuse=on): each pixel coloured by a hash of the
// light its stored reservoir holds after this frame's reuse (the sample it was shaded
// with and hands to the next frame); black where the reservoir is empty.
#include "common/frame.glsl"
#include "common/reservoir.glsl"
#include "common/debug_colors.glsl"

uniform usampler2D u_reuse_res;  // this frame's stored reservoirs (reservoir_pack)

layout(location = 0) out vec4 o_color;

void main() {
    Reservoir r = reservoir_unpack(texelFetch(u_reuse_res, ivec2(gl_FragCoord.xy), 0));
    o_color = vec4(r.y == LIM_EMPTY_LIGHT_INDEX ? vec3(0.0) : light_color(r.y), 1.0);
}
