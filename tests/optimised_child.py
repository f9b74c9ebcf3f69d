"""The optimised render child's set-up (tests/optimised.py), in a module of its own that
imports nothing of USD: the spawned child unpickles and runs it before its first task
imports ``optimised`` (and with it pxr and stb_hydra), so whatever must precede the
first GL context or the first USD import goes here. (A USD thread limit set here was
measured and dropped: docs/TESTING.md, "USD's threads in the workers".)"""

from __future__ import annotations

import os


def init() -> None:
    """Before the child's first GL context: LLVM's default optimisation for llvmpipe
    (``GALLIVM_PERF`` empty: the flag is read when the context starts; conftest keeps an
    existing value)."""
    os.environ["GALLIVM_PERF"] = ""
