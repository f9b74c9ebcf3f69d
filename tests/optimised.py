"""Long convergence renders in a child process whose shaders are LLVM-optimised (issue 32).

The test processes compile llvmpipe's shaders without LLVM's optimisation passes
(``GALLIVM_PERF=nopt``, tests/conftest.py): most of a cold run is compiling, and a
program compiles ~2.6x faster that way. The price is execution: STB and reuse frames
run ~1.7-2x slower under ``nopt`` (docs/TESTING.md, "Optimised child for the
convergence tests"). The convergence tests are the exception to "mostly compiling":
a few option sets each, hundreds of frames each. :func:`render_progressive` renders
them in one child process per test process (spawned once, on first use) with the
optimisation on, so a few programs compile slower and many frames run faster.

The images are the same bit for bit either way (LLVM's passes do not reassociate or
contract float operations here; ``tests/test_shader_optimisation.py``), so a test's
verdict does not depend on where it rendered. Mesa's shader cache keys its entries on
the flag: the child's programs are cached beside the parent's.

The child is used only where the parent runs under ``nopt``; with ``GALLIVM_PERF``
set otherwise the render runs in process. On a GPU host (which ignores the flag) the
child still renders, on the GPU, in a context of its own: no gain, no harm.
``STB_TEST_OPT_CHILD=0`` turns the child off.
"""

from __future__ import annotations

import atexit
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from pxr import Usd

import stb_hydra

_pool: ProcessPoolExecutor | None = None
#: CPU seconds (user + sys) the child spent on renders this process asked for: added
#: to the per-test CPU log of tests/conftest.py (the child is never waited for).
child_cpu_s = 0.0


def _use_child() -> bool:
    return os.environ.get("GALLIVM_PERF") == "nopt" and os.environ.get("STB_TEST_OPT_CHILD") != "0"


def _child_init() -> None:
    # Before the child's first GL context: llvmpipe reads the flag when it starts.
    # Empty = LLVM's default optimisation (conftest keeps an existing value).
    os.environ["GALLIVM_PERF"] = ""


def _timed(fn, args: tuple, kwargs: dict):
    t0 = os.times()
    out = fn(*args, **kwargs)
    t1 = os.times()
    return out, (t1.user - t0.user) + (t1.system - t0.system)


def _render_text(usda: str, counts: list[int], kwargs: dict) -> dict[int, np.ndarray]:
    from pxr import Sdf

    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.ImportFromString(usda)
    return stb_hydra.render_progressive(Usd.Stage.Open(layer), counts, **kwargs)


def _child() -> ProcessPoolExecutor:
    global _pool
    if _pool is None:
        _pool = ProcessPoolExecutor(
            max_workers=1,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_child_init,
        )
        atexit.register(_pool.shutdown)
    return _pool


def call(fn, *args, **kwargs):
    """``fn(*args, **kwargs)``, in the optimised child when the test process runs under
    ``nopt``. ``fn`` must be a module-level function of an importable module (a test
    module is: tests/ is on the path) and its arguments and result picklable; it makes
    its own engines (the child has its own GL context)."""
    global child_cpu_s
    if not _use_child():
        return fn(*args, **kwargs)
    out, cpu = _child().submit(_timed, fn, args, kwargs).result()
    child_cpu_s += cpu
    return out


def render_progressive(stage: Usd.Stage, counts, **kwargs) -> dict[int, np.ndarray]:
    """:func:`stb_hydra.render_progressive` of ``stage`` (an in-memory stage of one
    root layer, as ``stagegen.usda_stage`` makes), in the optimised child when the
    test process runs under ``nopt``."""
    if not _use_child():
        return stb_hydra.render_progressive(stage, counts, **kwargs)
    return call(_render_text, stage.GetRootLayer().ExportToString(), list(counts), kwargs)
