"""The optimised render child's set-up (tests/optimised.py), in a module of its own that
imports nothing of USD: the spawned child unpickles and runs it before its first task
imports ``optimised`` (and with it pxr and stb_hydra).

Order matters for USD's threads: ``import stb_hydra`` already starts TBB's worker
threads, and a concurrency limit set after that leaves them spinning in
``sched_yield`` for as long as the process lives (measured: an idle process, 8 s: 1.3 s
user + 6.7 s sys; in a whole warm run the two children spent ~40 s of sys time so).
Set first, TBB starts none (docs/TESTING.md, "USD's threads in the workers")."""

from __future__ import annotations

import os


def init() -> None:
    """Before the child's first GL context and its first USD import: LLVM's default
    optimisation for llvmpipe (``GALLIVM_PERF`` empty: the flag is read when the context
    starts; conftest keeps an existing value) and USD serial, as in the xdist workers."""
    os.environ["GALLIVM_PERF"] = ""
    from pxr import Work

    Work.SetConcurrencyLimit(1)
