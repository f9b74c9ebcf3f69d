// Min/max linear-depth pyramid: level k (rg32f: min, max) from level k-1 (or from
// the G-buffer depth for k = 1). Background (depth 0) is ignored: an empty texel
// holds (+HUGE, 0). Each texel of level k covers 2^k x 2^k pixels.
layout(local_size_x = 8, local_size_y = 8) in;
uniform sampler2D u_src;          // level k-1 (r32f depth for k = 1, rg32f otherwise)
uniform int u_from_depth;         // 1: u_src is the G-buffer depth
layout(rg32f, binding = IMAGE_UNIT_HIZ_DST) writeonly uniform image2D u_dst;

const float HUGE_DEPTH = 3.0e38;

void main() {
    ivec2 o = ivec2(gl_GlobalInvocationID.xy);
    ivec2 dst_size = imageSize(u_dst);
    if (o.x >= dst_size.x || o.y >= dst_size.y) return;
    ivec2 src_size = textureSize(u_src, 0);
    float mn = HUGE_DEPTH, mx = 0.0;
    for (int y = 0; y < 2; ++y) {
        for (int x = 0; x < 2; ++x) {
            ivec2 p = o * 2 + ivec2(x, y);
            if (p.x >= src_size.x || p.y >= src_size.y) continue;
            vec2 v = texelFetch(u_src, p, 0).rg;
            if (u_from_depth == 1) {
                if (v.r > 0.0) { mn = min(mn, v.r); mx = max(mx, v.r); }
            } else {
                mn = min(mn, v.r); mx = max(mx, v.g);
            }
        }
    }
    imageStore(u_dst, o, vec4(mn, mx, 0.0, 0.0));
}
