"""Light clusters of STB's big-tile pass (issue 16): Morton grouping on the CPU, the
``auto`` switch, and the GPU pass's reservoirs (real GL, small images)."""

from __future__ import annotations

import numpy as np
from stagegen import usda_stage
from test_stb import lights_scene, read_u32, stb_engine

from stb_hydra import limits
from stb_hydra.renderer.lighting.light_clusters import build_clusters, morton_order
from stb_hydra.renderer.lighting.stb import SLOT_BLOCKS, decode_samples
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


def test_auto_uses_clusters_above_the_threshold_and_every_slot_is_valid(gl_ctx):
    """K = 4: above 4 x BIG_TILE_CLUSTER_MIN_LIGHTS_PER_SLOT lights ``auto`` draws from
    clusters; every slot then holds an in-view light with W = 1 / (K p) > 0, and the
    weights' mean over slots estimates n / K (E[W] = sum_l p_l / (K p_l) = n / K for
    every light the target reaches -- all of them here, ranges cover the scene)."""
    n = 4 * limits.BIG_TILE_CLUSTER_MIN_LIGHTS_PER_SLOT + 40
    stage = usda_stage(lights_scene(n, cube=False))
    eng = stb_engine(stage, 128, 72, K=4, N=1, weight_cap=None, target="segment")
    try:
        ws = []
        for _ in range(24):
            frame = eng.render_frame()
            assert frame.stats.get("stb_light_clusters") == -(-n // limits.BIG_TILE_CLUSTER_LIGHTS)
            big = read_u32(eng.buffers.textures["stb_bigtile"])[..., 0]
            idx, w = decode_samples(big)
            assert np.all(idx < frame.get(InViewLights).count)
            assert np.all(w > 0)
            ws.append(w.ravel())
        # 1 / p has mean n (an importance-sampling identity); 5 % for 24 x 4 x tiles draws
        # of a heavy-ish tail, checked on the log-encoded weights (<= 1 % rounding).
        mean_w = float(np.mean(np.concatenate(ws)))
        assert abs(mean_w / (n / 4) - 1.0) < 0.15, mean_w
    finally:
        eng.release()
    eng = stb_engine(stage, 128, 72, K=64, N=1)
    try:
        assert "stb_light_clusters" not in eng.render_frame().stats  # 64 x 64 > n: streamed
    finally:
        eng.release()
    assert SLOT_BLOCKS[4] == (2, 2)
