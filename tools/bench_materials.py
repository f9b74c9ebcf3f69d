#!/usr/bin/env python3
"""What textured materials cost (issue 30): per scene, in one run,

1. **First frame**: wall seconds from opening the stage to the first finished frame
   (the scene index, material translation, geometry with texture coordinates and
   tangents, texture reads + colour conversion + upload + mips, program compiles),
   and the part spent loading textures (``TextureCache.stats``);
2. **Texture memory**: textures on the GPU, their bytes (mips included) and the
   budget (``limits.TEXTURE_BUDGET_BYTES``);
3. **G-buffer pass** (``RenderSettings(profile=True)``: ``ctx.finish()`` after every
   pass; llvmpipe timer queries are meaningless): medians over ``--frames`` after
   ``--warmup``, the scene's materials as authored against the same materials with
   every texture / primvar / normal map stripped (their constants kept), measured
   frame by frame in turn so machine load falls on both alike;
4. **The lighting frame** of ``--methods`` with textures (the lighting passes read the
   same G-buffer, so they should not change).

Prints a table and the 1-minute load average; ``--json FILE`` writes the numbers.

    .venv/bin/python tools/bench_materials.py [SCENE ...] [--size 745x360] [--frames 8]

SCENE defaults to the OpenChessSet as shipped (``../shared/testdata``).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _size(text: str) -> tuple[int, int]:
    w, _, h = text.lower().partition("x")
    return int(w), int(h)


def _default_scene() -> Path:
    shared = Path(os.environ.get("STB_SHARED", REPO.parent / "shared"))
    return shared / "testdata" / "scenes" / "OpenChessSet" / "chess_set.usda"


def _engine(path: Path, size: tuple[int, int], method: str, strip: bool):
    from pxr import Usd

    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings
    from stb_hydra.scene.usd_diagnostics import UsdDiagnostics, summarize

    t0 = time.perf_counter()
    with UsdDiagnostics() as diag:  # the .mtlx arcs the scene index reads itself
        stage = Usd.Stage.Open(str(path))
        for line in summarize(diag.drain()):
            print("warning:", line, file=sys.stderr)
    eng = Engine(
        stage,
        RenderSettings(width=size[0], height=size[1], lighting=method, profile=True),
    )
    if strip:
        strip_textures(eng)
    eng.render_frame(None)
    eng.ctx.finish()
    return eng, time.perf_counter() - t0


def strip_textures(eng) -> None:
    """Every material keeps its constants and loses its textures, primvar inputs and
    normal tilt (the constant-material baseline of the same scene)."""
    import numpy as np

    d = eng.delegate
    eng.render_frame(None)  # sync once so every material sprim exists
    for sp in d.materials.values():
        m = sp.material
        if m is not None:
            m.textures.clear()
            m.primvars.clear()
            m.normal = np.array([0.0, 0.0, 1.0])
    d._batches_dirty = True
    d.commit_resources()


def _gbuffer_ms(eng) -> float:
    eng.render_frame(None)
    return float(eng.timings.frames[-1].get("gbuffer", float("nan")))


def bench_scene(path: Path, size, methods, frames: int, warmup: int) -> dict:
    from stb_hydra import limits

    eng, first_s = _engine(path, size, "sun", strip=False)
    cache = eng.delegate.textures
    res = {
        "scene": str(path),
        "size": f"{size[0]}x{size[1]}",
        "first_frame_s": round(first_s, 3),
        "texture_load_s": round(float(cache.stats["load_seconds"]), 3),
        "textures": len(cache.textures),
        "texture_mib": round(cache.nbytes / 2**20, 1),
        "texture_budget_mib": round(limits.TEXTURE_BUDGET_BYTES / 2**20, 1),
        "batches": len(eng.delegate.batches),
        "textured_batches": sum(1 for b in eng.delegate.batches if b.material.textured),
    }
    base, _ = _engine(path, size, "sun", strip=True)
    tex_ms, const_ms = [], []
    for i in range(warmup + frames):
        a = _gbuffer_ms(eng)
        b = _gbuffer_ms(base)
        if i >= warmup:
            tex_ms.append(a)
            const_ms.append(b)
    base.release()
    res["gbuffer_textured_ms"] = round(statistics.median(tex_ms), 3)
    res["gbuffer_constant_ms"] = round(statistics.median(const_ms), 3)
    res["gbuffer_ratio"] = round(res["gbuffer_textured_ms"] / res["gbuffer_constant_ms"], 3)
    eng.release()
    res["frames"] = {}
    for m in methods:
        e, _ = _engine(path, size, m, strip=False)
        for _ in range(warmup):
            e.render_frame(None)
        ms = []
        for _ in range(frames):
            t0 = time.perf_counter()
            e.render_frame(None)
            e.ctx.finish()
            ms.append((time.perf_counter() - t0) * 1000.0)
        res["frames"][m] = round(statistics.median(ms), 2)
        e.release()
    return res


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="*", type=Path)
    ap.add_argument("--size", type=_size, default=(745, 360))
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--methods", default="stb,reference")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    from stb_hydra.apps.bench_core import load_average
    from stb_hydra.renderer.gl import get_context, renderer_info

    scenes = args.scenes or [_default_scene()]
    methods = [m for m in args.methods.split(",") if m]
    out = {"renderer": renderer_info(get_context()), "load_1min": load_average(), "scenes": []}
    for s in scenes:
        r = bench_scene(s, args.size, methods, args.frames, args.warmup)
        out["scenes"].append(r)
        print(f"{s}  {r['size']}")
        print(
            f"  first frame {r['first_frame_s']:.2f} s (textures {r['texture_load_s']:.2f} s: "
            f"{r['textures']} textures, {r['texture_mib']} MiB of {r['texture_budget_mib']} MiB)"
        )
        print(
            f"  G-buffer {r['gbuffer_textured_ms']:.2f} ms textured vs "
            f"{r['gbuffer_constant_ms']:.2f} ms constants ({r['gbuffer_ratio']:.2f}x); "
            f"{r['textured_batches']}/{r['batches']} batches textured"
        )
        for m, ms in r["frames"].items():
            print(f"  {m} frame {ms:.1f} ms")
    print(f"renderer: {out['renderer']}  load {out['load_1min']}")
    if args.json:
        args.json.write_text(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
