"""Previewer frame rate and UI/HUD overhead, in a real window (``docs/PERFORMANCE.md``).

    python -m stb_hydra.preview.bench SCENE [--width 640 --height 360] [--frames 60]

The camera tumbles by 2 px every frame (the interactive case: ``temporal=taa``, a new
frame each tick); ``--still`` keeps it still (accumulation, one sample a tick).
Frames alternate between panels shown and hidden, in one process, so both see the same
machine load; each tick is timed from input to ``ctx.finish()`` after the swap.
Prints medians (ms) and the overhead ratio as JSON.
"""

from __future__ import annotations

import argparse
import json
import time

import glfw
import numpy as np

from ..renderer.frame import RenderSettings
from .window import PreviewApp, RunOptions


def measure(
    scene: str,
    width: int,
    height: int,
    frames: int,
    lighting: str,
    still: bool = False,
    moving: str = "taa",
    scale: float = 1.0,
) -> dict[str, float | str]:
    """Median tick times (ms) with and without the panels, and the panels' own time.
    ``still``: no camera motion (accumulation, one new sample a frame) instead of a
    tumble every frame (taa)."""
    settings = RenderSettings(width=width, height=height, lighting=lighting)
    app = PreviewApp(
        scene, settings, RunOptions(), max_samples=1_000_000, moving=moving, scale=scale
    )
    if app.session.error:
        raise SystemExit(f"stb preview bench: {app.session.error}")
    ctx = app.window.ctx
    ticks: dict[bool, list[float]] = {True: [], False: []}
    ui_ms: list[float] = []
    render_ms: list[float] = []
    try:
        for i in range(frames + 10):
            ui = i % 2 == 0
            app.show_ui = ui
            t0 = time.perf_counter()
            glfw.poll_events()
            if still:
                app.session._force = True  # one more sample even if nothing moved
            else:
                app.session.tumble(2.0, 0.0)
            t1 = time.perf_counter()
            app.session.step()
            ctx.finish()
            t2 = time.perf_counter()
            app._draw()
            ctx.finish()
            dt = (time.perf_counter() - t0) * 1e3
            if i >= 10:  # warm-up: shader compiles, first shadow maps
                ticks[ui].append(dt)
                render_ms.append((t2 - t1) * 1e3)
                if ui:
                    ui_ms.append(app.ui_ms)
    finally:
        app.session.release()
        app.window.close()
    with_ui, without = float(np.median(ticks[True])), float(np.median(ticks[False]))
    return {
        "width": width,
        "height": height,
        "lighting": lighting,
        "camera": "still (accumulate)" if still else f"tumbling ({moving}, scale {scale:g})",
        "temporal": app.session.hud.temporal,
        "frames": frames,
        "tick_ms_with_ui": round(with_ui, 2),
        "tick_ms_without_ui": round(without, 2),
        "ui_overhead_ratio": round(with_ui / without - 1.0, 4),
        "ui_ms": round(float(np.median(ui_ms)), 2),
        "render_ms": round(float(np.median(render_ms)), 2),
        "fps_with_ui": round(1e3 / with_ui, 1),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m stb_hydra.preview.bench")
    ap.add_argument("scene")
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--lighting", default="stb")
    ap.add_argument("--still", action="store_true", help="no camera motion (accumulate)")
    ap.add_argument("--while-moving", choices=("taa", "off"), default="taa")
    ap.add_argument("--moving-scale", type=float, default=1.0)
    a = ap.parse_args(argv)
    m = measure(
        a.scene, a.width, a.height, a.frames, a.lighting, a.still, a.while_moving, a.moving_scale
    )
    print(json.dumps(m))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
