"""Crash-isolated worker processes for ``stb validate --jobs N``.

N long-lived worker processes (multiprocessing, ``spawn`` start method: a fresh
interpreter that imports ``stb_hydra`` -- schema registration -- before anything
else) each validate one asset at a time and send back a JSON-ready report over a
pipe. The parent waits on the pipes *and* the process sentinels: a worker that dies
mid-asset (segfault, abort, OOM kill) or runs past the per-asset timeout is
reported as a ``crash`` finding for that asset -- with the exit signal and the tail
of the worker's stderr (USD diagnostics go there) -- and replaced; the run goes on.
Exceptions inside an asset (Tf errors included) never kill a worker: they become
``crash`` findings in the worker. The parallelism is the processes; a worker keeps
USD's default thread count (lowering it after ``import stb_hydra`` would leave TBB's
threads spinning: :mod:`stb_hydra.usd_threads`).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait

from .. import limits
from .findings import AssetReport

#: Characters of a dead worker's stderr quoted in its crash finding.
_LOG_TAIL = 1500
#: Workers dying before they are ready, in one run, before the run is abandoned.
_MAX_START_FAILURES = 3


class WorkerStartError(RuntimeError):
    """Workers cannot start (broken environment); one-line message with their stderr."""


def _limit_memory(max_bytes: int) -> None:
    """Cap this process's address space (RLIMIT_AS) at ``max_bytes`` (never raised
    above an existing hard limit)."""
    import resource

    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    cap = max_bytes if hard == resource.RLIM_INFINITY else min(max_bytes, hard)
    if soft == resource.RLIM_INFINITY or soft > cap:
        resource.setrlimit(resource.RLIMIT_AS, (cap, hard))


def _worker_main(
    conn: Connection, log_path: str, rules: list[str] | None, thumbnails: bool
) -> None:
    """Worker loop: ``(path, root)`` in, report dict out; ``None`` ends it."""
    fd = os.open(log_path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    os.dup2(fd, 2)  # C++ diagnostics and Python tracebacks of this worker
    os.close(fd)
    _limit_memory(limits.VALIDATE_WORKER_MAX_BYTES)
    import stb_hydra  # noqa: F401  (schema before any stage)

    # Not lowered to one thread: TBB's threads, started by the import above, would spin
    # in sched_yield for the worker's life (stb_hydra.usd_threads).
    from . import register_validators
    from .runner import Selection, validate_in_process

    register_validators()
    sel = Selection.parse(rules)
    conn.send({"ready": True})
    while True:
        try:
            task = conn.recv()
        except EOFError:
            break
        if task is None:
            break
        path, root = task
        rep = validate_in_process(path, root, sel, thumbnails)
        conn.send(rep.to_dict())
    conn.close()


@dataclass
class _Worker:
    proc: mp.process.BaseProcess
    conn: Connection
    log: str
    task: int = -1
    started: float = 0.0
    log_offset: int = 0
    ready: bool = False


def _log_tail(path: str, offset: int) -> str:
    try:
        with open(path, "rb") as f:
            f.seek(offset)
            text = f.read().decode("utf-8", "replace")
    except OSError:
        return ""
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    return " | ".join(lines)[-_LOG_TAIL:]


def _exit_text(code: int | None) -> str:
    if code is None:
        return "still running"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exited with status {code}"


def run_parallel(
    tasks: Sequence[tuple[str, str]],
    jobs: int,
    rules: list[str] | None = None,
    thumbnails: bool = False,
    timeout_s: float = limits.VALIDATE_ASSET_TIMEOUT_S,
    on_done: Callable[[AssetReport], None] | None = None,
) -> list[AssetReport]:
    """Validate ``(path, library_root)`` tasks in ``jobs`` worker processes; reports in
    task order."""
    pool = _Pool(tasks, rules, thumbnails, timeout_s, on_done)
    try:
        pool.run(max(1, min(jobs, len(tasks))))
    finally:
        pool.close()
    return pool.reports()


class _Pool:
    """The workers of one :func:`run_parallel` call, its task queue and its results."""

    def __init__(
        self,
        tasks: Sequence[tuple[str, str]],
        rules: list[str] | None,
        thumbnails: bool,
        timeout_s: float,
        on_done: Callable[[AssetReport], None] | None,
    ) -> None:
        self.ctx = mp.get_context("spawn")
        self.tasks = tasks
        self.rules = rules
        self.thumbnails = thumbnails
        self.timeout_s = timeout_s
        self.on_done = on_done
        self.results: list[AssetReport | None] = [None] * len(tasks)
        self.pending = list(range(len(tasks)))[::-1]  # next task last: pop()
        self.logdir = tempfile.mkdtemp(prefix="stb-validate-")
        self.workers: list[_Worker] = []
        self.serial = 0
        self.start_failures = 0

    def run(self, n_workers: int) -> None:
        """Start ``n_workers`` and serve them until every task has a report."""
        self.workers = [self._spawn() for _ in range(n_workers)]
        while any(r is None for r in self.results):
            for w in self._wait():
                self._serve(w)
            self._reap_timeouts()
            if (
                not self.pending
                and all(w.task < 0 for w in self.workers)
                and any(r is None for r in self.results)
            ):
                break  # defensive: nothing in flight yet results missing

    def reports(self) -> list[AssetReport]:
        """Reports in task order; a task that never ran gets a ``not validated`` crash."""
        from .runner import crash_report

        return [
            r
            if r is not None
            else crash_report(self.tasks[i][0], self.tasks[i][1], "not validated")
            for i, r in enumerate(self.results)
        ]

    def close(self) -> None:
        """Stop every worker (politely, then by force) and delete their logs."""
        for w in self.workers:
            try:
                w.conn.send(None)
            except (OSError, ValueError):
                pass
        for w in self.workers:
            w.proc.join(5)
            if w.proc.is_alive():
                w.proc.kill()
                w.proc.join(1)
        for name in os.listdir(self.logdir):
            try:
                os.unlink(os.path.join(self.logdir, name))
            except OSError:
                pass
        try:
            os.rmdir(self.logdir)
        except OSError:
            pass

    # -- steps ------------------------------------------------------------------------------

    def _spawn(self) -> _Worker:
        self.serial += 1
        parent, child = self.ctx.Pipe()
        log = os.path.join(self.logdir, f"worker{self.serial}.log")
        p = self.ctx.Process(
            target=_worker_main,
            args=(child, log, self.rules, self.thumbnails),
            name=f"stb-validate-{self.serial}",
            daemon=True,
        )
        p.start()
        child.close()
        return _Worker(p, parent, log)

    def _finish(self, i: int, rep: AssetReport) -> None:
        self.results[i] = rep
        if self.on_done is not None:
            self.on_done(rep)

    def _dispatch(self, w: _Worker) -> None:
        """Send the next pending task to ``w`` once it is ready."""
        if not self.pending or not w.ready:
            return
        i = self.pending.pop()
        w.task, w.started = i, time.monotonic()
        try:
            w.log_offset = os.path.getsize(w.log)
        except OSError:
            w.log_offset = 0
        w.conn.send(self.tasks[i])

    def _fail(self, w: _Worker, why: str) -> None:
        """Report ``w``'s asset (if any) as a crash quoting its stderr, then kill ``w``."""
        from .runner import crash_report

        if w.task >= 0:
            path, root = self.tasks[w.task]
            tail = _log_tail(w.log, w.log_offset)
            msg = f"worker {why} while validating this asset" + (
                f"; stderr: {tail}" if tail else ""
            )
            self._finish(w.task, crash_report(path, root, msg, time.monotonic() - w.started))
            w.task = -1
        try:
            w.proc.kill()
        except (OSError, AttributeError):
            pass
        w.proc.join(5)
        w.conn.close()

    def _wait(self) -> list[_Worker]:
        """Workers with a message or a dead process, once each; waits until one is or
        the earliest per-asset deadline passes."""
        waitables: dict[object, _Worker] = {}
        for w in self.workers:
            waitables[w.conn] = w
            waitables[w.proc.sentinel] = w
        deadline = min(
            (w.started + self.timeout_s for w in self.workers if w.task >= 0), default=None
        )
        wait_s = None if deadline is None else max(0.0, deadline - time.monotonic())
        ready = wait(list(waitables), timeout=wait_s)
        out: dict[int, _Worker] = {}
        for obj in ready:
            w = waitables[obj]
            out.setdefault(id(w), w)
        return list(out.values())

    def _serve(self, w: _Worker) -> None:
        """Handle ``w``'s ready signal or report, or replace it when it died."""
        msg = None
        if w.conn.poll():
            try:
                msg = w.conn.recv()
            except (EOFError, OSError):
                msg = None
        if isinstance(msg, dict) and msg.get("ready"):
            w.ready = True
            self._dispatch(w)
            return
        if isinstance(msg, dict) and w.task >= 0:
            self._finish(w.task, AssetReport.from_dict(msg))
            w.task = -1
            self._dispatch(w)
            return
        if not w.proc.is_alive() or msg is None:
            w.proc.join(1)
            if not w.ready:
                self._count_start_failure(w)
            self._fail(w, _exit_text(w.proc.exitcode))
            self.workers[self.workers.index(w)] = self._spawn()

    def _count_start_failure(self, w: _Worker) -> None:
        """Raise WorkerStartError once ``_MAX_START_FAILURES`` workers died unready."""
        self.start_failures += 1
        if self.start_failures >= _MAX_START_FAILURES:
            tail = _log_tail(w.log, 0)
            raise WorkerStartError(
                f"validation worker failed to start ({_exit_text(w.proc.exitcode)}): {tail}"
            )

    def _reap_timeouts(self) -> None:
        """Crash-report and replace every worker past the per-asset timeout."""
        now = time.monotonic()
        for k, w in enumerate(self.workers):
            if w.task >= 0 and now - w.started > self.timeout_s:
                self._fail(w, f"timed out after {self.timeout_s:g} s")
                self.workers[k] = self._spawn()
