"""Moving-camera temporal reuse figures: a camera orbit of a stage (its camera's
transform turned about a vertical axis, one time sample per frame) rendered with
the exact per-frame reference, raw one-frame STB (--temporal off) and STB with taa;
per-frame HDR-FLIP (mid grey) and relMSE against the reference, temporal
instability of each sequence, and optionally a strip of PNGs.

    .venv/bin/python tools/taa_orbit.py usd_scenes/default.usda --frames 60 \\
        --width 320 --height 180 [--strip docs/images/taa] [--degrees 1.0] [--floors] \\
        [-o KEY=VALUE ...]  # STB options of the raw and taa rows

``--floors`` also measures what bounds taa's figures from below, against the same
per-frame reference: the exact lighting through the taa pass (its own error with
noise-free input: antialiasing, reprojection, the clip box's lag), the antialiasing
alone (the reference at the middle frame averaged over taa's jitter sequence, camera
still), and STB accumulated over 16 and 64 frames at the middle frame, camera still
(what any temporal reuse of that many STB frames can reach at best).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from pxr import Usd

from stb_hydra.apps.tradeoff_moving import orbit_copy
from stb_hydra.apps.tradeoff_moving import render_sequence as moving_sequence
from stb_hydra.metrics import display_referred, instability_ratio, per_frame_flip, relmse


def orbit_stage(path: str, frames: int, degrees: float, pivot: float = 12.0) -> Usd.Stage:
    stage = Usd.Stage.Open(path)
    orbit_copy(stage, frames, degrees, pivot, None)
    return stage


def render_sequence(stage, frames, width, height, lighting, temporal, **opts):
    """(frames, ms per frame) of the orbit (``stb tradeoff --moving``'s renderer)."""
    seq = moving_sequence(stage, frames, width, height, lighting, temporal, profile=False, **opts)
    return np.array(seq.images), seq.times


def sequence_figures(seq: np.ndarray, ref: np.ndarray, skip: int) -> tuple[float, float, float]:
    """Median per-frame HDR-FLIP, median relMSE and instability over the reference's,
    from frame ``skip`` on."""
    sl = slice(skip, len(ref))
    rm = [relmse(seq[i], ref[i]) for i in range(skip, len(ref))]
    return (
        float(np.median(per_frame_flip(seq[sl], ref[sl]))),
        float(np.median(rm)),
        instability_ratio(seq[sl], ref[sl]),
    )


def still_image(stage, frame: int, width, height, lighting, temporal, frames) -> np.ndarray:
    """Orbit frame ``frame`` with the camera held still: ``frames`` renders through
    ``temporal`` ("taa": the jitter sequence, averaged; "accumulate": no jitter)."""
    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings

    eng = Engine(
        stage, RenderSettings(width=width, height=height, lighting=lighting, temporal=temporal)
    )
    try:
        eng.request_aovs({"color"})
        if temporal == "accumulate":
            eng.render(time=1 + frame, accumulate=frames)
        else:
            for _ in range(frames):
                eng.render(time=1 + frame)
        return np.array(eng.aovs["color"][..., :3], dtype=np.float32)
    finally:
        eng.release()


def floors(stage, a, ref: np.ndarray) -> None:
    """Print the lower bounds of ``--floors`` (see the module docstring)."""
    rt, _ = render_sequence(stage, a.frames, a.width, a.height, "reference", "taa")
    f, r, inst = sequence_figures(rt, ref, a.skip)
    print(
        f"floor: reference lighting through taa (orbit, frames {a.skip}..{a.frames - 1}): "
        f"flip {f:.4f}  relmse {r:.4f}  instability {inst:.2f}x"
    )
    mid = a.frames // 2
    aa = still_image(stage, mid, a.width, a.height, "reference", "taa", 16)
    print(
        f"floor: antialiasing alone (frame {mid}, 16 jittered reference frames, still): "
        f"flip {per_frame_flip([aa], [ref[mid]])[0]:.4f}"
    )
    for n in (16, 64):
        acc = still_image(stage, mid, a.width, a.height, "stb", "accumulate", n)
        print(
            f"floor: STB accumulated over {n} frames (frame {mid}, still camera): "
            f"flip {per_frame_flip([acc], [ref[mid]])[0]:.4f}"
        )


def write_strip(out: Path, seqs, frames) -> None:
    """One PNG per frame: raw | taa | reference side by side (display-referred)."""
    from PIL import Image

    out.mkdir(parents=True, exist_ok=True)
    for i in frames:
        row = np.concatenate([display_referred(s[i]) for s in seqs], axis=1)
        img = (np.clip(row, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
        Image.fromarray(img).save(out / f"taa_orbit_f{i:02d}.png")
        print("wrote", out / f"taa_orbit_f{i:02d}.png")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("stage")
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=180)
    ap.add_argument("--degrees", type=float, default=1.0)
    ap.add_argument(
        "--pivot", type=float, default=12.0, help="orbit about the ground point this far ahead (m)"
    )
    ap.add_argument("--skip", type=int, default=8, help="frames left out of the medians")
    ap.add_argument("--strip", help="write raw/taa/reference PNGs of a few frames here")
    ap.add_argument(
        "--ref-cache",
        help="a .npy of the reference frames: read when it exists, else written (the "
        "256-light chess reference takes ~30 min on 2 cores); name it by the arguments",
    )
    ap.add_argument("--taa-filter", type=int, default=0, help="taa spatial filter levels")
    ap.add_argument(
        "--floors", action="store_true", help="also measure the lower bounds (module docstring)"
    )
    ap.add_argument("--option", "-o", action="append", default=[], metavar="K=V", help="STB option")
    a = ap.parse_args(argv)
    opts = dict(o.split("=", 1) for o in a.option)
    st = orbit_stage(a.stage, a.frames, a.degrees, a.pivot)
    cache = Path(a.ref_cache) if a.ref_cache else None
    if cache is not None and cache.exists():
        ref = np.load(cache)
        if ref.shape != (a.frames, a.height, a.width, 3):
            raise SystemExit(f"taa_orbit: {cache} holds {ref.shape}, not this orbit's frames")
    else:
        ref, _ = render_sequence(st, a.frames, a.width, a.height, "reference", "off")
        if cache is not None:
            np.save(cache, ref)
    raw, _ = render_sequence(st, a.frames, a.width, a.height, "stb", "off", **opts)
    taa, taa_ms = render_sequence(
        st, a.frames, a.width, a.height, "stb", "taa", taa_filter=a.taa_filter, **opts
    )
    rows = {name: sequence_figures(seq, ref, a.skip) for name, seq in (("raw", raw), ("taa", taa))}
    print(
        f"orbit {a.stage} {a.frames} frames {a.width}x{a.height} {a.degrees} deg/frame"
        f" {opts or 'STB defaults'}"
    )
    print(
        f"frames {a.skip}..{a.frames - 1}: median HDR-FLIP, median relMSE,"
        " instability over the reference's"
    )
    for k, (f, r, inst) in rows.items():
        print(f"{k:5s} flip {f:.4f}  relmse {r:.4f}  instability {inst:.2f}x")
    print(f"taa/raw HDR-FLIP ratio {rows['taa'][0] / rows['raw'][0]:.3f}")
    print(f"taa frame ms (median, AOV readback excluded) {np.median(taa_ms[a.skip :]):.1f}")
    if a.floors:
        floors(st, a, ref)
    if a.strip:
        write_strip(Path(a.strip), [raw, taa, ref], [a.skip, a.frames // 2, a.frames - 1])
    return 0


if __name__ == "__main__":
    sys.exit(main())
