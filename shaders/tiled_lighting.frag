// Shading of the list-based exact methods: `tiled` (cell = 16 px tile) and, with
// CLUSTERED defined, `clustered` (cell = tile x exponential depth slice). The light
// loop is the reference's (lighting_direct.frag) over the cell's list, which holds
// FoV indices in increasing order: same includes, same order of the non-zero terms.
// A light is skipped when the pixel is at or past its range -- the very test
// light_falloff makes before returning 0 -- before its full record is read.
#include "common/gbuffer.glsl"
#include "common/sun.glsl"
#include "common/lights.glsl"
#include "common/shadow.glsl"

layout(std430, binding = SSBO_CELL_HEADERS) readonly buffer CellHeaders { uvec2 cell_header[]; };
layout(std430, binding = SSBO_CELL_LISTS) readonly buffer CellLights { uint cell_lights[]; };
#ifdef CELL_POS_RANGE
layout(std430, binding = SSBO_CELL_POS_RANGE) readonly buffer CellPosRange { vec4 cell_pos_range[]; };
#endif
uniform ivec2 u_grid;      // tiles along x, y
uniform int u_tile_px;     // tile side (px)
uniform uint u_point_lights;  // the first u_point_lights lights have no extent
uniform uint u_sphere_end;    // from u_point_lights up to u_sphere_end: narrow spheres,
uniform uint u_wide_sphere_end;  // up to u_wide_sphere_end: the other sphere lights
#ifdef CLUSTERED
uniform vec4 u_slices;     // near_split, far, slices, slices / ln(far / near_split)

int depth_slice(float d) {
    if (u_slices.z < 0.5 || d < u_slices.x) return 0;
    int j = int(floor(log(d / u_slices.x) * u_slices.w));
    return 1 + clamp(j, 0, int(u_slices.z) - 1);
}
#endif

// Whether entry e of the lists reaches P: light_reaches (common/lights.glsl) of its
// light, the same expression on the same floats; with CELL_POS_RANGE read from the
// entry's own copy of pos_range (one load per step of the walk, not two).
bool entry_reaches(uint e, vec3 P) {
#ifdef CELL_POS_RANGE
    vec4 pr = cell_pos_range[e];
    return length(pr.xyz - P) < pr.w;
#else
    return light_reaches(cell_lights[e], P);
#endif
}

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
    ivec2 tile = px / u_tile_px;
    int cell = tile.y * u_grid.x + tile.x;
#ifdef CLUSTERED
    cell += depth_slice(texelFetch(g_depth, px, 0).r) * u_grid.x * u_grid.y;
#endif
    uvec2 h = cell_header[cell];
    // A cell's list is in ascending light order (tiled_cull.comp), and the point
    // lights come first (u_point_lights), then sphere lights (narrow up to u_sphere_end,
    // the others up to u_wide_sphere_end; renderer/light_buffer.by_light_model): each
    // part runs a loop holding only its model's code (light_radiance_point_at,
    // light_radiance_sphere_narrow / _wide), the rest the full light_radiance. A loop
    // is compiled only for the models the scene has (LOOP_* defines,
    // lighting/base.light_loops; wide spheres fall to the general loop when it is in).
    uint k = 0u;
#ifdef LOOP_POINT
    for (; k < h.y; ++k) {
        while (k < h.y && !entry_reaches(h.x + k, s.P)) ++k;  // SKIP_UNREACHED
        if (k >= h.y) break;
        uint i = cell_lights[h.x + k];
        if (i >= u_point_lights) break;
#ifdef HAS_LINKS
        if (!light_linked(i, group)) continue;
#endif
        c += light_radiance_point_at(i, s);  // tests the range itself
    }
#endif
#ifdef LOOP_SPHERE_NARROW
    for (; k < h.y; ++k) {  // then the narrow sphere lights (up to u_sphere_end)
        while (k < h.y && !entry_reaches(h.x + k, s.P)) ++k;  // SKIP_UNREACHED
        if (k >= h.y) break;
        uint i = cell_lights[h.x + k];
        if (i >= u_sphere_end) break;
#ifdef HAS_LINKS
        if (!light_linked(i, group)) continue;
#endif
        c += light_radiance_sphere_narrow(lights[i], s);
    }
#endif
#ifdef LOOP_SPHERE_WIDE
    for (; k < h.y; ++k) {  // the other sphere lights (up to u_wide_sphere_end)
        while (k < h.y && !entry_reaches(h.x + k, s.P)) ++k;  // SKIP_UNREACHED
        if (k >= h.y) break;
        uint i = cell_lights[h.x + k];
        if (i >= u_wide_sphere_end) break;
#ifdef HAS_LINKS
        if (!light_linked(i, group)) continue;
#endif
        c += light_radiance_sphere_wide(lights[i], s);
    }
#endif
#ifdef LOOP_GENERAL
    for (; k < h.y; ++k) {
        // SKIP_UNREACHED (lighting_direct.frag): entries out of the pixel's reach are
        // stepped over in a loop (a SIMD group runs an `if` body whenever any lane takes
        // it, but leaves a loop once every lane has); so in every loop here. An entry
        // past this loop's model may be stepped over too: it is out of reach, and
        // every later loop would skip it as well.
        while (k < h.y && !entry_reaches(h.x + k, s.P)) ++k;
        if (k >= h.y) break;
        uint i = cell_lights[h.x + k];
#ifdef HAS_LINKS
        if (!light_linked(i, group)) continue;
#endif
        c += light_radiance(lights[i], s);
    }
#endif
    c += emission;
    write_lighting(px, s, c);
}
