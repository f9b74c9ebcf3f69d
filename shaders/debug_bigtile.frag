// Debug AOV "bigtile": each big tile shows its K reservoir slots as a grid of
// cells (the slot block layout, e.g. 4x4 for K = 16), a cell coloured by a hash
// of the slot's light index and as bright as its weight relative to the tile's
// other slots (log2 scale, 0.25..1). Empty slots are dark grey, cell borders
// dimmed, big-tile borders black. Reads the r32ui stb_bigtile texture.
#include "common/frame.glsl"
#include "common/packing.glsl"
#include "common/debug_colors.glsl"

uniform usampler2D u_bigtile;   // r32ui reservoirs, u_block texels per big tile
uniform ivec2 u_block;          // slot block (columns, rows) per big tile
uniform int u_big_px;           // big tile size (px)

layout(location = 0) out vec4 o_color;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    ivec2 bt = px / u_big_px;
    ivec2 local = px - bt * u_big_px;
    ivec2 cell_px = max(ivec2(u_big_px) / u_block, ivec2(1));
    ivec2 cell = min(local / cell_px, u_block - 1);
    // log2 weight range over the tile's non-empty slots
    float lo = 1e30, hi = -1e30;
    for (int y = 0; y < u_block.y; ++y) {
        for (int x = 0; x < u_block.x; ++x) {
            uint s = texelFetch(u_bigtile, bt * u_block + ivec2(x, y), 0).r;
            float w = sample_weight(s);
            if (sample_index(s) == LIM_EMPTY_LIGHT_INDEX || w <= 0.0) continue;
            lo = min(lo, log2(w));
            hi = max(hi, log2(w));
        }
    }
    uint s = texelFetch(u_bigtile, bt * u_block + cell, 0).r;
    uint li = sample_index(s);
    float w = sample_weight(s);
    vec3 c = vec3(0.06);
    if (li != LIM_EMPTY_LIGHT_INDEX) {
        float b = 0.15;
        if (w > 0.0) b = hi > lo ? 0.25 + 0.75 * (log2(w) - lo) / (hi - lo) : 1.0;
        c = light_color(li) * b;
    }
    ivec2 inner = local - cell * cell_px;
    if (inner.x == 0 || inner.y == 0) c *= 0.4;
    if (local.x == 0 || local.y == 0) c = vec3(0.0);
    o_color = vec4(c, 1.0);
}
