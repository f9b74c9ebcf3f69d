// Direct lighting for the exact methods: `reference` (every FoV light per pixel,
// LOCAL_LIGHTS) and `sun` (sun + ambient only). Scene-linear radiance (nits).
#include "common/gbuffer.glsl"
#include "common/sun.glsl"
#ifdef LOCAL_LIGHTS
#include "common/lights.glsl"
#include "common/shadow.glsl"
uniform uint u_point_lights;  // the first u_point_lights lights have no extent,
uniform uint u_sphere_end;    // those up to u_sphere_end narrow sphere lights,
uniform uint u_wide_sphere_end;  // those up to u_wide_sphere_end other sphere lights
#ifdef SPLIT_UNSHADOWED  // light_buffer.unshadowed_first: lights without shadows first
uniform uint u_sphere_unshadowed_end;  // in the narrow spheres,
uniform uint u_tail_unshadowed_end;    // in the lights after them
#endif
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
    // Point lights first (u_point_lights of them), then sphere lights narrow against
    // every lobe (up to u_sphere_end), then the other sphere lights (up to
    // u_wide_sphere_end; renderer/light_buffer.by_light_model): each loop holds only its
    // model's code; the rest take the full light_radiance. A loop is compiled only when
    // the scene has lights of its model (LOOP_* defines, lighting/base.light_loops);
    // a model without its loop has no lights here, or lies in the general loop's range
    // (wide spheres when LOOP_GENERAL is in: it starts where the last loop ended).
    // The point loop reads each light's members only past its range test
    // (light_radiance_point_at); the others test the range before the Light argument
    // is copied from the SSBO (light_reaches).
    // SKIP_UNREACHED: the lights out of a pixel's reach are stepped over in an inner
    // loop of their own, not with `if (...) continue`: llvmpipe (and a GPU's SIMD
    // group) runs an `if` body for the whole group whenever any lane takes it, but
    // leaves a loop once every lane has; so each pixel steps over its own unreached
    // lights and the shading body runs about as often as the group's busiest pixel has
    // reached lights, not once per light. Same lights, same order per pixel: same sum.
    uint n = u_counts.x;
    uint i = 0u;
#ifdef LOOP_POINT
    for (uint e = min(u_point_lights, n); i < e; ++i) {
        while (i < e && !light_reaches(i, s.P)) ++i;  // SKIP_UNREACHED (above)
        if (i >= e) break;
#ifdef HAS_LINKS
        if (!light_linked(i, group)) continue;
#endif
        c += light_radiance_point_at(i, s);
    }
#endif
#ifdef LOOP_SPHERE_NARROW
#ifdef SPLIT_UNSHADOWED  // the part's lights without shadows first, no shadow code
    for (uint e = min(u_sphere_unshadowed_end, n); i < e; ++i) {
        while (i < e && !light_reaches(i, s.P)) ++i;  // SKIP_UNREACHED (above)
        if (i >= e) break;
#ifdef HAS_LINKS
        if (!light_linked(i, group)) continue;
#endif
        c += light_radiance_sphere_narrow_unshadowed(lights[i], s);
    }
#endif
    for (uint e = min(u_sphere_end, n); i < e; ++i) {
        while (i < e && !light_reaches(i, s.P)) ++i;  // SKIP_UNREACHED (above)
        if (i >= e) break;
#ifdef HAS_LINKS
        if (!light_linked(i, group)) continue;
#endif
        c += light_radiance_sphere_narrow(lights[i], s);
    }
#endif
#ifdef LOOP_SPHERE_WIDE
#ifdef SPLIT_UNSHADOWED
    for (uint e = min(u_tail_unshadowed_end, n); i < e; ++i) {
        while (i < e && !light_reaches(i, s.P)) ++i;  // SKIP_UNREACHED (above)
        if (i >= e) break;
#ifdef HAS_LINKS
        if (!light_linked(i, group)) continue;
#endif
        c += light_radiance_sphere_wide_unshadowed(lights[i], s);
    }
#endif
    for (uint e = min(u_wide_sphere_end, n); i < e; ++i) {
        while (i < e && !light_reaches(i, s.P)) ++i;  // SKIP_UNREACHED (above)
        if (i >= e) break;
#ifdef HAS_LINKS
        if (!light_linked(i, group)) continue;
#endif
        c += light_radiance_sphere_wide(lights[i], s);
    }
#endif
#ifdef LOOP_GENERAL
#ifdef SPLIT_UNSHADOWED
    for (uint e = min(u_tail_unshadowed_end, n); i < e; ++i) {
        while (i < e && !light_reaches(i, s.P)) ++i;  // SKIP_UNREACHED (above)
        if (i >= e) break;
#ifdef HAS_LINKS
        if (!light_linked(i, group)) continue;
#endif
        c += light_radiance_unshadowed(lights[i], s);
    }
#endif
    for (; i < n; ++i) {
        while (i < n && !light_reaches(i, s.P)) ++i;  // SKIP_UNREACHED (above)
        if (i >= n) break;
#ifdef HAS_LINKS
        if (!light_linked(i, group)) continue;
#endif
        c += light_radiance(lights[i], s);
    }
#endif
#endif
    c += emission;
    write_lighting(px, s, c);
}
