"""The suite's shaders are compiled without LLVM's optimisation passes; the images are not.

``tests/conftest.py`` sets ``GALLIVM_PERF=nopt`` for the test processes (llvmpipe then
compiles a program ~2.5x faster and runs it ~1.3x slower: docs/TESTING.md). So that no
bug that only the optimised code shows (a read of an uninitialised variable, undefined
behaviour that the optimiser turns into another value) hides behind it, this test
renders with the optimisation on, in a child process with ``GALLIVM_PERF`` empty, and
asserts the same images as the suite's own. Mesa's shader cache keys its entries on
the flag, so the child never reads an unoptimised program.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / "usd_scenes" / "default.usda"  # spheres, rects, IES, cones, shadows, sun
SIZE = (96, 54)
METHODS = ("reference", "stb")

_CHILD = r"""
import sys
import numpy as np
import stb_hydra.api as api
scene, out, w, h = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
imgs = {m: api.render(scene, width=w, height=h, lighting=m, seed=7) for m in sys.argv[5:]}
np.savez(out, **imgs)
"""


def _render(method: str) -> np.ndarray:
    import stb_hydra.api as api

    return api.render(str(SCENE), width=SIZE[0], height=SIZE[1], lighting=method, seed=7)


def test_optimised_shaders_render_the_suites_images(tmp_path, gl_ctx):
    if os.environ.get("GALLIVM_PERF", "") != "nopt":
        pytest.skip("the suite runs with LLVM's optimisation on: nothing to compare")
    out = tmp_path / "optimised.npz"
    env = {**os.environ, "GALLIVM_PERF": "", "PYTHONPATH": str(REPO)}
    args = [sys.executable, "-c", _CHILD, str(SCENE), str(out), *map(str, SIZE), *METHODS]
    proc = subprocess.run(args, env=env, cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    optimised = np.load(out)
    for m in METHODS:
        a, b = optimised[m], _render(m)
        assert a.shape == b.shape and np.isfinite(a).all()
        assert a.mean() > 0.0, m  # the scene is lit: an all-black pair proves nothing
        # same operations in the same order: equal to float rounding (bit for bit on
        # Mesa 22.3 / LLVM 15); a divergence from undefined behaviour is far larger
        scale = float(np.abs(b).max())
        assert np.abs(a - b).max() <= 1e-5 * scale, m
