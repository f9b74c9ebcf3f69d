"""``stb inspect SCENE [--time T] [--json]``: prims by type, every light in
physical units (render frame: Y up, metres; cd; lm), every material (where it came
from, which inputs are textured, its notes), plus all warnings."""

from __future__ import annotations

import argparse
import json
import math
import sys

import numpy as np

from .common import EXIT_OK, CliError, fail, open_stage


def _vec(v) -> list[float]:
    return [round(float(x), 6) for x in v]


def _num(x: float) -> float | None:
    x = float(x)
    return round(x, 6) if math.isfinite(x) else None


def inspect_stage(stage, time: float | None = None, usd_warnings: list[str] | None = None) -> dict:
    """The ``stb inspect`` report as a JSON-ready dict (schema in the README).
    ``time``: ``"default"`` when the stage is read at its default time (no time given
    and no authored time range). ``usd_warnings``: USD's own diagnostics (one line
    per cause) to list first among the warnings."""
    from ..renderer.delegate import RenderDelegate
    from ..renderer.render_index import RenderIndex
    from ..scene import prims
    from ..scene.lights import influence_range
    from ..scene.stage_io import time_label
    from ..scene.stage_scene_index import StageSceneIndex

    si = StageSceneIndex(stage, time)
    ri = RenderIndex(si, RenderDelegate())
    ri.sync_all()
    # Ranges as a render through the default camera uses them: automatic ranges
    # follow the camera's exposure (stb_hydra.scene.lights.influence_range).
    cams = si.cameras()
    sp = ri.delegate.cameras.get(cams[0]) if cams else None
    exposure = float(sp.exposure_scale) if sp is not None else 1.0
    lights = []
    for path in sorted(ri.delegate.lights):
        lp = ri.delegate.lights[path].light
        local = lp.type in prims.LOCAL_LIGHT_TYPES
        rec = {
            "path": path,
            "type": lp.type,
            "enabled": bool(lp.enabled),
            "position": _vec(lp.position),
            "direction": _vec(lp.direction),
            "intensity": _vec(lp.intensity),
            "intensity_unit": "cd" if local else ("lx" if lp.type == "distantLight" else "nit"),
            "flux": _num(lp.flux),
            "cone": (
                {"angle": lp.cone_angle, "softness": lp.cone_softness, "focus": lp.focus}
                if lp.has_cone
                else None
            ),
            "ies": (
                {
                    "file": lp.ies_file or lp.ies_asset,
                    "resolved": lp.ies_file is not None,
                    "power": _num(lp.ies_power),
                    "angleScale": lp.ies_angle_scale,
                    "normalize": lp.ies_normalize,
                }
                if lp.ies_asset
                else None
            ),
            "shadow": {
                "enable": bool(lp.shadow_enable),
                "update": lp.shadow_update,
                "color": _vec(lp.shadow_color),
            },
            "range": (
                _num(
                    lp.range if lp.range_authored else influence_range(lp.peak_intensity, exposure)
                )
                if local
                else None
            ),
            "shape": {
                k: round(v, 6)
                for k, v in (
                    ("radius", lp.radius),
                    ("width", lp.width),
                    ("height", lp.height),
                    ("length", lp.length),
                )
                if v
            },
        }
        lights.append(rec)
    materials = []
    for path in sorted(ri.delegate.materials):
        mp = ri.delegate.materials[path].material
        if mp is None:
            continue
        materials.append(
            {
                "path": path,
                "source": mp.source or None,
                "uses_defaults": bool(mp.uses_defaults),
                "textured": sorted(mp.textures),
                "notes": list(mp.notes),
            }
        )
    counts = si.counts_by_type()
    total_flux = float(np.sum([lr["flux"] or 0.0 for lr in lights]))
    return {
        "stage": stage.GetRootLayer().identifier,
        "time": time_label(si.time),
        "metersPerUnit": si.mpu,
        "prims": counts,
        "lights": lights,
        "materials": materials,
        "cameras": si.cameras(),
        "summary": {
            "lights": len(lights),
            "enabled": sum(1 for lr in lights if lr["enabled"]),
            "total_flux_lm": round(total_flux, 3),
            "range_exposure_scale": round(exposure, 9),
        },
        "warnings": list(
            dict.fromkeys([*(usd_warnings or ()), *si.warnings, *ri.delegate.warnings])
        ),
    }


def _print_report(rep: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    con = Console(width=None if sys.stdout.isatty() else 220)
    con.print(
        f"[bold]{rep['stage']}[/bold]  time={rep['time']}  metersPerUnit={rep['metersPerUnit']}"
    )
    con.print("prims: " + ", ".join(f"{k}={v}" for k, v in sorted(rep["prims"].items())))
    t = Table(show_lines=False)
    for col in (
        "path",
        "type",
        "on",
        "position (m)",
        "intensity",
        "flux (lm)",
        "cone",
        "IES",
        "shadow",
        "range (m, at camera exposure)",
    ):
        t.add_column(col)
    for lr in rep["lights"]:
        cone = lr["cone"]
        ies = lr["ies"]
        t.add_row(
            lr["path"],
            lr["type"],
            "yes" if lr["enabled"] else "no",
            ", ".join(f"{x:.2f}" for x in lr["position"]),
            ", ".join(f"{x:.3g}" for x in lr["intensity"]) + " " + lr["intensity_unit"],
            "-" if lr["flux"] is None else f"{lr['flux']:.4g}",
            "-" if cone is None else f"{cone['angle']:g}/{cone['softness']:g}",
            "-" if ies is None else (ies["file"] or "") + ("" if ies["resolved"] else " (missing)"),
            ("on" if lr["shadow"]["enable"] else "off") + f" {lr['shadow']['update']}",
            "-" if lr["range"] is None else f"{lr['range']:.3g}",
        )
    con.print(t)
    if rep["materials"]:
        mt = Table(show_lines=False)
        for col in ("material", "source", "textured inputs"):
            mt.add_column(col)
        for mr in rep["materials"]:
            src = mr["source"] or "-"
            mt.add_row(
                mr["path"],
                src + (" (defaults)" if mr["uses_defaults"] else ""),
                ", ".join(mr["textured"]) or "-",
            )
        con.print(mt)
        notes = dict.fromkeys(n for mr in rep["materials"] for n in mr["notes"])
        for n in notes:
            con.print(f"[dim]note:[/dim] {n}", markup=True, highlight=False)
    for w in rep["warnings"]:
        con.print(f"[yellow]warning:[/yellow] {w}", markup=True, highlight=False)


def add_parser(sub) -> None:
    p = sub.add_parser("inspect", help="list prims, lights in physical units and materials")
    p.add_argument("scene", help="USD file")
    p.add_argument("--time", type=float, default=None, help="time code (default: stage start)")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    import os

    try:
        stage = open_stage(args.scene)
    except CliError as exc:
        return fail(str(exc))
    reporter = getattr(args, "reporter", None)
    base = os.path.dirname(os.path.abspath(args.scene))
    usd = reporter.take_usd(base) if reporter is not None else []
    rep = inspect_stage(stage, args.time, usd)
    if reporter is not None:  # diagnostics of the scene read itself
        rep["warnings"] = list(dict.fromkeys(rep["warnings"] + reporter.take_usd()))
    if args.json:
        json.dump(rep, sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        _print_report(rep)
    return EXIT_OK
