"""The engine's per-frame shortcuts give what the full per-frame work gives (issue 32,
"Performance is a feature"): the delegate's incremental draw-batch rebuild (a mesh that
synced nothing keeps its part, an unchanged batch is kept whole, a changed one keeps its
GPU objects) against a fresh engine's from-scratch rebuild at the same time; the
shadow atlas' per-light work recomputed only for the lights a changed batch reaches,
against recomputing every light's; the colour pass' exposure uniforms pushed only on a
change, against the exposures' own images."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, Sdf, UsdGeom, UsdShade

from stb_hydra import Engine, RenderSettings, limits
from stb_hydra.scenegen.orbs import build_orbs_stage

W, H = 32, 18


def _settings() -> RenderSettings:
    return RenderSettings(
        width=W,
        height=H,
        lighting="stb",
        temporal="taa",
        shadow_budget=limits.SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT,
    )


def _key(b) -> tuple:
    return (b.geometry_key, b.material.key(), b.dynamic, b.links)


def _state(d) -> dict:
    """The delegate's batches by key (their order follows the render index's prims,
    which edits may reorder: a draw order, not an image) and its bounds."""
    rows = np.concatenate((*d.receiver_boxes[:2], d.receiver_boxes[2][:, None]), axis=1)
    return {
        "batches": {_key(b): b for b in d.batches},
        "receivers": rows[np.lexsort(rows.T[::-1])],
        "mesh_bounds": d.mesh_bounds,
        "scene_bounds": d.scene_bounds,
    }


def _assert_same(got: dict, ref: dict, when: str) -> None:
    assert sorted(map(repr, got["batches"])) == sorted(map(repr, ref["batches"])), when
    assert len(got["batches"]) == len(ref["batches"]), when
    for k, b in ref["batches"].items():
        a = got["batches"][k]
        np.testing.assert_array_equal(a.models, b.models, err_msg=when)
        np.testing.assert_array_equal(a.bounds[0], b.bounds[0], err_msg=when)
        np.testing.assert_array_equal(a.bounds[1], b.bounds[1], err_msg=when)
        assert a.material == b.material, when
    np.testing.assert_array_equal(got["receivers"], ref["receivers"], err_msg=when)
    assert got["mesh_bounds"].keys() == ref["mesh_bounds"].keys(), when
    for p, (lo, hi) in ref["mesh_bounds"].items():
        np.testing.assert_array_equal(got["mesh_bounds"][p][0], lo, err_msg=f"{when} {p}")
        np.testing.assert_array_equal(got["mesh_bounds"][p][1], hi, err_msg=f"{when} {p}")
    np.testing.assert_array_equal(got["scene_bounds"][0], ref["scene_bounds"][0], err_msg=when)
    np.testing.assert_array_equal(got["scene_bounds"][1], ref["scene_bounds"][1], err_msg=when)


def _stone_shader(stage) -> UsdShade.Shader:
    mat = stage.GetPrimAtPath("/World/Looks/Stone")
    return next(UsdShade.Shader(p) for p in mat.GetAllChildren() if p.IsA(UsdShade.Shader))


@pytest.mark.gl
def test_incremental_batches_match_a_rebuild_from_scratch(gl_ctx):
    """Orbs fly (transforms every frame), spawn (visibility: batches gain instances), a
    material is edited, a static mesh moved, one frame repeats its time and the last goes
    back in time: after
    each frame the batches, their matrices and bounds, the receiver boxes and the scene
    bounds equal a fresh engine's at that time, every instance buffer holds (this
    frame's, the previous frame's) matrices, and the previous ones are the last frame's
    (the frame's own when the batch was not there or changed its instance count)."""
    stage = build_orbs_stage(4, 6)
    eng = Engine(stage, _settings())
    d = eng.delegate
    shader = _stone_shader(stage)
    last: dict[tuple, np.ndarray] = {}
    kept_whole = 0
    pillars = next(p for p in stage.Traverse() if p.GetName() == "Pillars")
    plan = [1.0, 2.0, 3.0, 3.0, 4.0, "material", 5.0, "move", 6.0, 1.0]
    t = 1.0
    for step in plan:
        if step == "material":
            shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(
                Gf.Vec3f(0.6, 0.2, 0.1)
            )
        elif step == "move":
            UsdGeom.Xformable(pillars).AddTranslateOp().Set(Gf.Vec3d(0.5, 0, 0))
        else:
            t = float(step)
        before = {id(b) for b in d.batches}
        eng.render_frame(t)
        kept_whole += sum(id(b) in before for b in d.batches)
        ref = Engine(stage, _settings(), time=t)  # its first sync: a rebuild from scratch
        _assert_same(_state(d), _state(ref.delegate), f"{step}")
        ref.release()
        for b in d.batches:
            gpu = np.frombuffer(b.instance_buffer.read(), dtype=np.float32).reshape(-1, 32)
            want = np.concatenate([b.models.reshape(-1, 16), b.prev_models.reshape(-1, 16)], 1)
            np.testing.assert_array_equal(gpu, want, err_msg=f"{step} {b.geometry_key}")
            prev = last.get(_key(b))
            expect = prev if prev is not None and prev.shape == b.models.shape else b.models
            np.testing.assert_array_equal(b.prev_models, expect, err_msg=f"{step}")
        last = {_key(b): b.models for b in d.batches}
    assert kept_whole > 0  # the shortcut ran (static batches kept while orbs moved)
    eng.release()


@pytest.mark.gl
def test_shadow_work_of_lights_out_of_reach_is_unchanged(gl_ctx):
    """After each frame, every registered light's triangle work (the shadow cost model's
    input) equals what recomputing all of them gives (the shortcut skips only lights no
    changed batch reaches): orbs fly (dynamic casters; their lights fly too), spawn, and a static
    mesh is moved twice (the torches' static maps in its reach)."""
    stage = build_orbs_stage(6, 8)
    eng = Engine(stage, _settings())
    task = eng.task("shadow_atlas")
    assert task is not None
    sch = task.scheduler
    pillars = next(p for p in stage.Traverse() if p.GetName() == "Pillars")
    for i, t in enumerate([1.0, 2.0, 3.0, 5.0, 6.0, 8.0, 2.0]):
        if i in (2, 4):  # a static mesh moves: the static maps in its reach change work
            UsdGeom.Xformable(pillars).AddTranslateOp(opSuffix=f"m{i}").Set(Gf.Vec3d(1.5, 0, 0))
        eng.render_frame(t)
        keys = list(task._captures)
        got = {k: (sch._lights[k].triangles, sch._lights[k].face_tris) for k in keys}
        task._update_work(keys)
        for k in keys:
            tri, faces = got[k]
            assert sch._lights[k].triangles == tri, (t, k)
            if faces is None:
                assert sch._lights[k].face_tris is None
            else:
                np.testing.assert_array_equal(sch._lights[k].face_tris, faces)
    eng.release()


@pytest.mark.gl
def test_colour_pass_exposure_switches_back_and_forth(gl_ctx):
    """Two passes share one OCIO program with different exposures: run in turn, each
    draws its own exposure's image (the uniforms are pushed again on every change)."""
    from stb_hydra.color.ocio import ColorCorrectionPass, ColorPipeline

    img = np.full((4, 8, 4), 0.18, np.float32)
    img[..., 3] = 1.0
    src = gl_ctx.texture((8, 4), 4, img.tobytes(), dtype="f4")
    a = ColorCorrectionPass(gl_ctx, ColorPipeline(exposure=0.0))
    b = ColorCorrectionPass(gl_ctx, ColorPipeline(exposure=2.0))
    assert a.program is b.program
    ra = a.run_to_array(src, "f4")
    rb = b.run_to_array(src, "f4")
    assert float(rb[..., :3].mean()) > float(ra[..., :3].mean()) + 0.05
    np.testing.assert_array_equal(a.run_to_array(src, "f4"), ra)
    np.testing.assert_array_equal(b.run_to_array(src, "f4"), rb)
    a.pipeline.exposure = 2.0
    np.testing.assert_array_equal(a.run_to_array(src, "f4"), rb)
    src.release()
