"""``stb tradeoff SCENE --moving DEG``: the moving-camera scenario of the trade-off study.

The scene's camera is turned about a vertical axis through the ground point
``--pivot`` metres ahead of it, ``DEG`` degrees per frame, for ``--moving-frames``
frames (one time sample per frame, authored on the session layer; the stage file is
not touched). Every configuration renders the same sequence; the reference is exact
per frame. Per configuration: median frame time (``ctx.finish()`` after every task,
the AOV readback excluded), and from frame ``--moving-skip`` on (history filled)
the median per-frame HDR-FLIP against the per-frame reference (mid grey), the median
relMSE, and temporal instability over the reference's own
(:func:`stb_hydra.metrics.instability_ratio`: 1 = as stable as the reference).

Configurations: ``reference``; ``stb``'s default (the reservoir reuse, issue 31) and the
talk's pipeline (``-o reuse=off``) with N = 1 and 4 and N = 4 with ``select=ris``, each
with ``temporal`` off (raw frames: what still-camera accumulation
shows while the camera moves, since every new camera position restarts the average) and
``taa``; ``tiled``, ``clustered`` and ``lighttree``. Writes ``moving.csv`` and
``moving.md`` (atomically).
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..io.files import write_csv_atomic, write_text_atomic

#: (method, temporal, options) of the moving scenario, reference first.
MOVING_CONFIGS: tuple[tuple[str, str, dict], ...] = (
    ("reference", "off", {}),
    ("stb", "off", {"reuse": False, "N": 1}),
    ("stb", "taa", {"reuse": False, "N": 1}),
    ("stb", "off", {"reuse": False, "N": 4}),
    ("stb", "taa", {"reuse": False, "N": 4}),
    ("stb", "off", {"reuse": False, "N": 4, "select": "ris"}),
    ("stb", "taa", {"reuse": False, "N": 4, "select": "ris"}),
    ("stb", "off", {"reuse": True}),
    ("stb", "taa", {"reuse": True}),
    ("tiled", "off", {}),
    ("clustered", "off", {}),
    ("lighttree", "off", {}),
)
MOVING_FIELDS = [
    "scene",
    "label",
    "method",
    "temporal",
    "N",
    "select",
    "reuse",
    "frame_ms",
    "temporal_ms",
    "hdr_flip_median",
    "relmse_median",
    "instability",
    "frames",
    "skip",
    "degrees_per_frame",
    "width",
    "height",
]


@dataclass
class Sequence:
    """One configuration's frames of the moving sequence."""

    method: str
    temporal: str
    options: dict
    images: list[np.ndarray] = field(default_factory=list)
    times: list[float] = field(default_factory=list)
    temporal_times: list[float] = field(default_factory=list)

    @property
    def label(self) -> str:
        if self.method != "stb":
            return self.method
        if self.options.get("reuse"):
            return f"stb reuse {self.temporal}"
        select = self.options.get("select", "all")
        sel = "" if select == "all" else f" {select}"
        return f"stb N{self.options.get('N', 1)}{sel} {self.temporal}"


def render_sequence(
    stage,
    frames: int,
    width: int,
    height: int,
    method: str,
    temporal: str,
    *,
    camera: str | None = None,
    seed: int = 0,
    profile: bool = True,
    on_frame=None,
    taa_filter: int = 0,
    **options,
) -> Sequence:
    """Render times 1..``frames`` of ``stage`` with one engine (history carried over);
    per frame: the colour image and the frame time without the AOV readback (ms)."""
    from ..renderer.engine import Engine
    from ..renderer.frame import RenderSettings

    settings = RenderSettings(
        width=width,
        height=height,
        camera=camera,
        lighting=method,
        seed=seed,
        temporal=temporal,
        taa_filter=taa_filter if temporal == "taa" else 0,
        profile=profile,
        method_options=dict(options),
    )
    seq = Sequence(method, temporal, dict(options))
    eng = Engine(stage, settings)
    try:
        eng.request_aovs({"color"})
        for i in range(frames):
            t0 = _time.perf_counter()
            eng.render(time=1 + i)
            wall = (_time.perf_counter() - t0) * 1e3
            tf = eng.timings.frames[-1] if eng.timings.frames else {}
            seq.times.append(wall - tf.get("aov_output", 0.0))
            seq.temporal_times.append(tf.get("temporal", 0.0) + tf.get("accumulate", 0.0))
            seq.images.append(np.array(eng.aovs["color"][..., :3], dtype=np.float32))
            if on_frame:
                on_frame()
    finally:
        eng.release()
    return seq


def evaluate_sequence(seq: Sequence, ref: Sequence, skip: int) -> dict:
    """Median per-frame HDR-FLIP and relMSE from frame ``skip`` on, instability ratio."""
    from ..metrics import instability_ratio, per_frame_flip, relmse

    sl = slice(skip, len(ref.images))
    imgs, refs = seq.images[sl], ref.images[sl]
    flips = per_frame_flip(imgs, refs)
    rel = [relmse(a, b) for a, b in zip(imgs, refs, strict=True)]
    return {
        "label": seq.label,
        "method": seq.method,
        "temporal": seq.temporal,
        "N": seq.options.get("N", ""),
        "select": seq.options.get("select", "all") if seq.method == "stb" else "",
        "reuse": int(bool(seq.options.get("reuse"))) if seq.method == "stb" else "",
        "frame_ms": round(float(np.median(seq.times[sl])), 3),
        "temporal_ms": round(float(np.median(seq.temporal_times[sl])), 3),
        "hdr_flip_median": round(float(np.median(flips)), 5),
        "relmse_median": round(float(np.median(rel)), 6),
        "instability": round(float(instability_ratio(imgs, refs)), 4) if len(imgs) > 1 else 0.0,
    }


def orbit_copy(stage, frames: int, degrees: float, pivot: float, camera: str | None) -> None:
    """Author the orbit on ``stage``'s session layer (the stage's layers stay as they are)."""
    from ..scenegen.orbit import orbit_camera

    stage.SetEditTarget(stage.GetSessionLayer())
    orbit_camera(stage, frames, degrees, pivot, camera)


def run_moving(args, stage, name: str, out: Path) -> list[dict]:
    """The moving-camera scenario on ``stage`` (already opened); rows as written."""
    import sys

    from tqdm import tqdm

    from .common import CliError

    frames, skip = int(args.moving_frames), int(args.moving_skip)
    if frames < 2 or not 0 <= skip < frames - 1:
        raise CliError("--moving-frames must be >= 2 and --moving-skip < frames - 1")
    try:
        orbit_copy(stage, frames, float(args.moving), float(args.pivot), args.camera)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    methods = set(args.methods.split(",")) | {"reference"} if args.methods else None
    configs = [c for c in MOVING_CONFIGS if methods is None or c[0] in methods]
    bar = tqdm(
        total=frames * len(configs),
        unit="frame",
        desc=f"tradeoff {name} moving",
        disable=None,
        file=sys.stderr,
    )
    rows: list[dict] = []
    ref: Sequence | None = None
    common = {
        "scene": name,
        "frames": frames,
        "skip": skip,
        "degrees_per_frame": float(args.moving),
        "width": args.width,
        "height": args.height,
    }
    try:
        for method, temporal, opts in configs:
            bar.set_postfix_str(f"{method} {temporal} {opts or ''}")
            seq = render_sequence(
                stage,
                frames,
                args.width,
                args.height,
                method,
                temporal,
                camera=args.camera,
                seed=args.seed,
                on_frame=lambda: bar.update(1),
                **opts,
            )
            if ref is None:
                ref = seq
            rows.append({**common, **evaluate_sequence(seq, ref, skip)})
            if seq is not ref:
                seq.images.clear()
                write_moving(rows, out)  # partial results survive
    finally:
        bar.close()
    write_moving(rows, out)
    return rows


def write_moving(rows: list[dict], out: Path) -> None:
    """``moving.csv`` and ``moving.md`` in ``out`` (atomic writes)."""
    write_csv_atomic(out / "moving.csv", rows, MOVING_FIELDS)
    if not rows:
        return
    r0 = rows[0]
    raw = {
        (r["N"], r["select"], r["reuse"]): r["hdr_flip_median"]
        for r in rows
        if r["temporal"] == "off" and r["method"] == "stb"
    }
    lines = [
        f"# Moving camera: {r0['scene']}, {r0['width']}x{r0['height']}, {r0['frames']} frames"
        f" orbiting {r0['degrees_per_frame']:g} deg/frame",
        "",
        f"Medians over frames {r0['skip']}..{r0['frames'] - 1} against the exact per-frame"
        " reference. HDR-FLIP: mid grey; instability: frame-to-frame change of the display"
        " image over the reference's own (1 = as stable as the reference).",
        "",
        "| configuration | frame ms | temporal pass ms | HDR-FLIP | vs raw | relMSE |"
        " instability |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        base = raw.get((r["N"], r["select"], r["reuse"])) if r["method"] == "stb" else None
        vs = f"{r['hdr_flip_median'] / base:.2f}x" if base else ""
        lines.append(
            f"| {r['label']} | {r['frame_ms']:.1f} | {r['temporal_ms']:.2f} |"
            f" {r['hdr_flip_median']:.4f} | {vs} | {r['relmse_median']:.4g} |"
            f" {r['instability']:.2f} |"
        )
    write_text_atomic(out / "moving.md", "\n".join(lines) + "\n")


__all__ = ["MOVING_CONFIGS", "Sequence", "evaluate_sequence", "render_sequence", "run_moving"]
