"""Shared pytest fixtures: real data from ../shared/testdata, a real GL context."""

from __future__ import annotations

import os
import resource
import time
from pathlib import Path

import pytest

import stb_hydra  # noqa: F401  (registers the codeless USD schema before any stage opens)

# llvmpipe compiles the suite's shader variants with LLVM's optimisation passes off:
# ~2.5x faster compiles (most of a cold run), ~1.3x slower execution, the same images
# (tests/test_shader_optimisation.py renders with them on and compares). Set before
# any GL context; a GALLIVM_PERF already in the environment (even empty: optimised)
# wins, and the CLI subprocesses inherit it. No effect on GPU drivers. docs/TESTING.md.
os.environ.setdefault("GALLIVM_PERF", "nopt")
# Under ``pytest -n N`` with at least one worker per core, each worker's llvmpipe draws on
# its own thread instead of starting one rasterizer thread per core (N x cores threads
# on the cores): on the 2-core machine, warm, 346 s instead of 398 s in one pytest run and
# 390 s instead of 399 s through `make test` (docs/TESTING.md, runs 7 and 8). Images do
# not depend on it. An LP_NUM_THREADS already in the environment wins; GPU drivers
# ignore it.
_workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "0") or 0)
# The same for OpenMP: flip-evaluator (HDR-FLIP, imported lazily, so this comes before
# its libgomp loads) otherwise starts one thread per core in each worker, and libgomp's
# threads spin at their barriers while the other worker wants the core: on test_tradeoff
# and test_exposure_invariance under -n 2, process CPU 67-76 s -> 34 s and wall 92-104 s
# -> 54 s (docs/TESTING.md, "OpenMP threads"). HDR-FLIP values do not depend on it.
# USD's own threads (TBB) are left at their default: a limit set here measured worse in
# whole warm runs, and lowered after `import stb_hydra` it makes TBB's threads spin
# (stb_hydra/usd_threads.py; docs/TESTING.md, "USD's threads in the workers").
if _workers >= 2 and _workers >= (os.cpu_count() or 1):
    os.environ.setdefault("LP_NUM_THREADS", "0")
    os.environ.setdefault("OMP_NUM_THREADS", "1")

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("STB_SHARED", REPO.parent / "shared")).resolve()
TESTDATA = SHARED / "testdata"


@pytest.fixture(scope="session")
def testdata() -> Path:
    """``../shared/testdata``. Missing data is an error, never a silent skip."""
    if not TESTDATA.is_dir():
        pytest.fail(f"shared test data not found at {TESTDATA} (set STB_SHARED)")
    return TESTDATA


@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO


@pytest.fixture(scope="session", autouse=True)
def _private_bake_cache(tmp_path_factory):
    """The xatlas unwrap cache (``STB_BAKE_CACHE``, default ~/.cache) in this session's
    temporary folder: a bake test never reads an entry of an earlier run or of another
    ``pytest -n`` worker, and the CLI subprocesses inherit it."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("STB_BAKE_CACHE", str(tmp_path_factory.mktemp("bake_cache")))
        yield


@pytest.fixture(scope="session")
def gl_ctx():
    """The process-wide OpenGL 4.3+ context (EGL: llvmpipe here, NVIDIA on GPU hosts).
    One context per process: the engine and every GL test share it; under
    ``pytest -n`` (pytest-xdist) each worker process has its own."""
    from stb_hydra.renderer.gl import get_context

    return get_context()


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    """The random order's seed, also under ``-q`` (pytest-randomly prints it only in the
    header, which ``-q`` hides): rerun a failing order with ``-p randomly
    -p "randomly" --randomly-seed=N``."""
    seed = getattr(config.option, "randomly_seed", None)
    if seed is not None and getattr(config.option, "randomly_reorganize", True):
        terminalreporter.write_line(f"test order: --randomly-seed={seed}")


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(config, items):
    """Under ``pytest -n`` (docs/TESTING.md): the modules that hold a test marked
    ``slow`` go first, whole (a stable sort: the modules and the tests in each keep
    pytest-randomly's order). ``make test`` hands out whole modules (``--dist
    loadfile``: module fixtures built once) in this order, so no long module starts
    last while the other worker sits idle. A serial run keeps the random order."""
    if not hasattr(config, "workerinput"):  # not an xdist worker
        return
    heavy = {item.path for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: item.path not in heavy)


_CPU_LOG = os.environ.get("STB_TEST_CPU_LOG")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """With ``STB_TEST_CPU_LOG=PATH``: one line per test appended to PATH -- node id,
    wall s, this process's CPU s (user + sys, every thread: llvmpipe's too) and its
    waited-for children's CPU s (the CLI subprocesses; and the optimised render child's,
    tests/optimised.py), set-up to teardown, then the xdist worker (``-`` serially) and
    the test's start and end (epoch s: where a worker sat idle). CPU time
    stays comparable on a loaded machine where wall time does not (docs/TESTING.md)."""
    if not _CPU_LOG:
        yield
        return
    import optimised  # the optimised child's CPU (tests/optimised.py)

    k0 = optimised.child_cpu_s
    s0 = resource.getrusage(resource.RUSAGE_SELF)
    c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    e0 = time.time()
    yield
    t1 = time.perf_counter()
    s1 = resource.getrusage(resource.RUSAGE_SELF)
    c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    own = (s1.ru_utime - s0.ru_utime) + (s1.ru_stime - s0.ru_stime)
    kids = (c1.ru_utime - c0.ru_utime) + (c1.ru_stime - c0.ru_stime) + optimised.child_cpu_s - k0
    with open(_CPU_LOG, "a") as log:  # one short line per write: O_APPEND keeps lines whole
        worker = os.environ.get("PYTEST_XDIST_WORKER", "-")
        log.write(
            f"{item.nodeid}\t{t1 - t0:.3f}\t{own:.3f}\t{kids:.3f}"
            f"\t{worker}\t{e0:.3f}\t{e0 + t1 - t0:.3f}\n"
        )
