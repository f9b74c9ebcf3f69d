"""The timing loop behind ``stb bench`` (and tools that reuse it), GL-free.

Nothing here imports moderngl: :func:`measure_engine` drives any engine-like
object with ``render_frame(time)``, ``timings.frames`` ({key: ms} per frame),
``tasks`` (objects with ``.name``) and ``settings.profile``. With
``RenderSettings(profile=True)`` the engine calls ``ctx.finish()`` after every
task, so each task's wall time is its real cost (llvmpipe timer queries are
meaningless, see ../shared/docs/TOOLCHAIN_NOTES.md) and every frame is finished.

Per frame (all ms, wall clock):

* ``frame``: ``render_frame()`` end to end (CPU phases + finished GPU tasks);
* ``passes``: each execute task (``gbuffer``, ``lighting``, ...); a task that
  reports sub-passes (``lighting.stb_bigtile``...) is replaced by them plus
  ``<task>.other`` (the remainder), so passes never count anything twice;
* ``cpu``: ``frame`` minus the sum of the passes (sync + prepare + commit + Python);
* ``timings``: the CPU phase keys as the engine reports them (``sync``,
  ``commit``, ``prepare``, ``prepare.light_cull``, ``prepare.light_upload``...).

Reported values are medians over the measured frames (after ``warmup`` frames).
"""

from __future__ import annotations

import os
import statistics
import time as _time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

#: CPU phase keys of the engine's timings (anything starting with one of these).
CPU_PREFIXES = ("sync", "commit", "prepare")
#: Keys summed into the per-frame "cull + upload" overhead (the upload key exists
#: once the light buffer upload moved to the commit phase).
CULL_UPLOAD_KEYS = ("prepare.light_cull", "prepare.light_upload")


@dataclass
class Measurement:
    """Per-frame samples of one measured configuration (ms)."""

    frame: list[float] = field(default_factory=list)
    passes: list[dict[str, float]] = field(default_factory=list)
    timings: list[dict[str, float]] = field(default_factory=list)
    #: Scalar ``frame.stats`` of the last measured frame (+ ``fov_lights``).
    stats: dict[str, Any] = field(default_factory=dict)
    #: Scalar ``frame.stats`` of every measured frame.
    frame_stats: list[dict[str, Any]] = field(default_factory=list)
    #: First frame (0-based, warm-up included) after which every shadow map was fresh
    #: (``shadow_stale_maps`` 0), and the wall seconds from the first frame's start to
    #: that frame's end; None when it never happened (or the scene has no such stat).
    all_fresh_frame: int | None = None
    all_fresh_s: float | None = None
    #: Wall seconds of the first frame (shader compiles, first shadow captures) and of
    #: all the warm-up frames (the first included; 0 without warm-up).
    first_frame_s: float = 0.0
    warmup_s: float = 0.0

    def summary(self) -> dict[str, Any]:
        """Medians: ``frame_ms``, ``frame_ms_min/max``, ``passes``, ``gpu_ms``,
        ``cpu_ms``, ``cull_upload_ms``, ``timings`` (all ms), and
        ``accounted_fraction``: the timed passes plus the CPU phases (sync, commit,
        prepare) over the frame time -- near 1 when every cost is timed; far from it,
        a pass is untimed or the machine was loaded (a benchmark figure, not a test)."""
        passes = median_dict(self.passes)
        timings = median_dict(self.timings)
        cpu = [f - sum(p.values()) for f, p in zip(self.frame, self.passes)]
        frame = median(self.frame)
        phases = sum(timings.get(k, 0.0) for k in CPU_PREFIXES)
        accounted = (sum(passes.values()) + phases) / frame if frame > 0 else 0.0
        return {
            "frame_ms": _r(median(self.frame)),
            "frame_ms_min": _r(min(self.frame, default=0.0)),
            "frame_ms_max": _r(max(self.frame, default=0.0)),
            "gpu_ms": _r(sum(passes.values())),
            "cpu_ms": _r(median(cpu)),
            "cull_upload_ms": _r(sum(timings.get(k, 0.0) for k in CULL_UPLOAD_KEYS)),
            "accounted_fraction": _r(accounted),
            "passes": {k: _r(v) for k, v in passes.items()},
            "timings": {k: _r(v) for k, v in timings.items()},
        }


def _r(x: float) -> float:
    return round(float(x), 4)


def median(values: Sequence[float]) -> float:
    return float(statistics.median(values)) if len(values) else 0.0


def median_dict(rows: Sequence[Mapping[str, float]]) -> dict[str, float]:
    """Key-wise median over dicts (a key missing from a row counts as 0)."""
    keys: list[str] = []
    for r in rows:
        keys.extend(k for k in r if k not in keys)
    return {k: median([r.get(k, 0.0) for r in rows]) for k in keys}


def is_cpu_key(key: str) -> bool:
    return any(key == p or key.startswith(p + ".") for p in CPU_PREFIXES)


def split_frame_timings(
    timings: Mapping[str, float], task_names: Iterable[str]
) -> tuple[dict[str, float], dict[str, float]]:
    """One frame's ``{key: ms}`` -> (passes, cpu timings); see the module doc."""
    names = list(task_names)
    passes: dict[str, float] = {}
    for name in names:
        if name not in timings:
            continue
        total = float(timings[name])
        subs = {k: float(v) for k, v in timings.items() if k.startswith(name + ".")}
        if subs and not is_cpu_key(name):
            passes.update(subs)
            passes[name + ".other"] = max(total - sum(subs.values()), 0.0)
        else:
            passes[name] = total
    cpu = {k: float(v) for k, v in timings.items() if is_cpu_key(k)}
    return passes, cpu


def measure_engine(
    engine,
    *,
    frames: int = 10,
    warmup: int = 2,
    time: float | None = None,
    readback: bool = False,
    on_frame: Callable[[], None] | None = None,
    max_seconds: float | None = None,
) -> Measurement:
    """Render ``warmup`` + ``frames`` frames at ``time`` and keep the last ``frames``.

    ``readback=False`` turns the AOV readback off (a real-time frame has none);
    each frame still ends finished when ``engine.settings.profile`` is on.
    ``on_frame`` is called after every frame (progress bars). ``max_seconds``
    bounds the wall time of the whole measurement for slow methods: once it is
    spent, the remaining warm-up frames are skipped and measuring stops, but at
    least one warm-up frame (when ``warmup`` > 0) and one measured frame always run.
    ``Measurement.frame`` holds the frames actually measured.
    """
    if frames < 1 or warmup < 0:
        raise ValueError("need frames >= 1 and warmup >= 0")
    aov = getattr(engine, "aov_output", None)
    saved = None
    if aov is not None and not readback:
        saved, aov.requested = aov.requested, set()
    names = [t.name for t in engine.tasks]
    m = Measurement()
    start = _time.perf_counter()
    try:
        i = 0
        while i < warmup + frames:
            t0 = _time.perf_counter()
            frame = engine.render_frame(time)
            wall = (_time.perf_counter() - t0) * 1e3
            if i == 0:
                m.first_frame_s = wall / 1e3
            if i < warmup:
                m.warmup_s += wall / 1e3
            if m.all_fresh_frame is None and frame.stats.get("shadow_stale_maps", 1) == 0:
                m.all_fresh_frame = i
                m.all_fresh_s = _time.perf_counter() - start
            if i >= warmup:
                passes, cpu = split_frame_timings(engine.timings.frames[-1], names)
                m.frame.append(wall)
                m.passes.append(passes)
                m.timings.append(cpu)
                m.stats = {
                    k: v for k, v in frame.stats.items() if isinstance(v, (int, float, bool))
                }
                m.stats["fov_lights"] = int(frame.light_count)
                m.frame_stats.append(m.stats)
            if on_frame is not None:
                on_frame()
            i += 1
            if max_seconds is not None and _time.perf_counter() - start >= max_seconds:
                if i >= warmup + 1:
                    break  # at least one measured frame is in
                i = warmup  # skip the rest of the warm-up
    finally:
        if saved is not None:
            aov.requested = saved
    return m


def load_average() -> float | None:
    """1-minute load average (the machine may be shared), or None."""
    try:
        return round(os.getloadavg()[0], 2)
    except OSError:
        return None
