// Debug AOV "reuse_reject" (STB with -o reuse=on): what the temporal reuse did at each
// pixel this frame. Green: last frame's reservoir of the same surface was combined;
// red: it was rejected (disocclusion: depth / normal / roughness mismatch, the surface
// was off screen, or a light that changed there dropped the history); blue: no history
// this frame (first frame, reset, or temporal reuse off); black: background.
#include "common/frame.glsl"
#include "common/reservoir.glsl"

uniform usampler2D u_reuse_cur;  // this frame's reservoirs after temporal reuse
uniform int u_history;           // 1: the temporal pass had a history this frame

layout(location = 0) out vec4 o_color;

void main() {
    // Background pixels leave the temporal pass with an empty reservoir (M = 0); every
    // surface pixel has M >= 1 (its own candidates) plus the history's M if it took it.
    Reservoir r = reservoir_unpack(texelFetch(u_reuse_cur, ivec2(gl_FragCoord.xy), 0));
    vec3 c = r.M <= 0.0      ? vec3(0.0)
           : u_history == 0 ? vec3(0.15, 0.3, 1.0)
           : r.M > 1.0     ? vec3(0.1, 0.85, 0.2)
                           : vec3(1.0, 0.1, 0.1);
    o_color = vec4(c, 1.0);
}
