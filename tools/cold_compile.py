"""Cold shader compile of the first frame, one method per fresh process (issue 34).

Each ``SCENE x METHOD`` runs in its own Python process with an empty
``MESA_SHADER_CACHE_DIR`` (a new temporary folder, removed afterwards), so every program
of the frame is compiled and JIT-ed from scratch: the process opens a GL context and
the stage, then renders a new ``Engine`` at ``--size`` twice (``render()`` +
``ctx.finish()``). Printed per run, as one JSON line: the first frame's wall time and
the process's CPU time over it (seconds; compilation is single-threaded, so CPU time is
the figure that survives other jobs on the machine), the second frame's (the warm
cost), and the number of programs built. ``--root`` runs another checkout's
``stb_hydra`` (its tree on ``PYTHONPATH``): an A/B of two trees back to back.

    python tools/cold_compile.py usd_scenes/default.usda --methods reference,tiled
    python tools/cold_compile.py SCENE --root /tmp/main_tree --root .
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

_CHILD = r"""
import json, sys, time
from pxr import Usd
from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings
from stb_hydra.renderer.gl import get_context, shader_library

path, method, w, h = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
ctx = get_context(); ctx.finish()
stage = Usd.Stage.Open(path)
wall, cpu = [], []
for _ in range(2):
    t, c = time.perf_counter(), time.process_time()
    eng = Engine(stage, RenderSettings(width=w, height=h, lighting=method), ctx=ctx)
    eng.render(); ctx.finish()
    wall.append(time.perf_counter() - t); cpu.append(time.process_time() - c)
    eng.release()
print(json.dumps({"first_s": round(wall[0], 2), "cpu_first_s": round(cpu[0], 2),
                  "second_s": round(wall[1], 2), "cpu_second_s": round(cpu[1], 2),
                  "programs": shader_library(ctx).compiled}))
"""


def cold_frame(root: Path, scene: Path, method: str, size: tuple[int, int]) -> dict:
    """One fresh process of ``root``'s ``stb_hydra`` with an empty Mesa shader cache:
    the first and second frame of ``method`` on ``scene`` (times in s)."""
    with tempfile.TemporaryDirectory(prefix="mesa_cache_") as cache:
        env = {**os.environ, "MESA_SHADER_CACHE_DIR": cache, "PYTHONPATH": str(root)}
        args = [sys.executable, "-c", _CHILD, str(scene), method, *map(str, size)]
        out = subprocess.run(args, env=env, cwd=root, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="+", type=Path)
    ap.add_argument("--methods", default="reference,tiled,clustered,lighttree")
    ap.add_argument("--size", default="64x36", help="WxH (default 64x36)")
    ap.add_argument("--root", action="append", type=Path, help="checkout(s) to run (default .)")
    a = ap.parse_args(argv)
    w, h = (int(v) for v in a.size.lower().split("x"))
    roots = [r.resolve() for r in (a.root or [Path(".")])]
    for scene in a.scenes:
        for method in a.methods.split(","):
            for root in roots:
                load = os.getloadavg()[0]
                r = cold_frame(root, scene.resolve(), method, (w, h))
                rec = {"root": str(root), "scene": str(scene), "method": method, "load": load}
                print(json.dumps({**rec, **r}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
