"""The README's Python example runs as written (sizes shrunk), and the flat API is a
plain function with a real signature."""

from __future__ import annotations

import inspect
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def python_api_block() -> str:
    text = (REPO / "README.md").read_text()
    section = text[text.index("## Python API") :]
    m = re.search(r"```python\n(.*?)```", section, re.S)
    assert m, "README has no Python example under '## Python API'"
    return m.group(1)


@pytest.mark.gl
def test_readme_python_example_runs():
    code = python_api_block()
    for big, small in (
        ("width=256, height=144", "width=64, height=36"),
        ("width=745, height=360", "width=64, height=36"),
        ("accumulate=16", "accumulate=2"),
    ):
        assert big in code, big
        code = code.replace(big, small)
    r = subprocess.run(
        [sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=300
    )
    assert r.returncode == 0, r.stderr
    assert "passes (execution order):" in r.stdout


def test_render_is_a_plain_function_with_a_signature():
    import stb_hydra
    from stb_hydra import api

    assert stb_hydra.render is api.render and inspect.isfunction(stb_hydra.render)
    params = inspect.signature(stb_hydra.render).parameters
    assert {"stage", "width", "height", "lighting", "accumulate", "seed"} <= set(params)
    assert "scene-linear" in (stb_hydra.render.__doc__ or "")
