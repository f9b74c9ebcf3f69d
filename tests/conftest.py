"""Shared pytest fixtures: real data from ../shared/testdata, a real GL context."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

import stb_hydra  # noqa: F401  (registers the codeless USD schema before any stage opens)

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


@pytest.fixture(scope="session")
def gl_ctx():
    """The process-wide OpenGL 4.3+ context (EGL: llvmpipe here, NVIDIA on GPU hosts).
    One context per process: the engine and every GL test share it."""
    from stb_hydra.renderer.gl import get_context

    return get_context()


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    """The random order's seed, also under ``-q`` (pytest-randomly prints it only in the
    header, which ``-q`` hides): rerun a failing order with ``-p randomly
    -p "randomly" --randomly-seed=N``."""
    seed = getattr(config.option, "randomly_seed", None)
    if seed is not None and getattr(config.option, "randomly_reorganize", True):
        terminalreporter.write_line(f"test order: --randomly-seed={seed}")
