"""``stb tradeoff --sweep-lights 50,500,5000``: frame time against light count (the
``lights`` generator, or ``chess`` with ``SCENE=chess``), one engine per light count
measured by :mod:`.tradeoff_measure`; writes ``sweep.csv``, ``sweep.md`` and
``frame_time_vs_lights.png``.
"""

from __future__ import annotations

import os
import sys
import time as _time
from pathlib import Path

import numpy as np

from ..io.files import write_text_atomic
from .tradeoff_measure import EnginePool, Unit, _load, _median, generated_stage, measure
from .tradeoff_report import STYLE, write_csv

SWEEP_METHODS = ("stb", "reference", "sun", "tiled", "clustered", "lighttree")

SWEEP_FIELDS = [
    "scene",
    "lights",
    "fov_lights",
    "method",
    "frame_ms",
    "frame_ms_min",
    "frame_ms_max",
    "lighting_ms",
    "prepare_ms",
    "relmse",
    "flip",
    "dropped_median",
    "list_entries",
    "frames",
    "width",
    "height",
    "load1",
]


def run_sweep(args) -> list[dict]:
    from tqdm import tqdm

    from ..metrics import display_referred, flip_ldr, relmse
    from ..renderer.gl import get_context, renderer_info

    kind = args.scene if args.scene in ("lights", "chess") else "lights"
    counts = [int(x) for x in args.sweep_lights.split(",") if x.strip()]
    methods = args.sweep_methods.split(",") if args.sweep_methods else list(SWEEP_METHODS)
    if "reference" in methods:  # first: the others' relMSE needs its image
        methods = ["reference"] + [m for m in methods if m != "reference"]
    out = Path(args.out or Path("out") / "tradeoff" / f"sweep_{kind}")
    out.mkdir(parents=True, exist_ok=True)
    rows: list[dict] = []
    load_before, t0 = _load(), _time.perf_counter()
    bar = tqdm(
        total=len(counts) * len(methods), unit="config", desc="sweep", disable=None, file=sys.stderr
    )
    try:
        for n in counts:
            stage = generated_stage(kind, n, args.seed)
            pool = EnginePool(stage, args)
            ref_img = None
            for m in methods:
                bar.set_postfix_str(f"{n} lights, {m}")
                run = measure(pool, Unit(m), args, args.frames, 1)
                if m == "reference":
                    ref_img = run.images[0]
                    ref_disp = display_referred(ref_img)
                st = run.stats[-1] if run.stats else {}
                rows.append(
                    {
                        "scene": kind,
                        "lights": n,
                        "fov_lights": int(st.get("fov_lights", 0)),
                        "method": m,
                        "frame_ms": round(_median(run.times), 3),
                        "frame_ms_min": round(min(run.times), 3),
                        "frame_ms_max": round(max(run.times), 3),
                        "lighting_ms": round(_median(run.lighting), 3),
                        "prepare_ms": round(_median(run.prepare), 3),
                        "relmse": (
                            relmse(run.images[0], ref_img, args.eps) if ref_img is not None else ""
                        ),
                        "flip": (
                            round(flip_ldr(display_referred(run.images[0]), ref_disp), 5)
                            if ref_img is not None
                            else ""
                        ),
                        "dropped_median": float(
                            np.median([s.get("dropped_lights", 0) for s in run.stats])
                        ),
                        "list_entries": int(st.get("list_entries", 0)),
                        "frames": len(run.times),
                        "width": args.width,
                        "height": args.height,
                        "load1": round(os.getloadavg()[0], 2),
                    }
                )
                write_csv(rows, out / "sweep.csv", SWEEP_FIELDS)
                bar.update(1)
            pool.close()
    finally:
        bar.close()
    renderer = renderer_info(get_context())
    plot_sweep(
        rows,
        out / "frame_time_vs_lights.png",
        f"{kind} scene, {args.width}x{args.height}, {renderer.split('|')[0].strip()}, "
        f"load {load_before}",
    )
    lines = [
        f"# Frame time vs light count ({kind} scene)",
        "",
        f"- {args.width}x{args.height}, `{renderer}`; load average before {load_before}, "
        f"after {_load()}; {_time.perf_counter() - t0:.0f} s",
        "- median frame time (ms, profile mode, readback excluded); in brackets relMSE / "
        "LDR-FLIP of one frame vs the reference (and light-tile pairs dropped)",
        "",
        "| lights (in view) | " + " | ".join(methods) + " |",
        "|---|" + "---|" * len(methods),
    ]
    for n in counts:
        cells = []
        for m in methods:
            r = next((r for r in rows if r["lights"] == n and r["method"] == m), None)
            if r is None:
                cells.append("")
                continue
            extra = f", drops {r['dropped_median']:g}" if r["dropped_median"] else ""
            err = (
                f" ({float(r['relmse']):.2g} / {float(r['flip']):.3f}{extra})"
                if r["relmse"] not in ("", None) and m != "reference"
                else ""
            )
            cells.append(f"{float(r['frame_ms']):.0f}{err}")
        fov = next((r["fov_lights"] for r in rows if r["lights"] == n), n)
        lines.append(f"| {n} ({fov}) | " + " | ".join(cells) + " |")
    write_text_atomic(out / "sweep.md", "\n".join(lines) + "\n")
    print(
        f"stb tradeoff: wrote {out / 'sweep.csv'}, {out / 'frame_time_vs_lights.png'}",
        file=sys.stderr,
    )
    return rows


def plot_sweep(rows: list[dict], path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 5))
    for m in dict.fromkeys(r["method"] for r in rows):
        rs = sorted((r for r in rows if r["method"] == m), key=lambda r: r["fov_lights"])
        marker, color = STYLE.get(m, ("o", None))
        ax.plot(
            [r["fov_lights"] or r["lights"] for r in rs],
            [r["frame_ms"] for r in rs],
            marker=marker,
            color=color,
            label=m,
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("local lights in view")
    ax.set_ylabel("median frame time (ms)")
    ax.grid(True, which="both", alpha=0.25)
    ax.legend()
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
