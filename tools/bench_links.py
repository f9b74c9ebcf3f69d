"""Frame time with and without a light link (issue 30): ``usd_scenes/default.usda`` at
320x180, reference and stb, wall clock with ``ctx.finish()`` per frame (timer queries
are meaningless on llvmpipe). One torch (Gate_W, not an instance) gets a
``collection:lightLink`` on the session layer, which switches on the G-buffer's link
target, the link SSBO and the mask tests in every lighting shader:

* ``overhead``: it includes ``/World`` (every prim it lit before: the same image), so
  the difference is the machinery alone;
* ``ground``: it lights the ground only (a real link: it also skips the light elsewhere).

    python tools/bench_links.py [--frames 12] [--width 320 --height 180] [--methods reference,stb]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

from pxr import Sdf, Usd, UsdLux

import stb_hydra  # noqa: F401  (schema registration)
from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings

LIGHT = "/World/Lights/Torches/Gate_W/Light"
TARGETS = {"overhead": "/World", "ground": "/World/Geometry/Ground"}


def engine(method: str, link: str | None, w: int, h: int) -> Engine:
    stage = Usd.Stage.Open("usd_scenes/default.usda")
    if link:
        with Usd.EditContext(stage, stage.GetSessionLayer()):
            col = UsdLux.LightAPI(stage.GetPrimAtPath(LIGHT)).GetLightLinkCollectionAPI()
            col.CreateIncludeRootAttr(False)
            col.CreateIncludesRel().SetTargets([Sdf.Path(TARGETS[link])])
    eng = Engine(stage, RenderSettings(width=w, height=h, lighting=method))
    for _ in range(2):  # warm-up: shaders, shadow maps
        eng.render_frame()
    eng.ctx.finish()
    return eng


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=180)
    ap.add_argument("--methods", default="reference,stb")
    a = ap.parse_args()
    out = {}
    modes = ("none", "overhead", "ground")
    for method in a.methods.split(","):
        engs = {m: engine(method, None if m == "none" else m, a.width, a.height) for m in modes}
        try:
            times: dict[str, list[float]] = {m: [] for m in modes}
            # Frame by frame, the three engines in a rotating order: a shared machine's
            # drift hits all of them alike.
            for i in range(a.frames):
                for m in modes[i % 3 :] + modes[: i % 3]:
                    e = engs[m]
                    t0 = time.perf_counter()
                    e.render_frame()
                    e.ctx.finish()
                    times[m].append((time.perf_counter() - t0) * 1e3)
            med = {m: statistics.median(times[m]) for m in modes}
            out[method] = {
                **{f"{m}_ms": round(med[m], 2) for m in modes},
                **{f"{m}_ratio": round(med[m] / med["none"], 3) for m in modes[1:]},
                "g_link": {m: "g_link" in engs[m].buffers.textures for m in modes},
                "frames": a.frames,
            }
        finally:
            for e in engs.values():
                e.release()
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
