"""The exact baselines on real GL: without caps `tiled`, `clustered` (CPU and GPU
assignment) and `lighttree` (hybrid, tree-only) equal `reference`; a tile cap drops
lights, counts them and darkens exactly the tiles it dropped in. Small images."""

from __future__ import annotations

import numpy as np
import pytest
from stagegen import BOX_USDA, USDA_HEADER, camera_usda, ground_usda, usda_stage

from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings
from stb_hydra.renderer.lighting import available
from stb_hydra.renderer.lighting.base import light_loops
from stb_hydra.renderer.records import InViewLights

W, H = 192, 108
TOL = 1e-4


def relmse(a, b, eps=1e-2):
    return float(np.mean((a - b) ** 2 / (b**2 + eps)))


def small_lights_scene(
    n: int,
    seed: int = 3,
    ortho: bool = False,
    spread: float = 9.0,
    models: tuple[str, ...] = (),
) -> str:
    """Ground + box + n lights with short authored ranges (0.6-3 m) 0.2-2 m above the
    ground, a third of them spots: culling matters (lists are far shorter than n).
    ``models`` turns some of the 5 cm spheres into other light models (the exact
    methods' loops by model, issue 34): "point" every 4th light radius 0, "wide" every
    5th radius 0.4 (never narrow against the ground), "rect" every 6th a 0.4 x 0.1 m
    RectLight (a spot: facing down; the general loop)."""
    rng = np.random.default_rng(seed)
    s = [
        USDA_HEADER
        + camera_usda((0, 9, 9), -45, clipping=(0.1, 200), ortho=ortho)
        + ground_usda(30)
        + BOX_USDA
    ]
    for i in range(n):
        p = rng.uniform([-spread, 0.2, -spread], [spread, 2.0, spread])
        c = rng.uniform(0.3, 1.0, 3)
        cone = i % 3 == 0
        extra = (
            "    float inputs:shaping:cone:angle = 50\n"
            "    float inputs:shaping:cone:softness = 0.3\n"
            "    float xformOp:rotateX = -90\n"
            if cone
            else ""
        )
        api = '"ShapingAPI", "StbLightAPI"' if cone else '"StbLightAPI"'
        order = '"xformOp:translate", "xformOp:rotateX"' if cone else '"xformOp:translate"'
        kind, size = "SphereLight", "    float inputs:radius = 0.05\n"
        if "point" in models and i % 4 == 1:
            size = "    float inputs:radius = 0\n"
        elif "wide" in models and i % 5 == 2:
            size = "    float inputs:radius = 0.4\n"
        elif "rect" in models and i % 6 == 3:
            kind = "RectLight"
            size = "    float inputs:width = 0.4\n    float inputs:height = 0.1\n"  # a spot
        s.append(
            f'def {kind} "L{i}" (\n    prepend apiSchemas = [{api}]\n)\n{{\n'
            f"    float inputs:intensity = {rng.uniform(2000, 20000):.1f}\n"
            f"{size}"
            f"    float stb:range = {rng.uniform(0.6, 3.0):.3f}\n"
            f"    color3f inputs:color = ({c[0]:.3f}, {c[1]:.3f}, {c[2]:.3f})\n{extra}"
            f"    double3 xformOp:translate = ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f})\n"
            f"    uniform token[] xformOpOrder = [{order}]\n}}\n"
        )
    return "".join(s)


def render(stage, method, **opts):
    eng = Engine(stage, RenderSettings(width=W, height=H, lighting=method, method_options=opts))
    try:
        frame = eng.render_frame()
        img = eng.aovs["color"][..., :3].copy()
        extra = eng.method.tile_totals() if method == "tiled" else None
        rows = frame.get(InViewLights).rows
        return img, dict(frame.stats), extra, eng.delegate.light_table.range[rows]
    finally:
        eng.release()


@pytest.fixture(scope="module")
def scene(gl_ctx):
    stage = usda_stage(small_lights_scene(160))
    ref, stats, _x, _r = render(stage, "reference")
    assert stats["fov_lights"] > 100 and ref.max() > 0
    return stage, ref


def test_registered():
    assert {"tiled", "clustered", "lighttree", "reference", "stb", "sun"} <= set(available())


EXACT = [
    ("tiled", {"tile_cap": None}),
    ("clustered", {}),
    ("clustered", {"assign": "gpu"}),
    ("lighttree", {}),
    ("lighttree", {"slices": 4}),  # coarse slices: the heuristic picks trees
    ("lighttree", {"mode": "tree", "slices": 0, "leaf": 2}),  # the paper's tree-only
]


@pytest.mark.parametrize(("method", "opts"), EXACT, ids=[f"{m}-{o}" for m, o in EXACT])
def test_uncapped_methods_equal_reference(scene, method, opts):
    stage, ref = scene
    img, stats, _x, _r = render(stage, method, **opts)
    assert relmse(img, ref) <= TOL
    if method != "lighttree":  # same summation order: identical to the last bit
        np.testing.assert_array_equal(img, ref)
    assert stats.get("dropped_lights", 0) == 0
    # culling did something: far fewer entries than cells x lights
    cells = stats.get("clusters", -(-W // 16) * -(-H // 16))
    share = 0.5 if opts.get("slices") == 0 else 0.25  # 2D 64 px tiles cull less
    assert stats["list_entries"] < share * cells * stats["fov_lights"]
    if opts.get("slices") == 4:
        assert stats["tree_cells"] > 0
    if opts.get("mode") == "tree":
        assert stats["list_cells"] == 0 and stats["tree_cells"] > 0


#: Scenes whose in-view lights fill every light model's loop (issue 34): point, narrow
#: and wide spheres (no general loop: the wide-sphere loop runs), and the same with rect
#: lights (the general loop, which then also takes the wide spheres).
MODEL_SCENES = {
    "point+spheres": (("point", "wide"), {"point", "sphere_narrow", "sphere_wide"}),
    "every-model": (("point", "wide", "rect"), {"point", "sphere_narrow", "general"}),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(MODEL_SCENES))
def test_every_light_model_loop_equals_reference(gl_ctx, name):
    """With every light model in view, each in its loop (the LOOP_* defines the scene
    compiles), tiled and clustered equal the reference to the last bit and the light
    tree to relMSE 1e-4."""
    models, loops = MODEL_SCENES[name]
    stage = usda_stage(small_lights_scene(80, seed=7, models=models))
    eng = Engine(stage, RenderSettings(width=W, height=H, lighting="reference"))
    try:
        iv = eng.render_frame().get(InViewLights)
        ref = eng.aovs["color"][..., :3].copy()
        parts = (iv.point_count, iv.sphere_count, iv.wide_sphere_count)
        rest = iv.count - sum(parts)
        assert min(parts) > 0 and (rest > 0) == ("rect" in models), parts
        assert light_loops(eng.method.light_models) == loops
    finally:
        eng.release()
    assert ref.max() > 0
    # the tree-only light tree with 2-light leaves: pixels walk several leaves, each
    # through every model's loop (lighttree_lighting.frag's leaf walk, issue 34)
    tree_only = {"mode": "tree", "slices": 0, "leaf": 2}
    for method, opts in [
        ("tiled", {"tile_cap": None}),
        ("clustered", {}),
        ("lighttree", {}),
        ("lighttree", tree_only),
    ]:
        img = render(stage, method, **opts)[0]
        assert relmse(img, ref) <= TOL, (method, opts)
        if method != "lighttree":
            np.testing.assert_array_equal(img, ref)


def test_tiled_cap_drops_counts_and_darkens_where_it_dropped(scene):
    stage, ref = scene
    cap = 6
    img, stats, totals, _r = render(stage, "tiled", tile_cap=cap)
    over = totals > cap
    assert over.any() and (~over).any()
    assert stats["dropped_lights"] == int(np.maximum(totals - cap, 0).sum()) > 0
    assert stats["tiles_over_cap"] == int(over.sum())
    assert stats["max_tile_lights"] == int(totals.max())
    # per-pixel tile mask (top row first like the image; GL tile rows are bottom-up)
    rows = (H - 1 - np.arange(H)) // 16
    cols = np.arange(W) // 16
    pix_over = over[rows][:, cols]
    # every term is >= 0: a subset sum never exceeds the full one
    assert np.all(img <= ref)
    np.testing.assert_array_equal(img[~pix_over], ref[~pix_over])
    lum = img.sum(-1)
    lref = ref.sum(-1)
    darker = [
        lum[r0 : r0 + 16, c0 : c0 + 16].sum() < lref[r0 : r0 + 16, c0 : c0 + 16].sum()
        for r0 in range(0, H, 16)
        for c0 in range(0, W, 16)
        if pix_over[r0, c0]
    ]
    assert np.mean(darker) > 0.5
    assert lum.sum() < lref.sum()


def test_clustered_cap_counts_drops(scene):
    stage, ref = scene
    img, stats, _x, _r = render(stage, "clustered", cap=2)
    img_g, stats_g, _x, _r = render(stage, "clustered", cap=2, assign="gpu")
    assert stats["dropped_lights"] > 0 and stats_g["dropped_lights"] > 0
    assert np.all(img <= ref) and img.sum() < ref.sum()
    assert np.all(img_g <= ref) and img_g.sum() < ref.sum()


def test_default_tile_cap_is_64(scene):
    stage, ref = scene
    img, stats, totals, _r = render(stage, "tiled")
    assert stats["tile_cap"] == 64
    assert totals.max() <= 64 and stats["dropped_lights"] == 0
    np.testing.assert_array_equal(img, ref)


def test_orthographic_camera(gl_ctx):
    stage = usda_stage(small_lights_scene(60, seed=5, ortho=True))
    ref = render(stage, "reference")[0]
    assert ref.max() > 0
    for method, opts in [("tiled", {"tile_cap": None}), ("clustered", {}), ("lighttree", {})]:
        assert relmse(render(stage, method, **opts)[0], ref) <= TOL, method


def test_courtyard_with_ies_cones_shadows_sun(gl_ctx, repo):
    stage = str(repo / "usd_scenes" / "default.usda")
    ref = render(stage, "reference")[0]
    for method, opts in [("tiled", {"tile_cap": None}), ("clustered", {}), ("lighttree", {})]:
        assert relmse(render(stage, method, **opts)[0], ref) <= TOL, method


def test_no_local_lights_falls_back_to_sun_and_ambient(gl_ctx):
    text = small_lights_scene(0) + (
        'def DistantLight "Sun"\n{\n    float inputs:intensity = 3\n'
        "    float3 xformOp:rotateXYZ = (-60, 20, 0)\n"
        '    uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]\n}\n'
    )
    stage = usda_stage(text)
    ref = render(stage, "reference")[0]
    assert ref.max() > 0
    for method in ("tiled", "clustered", "lighttree"):
        np.testing.assert_array_equal(render(stage, method)[0], ref)


@pytest.mark.parametrize(
    ("method", "opts"),
    [
        ("tiled", {"tile_cap": "lots"}),
        ("tiled", {"bogus": 1}),
        ("clustered", {"assign": "fpga"}),
        ("clustered", {"slices": 1000}),
        ("clustered", {"tile": 1}),
        ("clustered", {"near_split": 5.0, "far": 2.0}),
        ("lighttree", {"mode": "forest"}),
        ("lighttree", {"leaf": 0}),
    ],
)
def test_bad_options_are_rejected(gl_ctx, method, opts):
    stage = usda_stage(small_lights_scene(2))
    with pytest.raises(ValueError):
        Engine(stage, RenderSettings(width=32, height=18, lighting=method, method_options=opts))
