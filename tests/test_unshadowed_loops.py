"""The reference's loops over lights without shadows (issue 34, ``SPLIT_UNSHADOWED``):
``light_buffer.unshadowed_first`` puts, within the narrow spheres and within the lights
after them, the lights without shadows first, and lighting_direct.frag shades those in
loops without the shadow code. Same lights, same order, same per-light values: the
image equals the same engine compiled without the split, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from stb_hydra.apps.bench import parse_scene
from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings
from stb_hydra.renderer.light_buffer import unshadowed_first
from stb_hydra.renderer.light_table import LightTable
from stb_hydra.renderer.lighting import base
from stb_hydra.renderer.records import InViewLights


def test_unshadowed_first_partitions_each_part_stably():
    t = LightTable()
    for i in range(12):
        t.alloc(f"/L{i}")
    shadow = np.array([1, 0, 1, 0, 0, 1, 1, 0, 1, 0, 0, 1], dtype=bool)
    t.cols["shadow_enable"][:12] = shadow
    rows = np.array([11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0])
    # parts: 2 "points", 4 narrow spheres, 6 after them
    out, n_sphere, n_tail = unshadowed_first(t, rows, 2, 4)
    assert out[:2].tolist() == [11, 10]  # the point part is left alone
    narrow, tail = rows[2:6], rows[6:]
    want_narrow = [r for r in narrow if not shadow[r]] + [r for r in narrow if shadow[r]]
    want_tail = [r for r in tail if not shadow[r]] + [r for r in tail if shadow[r]]
    assert out[2:6].tolist() == want_narrow
    assert out[6:].tolist() == want_tail
    assert n_sphere == sum(not shadow[r] for r in narrow)
    assert n_tail == sum(not shadow[r] for r in tail)


def _render(stage, monkeypatch, drop: str | None):
    """The reference's colour AOV, its defines and in-view lights; ``drop``: a define
    left out."""
    seen: list[dict[str, object]] = []
    lights: list[InViewLights] = []
    orig = base.LightingMethod.scene_defines

    def defines(self, frame):
        d = orig(self, frame)
        d.pop(drop, None)
        seen.append(d)
        lights.append(frame.get(InViewLights))
        return d

    with monkeypatch.context() as m:
        m.setattr(base.LightingMethod, "scene_defines", defines)
        eng = Engine(stage, RenderSettings(width=64, height=36, lighting="reference"))
        try:
            eng.render()
            return eng.aovs["color"][..., :3].copy(), seen, lights
        finally:
            eng.release()


@pytest.mark.gl
def test_split_loops_equal_the_loops_with_shadow_code(gl_ctx, monkeypatch):
    (case,) = parse_scene("gen:lights:80:shadow_fraction=0.5")
    stage = case.build()
    split, defs, lights = _render(stage, monkeypatch, None)
    plain, defs0, _ = _render(stage, monkeypatch, "SPLIT_UNSHADOWED")
    assert any("SPLIT_UNSHADOWED" in d for d in defs)
    assert not any("SPLIT_UNSHADOWED" in d for d in defs0)
    iv = lights[-1]
    # lights without shadows in both parts, and shadowed ones after them
    assert iv.sphere_unshadowed > 0 and iv.tail_unshadowed > 0
    assert iv.sphere_unshadowed < iv.sphere_count
    assert iv.tail_unshadowed < iv.count - iv.point_count - iv.sphere_count
    assert float(plain.max()) > 0.0
    np.testing.assert_array_equal(split, plain)


@pytest.mark.gl
@pytest.mark.parametrize("method", ["reference", "tiled"])
def test_shadows_switched_off_are_gone_in_the_next_frame(gl_ctx, method):
    """A light whose ``shadow:enable`` is edited off keeps its atlas map until the
    atlas forgets it, but no method may read that map from the next frame on: the
    reference shades it in its loop without shadow code, tiled from its record; both
    equal a fresh engine of the edited stage."""
    from pxr import UsdLux

    (case,) = parse_scene("gen:lights:40:shadow_fraction=1")
    stage = case.build()
    opts = {"tile_cap": None} if method == "tiled" else {}
    settings = dict(width=64, height=36, lighting=method, method_options=opts)
    eng = Engine(stage, RenderSettings(**settings))
    try:
        shadowed = eng.render()
        before = eng.aovs["color"][..., :3].copy()
        for prim in stage.Traverse():
            if prim.HasAPI(UsdLux.ShadowAPI):
                UsdLux.ShadowAPI(prim).CreateShadowEnableAttr(False)
        eng.render()
        after = eng.aovs["color"][..., :3].copy()
    finally:
        eng.release()
    assert shadowed is not None
    fresh = Engine(stage, RenderSettings(**settings))
    try:
        fresh.render()
        want = fresh.aovs["color"][..., :3].copy()
    finally:
        fresh.release()
    assert not np.array_equal(before, want)  # the shadows did show before the edit
    np.testing.assert_array_equal(after, want)
