"""Light clusters of STB's big-tile pass (issue 16): Morton grouping on the CPU, the
``auto`` switch, and the GPU pass's reservoirs (real GL, small images)."""

from __future__ import annotations

import numpy as np
import pytest
from stagegen import usda_stage
from test_stb import lights_scene, read_u32, stb_engine

from stb_hydra import limits
from stb_hydra.renderer.lighting.light_clusters import (
    build_clusters,
    cluster_cdf,
    morton_order,
)
from stb_hydra.renderer.lighting.stb import SLOT_BLOCKS, StbLighting, decode_samples
from stb_hydra.renderer.records import InViewLights


def test_morton_order_keeps_neighbours_together():
    """Two groups of 32 lights 100 m apart, shuffled: each cluster of 32 holds one group."""
    rng = np.random.default_rng(3)
    a = rng.uniform(0, 1, (32, 3))
    b = rng.uniform(0, 1, (32, 3)) + 100.0
    pos = np.concatenate([a, b])
    perm = rng.permutation(64)
    pos = pos[perm]
    cl = build_clusters(pos, np.full(64, 2.0), np.arange(64, dtype=float), group=32, fanout=2)
    assert cl.count == 2 and len(cl.supers) == 1
    assert sorted(cl.order.tolist()) == list(range(64))  # a permutation of the FoV lights
    groups = [set((perm[cl.order[c * 32 : (c + 1) * 32]] >= 32).tolist()) for c in range(2)]
    assert all(len(g) == 1 for g in groups), groups
    for c in range(2):
        members = cl.order[c * 32 : (c + 1) * 32]
        np.testing.assert_allclose(cl.clusters[c, 0:3], pos[members].min(0), rtol=1e-6)
        np.testing.assert_allclose(cl.clusters[c, 4:7], pos[members].max(0), rtol=1e-6)
        assert cl.clusters[c, 3] == np.float32(np.arange(64)[members].sum())
        assert cl.clusters[c, 7] == 2.0
    np.testing.assert_allclose(cl.supers[0, 0:3], pos.min(0), rtol=1e-6)
    np.testing.assert_allclose(cl.supers[0, 4:7], pos.max(0), rtol=1e-6)
    assert cl.supers[0, 3] == np.float32(np.arange(64).sum())
    assert cl.records().shape == (3, 8)  # the GPU array: super-clusters, then clusters


def test_clusters_of_a_ragged_tail_and_negative_flux():
    pos = np.stack([np.arange(70.0), np.zeros(70), np.zeros(70)], 1)
    flux = np.full(70, 1.0)
    flux[5] = -3.0  # a negative flux counts as 0, never lowers a cluster's score
    cl = build_clusters(pos, np.linspace(1, 7, 70), flux, group=32, fanout=2)
    assert cl.count == 3 and len(cl.supers) == 2
    assert cl.order.tolist() == list(range(70))  # on a line the curve keeps the order
    assert cl.clusters[:, 3].tolist() == [31.0, 32.0, 6.0]
    assert cl.clusters[2, 7] == np.float32(7.0)
    assert cl.supers[:, 3].tolist() == [63.0, 6.0]
    assert cl.supers[:, 7].tolist() == [np.float32(cl.clusters[1, 7]), np.float32(7.0)]
    assert morton_order(np.zeros((0, 3))).size == 0


def test_cluster_cdf_per_run():
    """The flux pick's CDF: inclusive within each run of ``group`` (ragged tail too),
    the run's last entry exactly 1, a run without flux uniform."""
    f = np.array([1.0, 1.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 5.0, 0.0, 5.0])
    np.testing.assert_array_equal(
        cluster_cdf(f, 4), [0.25, 0.5, 1.0, 1.0, 0.25, 0.5, 0.75, 1.0, 0.5, 0.5, 1.0]
    )
    rng = np.random.default_rng(0)
    g = rng.uniform(0.0, 1e4, 1000)
    cdf = cluster_cdf(g, 16)
    ends = np.minimum(np.arange(16, 1001, 16), 1000) - 1
    assert np.all(cdf[ends] == 1.0) and np.all(np.diff(cdf.reshape(-1)[:992].reshape(62, 16)) >= 0)
    np.testing.assert_allclose(np.diff(cdf[:16], prepend=0.0), g[:16] / g[:16].sum(), atol=1e-6)
    assert build_clusters(np.zeros((0, 3)), np.zeros(0), np.zeros(0)).cdf.size == 0


def test_frame_tiling_keeps_the_big_tile_pass_bounded():
    """``big_tile=0`` (the reuse's default): 16 px tiles stream up to 2 x 16^2 lights,
    32 px up to 2 x 32^2, then 32 px tiles draw from clusters; ``bigtile`` forces the
    mode; a given big tile keeps the clusters' threshold of K x 64 lights."""
    m = StbLighting(None)
    assert m.o["big_tile"] == 0 and m.o["cluster_pick"] == "flux"
    got = [m.frame_tiling(n) for n in (1, 512, 513, 2048, 2049, 5000, 100000)]
    assert got == [(16, False), (16, False), (32, False), (32, False)] + [(32, True)] * 3
    assert limits.STB_REUSE_BIG_TILES_PX == (16, 32)
    assert StbLighting(None, bigtile="clusters").frame_tiling(50) == (32, True)
    assert StbLighting(None, bigtile="stream").frame_tiling(5000) == (32, False)
    fixed = StbLighting(None, big_tile=16)
    assert fixed.frame_tiling(5000) == (16, True) and fixed.frame_tiling(4096) == (16, False)
    assert StbLighting(None, reuse=False).frame_tiling(5000) == (128, True)


@pytest.mark.parametrize(
    "pick,flat,target",
    [
        ("target", 0, "segment"),
        ("flux", 0, "segment"),
        ("flux", 0, "uniform"),
        ("flux", 1, "uniform"),
    ],
)
def test_auto_uses_clusters_above_the_threshold_and_every_slot_is_valid(
    gl_ctx, monkeypatch, pick, flat, target
):
    """K = 4: above 4 x BIG_TILE_CLUSTER_MIN_LIGHTS_PER_SLOT lights ``auto`` draws from
    clusters; every slot then holds an in-view light with W = 1 / (K p) > 0, and the
    weights' mean over slots estimates n / K (E[W] = sum_l p_l / (K p_l) = n / K for
    every light the target reaches -- all of them here, ranges cover the scene).
    ``cluster_pick=flux``: p_l = p(cluster) x flux_l / flux_cluster. Any pdf stored
    normalised within a cluster keeps E[W], so the uniform-target cases (light tails)
    also check E[W flux_l] = sum flux / K, which a stored in-cluster p other than the
    one drawn from moves (the lights' intensities spread 10x). ``flat``: the tile's one
    CDF over every cluster (BIG_TILE_CLUSTERS_FLAT_MAX), else super-clusters first."""
    monkeypatch.setattr(limits, "BIG_TILE_CLUSTERS_FLAT_MAX", 1 << 20 if flat else 0)
    n = 4 * limits.BIG_TILE_CLUSTER_MIN_LIGHTS_PER_SLOT + 40
    stage = usda_stage(lights_scene(n, cube=False))
    eng = stb_engine(stage, 128, 72, K=4, N=1, weight_cap=None, target=target, cluster_pick=pick)
    try:
        ws, fs = [], []
        for _ in range(24):
            frame = eng.render_frame()
            assert frame.stats.get("stb_light_clusters") == -(-n // limits.BIG_TILE_CLUSTER_LIGHTS)
            big = read_u32(eng.buffers.textures["stb_bigtile"])[..., 0]
            idx, w = decode_samples(big)
            rows = frame.get(InViewLights)
            assert np.all(idx < rows.count)
            assert np.all(w > 0)
            ws.append(w.ravel())
            fs.append(eng.delegate.light_table.flux[rows.rows][idx.ravel()])
        flux_all = eng.delegate.light_table.flux[rows.rows]
        # 1 / p has mean n (an importance-sampling identity); 5 % for 24 x 4 x tiles draws
        # of a heavy-ish tail, checked on the log-encoded weights (<= 1 % rounding).
        w_all = np.concatenate(ws)
        mean_w = float(np.mean(w_all))
        assert abs(mean_w / (n / 4) - 1.0) < 0.15, mean_w
        if target == "uniform":
            mean_wf = float(np.mean(w_all * np.concatenate(fs)))
            assert abs(mean_wf / (flux_all.sum() / 4) - 1.0) < 0.15, mean_wf
    finally:
        eng.release()
    eng = stb_engine(stage, 128, 72, K=64, N=1)
    try:
        assert "stb_light_clusters" not in eng.render_frame().stats  # 64 x 64 > n: streamed
    finally:
        eng.release()
    assert SLOT_BLOCKS[4] == (2, 2)
