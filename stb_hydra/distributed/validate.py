"""``stb validate ... --ray [ADDRESS]``: one Ray task per asset.

Each task runs :func:`stb_hydra.validate.runner.validate_in_process` in a Ray worker
process (set up once per process as the local ``--jobs`` workers are: schema
registration, our validators, USD single-threaded) and returns the asset's report as
a dict; the driver keeps as many tasks in flight as the cluster has CPUs, feeds the
next asset to whichever finishes (``ray.wait``) and assembles the JSON/HTML report
itself, so the findings are those of a local run. A worker that dies on an asset is
retried once (:data:`MAX_RETRIES`: a lost machine), then the asset gets a ``crash``
finding, as locally; an asset running past the per-asset timeout is cancelled and
gets a ``crash`` finding too.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Callable, Sequence
from typing import Any

from .. import limits
from .cluster import cluster_resources, connected

#: Re-runs of an asset whose worker died (a lost machine) before it is a crash.
MAX_RETRIES = 1

_READY = False
_SELECTIONS: dict[tuple[str, ...] | None, Any] = {}


def _setup() -> None:
    """Once per worker process: what ``validate.parallel._worker_main`` does."""
    global _READY
    if _READY:
        return
    import stb_hydra  # noqa: F401  (schema before any stage)

    # USD's threads are not lowered to 1 here: TBB's started threads would spin for the
    # worker's life (stb_hydra.usd_threads); the parallelism is still the workers.
    from ..validate import register_validators

    register_validators()
    _READY = True


def validate_one(
    path: str, root: str, rules: list[str] | None, thumbnails: bool, hook: str | None = None
) -> dict:
    """One asset's report (a dict: :meth:`AssetReport.to_dict`), in a Ray worker.
    ``hook``: the driver's test crash hook (``validate.common.CRASH_HOOK_ENV``), which
    Ray workers started before it was set do not inherit."""
    import os

    from ..validate.common import CRASH_HOOK_ENV

    if hook:
        os.environ[CRASH_HOOK_ENV] = hook
    else:
        os.environ.pop(CRASH_HOOK_ENV, None)
    _setup()
    from ..validate.runner import Selection, validate_in_process

    key = tuple(rules) if rules else None
    sel = _SELECTIONS.get(key)
    if sel is None:
        sel = _SELECTIONS[key] = Selection.parse(rules)
    out = validate_in_process(path, root, sel, thumbnails).to_dict()
    return out


def run_on_ray(
    address: str | None,
    tasks: Sequence[tuple[str, str]],
    rules: list[str] | None = None,
    thumbnails: bool = False,
    timeout_s: float = limits.VALIDATE_ASSET_TIMEOUT_S,
    on_done: Callable[[Any], None] | None = None,
    in_flight: int | None = None,
) -> tuple[list[Any], int]:
    """Validate ``(path, library_root)`` tasks on Ray; (reports in task order, the
    number of assets kept in flight: the cluster's CPUs unless ``in_flight``)."""
    import os

    from ..validate.common import CRASH_HOOK_ENV
    from ..validate.findings import AssetReport
    from ..validate.runner import crash_report

    hook = os.environ.get(CRASH_HOOK_ENV) or None

    results: list[Any] = [None] * len(tasks)
    with connected(address) as ray:
        n = in_flight or max(1, int(cluster_resources(ray).get("CPU", 1.0)))
        n = max(1, min(n, len(tasks)))
        fn = ray.remote(num_cpus=1, max_retries=MAX_RETRIES)(validate_one)
        pending = list(range(len(tasks)))[::-1]
        running: dict[Any, tuple[int, float]] = {}

        def submit() -> None:
            while pending and len(running) < n:
                i = pending.pop()
                path, root = tasks[i]
                running[fn.remote(path, root, rules, thumbnails, hook)] = (i, time.monotonic())

        def finish(i: int, rep: Any) -> None:
            results[i] = rep
            if on_done is not None:
                on_done(rep)

        submit()
        while running:
            deadline = min(t for _, t in running.values()) + timeout_s
            wait_s = max(0.0, deadline - time.monotonic())
            done, _ = ray.wait(list(running), num_returns=1, timeout=wait_s)
            for ref in done:
                i, t0 = running.pop(ref)
                path, root = tasks[i]
                try:
                    rep = AssetReport.from_dict(ray.get(ref))
                except ray.exceptions.RayError as exc:
                    why = " ".join(str(exc).split()).splitlines()[0][:300]
                    msg = (
                        f"Ray worker died while validating this asset ({type(exc).__name__}: {why})"
                    )
                    rep = crash_report(path, root, msg, time.monotonic() - t0)
                finish(i, rep)
            now = time.monotonic()
            for ref, (i, t0) in list(running.items()):
                if now - t0 > timeout_s:
                    running.pop(ref)
                    ray.cancel(ref, force=True)
                    path, root = tasks[i]
                    msg = f"worker timed out after {timeout_s:g} s while validating this asset"
                    finish(i, crash_report(path, root, msg, now - t0))
            submit()
    host = socket.gethostname()
    return [
        r if r is not None else crash_report(p, root, f"not validated (driver {host})")
        for r, (p, root) in zip(results, tasks)
    ], n
