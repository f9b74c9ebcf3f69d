"""Cost of the taa pass in an STB frame (llvmpipe or a GPU): per-pass wall times
with ``ctx.finish()`` after every pass (``RenderSettings.profile``), medians over
frames after a warm-up, for --temporal taa and accumulate. The two engines render
their frames in turn, so a machine's changing load falls on both alike.

    .venv/bin/python tools/taa_cost.py usd_scenes/default.usda --width 745 --height 360
"""

from __future__ import annotations

import argparse
import sys

from stb_pass_cost import render_in_turn

from stb_hydra.renderer.frame import RenderSettings

#: Timing keys that are not passes (phases, sub-pass scopes).
_NOT_PASSES = ("sync", "commit", "prepare")


def _settings(w: int, h: int, temporal: str, taa_filter: int) -> RenderSettings:
    return RenderSettings(
        width=w,
        height=h,
        lighting="stb",
        temporal=temporal,
        profile=True,
        taa_filter=taa_filter if temporal == "taa" else 0,
    )


def pass_ms(
    stage: str, w: int, h: int, frames: int, warmup: int, taa_filter: int = 0
) -> dict[str, dict[str, float]]:
    """Median ms per pass of each temporal mode (taa, accumulate), frames interleaved."""
    settings = {t: _settings(w, h, t, taa_filter) for t in ("taa", "accumulate")}
    return {
        t: {
            k: v
            for k, v in timings.medians(skip=warmup).items()
            if not k.startswith(_NOT_PASSES) and "." not in k
        }
        for t, timings in render_in_turn(stage, settings, frames).items()
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("stage")
    ap.add_argument("--width", type=int, default=745)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--warmup", type=int, default=6)
    ap.add_argument("--taa-filter", type=int, default=0, help="a-trous levels of taa's filter")
    a = ap.parse_args(argv)
    for temporal, passes in pass_ms(
        a.stage, a.width, a.height, a.frames, a.warmup, a.taa_filter
    ).items():
        total = sum(passes.values())
        key = "temporal" if temporal == "taa" else "accumulate"
        share = passes.get(key, 0.0) / max(total, 1e-9)
        print(
            f"{temporal:10s} passes {total:7.1f} ms  {key} {passes.get(key, 0.0):6.2f} ms "
            f"({100 * share:.1f} %)  lighting {passes.get('lighting', 0.0):6.1f} ms"
        )
        if temporal == "taa" and a.taa_filter:
            tf = passes.get("taa_filter", 0.0)
            print(f"taa_filter ({a.taa_filter} levels) {tf:6.2f} ms ({100 * tf / total:.1f} %)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
