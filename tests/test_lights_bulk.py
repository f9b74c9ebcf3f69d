"""The bulk light reader (scene/lights_bulk.py) against the single-light reader.

The peer is ``read_light``, the reader every light test checks against closed forms
and published values: the bulk path must give the same records (every field), the
same warnings for bad input, the same light-table rows, and an edit of one light
must still re-read and rewrite that light only.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from pxr import Usd

from stb_hydra.renderer.delegate import RenderDelegate
from stb_hydra.renderer.light_table import LightTable
from stb_hydra.renderer.render_index import RenderIndex
from stb_hydra.scene import lights_bulk
from stb_hydra.scene.lights import LightReadContext, read_light
from stb_hydra.scene.lights_bulk import LightItem, read_lights
from stb_hydra.scene.prims import LightPrim
from stb_hydra.scene.stage_scene_index import StageSceneIndex
from stb_hydra.scenegen.lights import build_lights_stage

_HEADER = '#usda 1.0\n(\n    metersPerUnit = 1\n    upAxis = "Y"\n)\n'

#: Lights the bulk path reads itself and lights it must hand to read_light (bad or
#: unusual input: each warns there), on a parent scaled by 2.
_ODD_LIGHTS = """
def Xform "W" (
)
{
    double3 xformOp:scale = (2, 2, 2)
    uniform token[] xformOpOrder = ["xformOp:scale"]

    def SphereLight "plain"
    {
    }
    def SphereLight "point"
    {
        bool treatAsPoint = 1
        float inputs:radius = 0.2
    }
    def SphereLight "norm"
    {
        bool inputs:normalize = 1
        float inputs:intensity = 30
        float inputs:exposure = 1.5
    }
    def DiskLight "disk"
    {
        float inputs:radius = 0.3
        color3f inputs:color = (0.2, 0.5, 1)
    }
    def RectLight "rect"
    {
        float inputs:width = 2
        float inputs:height = 0.5
        bool inputs:normalize = 1
    }
    def CylinderLight "cyl"
    {
        float inputs:length = 3
        float inputs:radius = 0.1
        double3 xformOp:rotateXYZ = (0, 40, 10)
        uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]
    }
    def SphereLight "shaping_api" (prepend apiSchemas = ["ShapingAPI"])
    {
    }
    def SphereLight "spot"
    {
        float inputs:shaping:cone:angle = 30
        float inputs:shaping:cone:softness = 1.5
        float inputs:shaping:focus = 2
        color3f inputs:shaping:focusTint = (1, 0.5, 0)
    }
    def SphereLight "temp"
    {
        bool inputs:enableColorTemperature = 1
        float inputs:colorTemperature = 3000
    }
    def SphereLight "temp_off"
    {
        float inputs:colorTemperature = 3000
    }
    def SphereLight "shadowed"
    {
        bool inputs:shadow:enable = 0
        color3f inputs:shadow:color = (2, 0.5, -1)
        float inputs:shadow:distance = 4
        float inputs:shadow:falloff = 9
        float inputs:shadow:falloffGamma = 0
    }
    def SphereLight "stb"
    {
        token stb:shadow:update = "dynamic"
        token stb:mobility = "static"
        bool stb:baked = 1
        float stb:range = 7
        float inputs:diffuse = 0.5
        float inputs:specular = 0
    }
    def SphereLight "range_nan"
    {
        float stb:range = nan
    }
    def SphereLight "range_neg"
    {
        float stb:range = -3
    }
    def SphereLight "bad_intensity"
    {
        float inputs:intensity = nan
    }
    def SphereLight "neg_intensity"
    {
        float inputs:intensity = -1
    }
    def SphereLight "bad_exposure"
    {
        float inputs:exposure = 200
    }
    def SphereLight "neg_colour"
    {
        color3f inputs:color = (1, -0.5, 1)
    }
    def SphereLight "string_colour"
    {
        string inputs:color = "red"
    }
    def SphereLight "neg_radius"
    {
        float inputs:radius = -1
    }
    def SphereLight "zero_radius"
    {
        float inputs:radius = 0
    }
    def SphereLight "zero_norm"
    {
        float inputs:radius = 0
        bool inputs:normalize = 1
    }
    def RectLight "neg_width"
    {
        float inputs:width = -1
    }
    def CylinderLight "inf_length"
    {
        float inputs:length = inf
    }
    def SphereLight "wide_cone"
    {
        float inputs:shaping:cone:angle = 200
    }
    def SphereLight "nan_focus"
    {
        float inputs:shaping:focus = nan
    }
    def SphereLight "bad_tint"
    {
        int[] inputs:shaping:focusTint = [1, 2]
    }
    def SphereLight "bad_update"
    {
        token stb:shadow:update = "sometimes"
    }
    def SphereLight "bad_mobility"
    {
        token stb:mobility = "fixed"
    }
    def SphereLight "legacy"
    {
        float intensity = 5
    }
    def SphereLight "missing_ies"
    {
        asset inputs:shaping:ies:file = @no_such.ies@
    }
    def SphereLight "huge"
    {
        float inputs:intensity = 1e30
        float inputs:exposure = 30
    }
    def SphereLight "far"
    {
        double3 xformOp:translate = (1e20, 0, 0)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
    def DistantLight "sun"
    {
        float inputs:intensity = 3
    }
    def DomeLight "dome"
    {
    }
}
"""


def _fields(lp: LightPrim) -> dict:
    return {k: getattr(lp, k) for k in LightPrim.__dataclass_fields__}


def _assert_same(a: LightPrim, b: LightPrim) -> None:
    fa, fb = _fields(a), _fields(b)
    assert fa.keys() == fb.keys()
    for k in fa:
        va, vb = fa[k], fb[k]
        if isinstance(va, np.ndarray) or isinstance(vb, np.ndarray):
            np.testing.assert_allclose(
                np.asarray(va, float),
                np.asarray(vb, float),
                rtol=1e-12,
                atol=1e-300,
                err_msg=f"{a.path}: {k}",
            )
        elif isinstance(va, float) and isinstance(vb, float):
            assert va == pytest.approx(vb, rel=1e-12, abs=1e-300) or (
                math.isnan(va) and math.isnan(vb)
            ), f"{a.path}: {k} {va} != {vb}"
        else:
            assert va == vb, f"{a.path}: {k} {va!r} != {vb!r}"


def _read_both(stage: Usd.Stage) -> tuple[list[LightPrim], list[LightPrim], list[str], list[str]]:
    """(bulk records, single records, bulk warnings, single warnings) of every light."""
    from stb_hydra.scene.lights import light_type_of

    cache = __import__("pxr").UsdGeom.XformCache(Usd.TimeCode(1.0))
    items = []
    for p in stage.Traverse():
        if light_type_of(p) is None:
            continue
        m = np.array(cache.GetLocalToWorldTransform(p), dtype=np.float64).reshape(4, 4)
        items.append(LightItem(p, str(p.GetPath()), m, True, None))
    warned: dict[str, list[str]] = {"bulk": [], "single": []}

    def ctx(key: str) -> LightReadContext:
        return LightReadContext(stage, np.eye(4), warned[key].append, lambda k, m: None)

    t = Usd.TimeCode(1.0)
    bulk = read_lights(items, ctx("bulk"), t)
    single = [read_light(i.prim, ctx("single"), t, i.world, True, i.path) for i in items]
    return bulk, single, warned["bulk"], warned["single"]


def test_bulk_reader_matches_single_reader_on_a_generated_scene():
    """Every light type the generator writes (spheres, spots with cones, disks,
    rects, IES lights), colour temperatures, shadows, animation: field for field."""
    stage = build_lights_stage(n_lights=600, seed=3, animated=20)
    bulk, single, wb, ws = _read_both(stage)
    assert len(bulk) == 600
    for a, b in zip(bulk, single, strict=True):
        _assert_same(a, b)
    assert wb == ws == []
    assert any(lp.ies_file for lp in bulk) and any(lp.has_cone for lp in bulk)


def test_bulk_reader_matches_single_reader_on_odd_and_bad_lights():
    """Edge values the bulk path models (scale, normalise, cylinder, treatAsPoint, an
    applied ShapingAPI without inputs, clamped shadow colour, stb:*) and bad input it
    hands back to read_light: the same records and the same warnings."""
    stage = Usd.Stage.CreateInMemory()
    stage.GetRootLayer().ImportFromString(_HEADER + _ODD_LIGHTS)
    bulk, single, wb, ws = _read_both(stage)
    assert len(bulk) == _ODD_LIGHTS.count('Light "')
    for a, b in zip(bulk, single, strict=True):
        _assert_same(a, b)
    assert sorted(wb) == sorted(ws)
    bad = {lp.path.rsplit("/", 1)[1] for lp in bulk if not lp.enabled}
    assert {"bad_intensity", "neg_radius", "string_colour", "wide_cone", "far"} <= bad
    assert {"plain", "spot", "stb", "cyl", "norm"}.isdisjoint(bad)


def test_write_many_equals_write_row_by_row():
    stage = build_lights_stage(n_lights=300, seed=5)
    bulk, _single, _wb, _ws = _read_both(stage)
    one, many = LightTable(), LightTable()
    one.set_exposure(4.0)
    many.set_exposure(4.0)
    rows = [one.alloc(lp.path) for lp in bulk]
    assert rows == [many.alloc(lp.path) for lp in bulk]
    layers = np.array([i % 3 - 1 for i in range(len(bulk))])
    for r, lp, layer in zip(rows, bulk, layers, strict=True):
        one.write(r, lp, int(layer))
    many.write_many(np.array(rows), bulk, layers)
    for name, colv in one.cols.items():
        if name != "version":
            np.testing.assert_array_equal(colv, many.cols[name], err_msg=name)


def test_first_sync_is_bulk_and_an_edit_rewrites_one_row():
    """The render index's first sync goes through the bulk reader (same table as
    light-by-light syncs); then one light's edit re-reads and rewrites that light only."""
    stage = build_lights_stage(n_lights=200, seed=7)
    si = StageSceneIndex(stage, 1.0)
    ri = RenderIndex(si, RenderDelegate())
    calls = []
    real = lights_bulk._read_group

    def spy(items, *a, **k):
        calls.append(len(items))
        return real(items, *a, **k)

    lights_bulk._read_group = spy
    try:
        ri.sync_all()
    finally:
        lights_bulk._read_group = real
    assert calls == [200]
    table = ri.delegate.light_table
    # The same stage synced light by light (below the bulk threshold each time).
    si2 = StageSceneIndex(stage, 1.0)
    ri2 = RenderIndex(si2, RenderDelegate())
    for path, rp in ri2.prims.items():
        sp = si2.get_prim(path)
        rp.sync(sp.data_source, ri2._dirty.pop(path))
    t2 = ri2.delegate.light_table
    for name, colv in table.cols.items():
        if name != "version":
            np.testing.assert_array_equal(colv, t2.cols[name], err_msg=name)

    path = "/World/Lights/L000042"
    prim = stage.GetPrimAtPath(path)
    assert prim, "the generator's light naming changed"
    versions = table.cols["version"][: table.n_rows].copy()
    attr = prim.GetAttribute("inputs:intensity")
    attr.Set(attr.Get() * 2.0)
    si.apply_pending_updates()
    assert ri.sync_all() == 1
    changed = np.nonzero(table.cols["version"][: table.n_rows] != versions)[0]
    assert changed.tolist() == [table.rows[path]]
