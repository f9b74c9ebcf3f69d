"""Shadow-atlas measurements (issue "Shadow atlas manager", Measure).

* ``room``: 50 shadowed lights in a 10 m room (``stb_hydra.scenegen.lights``), static camera:
  frames until every map is fresh, texels per frame against the budget.
* ``lights5000``: the ``stb bench`` generator at 5,000 lights (1,278 shadowed): the
  atlas fill with many small maps; capture time per frame (median / max).
* ``chess``: 500 shadowed lights over the OpenChessSet (``stb_hydra.scenegen.chess``): same.
* ``moving``: the room with 20 of its lights animated: static-map staleness
  (frames a dirty map waited: mean / p95 / max) while lights move.
* ``orbs``: 1,000 frames of the orbs scene (``stb_hydra.scenegen.orbs``: orbs spawn and move,
  dynamic shadows): atlas occupancy and fragmentation at the end, staleness.

The lighting method is ``stb`` (N=1; the atlas work does not depend on the method,
but ``sun`` samples no local shadows and so captures none) at 745x360 unless
``--method`` / ``--size`` say otherwise. Prints a table; ``--json`` writes it.

    .venv/bin/python tools/bench_shadows.py [--cases room,chess,moving,orbs] [--frames 1000]
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np

METHOD = "stb"


def _engine(stage, width, height):
    from stb_hydra import limits
    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings

    eng = Engine(
        stage,
        RenderSettings(
            width=width,
            height=height,
            lighting=METHOD,
            profile=True,
            shadow_budget=limits.SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT,  # real time
        ),
    )
    eng.request_aovs(set())
    eng.aov_output.requested = set()
    return eng


def run_static(stage, width, height, max_frames=400) -> dict:
    """Frames until every shadowed FoV light has a fresh map."""
    eng = _engine(stage, width, height)
    try:
        atlas = eng.task("shadow_atlas")
        texels = []
        capture_ms = []
        fresh_at = None
        t0 = time.perf_counter()
        for i in range(max_frames):
            f = eng.render_frame()
            texels.append(f.stats.get("shadow_texels_rendered", 0))
            tm = eng.timings.frames[-1]
            capture_ms.append(tm.get("prepare.shadow_atlas", 0.0) + tm.get("shadow_atlas", 0.0))
            sch = atlas.scheduler
            keys = atlas.registered_keys()
            if keys and all(sch.is_fresh(k) for k in keys):
                fresh_at = i + 1
                break
        wall = time.perf_counter() - t0
        st = atlas.last_stats
        return {
            "shadowed_lights": st.lights,
            "frames_until_fresh": fresh_at,
            "texels_per_frame_mean": float(np.mean(texels)),
            "texels_per_frame_max": int(np.max(texels)),
            "budget_texels": st.budget_texels,
            # shadow-atlas task wall time per frame (prepare + execute, ctx.finish())
            "capture_ms_median": round(float(np.median(capture_ms)), 1),
            "capture_ms_max": round(float(np.max(capture_ms)), 1),
            "occupancy": round(st.atlas.occupancy, 4),
            "fragmentation": round(st.atlas.fragmentation, 4),
            "downgrades": st.atlas.downgrades,
            "evictions": st.atlas.evictions,
            "unplaced": st.unplaced,
            "undersized": st.undersized,
            "wall_s": round(wall, 1),
        }
    finally:
        eng.release()


def run_animated(stage, width, height, frames, t0_code=1.0, t1_code=None) -> dict:
    """Staleness and atlas state over an animation (time advances one code per frame,
    looping over the stage's time range)."""
    eng = _engine(stage, width, height)
    try:
        atlas = eng.task("shadow_atlas")
        start = stage.GetStartTimeCode() if stage.HasAuthoredTimeCodeRange() else t0_code
        end = stage.GetEndTimeCode() if stage.HasAuthoredTimeCodeRange() else (t1_code or 48.0)
        span = max(end - start, 1.0)
        texels = []
        waits = []
        ages = []
        t0 = time.perf_counter()
        for i in range(frames):
            f = eng.render_frame(time=start + (i % int(span + 1)))
            texels.append(f.stats.get("shadow_texels_rendered", 0))
            st = atlas.last_stats
            waits.append((st.static_wait.mean, st.static_wait.p95, st.static_wait.max))
            ages.append((st.dynamic_age.mean, st.dynamic_age.p95, st.dynamic_age.max))
        wall = time.perf_counter() - t0
        st = atlas.last_stats
        return {
            "frames": frames,
            "shadowed_lights_registered": st.lights,
            "dynamic_maps": st.dynamic_maps,
            "static_wait_mean": round(st.static_wait.mean, 2),
            "static_wait_p95": st.static_wait.p95,
            "static_wait_max": st.static_wait.max,
            "dynamic_refresh_p95": st.dynamic_age.p95,
            "dynamic_refresh_max": st.dynamic_age.max,
            "texels_per_frame_mean": float(np.mean(texels)),
            "texels_per_frame_p95": float(np.percentile(texels, 95)),
            "texels_per_frame_max": int(np.max(texels)),
            "budget_texels": st.budget_texels,
            "occupancy": round(st.atlas.occupancy, 4),
            "fragmentation": round(st.atlas.fragmentation, 4),
            "largest_free_fraction": round(st.atlas.largest_free_fraction, 4),
            "downgrades": st.atlas.downgrades,
            "evictions": st.atlas.evictions,
            "unplaced": st.unplaced,
            "wall_s": round(wall, 1),
        }
    finally:
        eng.release()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", default="room,lights5000,chess,moving,orbs")
    ap.add_argument("--frames", type=int, default=1000, help="frames of the orbs run")
    ap.add_argument("--size", default="745x360")
    ap.add_argument("--json")
    ap.add_argument(
        "--method", default="stb", help="lighting method (one that samples local shadows)"
    )
    a = ap.parse_args(argv)
    global METHOD
    METHOD = a.method
    from pxr import Usd

    import stb_hydra  # noqa: F401
    from stb_hydra.scenegen.chess import main as chess_main
    from stb_hydra.scenegen.lights import build_lights_stage
    from stb_hydra.scenegen.orbs import main as orbs_main

    w, h = (int(x) for x in a.size.split("x"))
    cases = [c.strip() for c in a.cases.split(",") if c.strip()]
    out: dict = {"size": a.size, "method": METHOD, "load_avg_1min": os.getloadavg()[0]}
    tmp = Path(tempfile.mkdtemp(prefix="stb_shadow_bench_"))
    if "room" in cases:
        st = build_lights_stage(n_lights=50, seed=1, shadow_fraction=1.0, size=10.0)
        out["room_50"] = run_static(st, w, h)
        print("room_50", out["room_50"], flush=True)
    if "lights5000" in cases:
        # The stb bench generator at 5,000 lights (1,278 shadowed, ~320 dynamic): the
        # atlas fill, where many small maps per frame test the per-pass charge.
        st = build_lights_stage(n_lights=5000, seed=0)
        out["lights_5000"] = run_static(st, w, h)
        print("lights_5000", out["lights_5000"], flush=True)
    if "chess" in cases:
        p = tmp / "chess.usda"
        chess_main([str(p), "--lights", "500", "--seed", "1"])
        out["chess_500"] = run_static(Usd.Stage.Open(str(p)), w, h)
        print("chess_500", out["chess_500"], flush=True)
    if "moving" in cases:
        st = build_lights_stage(n_lights=50, seed=1, shadow_fraction=1.0, size=10.0, animated=20)
        out["room_50_moving"] = run_animated(st, w, h, 200)
        print("room_50_moving", out["room_50_moving"], flush=True)
    if "orbs" in cases:
        p = tmp / "orbs.usda"
        orbs_main([str(p), "--orbs", "200", "--frames", "240", "--seed", "1"])
        out["orbs_1000"] = run_animated(Usd.Stage.Open(str(p)), w, h, a.frames)
        print("orbs", out["orbs_1000"], flush=True)
    out["load_avg_1min_end"] = os.getloadavg()[0]
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
