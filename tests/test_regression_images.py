"""Pixel regression: every lighting method on four small scenes against EXRs written
before the render-core refactor (``tools/make_regression_images.py``).

Deterministic methods must match with relMSE <= 1e-6; STB with the same seed must be
identical. A change meant to alter pixels regenerates the data and says so. The
``stb_talk`` rows (``-o reuse=off``) are the ``stb`` images from before the reuse became
STB's default.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
DATA = REPO / "tests" / "data" / "regression"
SIZE = (128, 72)
METHODS = ("reference", "sun", "tiled", "clustered", "lighttree", "stb")


@dataclass(frozen=True)
class Case:
    name: str
    scene: str  # path relative to the repository root
    lighting: str
    accumulate: int = 1
    options: dict = field(default_factory=dict, hash=False, compare=False)


def _cases() -> list[Case]:
    scenes = {
        "default": "usd_scenes/default.usda",
        "lights64": "tests/data/regression/lights64.usda",
        "ies12": "tests/data/regression/ies12.usda",
        "chess24": "tests/data/regression/chess24.usda",
    }
    out = []
    for key, path in scenes.items():
        opts = {"shadows": False} if key == "chess24" else {}
        for m in METHODS:
            out.append(Case(f"{key}.{m}", path, m, options=opts))
        out.append(Case(f"{key}.stb.acc4", path, "stb", accumulate=4, options=opts))
        # The talk's pipeline: its images are the `stb` rows' from before the reservoir
        # reuse became STB's default (issue 31), kept as they were.
        talk = {**opts, "reuse": False}
        out.append(Case(f"{key}.stb_talk", path, "stb", options=talk))
        out.append(Case(f"{key}.stb_talk.acc4", path, "stb", accumulate=4, options=talk))
    return out


CASES = _cases()


#: How the stored stages reach ../shared (chess24: the OpenChessSet), relative to their
#: folder; with the data elsewhere (``STB_SHARED``, a checkout not beside ../shared) the
#: stage is opened from its text with that reference made absolute.
_SHARED_REF = "@../../../../shared/"


def _stage(case: Case):
    """The case's stage: its file, or (it references ../shared and the shared data is
    not there) an in-memory copy whose reference points at ``conftest.SHARED``."""
    from conftest import SHARED

    path = REPO / case.scene
    text = path.read_text()
    if _SHARED_REF not in text or (REPO.parent / "shared").resolve() == SHARED:
        return str(path)
    from pxr import Sdf, Usd

    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.ImportFromString(text.replace(_SHARED_REF, f"@{SHARED.as_posix()}/"))
    return Usd.Stage.Open(layer)


def render_case(case: Case) -> np.ndarray:
    import stb_hydra.api as api

    return api.render(
        _stage(case),
        width=SIZE[0],
        height=SIZE[1],
        lighting=case.lighting,
        accumulate=case.accumulate,
        seed=7,
        **case.options,
    )


def _relmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.mean((a - b) ** 2 / (b * b + 1e-2)))


@pytest.mark.gl
@pytest.mark.slow
@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_pixels_match_regression_data(case: Case, gl_ctx, testdata) -> None:
    from stb_hydra.io.images import read_image

    ref, _ = read_image(DATA / f"{case.name}.exr")
    img = render_case(case)
    assert img.shape == (*ref.shape[:2], 3)
    assert np.all(np.isfinite(img))
    if case.lighting != "sun":  # sun-only on a stage without a sun is black by design
        assert float(ref.max()) > 0.0, "regression image is black: the data is broken"
    if case.lighting == "stb":  # stb_talk too
        np.testing.assert_array_equal(img, ref[..., :3], err_msg=f"{case.name} changed")
    else:
        err = _relmse(img, ref[..., :3])
        assert err <= 1e-6, f"{case.name}: relMSE {err:.3g} against the regression image"
