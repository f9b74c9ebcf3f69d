// Direct lighting for the exact methods: `reference` (every FoV light per pixel,
// LOCAL_LIGHTS) and `sun` (sun + ambient only). Scene-linear radiance (nits).
#include "common/gbuffer.glsl"
#include "common/sun.glsl"
#ifdef LOCAL_LIGHTS
#include "common/lights.glsl"
#include "common/shadow.glsl"
#endif

#include "common/lighting_out.glsl"

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    Surface s;
    vec3 emission = texelFetch(g_emission, px, 0).rgb;
    if (!read_surface(px, s)) {
        write_background(px);
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
    write_lighting(px, s, c);
}
