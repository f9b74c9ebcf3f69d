// Shading of `lighttree` (O'Donnell & Chajdas 2017, hybrid): the pixel's cell (tile x
// exponential depth slice) holds a list (one leaf node) or a light tree; the stack-
// less walk of Listing 3 visits nodes in memory order: a node whose depth interval
// holds the pixel's view depth is entered (a leaf evaluates its lights), a missed
// node jumps over its subtree by its skip count. Node (Listing 1, std430 16 B):
// min depth, max depth, first light, bits = leaf | count << 1 | skip << 17.
// The light loop is the reference's (same includes, split by light model) over the
// leaf's lights.
#include "common/gbuffer.glsl"
#include "common/sun.glsl"
#include "common/lights.glsl"
#include "common/shadow.glsl"

struct Node {
    float min_depth;
    float max_depth;
    uint first_light;
    uint bits;
};
layout(std430, binding = SSBO_CELL_HEADERS) readonly buffer CellHeaders { uvec2 cell_header[]; };  // first node, nodes
layout(std430, binding = SSBO_CELL_LISTS) readonly buffer TreeNodes { Node nodes[]; };
layout(std430, binding = SSBO_CELL_EXTRA) readonly buffer TreeLights { uint tree_lights[]; };
uniform ivec2 u_grid;
uniform int u_tile_px;
uniform vec4 u_slices;     // near_split, far, slices, slices / ln(far / near_split)

int depth_slice(float d) {
    if (u_slices.z < 0.5 || d < u_slices.x) return 0;
    int j = int(floor(log(d / u_slices.x) * u_slices.w));
    return 1 + clamp(j, 0, int(u_slices.z) - 1);
}

uniform uint u_point_lights;     // lights [0, u_point_lights) have no extent,
uniform uint u_sphere_end;       // then narrow sphere lights,
uniform uint u_wide_sphere_end;  // then the other sphere lights

// Light i is linked to the pixel's group and P lies within its range.
bool tree_light_reaches(uint i, vec3 P, uint group) {
#ifdef HAS_LINKS
    if (!light_linked(i, group)) return false;
#endif
    return length(lights[i].pos_range.xyz - P) < lights[i].pos_range.w;
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
    uint group = 0u;  // unused without links
    vec3 c = sun_and_ambient(s);
#endif
    float depth = texelFetch(g_depth, px, 0).r;
    ivec2 tile = px / u_tile_px;
    int cell = (depth_slice(depth) * u_grid.y + tile.y) * u_grid.x + tile.x;
    uvec2 h = cell_header[cell];
    uint ni = 0u;
    for (;;) {
        // SKIP_UNREACHED at the node level: the walk steps to the pixel's next entered
        // leaf in an inner loop of its own (an entered inner node: the next node; a
        // missed node: past its subtree), so a SIMD group whose pixels sit in different
        // leaves shades them together once every lane has found its own, instead of
        // running each leaf's loops for the whole group in turn (`if (entered)` bodies).
        // Each pixel visits the same leaves in the same order as before: same sum.
        while (ni < h.y) {
            uint b = nodes[h.x + ni].bits;
            bool entered = depth >= nodes[h.x + ni].min_depth && depth <= nodes[h.x + ni].max_depth;
            if (entered && (b & 1u) != 0u) break;
            ni += entered ? 1u : b >> 17;
        }
        if (ni >= h.y) break;
        Node nd = nodes[h.x + ni];
        uint count = (nd.bits >> 1) & 0xFFFFu;
        uint first = nd.first_light;
        // A leaf's lights ascend (light_tree_build.build_cells): point lights,
        // narrow and other sphere lights, the rest, each part in a loop holding
        // only its model's code (renderer/light_buffer.by_light_model), compiled
        // only for the models the scene has (LOOP_*, lighting/base.light_loops).
        // SKIP_UNREACHED (lighting_direct.frag): every loop steps over the lights
        // out of the pixel's reach (or link group) in an inner loop of its own,
        // which a SIMD group leaves once every lane has (an `if (...) continue`
        // ran the body for the group whenever one lane took it); a light past
        // the loop's model stepped over is out of reach for the later loops too.
        uint k = 0u;
#ifdef LOOP_POINT
        for (; k < count; ++k) {
            while (k < count && !tree_light_reaches(tree_lights[first + k], s.P, group)) ++k;
            if (k >= count) break;
            uint i = tree_lights[first + k];
            if (i >= u_point_lights) break;
            c += light_radiance_point_at(i, s);
        }
#endif
#ifdef LOOP_SPHERE_NARROW
        for (; k < count; ++k) {
            while (k < count && !tree_light_reaches(tree_lights[first + k], s.P, group)) ++k;
            if (k >= count) break;
            uint i = tree_lights[first + k];
            if (i >= u_sphere_end) break;
            c += light_radiance_sphere_narrow(lights[i], s);
        }
#endif
#ifdef LOOP_SPHERE_WIDE
        for (; k < count; ++k) {
            while (k < count && !tree_light_reaches(tree_lights[first + k], s.P, group)) ++k;
            if (k >= count) break;
            uint i = tree_lights[first + k];
            if (i >= u_wide_sphere_end) break;
            c += light_radiance_sphere_wide(lights[i], s);
        }
#endif
#ifdef LOOP_GENERAL
        for (; k < count; ++k) {
            while (k < count && !tree_light_reaches(tree_lights[first + k], s.P, group)) ++k;
            if (k >= count) break;
            uint i = tree_lights[first + k];
            c += light_radiance(lights[i], s);
        }
#endif
        ni += 1u;
    }
    c += emission;
    write_lighting(px, s, c);
}
