"""``stb render ... --ray [ADDRESS]``: frames rendered by Ray actors.

Each worker is an actor (``num_cpus`` 1, ``num_gpus`` 1 when the cluster has GPUs or
``--worker-gpus`` asks) in its own process: it opens the stage and builds its own
:class:`~stb_hydra.renderer.engine.Engine` (its own EGL context; nothing GL crosses a
process) once, then renders the frames the driver hands it one at a time -- the next
frame goes to whichever worker is free (``ray.wait``), so a slow frame does not stall
a fixed slice. A frame's seeds are those of a local render of the same ``--frames``
(the engine's frame counter is set to the frame's position times ``--accumulate``),
so the files are byte-identical to a local render's. The worker writes its files
atomically through the image writer (shared storage on a farm) and sends back the
frame's stats record and any new warnings; the driver shows the progress bar and
writes the one ``--stats`` JSON.

Faults: a worker that dies (machine lost, process killed, segfault) loses only the
frame it had; that frame goes back to the queue (at most :data:`MAX_ATTEMPTS`
attempts) and a replacement worker is started. A frame that fails for a reason of the
scene (``RenderError``, an unwritable path, ...) is reported once and not retried; a
worker that cannot open the stage reports the path on its host. The run ends with a
summary of frames done, failed and retried.
"""

from __future__ import annotations

import argparse
import os
import socket
import sys
import time as _time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..apps.common import EXIT_ERROR, EXIT_OK, CliError, Reporter
from .cluster import cluster_resources, connected

#: Attempts per frame when its workers die (the first one included).
MAX_ATTEMPTS = 3
#: taa on Ray: unwritten frames a run renders before its first written one. The
#: history never forgets within ``tasks.temporal.MAX_HISTORY`` frames and then decays
#: by 1/64 a frame (still pixels), so a finite warm-up stays far from the local
#: frames (measured, tools/ray_taa.py, 64x36 moving scene, frame 200: HDR-FLIP
#: W=16 0.26, 32 0.20, 64 0.14, 96 0.065, 128 0.041, 160 0.025; frame 24: W=8 0.28,
#: 16 0.16): runs warm up from --frames' first frame (exact, byte-identical; the
#: planner then keeps a sequence in one run). Lower it for speed at that cost.
TAA_WARMUP_FRAMES = 1_000_000
#: taa on Ray: the most frames (warm-up included) one run costs when a sequence is
#: split into more runs than workers (long sequences: runs are then handed out as
#: workers come free, and a lost worker loses at most this much work).
TAA_RUN_MAX_COST = 16 * TAA_WARMUP_FRAMES
#: Test hook: called as ``hook(pool, worker, index)`` right after a frame is dispatched.
on_dispatch: Callable[[Any, Any, int], None] | None = None
#: Test hook: ``{"index": i, "marker": path}``: the first worker to render frame ``i``
#: (the one that creates ``marker``) exits between rendering and writing it.
exit_mid_frame: dict[str, Any] | None = None

# argparse values that travel to the workers (everything the render steps read).
_SKIP_ARGS = {"func", "reporter", "ray", "workers", "worker_gpus", "worker_cpus"}


class RenderWorker:
    """One render process: the stage opened and the engine built once (``job``: the
    render's arguments, absolute paths), then :meth:`render` per frame. Errors while
    setting up are kept and returned by :meth:`ready` (one line, with the host)."""

    def __init__(self, job: dict[str, Any]) -> None:
        self.host = socket.gethostname()
        self.error: str | None = None
        self.eng: Any = None
        self.sent = 0
        try:
            self._setup(job)
        except CliError as exc:
            self.error = str(exc)
        except Exception as exc:  # noqa: BLE001 - reported by ready()
            self.error = " ".join(f"{type(exc).__name__}: {exc}".split())

    def _setup(self, job: dict[str, Any]) -> None:
        threads = job.get("threads")
        if threads:
            # llvmpipe's rasteriser threads: this worker's CPUs (before the context).
            os.environ.setdefault("LP_NUM_THREADS", str(threads))
        import stb_hydra  # noqa: F401  (schema registration before any stage)
        from stb_hydra.usd_threads import raise_limit

        from ..apps import render_steps as r
        from ..apps.common import open_stage

        if threads:  # never lowered once TBB runs: stb_hydra.usd_threads
            raise_limit(int(threads))
        args = argparse.Namespace(**job["args"])
        self.args = args
        self.rep = Reporter("stb render", quiet=True).__enter__()
        self.aovs = r._check_settings(args)
        self.stage = open_stage(args.scene)
        self.rep.drain_usd(os.path.dirname(args.scene))
        self.pipeline = r._color_pipeline(args)
        self.settings = r._render_settings(args)
        self.first = job["first"]
        #: ``--frames`` (the local render's sequence): taa warm-ups render from it.
        self.frames: list[float | None] = list(job.get("frames") or [self.first])
        self.ext = os.path.splitext(args.output)[1].lower()
        self._build()
        r._check_image_size(self.eng)
        self.rep.warn_all(self.eng.warnings)
        self.stats = r._stats_header(args, self.eng, self.settings, self.pipeline)
        self.samples = max(1, int(self.settings.accumulate))
        self.exit_mid_frame = job.get("exit_mid_frame")

    def _build(self) -> None:
        """The engine at the first frame; ``started`` False: nothing rendered yet."""
        from ..apps import render_steps as r

        if self.eng is not None:
            self.eng.release()
            self.eng = None
        self.eng = r._build_engine(self.stage, self.settings, self.pipeline, self.first)
        # --temporal auto decides as the local render does (taa when the camera moves).
        r._resolve_temporal(self.args, self.stage, self.eng, self.frames, self.rep)
        want = set(self.aovs) | ({"display"} if self.ext in (".png", ".jpg", ".jpeg") else set())
        self.eng.request_aovs(want)
        self.started = False
        #: taa: the position in ``--frames`` whose frame the engine's history expects
        #: next (-1: none, the engine is fresh or its state unknown).
        self.pos = -1

    def _new_warnings(self) -> list[str]:
        lines = self.rep.lines[self.sent :] if self.eng is not None else []
        self.sent += len(lines)
        return lines

    def ready(self) -> dict[str, Any]:
        """``{"host", "pid", "error"}`` and, when set up, the stats header."""
        out: dict[str, Any] = {"host": self.host, "pid": os.getpid(), "error": self.error}
        if self.error is None:
            out["header"] = self.stats
            out["temporal"] = self.eng.settings.temporal
            out["warnings"] = self._new_warnings()
        return out

    def render(
        self, index: int, fr: float | None, out: str, warm_from: int | None = None
    ) -> dict[str, Any]:
        """Render frame ``fr`` (position ``index`` of ``--frames``) to ``out``: its
        stats record, or ``{"error": ...}`` for a reason of the scene.

        ``warm_from`` (taa, a run of frames): unless the engine's history is already
        at ``index`` (the previous call rendered ``index - 1``), the engine is rebuilt
        and renders positions ``warm_from .. index - 1`` first, unwritten (after
        ``--frames``' first frame when ``warm_from`` > 0, for the shadow atlas, with
        the history dropped after it)."""
        from ..apps import render_steps as r
        from ..io.images import ImageWriteError
        from ..renderer.engine import RenderError

        t_start = _time.perf_counter()
        warmed = 0
        try:
            if self.eng.settings.temporal == "taa":
                warmed = self._position(index, index if warm_from is None else warm_from)
            else:
                self._position_still(index)
            eng, rep = self.eng, self.rep
            eng.frame_index = index * self.samples  # the seeds of a local render
            t0 = _time.perf_counter()
            self.pos = -1
            frame = eng.render(fr)
            self.pos = index + 1
            wall = (_time.perf_counter() - t0) * 1e3
            _maybe_exit(self.exit_mid_frame, index)
            rep.warn_all(eng.warnings)
            rep.drain_usd()
            r._warn_empty_view(eng, rep)
            meta = r._frame_meta(self.stats, eng, fr)
            r._write_outputs(eng, out, self.aovs, self.ext, self.pipeline, meta)
            record = r._frame_record(eng, frame, out, wall)
        except (RenderError, CliError, ImageWriteError, ValueError, OSError) as exc:
            return {"index": index, "error": str(exc), "warnings": self._new_warnings()}
        return {
            "index": index,
            "record": record,
            "warnings": self._new_warnings(),
            "busy_ms": (_time.perf_counter() - t_start) * 1e3,
            "warmup_frames": warmed,
        }

    def _position_still(self, index: int) -> None:
        """Frames without taa: the shadow atlas as the local render has it."""
        if self.started and index * self.samples < self.eng.frame_index:
            self._build()  # an earlier frame (a retry): frame counters only increase
        if not self.started and index != 0:
            # The engine keeps state between frames (shadow atlas and scheduler): a
            # local render starts at --frames' first frame, and so does this one
            # (rendered once, not written) before its first frame elsewhere.
            self.eng.frame_index = 0
            self.eng.render(self.first)
        self.started = True

    def _position(self, index: int, warm_from: int) -> int:
        """taa: the engine's history and shadow atlas at ``index`` as a local render
        has them, approximately (exactly when ``warm_from`` is 0): the unwritten
        warm-up frames ``warm_from .. index - 1`` (each with its local seed and
        jitter). Returns the number of frames rendered for it."""
        if self.pos == index:
            return 0  # the previous call rendered index - 1: the history is there
        if self.started or self.pos != -1 or self.eng.frame_index:
            self._build()
        self.started = True
        eng, n = self.eng, 0
        warm_from = max(0, min(warm_from, index))
        if warm_from > 0:
            # --frames' first frame places the shadow maps as the local render's did;
            # its history is then dropped (the warm-up starts from nothing).
            eng.frame_index = 0
            eng.render(self.first)
            n += 1
            temporal = eng.temporal
            assert temporal is not None  # settings.temporal == "taa"
            temporal.reset()
        for j in range(warm_from, index):
            eng.frame_index = j * self.samples
            eng.render(self.frames[j])
            n += 1
        return n

    def close(self) -> None:
        if self.eng is not None:
            self.eng.release()
            self.eng = None


@dataclass
class _Run:
    """Frames (positions in ``--frames``, contiguous) one worker renders in order;
    ``warm_from`` None: independent frames (no taa), else where its warm-up starts."""

    frames: deque[int]
    warm_from: int | None = None


def plan_runs(
    todo: list[int], workers: int, warmup: int, max_cost: int
) -> list[tuple[int, list[int]]]:
    """taa: ``todo`` (ascending positions in ``--frames``) split into contiguous runs
    ``(warm_from, positions)``, ``warm_from = max(0, first - warmup)``. A run's cost
    is its frames plus its warm-up (and ``--frames``' first frame when the warm-up
    does not start there); runs are as even in cost as can be, as few as ``workers``
    when each then costs at most ``max_cost`` frames, else as many as that cap needs
    (handed out as workers come free)."""
    if not todo:
        return []
    blocks: list[list[int]] = [[todo[0]]]
    for i in todo[1:]:
        if i == blocks[-1][-1] + 1:
            blocks[-1].append(i)
        else:
            blocks.append([i])

    def warm_cost(first: int) -> int:
        w = first - max(0, first - warmup)
        return w + (1 if first - warmup > 0 else 0)

    def split(cost: int) -> list[tuple[int, list[int]]] | None:
        runs: list[tuple[int, list[int]]] = []
        for block in blocks:
            k = 0
            while k < len(block):
                take = cost - warm_cost(block[k])
                if take < 1:
                    return None
                piece = block[k : k + take]
                runs.append((max(0, piece[0] - warmup), piece))
                k += take
        return runs

    lo, hi = 1, len(todo) + warmup + 1  # hi: every block in one run
    while lo < hi:  # the smallest cost that needs at most `workers` runs
        mid = (lo + hi) // 2
        runs = split(mid)
        if runs is not None and len(runs) <= max(1, workers):
            hi = mid
        else:
            lo = mid + 1
    cost = min(lo, max(max_cost, warmup + 2))
    out = split(cost)
    assert out is not None  # cost > warm_cost of any first frame
    return out


@dataclass
class _Slot:
    """A worker actor as the driver sees it."""

    actor: Any
    serial: int
    host: str = "?"
    ready: bool = False
    alive: bool = True
    index: int = -1  # the frame it renders, -1 when idle
    run: _Run | None = None  # the rest of its run (taa)
    sent_at: float = 0.0
    frames: int = 0


@dataclass
class RunResult:
    records: dict[int, dict] = field(default_factory=dict)
    failed: dict[int, str] = field(default_factory=dict)
    retried: int = 0
    workers_lost: int = 0
    header: dict | None = None
    hosts: set[str] = field(default_factory=set)
    overhead_ms: list[float] = field(default_factory=list)
    setup_errors: list[str] = field(default_factory=list)
    #: The workers' temporal mode (``--temporal auto`` resolved), None before any.
    temporal: str | None = None
    #: taa: the runs ``(warm_from, first, last)`` as planned (frames, not positions),
    #: whether every one warms up from --frames' first frame (the local render's
    #: history exactly), and the warm-up frames rendered (retries included).
    runs: list[tuple[float | None, float | None, float | None]] = field(default_factory=list)
    exact: bool = False
    warmup_frames: int = 0


class _Pool:
    """The driver's side: workers, the frame queue, and the results."""

    def __init__(
        self,
        ray: Any,
        job: dict,
        todo: list[int],
        frames: list[float | None],
        outputs: list[str],
        n_workers: int,
        resources: dict[str, float],
        rep: Reporter,
        tick: Callable[[], None],
    ) -> None:
        self.ray = ray
        self.job = job
        self.frames = frames
        self.outputs = outputs
        self.todo = list(todo)
        #: Runs not started: single frames until the workers' temporal mode is known
        #: (:meth:`_plan`).
        self.queue: deque[_Run] = deque(_Run(deque([i])) for i in todo)
        self.n_workers = n_workers
        self.planned = False
        self.attempts: dict[int, int] = {}
        self.rep = rep
        self.tick = tick
        self.cls = ray.remote(RenderWorker).options(
            max_restarts=0, max_task_retries=0, max_concurrency=1, **resources
        )
        self.slots: list[_Slot] = []
        self.refs: dict[Any, tuple[str, _Slot]] = {}
        self.serial = 0
        self.replacements = max(2, n_workers)
        self.res = RunResult()
        for _ in range(n_workers):
            self._start()

    def _start(self) -> None:
        self.serial += 1
        slot = _Slot(self.cls.remote(self.job), self.serial)
        self.slots.append(slot)
        self.refs[slot.actor.ready.remote()] = ("ready", slot)

    def _dispatch(self, slot: _Slot) -> None:
        """The next frame of ``slot``'s run, or of the next run queued."""
        if not slot.alive or not slot.ready or slot.index >= 0:
            return
        if slot.run is None or not slot.run.frames:
            slot.run = self.queue.popleft() if self.queue else None
        if slot.run is None:
            return
        i = slot.run.frames.popleft()
        slot.index, slot.sent_at = i, _time.perf_counter()
        ref = slot.actor.render.remote(i, self.frames[i], self.outputs[i], slot.run.warm_from)
        self.refs[ref] = ("frame", slot)
        if on_dispatch is not None:
            on_dispatch(self, slot, i)

    def _busy(self) -> bool:
        """Frames in flight, or frames queued and a worker still starting."""
        kinds = [k for k, _ in self.refs.values()]
        return "frame" in kinds or (bool(self.queue) and "ready" in kinds)

    def run(self) -> RunResult:
        ray = self.ray
        while self._busy():
            done, _ = ray.wait(list(self.refs), num_returns=1)
            kind, slot = self.refs.pop(done[0])
            try:
                msg = ray.get(done[0])
            except (ray.exceptions.RayActorError, ray.exceptions.ActorUnavailableError) as exc:
                self._lost(slot, exc)
                continue
            except ray.exceptions.RayTaskError as exc:
                msg = {"index": slot.index, "error": _task_error(exc)}
            if kind == "ready":
                self._ready(slot, msg)
            else:
                self._frame(slot, msg)
            self._dispatch(slot)
        for run in self.queue:  # no worker left to render them
            for i in run.frames:
                self.res.failed.setdefault(i, "no worker left to render it")
        return self.res

    def _ready(self, slot: _Slot, msg: dict) -> None:
        slot.host = msg.get("host", "?")
        if msg.get("error"):
            slot.alive = False
            # said at the end (once) when other workers ran, else the run's error
            self.res.setup_errors.append(f"Ray worker on {slot.host}: {msg['error']}")
            self.ray.kill(slot.actor)
            return
        slot.ready = True
        self.res.hosts.add(slot.host)
        if self.res.header is None:
            self.res.header = msg["header"]
        self.rep.warn_all(msg.get("warnings", ()))
        if not self.planned:
            self._plan(str(msg.get("temporal") or ""))

    def _plan(self, temporal: str) -> None:
        """The first worker set up: its temporal mode decides the queue. taa (the
        history is the previous frames): contiguous runs with warm-ups
        (:func:`plan_runs`), said in one line before any frame; else single frames."""
        self.planned = True
        self.res.temporal = temporal
        if temporal != "taa":
            return
        runs = plan_runs(self.todo, self.n_workers, TAA_WARMUP_FRAMES, TAA_RUN_MAX_COST)
        self.queue = deque(_Run(deque(p), w) for w, p in runs)
        fr = self.frames
        self.res.runs = [(fr[w], fr[p[0]], fr[p[-1]]) for w, p in runs]
        exact = self.res.exact = all(w == 0 for w, _ in runs)
        how = (
            "each warmed up from --frames' first frame: the local render's frames"
            if exact
            else f"each warmed up {TAA_WARMUP_FRAMES} frames early, unwritten: the taa "
            "history approximates the local render's (docs/DISTRIBUTED.md)"
        )
        self.rep.say(
            f"stb render: --temporal taa on Ray: {len(runs)} run{'s' if len(runs) != 1 else ''}"
            f" of contiguous frames, {how}"
        )

    def _frame(self, slot: _Slot, msg: dict) -> None:
        i = slot.index
        slot.index = -1
        rtt = (_time.perf_counter() - slot.sent_at) * 1e3
        self.rep.warn_all(msg.get("warnings", ()))
        if "error" in msg:
            self.res.failed[i] = str(msg["error"])
            _error(self.rep, f"stb render: frame {_label(self.frames[i])} failed: {msg['error']}")
        else:
            rec = msg["record"]
            rec["worker"] = {"serial": slot.serial, "host": slot.host}
            self.res.records[i] = rec
            slot.frames += 1
            self.res.warmup_frames += int(msg.get("warmup_frames", 0) or 0)
            if "busy_ms" in msg:
                self.res.overhead_ms.append(rtt - float(msg["busy_ms"]))
        self.tick()

    def _lost(self, slot: _Slot, exc: BaseException) -> None:
        """``slot``'s actor died: its frame back to the queue (bounded), a replacement."""
        slot.alive = False
        self.res.workers_lost += 1
        why = " ".join(str(exc).split())[:200]
        if not slot.ready:
            self.res.setup_errors.append(f"Ray worker {slot.serial} died while starting: {why}")
        i = slot.index
        slot.index = -1
        # the rest of its run goes back whole, with its warm-up (taa: from the same
        # frame, so that the frames are those of an uninterrupted run)
        rest = slot.run.frames if slot.run is not None else deque()
        warm_from = slot.run.warm_from if slot.run is not None else None
        slot.run = None
        if i >= 0:
            n = self.attempts[i] = self.attempts.get(i, 1) + 1
            if n > MAX_ATTEMPTS:
                self.res.failed[i] = f"its worker died {MAX_ATTEMPTS} times (last: {why})"
                _error(
                    self.rep,
                    f"stb render: frame {_label(self.frames[i])} failed: {self.res.failed[i]}",
                )
                self.tick()
            else:
                self.res.retried += 1
                rest.appendleft(i)
                self.rep.say(
                    f"stb render: worker {slot.serial} on {slot.host} died during frame "
                    f"{_label(self.frames[i])}; re-running it"
                )
        if rest:
            self.queue.appendleft(_Run(rest, warm_from))
        if self.queue and self.replacements > 0:
            self.replacements -= 1
            self._start()
        for s in self.slots:
            self._dispatch(s)

    def close(self) -> None:
        for s in self.slots:
            if s.alive:
                try:
                    self.ray.kill(s.actor)
                except Exception:  # noqa: BLE001 - best effort at the end
                    pass


def _maybe_exit(hook: dict[str, Any] | None, index: int) -> None:
    """The :data:`exit_mid_frame` test hook, in the worker."""
    if not hook or hook.get("index") != index:
        return
    try:
        fd = os.open(hook["marker"], os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:
        return
    os.close(fd)
    os._exit(1)


def _error(rep: Reporter, text: str) -> None:
    """A line that ``--quiet`` does not silence (a frame that failed)."""
    if rep.quiet:
        print(text, file=sys.stderr, flush=True)
    else:
        rep.say(text)


def _task_error(exc: BaseException) -> str:
    cause = getattr(exc, "cause", None)
    if isinstance(cause, BaseException):
        return " ".join(f"{type(cause).__name__}: {cause}".split())[:500]
    return " ".join(str(exc).split())[:500]


def _label(fr: float | None) -> str:
    if fr is None:
        return "default"
    return f"{fr:g}"


def _job(
    args: argparse.Namespace,
    first: float | None,
    threads: int,
    frames: list[float | None] | None = None,
) -> dict[str, Any]:
    """The render's arguments for the workers, with absolute paths; ``frames``: all
    of ``--frames`` (default: ``first`` alone)."""
    values = {k: v for k, v in vars(args).items() if k not in _SKIP_ARGS}
    for k in ("scene", "output", "ocio_config"):
        if values.get(k):
            values[k] = os.path.abspath(values[k])
    values["stats"] = None  # written by the driver
    values["quiet"] = True
    values["print_graph"] = False
    return {
        "args": values,
        "first": first,
        "frames": frames if frames is not None else [first],
        "threads": threads,
        "exit_mid_frame": exit_mid_frame,
    }


def _worker_resources(args: argparse.Namespace, total: dict[str, float]) -> dict[str, float]:
    cpus = float(args.worker_cpus)
    gpus = args.worker_gpus
    if gpus is None:
        gpus = 1.0 if total.get("GPU", 0.0) >= 1.0 else 0.0
    out = {"num_cpus": cpus}
    if gpus:
        out["num_gpus"] = float(gpus)
    return out


def _n_workers(args: argparse.Namespace, res: dict[str, float], total: dict, todo: int) -> int:
    """``--workers``, or as many as the cluster fits; never more than fit (an actor
    that can never be placed would wait for ever) nor more than the frames."""
    cpus, gpus = total.get("CPU", 0.0), total.get("GPU", 0.0)
    if res["num_cpus"] > cpus:
        raise CliError(f"--worker-cpus {res['num_cpus']:g}: the Ray cluster has {cpus:g} CPUs")
    fits = int(cpus // res["num_cpus"])
    if res.get("num_gpus"):
        if res["num_gpus"] > gpus:
            raise CliError(f"--worker-gpus {res['num_gpus']:g}: the Ray cluster has {gpus:g} GPUs")
        fits = min(fits, int(gpus // res["num_gpus"]))
    if args.workers is not None:
        if args.workers < 1:
            raise CliError(f"--workers must be >= 1, got {args.workers}")
        fits = min(fits, args.workers)
    return max(1, min(fits, todo))


def run(args: argparse.Namespace, rep: Reporter) -> int:
    """``stb render`` on Ray: the driver (checks, queue, progress, stats)."""
    from ..apps import render_steps as r
    from ..io.images import frame_path, has_frame_placeholder

    r._check_settings(args)
    frames = r._check_outputs(args)
    r._render_settings(args)  # option checks before any worker starts
    r._color_pipeline(args)
    if args.worker_cpus < 1:
        raise CliError(f"--worker-cpus must be >= 1, got {args.worker_cpus}")
    outputs = [
        os.path.abspath(
            frame_path(args.output, fr)
            if fr is not None and has_frame_placeholder(args.output)
            else args.output
        )
        for fr in frames
    ]
    todo, skipped = [], []
    for i, out in enumerate(outputs):
        if args.skip_existing and os.path.exists(out):
            skipped.append(i)
        else:
            todo.append(i)
    if skipped:
        r._say_skipped(rep, [outputs[i] for i in skipped], len(frames))
    stats: dict[str, Any] = {"scene": args.scene, "frames": []}
    res = RunResult()
    t0 = _time.perf_counter()
    n = 0
    if todo:
        with connected(args.ray) as ray:
            total = cluster_resources(ray)
            resources = _worker_resources(args, total)
            n = _n_workers(args, resources, total, len(todo))
            res = _render_on(ray, args, rep, frames, outputs, todo, skipped, n, resources)
    wall = _time.perf_counter() - t0
    if res.header is not None:
        stats = {**res.header}
        stats["frames"] = [res.records[i] for i in sorted(res.records)]
    done, failed = len(res.records), len(res.failed)
    over = sorted(res.overhead_ms)
    stats["ray"] = {
        "address": args.ray or "default",
        "workers": n,
        "hosts": sorted(res.hosts),
        "frames_done": done,
        "frames_failed": failed,
        "frames_skipped": len(skipped),
        "retried": res.retried,
        "workers_lost": res.workers_lost,
        "failures": [
            {"frame": frames[i] if frames[i] is not None else "default", "error": e}
            for i, e in sorted(res.failed.items())
        ],
        "temporal": _temporal_stats(res),
        "wall_s": round(wall, 3),
        # driver round trip minus the worker's own time, per frame
        "scheduling_overhead_ms": {
            "median": round(over[len(over) // 2], 3) if over else None,
            "mean": round(sum(over) / len(over), 3) if over else None,
        },
    }
    stats["warnings"] = list(rep.lines)
    if todo and res.header is None:
        raise CliError(res.setup_errors[0] if res.setup_errors else "no Ray worker started")
    rep.say(
        f"stb render: {done} frame{'s' if done != 1 else ''} done, {failed} failed, "
        f"{res.retried} retried, {len(skipped)} skipped ({n} Ray worker{'s' if n != 1 else ''}"
        f" on {len(res.hosts)} host{'s' if len(res.hosts) != 1 else ''}, {wall:.1f} s)"
    )
    r._finish(args, stats, done, rep)
    if failed:
        return EXIT_ERROR
    if done == 0 and not args.skip_existing:
        return EXIT_ERROR
    return EXIT_OK


def _temporal_stats(res: RunResult) -> dict[str, Any]:
    """``--stats``' ``ray.temporal``: the mode the workers used (as a local render
    would: ``--temporal auto`` resolved) and, with taa, how the frames were split."""
    out: dict[str, Any] = {"mode": res.temporal}
    if res.temporal == "taa":
        out.update(
            {
                "warmup": TAA_WARMUP_FRAMES,
                "runs": [{"warm_from": w, "first": a, "last": b} for w, a, b in res.runs],
                "warmup_frames_rendered": res.warmup_frames,
                # every run warmed up from --frames' first frame: the local frames
                "exact": res.exact,
            }
        )
    return out


def _render_on(
    ray: Any,
    args: argparse.Namespace,
    rep: Reporter,
    frames: list[float | None],
    outputs: list[str],
    todo: list[int],
    skipped: list[int],
    n: int,
    resources: dict[str, float],
) -> RunResult:
    from tqdm import tqdm

    bar = tqdm(
        total=len(frames),
        initial=len(skipped),
        unit="frame",
        desc="stb render (ray)",
        file=sys.stderr,
        disable=True if rep.quiet else None,
        dynamic_ncols=True,
    )
    if not bar.disable:
        rep.bar = bar
    job = _job(args, frames[0], int(resources["num_cpus"]), frames)
    pool = _Pool(ray, job, todo, frames, outputs, n, resources, rep, lambda: bar.update(1))
    try:
        res = pool.run()
    finally:
        pool.close()
        bar.close()
        rep.bar = None
    if res.header is not None:
        for err in dict.fromkeys(res.setup_errors):
            rep.say(f"stb render: {err}")
    return res
