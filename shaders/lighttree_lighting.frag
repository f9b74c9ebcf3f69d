// Shading of `lighttree` (O'Donnell & Chajdas 2017, hybrid): the pixel's cell (tile x
// exponential depth slice) holds a list (one leaf node) or a light tree; the stack-
// less walk of Listing 3 visits nodes in memory order: a node whose depth interval
// holds the pixel's view depth is entered (a leaf evaluates its lights), a missed
// node jumps over its subtree by its skip count. Node (Listing 1, std430 16 B):
// min depth, max depth, first light, bits = leaf | count << 1 | skip << 17.
// The light loop is the reference's (same includes) over the leaf's lights.
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
    float depth = texelFetch(g_depth, px, 0).r;
    ivec2 tile = px / u_tile_px;
    int cell = (depth_slice(depth) * u_grid.y + tile.y) * u_grid.x + tile.x;
    uvec2 h = cell_header[cell];
    uint ni = 0u;
    while (ni < h.y) {
        Node nd = nodes[h.x + ni];
        if (depth >= nd.min_depth && depth <= nd.max_depth) {
            if ((nd.bits & 1u) != 0u) {
                uint count = (nd.bits >> 1) & 0xFFFFu;
                for (uint k = 0u; k < count; ++k) {
                    uint i = tree_lights[nd.first_light + k];
#ifdef HAS_LINKS
                    if (!light_linked(i, group)) continue;
#endif
                    if (length(lights[i].pos_range.xyz - s.P) >= lights[i].pos_range.w) continue;
                    c += light_radiance(lights[i], s);
                }
            }
            ni += 1u;
        } else {
            ni += nd.bits >> 17;
        }
    }
    c += emission;
    write_lighting(px, s, c);
}
