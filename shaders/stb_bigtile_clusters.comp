// STB big-tile sampling for many lights (issue 16, `-o bigtile=clusters`): one
// workgroup per big tile, one invocation per reservoir slot (STB_K). The FoV lights
// come in clusters of LIM_BIG_TILE_CLUSTER_LIGHTS neighbours and super-clusters of
// LIM_BIG_TILE_CLUSTER_FANOUT clusters (Morton order, built on the CPU:
// renderer/lighting/light_clusters.py). The workgroup scores every super-cluster for
// this tile once, into a CDF in shared memory; each slot then draws a super-cluster,
// one of its clusters by their scores, and one light of that cluster by weighted
// reservoir sampling with the light's own target (common/bigtile_target.glsl). A slot
// is an independent one-sample estimate over all lights, p(l) = p(super) x
// p(cluster | super) x t(l) / sum t(cluster), and stores W = 1 / (K p(l)) (the small
// tile sums its K candidates' estimates). Cost per tile ~ n / (G F) super scores + K x
// (F cluster scores + G light targets), instead of n light targets.
//
// In-cluster pick (`-o cluster_pick`): by the lights' own targets (above; G target
// evaluations per slot), or, with STB_CLUSTER_PICK_FLUX, by their flux alone from a
// CDF built on the CPU (a binary search, then one target evaluation of the pick: a
// light whose target is 0 cannot reach the region and gives an empty slot), p(l |
// cluster) = flux(l) / flux(cluster). The reuse's per-pixel resampling shapes the
// candidates anyway; the flux pick costs a few reads instead of G targets.
//
// Flat (u_flat, with the flux pick while the clusters fit the shared CDF,
// limits.BIG_TILE_CLUSTERS_FLAT_MAX): step 1 scores every cluster instead of every
// super-cluster and step 3 is skipped, p(l) = p(cluster) x flux(l) / flux(cluster); the
// super level's coarse scores were most of what the hierarchy lost against streaming.
//
// Unbiased: a (super-)cluster scores 0 only when the region sphere lies beyond every
// light's range (its position box grown by its largest range), where every one of its
// lights' shaped target is 0 too; a light that can reach the region has its cluster
// and super-cluster scoring > 0, so p(l) > 0.
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
// Super-clusters 0 .. u_supers - 1, then clusters (cluster c at u_supers + c).
layout(std430, binding = SSBO_STB_CLUSTERS) readonly buffer Clusters { Cluster clusters[]; };
layout(std430, binding = SSBO_STB_CLUSTER_LIGHTS) readonly buffer ClusterLights {
    uint cluster_lights[];  // FoV light index, in Morton order (cluster c: c x G ...)
};
// The same lights' records in Morton order: a cluster's lights are read from one
// contiguous run (read through lights[] they were scattered over the whole buffer,
// and the pass slowed down with the buffer's size).
layout(std430, binding = SSBO_STB_CLUSTER_RECORDS) readonly buffer ClusterRecords {
    Light cluster_records[];
};
#ifdef STB_CLUSTER_PICK_FLUX
// Per clustered light (Morton order): its cluster's flux CDF, inclusive (the cluster's
// last light holds 1; a cluster without flux: uniform).
layout(std430, binding = SSBO_STB_CLUSTER_CDF) readonly buffer ClusterCdf {
    float cluster_cdf[];
};
#endif
uniform ivec2 u_block;          // slot block per big tile (K = x * y)
uniform int u_clusters;         // cluster count
uniform int u_supers;           // super-cluster count (<= LIM_BIG_TILE_SUPERS_MAX)
uniform int u_flat;             // 1: one level, the tile's CDF over every cluster
                                // (u_clusters <= LIM_BIG_TILE_SUPERS_MAX; no super level)
uniform float u_weight_cap;     // W <= cap x n / K; <= 0: unbiased (no cap)

shared float s_cdf[LIM_BIG_TILE_SUPERS_MAX];  // inclusive prefix sums of the super scores
shared float s_part[STB_K];

// Score of a (super-)cluster (record `ri`, `count` lights) for the tile: its flux
// over the squared distance from the segment to its position box (plus a quarter of the
// box's half diagonal, squared, so a box around the segment does not score as if every
// light sat on it); 0 when the region sphere is out of reach of all its lights (shaped
// target only, as for one light).
float cluster_score(int ri, float count, vec3 A, vec3 B, vec3 C, float R) {
    Cluster cl = clusters[ri];
    vec3 lo = cl.lo_flux.xyz, hi = cl.hi_range.xyz;
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

// Lights in cluster c (the last one may be short).
float cluster_lights_count(int c) {
    return float(min(LIM_BIG_TILE_CLUSTER_LIGHTS, int(u_counts.x) - c * LIM_BIG_TILE_CLUSTER_LIGHTS));
}

void main() {
    ivec2 tile = ivec2(gl_WorkGroupID.xy);
    int slot = int(gl_LocalInvocationID.x);
    int n = int(u_counts.x);
    // Level 1: the super-clusters, or (u_flat) every cluster, record rec0 + entry.
    int ns = u_flat != 0 ? u_clusters : u_supers;
    int rec0 = u_flat != 0 ? u_supers : 0;
    const int G = LIM_BIG_TILE_CLUSTER_LIGHTS, F = LIM_BIG_TILE_CLUSTER_FANOUT;
    vec3 A, B, C;
    float R;
    tile_segment(tile, A, B, C, R);

    // 1. Scores of all super-clusters (or clusters), a contiguous run per invocation, as
    // a CDF.
    int per = (ns + STB_K - 1) / STB_K;
    int s0 = min(slot * per, ns), s1 = min(s0 + per, ns);
    int span = u_flat != 0 ? G : G * F;  // lights per entry
    float run = 0.0;
    for (int sc = s0; sc < s1; ++sc) {
        float cnt = float(min(span, n - sc * span));
        run += cluster_score(rec0 + sc, cnt, A, B, C, R);
        s_cdf[sc] = run;
    }
    s_part[slot] = run;
    barrier();
    float base = 0.0;
    for (int k = 0; k < slot; ++k) base += s_part[k];
    for (int sc = s0; sc < s1; ++sc) s_cdf[sc] += base;
    barrier();

    // 2. This slot's super-cluster: the first whose prefix exceeds u x total.
    ivec2 texel = tile * u_block + ivec2(slot % u_block.x, slot / u_block.x);
    float total = ns > 0 ? s_cdf[ns - 1] : 0.0;
    uint tile_index = uint(tile.y) * 4096u + uint(tile.x);
    Rng rng = rng_init(tile_index * uint(LIM_BIG_TILE_SLOTS_MAX) + uint(slot) + 0x10000000u,
                       u_counts.y ^ 0x5bd1e995u);
    uint empty = pack_sample(LIM_EMPTY_LIGHT_INDEX, 0.0);
    if (!(total > 0.0)) {
        imageStore(u_out, texel, uvec4(empty));
        return;
    }
    float u = rng_float(rng) * total;
    int lo = 0, hi = ns - 1;
    while (lo < hi) {
        int mid = (lo + hi) >> 1;
        if (s_cdf[mid] > u) hi = mid; else lo = mid + 1;
    }
    int si = lo;
    float p_super = (s_cdf[si] - (si > 0 ? s_cdf[si - 1] : 0.0)) / total;

    // 3. One of its clusters, by their scores (flat: the drawn entry is the cluster).
    int ci = si;
    float p_cluster = 1.0;
    if (u_flat == 0) {
        int c_first = si * F;
        int c_last = min(c_first + F, u_clusters);
        float cs[LIM_BIG_TILE_CLUSTER_FANOUT];
        float c_total = 0.0;
        for (int c = c_first; c < c_last; ++c) {
            cs[c - c_first] = cluster_score(u_supers + c, cluster_lights_count(c), A, B, C, R);
            c_total += cs[c - c_first];
        }
        if (!(c_total > 0.0)) {
            imageStore(u_out, texel, uvec4(empty));
            return;
        }
        float uc = rng_float(rng) * c_total;
        ci = -1;
        float acc = 0.0;
        for (int c = c_first; c < c_last; ++c) {
            if (cs[c - c_first] <= 0.0) continue;
            ci = c;  // the last positive cluster absorbs rounding at the top
            acc += cs[c - c_first];
            if (uc < acc) break;
        }
        p_cluster = cs[ci - c_first] / c_total;
    }

    // 4. One light of the cluster, by its own target (one-sample WRS).
    int first = ci * G;
    int last = min(first + G, n);
    float sel_t = 0.0, p_light = 0.0;
    uint sel = LIM_EMPTY_LIGHT_INDEX;
#ifdef STB_CLUSTER_PICK_FLUX
    float ul = rng_float(rng);
    int a = first, b = last - 1;  // the first light whose CDF exceeds ul
    while (a < b) {
        int mid = (a + b) >> 1;
        if (cluster_cdf[mid] > ul) b = mid; else a = mid + 1;
    }
    p_light = cluster_cdf[a] - (a > first ? cluster_cdf[a - 1] : 0.0);
    sel_t = target_light(cluster_records[a], A, B, C, R);
    if (sel_t > 0.0) sel = cluster_lights[a];
#else
    float sum_t = 0.0;
    for (int k = first; k < last; ++k) {
        float t = target_light(cluster_records[k], A, B, C, R);
        sum_t += t;
        if (t > 0.0 && rng_float(rng) * sum_t <= t) {
            sel = cluster_lights[k];
            sel_t = t;
        }
    }
    p_light = sel_t / max(sum_t, 1e-38);
#endif
    float W = 0.0;
    float p = p_super * p_cluster * p_light;
    if (sel_t > 0.0 && p > 0.0) {
        W = 1.0 / (float(STB_K) * p);
        if (u_weight_cap > 0.0) W = min(W, u_weight_cap * float(n) / float(STB_K));
    }
    imageStore(u_out, texel, uvec4(W > 0.0 ? pack_sample(sel, W) : empty));
}
