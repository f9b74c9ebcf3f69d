"""The analysis and report writing of ``stb tradeoff`` (:mod:`.tradeoff`): the Pareto
frontier and the budget picks (:func:`pareto_front`, :func:`best_within`,
:func:`cheapest_reaching`, :func:`default_budgets`), ``pareto.png``
(:func:`plot_pareto`), ``report.md`` (:func:`write_report`), and the CSV rows written and
read back (:func:`write_csv`, :func:`read_rows`, used by ``--report-only``).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..io.files import write_csv_atomic, write_text_atomic

#: Marker and colour per method in the plots.
STYLE = {
    "stb": ("o", "tab:blue"),
    "tiled": ("s", "tab:orange"),
    "clustered": ("^", "tab:green"),
    "lighttree": ("D", "tab:red"),
    "reference": ("*", "black"),
    "sun": ("x", "tab:gray"),
}
#: relMSE drawn for (near-)exact methods on the log axis.
EXACT_FLOOR = 1e-7


# --- analysis ------------------------------------------------------------------------------


def pareto_front(times: np.ndarray, errors: np.ndarray) -> np.ndarray:
    """Indices of the non-dominated points (no other point is both faster-or-equal and
    strictly better, or strictly faster and better-or-equal), sorted by time."""
    t = np.asarray(times, dtype=np.float64)
    e = np.asarray(errors, dtype=np.float64)
    order = np.lexsort((e, t))
    keep, best = [], np.inf
    for i in order:
        if e[i] < best:
            keep.append(int(i))
            best = e[i]
    return np.array(keep, dtype=np.int64)


def best_within(
    rows: list[dict], budget_ms: float, time_key: str = "frame_ms", metric: str = "relmse"
) -> dict | None:
    """Lowest-``metric`` row (ties: faster, then lower FLIP) with time <= budget."""
    ok = [r for r in rows if float(r[time_key]) <= budget_ms]
    if not ok:
        return None
    return min(ok, key=lambda r: (float(r[metric]), float(r[time_key]), float(r["flip"])))


def cheapest_reaching(rows: list[dict], max_err: float, time_key: str = "frame_ms"):
    ok = [r for r in rows if float(r["relmse"]) <= max_err]
    return min(ok, key=lambda r: float(r[time_key])) if ok else None


def default_budgets(rows: list[dict], time_key: str = "frame_ms") -> list[float]:
    t = sorted(float(r[time_key]) for r in rows)
    if not t:
        return []
    lo, hi = t[0], t[-1]
    cand = [a * 10.0**e for e in range(-1, 7) for a in (1, 2, 5)]
    out = [c for c in cand if lo <= c < hi]
    above = [c for c in cand if c >= hi]
    return out + above[:1] if above else [*out, hi]


def plot_pareto(rows: list[dict], path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(13, 5.2), sharey=True)
    for ax, key, xlabel in (
        (axes[0], "frame_ms", "median frame time (ms, static camera, A-frame accumulation)"),
        (axes[1], "image_ms", "time to the accumulated image: A x frame time (ms)"),
    ):
        t = np.array([float(r[key]) for r in rows])
        e = np.array([max(float(r["relmse"]), EXACT_FLOOR) for r in rows])
        for m in STYLE:
            idx = [i for i, r in enumerate(rows) if r["method"] == m]
            if not idx:
                continue
            marker, color = STYLE[m]
            if m == "stb":
                for a, alpha in zip(
                    sorted({int(rows[i]["accumulate"]) for i in idx}), (0.35, 0.65, 1.0, 1.0)
                ):
                    sel = [i for i in idx if int(rows[i]["accumulate"]) == a]
                    ax.scatter(
                        t[sel],
                        e[sel],
                        marker=marker,
                        color=color,
                        alpha=alpha,
                        s=28,
                        label=f"stb A={a}",
                    )
            else:
                ax.scatter(
                    t[idx],
                    e[idx],
                    marker=marker,
                    color=color,
                    s=70 if m == "reference" else 44,
                    label=m,
                    zorder=3,
                )
                for i in idx:
                    if m == "tiled":
                        ax.annotate(
                            f"cap {rows[i]['tile_cap']}",
                            (t[i], e[i]),
                            fontsize=7,
                            xytext=(4, 4),
                            textcoords="offset points",
                        )
        front = pareto_front(t, e)
        ax.step(
            t[front], e[front], where="post", color="k", lw=1.0, alpha=0.6, label="Pareto frontier"
        )
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.grid(True, which="both", alpha=0.25)
    axes[0].set_ylabel(f"relMSE vs reference (exact methods drawn at {EXACT_FLOOR:g})")
    axes[0].legend(fontsize=8, loc="best")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _blank(v: object) -> bool:
    """A metric that was skipped, or a column a CSV written before it existed lacks."""
    return v in ("", None)


def _opt(v: object, fmt: str = ".4f") -> str:
    """A metric that may be absent ("" when skipped)."""
    return "" if _blank(v) else format(float(v), fmt)  # type: ignore[arg-type]


def _x_ref(r: dict) -> str:
    """``x_reference`` as ``0.05x`` ("" in a CSV written before the column existed)."""
    v = r.get("x_reference", "")
    return "" if _blank(v) else f"{float(v):.2f}x"


def _pct(v: object) -> str:
    return "" if _blank(v) else f"{float(v) * 100:.1f} %"  # type: ignore[arg-type]


def _fmt_row(r: dict | None, key: str = "frame_ms") -> str:
    if r is None:
        return "| (none) | | | | |"
    return (
        f"| {r['label']} | {float(r[key]):.1f} | {float(r['relmse']):.3g} | "
        f"{float(r['flip']):.4f} | {float(r['temporal']):.4f} |"
    )


def _short(r: dict | None, key: str) -> str:
    if r is None:
        return "(none) | |"
    return (
        f"{r['label']} ({float(r[key]):.0f} ms) | {float(r['relmse']):.3g} / {float(r['flip']):.3f}"
    )


def write_report(rows, path: Path, meta: dict, budgets: list[float] | None) -> None:
    lines = [
        f"# Trade-off: {meta['scene']}",
        "",
        f"- {meta['width']}x{meta['height']} px, {meta['fov_lights']} lights in view, "
        f"renderer `{meta['renderer']}`",
        f"- {meta['date']}; load average (1/5/15 min) before {meta['load_before']}, "
        f"after {meta['load_after']}; {meta['wall_s']:.0f} s",
        f"- command: `{meta['command']}`",
        "- frame time: median over the measured frames (profile mode, readback excluded); "
        "relMSE vs `reference` in scene-linear (eps "
        f"{meta['eps']:g}); FLIP: LDR-FLIP of the display-referred images; temporal: mean "
        "|frame-to-frame change| of the displayed image (display-referred) minus the "
        "reference's. `A` = frames accumulated (sliding mean, static camera).",
    ]
    if meta.get("mitsuba"):
        lines.append(f"- `reference` against Mitsuba 3: {meta['mitsuba']}")
    lines.append("")
    for key, heading in (
        (
            "frame_ms",
            "Best configuration per frame-time budget (static camera, A frames "
            "accumulated over time)",
        ),
        ("image_ms", "Best configuration per time-to-image budget (A x frame time)"),
    ):
        bs = budgets or default_budgets(rows, key)
        lines += [
            f"## {heading}",
            "",
            "| budget (ms) | lowest relMSE | relMSE / FLIP | lowest FLIP | relMSE / FLIP |",
            "|---|---|---|---|---|",
        ]
        for b in bs:
            lines.append(
                f"| {b:g} | {_short(best_within(rows, b, key), key)} | "
                f"{_short(best_within(rows, b, key, 'flip'), key)} |"
            )
        lines.append("")
    lines += [
        "## Cheapest configuration reaching an error level",
        "",
        "| relMSE <= | cheapest (frame time) | time (ms) | relMSE | FLIP | temporal |",
        "|---|---|---|---|---|---|",
    ]
    for lvl in (1.0, 0.1, 1e-2, 1e-3, 1e-4):
        lines.append(f"| {lvl:g} " + _fmt_row(cheapest_reaching(rows, lvl)))
    lines += [
        "",
        "## Pareto set (frame time)",
        "",
        "| config | frame (ms) | lighting (ms) | relMSE | FLIP | HDR-FLIP | structure | "
        "temporal | dropped |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    t = np.array([float(r["frame_ms"]) for r in rows])
    e = np.array([float(r["relmse"]) for r in rows])
    for i in pareto_front(t, e):
        r = rows[i]
        lines.append(
            f"| {r['label']} | {float(r['frame_ms']):.1f} | {float(r['lighting_ms']):.1f} | "
            f"{float(r['relmse']):.3g} | {float(r['flip']):.4f} | {_opt(r['hdr_flip'])} | "
            f"{float(r['structure']):.2f} | {float(r['temporal']):.4f} | {r['dropped_median']:g} |"
        )
    lines += [
        "",
        "## Exact methods and capped lists",
        "",
        "x reference: the frame over the reference's frame. Cell share: lights per tile / "
        "cluster over the lights in view (tiled: the mean share of the screen's tiles a "
        "light reaches; the work culling keeps of the reference's).",
        "",
        "| config | frame (ms) | x reference | cell share | lighting (ms) | relMSE | FLIP | "
        "dropped/frame |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if r["method"] != "stb":
            lines.append(
                f"| {r['label']} | {float(r['frame_ms']):.1f} | {_x_ref(r)} | "
                f"{_pct(r.get('cell_light_share'))} | {float(r['lighting_ms']):.1f} | "
                f"{float(r['relmse']):.3g} | {float(r['flip']):.4f} | {r['dropped_median']:g} |"
            )
    write_text_atomic(path, "\n".join(lines) + "\n")


def read_rows(path: Path) -> list[dict]:
    """A CSV written by :func:`write_csv`, numbers parsed back."""
    out = []
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            row = {}
            for k, v in r.items():
                try:
                    row[k] = float(v) if v not in ("", None) else v
                except ValueError:
                    row[k] = v
            for k in ("accumulate", "frames", "fov_lights", "width", "height"):
                if isinstance(row.get(k), float):
                    row[k] = int(row[k])
            out.append(row)
    return out


def write_csv(rows: list[dict], path: Path, fields: list[str]) -> None:
    """``rows`` to ``path`` as CSV, atomically (:func:`~stb_hydra.io.files.write_csv_atomic`)."""
    write_csv_atomic(path, rows, fields)


def finish_report(rows, out: Path, meta: dict, name: str, budgets) -> None:
    plot_pareto(
        rows,
        out / "pareto.png",
        f"{name}: {meta['width']}x{meta['height']}, {meta['fov_lights']} lights in view, "
        f"{meta['renderer'].split('|')[0].strip()}, load {meta['load_before']}",
    )
    write_report(rows, out / "report.md", meta, budgets)
