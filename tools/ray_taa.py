"""A moving-camera sequence on Ray against the local render (issue 36; docs/DISTRIBUTED.md
and docs/PERFORMANCE.md, "taa on Ray").

Writes the scene (:func:`moving_scene`: a ground, a box sliding across it, 64 sphere
lights, the camera orbiting 1 degree a frame), renders ``--frames 1:F`` with
``--lighting stb`` and the default options (``--temporal auto`` -> taa) locally and
with ``--ray local --workers N`` (a private Ray instance with N CPUs, started once;
its start not counted), and prints per frame the HDR-FLIP of the Ray frame against the
local one, whether the bytes are equal (but the EXR ``capDate`` stamp), and both wall
times. ``--warmup W`` (repeatable) sets ``TAA_WARMUP_FRAMES`` for one Ray run each.

    .venv/bin/python tools/ray_taa.py [--frames 24] [--width 160] [--height 90] \\
        [--workers 2] [--warmup 8 ...] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import sys
import tempfile
import time
from pathlib import Path

_CAPDATE = re.compile(rb"capDate\x00string\x00\x13\x00\x00\x00[0-9: ]{19}")


def moving_scene(frames: int, lights: int = 64) -> str:
    """The sequence's stage (usda text): times 1..``frames``; the camera orbits the
    origin 1 degree a frame; a 2 m box slides along x from -4 to +4 over the
    sequence; ``lights`` small sphere lights on a jittered grid (fixed pseudo-random
    colours and heights), so that STB samples among many."""
    import math

    import numpy as np

    rng = np.random.default_rng(36)
    cam = []
    for i in range(frames):
        a = math.radians(i)
        x, z = 14.0 * math.sin(a), 14.0 * math.cos(a)
        cam.append(f"{1 + i}: ({x:.6f}, 6, {z:.6f})")
    rot = ", ".join(f"{1 + i}: {float(i):.6f}" for i in range(frames))
    span = max(frames - 1, 1)
    box = ", ".join(f"{1 + i}: ({-4 + 8 * i / span:.6f}, 1, 0)" for i in range(frames))
    side = math.ceil(math.sqrt(lights))
    out = [
        "#usda 1.0",
        f'(\n    metersPerUnit = 1\n    upAxis = "Y"\n    startTimeCode = 1\n'
        f"    endTimeCode = {frames}\n)",
        'def Camera "Cam"\n{\n    float focalLength = 18\n    float horizontalAperture = 36\n'
        "    float verticalAperture = 20.25\n"
        f"    double3 xformOp:translate.timeSamples = {{{', '.join(cam)}}}\n"
        f"    float xformOp:rotateY.timeSamples = {{{rot}}}\n"
        "    float xformOp:rotateX = -22\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateY", '
        '"xformOp:rotateX"]\n}',
        'def Mesh "Ground"\n{\n    int[] faceVertexCounts = [4]\n'
        "    int[] faceVertexIndices = [0, 1, 2, 3]\n"
        "    point3f[] points = [(-20, 0, -20), (-20, 0, 20), (20, 0, 20), (20, 0, -20)]\n"
        "    color3f[] primvars:displayColor = [(0.5, 0.5, 0.5)]\n}",
        'def Cube "Box"\n{\n    double size = 2\n'
        "    color3f[] primvars:displayColor = [(0.8, 0.2, 0.2)]\n"
        f"    double3 xformOp:translate.timeSamples = {{{box}}}\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}',
    ]
    for k in range(lights):
        gx, gz = k % side, k // side
        x = -12 + 24 * (gx + 0.5) / side + rng.uniform(-1, 1)
        z = -12 + 24 * (gz + 0.5) / side + rng.uniform(-1, 1)
        y = rng.uniform(0.6, 3.0)
        c = rng.uniform(0.3, 1.0, 3)
        out.append(
            f'def SphereLight "L{k}"\n{{\n    float inputs:intensity = {rng.uniform(20, 80):.3f}\n'
            f"    color3f inputs:color = ({c[0]:.3f}, {c[1]:.3f}, {c[2]:.3f})\n"
            "    float inputs:radius = 0.1\n"
            f"    double3 xformOp:translate = ({x:.3f}, {y:.3f}, {z:.3f})\n"
            '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}'
        )
    return "\n".join(out) + "\n"


def compare(local: Path, other: Path, frames: int) -> list[dict]:
    """Per frame: HDR-FLIP of ``other``'s frame against ``local``'s, and byte equality."""
    from stb_hydra.io.images import read_image
    from stb_hydra.metrics.image import flip_hdr

    rows = []
    for i in range(1, frames + 1):
        a, b = local / f"f.{i:04d}.exr", other / f"f.{i:04d}.exr"
        same = _CAPDATE.sub(b"", a.read_bytes()) == _CAPDATE.sub(b"", b.read_bytes())
        ia, ib = read_image(str(a))[0][..., :3], read_image(str(b))[0][..., :3]
        rows.append({"frame": i, "flip": 0.0 if same else flip_hdr(ib, ia), "identical": same})
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=90)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--warmup", type=int, action="append", help="TAA_WARMUP_FRAMES (repeat)")
    ap.add_argument("--out", type=Path, help="keep the frames here (default: a temp dir)")
    ap.add_argument(
        "--repeat",
        type=int,
        default=3,
        help="local and Ray runs alternate this many times; medians reported (the first "
        "local run would otherwise pay the cold shader cache the Ray workers then reuse)",
    )
    a = ap.parse_args(argv)

    import ray

    from stb_hydra.apps.cli import main as stb
    from stb_hydra.distributed import render as dist

    root = a.out or Path(tempfile.mkdtemp(prefix="ray_taa_"))
    root.mkdir(parents=True, exist_ok=True)
    scene = root / "moving.usda"
    scene.write_text(moving_scene(a.frames))
    flags = ["--frames", f"1:{a.frames}", "--width", str(a.width), "--height", str(a.height)]
    flags += ["--lighting", "stb", "--quiet"]
    ray.init(address="local", num_cpus=a.workers, include_dashboard=False, log_to_driver=False)
    try:
        local = root / "local"
        local.mkdir(exist_ok=True)
        warmups = a.warmup or [dist.TAA_WARMUP_FRAMES]
        t_locals: list[float] = []
        t_rays: dict[int, list[float]] = {w: [] for w in warmups}
        for _ in range(max(1, a.repeat)):
            t0 = time.perf_counter()
            assert stb(["render", str(scene), str(local / "f.####.exr"), *flags]) == 0
            t_locals.append(time.perf_counter() - t0)
            for w in warmups:
                dist.TAA_WARMUP_FRAMES = w
                d = root / f"ray_w{w}"
                d.mkdir(exist_ok=True)
                st = d / "stats.json"
                t0 = time.perf_counter()
                rc = stb(
                    [
                        *("render", str(scene), str(d / "f.####.exr"), *flags, "--ray"),
                        *("--stats", str(st), "--workers", str(a.workers)),
                    ]
                )
                t_rays[w].append(time.perf_counter() - t0)
                assert rc == 0, rc
        t_local = statistics.median(t_locals)
        print(
            json.dumps({"run": "local", "wall_s": round(t_local, 2), "runs": len(t_locals)}),
            flush=True,
        )
        for w in warmups:
            d = root / f"ray_w{w}"
            st = d / "stats.json"
            t_ray = statistics.median(t_rays[w])
            doc = json.loads(st.read_text())["ray"]
            rows = compare(local, d, a.frames)
            flips = [r["flip"] for r in rows]
            print(
                json.dumps(
                    {
                        "run": f"ray {a.workers} workers, warm-up {w}",
                        "wall_s": round(t_ray, 2),
                        "ray_wall_s_last": doc["wall_s"],
                        "speedup": round(t_local / t_ray, 2),
                        "temporal": doc["temporal"],
                        "flip_max": round(max(flips), 5),
                        "identical": sum(r["identical"] for r in rows),
                        "flip_per_frame": [round(f, 5) for f in flips],
                    }
                ),
                flush=True,
            )
    finally:
        ray.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
