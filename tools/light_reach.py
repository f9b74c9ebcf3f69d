"""Per-light reach as a fraction of the view (issue 34 item C: "a scene whose lights
reach <= 10 % of the view each", checked rather than assumed).

Renders one frame of each scene (``--method``, default ``bare``: any method with local
lights gives the same G-buffer and in-view lights), reads the linear depth buffer back,
rebuilds every pixel's world-space surface point and view ray, and measures, for each
in-view light, the fraction of the view's pixels whose surface lies inside its range
sphere (``reach``: the light-pixel pairs an exact method shades) and whose ray meets
that sphere (``cover``: its projected footprint), with ``stb_hydra.metrics.light_reach``.
Prints median / p95 / max / mean of both, the lights over ``--limit``, and the lights
reaching a pixel (mean / p95 / max); ``--json`` writes them.

    python tools/light_reach.py gen:lights:5000:types=sphere:shadow_fraction=0 --size 160x90

Scenes are paths or ``stb bench``'s generators (``gen:lights:N[:K=V...]``).
"""

from __future__ import annotations

import argparse
import json

import numpy as np


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--size", default="160x90", help="WxH (default 160x90)")
    ap.add_argument("--method", default="bare", help="lighting method of the frame (bare)")
    ap.add_argument("--limit", type=float, default=0.10, help="reach limit, fraction (0.10)")
    ap.add_argument("--json", default=None, help="write the summaries here")
    a = ap.parse_args(argv)
    from stb_hydra.apps.bench import parse_scene
    from stb_hydra.metrics.light_reach import light_reach
    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings
    from stb_hydra.renderer.gl import get_context
    from stb_hydra.renderer.records import InViewLights

    w, h = (int(v) for v in a.size.lower().split("x"))
    ctx = get_context()
    out: dict[str, dict[str, float]] = {}
    for case in [c for sc in a.scenes for c in parse_scene(sc)]:
        eng = Engine(case.build(), RenderSettings(width=w, height=h, lighting=a.method), ctx=ctx)
        try:
            frame = eng.render()
            rows = frame.get(InViewLights).rows
            table = eng.delegate.light_table
            pos = np.asarray(table.position[rows], dtype=np.float64)
            rng = np.asarray(table.range[rows], dtype=np.float64)
            tex = eng.buffers.textures["g_depth"]
            tw, th = tex.size
            depth = np.frombuffer(tex.read(), dtype=np.float32).reshape(th, tw).astype(np.float64)
            v = frame.view
            # GL pixel centres (row 0 = bottom), as common/frame.glsl's view_pos_from_depth
            ys, xs = np.mgrid[0:th, 0:tw].astype(np.float64)
            ndc_x = (xs + 0.5) / tw * 2.0 - 1.0
            ndc_y = (ys + 0.5) / th * 2.0 - 1.0
            px = ndc_x * v.tan_half[0] + v.offset[0]
            py = ndc_y * v.tan_half[1] + v.offset[1]
            inv = np.asarray(v.inv_view, dtype=np.float64)  # row vectors: p @ inv
            rot, org = inv[:3, :3], inv[3, :3]
            if v.orthographic:
                vo = np.stack([px, py, np.zeros_like(px)], axis=-1).reshape(-1, 3)
                vd = np.tile([0.0, 0.0, -1.0], (vo.shape[0], 1))
                vpos = np.stack([px, py, -depth], axis=-1).reshape(-1, 3)
            else:
                vo = np.zeros((tw * th, 3))
                vd = np.stack([px, py, -np.ones_like(px)], axis=-1).reshape(-1, 3)
                vpos = vd * depth.reshape(-1, 1)
            origin = vo @ rot + org
            dirs = vd @ rot
            dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
            points = vpos @ rot + org
            st = light_reach(points, depth.reshape(-1) > 0, origin, dirs, pos, rng)
        finally:
            eng.release()
        s = st.summary(a.limit)
        out[case.label] = s
        pct = {k: v * 100 for k, v in s.items() if k.endswith(("median", "p95", "max", "mean"))}
        print(
            f"{case.label} ({w}x{h}, {s['lights']} in view): "
            f"reach median {pct.get('reach_median', 0):.2f} % p95 {pct.get('reach_p95', 0):.2f} % "
            f"max {pct.get('reach_max', 0):.2f} % mean {pct.get('reach_mean', 0):.2f} %, "
            f"over {a.limit:.0%}: {s.get('reach_over_limit', 0)}; "
            f"cover median {pct.get('cover_median', 0):.2f} % p95 {pct.get('cover_p95', 0):.2f} % "
            f"max {pct.get('cover_max', 0):.2f} %, over: {s.get('cover_over_limit', 0)}; "
            f"lights per pixel mean {s.get('reached_per_pixel_mean', 0):.1f} "
            f"p95 {s.get('reached_per_pixel_p95', 0):.0f} max {s.get('reached_per_pixel_max', 0)}",
            flush=True,
        )
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
