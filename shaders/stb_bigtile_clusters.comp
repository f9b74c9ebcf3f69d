// STB big-tile sampling for many lights (issue 16, `-o bigtile=clusters`): one
// workgroup per big tile, one invocation per reservoir slot (STB_K). The FoV lights
// come in clusters of up to LIM_BIG_TILE_CLUSTER_LIGHTS neighbours (Morton order, built
// on the CPU: renderer/lighting/light_clusters.py). The workgroup scores every cluster
// for this tile once, into a CDF in shared memory; each slot then draws one cluster
// from it and one light of that cluster by weighted reservoir sampling with the
// light's own target (common/bigtile_target.glsl). A slot is then an independent
// one-sample estimate over all lights, p(l) = p(cluster) x t(l) / sum t(cluster), and
// stores W = 1 / (K p(l)) (the small tile sums its K candidates' estimates). The cost
// per tile is ~ n / LIM_BIG_TILE_CLUSTER_LIGHTS cluster scores + K x
// LIM_BIG_TILE_CLUSTER_LIGHTS light targets, instead of n light targets.
//
// Unbiased: a cluster scores 0 only when the region sphere lies beyond every light's
// range (the cluster's position box grown by its largest range), where every light's
// shaped target is 0 too; any other cluster scores > 0.
#include "common/frame.glsl"
#include "common/rng.glsl"
#include "common/packing.glsl"
#include "common/lights.glsl"
#include "common/bigtile_target.glsl"

layout(local_size_x = STB_K) in;

layout(r32ui, binding = IMAGE_UNIT_BIGTILE) uniform writeonly uimage2D u_out;
struct Cluster {
    vec4 lo_flux;   // xyz min corner of the lights' positions (world, m), w summed flux (lm)
    vec4 hi_range;  // xyz max corner (world, m), w largest influence range (m)
};
layout(std430, binding = SSBO_STB_CLUSTERS) readonly buffer Clusters { Cluster clusters[]; };
layout(std430, binding = SSBO_STB_CLUSTER_LIGHTS) readonly buffer ClusterLights {
    uint cluster_lights[];  // FoV light index, in Morton order (cluster c: c x G ...)
};
uniform ivec2 u_block;          // slot block per big tile (K = x * y)
uniform int u_clusters;         // cluster count (<= LIM_BIG_TILE_CLUSTERS_MAX)
uniform float u_weight_cap;     // W <= cap x n / K; <= 0: unbiased (no cap)

shared float s_cdf[LIM_BIG_TILE_CLUSTERS_MAX];  // inclusive prefix sums of the scores
shared float s_part[STB_K];

// Score of cluster c for the tile: its flux over the squared distance from the segment
// to its position box (plus a quarter of the box's half diagonal, squared, so a box
// around the segment does not score as if every light sat on it); 0 when the region
// sphere is out of reach of all its lights (shaped target only, as for one light).
float cluster_score(int ci, vec3 A, vec3 B, vec3 C, float R) {
    Cluster cl = clusters[ci];
    vec3 lo = cl.lo_flux.xyz, hi = cl.hi_range.xyz;
    int first = ci * LIM_BIG_TILE_CLUSTER_LIGHTS;
    float count = float(min(LIM_BIG_TILE_CLUSTER_LIGHTS, int(u_counts.x) - first));
    if (u_target_mode == 2 && distance(clamp(C, lo, hi), C) > cl.hi_range.w + R) return 0.0;
    if (u_target_mode == 1) return count;
    vec3 mid = 0.5 * (lo + hi);
    vec3 ab = B - A;
    float t = clamp(dot(mid - A, ab) / max(dot(ab, ab), 1e-20), 0.0, 1.0);
    vec3 X = A + t * ab;
    vec3 d = X - clamp(X, lo, hi);
    vec3 half_diag = 0.5 * (hi - lo);
    float d2 = dot(d, d) + 0.25 * dot(half_diag, half_diag);
    d2 = max(d2, LIM_MIN_LIGHT_DISTANCE * LIM_MIN_LIGHT_DISTANCE);
    // Positive for a reachable cluster even if its flux sums to 0 (its lights' own
    // targets then decide).
    return max(cl.lo_flux.w, 1e-30) / d2;
}

void main() {
    ivec2 tile = ivec2(gl_WorkGroupID.xy);
    int slot = int(gl_LocalInvocationID.x);
    int n = int(u_counts.x);
    int nc = u_clusters;
    vec3 A, B, C;
    float R;
    tile_segment(tile, A, B, C, R);

    // 1. Scores of all clusters, a contiguous run per invocation, as a CDF.
    int per = (nc + STB_K - 1) / STB_K;
    int c0 = min(slot * per, nc), c1 = min(c0 + per, nc);
    float run = 0.0;
    for (int c = c0; c < c1; ++c) {
        run += cluster_score(c, A, B, C, R);
        s_cdf[c] = run;
    }
    s_part[slot] = run;
    barrier();
    float base = 0.0;
    for (int k = 0; k < slot; ++k) base += s_part[k];
    for (int c = c0; c < c1; ++c) s_cdf[c] += base;
    barrier();

    // 2. This slot's cluster: the first whose prefix exceeds u x total.
    ivec2 texel = tile * u_block + ivec2(slot % u_block.x, slot / u_block.x);
    float total = nc > 0 ? s_cdf[nc - 1] : 0.0;
    uint tile_index = uint(tile.y) * 4096u + uint(tile.x);
    Rng rng = rng_init(tile_index * uint(LIM_BIG_TILE_SLOTS_MAX) + uint(slot) + 0x10000000u,
                       u_counts.y ^ 0x5bd1e995u);
    if (!(total > 0.0)) {
        imageStore(u_out, texel, uvec4(pack_sample(LIM_EMPTY_LIGHT_INDEX, 0.0)));
        return;
    }
    float u = rng_float(rng) * total;
    int lo = 0, hi = nc - 1;
    while (lo < hi) {
        int mid = (lo + hi) >> 1;
        if (s_cdf[mid] > u) hi = mid; else lo = mid + 1;
    }
    int ci = lo;
    float score = s_cdf[ci] - (ci > 0 ? s_cdf[ci - 1] : 0.0);

    // 3. One light of the cluster, by its own target (one-sample WRS).
    int first = ci * LIM_BIG_TILE_CLUSTER_LIGHTS;
    int last = min(first + LIM_BIG_TILE_CLUSTER_LIGHTS, n);
    float sum_t = 0.0, sel_t = 0.0;
    uint sel = LIM_EMPTY_LIGHT_INDEX;
    for (int k = first; k < last; ++k) {
        uint i = cluster_lights[k];
        float t = target(i, A, B, C, R);
        sum_t += t;
        if (t > 0.0 && rng_float(rng) * sum_t <= t) {
            sel = i;
            sel_t = t;
        }
    }
    float W = 0.0;
    if (sel_t > 0.0 && score > 0.0) {
        // 1 / (K p) with p = (score / total) x (sel_t / sum_t)
        W = (total / score) * (sum_t / sel_t) / float(STB_K);
        if (u_weight_cap > 0.0) W = min(W, u_weight_cap * float(n) / float(STB_K));
    }
    imageStore(u_out, texel, uvec4(pack_sample(W > 0.0 ? sel : LIM_EMPTY_LIGHT_INDEX, W)));
}
