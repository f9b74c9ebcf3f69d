"""The flat Python API (Mitsuba style), run from a checkout::

    import stb_hydra
    from pxr import Usd

    rgb = stb_hydra.render("usd_scenes/default.usda", width=256, height=144)  # (h, w, 3)
    stage = Usd.Stage.Open("usd_scenes/default.usda")
    rgb = stb_hydra.render(stage, lighting="sun", time=12, accumulate=4)

Values are scene-linear radiance (nits) in linear Rec.709, times the camera's
exposure scale (UsdGeomCamera exposure controls); the top row comes first.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np
from pxr import Usd

from .renderer.engine import Engine, RenderError
from .renderer.frame import RenderSettings

__all__ = ["Engine", "RenderError", "RenderSettings", "render", "render_progressive"]


def render(
    stage: Usd.Stage | str | Path,
    *,
    width: int = 256,
    height: int | None = None,
    camera: str | None = None,
    lighting: str = "reference",
    time: float | None = None,
    accumulate: int = 1,
    seed: int = 0,
    ambient: float = 0.0,
    alpha: bool = False,
    **options,
) -> np.ndarray:
    """Render one image of ``stage`` (a ``Usd.Stage`` or a path) at ``time``.

    Returns (h, w, 3) float32 (``alpha``: (h, w, 4)), top row first: scene-linear
    radiance in nits, linear Rec.709 primaries, times the camera's exposure scale.
    ``height`` defaults to the camera's aspect ratio; ``camera`` defaults to the
    stage's first camera, else a free camera framing the stage bounds;
    ``lighting`` is a method name (``stb_hydra.renderer.lighting.METHODS``);
    ``accumulate`` averages that many frames with distinct seeds derived from
    ``seed``; ``ambient`` adds a uniform white dome (nits), e.g. for thumbnails.
    ``temporal="taa"`` (a ``RenderSettings`` field) feeds the ``accumulate`` frames
    through the reprojecting temporal pass (with subpixel jitter) instead of
    averaging them; ``"off"`` shows the last frame alone.
    Other keywords are ``RenderSettings`` fields (``shadows``, ``shadow_budget``
    (default None: every shadow map captured before the frame)...) or, failing that,
    options of the lighting method (e.g. ``N=4`` for stb), validated by its schema.
    """
    settings = _settings(width, height, camera, lighting, seed, accumulate, ambient, options)
    eng = Engine(stage, settings, time=time)
    try:
        eng.request_aovs({"color"})
        eng.render(time)
        return _color(eng, alpha)
    finally:
        eng.release()


def render_progressive(
    stage: Usd.Stage | str | Path,
    counts: Iterable[int],
    *,
    width: int = 256,
    height: int | None = None,
    camera: str | None = None,
    lighting: str = "reference",
    time: float | None = None,
    seed: int = 0,
    ambient: float = 0.0,
    alpha: bool = False,
    **options,
) -> dict[int, np.ndarray]:
    """The accumulated image after each of ``counts`` frames, from one accumulation of
    ``max(counts)`` frames: ``{count: image}``, each the image ``render(...,
    accumulate=count)`` returns (the same seeds), at the cost of ``max(counts)``
    frames. For convergence studies (error against the frame count). The keywords are
    :func:`render`'s."""
    counts = list(counts)  # the engine checks them (>= 1, not empty)
    settings = _settings(
        width, height, camera, lighting, seed, max(counts, default=1), ambient, options
    )
    eng = Engine(stage, settings, time=time)
    try:
        eng.request_aovs({"color"})
        return {n: _color(eng, alpha) for n, _frame in eng.render_progressive(counts, time)}
    finally:
        eng.release()


def _settings(
    width: int,
    height: int | None,
    camera: str | None,
    lighting: str,
    seed: int,
    accumulate: int,
    ambient: float,
    options: dict,
) -> RenderSettings:
    """``RenderSettings`` from the API's keywords: ``options`` that are settings fields
    go there, the others are the lighting method's options."""
    fields = set(RenderSettings.__dataclass_fields__)
    extra = {k: v for k, v in options.items() if k in fields}
    method_options = {k: v for k, v in options.items() if k not in fields}
    return RenderSettings(
        width=width,
        height=height,
        camera=camera,
        lighting=lighting,
        seed=seed,
        accumulate=accumulate,
        ambient=ambient,
        method_options=method_options,
        **extra,
    )


def _color(eng: Engine, alpha: bool) -> np.ndarray:
    img = eng.aovs["color"]
    return np.ascontiguousarray(img if alpha else img[..., :3])
