"""The OpenChessSet as shipped (no overrides) renders with its own looks: MaterialX
``standard_surface`` materials with 2k base colour / roughness / metallic / normal
maps. The board's base colour seen straight down must show the 8 x 8 squares, light
and dark alternating, read from the albedo AOV against the asset's own layout (the
pieces' authored positions put the squares 0.0625 m apart around the origin)."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Usd

from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings

SQUARE = 0.0625  # m: the rooks stand at x = +-0.219 = +-3.5 squares
W = H = 128  # 0.5 m x 0.5 m: 16 px a square


@pytest.mark.slow
def test_chess_board_shows_its_squares_and_loads_without_warnings(tmp_path, testdata, gl_ctx):
    chess = testdata / "scenes" / "OpenChessSet" / "chess_set.usda"
    scene = tmp_path / "top.usda"
    scene.write_text(
        '#usda 1.0\n(\n    metersPerUnit = 1\n    upAxis = "Y"\n)\n'
        f'def Xform "Set" (\n    references = @{chess}@\n)\n{{\n}}\n'
        'def Camera "Top"\n{\n    token projection = "orthographic"\n'
        "    float horizontalAperture = 5\n    float verticalAperture = 5\n"
        "    float2 clippingRange = (0.01, 10)\n"
        "    double3 xformOp:translate = (0, 1, 0)\n    float xformOp:rotateX = -90\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]\n}\n'
        'def DistantLight "Sun"\n{\n    float inputs:intensity = 1\n'
        "    bool inputs:normalize = 1\n}\n"
    )
    stage = Usd.Stage.Open(str(scene))
    eng = Engine(stage, RenderSettings(width=W, height=H, lighting="sun"))
    try:
        eng.request_aovs({"color", "albedo", "depth"})
        eng.render(None)
        alb = np.array(eng.aovs["albedo"][..., :3], dtype=np.float64)
        depth = np.array(eng.aovs["depth"], dtype=np.float64).reshape(H, W)
        warnings = list(eng.delegate.warnings) + list(eng.scene_index.warnings)
        mats = {
            p: sp.material for p, sp in eng.delegate.materials.items() if sp.material is not None
        }
    finally:
        eng.release()
    assert not warnings, warnings
    mx = [m for m in mats.values() if m.source == "MaterialX"]
    assert len(mx) >= 15, sorted(mats)
    # Every look has its normal map; all but the glass pawn tops a base-colour map.
    assert all("normal" in m.textures for m in mx), {p: sorted(m.textures) for p, m in mats.items()}
    assert all("diffuseColor" in m.textures for m in mx if "Pawn_Top" not in m.path)
    # Image top = -Z (the camera's up after rotateX -90); each square sampled at its
    # centre (4 x 4 px) where the board itself is seen (a piece stands nearer).
    lum = alb @ np.array([0.2126, 0.7152, 0.0722])
    board = np.median(depth[depth > 0])
    vals = np.full((8, 8), np.nan)
    for i in range(8):
        for j in range(8):
            cx, cy = int((j + 0.5) * SQUARE * W / 0.5), int((i + 0.5) * SQUARE * H / 0.5)
            patch = (slice(cy - 2, cy + 2), slice(cx - 2, cx + 2))
            if np.all(np.abs(depth[patch] - board) < 0.003):
                vals[i, j] = np.median(lum[patch])
    seen = np.isfinite(vals)
    assert seen.sum() >= 24, seen.sum()
    parity = (np.add.outer(np.arange(8), np.arange(8)) % 2).astype(bool)
    a, b = vals[parity & seen], vals[~parity & seen]
    light, dark = (a, b) if a.mean() > b.mean() else (b, a)
    assert dark.max() < light.min(), vals  # every square on its side of the split
    assert light.mean() > 2.0 * dark.mean(), vals
