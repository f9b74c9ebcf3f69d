"""Crash-isolated worker processes for ``stb validate --jobs N``.

N long-lived worker processes (multiprocessing, ``spawn`` start method: a fresh
interpreter that imports ``stb_hydra`` -- schema registration -- before anything
else) each validate one asset at a time and send back a JSON-ready report over a
pipe. The parent waits on the pipes *and* the process sentinels: a worker that dies
mid-asset (segfault, abort, OOM kill) or runs past the per-asset timeout is
reported as a ``crash`` finding for that asset -- with the exit signal and the tail
of the worker's stderr (USD diagnostics go there) -- and replaced; the run goes on.
Exceptions inside an asset (Tf errors included) never kill a worker: they become
``crash`` findings in the worker. Each worker runs USD single-threaded
(``Work.SetConcurrencyLimit(1)``): the parallelism is the processes.
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


def _worker_main(conn: Connection, log_path: str, rules: list[str] | None,
                 thumbnails: bool) -> None:
    """Worker loop: ``(path, root)`` in, report dict out; ``None`` ends it."""
    fd = os.open(log_path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    os.dup2(fd, 2)  # C++ diagnostics and Python tracebacks of this worker
    os.close(fd)
    from pxr import Work

    import stb_hydra  # noqa: F401  (schema before any stage)

    Work.SetConcurrencyLimit(1)
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
    from .runner import crash_report

    ctx = mp.get_context("spawn")
    results: list[AssetReport | None] = [None] * len(tasks)
    pending = list(range(len(tasks)))[::-1]
    logdir = tempfile.mkdtemp(prefix="stb-validate-")
    workers: list[_Worker] = []
    serial = 0
    start_failures = 0

    def spawn() -> _Worker:
        nonlocal serial
        serial += 1
        parent, child = ctx.Pipe()
        log = os.path.join(logdir, f"worker{serial}.log")
        p = ctx.Process(target=_worker_main, args=(child, log, rules, thumbnails),
                        name=f"stb-validate-{serial}", daemon=True)
        p.start()
        child.close()
        return _Worker(p, parent, log)

    def finish(i: int, rep: AssetReport) -> None:
        results[i] = rep
        if on_done is not None:
            on_done(rep)

    def dispatch(w: _Worker) -> None:
        if not pending or not w.ready:
            return
        i = pending.pop()
        w.task, w.started = i, time.monotonic()
        try:
            w.log_offset = os.path.getsize(w.log)
        except OSError:
            w.log_offset = 0
        w.conn.send(tasks[i])

    def fail(w: _Worker, why: str) -> None:
        if w.task >= 0:
            path, root = tasks[w.task]
            tail = _log_tail(w.log, w.log_offset)
            msg = f"worker {why} while validating this asset" + (f"; stderr: {tail}" if tail
                                                                 else "")
            finish(w.task, crash_report(path, root, msg, time.monotonic() - w.started))
            w.task = -1
        try:
            w.proc.kill()
        except (OSError, AttributeError):
            pass
        w.proc.join(5)
        w.conn.close()

    try:
        n = max(1, min(jobs, len(tasks)))
        workers = [spawn() for _ in range(n)]
        while any(r is None for r in results):
            waitables = {}
            for w in workers:
                waitables[w.conn] = w
                waitables[w.proc.sentinel] = w
            deadline = min((w.started + timeout_s for w in workers if w.task >= 0),
                           default=None)
            wait_s = None if deadline is None else max(0.0, deadline - time.monotonic())
            ready = wait(list(waitables), timeout=wait_s)
            handled: set[int] = set()
            for obj in ready:
                w = waitables[obj]
                if id(w) in handled:
                    continue
                handled.add(id(w))
                msg = None
                if w.conn.poll():
                    try:
                        msg = w.conn.recv()
                    except (EOFError, OSError):
                        msg = None
                if isinstance(msg, dict) and msg.get("ready"):
                    w.ready = True
                    dispatch(w)
                    continue
                if isinstance(msg, dict) and w.task >= 0:
                    finish(w.task, AssetReport.from_dict(msg))
                    w.task = -1
                    dispatch(w)
                    continue
                if not w.proc.is_alive() or msg is None:
                    w.proc.join(1)
                    if not w.ready:
                        start_failures += 1
                        if start_failures >= _MAX_START_FAILURES:
                            tail = _log_tail(w.log, 0)
                            raise WorkerStartError(
                                f"validation worker failed to start "
                                f"({_exit_text(w.proc.exitcode)}): {tail}"
                            )
                    fail(w, _exit_text(w.proc.exitcode))
                    workers[workers.index(w)] = spawn()
            now = time.monotonic()
            for k, w in enumerate(workers):
                if w.task >= 0 and now - w.started > timeout_s:
                    fail(w, f"timed out after {timeout_s:g} s")
                    workers[k] = spawn()
            if not pending and all(w.task < 0 for w in workers) and any(
                r is None for r in results
            ):
                break  # defensive: nothing in flight yet results missing
    finally:
        for w in workers:
            try:
                w.conn.send(None)
            except (OSError, ValueError):
                pass
        for w in workers:
            w.proc.join(5)
            if w.proc.is_alive():
                w.proc.kill()
                w.proc.join(1)
        for name in os.listdir(logdir):
            try:
                os.unlink(os.path.join(logdir, name))
            except OSError:
                pass
        try:
            os.rmdir(logdir)
        except OSError:
            pass
    return [r if r is not None else crash_report(tasks[i][0], tasks[i][1], "not validated")
            for i, r in enumerate(results)]
