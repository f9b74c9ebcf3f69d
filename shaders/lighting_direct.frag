// Direct lighting for the exact methods: `reference` (every FoV light per pixel,
// LOCAL_LIGHTS) and `sun` (sun + ambient only). Scene-linear radiance (nits).
#include "common/gbuffer.glsl"
#include "common/sun.glsl"
#ifdef LOCAL_LIGHTS
#include "common/lights.glsl"
#include "common/shadow.glsl"
uniform uint u_point_lights;  // the first u_point_lights lights have no extent
#endif

#ifdef DOME_SAMPLED
#include "common/dome_sampled.glsl"
#endif

#include "common/lighting_out.glsl"

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    Surface s;
    vec3 emission = surface_emission(px);
    if (!read_surface(px, s)) {
        write_background(px);
        return;
    }
#ifdef HAS_LINKS
    uint group = link_group(px);  // lights test their mask bit for it (common/links.glsl)
    vec3 c = sun_and_ambient(s, group);
#else
    vec3 c = sun_and_ambient(s);
#endif
#ifdef DOME_SAMPLED
    // The textured dome, importance-sampled and shadowed (under light linking: in the
    // groups its link collection reaches, link_ambient[group].w).
#ifdef HAS_LINKS
    c += dome_sampled(s) * link_ambient[group].w;
#else
    c += dome_sampled(s);
#endif
#endif
#ifdef LOCAL_LIGHTS
    // Point lights first (u_point_lights of them, renderer/light_buffer.points_first):
    // their loop holds only the point model; the rest take the full light_radiance.
    uint n = u_counts.x;
    uint np = min(u_point_lights, n);
    for (uint i = 0u; i < np; ++i) {
#ifdef HAS_LINKS
        if (!light_linked(i, group)) continue;
#endif
        c += light_radiance_point(lights[i], s);
    }
    for (uint i = np; i < n; ++i) {
#ifdef HAS_LINKS
        if (!light_linked(i, group)) continue;
#endif
        c += light_radiance(lights[i], s);
    }
#endif
    c += emission;
    write_lighting(px, s, c);
}
