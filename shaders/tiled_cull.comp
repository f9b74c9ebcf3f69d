// Light culling for `tiled` (Andersson 2009) and, with CLUSTERED defined, the GPU
// light assignment of `clustered` (Persson 2013). One workgroup per cell (a 16 px
// tile, or a cluster = tile x depth slice); its CULL_GROUP_SIZE invocations test the
// FoV lights (LIM_CULL_LIGHTS_PER_INVOCATION consecutive ones each) against the cell: the four
// side planes of the tile's frustum (through its pixel edges) and its depth range
// (tiled: the tile's min/max depth from the depth pyramid; clustered: the slice).
// Hits are compacted in light order (a mask word per invocation of 32 consecutive
// lights + bitCount), so a capped list keeps the lowest FoV indices and the sums run
// in the reference's order.
// Output: cell header (first entry, kept count), entries, the uncapped total per
// cell, and frame counters (dropped light-cell pairs, cells over the cap, max total,
// entries kept).
layout(local_size_x = CULL_GROUP_SIZE) in;
#include "common/frame.glsl"
#include "common/lights.glsl"

layout(std430, binding = SSBO_CELL_HEADERS) writeonly buffer CellHeaders { uvec2 cell_header[]; };
layout(std430, binding = SSBO_CELL_LISTS) writeonly buffer CellLights { uint cell_lights[]; };
#ifdef CELL_POS_RANGE
// each kept entry's light pos_range beside its index (tiled_lighting.frag's walk)
layout(std430, binding = SSBO_CELL_POS_RANGE) writeonly buffer CellPosRange { vec4 cell_pos_range[]; };
#endif
layout(std430, binding = SSBO_CELL_EXTRA) buffer CullStats {
    uint stat_dropped;      // light-cell pairs past the cap
    uint stat_cells_over;   // cells whose list overflowed
    uint stat_max_total;    // largest uncapped list
    uint stat_entries;      // entries kept
    uint cell_total[];      // uncapped count per cell
};

uniform ivec2 u_grid;          // cells along x, y
uniform int u_tile_px;         // tile side (px)
uniform uint u_stride;         // list capacity per cell
uniform uint u_cap;            // lights kept per cell (<= u_stride)
uniform float u_radius_scale;  // world -> view length scale (1 for rigid cameras)
uniform float u_rel_margin;    // LIM: relative radius / bound widening
uniform float u_depth_margin;  // LIM: depth-relative widening
#ifdef CLUSTERED
uniform vec4 u_slices;         // near_split, far, slices, slices / ln(far / near_split)
#else
layout(binding = TEX_UNIT_HIZ) uniform sampler2D u_hiz;  // rg32f (min, max) depth, one texel per tile
#endif

shared uint s_word[CULL_GROUP_SIZE];  // one hit mask per invocation
shared uint s_count;

// Inside-distance of a view-space point to the side plane through the screen line
// with slope a (x/depth for perspective, x for orthographic) on one axis.
float side_distance(float coord, float depth, float a, float sign_) {
    if (u_cam_pos.w > 0.5) return sign_ * (coord - a);
    return sign_ * (coord - a * depth) / sqrt(1.0 + a * a);
}

void main() {
    ivec3 g = ivec3(gl_WorkGroupID);
    uint cell = uint((g.z * u_grid.y + g.y) * u_grid.x + g.x);
    uint t = gl_LocalInvocationIndex;
    float m = 1.0 + u_rel_margin;

    // depth range of the cell
    float dmin, dmax;
#ifdef CLUSTERED
    if (u_slices.z < 0.5) {
        dmin = 0.0; dmax = 3.0e38;
    } else if (g.z == 0) {
        dmin = 0.0; dmax = u_slices.x * m;
    } else {
        float k = 1.0 / u_slices.w;  // ln(far / near_split) / slices
        dmin = u_slices.x * exp(float(g.z - 1) * k) / m;
        dmax = g.z >= int(u_slices.z) ? 3.0e38 : u_slices.x * exp(float(g.z) * k) * m;
    }
#else
    vec2 mm = texelFetch(u_hiz, g.xy, 0).rg;
    dmin = mm.x / m; dmax = mm.y * m;
#endif
    // side planes through the tile's pixel edges (slopes at unit depth)
    vec2 p0 = vec2(g.xy * u_tile_px);
    vec2 p1 = min(p0 + float(u_tile_px), u_resolution.xy);
    vec2 a0 = (p0 * u_resolution.zw * 2.0 - 1.0) * u_tan_off.xy + u_tan_off.zw;
    vec2 a1 = (p1 * u_resolution.zw * 2.0 - 1.0) * u_tan_off.xy + u_tan_off.zw;

    if (t == 0u) s_count = 0u;
    memoryBarrierShared();
    barrier();
    // Each invocation tests LIM_CULL_LIGHTS_PER_INVOCATION consecutive lights into one
    // mask word, so a batch of CULL_GROUP_SIZE words takes four barriers for
    // CULL_GROUP_SIZE x 32 lights (llvmpipe runs a barrier as a switch between the
    // group's invocations: one batch of 64 lights per four barriers cost ~8 ms a frame
    // at 5,000 lights and 60 tiles). Ranks: the hits in the words below, then the bits
    // below in the own word -- light order, as before.
    uint n = dmax >= dmin ? u_counts.x : 0u;  // empty (background-only) tile: nothing
    const uint per = uint(LIM_CULL_LIGHTS_PER_INVOCATION);
    for (uint base = 0u; base < n; base += uint(CULL_GROUP_SIZE) * per) {
        uint first = base + t * per;
        uint word = 0u;
        for (uint j = 0u; j < per; ++j) {
            uint i = first + j;
            if (i >= n) break;
            vec4 pr = lights[i].pos_range;
            vec3 c = (u_view * vec4(pr.xyz, 1.0)).xyz;
            float d = -c.z;
            float r0 = pr.w * u_radius_scale;
            float r = r0 * m + u_depth_margin * (abs(d) + r0);
            bool hit = d + r >= dmin && d - r <= dmax
                && side_distance(c.x, d, a0.x, 1.0) >= -r
                && side_distance(c.x, d, a1.x, -1.0) >= -r
                && side_distance(c.y, d, a0.y, 1.0) >= -r
                && side_distance(c.y, d, a1.y, -1.0) >= -r;
            if (hit) word |= 1u << j;
        }
        s_word[t] = word;
        memoryBarrierShared();
        barrier();
        uint rank = s_count;
        for (uint w = 0u; w < t; ++w) rank += uint(bitCount(s_word[w]));
        uint bits = word;
        while (bits != 0u && rank < u_cap) {
            uint j = uint(findLSB(bits));
            bits &= bits - 1u;
            uint i = first + j;
            cell_lights[cell * u_stride + rank] = i;
#ifdef CELL_POS_RANGE
            cell_pos_range[cell * u_stride + rank] = lights[i].pos_range;
#endif
            ++rank;
        }
        memoryBarrierShared();
        barrier();
        if (t == 0u) {
            for (uint w = 0u; w < uint(CULL_GROUP_SIZE); ++w) s_count += uint(bitCount(s_word[w]));
        }
        memoryBarrierShared();
        barrier();
    }
    if (t == 0u) {
        uint total = s_count;
        uint kept = min(total, u_cap);
        cell_header[cell] = uvec2(cell * u_stride, kept);
        cell_total[cell] = total;
        if (total > kept) {
            atomicAdd(stat_dropped, total - kept);
            atomicAdd(stat_cells_over, 1u);
        }
        atomicMax(stat_max_total, total);
        atomicAdd(stat_entries, kept);
    }
}
