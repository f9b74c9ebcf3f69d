"""Layering at run time (import-linter checks the static graph: ``lint-imports``).

scene <- renderer <- apps: the GL-free packages load without the renderer or
moderngl, and the copies of camera maths the shadow package keeps (it may not import
the renderer) stay equal to the renderer's.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest


@pytest.mark.parametrize(
    "module",
    [
        "stb_hydra.shadows",
        "stb_hydra.shadows.capture",
        "stb_hydra.scene.stage_io",
        "stb_hydra.scenegen.lights",
        "stb_hydra.scenegen.chess",
        "stb_hydra.scenegen.orbs",
    ],
)
def test_gl_free_modules_load_without_renderer_or_moderngl(module: str):
    code = (
        f"import json, sys, {module}\n"
        "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] == 'moderngl'\n"
        "      or m.startswith(('stb_hydra.renderer', 'stb_hydra.apps', 'stb_hydra.api')))))"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout.strip().splitlines()[-1]) == []


def test_map_record_layout():
    from stb_hydra import limits
    from stb_hydra.shadows.atlas import AtlasRect
    from stb_hydra.shadows.capture import (
        NORMAL_BIAS_TEXELS,
        RECORD_FLOATS,
        capture_for,
        map_record,
        spot_view_proj,
        texel_angle,
    )

    b = limits.SHADOW_MAP_BORDER_PX
    spot = capture_for((1.0, 2.0, 3.0), (0.0, -1.0, 0.0), 8.0, 0.05, np.radians(30.0), 0)
    omni = capture_for((1.0, 2.0, 3.0), (0.0, -1.0, 0.0), 8.0, 0.05, np.pi, 0)
    assert not spot.omni and omni.omni
    for c in (spot, omni):
        rect = AtlasRect(64, 128, 256)
        rec = map_record(c, rect, 4096)
        assert rec.shape == (RECORD_FLOATS,) and rec.dtype == np.float32
        vp = spot_view_proj(c).astype(np.float32).reshape(16) if not c.omni else np.zeros(16)
        assert np.array_equal(rec[:16], vp)
        assert np.array_equal(rec[16:20], np.float32([*c.position, c.range]))
        assert np.array_equal(rec[20:24], np.float32([64 + b, 128 + b, 256 - 2 * b, c.omni]))
        assert np.array_equal(
            rec[24:28],
            np.float32([c.near, texel_angle(c, 256 - 2 * b), 1 / 4096, NORMAL_BIAS_TEXELS]),
        )
