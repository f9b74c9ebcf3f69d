// Debug AOV "smalltile": each pixel coloured by a hash of a light index held by
// its small tile (found through the interleaved quad LUT, as the lighting pass
// does): a 2x2 mosaic over each quad, the quad's pixel k showing sample
// k mod STB_N (so N = 1 shows sample 0 everywhere). Empty samples are black.
#include "common/frame.glsl"
#include "common/packing.glsl"
#include "common/debug_colors.glsl"
#include "common/tiles.glsl"

uniform usampler2D u_smalltile;  // rgba32ui small-tile samples

layout(location = 0) out vec4 o_color;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    ivec2 st;
    int slot;
    quad_owner(px, st, slot);
    uvec4 smp = texelFetch(u_smalltile, st, 0);
    int j = ((px.x & 1) | ((px.y & 1) << 1)) % STB_N;
    uint li = sample_index(smp[j]);
    vec3 c = li == LIM_EMPTY_LIGHT_INDEX ? vec3(0.0) : light_color(li);
    o_color = vec4(c, 1.0);
}
