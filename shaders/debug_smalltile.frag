// Debug AOV "smalltile": each pixel coloured by a hash of a light index held by
// its small tile (found through the interleaved quad LUT, as the lighting pass
// does): a 2x2 mosaic over each quad, the quad's pixel k showing sample
// k mod STB_N (so N = 1 shows sample 0 everywhere). Empty samples are black.
#include "common/frame.glsl"
#include "common/packing.glsl"
#include "common/tiles.glsl"

uniform usampler2D u_smalltile;  // rgba32ui small-tile samples

layout(location = 0) out vec4 o_color;

// Hash colour of a light index (numpy twin: render/tasks/aov_output.hash_colors).
vec3 light_color(uint i) {
    uint h = i * 747796405u + 2891336453u;
    h = ((h >> ((h >> 28u) + 4u)) ^ h) * 277803737u;
    h = (h >> 22u) ^ h;
    float hue = float(h & 1023u) / 1024.0;
    vec3 c = clamp(abs(fract(hue + vec3(0.0, 2.0 / 3.0, 1.0 / 3.0)) * 6.0 - 3.0) - 1.0, 0.0, 1.0);
    float v = 0.55 + 0.45 * float((h >> 10u) & 255u) / 255.0;
    return mix(vec3(1.0), c, 0.85) * v;
}

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
