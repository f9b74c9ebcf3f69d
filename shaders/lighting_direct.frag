// Direct lighting for the exact methods: `reference` (every FoV light per pixel,
// LOCAL_LIGHTS) and `sun` (sun + ambient only). Scene-linear radiance (nits).
#include "common/gbuffer.glsl"
#include "common/sun.glsl"
#ifdef LOCAL_LIGHTS
#include "common/lights.glsl"
#include "common/shadow.glsl"
#endif

layout(location = 0) out vec4 o_color;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    Surface s;
    vec3 emission = texelFetch(g_emission, px, 0).rgb;
    if (!read_surface(px, s)) {
        // Background: the dome seen directly (alpha 1), else transparent black.
        o_color = u_ambient.r + u_ambient.g + u_ambient.b > 0.0
            ? vec4(sanitize_radiance(u_ambient.rgb * u_clip.w), 1.0) : vec4(0.0);
        return;
    }
    vec3 c = sun_and_ambient(s);
#ifdef LOCAL_LIGHTS
    uint n = u_counts.x;
    for (uint i = 0u; i < n; ++i) {
        c += light_radiance(lights[i], s);
    }
#endif
    c += emission;
    o_color = vec4(sanitize_radiance(c * u_clip.w), 1.0);
}
