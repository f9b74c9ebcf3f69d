// Debug AOV "reuse_reject" (STB with -o reuse=on): what the temporal reuse did at each
// pixel this frame. Green: last frame's reservoir of the same surface was combined;
// red: it was rejected (disocclusion: depth / normal / roughness mismatch, the surface
// was off screen, or a light that changed there dropped the history); blue: no history
// this frame (first frame, reset, or temporal reuse off); black: background.
#include "common/frame.glsl"
#include "common/reservoir.glsl"

uniform usampler2D u_reuse_cur;  // this frame's reservoirs after temporal reuse
uniform usampler2D u_reuse_res;  // this frame's stored reservoirs (M = 0: background)
uniform int u_history;           // 1: the temporal pass had a history this frame
uniform int u_cur_shift;         // 1: u_reuse_cur holds one reservoir per 2x2 quad

layout(location = 0) out vec4 o_color;

void main() {
    // Background pixels are stored as empty reservoirs (M = 0). Without a history the
    // temporal pass may not run at all (per-pixel candidates, nothing reused): blue.
    // Otherwise every surface pixel left it with M >= 1 (its own candidates) plus the
    // history's M if it took it.
    ivec2 px = ivec2(gl_FragCoord.xy);
    Reservoir stored = reservoir_unpack(texelFetch(u_reuse_res, px, 0));
    Reservoir r = reservoir_unpack(texelFetch(u_reuse_cur, px >> u_cur_shift, 0));
    vec3 c = stored.M <= 0.0 ? vec3(0.0)
           : u_history == 0 ? vec3(0.15, 0.3, 1.0)
           : r.M > 1.0     ? vec3(0.1, 0.85, 0.2)
                           : vec3(1.0, 0.1, 0.1);
    o_color = vec4(c, 1.0);
}
