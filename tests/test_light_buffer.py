"""The FoV light buffer on the GPU always equals a fresh pack of the light table,
whether the delegate uploaded it whole or patched only the records that changed."""

from __future__ import annotations

import numpy as np
import pytest

from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings
from stb_hydra.renderer.light_buffer import LIGHT_STRIDE_FLOATS, pack_lights
from stb_hydra.renderer.records import InViewLights, LightBuffer, ShadowSlots

pytestmark = pytest.mark.gl


def gpu_records(frame) -> np.ndarray:
    lb = frame.get(LightBuffer)
    raw = lb.ssbo.read(size=lb.count * LIGHT_STRIDE_FLOATS * 4)
    return np.frombuffer(raw, np.float32).reshape(lb.count, LIGHT_STRIDE_FLOATS)


def expected(d, frame) -> np.ndarray:
    return pack_lights(d.light_table, frame.get(InViewLights).rows, frame.get(ShadowSlots).maps)


def test_partial_uploads_keep_the_buffer_equal_to_a_full_pack(gl_ctx):
    from stb_hydra.scenegen.lights import build_lights_stage

    stage = build_lights_stage(n_lights=40, seed=3, shadow_fraction=1.0, size=10.0)
    # A tiny capture budget: one map per frame, so slots appear frame by frame.
    eng = Engine(stage, RenderSettings(width=64, height=36, lighting="stb", shadow_budget=1))
    eng.request_aovs(set())
    d = eng.delegate
    try:
        # First frames: shadow maps get slots a few at a time (budget), so the
        # slot column changes while the culled set stays the same.
        for _ in range(4):
            f = eng.render_frame()
            np.testing.assert_array_equal(gpu_records(f), expected(d, f))
        assert d.stats["light_partial_uploads"] >= 1
        # Each new slot rewrites one record; once every map has one, nothing is uploaded.
        assert d.last_upload_records == 1
        for _ in range(60):
            f = eng.render_frame()
            if not f.stats["light_upload"]:
                break
            np.testing.assert_array_equal(gpu_records(f), expected(d, f))
        assert not eng.render_frame().stats["light_upload"]
        # One light's intensity edit: exactly its record is rewritten.
        paths = [p for p in d.light_table.paths if p]
        target = paths[len(paths) // 2]
        prim = stage.GetPrimAtPath(target)
        attr = prim.GetAttribute("inputs:intensity")
        before = d.stats["light_partial_uploads"]
        attr.Set(float(attr.Get() or 1.0) * 3.0)
        f = eng.render_frame()
        np.testing.assert_array_equal(gpu_records(f), expected(d, f))
        assert d.stats["light_partial_uploads"] == before + 1
        assert d.last_upload_records == 1
    finally:
        eng.release()
